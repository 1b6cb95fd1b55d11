"""Nesting: parts (bars, spacer rings, a 100 mm reference square) packed onto sheets.

Each part is packed by its bounding box plus the spacing (rectpack, quarter turns allowed,
best-fit-first over the sheets) on as many sheets as needed, in integer units of 0.01 mm so that
the result does not depend on float round-off. Five packing algorithms (MaxRects with three
fit rules, guillotine, skyline) and three orders (area, long side, perimeter) are tried and the
packing with the fewest sheets, then the least left on the last sheet, is kept; every sheet
reports its utilisation (cut part area over sheet area, :func:`utilisation`). A quarter turn maps (x, y)
to (-y, x) exactly, so hole centres keep their distances to round-off.

Bars are engraved with a label ``B<bar> L<layer> J<i>-<j>`` along their axis between the holes,
shrunk to fit (down to ``B<bar>`` on short bars); :func:`label_outlines` turns a label into
glyph outlines for lasers that ignore text.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import FabricationError
from .bars import bar_outline, hole_radius, outline_radius
from .free_space import fill_back
from .shelves import shelf_pack

__all__ = ["Part", "Label", "Sheet", "make_parts", "nest_parts", "place_like", "label_outlines",
           "REFERENCE_SIZE", "part_area", "utilisation"]

#: Side of the reference square (mm).
REFERENCE_SIZE = 100.0
_UNIT = 100  # rectpack works in 0.01 mm
#: Sizes within this (in rectpack's 0.01 mm units) of a whole unit round to it, not past it:
#: mm values such as 0.29 carry round-off that would otherwise cost a whole unit.
UNIT_SLACK = 1e-6
# Average advance of a character relative to the text height (sans-serif capitals, digits).
_CHAR_WIDTH = 0.7
_MIN_TEXT = 1.0  # mm; smaller labels are left off (and counted in the report)


@dataclass(frozen=True)
class Label:
    """Engraved text: ``insert`` is its centre, ``angle`` in degrees."""

    text: str
    insert: tuple[float, float]
    height: float
    angle: float
    part: str


@dataclass(frozen=True, eq=False)
class Part:
    """A part in its own frame.

    Attributes
    ----------
    id : str
        ``"B3"`` (bar 3), ``"S5.2"`` (spacer at joint 5, layer 2) or ``"REF"``.
    kind : str
        ``"bar"``, ``"spacer"`` or ``"reference"``.
    outline : numpy.ndarray, shape (K, 3) or None
        Closed outer contour ``(x, y, bulge)``, kerf applied (None for a spacer ring, whose
        outer contour is the circle ``ring``).
    ring : float or None
        Outer radius of a spacer ring (kerf applied).
    holes : numpy.ndarray, shape (H, 2)
        Hole centres.
    hole_radius : float
        Drawn hole radius (kerf applied).
    labels : list of Label
    bbox : (xmin, ymin, xmax, ymax)
    meta : dict
        ``bar``, ``joints``, ``layer`` for bars; ``joint``, ``layer`` for spacers. A reference
        part may carry ``cut`` (True: its outline is cut, not engraved on the REFERENCE
        layer) and ``hole_radii`` (a drawn radius per hole, in place of ``hole_radius``).
    """

    id: str
    kind: str
    outline: np.ndarray | None
    ring: float | None
    holes: np.ndarray
    hole_radius: float
    labels: list
    bbox: tuple[float, float, float, float]
    meta: dict = field(default_factory=dict)
    engrave_outline: bool = False


@dataclass(eq=False)
class Sheet:
    """Parts placed on one sheet (sheet coordinates in mm, origin at the lower-left corner).

    Attributes
    ----------
    index : int
        1-based.
    width, height : float
    parts : list of Part
        Parts moved into sheet coordinates.
    placements : dict
        part id -> {"x", "y", "rotated"}.
    """

    index: int
    width: float
    height: float
    parts: list = field(default_factory=list)
    placements: dict = field(default_factory=dict)


def _bar_label(k: int, layer: int, i: int, j: int, length: float, settings):
    width = settings.bar_width
    room = length - settings.screw.hole_diameter - 2.0  # 1 mm clear of each hole
    for text in (f"B{k} L{layer} J{i}-{j}", f"B{k} L{layer}", f"B{k}"):
        h = min(settings.label_height, 0.45 * width, room / (_CHAR_WIDTH * len(text)))
        if h >= _MIN_TEXT:
            return Label(text, (0.5 * length, 0.0), float(round(h, 3)), 0.0, f"B{k}")
    return None


def make_parts(bars, stacking, settings) -> list[Part]:
    """All parts to cut: one per bar, one spacer ring per empty layer a screw passes, and the
    reference square.

    Parameters
    ----------
    bars : BarSet
    stacking : Stacking
    settings : LaserSettings

    Returns
    -------
    list of Part
    """
    parts = []
    r_out = outline_radius(bars.width, bars.kerf)
    r_hole = hole_radius(bars.hole_diameter, bars.kerf)
    for k in range(bars.n_bars):
        i, j = (int(v) for v in bars.edges[k])
        L = float(bars.lengths[k])
        layer = int(stacking.layer[k])
        label = _bar_label(k, layer, i, j, L, settings) if settings.labels != "none" else None
        parts.append(Part(
            id=f"B{k}", kind="bar", outline=bar_outline(L, bars.width, bars.kerf), ring=None,
            holes=np.array([[0.0, 0.0], [L, 0.0]]), hole_radius=r_hole,
            labels=[label] if label else [], bbox=(-r_out, -r_out, L + r_out, r_out),
            meta={"bar": k, "joints": [i, j], "layer": layer, "length": L}))
    ring = 0.5 * (settings.spacer_diameter + bars.kerf)
    web = ring - r_hole
    for js in stacking.joints:
        for z in js.spacers:
            labels = []
            if settings.labels != "none":
                # "S<joint>.<layer>" engraved in the web above the hole, as wide as fits there:
                # the name the guide and the bill of materials give the ring
                text = f"S{js.joint}.{z}"
                y = r_hole + 0.5 * web
                half = math.sqrt(max(ring ** 2 - (y + 0.25 * web) ** 2, 0.0))
                h = min(0.5 * web, 2 * half / (_CHAR_WIDTH * len(text)), settings.label_height)
                if h >= _MIN_TEXT:
                    labels = [Label(text, (0.0, y), float(round(h, 3)), 0.0, f"S{js.joint}.{z}")]
            parts.append(Part(
                id=f"S{js.joint}.{z}", kind="spacer", outline=None, ring=ring,
                holes=np.zeros((1, 2)), hole_radius=r_hole, labels=labels,
                bbox=(-ring, -ring, ring, ring), meta={"joint": js.joint, "layer": z}))
    if settings.reference_square != "none":
        s = REFERENCE_SIZE
        square = np.array([[0.0, 0.0, 0.0], [s, 0.0, 0.0], [s, s, 0.0], [0.0, s, 0.0]])
        if settings.reference_square == "cut":
            # grow by half the kerf so the square comes off the laser exactly 100 mm wide
            h = 0.5 * bars.kerf
            square[:, :2] = square[:, :2] * ((s + 2 * h) / s) - h
        labels = [Label("100 mm", (0.5 * s, 0.5 * s), 5.0, 0.0, "REF")] \
            if settings.labels != "none" else []
        lo, hi = float(square[:, :2].min()), float(square[:, :2].max())
        parts.append(Part(id="REF", kind="reference", outline=square, ring=None,
                          holes=np.zeros((0, 2)), hole_radius=0.0, labels=labels,
                          bbox=(lo, lo, hi, hi), meta={"size": s},
                          engrave_outline=settings.reference_square == "engrave"))
    return parts


def _moved(part: Part, rotated: bool, shift) -> Part:
    """The part turned a quarter (if asked) and shifted."""
    tx, ty = float(shift[0]), float(shift[1])

    def move(xy):
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if rotated:
            xy = np.stack([-xy[:, 1], xy[:, 0]], axis=1)
        return xy + [tx, ty]

    outline = None
    if part.outline is not None:
        outline = part.outline.copy()
        outline[:, :2] = move(part.outline[:, :2])
    labels = [Label(lb.text, tuple(float(v) for v in move(lb.insert)[0]), lb.height,
                    (lb.angle + (90.0 if rotated else 0.0)) % 360.0, lb.part) for lb in part.labels]
    x0, y0, x1, y1 = part.bbox
    corners = move([[x0, y0], [x1, y1]])
    bbox = (float(corners[:, 0].min()), float(corners[:, 1].min()),
            float(corners[:, 0].max()), float(corners[:, 1].max()))
    return Part(id=part.id, kind=part.kind, outline=outline, ring=part.ring,
                holes=move(part.holes) if part.holes.size else part.holes,
                hole_radius=part.hole_radius, labels=labels, bbox=bbox, meta=dict(part.meta),
                engrave_outline=part.engrave_outline)


def nest_parts(parts, settings) -> list[Sheet]:
    """Pack parts onto as many sheets as needed.

    Parameters
    ----------
    parts : list of Part
    settings : LaserSettings
        ``sheet_width``, ``sheet_height``, ``spacing`` (gap between parts), ``margin``.

    Returns
    -------
    list of Sheet

    Raises
    ------
    FabricationError
        A part larger than the usable sheet (the message names it and its size).
    """
    s = settings
    free_w = s.sheet_width - 2 * s.margin
    free_h = s.sheet_height - 2 * s.margin
    bin_w = int(math.floor((free_w + s.spacing) * _UNIT + UNIT_SLACK))
    bin_h = int(math.floor((free_h + s.spacing) * _UNIT + UNIT_SLACK))
    sizes = {}
    for n, p in enumerate(parts):
        x0, y0, x1, y1 = p.bbox
        w = int(math.ceil((x1 - x0 + s.spacing) * _UNIT - UNIT_SLACK))
        h = int(math.ceil((y1 - y0 + s.spacing) * _UNIT - UNIT_SLACK))
        if min(w, h) > min(bin_w, bin_h) or max(w, h) > max(bin_w, bin_h):
            raise FabricationError(
                f"part {p.id} ({x1 - x0:.1f} x {y1 - y0:.1f} mm) does not fit on a "
                f"{s.sheet_width:g} x {s.sheet_height:g} mm sheet with {s.margin:g} mm margins; "
                "use a larger sheet or a smaller scale")
        sizes[n] = (w, h)
    placed = _pack_in_groups(sizes, bin_w, bin_h)
    sheets: dict[int, Sheet] = {}
    for b, x, y, w, h, rid in sorted(placed, key=lambda r: (r[0], r[5])):
        part = parts[rid]
        rotated = (w, h) != sizes[rid]  # a square part's turn does not matter
        x0, y0, x1, y1 = part.bbox
        if rotated:  # after (x, y) -> (-y, x) the box is [-y1, -y0] x [x0, x1]
            min_x, min_y = -y1, x0
        else:
            min_x, min_y = x0, y0
        shift = (s.margin + x / _UNIT - min_x, s.margin + y / _UNIT - min_y)
        sheet = sheets.setdefault(b, Sheet(index=b + 1, width=s.sheet_width, height=s.sheet_height))
        _place(sheet, part, rotated, shift)
    out = [sheets[k] for k in sorted(sheets)]
    # the packers see boxes: the parts of a last sheet may fit between the round ends and rings
    # of the sheets before; a sheet is kept only when its parts fit nowhere else
    by_id = {p.id: p for p in parts}
    while len(out) > 1:
        moves = fill_back(out, by_id, s)
        if moves is None:
            break
        for pid, (k, rotated, shift) in moves.items():
            _place(out[k], by_id[pid], rotated, shift)
        out.pop()
    return out


def _place(sheet: Sheet, part: Part, rotated: bool, shift) -> None:
    """Put ``part`` (own frame) on ``sheet``, turned and shifted, and record where."""
    sheet.parts.append(_moved(part, rotated, shift))
    sheet.placements[part.id] = {"x": round(shift[0], 6), "y": round(shift[1], 6),
                                 "rotated": bool(rotated), "shift": shift}


def place_like(parts, sheets) -> list[Sheet]:
    """The same nesting with other parts of the same ids (drawn for another kerf): each part
    is turned and shifted exactly as its namesake was placed on ``sheets``.

    A part drawn for a smaller kerf is smaller, so the placements stay clear of each other.
    """
    by_id = {p.id: p for p in parts}
    out = []
    for sheet in sheets:
        new = Sheet(index=sheet.index, width=sheet.width, height=sheet.height,
                    placements=dict(sheet.placements))
        for placed in sheet.parts:
            where = sheet.placements[placed.id]
            new.parts.append(_moved(by_id[placed.id], where["rotated"], where["shift"]))
        out.append(new)
    return out


#: Parts are packed in groups of about this many sheets' worth of area: a packer that tries
#: every open sheet for every part (first fit) costs parts × sheets, quadratic in a chain's
#: length (a 1000-module kit, 8001 parts on 61 sheets: about 30 s); groups keep it linear.
GROUP_SHEETS = 12
#: Sheets at the end of a group filled below this fraction of the group's median sheet are
#: unpacked and their parts packed with the next group.
TAIL_FILL = 0.9


def _strategies():
    import rectpack

    return [(algo, order)
            for algo in (rectpack.MaxRectsBssf, rectpack.MaxRectsBaf, rectpack.MaxRectsBl,
                         rectpack.GuillotineBssfSas, rectpack.SkylineMwf)
            for order in (rectpack.SORT_AREA, rectpack.SORT_LSIDE, rectpack.SORT_PERI)]


def _pack(ids, sizes, bin_w, bin_h, strategies):
    """The best packing of these parts over the strategies: fewest sheets, then the emptiest
    last sheet (its parts moved onto fuller ones), deterministically. Returns
    ``(strategy, [(sheet, x, y, w, h, part), ...])``."""
    import rectpack

    best = None
    for strategy in strategies:
        algo, order = strategy
        packer = rectpack.newPacker(mode=rectpack.PackingMode.Offline,
                                    bin_algo=rectpack.PackingBin.BFF, pack_algo=algo,
                                    sort_algo=order, rotation=True)
        packer.add_bin(bin_w, bin_h, count=float("inf"))
        for n in ids:
            packer.add_rect(*sizes[n], rid=n)
        packer.pack()
        placed = packer.rect_list()
        if len(placed) != len(ids):  # pragma: no cover - infinite bins take every part
            continue
        n_bins = 1 + max((r[0] for r in placed), default=0)
        last = sum(r[3] * r[4] for r in placed if r[0] == n_bins - 1)
        key = (n_bins, last)
        if best is None or key < best[0]:
            best = (key, strategy, placed)
    if best is None:  # pragma: no cover
        raise FabricationError("nesting failed to place every part")
    # rows of bars: taken only where it saves a sheet (the boxes' packers place the rest)
    rows = shelf_pack(ids, sizes, bin_w, bin_h)
    if rows and 1 + max(r[0] for r in rows) < best[0][0]:
        return best[1], rows
    return best[1], best[2]


def _pack_in_groups(sizes: dict, bin_w: int, bin_h: int) -> list[tuple]:
    """Pack every part; returns ``[(sheet, x, y, w, h, part), ...]``.

    Up to :data:`GROUP_SHEETS` sheets' worth of area, all parts at once with every strategy
    (5 packers × 3 orders, quarter turns allowed). Larger kits (long chains) go in groups of
    that much area, each an even sample of the parts (every k-th): the first group with every strategy, the next ones
    with the strategy that won it (a chain's groups are alike). The parts of a group's last
    sheets, where they are emptier than its typical sheet, go back into the next group, so the
    kit is about as tight as a single packing; the cost grows linearly with the number of parts.
    """
    ids = list(sizes)
    area = [sizes[n][0] * sizes[n][1] for n in ids]
    budget = GROUP_SHEETS * bin_w * bin_h
    if sum(area) <= budget:
        return _pack(ids, sizes, bin_w, bin_h, _strategies())[1]
    # every group a even sample of the whole kit (long bars, short bars and spacer rings
    # alike), so that each packs as well as the whole would
    n_groups = math.ceil(sum(area) / budget)
    groups = [ids[g::n_groups] for g in range(n_groups)]
    out, offset, carry, strategies = [], 0, [], _strategies()
    for g, group in enumerate(groups):
        strategy, placed = _pack(carry + group, sizes, bin_w, bin_h, strategies)
        strategies = [strategy]
        n_bins = 1 + max(r[0] for r in placed)
        if g < len(groups) - 1:
            # the packers leave a tail of emptier sheets (the last parts spread over them):
            # their parts go on with the next group
            fill = np.zeros(n_bins)
            for r in placed:
                fill[r[0]] += r[3] * r[4]
            keep = n_bins - 1
            while keep > 0 and fill[keep - 1] < TAIL_FILL * np.median(fill):
                keep -= 1
            carry = sorted(r[5] for r in placed if r[0] >= keep)
            placed = [r for r in placed if r[0] < keep]
            n_bins = keep
        out.extend((b + offset, x, y, w, h, rid) for b, x, y, w, h, rid in placed)
        offset += n_bins
    return out


def label_outlines(label: Label) -> list[np.ndarray]:
    """Glyph outlines of a label, for lasers that ignore text.

    Parameters
    ----------
    label : Label

    Returns
    -------
    list of numpy.ndarray, shape (K, 2)
        Closed polylines (within :data:`GLYPH_FLATNESS` of the glyphs' curves)
        centred on ``label.insert`` and turned by ``label.angle``.

    Raises
    ------
    FabricationError
        When no font is available to draw the glyphs.
    """
    a = math.radians(label.angle)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return [pts @ rot.T + np.asarray(label.insert)
            for pts in _glyph_outlines(label.text, float(label.height))]


#: Largest distance between a glyph's curve and the polyline that stands for it (mm): a tenth
#: of a laser's spot.
GLYPH_FLATNESS = 0.02


@functools.lru_cache(maxsize=4096)
def _glyph_outlines(text: str, height: float) -> tuple:
    """A text's glyph outlines about the origin (read-only arrays; the sheets' DXF and SVG and
    every kit of a batch draw the same labels again).

    Each character is drawn once per height (:func:`_char_outlines`) and set after the one
    before it by its advance, as ezdxf's text2path sets a line without kerning; the line is
    centred as its MIDDLE_CENTER alignment centres it (across the glyphs' control points, and
    half a cap height down).
    """
    chars = [_char_outlines(c, height) for c in text]
    x, lo, hi = 0.0, math.inf, -math.inf
    offsets = []
    for outlines, (x0, x1), advance in chars:
        offsets.append(x)
        if outlines:
            lo, hi = min(lo, x + x0), max(hi, x + x1)
        x += advance
    if lo > hi:
        return ()
    shift = np.array([-0.5 * (lo + hi), -0.5 * height])
    out = []
    for (outlines, _, _), dx in zip(chars, offsets):
        for pts in outlines:
            placed = pts + (shift + (dx, 0.0))
            placed.setflags(write=False)
            out.append(placed)
    return tuple(out)


@functools.lru_cache(maxsize=1024)
def _char_outlines(char: str, height: float) -> tuple:
    """One character's closed outlines, its origin on the baseline at its left (flattened to
    :data:`GLYPH_FLATNESS`), the x range of its control points and its advance."""
    try:
        from ezdxf import path as ezpath
        from ezdxf.addons import text2path
        from ezdxf.fonts import fonts
    except ImportError as exc:  # pragma: no cover - ezdxf is a dependency
        raise FabricationError(f"labels as outlines need ezdxf's text2path: {exc}") from None
    try:
        face = fonts.FontFace(family="DejaVu Sans")
        paths = text2path.make_paths_from_str(char, face, size=height)
        # the glyph's own advance (the font's text_width_ex counts a lone space as 0 wide)
        advance = text2path.get_font(face).glyph_cache.get_text_length(char, height)
    except Exception as exc:  # font lookup errors come in many types
        raise FabricationError(f"cannot draw label character {char!r} as outlines ({exc}); "
                               "use labels = \"text\" or \"none\"") from None
    out = []
    for sub in paths:
        # the distance bounds the error; ezdxf's default of at least 4 segments per curve
        # would add points no cutter resolves
        pts = np.array([(v.x, v.y) for v in sub.flattening(distance=GLYPH_FLATNESS, segments=1)],
                       dtype=np.float64)
        if pts.shape[0] >= 3:
            out.append(pts)
    box = ezpath.bbox(paths, fast=True) if paths else None
    x_range = (box.extmin.x, box.extmax.x) if box is not None and box.has_data else (0.0, 0.0)
    return tuple(out), x_range, float(advance)


def part_area(part: Part) -> float:
    """Area of material a part takes off the sheet (mm^2): its outer contour minus its holes
    (the reference square counts when it is cut out, not when engraved)."""
    holes = part.holes.shape[0] * math.pi * part.hole_radius ** 2 if part.holes.size else 0.0
    if part.ring is not None:
        return math.pi * part.ring ** 2 - holes
    if part.engrave_outline or part.outline is None:
        return 0.0
    v = np.asarray(part.outline, dtype=np.float64)
    x, y, b = v[:, 0], v[:, 1], v[:, 2]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    area = 0.5 * float(np.sum(x * yn - xn * y))          # polygon of the vertices (CCW > 0)
    theta = 4.0 * np.arctan(b)                           # plus the circular segments of arcs
    chord = np.hypot(xn - x, yn - y)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(b != 0, chord / (2 * np.sin(np.abs(theta) / 2)), 0.0)
    area += float(np.sum(np.sign(theta) * 0.5 * r ** 2 * (np.abs(theta) - np.sin(np.abs(theta)))))
    return abs(area) - holes


def utilisation(sheet: Sheet) -> float:
    """Fraction of a sheet's area taken by its parts."""
    return sum(part_area(p) for p in sheet.parts) / (sheet.width * sheet.height)
