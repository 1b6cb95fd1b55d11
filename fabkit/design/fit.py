"""How well a chain's final state follows its curve: the best rigid fit of the chain onto the
curve, the distances that remain, and the proportions that mean something for that curve.

The fit starts from the points at equal arclength (the chain is laid along the curve from its
start, in the drawing's direction) and is refined by a few rounds of closest points (iterative
closest points, each closest point sought near the arclength of the last, so the chain never
jumps to another pass of a curve that crosses itself, and both ends held to the curve's ends):
the rigid motion that brings the chain closest to the curve, mirror images excluded. The errors
are distances of the fitted chain's points to the curve, as a set, and of its ends to the
curve's ends, in mm and as fractions of the curve's size (the diagonal of its bounding box).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..numerics import TINY, apply_fit, rigid_fit

__all__ = ["CurveFit", "fit_to_curve", "arclength", "point_at", "polyline_distance",
           "curve_size", "describe_curve", "circle_fit", "turning"]

#: Rounds of closest points after the fit at equal arclength.
ICP_ROUNDS = 12
#: Each end of the chain counts like this many of its points in the fit: a chain must cover its
#: curve end to end, and a fit that slides it along the curve hides a missing module.
END_WEIGHT = 4
#: While fitting, the curve is sampled at this many points per step of the chain.
COARSE = 10
#: A circle is part of the description only when the curve is one: its points lie within this
#: fraction of the radius from the fitted circle (RMS), over at least ``MIN_ARC_DEG``.
ARC_RTOL = 0.01
MIN_ARC_DEG = 5.0
#: A curve whose ends are this close (fraction of its size) is closed: it has no chord.
CLOSED_RTOL = 0.01
#: The closest points have settled when none moves by more than this (relative to the curve's
#: length) in a round.
SETTLED_RTOL = 1e-9


def arclength(points) -> np.ndarray:
    """Cumulative arclength at every point of a polyline, shape (M,)."""
    p = np.asarray(points, dtype=np.float64)
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


def point_at(points, s_nodes, s) -> np.ndarray:
    """Points of a polyline at arclengths ``s`` (clipped to its ends), shape s.shape + (2,)."""
    p = np.asarray(points, dtype=np.float64)
    s = np.clip(np.asarray(s, dtype=np.float64), 0.0, s_nodes[-1])
    return np.stack([np.interp(s, s_nodes, p[:, 0]), np.interp(s, s_nodes, p[:, 1])], axis=-1)


def closest_on_curve(points, curve, s_nodes, near, window):
    """Closest points of ``curve`` to ``points`` among the segments within ``window`` of
    arclength around ``near``.

    Parameters
    ----------
    points : numpy.ndarray, shape (P, 2)
        The points to project.
    curve : numpy.ndarray, shape (K + 1, 2)
        The curve's polyline.
    s_nodes : numpy.ndarray, shape (K + 1,)
        Arclength at each of its vertices (:func:`arclength`).
    near : numpy.ndarray, shape (P,)
        Arclength around which each point's closest point is sought.
    window : float
        Arclength on either side of ``near`` searched.

    Returns
    -------
    distance : numpy.ndarray, shape (P,)
    s : numpy.ndarray, shape (P,)
        Arclength of each closest point.
    closest : numpy.ndarray, shape (P, 2)
    """
    n = len(curve) - 1
    lo = np.searchsorted(s_nodes, near - window, side="right") - 1
    hi = np.searchsorted(s_nodes, near + window, side="left")
    width = int(np.max(hi - lo)) + 1
    idx = np.clip(lo[:, None] + np.arange(width)[None, :], 0, n - 1)
    a, b = curve[idx], curve[idx + 1]
    ab = b - a
    p = points[:, None, :]
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), TINY),
                0.0, 1.0)
    q = a + t[..., None] * ab
    d = np.linalg.norm(p - q, axis=-1)
    k = np.argmin(d, axis=1)
    rows = np.arange(len(points))
    s = s_nodes[idx[rows, k]] + t[rows, k] * np.linalg.norm(ab[rows, k], axis=-1)
    return d[rows, k], s, q[rows, k]


def polyline_distance(points, polyline) -> np.ndarray:
    """Distance of each point to a polyline (as a set), shape (P,): the nearest vertex is found
    with a k-d tree, and the distance measured to the two segments that meet there (exact for
    a polyline sampled finely against the distances, as a drawn curve's 2 points per mm are).

    Examples
    --------
    >>> polyline_distance([[0.5, 1.0], [2.0, 0.0]], [[0, 0], [0.5, 0], [1, 0]]).tolist()
    [1.0, 1.0]
    """
    from scipy.spatial import cKDTree

    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    line = np.asarray(polyline, dtype=np.float64)
    if len(p) == 0:
        return np.zeros(0)
    if len(line) == 1:
        return np.linalg.norm(p - line[0], axis=1)
    _, i = cKDTree(line).query(p)
    best = np.full(len(p), np.inf)
    for a_i in (i - 1, i):
        a_i = np.clip(a_i, 0, len(line) - 2)
        a, b = line[a_i], line[a_i + 1]
        ab = b - a
        t = np.clip(np.sum((p - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), TINY),
                    0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(p - a - t[:, None] * ab, axis=1))
    return best


def curve_size(points) -> float:
    """The diagonal of a curve's bounding box: the size errors are measured against."""
    p = np.asarray(points, dtype=np.float64)
    return float(np.linalg.norm(np.ptp(p, axis=0)))


@dataclass(frozen=True)
class CurveFit:
    """A chain's points rigidly fitted onto a curve.

    Attributes
    ----------
    points : numpy.ndarray, shape (K, 2)
        The chain's points after the fit.
    rotation : numpy.ndarray, shape (2, 2)
    translation : numpy.ndarray, shape (2,)
        ``points = rotation @ original + translation``.
    errors : dict
        ``mean``, ``rms``, ``max`` (distance of the points to the curve), ``start``, ``end``
        (of the chain's first and last point to the curve's), all in the curve's length unit,
        and the same divided by the curve's size as ``*_fraction``; ``size`` itself.
    """

    points: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    errors: dict

    def apply(self, x) -> np.ndarray:
        """Move other points (e.g. every node of the chain) by the same rigid motion."""
        x = np.asarray(x, dtype=np.float64)
        return x @ self.rotation.T + self.translation


def _coarse(curve: np.ndarray, chain: np.ndarray) -> np.ndarray:
    """The curve resampled at a tenth of the chain's mean step (at most its own points): what
    the closest points are sought on while fitting; the errors are measured on the curve."""
    s = arclength(curve)
    step = float(arclength(chain)[-1]) / max(len(chain) - 1, 1) / COARSE
    n = int(min(len(curve), max(2, math.ceil(s[-1] / max(step, TINY)) + 1)))
    if n >= len(curve):
        return curve
    return point_at(curve, s, np.linspace(0.0, s[-1], n))


def fit_to_curve(points, curve, *, rounds: int = ICP_ROUNDS) -> CurveFit:
    """The best rigid fit (no mirror) of a chain's points onto a curve, chain start at the
    curve's start.

    Parameters
    ----------
    points : array_like, shape (K, 2)
        The chain's centre line (or any ordered points along it).
    curve : array_like, shape (M, 2)
        The curve, from its start to its end.
    rounds : int
        Rounds of closest points after the fit at equal arclength.

    Returns
    -------
    CurveFit

    Examples
    --------
    >>> t = np.linspace(0, np.pi / 2, 199)
    >>> arc = np.column_stack([np.cos(t), np.sin(t)])
    >>> pts = arc[::11]                                     # 19 points, both ends included
    >>> moved = pts @ np.array([[0, -1], [1, 0]]).T + [3, 4]   # the same points, moved
    >>> f = fit_to_curve(moved, arc)
    >>> f.errors["max"] < 1e-4 and f.errors["end"] < 1e-4
    True
    """
    src = np.asarray(points, dtype=np.float64)
    full = np.asarray(curve, dtype=np.float64)
    crv = _coarse(full, src)
    s_curve = arclength(crv)
    s_chain = arclength(src)
    length = float(s_curve[-1])
    near = np.clip(s_chain * (length / max(float(s_chain[-1]), TINY)), 0.0, length)
    ends = np.r_[np.zeros(END_WEIGHT, dtype=int), np.full(END_WEIGHT, len(src) - 1)]
    end_targets = np.r_[np.repeat(crv[:1], END_WEIGHT, axis=0), np.repeat(crv[-1:], END_WEIGHT,
                                                                          axis=0)]
    dst = point_at(crv, s_curve, near)
    window = max(0.01 * length, 4.0 * float(np.max(np.diff(s_chain))) if len(src) > 1 else 0.0)
    move = None
    for _ in range(int(rounds) + 1):
        move = rigid_fit(np.r_[src, src[ends]], np.r_[dst, end_targets], handedness="proper")
        moved = apply_fit(move, src)
        _, near_new, dst = closest_on_curve(moved, crv, s_curve, near, window)
        if np.allclose(near_new, near, atol=SETTLED_RTOL * length, rtol=0.0):
            break
        near = near_new
    moved = apply_fit(move, src)
    crv = full
    dist = polyline_distance(moved, crv)
    size = curve_size(crv) or 1.0
    errors = {"mean": float(dist.mean()), "rms": float(np.sqrt(np.mean(dist ** 2))),
              "max": float(dist.max()), "start": float(np.linalg.norm(moved[0] - crv[0])),
              "end": float(np.linalg.norm(moved[-1] - crv[-1])), "size": size}
    for key in ("mean", "rms", "max", "start", "end"):
        errors[f"{key}_fraction"] = errors[key] / size
    rotation = np.asarray(move.rotation, dtype=np.float64)
    translation = np.asarray(move.shift, dtype=np.float64)
    return CurveFit(points=moved, rotation=rotation, translation=translation, errors=errors)


def circle_fit(points) -> tuple[float, np.ndarray, float, float]:
    """Least-squares circle through points (algebraic fit, refined by Gauss-Newton on the
    geometric distances).

    Parameters
    ----------
    points : array_like, shape (M, 2)

    Returns
    -------
    radius : float
    centre : numpy.ndarray, shape (2,)
    sweep : float
        Angle (radians) the points sweep around the centre, first to last.
    residual : float
        RMS distance of the points from the circle.

    Examples
    --------
    >>> t = np.linspace(0, np.pi / 2, 50)
    >>> r, c, a, res = circle_fit(np.column_stack([3 + 2 * np.cos(t), 1 + 2 * np.sin(t)]))
    >>> round(r, 9), [round(float(v), 9) for v in c], round(float(np.degrees(a)), 6)
    (2.0, [3.0, 1.0], 90.0)
    """
    p = np.asarray(points, dtype=np.float64)
    A = np.column_stack([2 * p, np.ones(len(p))])
    sol = np.linalg.lstsq(A, np.sum(p * p, axis=1), rcond=None)[0]
    c = sol[:2]
    r = math.sqrt(max(sol[2] + c @ c, 0.0))
    for _ in range(20):
        d = p - c
        dist = np.maximum(np.linalg.norm(d, axis=1), TINY)
        J = np.column_stack([-d / dist[:, None], -np.ones(len(p))])
        step = np.linalg.lstsq(J, -(dist - r), rcond=None)[0]
        if not np.all(np.isfinite(step)):
            break
        c, r = c + step[:2], r + step[2]
    ang = np.unwrap(np.arctan2(p[:, 1] - c[1], p[:, 0] - c[0]))
    residual = float(np.sqrt(np.mean((np.linalg.norm(p - c, axis=1) - r) ** 2)))
    return float(abs(r)), c, float(abs(ang[-1] - ang[0])), residual


def turning(points) -> float:
    """Total signed turn (radians) of the curve a polyline samples, end to end: the turns
    between its segments, plus half the first and half the last for the stretches from the
    ends to the middle of the first and last segment (a chain's centre line, a point per
    module, would otherwise miss a module's worth of an arc's turn).

    Examples
    --------
    >>> t = np.linspace(0, np.pi, 17)
    >>> round(float(np.degrees(turning(np.column_stack([np.cos(t), np.sin(t)])))), 6)
    180.0
    """
    d = np.diff(np.asarray(points, dtype=np.float64), axis=0)
    d = d[np.linalg.norm(d, axis=1) > 0]
    if len(d) < 2:
        return 0.0
    cross = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]
    turns = np.arctan2(cross, np.sum(d[:-1] * d[1:], axis=1))
    return float(np.sum(turns) + 0.5 * (turns[0] + turns[-1]))


def describe_curve(points) -> dict:
    """What describes a curve's proportions: its length, size (bounding-box diagonal), total
    turn, its chord unless it is closed (ends within ``CLOSED_RTOL`` of its size), and, only
    when it is a circular arc (points within ``ARC_RTOL`` of the radius
    from a circle, over at least ``MIN_ARC_DEG``), that circle's radius and sweep.

    Examples
    --------
    >>> sorted(describe_curve([[0, 0], [1, 0], [2, 0]]))
    ['chord', 'length', 'size', 'turn_deg']
    """
    p = np.asarray(points, dtype=np.float64)
    out = {"length": float(arclength(p)[-1]), "size": curve_size(p),
           "turn_deg": math.degrees(turning(p))}
    chord = float(np.linalg.norm(p[-1] - p[0]))
    if chord > CLOSED_RTOL * out["size"]:
        out["chord"] = chord
    else:
        out["closed"] = True
    if len(p) >= 3:
        r, _, sweep, residual = circle_fit(p)
        if (math.isfinite(r) and r > 0 and residual <= ARC_RTOL * r
                and math.degrees(sweep) >= MIN_ARC_DEG):
            out["circle_radius"] = r
            out["circle_sweep_deg"] = math.degrees(sweep)
    return out
