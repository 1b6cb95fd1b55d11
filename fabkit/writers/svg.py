"""SVG crease patterns a folder can use, in the conventions origami software reads (Origami
Simulator), and a cut-ready variant (:mod:`fabkit.writers.svg_cut`).

Every crease or boundary segment is one ``<line>`` that is a direct child of ``<svg>`` (no
transforms), in mm. Stroke colour: black boundary, red (#ff0000) mountain, blue (#0000ff)
valley, green (#00ff00) cut, yellow (#ffff00) flat/facet, magenta (#ff00ff) unassigned.
``stroke-opacity`` = |target fold angle| / 180° on mountain and valley creases (the angle where
the crease is folded most along the simulated motion), 1 elsewhere; ``opacity`` is never set
(the two multiply). Mountain and valley differ by line style too, so they read apart in black
and white: valley dashed (:data:`DASHES`), mountain dash-dot, the boundary solid (Origami
Simulator ignores dash patterns). The pattern is drawn as seen from the side its faces face
(+z), y up.

What a folder needs and a simulator must not read is in groups (Origami Simulator reads only
direct children of ``<svg>``): the legend (line styles, the sheet's side length, the fold angle
of every crease by name), a dimension along the sheet's longest side and each crease's angle
beside it.

A design of several sheets (a chain) gets a printable layout instead: every sheet drawn
separately, nested in a grid on pages of the medium (``origami.medium``: A4 by default, Letter,
or a laser's bed or a cutter's width in mm, :mod:`fabkit.fab.creases.media`), as many pages as
it takes (``NAME_layout.svg``, ``NAME_layout_p2.svg``, ...; the cut files alike). Every join
(the corners of neighbouring sheets that meet) has a number: a corner is labelled with its
name and its join (``C·4``), a 1.5 mm thread hole is drawn (and cut) 3 mm in from it, and each
page's legend says how to join (a thread through the holes of the corners of one number,
knotted loosely, so that they still turn) and lists its joins (``·4 = 2C + 3B + 4A``).

Settings (``[fabrication.origami]``, overridable as ``origami.<key>``): ``sheet_size`` (mm, the
larger side of one sheet's flat bounding box, default 150), ``samples``, ``branch``, ``sign``,
``medium``.

What goes where (the realised assignment, the fold angles, which sheet on which page, the join
numbers and holes) is decided by the origami plan (:mod:`fabkit.fab.creases.layout`); this
module only draws it.
"""

from __future__ import annotations

from xml.sax.saxutils import escape

import numpy as np

from ..fab.creases import layout
from ..fab.creases.layout import corner_text, page_names, place
from ..numerics import MM_SLACK, TINY
from . import ExportResult

FORMAT = "svg"

#: The process whose plan (:func:`fabkit.fab.creases.plan.origami_plan`) this format is written from.
PROCESS = "origami"
#: The sections of ``--set`` this format reads (any other has no effect on it).
READS = ("origami",)

#: Sheets of a chain whose fold angles for one crease differ by less than this (degrees) are
#: given one angle in the legend.
ANGLE_SPREAD_DEG = 0.05

#: Stroke colour of each FOLD assignment (Origami Simulator's import colours).
COLOURS = {"B": "#000000", "M": "#ff0000", "V": "#0000ff", "C": "#00ff00", "F": "#ffff00",
           "U": "#ff00ff", "J": "#ff00ff"}

#: Dash patterns (mm) by assignment: valley dashed, mountain dash-dot (the folding diagrams'
#: convention); others solid.
DASHES = {"V": "4 2", "M": "4 1.5 0.8 1.5"}
#: What each assignment means to a folder.
MEANING = {"V": "valley fold (dashed): the sides come up towards you",
           "M": "mountain fold (dash-dot): the sides go away from you",
           "B": "edge of the sheet", "C": "cut", "F": "flat (do not fold)",
           "U": "unassigned crease"}
NAMES = layout.NAMES

_MARGIN, _FONT, _LINE = layout.MARGIN, layout.FONT, layout.LINE
_LABEL_ROOM, _TITLE_ROOM = layout.LABEL_ROOM, layout.TITLE_ROOM
#: Thread holes of the joins: diameter, and distance in from the corner (mm), as planned
#: (:mod:`fabkit.fab.creases.layout`).
JOIN_HOLE, JOIN_INSET = layout.JOIN_HOLE, layout.JOIN_INSET


#: Why the format does not apply, when :func:`applies` says so (reported by ``--to svg``).
NOT_APPLICABLE = ("a crease pattern needs a [fabrication.origami] table (mountain/valley "
                  "assignment); this design has none: cut it (dxf) or print it (stl)")


def applies(design) -> bool:
    """True when the template has a ``[fabrication.origami]`` table."""
    fab = getattr(design, "fabrication", None)
    return isinstance(fab, dict) and isinstance(fab.get("origami"), dict)


def _fmt(v: float) -> str:
    return f"{v:.4f}".rstrip("0").rstrip(".")


def _lines(pattern, target, scale, dx, dy):
    """SVG <line> elements of one sheet placed with its bounding box at (dx, dy) (mm)."""
    v = pattern.vertices
    lo = v.min(axis=0)
    top = v[:, 1].max()
    out = []
    for k, (a, b) in enumerate(pattern.edges.tolist()):
        lab = pattern.assignment[k]
        p, q = v[a], v[b]
        x1, y1 = dx + (p[0] - lo[0]) * scale, dy + (top - p[1]) * scale
        x2, y2 = dx + (q[0] - lo[0]) * scale, dy + (top - q[1]) * scale
        op = min(abs(float(target[k])) / 180.0, 1.0) if lab in ("M", "V") else 1.0
        dash = f' stroke-dasharray="{DASHES[lab]}"' if lab in DASHES else ""
        out.append(f'<line x1="{_fmt(x1)}" y1="{_fmt(y1)}" x2="{_fmt(x2)}" y2="{_fmt(y2)}" '
                   f'stroke="{COLOURS[lab]}" stroke-opacity="{_fmt(op)}" stroke-width="0.5"'
                   f'{dash} fill="none"/>')
    return out


def sheet_text(geom: dict) -> str:
    """The sheet in words: ``"square, side 106.07 mm (150.00 mm corner to corner)"``."""
    if geom["shape"] == "square":
        return (f"square, side {geom['side_mm']:.2f} mm ({geom['across_mm']:.2f} mm corner to "
                "corner)")
    sides = " × ".join(f"{x:.2f}" for x in geom["sides_mm"])
    return f"{geom['shape']}, sides {sides} mm"


def _legend(x0, y0, width, geom, table, sheets: int):
    """The legend (a group) with its top-left corner at (x0, y0); returns (svg, height)."""
    out = ['<g id="legend">']
    y = y0 + _FONT
    for lab in ("B", "V", "M"):
        dash = f' stroke-dasharray="{DASHES[lab]}"' if lab in DASHES else ""
        text = MEANING[lab] + (": cut along it" if lab == "B" else "")
        out.append(f'<line x1="{_fmt(x0)}" y1="{_fmt(y - 1.2)}" x2="{_fmt(x0 + 14)}" '
                   f'y2="{_fmt(y - 1.2)}" stroke="{COLOURS[lab]}" stroke-width="0.5"{dash}/>'
                   f'<text x="{_fmt(x0 + 17)}" y="{_fmt(y)}" font-size="{_FONT}" '
                   f'font-family="sans-serif">{escape(text)}</text>')
        y += _LINE
    each = f"{sheets} sheets, each " if sheets > 1 else "Sheet: "
    out.append(f'<text x="{_fmt(x0)}" y="{_fmt(y)}" font-size="{_FONT}" font-family="sans-serif" '
               f'font-weight="bold">{escape(each + sheet_text(geom))}</text>')
    y += _LINE
    out.append(f'<text x="{_fmt(x0)}" y="{_fmt(y)}" font-size="{_FONT}" '
               'font-family="sans-serif">Fold angles, seen from this side (0° flat, 180° '
               'folded flat):</text>')
    y += _LINE
    per_line = max(1, int(width // layout.LEGEND_ENTRY))
    for k in range(0, len(table), per_line):
        parts = []
        for row in table[k:k + per_line]:
            ang = f"{row['angle_deg']:.1f}°"
            if "min_deg" in row and row["max_deg"] - row["min_deg"] >= ANGLE_SPREAD_DEG:
                ang = f"{row['min_deg']:.1f}-{row['max_deg']:.1f}°"
            parts.append(f"{row['crease']} {row['fold']} {ang}")
        out.append(f'<text x="{_fmt(x0 + 4)}" y="{_fmt(y)}" font-size="{_FONT}" '
                   f'font-family="sans-serif" xml:space="preserve">'
                   f'{escape("    ".join(parts))}</text>')
        y += _LINE
    out.append("</g>")
    return out, y - y0


def _angle_labels(pattern, target, p, size):
    """Each crease's fold angle beside it, along it (text elements)."""
    out = []
    for k, (a, b) in enumerate(pattern.edges.tolist()):
        lab = pattern.assignment[k]
        if lab not in ("M", "V"):
            continue
        d = p[b] - p[a]
        ang = float(np.degrees(np.arctan2(d[1], d[0])))
        if ang > 90 or ang <= -90:  # keep the text upright
            ang -= 180 if ang > 0 else -180
        n = np.array([-d[1], d[0]]) / max(float(np.linalg.norm(d)), TINY)
        c = 0.5 * (p[a] + p[b]) + n * 1.1 * size
        out.append(f'<text x="{_fmt(c[0])}" y="{_fmt(c[1])}" font-size="{_fmt(size)}" '
                   f'font-family="sans-serif" text-anchor="middle" dominant-baseline="central" '
                   f'fill="{COLOURS[lab]}" '
                   f'transform="rotate({_fmt(ang)} {_fmt(c[0])} {_fmt(c[1])})">'
                   f'{NAMES[lab][0].upper()} {abs(float(target[k])):.0f}°</text>')
    return out


def _vertex_labels(pattern, p, size):
    """Each vertex's label (the names the legend's creases use) beside it (text elements)."""
    labels = pattern.labels or tuple(str(i) for i in range(pattern.n_vertices))
    centre = p.mean(axis=0)
    out = []
    for a, q in enumerate(p):
        ray = q - centre
        nrm = float(np.linalg.norm(ray))
        off = ray / nrm * 1.6 * size if nrm > 0 else np.array([0.0, -1.6 * size])
        if nrm > 0 and nrm < 0.5 * float(np.abs(p - centre).max()):  # inside: beside it
            off = np.array([1.3 * size, -1.0 * size])
        c = q + off
        out.append(f'<text x="{_fmt(c[0])}" y="{_fmt(c[1])}" font-size="{_fmt(size)}" '
                   'font-family="sans-serif" font-weight="bold" text-anchor="middle" '
                   f'dominant-baseline="central">{escape(labels[a])}</text>')
    return out


def _dimension(geom_p, loop, size):
    """A dimension line along the sheet's longest outline side, outside it (a group)."""
    p = geom_p[loop]
    q = np.roll(p, -1, axis=0)
    k = int(np.argmax(np.linalg.norm(q - p, axis=1)))
    a, b = p[k], q[k]
    centre = p.mean(axis=0)
    d = b - a
    length = float(np.linalg.norm(d))
    n = np.array([-d[1], d[0]]) / length
    if np.dot(0.5 * (a + b) - centre, n) < 0:
        n = -n
    a2, b2 = a + n * 4.0, b + n * 4.0
    ang = float(np.degrees(np.arctan2(d[1], d[0])))
    if ang > 90 or ang <= -90:
        ang -= 180 if ang > 0 else -180
    c = 0.5 * (a2 + b2) + n * 1.2
    ticks = "".join(f'<line x1="{_fmt(e[0] + n[0])}" y1="{_fmt(e[1] + n[1])}" '
                    f'x2="{_fmt(e[0] + 5 * n[0])}" y2="{_fmt(e[1] + 5 * n[1])}" '
                    'stroke="#555555" stroke-width="0.25"/>' for e in (a, b))
    return ['<g id="dimensions">', ticks,
            f'<line x1="{_fmt(a2[0])}" y1="{_fmt(a2[1])}" x2="{_fmt(b2[0])}" y2="{_fmt(b2[1])}" '
            'stroke="#555555" stroke-width="0.25"/>',
            f'<text x="{_fmt(c[0])}" y="{_fmt(c[1])}" font-size="{_fmt(size)}" '
            'font-family="sans-serif" text-anchor="middle" fill="#555555" '
            f'transform="rotate({_fmt(ang)} {_fmt(c[0])} {_fmt(c[1])})">{length:.2f} mm</text>',
            "</g>"]


def _document(width, height, body, title):
    head = ('<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{_fmt(width)}mm" '
            f'height="{_fmt(height)}mm" viewBox="0 0 {_fmt(width)} {_fmt(height)}">\n'
            f'<title>{escape(title)}</title>\n')
    return (head + "\n".join(body) + "\n</svg>\n").encode("utf-8")


def _join_legend(x0, y0, width, joins) -> tuple[list, float]:
    """How to join, and the joins of a page (a group); returns (svg, height)."""
    out, y = ['<g id="join-legend">'], y0 + _FONT
    for line in layout.join_legend_lines(joins, width):
        out.append(f'<text x="{_fmt(x0)}" y="{_fmt(y)}" font-size="{_FONT}" '
                   f'font-family="sans-serif">{escape(line)}</text>')
        y += _LINE
    out.append("</g>")
    return out, y - y0


def render(plan) -> tuple[bytes | list, dict]:
    """The SVG of an origami plan's crease layout (one sheet, or one page per page of the
    layout of all sheets) and a small report. Crease colours follow the folding the simulator
    did (the layout's realised model)."""
    from ..fab.creases.perforation import outline_loops

    lay = plan.layout
    model = lay.realised
    scale = model.scale
    targets, geom, table = lay.targets, lay.sheet, list(lay.creases)
    pat0 = model.sheets[0].pattern
    facts = {"sheet": geom, "creases": table}
    if lay.chain:
        return _render_pages(lay, facts)
    w, h = np.ptp(pat0.vertices, axis=0) * scale
    body = _lines(pat0, targets[0], scale, _MARGIN, _MARGIN)
    n_lines = len(body)
    p = place(pat0, scale, _MARGIN, _MARGIN)
    body += ['<g id="fold-angles">', *_angle_labels(pat0, targets[0], p, 3.0), "</g>",
             '<g id="vertex-labels">', *_vertex_labels(pat0, p, 4.0), "</g>"]
    loop = max(outline_loops(pat0.edges, np.isin(pat0.assignment, ["B", "C"])), key=len)
    body += _dimension(p, loop, 3.0)
    width = w + 2 * _MARGIN
    legend, lh = _legend(_MARGIN, h + 2 * _MARGIN, width - 2 * _MARGIN, geom, table, 1)
    data = _document(width, h + 3 * _MARGIN + lh, body + legend,
                     f"{model.name}: crease pattern, {sheet_text(geom)}")
    return data, {"sheets": 1, "lines": n_lines, "width_mm": float(width),
                  "height_mm": float(h + 3 * _MARGIN + lh), **facts}


def _sheet_drawing(pat, target, k, numbers, scale, offset) -> tuple[list, list, float]:
    """One sheet of a page: its lines, title, joined corners and labels; its fold angles; the
    bottom of its title (mm)."""
    dx, dy = offset
    body = _lines(pat, target, scale, dx, dy)
    p = place(pat, scale, dx, dy)
    angles = _angle_labels(pat, target, p, 2.5)
    centre = p.mean(axis=0)
    top, low = float(p[:, 1].min()), float(p[:, 1].max())
    body.append(f'<text x="{_fmt(centre[0])}" y="{_fmt(low + _LABEL_ROOM + 4.5)}" '
                f'font-size="5" text-anchor="middle" fill="#000000">sheet {k + 1}</text>')
    for a in range(pat.n_vertices):
        x, y = p[a]
        if a in numbers:
            body.append(f'<circle cx="{_fmt(x)}" cy="{_fmt(y)}" r="1.2" fill="#000000"/>')
        elif abs(y - top) > MM_SLACK and abs(y - low) > MM_SLACK:
            continue  # an inner vertex (P) is named by the legend's creases
        # labels above the top corners and below the bottom ones, centred on them
        ly = y - 3.0 if abs(y - top) <= abs(y - low) else y + 5.5
        body.append(f'<text x="{_fmt(x)}" y="{_fmt(ly)}" font-size="4" '
                    'font-family="sans-serif" text-anchor="middle" fill="#000000">'
                    f'{escape(corner_text(pat, numbers, a))}</text>')
    return body, angles, low + _LABEL_ROOM + _TITLE_ROOM


def _render_pages(lay, facts):
    """The layout of a chain's sheets: one SVG per page of the medium."""
    model, media, geom, table = lay.drawn, lay.medium, lay.sheet, list(lay.creases)
    n = len(model.sheets)
    width = media.width - 2 * _MARGIN
    scale = model.scale
    docs, n_lines = [], 0
    for number, page in enumerate(lay.pages):
        body, angles, holes = [], [], []
        bottom = 0.0
        for sheet in page.sheets:
            k = sheet.sheet
            lines, more, low = _sheet_drawing(model.sheets[k].pattern, lay.targets[k], k,
                                              lay.numbers[k], scale, sheet.offset)
            n_lines += sum(1 for line in lines if line.startswith("<line"))
            body += lines
            angles += more
            bottom = max(bottom, low)
            holes += [f'<circle cx="{_fmt(c[0])}" cy="{_fmt(c[1])}" r="{_fmt(0.5 * JOIN_HOLE)}" '
                      'fill="none" stroke="#000000" stroke-width="0.2"/>' for c in sheet.holes]
        y0 = bottom + 0.5 * _MARGIN
        legend, lh_page = _legend(_MARGIN, y0, width, geom, table, n)
        jlegend, _ = _join_legend(_MARGIN, y0 + lh_page, width, list(page.joins))
        body += ['<g id="join-holes">', *holes, "</g>", '<g id="fold-angles">', *angles,
                 "</g>"] + legend + jlegend
        docs.append(_document(media.width, media.height, body,
                              f"{model.name}: layout of {n} sheets, each "
                              f"{sheet_text(geom)}, page {number + 1} of "
                              f"{len(lay.pages)} ({media.text()}, print at 100 %)"))
    return docs, {"sheets": n, "lines": n_lines, "pages": len(lay.pages),
                  "medium": media.text(), "medium_mm": [media.width, media.height],
                  "sheets_per_page": [len(p.sheets) for p in lay.pages],
                  "joins": [{"join": j, "corners": [f"{k}{c}" for k, c in corners]}
                            for j, corners in enumerate(lay.joins, 1)],
                  "join_method": f"thread through {JOIN_HOLE:g} mm holes {JOIN_INSET:g} mm in "
                                 "from the joined corners, knotted loosely",
                  "width_mm": float(media.width), "height_mm": float(media.height), **facts}


def export_design(design, settings: dict | None = None, *, motion=None) -> ExportResult:
    """The crease pattern files of a design: its origami plan, written (see :func:`write`).

    Raises
    ------
    FabricationError
        No [fabrication.origami] table, bad settings, or a folding the simulator cannot do.
    """
    from ..fab.plans import make_plan

    return write(make_plan(PROCESS, design, settings, motion))


def write(plan) -> ExportResult:
    """Crease pattern SVG (``<name>.svg``, or the layout of all sheets ``<name>_layout.svg``)
    and the cut-ready sheet(s) (``<name>_cut.svg``, :mod:`fabkit.writers.svg_cut`) of an origami
    plan (:class:`fabkit.fab.creases.plan.OrigamiPlan`): its layout, drawn."""
    from dataclasses import replace

    from ..fab.creases.perforation import Perforation
    from .svg_cut import cut_svg

    design, model, lay = plan.design, plan.model, plan.layout
    data, report = render(plan)
    perf = Perforation.from_settings(model.settings)
    if not lay.chain:
        name, cut_name = f"{design.name}.svg", f"{design.name}_cut.svg"
        cut, cut_report = cut_svg(lay.realised, perf, lay.pages[0].offsets, lay.size)
        files = {name: data, cut_name: cut}
    else:
        names = page_names(design.name, len(lay.pages), "layout")
        cut_names = page_names(design.name, len(lay.pages), "cut")
        files, cut_report = dict(zip(names, data)), None
        for page, cut_name in zip(lay.pages, cut_names):
            sub = replace(lay.drawn, sheets=tuple(lay.drawn.sheets[k] for k in page.indices))
            cut, rep = cut_svg(sub, perf, page.offsets, lay.size,
                               holes=[list(s.holes) for s in page.sheets], hole=JOIN_HOLE,
                               numbers=[lay.numbers[k] for k in page.indices],
                               sheet_numbers=[k + 1 for k in page.indices])
            files[cut_name] = cut
            cut_report = rep if cut_report is None else _merge_cut(cut_report, rep)
        name, cut_name = names[0], cut_names[0]
        report.update(layout_files=names, cut_files=cut_names)
    report.update(format=FORMAT, sheet_size_mm=model.sheet_size, file=name, cut_file=cut_name,
                  cut=cut_report)
    return ExportResult(files=files, report=report)


def _merge_cut(a: dict, b: dict) -> dict:
    """The cut report of two pages as one."""
    out = dict(a)
    out["cuts"] = {k: a["cuts"].get(k, 0) + b["cuts"].get(k, 0) for k in {*a["cuts"], *b["cuts"]}}
    out["short_creases"] = a["short_creases"] + b["short_creases"]
    out["marks"] = a["marks"] + b["marks"]
    vals = [v for v in (a["closest_cut_to_a_vertex_mm"], b["closest_cut_to_a_vertex_mm"])
            if v is not None]
    out["closest_cut_to_a_vertex_mm"] = min(vals) if vals else None
    return out
