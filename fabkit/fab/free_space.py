"""The free space left on nested sheets, and parts of a last sheet moved into it.

The packers nest parts by their bounding boxes, so the free space they leave between round
bar ends, rings and short bars is invisible to them: a kit can open a sheet for a few spacer
rings that would fit between the bars of the sheets before (and_gate: six rings on a third
sheet 0.4 % used beside two sheets 69 % and 71 % used). :func:`fill_back` looks at the parts'
true shapes (a bar is a stadium round its two holes, a ring a disc) and moves the parts of the
last sheet into the free space of the earlier ones, when all of them fit: a sheet is opened only
when the parts on it fit nowhere else.

Candidate places come from the free space eroded by the part's half-width (for a ring that set
is exactly where its centre may go); each candidate is then tested on the part's whole shape,
so a part is placed only where it keeps the spacing to every other part and the margin to the
sheet's edge.
"""

from __future__ import annotations

import numpy as np
from shapely import affinity
from shapely.geometry import LineString, Point, Polygon, box
from shapely.ops import unary_union
from shapely.prepared import prep

__all__ = ["part_shape", "part_anchors", "placed_shape", "free_spot", "fill_back", "SHAPE_SLACK"]

#: Added to the spacing when testing a place (mm): shapely draws a circle as an inscribed
#: 64-gon, up to 0.0012 of its radius inside it (0.01 mm for a 7 mm ring); the slack covers that
#: on both parts with room to spare, so a place accepted here keeps the true spacing.
SHAPE_SLACK = 0.05
#: Candidate places lie this far inside the set their anchor may occupy (mm): a place on its
#: boundary would touch a neighbour's spacing exactly, which the test refuses.
CANDIDATE_INSET = 0.01
#: Segments per quarter circle in the shapes (shapely's ``quad_segs``).
QUAD_SEGS = 16
#: Candidate places tried per sheet and turn: the lowest first (a part goes to the bottom-left
#: of the free space, as the packers place theirs).
MAX_CANDIDATES = 4000


def part_shape(part):
    """The outline of a part in its own frame, as a shapely geometry.

    Parameters
    ----------
    part : fabkit.fab.nest.Part
        A bar (a stadium of its width round its two holes), a spacer ring (a disc) or another
        part (its outline polygon, or its bounding box when the outline has arcs).

    Returns
    -------
    shapely.geometry.base.BaseGeometry
    """
    if part.ring is not None:
        return Point(0.0, 0.0).buffer(part.ring, quad_segs=QUAD_SEGS)
    if part.kind == "bar":
        (x0, y0), (x1, y1) = np.asarray(part.holes, dtype=float)[:2]
        return LineString([(x0, y0), (x1, y1)]).buffer(part.bbox[3], quad_segs=QUAD_SEGS)
    if part.outline is not None and not np.any(part.outline[:, 2]):
        return Polygon(part.outline[:, :2])
    return box(*part.bbox)


def placed_shape(shape, rotated: bool, shift):
    """``shape`` turned a quarter (``(x, y) -> (-y, x)``, as the nesting turns) and shifted."""
    if rotated:
        shape = affinity.rotate(shape, 90.0, origin=(0.0, 0.0))
    return affinity.translate(shape, float(shift[0]), float(shift[1]))


def _candidates(region, limit: int) -> list:
    """Vertices of ``region``'s boundaries, lowest first (then leftmost), at most ``limit``."""
    geoms = getattr(region, "geoms", [region])
    pts = []
    for g in geoms:
        if g.is_empty or not hasattr(g, "exterior"):
            continue
        pts.extend(g.exterior.coords)
        for ring in g.interiors:
            pts.extend(ring.coords)
    pts = sorted(set((round(x, 6), round(y, 6)) for x, y in pts), key=lambda p: (p[1], p[0]))
    return pts[:limit]


def free_spot(shape, anchors, usable, taken, spacing: float):
    """Where a part fits among the parts placed already, or None.

    Parameters
    ----------
    shape : shapely geometry
        The part in its own frame (:func:`part_shape`).
    anchors : array_like, shape (A, 2)
        Points of the part (own frame) that may sit on a candidate place: a bar's two hole
        centres (the ends of its axis), else its centre.
    usable : shapely Polygon
        The sheet inside its margins.
    taken : list of shapely geometry
        The parts on the sheet, placed.
    spacing : float
        The least gap between two parts (mm).

    Returns
    -------
    tuple or None
        ``(rotated, (dx, dy))``: the quarter turn and shift that place the part; None when it
        fits nowhere.
    """
    blocked = unary_union(taken).buffer(spacing + SHAPE_SLACK, quad_segs=QUAD_SEGS) \
        if taken else Polygon()
    blocked_p = prep(blocked)
    usable_p = prep(usable)
    anchors = np.asarray(anchors, dtype=float).reshape(-1, 2)
    for rotated in (False, True):
        s = placed_shape(shape, rotated, (0.0, 0.0))
        ends = np.stack([-anchors[:, 1], anchors[:, 0]], axis=1) if rotated else anchors
        x0, y0, x1, y1 = s.bounds
        # an anchor lies this far inside the part's edge
        reach = 0.5 * min(x1 - x0, y1 - y0) + CANDIDATE_INSET
        region = usable.buffer(-reach, join_style="mitre").difference(blocked.buffer(reach))
        if region.is_empty:
            continue
        for px, py in _candidates(region, MAX_CANDIDATES):
            for ex, ey in ends:
                dx, dy = px - ex, py - ey
                moved = affinity.translate(s, dx, dy)
                if usable_p.contains(moved) and not blocked_p.intersects(moved):
                    return rotated, (float(dx), float(dy))
    return None


def part_anchors(part) -> np.ndarray:
    """Where a part may sit on a candidate place (own frame): a bar's hole centres, else the
    centre of its bounding box."""
    if part.kind == "bar":
        return np.asarray(part.holes, dtype=float)[:2]
    x0, y0, x1, y1 = part.bbox
    return np.array([[0.5 * (x0 + x1), 0.5 * (y0 + y1)]])


def fill_back(sheets, parts_by_id: dict, settings) -> dict | None:
    """Places on the earlier sheets for every part of the last sheet, or None.

    Parameters
    ----------
    sheets : list of fabkit.fab.nest.Sheet
        The nesting (parts placed, with their ``placements``).
    parts_by_id : dict
        Each part in its own frame, by id.
    settings : LaserSettings
        ``sheet_width``, ``sheet_height``, ``margin``, ``spacing``.

    Returns
    -------
    dict or None
        ``{part id: (sheet position in sheets, rotated, shift)}`` for every part of the last
        sheet; None when one of them fits on no earlier sheet (the sheet is needed).
    """
    s = settings
    usable = box(s.margin, s.margin, s.sheet_width - s.margin, s.sheet_height - s.margin)
    taken = [[placed_shape(part_shape(parts_by_id[p.id]), sheet.placements[p.id]["rotated"],
                           sheet.placements[p.id]["shift"]) for p in sheet.parts]
             for sheet in sheets[:-1]]
    moves = {}
    last = sorted(sheets[-1].parts, key=lambda p: -part_shape(parts_by_id[p.id]).area)
    for p in last:
        part = parts_by_id[p.id]
        shape = part_shape(part)
        for k in range(len(sheets) - 1):
            spot = free_spot(shape, part_anchors(part), usable, taken[k], s.spacing)
            if spot is not None:
                rotated, shift = spot
                moves[p.id] = (k, rotated, shift)
                taken[k].append(placed_shape(shape, rotated, shift))
                break
        else:
            return None
    return moves
