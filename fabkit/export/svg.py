"""SVG crease patterns a folder can use, in the conventions origami software reads (Origami
Simulator), and a cut-ready variant (:mod:`fabkit.export.svg_cut`).

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
"""

from __future__ import annotations

from xml.sax.saxutils import escape

import numpy as np

from ..numerics import MM_SLACK, TINY
from . import ExportResult

FORMAT = "svg"

#: The process whose plan (:func:`fabkit.fab.creases.plan.origami_plan`) this format is written from.
PROCESS = "origami"
#: The sections of ``--set`` this format reads (any other has no effect on it).
READS = ("origami",)

#: Outline sides equal (and corners right) to this fraction of the longest side make a square.
SHAPE_RTOL = 1e-9
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
NAMES = {"V": "valley", "M": "mountain", "U": "flat", "F": "flat", "B": "edge", "C": "cut"}

_MARGIN = 10.0  # mm around each sheet
_FONT = 3.5  # mm: legend text
_LINE = 5.0  # mm between legend lines
_CORNER_CHAR = 2.4  # mm: width of a character of a 4 mm corner label, at most
#: A turned sheet's box is smaller only by more than this fraction of its area (round-off of
#: the turn is not a better fit).
AREA_RTOL = 1e-9
#: Thread holes of the joins: diameter, and distance in from the corner (mm): the hole ends
#: before the perforations begin (3 mm from the corner) and keeps about 1 mm of paper to the
#: edges of a square corner.
JOIN_HOLE = 1.2
JOIN_INSET = 2.2
#: Room above and below a sheet for its corner labels (mm), and for its title below.
_LABEL_ROOM, _TITLE_ROOM = 7.0, 9.0
#: Mean width of a character of the legend (mm, at :data:`_FONT`), for wrapping.
_LEGEND_CHAR = 0.55 * 3.5


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


def sheet_geometry(pattern, scale: float) -> dict:
    """The paper a sheet is cut from, in mm: its outline's sides, and a name for its shape.

    Returns
    -------
    dict
        ``shape`` ("square", "rectangle" or "polygon"), ``sides_mm`` (outline sides in order),
        ``side_mm`` (a square's side, else None), ``bbox_mm`` (width, height as drawn),
        ``across_mm`` (the longest distance between two corners).
    """
    from ..fab.creases.perforation import outline_loops

    v = np.asarray(pattern.vertices, dtype=np.float64) * scale
    lab = np.asarray(pattern.assignment)
    loops = outline_loops(pattern.edges, np.isin(lab, ["B", "C"]))
    loop = max(loops, key=len)
    p = v[loop]
    sides = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    shape, side = "polygon", None
    if len(loop) == 4:
        d = np.roll(p, -1, axis=0) - p
        right = all(abs(float(np.dot(d[k], d[(k + 1) % 4]))) <= SHAPE_RTOL * sides.max() ** 2
                    for k in range(4))
        if right and np.ptp(sides) <= SHAPE_RTOL * sides.max():
            shape, side = "square", float(sides.mean())
        elif right:
            shape = "rectangle"
    across = max(float(np.linalg.norm(a - b)) for a in p for b in p)
    return {"shape": shape, "sides_mm": [round(float(x), 4) for x in sides],
            "side_mm": None if side is None else round(side, 4),
            "bbox_mm": [round(float(x), 4) for x in np.ptp(v, axis=0)],
            "across_mm": round(across, 4)}


def sheet_text(geom: dict) -> str:
    """The sheet in words: ``"square, side 106.07 mm (150.00 mm corner to corner)"``."""
    if geom["shape"] == "square":
        return (f"square, side {geom['side_mm']:.2f} mm ({geom['across_mm']:.2f} mm corner to "
                "corner)")
    sides = " × ".join(f"{x:.2f}" for x in geom["sides_mm"])
    return f"{geom['shape']}, sides {sides} mm"


def crease_names(pattern) -> list:
    """A name per edge from its vertices' labels: ``"A–P"`` (vertex numbers without labels)."""
    labels = pattern.labels or tuple(str(i) for i in range(pattern.n_vertices))
    return [f"{labels[a]}–{labels[b]}" for a, b in pattern.edges.tolist()]


def crease_table(model, targets) -> list:
    """Every mountain and valley crease of a sheet by name, with its fold angle.

    Returns
    -------
    list of dict
        ``crease``, ``fold`` ("mountain"/"valley"), ``angle_deg`` (its magnitude where it is
        folded most; 0 = flat, 180 = folded flat) and, for several sheets, ``min_deg`` and
        ``max_deg`` over them. One sheet's pattern names the creases (all sheets share it).
    """
    pat = model.sheets[0].pattern
    names = crease_names(pat)
    out = []
    for k, lab in enumerate(pat.assignment):
        if lab not in ("M", "V"):
            continue
        a = np.array([abs(float(t[k])) for t in targets])
        row = {"crease": names[k], "fold": NAMES[lab], "angle_deg": round(float(a.mean()), 2)}
        if len(targets) > 1:
            row.update(min_deg=round(float(a.min()), 2), max_deg=round(float(a.max()), 2))
        out.append(row)
    return out


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
    per_line = max(1, int(width // 62))
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


def _place(pattern, scale, dx, dy):
    """Drawing coordinates (mm, y down) of a sheet's vertices placed at (dx, dy)."""
    v = pattern.vertices
    lo, top = v.min(axis=0), v[:, 1].max()
    return np.stack([dx + (v[:, 0] - lo[0]) * scale, dy + (top - v[:, 1]) * scale], axis=1)


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


def sheet_targets(model, fold) -> list[np.ndarray]:
    """Target fold angle of every edge of every sheet (degrees): where it is folded most."""
    final = fold.target_angles
    index = {tuple(sorted(map(int, e))): k for k, e in enumerate(model.edges.tolist())}
    out = []
    for sh in model.sheets:
        ks = [index[tuple(sorted((int(sh.nodes[a]), int(sh.nodes[b]))))]
              for a, b in sh.pattern.edges.tolist()]
        out.append(final[ks])
    return out


def realised_model(model, fold):
    """The model with every sheet's assignment as the simulated folding realises it
    (:func:`fabkit.fab.creases.folded_assignment`), so that files never contradict their fold
    angles."""
    from dataclasses import replace

    from ..fab.creases import CreasePattern, folded_assignment

    realised = folded_assignment(model, fold)
    index = {tuple(sorted(map(int, e))): k for k, e in enumerate(model.edges.tolist())}
    sheets = []
    for sh in model.sheets:
        pat = sh.pattern
        labs = [realised[index[tuple(sorted((int(sh.nodes[a]), int(sh.nodes[b]))))]]
                for a, b in pat.edges.tolist()]
        sheets.append(replace(sh, pattern=CreasePattern(pat.vertices, pat.edges, labs, pat.faces,
                                                        pat.labels)))
    return replace(model, sheets=tuple(sheets))


def join_numbers(model) -> tuple[list, list]:
    """Number the joins of a chain: every network node that two or more sheets share.

    Returns
    -------
    numbers : list of dict
        Per sheet, {local vertex: join number (1, 2, ...)}.
    joins : list of list of (int, str)
        Per join (in number order), its corners as (sheet number, corner name).
    """
    owners: dict[int, list[tuple[int, int]]] = {}
    for k, sh in enumerate(model.sheets):
        for a, g in enumerate(sh.nodes.tolist()):
            owners.setdefault(int(g), []).append((k, a))
    numbers: list[dict] = [{} for _ in model.sheets]
    joins: list = []
    for k, sh in enumerate(model.sheets):  # numbered in the order the sheets meet them
        for a, g in enumerate(sh.nodes.tolist()):
            corners = owners[int(g)]
            if len(corners) < 2 or a in numbers[k]:
                continue
            joins.append([])
            for j, b in corners:
                numbers[j][b] = len(joins)
                labels = model.sheets[j].pattern.labels or tuple(
                    str(i) for i in range(model.sheets[j].pattern.n_vertices))
                joins[-1].append((j + 1, labels[b]))
    return numbers, joins


def _corner_text(pattern, numbers, a) -> str:
    labels = pattern.labels or tuple(str(i) for i in range(pattern.n_vertices))
    return labels[a] + (f"·{numbers[a]}" if a in numbers else "")


def _wrap(text: str, width_mm: float) -> list:
    import textwrap

    return textwrap.wrap(text, max(20, int(width_mm / _LEGEND_CHAR)))


def _join_legend(x0, y0, width, joins) -> tuple[list, float]:
    """How to join, and the joins of a page (a group); returns (svg, height)."""
    how = (f"JOINS: the corners that carry the same number (·1, ·2, ...) are joined. Lay them "
           f"on one another as their labels say (C·4 on one sheet goes on every other corner "
           f"·4), pass a thread through their {JOIN_HOLE:g} mm holes ({JOIN_INSET:g} mm in from "
           "the corner) and knot it loosely on both sides: the corners must still turn against "
           "each other, so do not glue them. Corner labels: C·4 = corner C of this sheet, at "
           "join 4.")
    listed = "Joins on this page: " + "; ".join(
        f"·{n} = " + " + ".join(f"{k}{c}" for k, c in corners) for n, corners in joins) + "."
    out, y = ['<g id="join-legend">'], y0 + _FONT
    for line in _wrap(how, width) + _wrap(listed, width):
        out.append(f'<text x="{_fmt(x0)}" y="{_fmt(y)}" font-size="{_FONT}" '
                   f'font-family="sans-serif">{escape(line)}</text>')
        y += _LINE
    out.append("</g>")
    return out, y - y0


def _cell(model, numbers) -> tuple[float, float, float]:
    """Width and height of the cell a sheet takes on a page (mm), and the room left and right
    of it for the corner labels (centred on the corners, above and below them)."""
    w, h = np.ptp(model.sheets[0].pattern.vertices, axis=0) * model.scale
    chars = max(len(_corner_text(sh.pattern, numbers[k], a))
                for k, sh in enumerate(model.sheets) for a in range(sh.pattern.n_vertices))
    side = 0.5 * chars * _CORNER_CHAR + 2.0
    return float(w + 2 * side), float(h + 2 * _LABEL_ROOM + _TITLE_ROOM), side


def _page_joins(joins, idx) -> list:
    """The joins (number, corners) that touch the sheets ``idx`` (0-based)."""
    return [(j, corners) for j, corners in enumerate(joins, 1)
            if any(k - 1 in idx for k, _ in corners)]


def pages(model, media, legend_height: float) -> list:
    """The sheets of a chain nested on pages of ``media``, rows of cells under one another,
    the legend (``legend_height`` mm, and the page's joins) below them.

    Returns
    -------
    list of (list of int, list of (float, float))
        Per page, the sheets on it and the (dx, dy) of each sheet's bounding box (mm).

    Raises
    ------
    FabricationError
        A sheet (with its labels, and the legend) does not fit the medium.
    """
    from ..errors import FabricationError

    numbers, joins = join_numbers(model)
    cw, ch, side = _cell(model, numbers)
    width = media.width - 2 * _MARGIN
    cols = int(width // cw)
    n = len(model.sheets)
    laid = None
    for rows in range(int(media.height // ch), 0, -1) if cols >= 1 else []:
        per = cols * rows
        chunks = [list(range(f, min(f + per, n))) for f in range(0, n, per)]
        joins_h = max(_join_legend(0.0, 0.0, width, _page_joins(joins, c))[1] for c in chunks)
        if rows * ch + legend_height + joins_h + 3 * _MARGIN <= media.height:
            laid = (rows, chunks)
            break
    if laid is None:
        raise FabricationError(
            f"a sheet of {cw - 2 * side:.1f} mm, with its corner labels and the legend, needs a "
            f"page of at least {cw + 2 * _MARGIN:.0f} x "
            f"{ch + legend_height + 3 * _MARGIN:.0f} mm; the medium is {media.text()}: choose "
            "a larger one (origami.medium = A3, or WIDTHxHEIGHT in mm) or a smaller "
            "origami.sheet_size")
    left = _MARGIN + 0.5 * (width - cols * cw)  # the grid centred across the page
    return [(idx, [(left + c * cw + side, _MARGIN + r * ch + _LABEL_ROOM)
                   for r, c in (divmod(i, cols) for i in range(len(idx)))])
            for idx in laid[1]]


def upright(model):
    """The model with every sheet turned in its plane so that its flat outline's bounding box
    is the smallest (a square sheet drawn as a diamond is turned square to the page): the
    sheets nest far tighter, and the drawing is the same sheet."""
    from dataclasses import replace

    from ..fab.creases.perforation import outline_loops

    sheets = []
    for sh in model.sheets:
        pat = sh.pattern
        v = np.asarray(pat.vertices, dtype=np.float64)
        loop = max(outline_loops(pat.edges, np.isin(pat.assignment, ["B", "C"])), key=len)
        ring = v[loop]
        sides = np.roll(ring, -1, axis=0) - ring
        best = None
        for ang in np.arctan2(sides[:, 1], sides[:, 0]):
            c, s_ = np.cos(-ang), np.sin(-ang)
            turned = v @ np.array([[c, s_], [-s_, c]])
            area = float(np.prod(np.ptp(turned, axis=0)))
            if best is None or area < best[0] - AREA_RTOL * area:
                best = (area, turned)
        if best is not None and best[0] < (1.0 - AREA_RTOL) * float(np.prod(np.ptp(v, axis=0))):
            pat = replace(pat, vertices=best[1])
        sheets.append(replace(sh, pattern=pat))
    # the same mm per design unit: sheet_size is the larger side of the turned sheets' boxes
    ext = max(float(np.ptp(sh.pattern.vertices, axis=0).max()) for sh in sheets)
    return replace(model, sheets=tuple(sheets), sheet_size=model.scale * ext)


def page_names(name: str, n: int, kind: str) -> list:
    """``NAME_layout.svg`` for page 1, ``NAME_layout_p2.svg`` ... (``kind``: layout, cut)."""
    return [f"{name}_{kind}.svg" if k == 0 else f"{name}_{kind}_p{k + 1}.svg" for k in range(n)]


def join_holes(pattern, numbers, p) -> list:
    """Centres (drawing mm) of the thread holes of a sheet's joined corners: on the bisector
    of the corner, :data:`JOIN_INSET` in from it."""
    from ..fab.creases.perforation import outline_loops

    loop = max(outline_loops(pattern.edges, np.isin(pattern.assignment, ["B", "C"])), key=len)
    at = {v: (loop[i - 1], loop[(i + 1) % len(loop)]) for i, v in enumerate(loop)}
    out = []
    for a in sorted(numbers):
        if a not in at:
            continue  # a joined vertex inside the sheet: no corner to hold
        u = [(p[b] - p[a]) / max(float(np.linalg.norm(p[b] - p[a])), TINY) for b in at[a]]
        ray = u[0] + u[1]
        out.append(p[a] + ray / max(float(np.linalg.norm(ray)), TINY) * JOIN_INSET)
    return out


def render(model, fold) -> tuple[bytes, dict]:
    """The SVG of a model (one sheet, or a layout of all sheets) and a small report.

    Crease colours follow the folding the simulator did (:func:`realised_model`).
    """
    from ..fab.creases.perforation import outline_loops

    model = realised_model(model, fold)
    scale = model.scale
    targets = sheet_targets(model, fold)
    pat0 = model.sheets[0].pattern
    geom = sheet_geometry(pat0, scale)
    table = crease_table(model, targets)
    facts = {"sheet": geom, "creases": table}
    if len(model.sheets) == 1:
        w, h = np.ptp(pat0.vertices, axis=0) * scale
        body = _lines(pat0, targets[0], scale, _MARGIN, _MARGIN)
        n_lines = len(body)
        p = _place(pat0, scale, _MARGIN, _MARGIN)
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
    return _render_pages(model, targets, geom, table, facts)


def _render_pages(model, targets, geom, table, facts):
    """The layout of a chain's sheets: one SVG per page of the medium."""
    from ..fab.creases.media import medium

    model = upright(model)
    media = medium(model.settings.medium)
    numbers, joins = join_numbers(model)
    n = len(model.sheets)
    width = media.width - 2 * _MARGIN
    _, lh = _legend(0.0, 0.0, width, geom, table, n)
    laid = pages(model, media, lh)
    scale = model.scale
    docs, n_lines = [], 0
    for page, (idx, offsets) in enumerate(laid):
        body, angles, holes = [], [], []
        bottom = 0.0
        for k, (dx, dy) in zip(idx, offsets):
            pat = model.sheets[k].pattern
            lines = _lines(pat, targets[k], scale, dx, dy)
            n_lines += len(lines)
            body += lines
            p = _place(pat, scale, dx, dy)
            angles += _angle_labels(pat, targets[k], p, 2.5)
            centre = p.mean(axis=0)
            top, low = float(p[:, 1].min()), float(p[:, 1].max())
            bottom = max(bottom, low + _LABEL_ROOM + _TITLE_ROOM)
            body.append(f'<text x="{_fmt(centre[0])}" y="{_fmt(low + _LABEL_ROOM + 4.5)}" '
                        f'font-size="5" text-anchor="middle" fill="#000000">sheet {k + 1}</text>')
            for a in range(pat.n_vertices):
                x, y = p[a]
                if a in numbers[k]:
                    body.append(f'<circle cx="{_fmt(x)}" cy="{_fmt(y)}" r="1.2" '
                                'fill="#000000"/>')
                elif abs(y - top) > MM_SLACK and abs(y - low) > MM_SLACK:
                    continue  # an inner vertex (P) is named by the legend's creases
                # labels above the top corners and below the bottom ones, centred on them
                ly = y - 3.0 if abs(y - top) <= abs(y - low) else y + 5.5
                body.append(f'<text x="{_fmt(x)}" y="{_fmt(ly)}" font-size="4" '
                            'font-family="sans-serif" text-anchor="middle" fill="#000000">'
                            f'{escape(_corner_text(pat, numbers[k], a))}</text>')
            holes += [f'<circle cx="{_fmt(c[0])}" cy="{_fmt(c[1])}" r="{_fmt(0.5 * JOIN_HOLE)}" '
                      'fill="none" stroke="#000000" stroke-width="0.2"/>'
                      for c in join_holes(pat, numbers[k], p)]
        mine = _page_joins(joins, idx)
        y0 = bottom + 0.5 * _MARGIN
        legend, lh_page = _legend(_MARGIN, y0, width, geom, table, n)
        jlegend, _ = _join_legend(_MARGIN, y0 + lh_page, width, mine)
        body += ['<g id="join-holes">', *holes, "</g>", '<g id="fold-angles">', *angles,
                 "</g>"] + legend + jlegend
        docs.append(_document(media.width, media.height, body,
                              f"{model.name}: layout of {n} sheets, each {sheet_text(geom)}, "
                              f"page {page + 1} of {len(laid)} ({media.text()}, print at "
                              "100 %)"))
    return docs, {"sheets": n, "lines": n_lines, "pages": len(laid), "medium": media.text(),
                  "medium_mm": [media.width, media.height],
                  "sheets_per_page": [len(i) for i, _ in laid],
                  "joins": [{"join": j, "corners": [f"{k}{c}" for k, c in corners]}
                            for j, corners in enumerate(joins, 1)],
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
    and the cut-ready sheet(s) (``<name>_cut.svg``, :mod:`fabkit.export.svg_cut`) of an origami
    plan (:class:`fabkit.fab.creases.plan.OrigamiPlan`)."""
    from ..fab.creases.perforation import Perforation
    from .svg_cut import cut_svg

    design, model, fold = plan.design, plan.model, plan.fold
    data, report = render(model, fold)
    perf = Perforation.from_settings(model.settings)
    realised = realised_model(model, fold)
    if len(model.sheets) == 1:
        name = f"{design.name}.svg"
        w, h = np.ptp(model.sheets[0].pattern.vertices, axis=0) * model.scale
        cut, cut_report = cut_svg(realised, perf, [(_MARGIN, _MARGIN)],
                                  (w + 2 * _MARGIN, h + 2 * _MARGIN))
        cut_name = f"{design.name}_cut.svg"
        files = {name: data, cut_name: cut}
    else:
        from dataclasses import replace

        from ..fab.creases.media import medium

        media = medium(model.settings.medium)
        realised = upright(realised)
        turned = upright(model)
        numbers, _ = join_numbers(turned)
        geom = sheet_geometry(turned.sheets[0].pattern, turned.scale)
        table = crease_table(turned, sheet_targets(turned, fold))
        width = media.width - 2 * _MARGIN
        _, lh = _legend(0.0, 0.0, width, geom, table, len(model.sheets))
        laid = pages(turned, media, lh)
        names = page_names(design.name, len(laid), "layout")
        cut_names = page_names(design.name, len(laid), "cut")
        files, cut_report = dict(zip(names, data)), None
        for (idx, offsets), cut_name in zip(laid, cut_names):
            sub = replace(realised, sheets=tuple(realised.sheets[k] for k in idx))
            holes = [join_holes(realised.sheets[k].pattern, numbers[k],
                                _place(realised.sheets[k].pattern, turned.scale, dx, dy))
                     for k, (dx, dy) in zip(idx, offsets)]
            cut, rep = cut_svg(sub, perf, offsets, (media.width, media.height),
                               holes=holes, hole=JOIN_HOLE)
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
    vals = [v for v in (a["closest_cut_to_a_vertex_mm"], b["closest_cut_to_a_vertex_mm"])
            if v is not None]
    out["closest_cut_to_a_vertex_mm"] = min(vals) if vals else None
    return out
