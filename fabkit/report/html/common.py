"""What every section of a report page shares: escaping and number formats, pictures inlined
at their own size, blocks of text and tables, a verdict level or a check's result as a coloured
word, and the processes a design can be made for."""

from __future__ import annotations

import base64
import html
import re


#: CSS pixels per mm (96 per inch): an SVG drawn in mm shows at its true size.
PX_PER_MM = 96 / 25.4


LAYER_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
                  "#17becf", "#bcbd22", "#7f7f7f"]


#: The CSS class a verdict level is shown with: green ok, brown "by design" (said in words, not
#: alarmed), red FLAG and FAIL.
LEVEL_CLASS = {"ok": "ok", "by design": "note", "FLAG": "bad", "FAIL": "bad"}


#: The processes a design can be made for and the formats of each (one table, with the
#: tolerance analysis: :data:`fabkit.tolerance.PROCESS_FORMATS`).
PROCESSES = {"print": ("stl",), "origami": ("svg", "fold", "cp"), "laser": ("dxf",)}


def esc(x) -> str:
    """Text made safe inside HTML (quotes too)."""
    return html.escape(str(x), quote=True)


def fmt_value(v) -> str:
    """A value of a report as a person reads it: ``–`` for none, yes/no, four significant
    digits, lists joined by commas."""
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, tuple)):
        return ", ".join(fmt_value(x) for x in v)
    return str(v)


def _data_uri(name: str, data: bytes) -> str:
    mime = {"png": "image/png", "svg": "image/svg+xml"}[name.rsplit(".", 1)[-1].lower()]
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


def image_size(name: str, data: bytes) -> tuple[int, int] | None:
    """Width and height (CSS pixels) at which a picture shows its text at its own size: a PNG's
    pixels, an SVG's ``width``/``height`` in mm at 96 px per inch; None when not known."""
    if name.lower().endswith(".png") and data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    if name.lower().endswith(".svg"):
        head = data[:2000].decode("utf-8", "replace")
        m = re.search(r'<svg[^>]*\bwidth="([\d.]+)mm"[^>]*\bheight="([\d.]+)mm"', head)
        if m:
            return (round(float(m.group(1)) * PX_PER_MM), round(float(m.group(2)) * PX_PER_MM))
    return None


def img(name: str, data: bytes, alt: str, caption: str | None = None) -> str:
    """A picture at its own size (never scaled down: its box scrolls sideways instead)."""
    size = image_size(name, data)
    dims = f' width="{size[0]}" height="{size[1]}"' if size else ""
    return (f'<figure class="pic"><div class="scroll"><img src="{_data_uri(name, data)}" '
            f'alt="{esc(alt)}"{dims}></div><figcaption>{esc(caption or name)}</figcaption>'
            "</figure>")


def blocks_html(blocks, fold_rows: int | None = None) -> str:
    """Blocks of text and tables (:func:`fabkit.writers.dxf.bom_blocks`) as HTML; a table longer
    than ``fold_rows`` rows is folded under its heading (``<details>``)."""
    out, heading = [], ""
    for block in blocks:
        kind = block[0]
        if kind == "table":
            _, header, rows = block
            body = ("<tr>" + "".join(f"<th>{esc(c)}</th>" for c in header) + "</tr>"
                    + "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in row) + "</tr>"
                              for row in rows))
            table = f'<div class="scroll"><table>{body}</table></div>'
            if fold_rows is not None and len(rows) > fold_rows:
                table = (f"<details><summary>{esc(heading or 'table')}: {len(rows)} rows"
                         f"</summary>{table}</details>")
            out.append(table)
        elif kind in ("title", "heading"):
            heading = block[1]
            level = 3 if kind == "title" else 4
            out.append(f"<h{level}>{esc(block[1])}</h{level}>")
        elif kind == "strong":
            out.append(f"<p><b>{esc(block[1])}</b></p>")
        elif kind == "item":
            out.append(f"<ul><li>{esc(block[1])}</li></ul>")
        else:
            out.append(f"<p>{esc(block[1])}</p>")
    return "\n".join(out)


def exporter_report(formats: dict, fmt: str) -> dict:
    """The exporter's report of a format that wrote files (``{}`` when it wrote none)."""
    f = formats.get(fmt)
    return f.report if f is not None and f.status.produced else {}


def exported(report, proc: str) -> bool:
    """True when any format of the process ``proc`` wrote files."""
    return any(report.formats[f].status.produced for f in PROCESSES[proc]
               if f in report.formats)


def pass_span(ok) -> str:
    """A check's result as a coloured word: pass or FAIL."""
    return '<span class="ok">pass</span>' if ok else '<span class="bad">FAIL</span>'


def level_span(level) -> str:
    """A verdict level as a word in its colour."""
    word = "flagged by design" if str(level) == "by design" else str(level)
    return f'<span class="{LEVEL_CLASS[str(level)]}">{esc(word)}</span>'


def link(name: str) -> str:
    """A link to a file next to the page."""
    return f'<a href="{esc(name)}">{esc(name)}</a>'
