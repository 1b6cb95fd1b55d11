"""The crease pattern: its sheets, every crease's fold and angle, the cut-ready sheet, and the
paper to buy."""

from __future__ import annotations

from .common import esc, exporter_report, fmt_value, img, link
from .folder import describe_file


def origami_section(report, files: dict, ident: str = "origami") -> str:
    """The crease pattern: its sheets, each crease's fold and angle, the cut-ready sheet."""
    r = exporter_report(report.formats, "svg")
    svgs = [n for n in report.formats["svg"].files
            if n.endswith(".svg") and not n.endswith("_cut.svg") and n in files] if r else []
    body = "".join(img(n, files[n], "crease pattern", f"{n}: {describe_file(n)}")
                   for n in svgs)
    creases = r.get("creases") or []
    if creases:
        rows = "".join(f"<tr><td>{esc(c['crease'])}</td><td>{esc(c['fold'])}</td>"
                       f"<td>{c['angle_deg']:.1f}°</td></tr>" for c in creases)
        body += ("<p>Fold every crease to its angle (0° flat, 180° folded flat), seen from the "
                 'printed side:</p><div class="scroll"><table><tr><th>crease</th><th>fold</th>'
                 f"<th>angle</th></tr>{rows}</table></div>")
    cut = r.get("cut") or {}
    if r.get("cut_file") in files:
        perf = cut.get("perforation") or {}
        body += (f"<details><summary>Cut-ready sheet {esc(r['cut_file'])}: "
                 f"{fmt_value(perf.get('dash_mm'))} mm cuts, "
                 f"{fmt_value(perf.get('gap_mm'))} mm gaps, "
                 f"{fmt_value(perf.get('stop_mm'))} mm whole at every vertex</summary>"
                 + img(r["cut_file"], files[r["cut_file"]], "cut-ready sheet") + "</details>")
    return (f"<section id={ident}><h2>Crease pattern</h2><p>Valley folds blue and dashed, "
            "mountain folds red and dash-dot; the motion above shows the sheet folding.</p>"
            + body + "</section>")


def origami_bom(report, ident: str = "bom") -> str:
    """The paper to buy (``""`` when no crease pattern was written)."""
    svg = exporter_report(report.formats, "svg")
    if not svg:
        return ""
    sheet = svg.get("sheet") or {}
    size = (f"square, side {sheet['side_mm']:.2f} mm" if sheet.get("shape") == "square"
            else f"{fmt_value(sheet.get('bbox_mm'))} mm")
    return (f"<section id={ident}><h2>Bill of materials</h2><table><tr><th>origami</th>"
            f"<th>quantity</th></tr><tr><td>paper sheets ({esc(size)})</td>"
            f"<td>{fmt_value(svg.get('sheets', 1))}</td></tr></table></section>")


def origami_lead(formats: dict) -> list[str]:
    """The paper in a few words under "Made for", and the file to print and fold."""
    parts = []
    r = exporter_report(formats, "svg")
    sheet = r.get("sheet") or {}
    if sheet.get("shape") == "square":
        paper = (f"a square of side {sheet['side_mm']:.2f} mm ({sheet['across_mm']:.2f} mm "
                 "corner to corner)")
    else:
        paper = f"{esc(sheet.get('shape', 'a sheet'))} {fmt_value(sheet.get('bbox_mm'))} mm"
    n = r.get("sheets", 1)
    parts.append(f"<p>One sheet of paper, {paper}.</p>" if n == 1 else
                 f"<p>{n} sheets of paper, each {paper}.</p>")
    if r.get("file"):
        parts.append(f"<p><b>Start here:</b> {link(r['file'])} (print at 100 %, fold)"
                     + (f", or cut {link(r['cut_file'])} on a laser or vinyl cutter"
                        if r.get("cut_file") else "") + ".</p>")
    return parts
