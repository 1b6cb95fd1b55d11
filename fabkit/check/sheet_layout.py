"""Parts apart on a cut sheet: no two outlines read back from a DXF cross or come too close.

The nesting places parts by boxes, in rows, or in the free space between round ends
(:mod:`fabkit.fab.nest`); this check does not trust any of it. From the outlines read back
(:func:`fabkit.check.dxf.read_sheet`: a bar's two round ends, a spacer ring's circle) it rebuilds
each part's shape — a bar is the stadium of its round ends' radius round the segment joining
their centres, a ring the disc of its circle — and measures the least gap between the cut lines
of any two parts of a sheet.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_WEB_MM", "part_shapes", "least_gap"]

#: Least gap between the cut lines of two parts (mm): acrylic left narrower than this between two
#: passes of the beam warps in their heat and breaks off, and the second cut then runs along an
#: edge already free (the nesting's spacing is 3 mm by default).
MIN_WEB_MM = 1.0
#: Segments per quarter circle when a round end or a ring is drawn as a polygon; the polygon
#: lies inside the circle by at most r (1 - cos(pi / 64)), 0.01 mm for a 7 mm ring.
QUAD_SEGS = 16


def part_shapes(parts: dict) -> dict:
    """The outline of every part that has one, by part id.

    Parameters
    ----------
    parts : dict
        ``read_sheet(doc)["parts"]``: id -> {"kind", "arcs": [(centre, r)], "outer":
        [(centre, r)], ...}.

    Returns
    -------
    dict
        id -> shapely geometry: a bar with two round ends as a stadium, a part with an outer
        circle (a spacer ring) as a disc. Parts without either (the reference square, a bar
        whose ends the parts check already reports) are left out.
    """
    from shapely.geometry import LineString, Point

    out = {}
    for pid, part in parts.items():
        if part.get("outer"):
            (cx, cy), r = part["outer"][0]
            out[pid] = Point(cx, cy).buffer(r, quad_segs=QUAD_SEGS)
        elif len(part.get("arcs", ())) == 2:
            (a, ra), (b, rb) = part["arcs"]
            r = max(ra, rb)
            if np.allclose(a, b):
                out[pid] = Point(*a).buffer(r, quad_segs=QUAD_SEGS)
            else:
                out[pid] = LineString([a, b]).buffer(r, quad_segs=QUAD_SEGS)
    return out


def least_gap(parts: dict) -> tuple[float, tuple | None]:
    """The least gap between the outlines of two parts of one sheet.

    Parameters
    ----------
    parts : dict
        ``read_sheet(doc)["parts"]``.

    Returns
    -------
    gap : float
        mm; -1 when two outlines overlap (how far one reaches into the other is not measured);
        inf with fewer than two parts; ``4 * MIN_WEB_MM`` when no two parts come that close
        (a gap at least that wide).
    pair : tuple of str or None
        The two parts' ids.
    """
    from shapely import STRtree

    shapes = part_shapes(parts)
    ids = sorted(shapes)
    if len(ids) < 2:
        return float("inf"), None
    geoms = [shapes[i] for i in ids]
    tree = STRtree(geoms)
    reach = MIN_WEB_MM * 4.0  # pairs farther apart than this cannot set the least gap below it
    best, pair = float("inf"), None
    for a, b in zip(*tree.query(geoms, predicate="dwithin", distance=reach)):
        if a >= b:
            continue
        ga, gb = geoms[a], geoms[b]
        gap = -1.0 if ga.intersects(gb) else float(ga.distance(gb))
        if gap < best:
            best, pair = gap, (ids[a], ids[b])
    if pair is None:
        return reach, None  # every pair farther apart than ``reach``
    return best, pair
