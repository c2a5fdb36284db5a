"""Self-contained HTML pages (the study's report, the sensitivity study, the batch fits and
sweeps): one style, tables that fit the page, figures inlined as PNG. Pure string building;
no Matplotlib here (figures come as PNG bytes, `torquesim.plots.figure_png`)."""

from __future__ import annotations

import base64
import html

#: Tables wrap their header text and sit in a box that scrolls sideways on its own when a
#: narrow window cannot hold them, so the page itself never grows wider than the window.
STYLE = ("body{font-family:sans-serif;max-width:1100px;margin:auto;padding:0 12px}"
         "img{max-width:100%;height:auto}"
         ".table{overflow-x:auto;max-width:100%}"
         "table{border-collapse:collapse;font-size:12px}"
         "td,th{border:1px solid #ccc;padding:2px 5px;text-align:right}"
         "th{background:#eee;white-space:normal;max-width:9em}"
         "td.name,th.name{text-align:left}")


def cell(value) -> str:
    """A table cell's text: 4 significant digits for floats, yes/no, — for missing."""
    if value is None or value == "":
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}"
    return html.escape(str(value))


def table(headers, rows, *, name_columns=1) -> str:
    """An HTML table; the first ``name_columns`` columns are left-aligned names."""
    def row(tag, values):
        return "<tr>" + "".join(
            f"<{tag}{' class=name' if i < name_columns else ''}>{v}</{tag}>"
            for i, v in enumerate(values)) + "</tr>"

    return ("<div class=table><table>" + row("th", [html.escape(h) for h in headers])
            + "".join(row("td", [cell(v) for v in r]) for r in rows) + "</table></div>")


def settings_table(settings: dict) -> str:
    """Settings as a two-column table (lists joined by commas)."""
    def text(value):
        if isinstance(value, list | tuple):
            return ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
        return value

    return table(("setting", "value"), [(k, text(v)) for k, v in settings.items()],
                 name_columns=2)


def image(png: bytes, alt: str) -> str:
    return (f"<img alt='{html.escape(alt)}' "
            f"src='data:image/png;base64,{base64.b64encode(png).decode()}'>")


def page(title: str, body: list[str]) -> str:
    return "\n".join([f"<!doctype html><html><head><meta charset='utf-8'>"
                      f"<meta name='viewport' content='width=device-width'>"
                      f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>",
                      f"<h1>{html.escape(title)}</h1>", *body, "</body></html>"])
