"""The files of a design folder: what each is, why a format wrote none, the table of every file
and the exports whose formats the folder holds."""

from __future__ import annotations

import re

from .common import esc, link


#: What each file of a design folder is, by name (first match).
FILE_ROLES = (
    (r"laser_guide\.pdf", "assembly guide: A4 pages to print and follow at the bench"),
    (r"laser_guide_page1\.png", "the assembly guide's first page (overview)"),
    (r".*coupon.*", "test coupon: cut it first to check kerf and fit"),
    (r"laser_sheet(\d+)\.dxf", "sheet {0} to cut (DXF, mm)"),
    (r"laser_sheet(\d+)\.svg", "sheet {0} to cut (SVG for laser programs, mm)"),
    (r"laser_bom\.md", "bill of materials (to read)"),
    (r"laser_bom\.json", "bill of materials (data)"),
    (r"print_bom\.md", "print bill of materials: beds, parts, filament, bolts (to read)"),
    (r"print_bom\.json", "print bill of materials (data)"),
    (r"laser_assembly\.png", "picture: the kit by layer, in rows"),
    (r"laser_layers_motion\.png", "picture: the motion test with the layers"),
    (r".*_cut\.svg", "cut-ready sheet: perforated creases and the outline (laser or vinyl cutter)"),
    (r".*_layout\.svg", "crease patterns of every sheet and how they join (to print and fold)"),
    (r".*\.svg", "crease pattern (to print and fold; Origami Simulator reads it)"),
    (r".*\.fold", "FOLD file with the simulated folding"),
    (r".*\.cp", "ORIPA crease pattern"),
    (r".*\.3mf", "3D print with its settings (3MF)"),
    (r".*\.stl", "3D print (STL)"),
    (r".*_print\.png", "picture: the printed part"),
    (r"preview_motion\.png", "picture: the motion"),
    (r"preview_map\.png", "picture: the map and cobweb"),
    (r"preview_tolerance\.png", "picture: the tolerance analysis"),
    (r"report\.json", "this report as data"),
    (r"report\.md", "this report as text"),
    (r"exports\.json", "which export made each format's files, and how (read by the next export)"),
)


def describe_file(name: str) -> str:
    """What a file of a design folder is (``""`` when fabkit does not know the name)."""
    for pattern, text in FILE_ROLES:
        m = re.fullmatch(pattern, name)
        if m:
            return text.format(*m.groups())
    return ""


def not_exported(formats: dict) -> list:
    """Why each format that was tried wrote nothing: ``["dxf: skipped by the template – …"]``.

    Parameters
    ----------
    formats : dict of str to FormatResult
    """
    out, never = [], []
    for fmt, f in sorted(formats.items()):
        if f.status.value == "does not apply":
            never.append(f"{fmt}: does not apply")  # said only when nothing else explains it
        elif not f.status.produced:
            out.append(f"{fmt}: {f.status}" + (f" – {f.message}" if f.message else ""))
    return out or never


def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else (f"{n / 1e3:.0f} kB" if n >= 1e3 else f"{n} B")


def files_section(listing: dict, process: str | None) -> str:
    """The Files section: every file of the folder, the process's own first, with its size
    and what it is."""
    def rank(name):
        if name.startswith(("report.", "preview_")):
            return 3
        owner = ("laser" if name.startswith("laser_") else
                 "print" if name.endswith((".stl", ".3mf", "_print.png")) else "origami")
        return 0 if owner == process else (1 if name != "report.html" else 2)

    rows = "".join(f"<tr><td>{link(n)}</td><td class=nowrap>{_size(listing[n])}</td>"
                   f"<td>{esc(describe_file(n))}</td></tr>"
                   for n in sorted(listing, key=lambda n: (rank(n), n)) if n != "report.html")
    return ("<section id=files><h2>Files</h2><p>Every file written for this design, next to this "
            'page.</p><div class="scroll"><table><tr><th>file</th><th>size</th><th>what it is'
            "</th></tr>" + rows + "</table></div></section>")


def _kept_word(report, fmt: str) -> str:
    f = report.formats.get(fmt)
    return "kept, checked again" if f is not None and f.checks else "kept"


def exports_section(report) -> str:
    """Which export made each format's files in the folder, when and with what settings, and
    the stale formats removed (:mod:`fabkit.pipeline.manifest`)."""
    if not report.origins and not report.removed:
        return ""
    kept = report.kept
    rows = "".join(
        f"<tr><td>{esc(f)}</td><td>{o.export}</td><td class=nowrap>{esc(o.when)} UTC</td>"
        f"<td>{esc(o.line().split('settings: ', 1)[1])}</td>"
        f"<td>{_kept_word(report, f) if f in kept else 'made now'}</td></tr>"
        for f, o in sorted(report.origins.items()))
    gone = "".join(f"<li>{esc(r)}</li>" for r in report.removed)
    return ("<section id=exports><h2>Exports in this folder</h2><p>A later export adds its "
            "formats to those already here; an earlier format stays while it was made from the "
            "same design, settings and fabkit version.</p><div class=\"scroll\"><table><tr>"
            "<th>format</th><th>export</th><th>when</th><th>settings</th><th>here</th></tr>"
            + rows + "</table></div>" + (f"<p>Removed (stale):</p><ul>{gone}</ul>" if gone
                                         else "") + "</section>")
