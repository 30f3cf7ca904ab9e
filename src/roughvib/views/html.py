"""The one HTML builder of the reports: escaping, number formatting, tables, embedded figures and
the page (CSS, title, navigation, sections).

Every report page (the run report, the sweep report) is built from these pieces, so the pages
look alike and escape the same way. A page is self-contained: one file, no script, no network;
figures are embedded as PNG data URIs (also where a report keeps its PNGs beside the page).
"""

from __future__ import annotations

import base64
import html
import io
import math
import re
from collections.abc import Callable, Iterable, Sequence

import numpy as np

__all__ = ["CSS", "esc", "figure", "figure_data_uri", "frame_table", "kv_table", "num", "page",
           "png_data_uri", "slug", "table"]

#: the style sheet of every report page (inline, so that a page is one file)
CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 2em auto;
       max-width: 1100px; padding: 0 1em; color: #222; line-height: 1.4; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
h2 { font-size: 1.15em; border-bottom: 1px solid #ccc; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.85em; }
th, td { border: 1px solid #ddd; padding: 2px 8px; text-align: right; }
th { background: #f3f3f3; }
td.key, th.key { text-align: left; }
pre { background: #f7f7f7; padding: 0.8em; overflow-x: auto; font-size: 0.8em; }
figure { margin: 1.5em 0; }
figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: 0.85em; color: #555; }
.status-success { color: #17692b; } .status-failed { color: #a11; }
.note { font-size: 0.85em; color: #555; }
.banner { border: 2px solid #a11; background: #fdecea; padding: 0.6em 1em; margin: 1em 0; }
nav a { margin-right: 1em; }
"""


def esc(x) -> str:
    """``str(x)`` with ``& < > " '`` escaped, safe in text and in quoted attributes."""
    return html.escape(str(x), quote=True)


def num(x, fmt: str = ".6g") -> str:
    """A table cell's text: numbers formatted with ``fmt`` (``n/a`` for None, NaN and inf),
    integers and booleans as they are, anything else escaped."""
    if x is None:
        return "n/a"
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, int | np.integer):
        return str(int(x))
    if isinstance(x, float | np.floating):
        return "n/a" if not math.isfinite(float(x)) else format(float(x), fmt)
    return esc(x)


def _table(head: Iterable[str], rows: Iterable[Iterable[str]]) -> str:
    """A table from cells that are already HTML."""
    head_html = "".join(head)
    body = "".join(f"<tr>{''.join(cells)}</tr>" for cells in rows)
    return f"<table><tr>{head_html}</tr>{body}</table>"


def table(header: Sequence, rows: Iterable[Sequence]) -> str:
    """A table of plain text cells (all escaped).

    Parameters
    ----------
    header : sequence
        Column headings.
    rows : iterable of sequences
        One sequence of cells per row, as many as ``header``.
    """
    return _table((f"<th>{esc(h)}</th>" for h in header),
                  ((f"<td>{esc(c)}</td>" for c in r) for r in rows))


def kv_table(rows: Iterable[tuple[str, object, str]], fmt: str = ".4g") -> str:
    """A quantity / value / unit table; values formatted with :func:`num`.

    Parameters
    ----------
    rows : iterable of (str, object, str)
        Quantity, value and unit of each row.
    fmt : str
        Format of the floating-point values (default: 4 significant digits, as a reader
        compares them; integers are shown whole).
    """
    return _table(["<th class='key'>quantity</th>", "<th>value</th>",
                   "<th class='key'>unit</th>"],
                  ([f"<td class='key'>{esc(k)}</td>", f"<td>{num(v, fmt)}</td>",
                    f"<td class='key'>{esc(u)}</td>"] for k, v, u in rows))


def frame_table(df, formats: dict[str, Callable[[object], str]] | None = None) -> str:
    """A table of a pandas DataFrame: one column per column, cells formatted with :func:`num`.

    Parameters
    ----------
    df : pandas.DataFrame
    formats : dict, optional
        Column -> function giving the cell's HTML for a value (instead of :func:`num`).
    """
    formats = formats or {}
    return _table((f"<th>{esc(c)}</th>" for c in df.columns),
                  ((f"<td>{formats[c](row[c]) if c in formats else num(row[c])}</td>"
                    for c in df.columns) for _, row in df.iterrows()))


def figure_data_uri(fig, *, dpi: int) -> str:
    """A matplotlib figure as a ``data:image/png;base64,...`` URI.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Drawn as it is (neither laid out nor closed here).
    dpi : int
        Resolution [dots per inch].
    """
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return png_data_uri(buf.getvalue())


def png_data_uri(png: bytes) -> str:
    """PNG bytes (a file's content) as a ``data:image/png;base64,...`` URI."""
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def figure(src: str, *, alt: str, caption_html: str = "", id: str | None = None) -> str:
    """A ``<figure>``: the image and an optional caption.

    Parameters
    ----------
    src : str
        Data URI (:func:`figure_data_uri`, :func:`png_data_uri`).
    alt : str
        Text of the image for readers that do not show it.
    caption_html : str
        The caption, already HTML (escape text with :func:`esc`); none if empty.
    id : str, optional
        Element id (a target of the page's links).
    """
    ident = f' id="{esc(id)}"' if id else ""
    caption = f"<figcaption>{caption_html}</figcaption>" if caption_html else ""
    return f'<figure{ident}><img src="{esc(src)}" alt="{esc(alt)}">{caption}</figure>'


def slug(text: str) -> str:
    """An element id from a heading: lower-case letters, digits and hyphens."""
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "section"


def page(title: str, sections: Sequence[tuple[str, str, str]], *, header_html: str = "") -> str:
    """A complete HTML5 document: title, header, a navigation bar over the sections, sections.

    Parameters
    ----------
    title : str
        Page title and top heading (escaped here).
    sections : sequence of (str, str, str)
        Id, heading (text) and content (HTML) of each section, in page order.
    header_html : str
        HTML between the top heading and the navigation bar (status lines, an introduction).

    Returns
    -------
    str
        The document, with the CSS of :data:`CSS` inline.
    """
    nav = "".join(f"<a href='#{esc(i)}'>{esc(h)}</a>" for i, h, _ in sections)
    body = "".join(f"<section id='{esc(i)}'><h2>{esc(h)}</h2>{c}</section>"
                   for i, h, c in sections)
    return (
        "<!DOCTYPE html>\n<html lang='en'>\n<head>\n<meta charset='utf-8'>\n"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>\n"
        f"<title>{esc(title)}</title>\n<style>{CSS}</style>\n</head>\n<body>\n"
        f"<h1>{esc(title)}</h1>\n{header_html}\n"
        f"<nav>{nav}</nav>\n{body}\n</body>\n</html>\n")
