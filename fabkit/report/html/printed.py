"""The printed part: its plates or bars and pins, the printer's bed layout, its pictures, and
the filament and parts to buy."""

from __future__ import annotations

from .common import esc, exporter_report, fmt_value, img, link


def print_section(report, files: dict, ident: str = "print") -> str:
    """The printed part: its plates or bars and pins, the printer's layout, its pictures."""
    r = exporter_report(report.formats, "stl")
    if not r:
        return ""
    pr = r.get("printer") or {}
    body = []
    s = r["settings"]
    if r["linkage"] == "pins":
        body.append(f"<p>Printed in place: {r['bars']} bars in {r['layers']} layers "
                    f"on {r['printed_pins']} printed pins ({esc(s['material'])}), "
                    f"{fmt_value(r['height_mm'])} mm tall, {fmt_value(r['volume_mm3'])} mm³.</p>")
    else:
        body.append(f"<p>{r['plates']} plates, {r['hinges']} hinges "
                    f"({esc(s['hinge_style'])}, {esc(s['material'])}), "
                    f"{esc(fmt_value(r['size_mm']))} mm, {fmt_value(r['volume_mm3'])} mm³.</p>")
    if pr:
        bed = pr.get("printer") or {}
        layout = "; ".join(f"piece {p['piece']} on bed {p['bed']} turned "
                           f"{p['angle_deg']:.0f}°" + (f", joined at {p['joined_at']}"
                                                      if p.get("joined_at") else "")
                           for p in pr.get("pieces", []))
        body.append(f"<p>Printer: {esc(bed.get('description'))}. {esc(layout)}. "
                    f"Files: {esc(', '.join(pr.get('files', [])))}.</p>")
        if pr.get("note"):
            body.append(f"<p>{esc(pr['note'])}</p>")
        if pr.get("join"):
            body.append(f"<p>Join: {esc(pr['join'])}</p>")
        if pr.get("stl"):
            body.append(f"<p>The STL files: {esc(pr['stl'])}.</p>")
    pics = [n for n in sorted(files) if n.endswith("_print.png")]
    body.append("".join(img(n, files[n], "printed part") for n in pics))
    return f"<section id={ident}><h2>Printed part</h2>" + "".join(body) + "</section>"


def print_bom(report, ident: str = "bom") -> str:
    """The filament and printed parts, and the parts to buy (``""`` when nothing was
    printed)."""
    stl = exporter_report(report.formats, "stl")
    if not stl:
        return ""
    s = stl["settings"]
    return (f"<section id={ident}><h2>Bill of materials</h2>"
            "<table><tr><th>printed part</th><th>quantity</th></tr>"
            f"<tr><td>{esc(s['material'])} filament</td>"
            f"<td>{fmt_value((stl.get('volume_mm3') or 0) / 1000.0)} cm³</td></tr>"
            + (f"<tr><td>printed bars</td><td>{stl['bars']}</td></tr>"
               f"<tr><td>printed pins</td><td>{stl['printed_pins']}</td></tr>"
               if stl["linkage"] == "pins" else
               f"<tr><td>plates</td><td>{stl['plates']}</td></tr>"
               f"<tr><td>hinges</td><td>{stl['hinges']}</td></tr>") + "</table>"
            + _print_buy(stl) + "</section>")


def _print_buy(stl: dict) -> str:
    """The parts a print needs that are not printed (bolts where it is cut), with their size
    and count."""
    buy = (stl.get("print_bom") or {}).get("buy") or []
    if not buy:
        return ""
    rows = "".join(f"<tr><td>{esc(b['part'])}</td><td>{esc(b['standard'])}</td>"
                   f"<td>{esc(b['size'])}</td><td>{b['count']}</td></tr>" for b in buy)
    return ("<table><tr><th>to buy (not printed)</th><th>standard</th><th>size</th>"
            f"<th>count</th></tr>{rows}</table>")


def print_lead(formats: dict) -> list[str]:
    """The print in a few words under "Made for", and the files to print."""
    parts = []
    r = exporter_report(formats, "stl")
    st = r["settings"]
    size = " × ".join(fmt_value(v) for v in r.get("size_mm") or [])
    if r["linkage"] == "pins":
        parts.append(f"<p>Printed in place: {esc(r['bars'])} bars in "
                     f"{esc(r['layers'])} layers on {esc(r['printed_pins'])} "
                     f"printed pins ({esc(st['material'])}), {fmt_value(st['scale'])} mm a "
                     f"design unit, {fmt_value(st['pin_clearance'])} mm pin clearance, "
                     f"{fmt_value(st['clearance'])} mm between bars.</p>")
    else:
        parts.append(f"<p>{esc(r['plates'])} plates joined by "
                     f"{esc(r['hinges'])} hinges ({esc(st['hinge_style'])}, "
                     f"{esc(st['material'])}), {esc(size)} mm.</p>")
    prints = sorted((n for n in formats["stl"].files if n.endswith((".3mf", ".stl"))),
                    key=lambda n: (not n.endswith(".3mf"), n))
    if prints:
        parts.append("<p><b>Start here:</b> " + ", ".join(link(n) for n in prints) + ".</p>")
    return parts
