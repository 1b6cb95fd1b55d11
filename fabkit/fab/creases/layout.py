"""What the origami writers draw, decided once in the origami plan: every sheet's realised
assignment and fold angles, its paper, its crease table, and for a chain of sheets the joins
(which corners meet, their numbers, their thread holes) and the pages of the medium each sheet
goes on (:func:`crease_layout`).

The crease SVG and its cut sheets (:mod:`fabkit.writers.svg`, :mod:`fabkit.writers.svg_cut`) only
draw this layout. The sizes of the legend's text (:data:`FONT`, :data:`LINE`, the wrapping width)
are here because a page holds as many sheets as leave room for its legend; the writer draws the
legend with the same sizes and the same words (:func:`join_legend_lines`).
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, replace

import numpy as np

from ...errors import FabricationError
from ...numerics import TINY
from .folding import folded_assignment
from .media import medium
from .pattern import CreasePattern
from .perforation import outline_loops

__all__ = ["SheetLayout", "PageLayout", "CreaseLayout", "crease_layout", "sheet_geometry",
           "crease_names", "crease_table", "sheet_targets", "realised_model", "join_numbers",
           "corner_text", "upright", "join_holes", "place", "legend_lines", "legend_height",
           "join_legend_lines", "text_height", "page_joins", "pages", "page_names", "wrap"]

#: Outline sides equal (and corners right) to this fraction of the longest side make a square.
SHAPE_RTOL = 1e-9
#: A turned sheet's box is smaller only by more than this fraction of its area (round-off of
#: the turn is not a better fit).
AREA_RTOL = 1e-9
#: What each mountain/valley assignment is called in the crease table.
NAMES = {"V": "valley", "M": "mountain", "U": "flat", "F": "flat", "B": "edge", "C": "cut"}

#: Margin around each sheet and around a page's contents (mm).
MARGIN = 10.0
#: Legend text size and the distance between its lines (mm).
FONT = 3.5
LINE = 5.0
#: Width of a character of a 4 mm corner label, at most (mm).
CORNER_CHAR = 2.4
#: Room above and below a sheet for its corner labels (mm), and for its title below.
LABEL_ROOM, TITLE_ROOM = 7.0, 9.0
#: Mean width of a character of the legend (mm, at :data:`FONT`), for wrapping.
LEGEND_CHAR = 0.55 * 3.5
#: Width of one "crease fold angle" entry of the legend (mm): as many go on a line as fit.
LEGEND_ENTRY = 62
#: Lines of the legend above its crease list: the three line styles, the sheet, the heading.
LEGEND_HEAD = 5
#: Thread holes of the joins: diameter, and distance in from the corner (mm): the hole ends
#: before the perforations begin (3 mm from the corner) and keeps about 1 mm of paper to the
#: edges of a square corner.
JOIN_HOLE = 1.2
JOIN_INSET = 2.2


@dataclass(frozen=True)
class SheetLayout:
    """One sheet on a page.

    Attributes
    ----------
    sheet : int
        The sheet (0-based).
    offset : (float, float)
        Where its bounding box's top-left corner goes on the page (mm, y down).
    holes : tuple of (float, float)
        Centres of its joins' thread holes on the page (mm).
    """

    sheet: int
    offset: tuple
    holes: tuple = ()


@dataclass(frozen=True)
class PageLayout:
    """One page of the medium: its sheets and the joins that touch them.

    Attributes
    ----------
    sheets : tuple of SheetLayout
    joins : tuple of (int, tuple of (int, str))
        The joins of the page by number, each with its corners (sheet number, corner name).
    """

    sheets: tuple
    joins: tuple

    @property
    def indices(self) -> list:
        """The sheets on the page (0-based)."""
        return [s.sheet for s in self.sheets]

    @property
    def offsets(self) -> list:
        return [s.offset for s in self.sheets]


@dataclass(frozen=True, eq=False)
class CreaseLayout:
    """What the crease SVG and its cut sheets draw (see the module docstring).

    Attributes
    ----------
    assignment : tuple of str
        The assignment of every paper edge of the model as the folding realises it
        (:func:`~fabkit.fab.creases.folded_assignment`): what the FOLD and .cp files write.
    realised : OrigamiModel
        The model with every sheet's assignment as the folding realises it
        (:func:`realised_model`).
    targets : tuple of numpy.ndarray
        Per sheet, the target fold angle of each of its edges (degrees, :func:`sheet_targets`).
    sheet : dict
        The paper of one sheet (:func:`sheet_geometry`).
    creases : tuple of dict
        Every mountain and valley crease with its fold angle (:func:`crease_table`).
    drawn : OrigamiModel
        The model as drawn: ``realised``, or for a chain its sheets turned upright
        (:func:`upright`).
    medium : Medium or None
        The medium a chain is laid out on (None for one sheet).
    numbers : tuple of dict
        Per sheet, {local vertex: join number} (empty for one sheet).
    joins : tuple of (int, str) tuples
        Per join (in number order), its corners (sheet number, corner name).
    pages : tuple of PageLayout
        The pages (one sheet: one page holding it at (:data:`MARGIN`, :data:`MARGIN`)).
    size : (float, float)
        Width and height of a page of the cut file (mm).
    """

    assignment: tuple
    realised: object
    targets: tuple
    sheet: dict
    creases: tuple
    drawn: object
    medium: object
    numbers: tuple
    joins: tuple
    pages: tuple
    size: tuple

    @property
    def chain(self) -> bool:
        return len(self.realised.sheets) > 1


def sheet_geometry(pattern, scale: float) -> dict:
    """The paper a sheet is cut from, in mm: its outline's sides, and a name for its shape.

    Returns
    -------
    dict
        ``shape`` ("square", "rectangle" or "polygon"), ``sides_mm`` (outline sides in order),
        ``side_mm`` (a square's side, else None), ``bbox_mm`` (width, height as drawn),
        ``across_mm`` (the longest distance between two corners).
    """
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


def _edge_index(model) -> dict:
    return {tuple(sorted(map(int, e))): k for k, e in enumerate(model.edges.tolist())}


def sheet_targets(model, fold) -> list[np.ndarray]:
    """Target fold angle of every edge of every sheet (degrees): where it is folded most."""
    final = fold.target_angles
    index = _edge_index(model)
    out = []
    for sh in model.sheets:
        ks = [index[tuple(sorted((int(sh.nodes[a]), int(sh.nodes[b]))))]
              for a, b in sh.pattern.edges.tolist()]
        out.append(final[ks])
    return out


def realised_model(model, fold, assignment=None):
    """The model with every sheet's assignment as the simulated folding realises it
    (:func:`fabkit.fab.creases.folded_assignment`, or ``assignment`` when given: the same), so
    that files never contradict their fold angles."""
    realised = folded_assignment(model, fold) if assignment is None else assignment
    index = _edge_index(model)
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


def corner_text(pattern, numbers, a) -> str:
    """A corner's label: its name and its join (``C·4``)."""
    labels = pattern.labels or tuple(str(i) for i in range(pattern.n_vertices))
    return labels[a] + (f"·{numbers[a]}" if a in numbers else "")


def wrap(text: str, width_mm: float) -> list:
    """``text`` in lines of the legend ``width_mm`` wide."""
    return textwrap.wrap(text, max(20, int(width_mm / LEGEND_CHAR)))


def legend_lines(table, width: float) -> int:
    """Lines the crease list of the legend takes (:data:`LEGEND_ENTRY` per entry)."""
    per_line = max(1, int(width // LEGEND_ENTRY))
    return len(range(0, len(table), per_line))


def text_height(lines: int) -> float:
    """Height (mm) of a block of ``lines`` lines of legend text, from its top to below its
    last line's baseline, as the writer draws it (line by line)."""
    y = FONT
    for _ in range(lines):
        y += LINE
    return y


def legend_height(table, width: float) -> float:
    """Height of the legend (mm) of a crease table on a page ``width`` mm wide."""
    return text_height(LEGEND_HEAD + legend_lines(table, width))


def join_legend_lines(joins, width: float) -> list:
    """The lines of a page's join legend: how to join, and the joins of the page."""
    how = (f"JOINS: the corners that carry the same number (·1, ·2, ...) are joined. Lay them "
           f"on one another as their labels say (C·4 on one sheet goes on every other corner "
           f"·4), pass a thread through their {JOIN_HOLE:g} mm holes ({JOIN_INSET:g} mm in from "
           "the corner) and knot it loosely on both sides: the corners must still turn against "
           "each other, so do not glue them. Corner labels: C·4 = corner C of this sheet, at "
           "join 4.")
    listed = "Joins on this page: " + "; ".join(
        f"·{n} = " + " + ".join(f"{k}{c}" for k, c in corners) for n, corners in joins) + "."
    return wrap(how, width) + wrap(listed, width)


def _cell(model, numbers) -> tuple[float, float, float]:
    """Width and height of the cell a sheet takes on a page (mm), and the room left and right
    of it for the corner labels (centred on the corners, above and below them)."""
    w, h = np.ptp(model.sheets[0].pattern.vertices, axis=0) * model.scale
    chars = max(len(corner_text(sh.pattern, numbers[k], a))
                for k, sh in enumerate(model.sheets) for a in range(sh.pattern.n_vertices))
    side = 0.5 * chars * CORNER_CHAR + 2.0
    return float(w + 2 * side), float(h + 2 * LABEL_ROOM + TITLE_ROOM), side


def page_joins(joins, idx) -> list:
    """The joins (number, corners) that touch the sheets ``idx`` (0-based)."""
    return [(j, corners) for j, corners in enumerate(joins, 1)
            if any(k - 1 in idx for k, _ in corners)]


def pages(model, media, legend_height_mm: float) -> list:
    """The sheets of a chain nested on pages of ``media``, rows of cells under one another,
    the legend (``legend_height_mm``, and the page's joins) below them.

    Returns
    -------
    list of (list of int, list of (float, float))
        Per page, the sheets on it and the (dx, dy) of each sheet's bounding box (mm).

    Raises
    ------
    FabricationError
        A sheet (with its labels, and the legend) does not fit the medium.
    """
    numbers, joins = join_numbers(model)
    cw, ch, side = _cell(model, numbers)
    width = media.width - 2 * MARGIN
    cols = int(width // cw)
    n = len(model.sheets)
    laid = None
    for rows in range(int(media.height // ch), 0, -1) if cols >= 1 else []:
        per = cols * rows
        chunks = [list(range(f, min(f + per, n))) for f in range(0, n, per)]
        joins_h = max(text_height(len(join_legend_lines(page_joins(joins, c), width)))
                      for c in chunks)
        if rows * ch + legend_height_mm + joins_h + 3 * MARGIN <= media.height:
            laid = (rows, chunks)
            break
    if laid is None:
        raise FabricationError(
            f"a sheet of {cw - 2 * side:.1f} mm, with its corner labels and the legend, needs a "
            f"page of at least {cw + 2 * MARGIN:.0f} x "
            f"{ch + legend_height_mm + 3 * MARGIN:.0f} mm; the medium is {media.text()}: choose "
            "a larger one (origami.medium = A3, or WIDTHxHEIGHT in mm) or a smaller "
            "origami.sheet_size")
    left = MARGIN + 0.5 * (width - cols * cw)  # the grid centred across the page
    return [(idx, [(left + c * cw + side, MARGIN + r * ch + LABEL_ROOM)
                   for r, c in (divmod(i, cols) for i in range(len(idx)))])
            for idx in laid[1]]


def upright(model):
    """The model with every sheet turned in its plane so that its flat outline's bounding box
    is the smallest (a square sheet drawn as a diamond is turned square to the page): the
    sheets nest far tighter, and the drawing is the same sheet."""
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
    # the same mm per design unit: sheet_size is a sheet's diameter (corner to corner), which a
    # turn in its plane keeps (it was once replaced by the turned box's side, so a square drawn
    # as a diamond came out 1/sqrt(2) of the size its legend states)
    return replace(model, sheets=tuple(sheets))


def place(pattern, scale, dx, dy):
    """Drawing coordinates (mm, y down) of a sheet's vertices placed at (dx, dy)."""
    v = pattern.vertices
    lo, top = v.min(axis=0), v[:, 1].max()
    return np.stack([dx + (v[:, 0] - lo[0]) * scale, dy + (top - v[:, 1]) * scale], axis=1)


def join_holes(pattern, numbers, p) -> list:
    """Centres (drawing mm) of the thread holes of a sheet's joined corners: on the bisector
    of the corner, :data:`JOIN_INSET` in from it."""
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


def page_names(name: str, n: int, kind: str) -> list:
    """``NAME_layout.svg`` for page 1, ``NAME_layout_p2.svg`` ... (``kind``: layout, cut)."""
    return [f"{name}_{kind}.svg" if k == 0 else f"{name}_{kind}_p{k + 1}.svg" for k in range(n)]


def crease_layout(model, fold) -> CreaseLayout:
    """The layout of a folded origami model: what its crease SVG and cut sheets draw.

    Parameters
    ----------
    model : OrigamiModel
    fold : FoldResult
        Its fold (the realised assignment and the fold angles come from it).

    Returns
    -------
    CreaseLayout

    Raises
    ------
    FabricationError
        A bad ``origami.medium``, or a sheet (with its labels, and the legend) that does not
        fit the medium.
    """
    assignment = folded_assignment(model, fold)
    realised = realised_model(model, fold, assignment)
    targets = tuple(sheet_targets(realised, fold))
    geom = sheet_geometry(realised.sheets[0].pattern, realised.scale)
    table = tuple(crease_table(realised, targets))
    if len(model.sheets) == 1:
        w, h = np.ptp(realised.sheets[0].pattern.vertices, axis=0) * realised.scale
        page = PageLayout((SheetLayout(0, (MARGIN, MARGIN)),), ())
        return CreaseLayout(assignment, realised, targets, geom, table, realised, None, ({},), (),
                            (page,),
                            (float(w + 2 * MARGIN), float(h + 2 * MARGIN)))
    media = medium(model.settings.medium)
    drawn = upright(realised)
    numbers, joins = join_numbers(drawn)
    width = media.width - 2 * MARGIN
    laid = pages(drawn, media, legend_height(table, width))
    out = []
    for idx, offsets in laid:
        sheets = []
        for k, (dx, dy) in zip(idx, offsets):
            pat = drawn.sheets[k].pattern
            holes = join_holes(pat, numbers[k], place(pat, drawn.scale, dx, dy))
            sheets.append(SheetLayout(k, (dx, dy), tuple(tuple(map(float, c)) for c in holes)))
        out.append(PageLayout(tuple(sheets), tuple(
            (j, tuple(corners)) for j, corners in page_joins(joins, idx))))
    return CreaseLayout(assignment, realised, targets, geom, table, drawn, media,
                        tuple(numbers), tuple(tuple(c) for c in joins), tuple(out),
                        (media.width, media.height))
