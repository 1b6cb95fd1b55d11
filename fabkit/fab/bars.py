"""Bars: round-ended outlines with exact arcs, one screw hole per joint, kerf compensation.

A bar for edge (i, j) is a stadium: the hole centres lie on its axis ``length`` apart, and the
outline is the set of points within ``width / 2`` of the segment between them, drawn as two
straight sides and two half circles (bulge 1 in DXF terms: exact arcs, never polygons). In the
bar's own frame the holes sit at (0, 0) and (length, 0).

Kerf: the laser burns away a strip ``kerf`` wide centred on the drawn line, so outlines are
drawn ``kerf / 2`` larger and holes ``kerf / 2`` smaller; the hole centres, and so the bar
lengths that define the network, are unaffected by kerf.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import FabricationError
from ..numerics import MM_SLACK

__all__ = ["BarSet", "bar_set", "check_bar_lengths", "bar_outline", "bulge_primitives",
           "outline_radius", "hole_radius", "undo_kerf", "stadium_polygon"]


#: Angles within this (degrees) below 360 are 0: round-off of a full turn.
ANGLE_SLACK_DEG = 1e-9


@dataclass(frozen=True, eq=False)
class BarSet:
    """The bars of a network in millimetres.

    Attributes
    ----------
    edges : numpy.ndarray of int, shape (E, 2)
        Joint (node) indices of each bar.
    lengths : numpy.ndarray, shape (E,)
        Hole-centre distances (mm).
    width : float
        Designed bar width (mm), before kerf.
    hole_diameter : float
        Designed hole diameter (mm), before kerf.
    kerf : float
    """

    edges: np.ndarray
    lengths: np.ndarray
    width: float
    hole_diameter: float
    kerf: float

    @property
    def n_bars(self) -> int:
        return int(self.edges.shape[0])

    def outline(self, k: int) -> np.ndarray:
        """Cut outline of bar ``k`` in its own frame (kerf applied), shape (4, 3): x, y, bulge."""
        return bar_outline(self.lengths[k], self.width, self.kerf)

    def holes(self, k: int) -> tuple[np.ndarray, float]:
        """Hole centres (2, 2) in the bar's frame and the cut hole radius (kerf applied)."""
        return (np.array([[0.0, 0.0], [float(self.lengths[k]), 0.0]]),
                hole_radius(self.hole_diameter, self.kerf))


def outline_radius(width: float, kerf: float) -> float:
    """Radius of a bar's round end as drawn for cutting: ``width / 2 + kerf / 2``."""
    return 0.5 * (width + kerf)


def hole_radius(hole_diameter: float, kerf: float) -> float:
    """Radius of a hole as drawn for cutting: ``hole_diameter / 2 - kerf / 2``."""
    return 0.5 * (hole_diameter - kerf)


def undo_kerf(drawn_outline_radius, drawn_hole_radius, kerf: float):
    """The part as it comes off the laser: (bar width, hole diameter) from drawn radii (mm)."""
    return 2.0 * np.asarray(drawn_outline_radius) - kerf, 2.0 * np.asarray(drawn_hole_radius) + kerf


def check_bar_lengths(lengths, edges, settings, *, scale: float | None = None) -> None:
    """Refuse bars too short for their two holes and the web between them.

    Parameters
    ----------
    lengths : array_like, shape (E,)
        Hole-centre distances in mm.
    edges : array_like of int, shape (E, 2)
    settings : LaserSettings
    scale : float, optional
        mm per design unit, to suggest the scale that would fix it.

    Raises
    ------
    FabricationError
        Names the shortest offending bar, its joints, and the length or scale needed.
    """
    lengths = np.asarray(lengths, dtype=np.float64)
    hole = settings.screw.hole_diameter
    need = hole + settings.min_web
    short = lengths < need - MM_SLACK
    if not short.any():
        return
    k = int(np.argmin(np.where(short, lengths, np.inf)))
    i, j = (int(v) for v in np.asarray(edges)[k])
    fix = ""
    if scale:
        fix = f"; raise scale to >= {scale * need / lengths[k]:.4g} mm per design unit"
    if lengths[k] < hole:
        raise FabricationError(
            f"the two {hole:g} mm holes of bar {k} (joints {i}-{j}) overlap: the bar is only "
            f"{lengths[k]:.3f} mm long and needs >= {need:.2f} mm{fix}")
    raise FabricationError(
        f"bar {k} (joints {i}-{j}) is too short: {lengths[k]:.3f} mm between hole centres leaves "
        f"{lengths[k] - hole:.2f} mm of web between its holes, below the minimum "
        f"{settings.min_web:.2f} mm; it needs >= {need:.2f} mm{fix}")


def bar_set(lengths_mm, edges, settings, *, scale: float | None = None) -> BarSet:
    """Bars for the given hole-centre distances, after the fabrication checks.

    Parameters
    ----------
    lengths_mm : array_like, shape (E,)
    edges : array_like of int, shape (E, 2)
    settings : LaserSettings
        Bar width, hole (from the screw entry), kerf and minimum web (already validated
        against each other by :func:`~fabkit.settings.laser.laser_settings`).
    scale : float, optional
        Only used to suggest a fix in error messages.

    Returns
    -------
    BarSet

    Raises
    ------
    FabricationError
        A bar too short for its holes (see :func:`check_bar_lengths`).

    Examples
    --------
    >>> from fabkit.settings.laser import laser_settings
    >>> bars = bar_set([100.0], [[0, 1]], laser_settings())
    >>> bars.outline(0)[:, 2].tolist()   # bulges: straight, half circle, straight, half circle
    [0.0, 1.0, 0.0, 1.0]
    """
    lengths = np.asarray(lengths_mm, dtype=np.float64).copy()
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2).copy()
    check_bar_lengths(lengths, edges, settings, scale=scale)
    lengths.setflags(write=False)
    edges.setflags(write=False)
    return BarSet(edges=edges, lengths=lengths, width=float(settings.bar_width),
                  hole_diameter=float(settings.screw.hole_diameter), kerf=float(settings.kerf))


def bar_outline(length: float, width: float, kerf: float = 0.0) -> np.ndarray:
    """Closed round-ended outline of a bar in its own frame, counter-clockwise.

    Parameters
    ----------
    length : float
        Hole-centre distance (mm); the holes are at (0, 0) and (length, 0).
    width : float
        Bar width (mm).
    kerf : float
        The outline is offset outwards by ``kerf / 2``.

    Returns
    -------
    numpy.ndarray, shape (4, 3)
        Vertices ``(x, y, bulge)``; the bulge belongs to the segment leaving the vertex
        (1 = counter-clockwise half circle), the polyline is closed.

    Examples
    --------
    >>> bar_outline(30.0, 14.0).tolist()
    [[0.0, -7.0, 0.0], [30.0, -7.0, 1.0], [30.0, 7.0, 0.0], [0.0, 7.0, 1.0]]
    """
    r = outline_radius(width, kerf)
    L = float(length)
    return np.array([[0.0, -r, 0.0], [L, -r, 1.0], [L, r, 0.0], [0.0, r, 1.0]])


def _angle(deg: float) -> float:
    """Degrees in [0, 360), with -0 and round-off just below 360 mapped to 0."""
    a = float(deg) % 360.0
    return 0.0 if a >= 360.0 - ANGLE_SLACK_DEG else a + 0.0


def bulge_primitives(vertices) -> list[tuple]:
    """Explode a closed bulge polyline into exact lines and arcs (the LINE/ARC flavour).

    Parameters
    ----------
    vertices : array_like, shape (K, 3)
        ``(x, y, bulge)`` rows of a closed polyline.

    Returns
    -------
    list of tuple
        ``("line", (x0, y0), (x1, y1))`` or ``("arc", (cx, cy), radius, start_deg, end_deg)``;
        arcs run counter-clockwise from start to end angle, as DXF ARC entities do.
    """
    v = np.asarray(vertices, dtype=np.float64)
    out = []
    for k in range(v.shape[0]):
        p, q, b = v[k, :2], v[(k + 1) % v.shape[0], :2], v[k, 2]
        if b == 0.0:
            out.append(("line", (float(p[0]), float(p[1])), (float(q[0]), float(q[1]))))
            continue
        theta = 4.0 * np.arctan(b)              # signed included angle
        chord = q - p
        c = np.hypot(*chord)
        r = c / (2.0 * np.sin(abs(theta) / 2.0))
        mid = 0.5 * (p + q)
        # distance from chord midpoint to centre, towards the left of p->q for a CCW arc
        h = r * np.cos(abs(theta) / 2.0)
        left = np.array([-chord[1], chord[0]]) / c
        centre = mid + np.sign(theta) * h * left if abs(theta) <= np.pi else mid - np.sign(theta) * h * left
        a0 = np.degrees(np.arctan2(*(p - centre)[::-1]))
        a1 = np.degrees(np.arctan2(*(q - centre)[::-1]))
        if theta < 0:  # clockwise: DXF arcs are counter-clockwise, so swap the ends
            a0, a1 = a1, a0
        out.append(("arc", (float(centre[0]), float(centre[1])), float(r),
                    _angle(a0), _angle(a1)))
    return out


def stadium_polygon(p, q, r: float, n: int = 12) -> np.ndarray:
    """A bar's round-ended outline as a polygon, for drawings (the cut files use exact arcs).

    Parameters
    ----------
    p, q : array_like, shape (2,)
        The bar's joint centres.
    r : float
        Half the bar width.
    n : int
        Points per half circle.

    Returns
    -------
    numpy.ndarray, shape (2 n, 2)
        Counter-clockwise.

    Examples
    --------
    >>> poly = stadium_polygon([0.0, 0.0], [10.0, 0.0], 2.0)
    >>> poly.shape, float(poly[:, 1].max()), bool(11.9 < poly[:, 0].max() <= 12.0)
    ((24, 2), 2.0, True)
    """
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    d = q - p
    a = math.atan2(d[1], d[0])
    t1 = np.linspace(a - math.pi / 2, a + math.pi / 2, n)
    t0 = np.linspace(a + math.pi / 2, a + 3 * math.pi / 2, n)
    return np.concatenate([q + r * np.stack([np.cos(t1), np.sin(t1)], 1),
                           p + r * np.stack([np.cos(t0), np.sin(t0)], 1)])
