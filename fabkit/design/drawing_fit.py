"""How closely a designed chain folds onto its drawing, measured the way a maker would check it.

The chain is traced with fabkit's simulator (``constructive``, from its initial state to its
final one), its port midpoints (the centre line) and its designed nodes (the joints of the ports)
are taken from the traced final state, and the centre line is laid on the drawing by the best
rigid motion (no mirror): the one that minimises the mean squared distance of the midpoints to
the drawn curve (as a set, the curve sampled every ``1 / DENSE`` of its size), the chain's two
ends counting as two more points whose targets are the drawing's two ends. The search starts
from the points at equal arclength (Kabsch) and from the designer's own fit
(:func:`~fabkit.design.fit.fit_to_curve`), and polishes each with Nelder-Mead; the better is
kept. Nothing of the designer's zigzag model is used: only the network, its scale and the
drawing.

Distances are fractions of the drawing's size (the diagonal of its bounding box): the mean and
largest distance of the midpoints to the curve, the distance of the chain's first and last
midpoint to the drawing's first and last point, and the mean and largest distance of the
designed nodes to the curve.

The designed nodes (every end of every port, in the traced final state, moved by the fit of
the midpoints) are measured against the drawn curve itself: not against the curve offset by
half a module's width, nor against where the designer's model puts them. A drawing is a line;
a chain is a strip whose nodes lie half a module's width off its centre line on either side.
Nodes within 1 % of the size then say that the whole chain, as built, lies on the line drawn
(its width small against the drawing), which is what a maker sees when the chain is laid on
the drawing. The model's own node positions would say only that the trace reproduces the
model, which the midpoints nearly say already (the model's nodes lie as far from the curve
as the traced ones, on average, to within 0.01 % of the size: docs/design.md); an offset curve
would hide the width altogether.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import DesignError
from ..kinematics import trace
from ..numerics import rigid_fit, TINY
from .curvature import LEG_RATIO
from .fit import arclength, curve_size, fit_to_curve, point_at
from .letters import chain_centerline

__all__ = ["DrawingFit", "fold_onto_drawing", "fit_final_state", "fit_onto_drawing"]

#: The drawing is sampled at this many points per its size (diagonal) for nearest distances:
#: the nearest sample is within half a step, 0.0025 % of the size, of the nearest curve point.
DENSE = 20000
#: Nelder-Mead: tolerance on the angle (radians) and on the shift (fraction of the size), and
#: on the cost (fraction of the size, squared); evaluations at most.
FIT_XATOL = 1e-7
FIT_FATOL = 1e-14
FIT_EVALUATIONS = 4000
#: A traced chain must keep its bars to this (relative to its scale, design units).
EDGE_ATOL = 1e-9


@dataclass(frozen=True, eq=False)
class DrawingFit:
    """A traced chain laid on its drawing.

    Attributes
    ----------
    mean, max : float
        Distance of the port midpoints to the curve, fractions of the drawing's size.
    start, end : float
        Distance of the chain's first and last port midpoint to the drawing's first and last
        point, fractions of its size.
    nodes_mean, nodes_max : float
        Distance of the designed nodes (the joints of the ports) to the curve, fractions.
    size : float
        The drawing's size (bounding-box diagonal), mm.
    midpoints, nodes : numpy.ndarray, shape (K + 1, 2), (P, 2)
        The fitted midpoints and nodes, mm, in the drawing's frame.
    """

    mean: float
    max: float
    start: float
    end: float
    nodes_mean: float
    nodes_max: float
    size: float
    midpoints: np.ndarray
    nodes: np.ndarray

    def percent(self) -> dict:
        """The distances as percentages of the drawing's size, by name."""
        return {k: 100.0 * getattr(self, k)
                for k in ("mean", "max", "start", "end", "nodes_mean", "nodes_max")}

    def line(self) -> str:
        """One line: the mean and the ends (and the nodes) as percentages of the size."""
        p = self.percent()
        return (f"port midpoints {p['mean']:.3g} % of the drawing's size on average (largest "
                f"{p['max']:.3g} %), ends {p['start']:.3g} % / {p['end']:.3g} %; designed nodes "
                f"{p['nodes_mean']:.3g} % on average")


def _dense(curve: np.ndarray) -> np.ndarray:
    s = arclength(curve)
    n = int(min(2_000_000, max(2, math.ceil(DENSE * s[-1] / max(curve_size(curve), TINY)))))
    return point_at(curve, s, np.linspace(0.0, s[-1], n + 1))


def _moved(points: np.ndarray, p: np.ndarray, size: float) -> np.ndarray:
    c, s = math.cos(p[0]), math.sin(p[0])
    return points @ np.array([[c, -s], [s, c]]).T + size * p[1:]


def _start(points: np.ndarray, curve: np.ndarray, size: float) -> np.ndarray:
    """The rigid motion (angle, shift / size) of the points at equal arclength (Kabsch)."""
    s_c, s_k = arclength(points), arclength(curve)
    ref = point_at(curve, s_k, s_c * s_k[-1] / max(s_c[-1], TINY))
    move = rigid_fit(points, ref, handedness="proper")
    rot = np.asarray(move.rotation, dtype=np.float64)
    return np.array([math.atan2(rot[1, 0], rot[0, 0]), *(np.asarray(move.shift) / size)])


def fit_onto_drawing(midpoints, curve) -> tuple[np.ndarray, np.ndarray]:
    """The best rigid motion (no mirror) of a chain's port midpoints onto a drawn curve.

    Parameters
    ----------
    midpoints : array_like, shape (K + 1, 2)
        The chain's centre line, mm, in any frame.
    curve : array_like, shape (M, 2)
        The drawing, mm, from its start to its end.

    Returns
    -------
    rotation : numpy.ndarray, shape (2, 2)
    shift : numpy.ndarray, shape (2,)
        ``fitted = midpoints @ rotation.T + shift``.

    Examples
    --------
    >>> t = np.linspace(0, np.pi / 2, 400)
    >>> arc = np.column_stack([np.cos(t), np.sin(t)]) * 100
    >>> pts = arc[::21] @ np.array([[0, -1], [1, 0]]).T + [30, 40]
    >>> rot, shift = fit_onto_drawing(pts, arc)
    >>> float(np.abs(pts @ rot.T + shift - arc[::21]).max()) < 1e-3
    True
    """
    from scipy.optimize import minimize
    from scipy.spatial import cKDTree

    pts = np.asarray(midpoints, dtype=np.float64)
    crv = np.asarray(curve, dtype=np.float64)
    size = curve_size(crv) or 1.0
    tree = cKDTree(_dense(crv))
    ends = crv[[0, -1]]

    def cost(p):
        m = _moved(pts, p, size)
        near = tree.query(m)[0]
        return float((np.sum(near ** 2) + np.sum((m[[0, -1]] - ends) ** 2))
                     / (len(m) + 2) / size ** 2)

    own = fit_to_curve(pts, crv)
    starts = [_start(pts, crv, size),
              np.array([math.atan2(own.rotation[1, 0], own.rotation[0, 0]),
                        *(own.translation / size)])]
    best = None
    for p0 in starts:
        r = minimize(cost, p0, method="Nelder-Mead",
                     options={"xatol": FIT_XATOL, "fatol": FIT_FATOL,
                              "maxfev": FIT_EVALUATIONS})
        if best is None or r.fun < best.fun:
            best = r
    c, s = math.cos(best.x[0]), math.sin(best.x[0])
    return np.array([[c, -s], [s, c]]), size * best.x[1:]


def fold_onto_drawing(network, scale: float, modules: int, curve, *,
                      to: float = LEG_RATIO) -> DrawingFit:
    """Trace a curvature chain to its final state and measure it on its drawing.

    Parameters
    ----------
    network : Network
        The chain as built (ports ``d1`` … ``d{K+1}``), design units.
    scale : float
        mm per design unit.
    modules : int
        K, the number of modules.
    curve : array_like, shape (M, 2)
        The drawing, mm.
    to : float
        The final value of ``d1`` (the modules' D2*).

    Returns
    -------
    DrawingFit

    Raises
    ------
    DesignError
        The chain does not reach its final state.
    """
    traj = trace(network, "d1", to=to, method="constructive", samples=2)
    if not traj.success or not traj.max_edge_error <= EDGE_ATOL:
        raise DesignError(f"the chain does not reach its final state: {traj.message}")
    return fit_final_state(network, np.asarray(traj.positions[-1]) * scale, modules, curve)


def fit_final_state(network, final, modules: int, curve) -> DrawingFit:
    """A chain's traced final state (mm) laid on its drawing: :func:`fold_onto_drawing` from
    the positions, for a chain already traced.

    Parameters
    ----------
    network : Network
    final : array_like, shape (N, 2)
        Every node's final position, mm.
    modules : int
    curve : array_like, shape (M, 2)

    Returns
    -------
    DrawingFit
    """
    from scipy.spatial import cKDTree

    final = np.asarray(final, dtype=np.float64)
    centre = chain_centerline(network, final, modules)
    crv = np.asarray(curve, dtype=np.float64)
    rot, shift = fit_onto_drawing(centre, crv)
    mid = centre @ rot.T + shift
    ports = np.unique([network.port(f"d{i}") for i in range(1, modules + 2)])
    nodes = final[ports] @ rot.T + shift
    tree = cKDTree(_dense(crv))
    size = curve_size(crv) or 1.0
    d_mid, d_nodes = tree.query(mid)[0], tree.query(nodes)[0]
    return DrawingFit(mean=float(d_mid.mean()) / size, max=float(d_mid.max()) / size,
                      start=float(np.linalg.norm(mid[0] - crv[0])) / size,
                      end=float(np.linalg.norm(mid[-1] - crv[-1])) / size,
                      nodes_mean=float(d_nodes.mean()) / size,
                      nodes_max=float(d_nodes.max()) / size, size=size, midpoints=mid,
                      nodes=nodes)
