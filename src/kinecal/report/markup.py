"""Building blocks of kinecal's self-contained HTML reports: number formatting, escaped
tables, embedded PNG figures, sections and the page with its inline CSS (used by
`kinecal.report.html` and every other report module).
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Iterable, Sequence
from typing import Any

from kinecal.report.figures import DPI, FIGSIZE

__all__ = ["FIG_HEIGHT", "FIG_WIDTH", "fmt", "image_tag", "kv", "page", "section", "table"]

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;margin:2em auto;max-width:60em;
color:#222;padding:0 1em}
h1{font-size:1.6em;margin-bottom:.2em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;
margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}
th,td{border:1px solid #ddd;padding:.25em .6em;text-align:right}
th{background:#f3f3f3}td.l,th.l{text-align:left}
tr.fixed td{color:#888}
figure{margin:1em 0}figcaption{font-size:.9em;color:#555}
img.fig{display:block;border:1px solid #eee}
p.meta{color:#555;margin-top:0}code,pre{background:#f6f6f6;padding:.1em .3em}
pre{padding:.6em;overflow-x:auto}
section.summary{background:#eef5fb;border-left:4px solid #1f77b4;padding:.2em 1em;margin:1em 0}
section.summary h2{border:none;margin-top:.4em}section.summary p{margin:.35em 0}
table.files td:nth-child(3){font-family:ui-monospace,monospace;font-size:.85em;word-break:break-all}
@page{size:A4;margin:14mm 12mm 16mm;
@bottom-left{content:string(meta);font:7.5pt system-ui,sans-serif;color:#555}
@bottom-right{content:"page " counter(page) " of " counter(pages);font:7.5pt system-ui,
sans-serif;color:#555}}
@media print{body{margin:0;max-width:none;padding:0;font-size:9pt}
img.fig{width:100%;height:auto}figure,tr{break-inside:avoid}h2{break-after:avoid}
p.meta{string-set:meta content()}table{font-size:.9em}
#correlation table{font-size:.62em}#correlation th,#correlation td{padding:.15em .2em}}
"""

#: pixel size of every embedded figure
FIG_WIDTH, FIG_HEIGHT = round(FIGSIZE[0] * DPI), round(FIGSIZE[1] * DPI)


def fmt(value: Any, digits: int = 4) -> str:
    """Format a number with `digits` significant digits (``-`` for None/NaN)."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "-"
        return f"{value:.{digits}g}"
    return str(value)


def table(header: Sequence[str] | None, rows: Iterable[Sequence[Any]], *, left: int = 1,
          row_classes: Sequence[str] | None = None, digits: int = 4) -> str:
    """An HTML table; every cell is formatted with `fmt` and escaped.

    No header row when `header` is None. The first `left` columns are left-aligned
    (names), the others right-aligned (numbers).
    """
    def cell(tag: str, k: int, v: Any) -> str:
        cls = ' class="l"' if k < left else ""
        return f"<{tag}{cls}>{html.escape(fmt(v, digits))}</{tag}>"

    head = ("" if header is None else
            "<thead><tr>" + "".join(cell("th", k, h) for k, h in enumerate(header))
            + "</tr></thead>")
    body = []
    for i, row in enumerate(rows):
        cls = row_classes[i] if row_classes is not None and row_classes[i] else ""
        attr = f' class="{html.escape(cls)}"' if cls else ""
        body.append(f"<tr{attr}>" + "".join(cell("td", k, v) for k, v in enumerate(row))
                    + "</tr>")
    return f"<table>{head}<tbody>{''.join(body)}</tbody></table>"


def image_tag(png: bytes, alt: str, caption: str = "", ident: str = "") -> str:
    """A ``<figure>`` embedding `png` as a base64 data URI (width/height attributes set)."""
    data = base64.b64encode(png).decode("ascii")
    idattr = f' id="{html.escape(ident)}"' if ident else ""
    cap = f"<figcaption>{html.escape(caption)}</figcaption>" if caption else ""
    return (f'<figure{idattr}><img class="fig" src="data:image/png;base64,{data}" '
            f'alt="{html.escape(alt)}" width="{FIG_WIDTH}" height="{FIG_HEIGHT}">{cap}'
            "</figure>")


def section(ident: str, title: str, body: str) -> str:
    """A ``<section>`` with an ``h2`` title (the title is escaped, the body is not)."""
    return (f'<section id="{html.escape(ident)}"><h2>{html.escape(title)}</h2>'
            f"{body}</section>")


def page(title: str, subtitle: str, sections: Sequence[str], created: str | None = None
         ) -> str:
    """The complete document: escaped title, inline CSS, the given sections.

    The line under the title names kinecal's version and, when given, the report's date
    (`created`, ISO 8601); printed (PDF), it is the footer of every page.
    """
    from kinecal import __version__

    when = f" &middot; {html.escape(created)}" if created else ""
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>"
        f"<h1>{html.escape(title)}</h1><p class=\"meta\">{html.escape(subtitle)} "
        f"&middot; kinecal {html.escape(__version__)}{when}</p>"
        + "".join(sections) + "</body></html>\n"
    )


def kv(pairs: Sequence[tuple[str, Any]]) -> str:
    """A two-column name / value table without header."""
    return table(None, pairs, left=1)
