"""Untrusted text made safe where it is rendered.

Column names, file names, paths and the messages that quote them come from the user's data; each output that gives
some characters a meaning gets them escaped here, so the text shows literally and never breaks the output:

* :func:`mpl` — matplotlib text (labels, titles, legends): a pair of ``$`` would start mathtext (``$\\frac{x$``
  raises when the figure is drawn); every ``$`` becomes ``\\$``, which matplotlib shows as ``$``.  Names are never
  put inside a math string (``$...$``): they stay plain text beside it.
* :func:`rich` — the console's Rich markup: ``[/x]`` is a closing tag (an unmatched one raises), ``[bold]`` a style.
* :func:`csv_cell` — spreadsheet formula injection: a text cell starting with ``=``, ``+``, ``-``, ``@``, a tab or a
  carriage return is run as a formula by Excel/LibreOffice; it gets a leading ``'`` (the OWASP rule).  Numbers
  stay numbers.
* HTML: :func:`nnphd.io.html.escape`.
"""

from __future__ import annotations

import re

__all__ = ["mpl", "rich", "csv_cell", "CSV_FORMULA_START"]

CSV_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def mpl(text) -> str:
    """``str(text)`` for a plain (non-math) matplotlib text: ``$`` escaped as ``\\$``, so it renders literally."""
    return str(text).replace("$", r"\$")


def rich(text) -> str:
    """``str(text)`` with Rich markup escaped, so ``console.print`` shows it literally: a ``[`` that starts a tag gets a
    backslash (and the backslashes before it are doubled), a backslash before any other ``[`` gets one more (Rich
    turns every ``\\[`` of plain text into ``[``).  Unlike :func:`rich.markup.escape` (which misses the second case),
    a trailing backslash is left as it is: place the result at the end or before plain text, not directly before a
    markup tag."""
    return _RICH_BRACKET.sub(_rich_bracket, str(text))


_RICH_BRACKET = re.compile(r"(\\*)\[(?=([a-z#/@][^[]*?\])?)")  # rich.markup.RE_TAGS, with the tag as a look-ahead


def _rich_bracket(m: re.Match) -> str:
    k = len(m.group(1))
    if m.group(2) is not None:  # a tag: k literal backslashes, then an escaped "["
        return "\\" * (2 * k + 1) + "["
    return "\\" * (k + 1) + "[" if k else "["  # plain text: Rich removes one backslash before "["


def csv_cell(value) -> str | int | float:
    """A CSV cell: a number (int or float, not bool) as it is; anything else as text, prefixed with ``'`` when it
    starts with a character a spreadsheet reads as the start of a formula (``=``, ``+``, ``-``, ``@``, tab, CR)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value
    text = "" if value is None else str(value)
    return "'" + text if text.startswith(CSV_FORMULA_START) else text
