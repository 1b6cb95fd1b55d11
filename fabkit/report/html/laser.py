"""The laser-cut kit: its pictures, the cut sheets at true size and its bill of materials."""

from __future__ import annotations

from .common import blocks_html, esc, exporter_report, fmt_value, img, link
from .folder import describe_file


#: Tables of a bill of materials longer than this are folded (the screws and sheets stay open,
#: the 144 bars of a long chain do not bury what follows).
FOLD_ROWS = 12


def laser_section(files: dict, ident: str = "laser") -> str:
    """The laser-cut kit's pictures, and its cut sheets at true size folded."""
    pics = [n for n in ("laser_assembly.png", "laser_layers_motion.png",
                        "laser_guide_page1.png") if n in files]
    pics += [n for n in sorted(files) if n.startswith("laser_") and n.endswith(".png")
             and n not in pics]
    sheets = [n for n in sorted(files) if n.startswith("laser_sheet") and n.endswith(".svg")]
    body = "".join(img(n, files[n], n, f"{n}: {describe_file(n)}") for n in pics)
    if sheets:
        body += ("<details><summary>The cut sheets at true size (1 mm = 3.78 px)</summary>"
                 + "".join(img(n, files[n], n) for n in sheets) + "</details>")
    return f"<section id={ident}><h2>Laser-cut kit</h2>{body}</section>"


def laser_bom(report, ident: str = "bom") -> str:
    """The kit's bill of materials (``""`` when no laser kit was written)."""
    from ...writers.dxf import bom_blocks

    bom = exporter_report(report.formats, "dxf")
    if not bom:
        return ""
    return (f"<section id={ident}><h2>Bill of materials</h2>"
            + blocks_html(bom_blocks(bom), FOLD_ROWS) + "</section>")


def laser_lead(formats: dict, files: dict) -> list[str]:
    """The kit in a few words under "Made for": its sheets, bars, layers and hardware,
    and the assembly guide to start from."""
    parts = []
    b = exporter_report(formats, "dxf")
    st = b["settings"]
    sheets = b["sheets"]
    sizes = sorted({f"{s['size_mm'][0]:g} × {s['size_mm'][1]:g} mm" for s in sheets})
    screws = sum(s["count"] for s in b["screws"])
    parts.append(f"<p>{len(sheets)} sheet{'s' if len(sheets) != 1 else ''} of "
                 f"{esc(', '.join(sizes))}, {fmt_value(st['thickness'])} mm acrylic, "
                 f"{fmt_value(b['scale_mm_per_unit'])} mm a design unit; {len(b['bars'])} bars "
                 f"in {esc(b['layers']['count'])} layers; {screws} screws, "
                 f"{b['washers']['count']} washers, {b['spacer_rings']['count']} spacer "
                 "rings (see the bill of materials).</p>")
    if "laser_guide.pdf" in files:
        parts.append(f"<p><b>Start here:</b> {link('laser_guide.pdf')}, the assembly guide "
                     f"({b['guide_pages']} A4 pages: overview, how to build, a page per two "
                     "modules, the motion test).</p>")
    return parts
