"""The true gap between the parts nested on a sheet: bars as stadiums round their holes, rings as
discs, the reference square as its box, computed from the placed parts (not the packer's boxes)."""

from __future__ import annotations

import itertools

import numpy as np

from fabkit.fab.nest import Part, Sheet

#: a separation computed from the placed parts may fall short of the spacing by round-off only
SEPARATION_TOL = 1e-6


def _segment_distance(p, q, a, b) -> float:
    """Least distance between segments pq and ab (brute force over a fine parameter grid,
    then exact endpoint-to-segment refinement)."""
    def point_seg(x, u, v):
        d = v - u
        t = 0.0 if not d.any() else float(np.clip(np.dot(x - u, d) / np.dot(d, d), 0, 1))
        return float(np.linalg.norm(x - (u + t * d)))

    best = min(point_seg(p, a, b), point_seg(q, a, b), point_seg(a, p, q), point_seg(b, p, q))
    # segments that cross have distance 0
    def cross(o, x, y):
        return (x[0] - o[0]) * (y[1] - o[1]) - (x[1] - o[1]) * (y[0] - o[0])
    if (cross(p, q, a) * cross(p, q, b) < 0) and (cross(a, b, p) * cross(a, b, q) < 0):
        return 0.0
    return best


def _axis_and_radius(part: Part):
    """A placed part as an axis (two points) and a radius: bars round their holes, rings
    round their centre; the reference square as its centre and half-diagonal (conservative)."""
    if part.kind == "bar":
        r = float(np.max(np.abs(_dist_to_axis(part.outline[:, :2], *part.holes[:2]))))
        return part.holes[0], part.holes[1], r
    if part.ring is not None:
        return part.holes[0], part.holes[0], part.ring
    x0, y0, x1, y1 = part.bbox
    c = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
    return c, c, 0.5 * float(np.hypot(x1 - x0, y1 - y0))


def _dist_to_axis(pts, a, b):
    d = (b - a) / np.linalg.norm(b - a)
    return (pts - a) @ np.array([-d[1], d[0]])


def least_gap(sheet: Sheet, s) -> float:
    """Least true gap between two parts of a sheet, and whether all lie inside the margins."""
    shapes = [_axis_and_radius(p) for p in sheet.parts]
    for p, (a, b, r) in zip(sheet.parts, shapes):
        lo = np.minimum(a, b) - r
        hi = np.maximum(a, b) + r
        if p.kind != "reference":
            assert (lo >= s.margin - SEPARATION_TOL).all() and \
                (hi <= [s.sheet_width - s.margin + SEPARATION_TOL,
                        s.sheet_height - s.margin + SEPARATION_TOL]).all(), p.id
    gap = np.inf
    for (i, (a, b, r)), (j, (c, d, q)) in itertools.combinations(enumerate(shapes), 2):
        if "reference" in (sheet.parts[i].kind, sheet.parts[j].kind):
            # the square against a stadium: its box, grown by the spacing, must miss the axis
            sq, other = (i, j) if sheet.parts[i].kind == "reference" else (j, i)
            x0, y0, x1, y1 = sheet.parts[sq].bbox
            u, v, rr = shapes[other]
            for t in np.linspace(0.0, 1.0, 64):
                x = u + t * (v - u)
                dx = max(x0 - x[0], 0.0, x[0] - x1)
                dy = max(y0 - x[1], 0.0, x[1] - y1)
                gap = min(gap, float(np.hypot(dx, dy)) - rr)
            continue
        gap = min(gap, _segment_distance(a, b, c, d) - r - q)
    return gap
