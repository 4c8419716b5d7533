"""Self-contained HTML reports: escaping, one page skeleton with one stylesheet, tables, figures and sections.

The reports (``nnphd reproduce``: :mod:`nnphd.paper.reproduce`; ``nnphd detect``: :mod:`nnphd.user.report`) write
their own content with these pieces. Every function returns an HTML string; arguments named ``body`` or ``cells``
are HTML already (escape text with :func:`escape` first), titles, names and links are escaped here.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = ["CSS", "escape", "page", "table", "figure", "figure_file", "figures", "section", "details", "bullets"]

CSS = """
body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em}h2{border-bottom:2px solid #ccc;padding-top:.5em}
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right;vertical-align:top}
td.l,th.l{text-align:left}tr.best{font-weight:bold}.met{color:#0a0;font-weight:bold}.miss{color:#c00;font-weight:bold}
.claim{background:#f4f4f8;border-left:4px solid #88a;padding:.5em 1em;margin:1em 0}
.fig{display:flex;flex-wrap:wrap;gap:1em}.fig figure{margin:0;max-width:100%}.fig img{max-width:100%;border:1px solid #ddd}
.quick{background:#fff4d0;border:1px solid #e0c060;padding:.5em 1em}code,pre{font-size:.85em}pre{white-space:pre-wrap}
.status{font-size:1.4em}.st-detected{color:#c00}.st-none{color:#070}.st-inconclusive{color:#a60}.warn{color:#a60}
"""


def escape(x) -> str:
    """``str(x)`` with &, <, >, " and ' escaped."""
    return html.escape(str(x))


def page(title: str, body: str) -> str:
    """A whole document: ``<title>`` (escaped), the stylesheet :data:`CSS` and ``body``."""
    return (
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{escape(title)}</title><style>{CSS}</style>"
        f"</head><body>{body}</body></html>"
    )


def table(header: Sequence[str], rows: Iterable[Sequence], left: int = 1, row_classes: Sequence[str] = ()) -> str:
    """A table: ``header`` (text, escaped) and ``rows`` of cells (HTML, or anything ``str`` turns into HTML); the first
    ``left`` columns are left-aligned (class "l"), the rest right-aligned. ``row_classes``: a class per row ("" for
    none), e.g. "best" (bold)."""

    def cls(i):
        return ' class="l"' if i < left else ""

    th = "".join(f"<th{cls(i)}>{escape(h)}</th>" for i, h in enumerate(header))
    body = []
    for k, r in enumerate(rows):
        rc = row_classes[k] if k < len(row_classes) else ""
        tr = f'<tr class="{escape(rc)}">' if rc else "<tr>"
        body.append(tr + "".join(f"<td{cls(i)}>{c}</td>" for i, c in enumerate(r)) + "</tr>")
    return f"<table><tr>{th}</tr>{''.join(body)}</table>"


def figure(png: bytes, href: str) -> str:
    """A PNG embedded as a data URI (the page opens alone), captioned with a link to its file ``href``."""
    data = base64.b64encode(png).decode()
    return (
        f'<figure><img src="data:image/png;base64,{data}" alt="{escape(href)}">'
        f'<figcaption><a href="{escape(href)}">{escape(href)}</a></figcaption></figure>'
    )


def figure_file(outdir: str | Path, rel: str) -> str:
    """:func:`figure` of the PNG file ``outdir/rel`` (linked as ``rel``), or a note that it was not produced."""
    p = Path(outdir) / rel
    if not p.is_file():
        return f'<p class="miss">figure not produced: {escape(rel)}</p>'
    return figure(p.read_bytes(), rel)


def figures(items: Iterable[str]) -> str:
    """Figures (or any blocks) side by side, wrapping."""
    return f'<div class="fig">{"".join(items)}</div>'


def section(title: str, body: str, anchor: str | None = None) -> str:
    """``<section>`` with an ``<h2>`` heading (escaped), its ``id`` the ``anchor`` if given."""
    ident = f' id="{escape(anchor)}"' if anchor else ""
    return f"<section{ident}><h2>{escape(title)}</h2>{body}</section>"


def details(summary: str, text: str) -> str:
    """A collapsed block: ``summary`` (escaped) opens the preformatted ``text`` (escaped)."""
    return f"<details><summary>{escape(summary)}</summary><pre>{escape(text)}</pre></details>"


def bullets(items: Iterable[str]) -> str:
    """A bulleted list of HTML items."""
    return "<ul>" + "".join(f"<li>{x}</li>" for x in items) + "</ul>"
