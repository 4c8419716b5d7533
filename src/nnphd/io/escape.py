"""Untrusted text made safe where it is rendered.

Column names, file names, paths and the messages that quote them come from the user's data; each output that gives
some characters a meaning gets them escaped here, so the text shows literally and never breaks the output:

* :func:`mpl` — matplotlib text (labels, titles, legends): a pair of ``$`` would start mathtext (``$\\frac{x$``
  raises when the figure is drawn); every ``$`` becomes ``\\$``, which matplotlib shows as ``$``.  Names are never
  put inside a math string (``$...$``): they stay plain text beside it.
* :func:`terminal` — the terminal itself: control characters (C0 such as ESC, BEL, CR, newline and tab; DEL; C1
  such as CSI ``\\x9b``), format characters (the bidi overrides and isolates such as U+202E, zero-width ones), line
  and paragraph separators, lone surrogates and unassigned code points are shown as Python-style escapes
  (``\\x1b``, ``\\n``, ``\\u202e``), so a name can neither send terminal commands (``ESC]0;…BEL`` sets the window
  title, ``ESC[2J`` clears the screen) nor reorder what is shown around it.  :func:`one_line` is its form for
  one-line messages.  Every text nnphd's command line prints goes through it (:func:`rich` applies it).
* :func:`rich` — the console's Rich markup: ``[/x]`` is a closing tag (an unmatched one raises), ``[bold]`` a style;
  Rich escapes neither control codes nor bidi characters, so :func:`terminal` is applied first.
* :func:`csv_cell` — spreadsheet formula injection: a text cell starting with ``=``, ``+``, ``-``, ``@``, a tab or a
  carriage return is run as a formula by Excel/LibreOffice; it gets a leading ``'`` (the OWASP rule).  Numbers
  stay numbers.
* HTML: :func:`nnphd.io.html.escape`.
"""

from __future__ import annotations

import re
import unicodedata

__all__ = ["mpl", "terminal", "one_line", "rich", "csv_cell", "CSV_FORMULA_START"]

CSV_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def mpl(text) -> str:
    """``str(text)`` for a plain (non-math) matplotlib text: ``$`` escaped as ``\\$``, so it renders literally."""
    return str(text).replace("$", r"\$")


# Unicode categories shown as escapes: Cc (C0 controls, DEL, C1 controls), Cf (format: bidi marks, embeddings,
# overrides and isolates, zero-width joiners, soft hyphen, tags), Cs (lone surrogates: undecodable bytes of a file
# name), Zl/Zp (U+2028/U+2029 break lines) and Cn (unassigned here, perhaps a format character to a newer terminal)
TERMINAL_ESCAPED = frozenset({"Cc", "Cf", "Cs", "Zl", "Zp", "Cn"})


def _shown(c: str) -> str:
    return c.encode("unicode_escape").decode("ascii") if unicodedata.category(c) in TERMINAL_ESCAPED else c


def terminal(text) -> str:
    """``str(text)`` safe to print on a terminal: every character of the categories :data:`TERMINAL_ESCAPED` —
    control characters (ESC, BEL, newline, tab, DEL, the C1 range U+0080–U+009F), format characters (U+200E/U+200F,
    U+202A–U+202E, U+2066–U+2069, U+061C …), line and paragraph separators, lone surrogates, unassigned code points
    — becomes its Python escape (``\\x1b``, ``\\n``, ``\\u202e``, ``\\U000e0001``); every other character, and so
    any printable text, is kept as it is.  The result holds only printable characters and spaces (so applying it
    twice changes nothing).  A backslash is not doubled: a name that holds the four characters ``\\x1b`` shows like
    one holding ESC — a display, not an encoding."""
    s = str(text)
    if s.isprintable():  # no character of those categories (isprintable is False for each of them)
        return s
    return "".join(map(_shown, s))


_BREAKS = re.compile(r"[ \t\n\r\v\f]+")


def one_line(text, limit: int | None = None) -> str:
    """``text`` as one line for the terminal (an error, a warning): its own line breaks and runs of spaces, tabs,
    CR, VT and FF become one space, the ends are stripped, it is cut after ``limit`` characters (``…``), and then
    :func:`terminal` shows every other control or format character as an escape — so a name's ESC or U+202E shows
    as ``\\x1b`` / ``\\u202e``, while a tab or newline inside it shows as a space (a message cannot tell a name's
    line break from its own)."""
    s = _BREAKS.sub(" ", str(text)).strip(" ")
    if limit is not None and len(s) > limit:
        s = s[:limit] + "…"
    return terminal(s)


def rich(text) -> str:
    """``str(text)`` safe for ``console.print``: :func:`terminal` first (Rich passes control codes and bidi
    characters through), then Rich markup escaped, so it shows literally: a ``[`` that starts a tag gets a
    backslash (and the backslashes before it are doubled), a backslash before any other ``[`` gets one more (Rich
    turns every ``\\[`` of plain text into ``[``).  Unlike :func:`rich.markup.escape` (which misses the second case),
    a trailing backslash is left as it is: place the result at the end or before plain text, not directly before a
    markup tag."""
    return _RICH_BRACKET.sub(_rich_bracket, terminal(text))


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
