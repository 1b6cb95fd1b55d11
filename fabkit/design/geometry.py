"""Shared geometry of designed modules: designed triangles, designed velocities, and the measures
of buildability that choose between candidate designs.

Every 5-node module here has designed nodes 0, 1, 2 (ports d1 = (0, 1), d2 = (1, 2)) and two
variable nodes 3, 4, each joined to all three designed nodes (the paper's construction).
"""

from __future__ import annotations

import numpy as np

from ..numerics import TINY

#: Port pairs of every designed module (the paper's numbering).
D1_PAIR = (0, 1)
D2_PAIR = (1, 2)
#: Edges of a module: each variable node (3, 4) joined to each designed node (0, 1, 2).
MODULE_EDGES = np.array([[0, 3], [1, 3], [2, 3], [0, 4], [1, 4], [2, 4]], dtype=np.int64)


def triangle(left: float, right: float, apex: float) -> np.ndarray:
    """Designed nodes with |x0 - x1| = ``left``, |x1 - x2| = ``right`` and the angle ``apex``
    (radians) at node 1; node 1 on top, the triangle's centroid at the origin.

    Returns
    -------
    numpy.ndarray, shape (3, 2)

    Examples
    --------
    >>> x = triangle(1.0, 1.0, np.pi / 3)
    >>> [round(float(np.linalg.norm(x[i] - x[j])), 12) for i, j in ((0, 1), (1, 2), (0, 2))]
    [1.0, 1.0, 1.0]
    """
    h = 0.5 * apex
    x = np.array([[-left * np.sin(h), -left * np.cos(h)], [0.0, 0.0],
                  [right * np.sin(h), -right * np.cos(h)]])
    return x - x.mean(axis=0)


def slope_velocities(x: np.ndarray, slope: float, turn: float) -> np.ndarray:
    """Velocities of the designed nodes that change d1 at unit rate and d2 at rate ``slope``.

    Node 1 stands still; node 0 moves along its leg (d1 grows at rate 1), node 2 along its leg
    at rate ``slope`` and across it at rate ``turn`` (leg 2 turns about node 1 relative to
    leg 0; a common turn is a rigid rotation and changes nothing). ``turn`` is the one free
    choice of a velocity design with a given slope: it sets how fast the apex angle opens.

    Returns
    -------
    numpy.ndarray, shape (3, 2)
    """
    u0 = (x[0] - x[1]) / np.linalg.norm(x[0] - x[1])
    leg2 = x[2] - x[1]
    u2 = leg2 / np.linalg.norm(leg2)
    n2 = np.array([-u2[1], u2[0]])
    v = np.zeros((3, 2))
    v[0] = u0
    v[2] = slope * u2 + turn * n2
    return v


def module_positions(designed: np.ndarray, variable: np.ndarray) -> np.ndarray:
    """The module's five nodes: designed (3, 2) then variable (2, 2)."""
    return np.concatenate([np.asarray(designed, float), np.asarray(variable, float)], axis=0)


def bar_lengths(x: np.ndarray) -> np.ndarray:
    """Lengths of the six bars of configurations ``x`` (..., 5, 2), shape (..., 6)."""
    x = np.asarray(x, dtype=np.float64)
    return np.linalg.norm(x[..., MODULE_EDGES[:, 0], :] - x[..., MODULE_EDGES[:, 1], :], axis=-1)


def rigidity_margin(x: np.ndarray) -> np.ndarray:
    """Smallest non-zero singular value of the row-normalised rigidity matrix of each
    configuration (a module with one motion has rank 6): how far it is from gaining a motion or
    a state of self-stress. Scale-free; near 0 is a nearly flat, ill-conditioned module.

    Parameters
    ----------
    x : array_like, shape (K, 5, 2) or (5, 2)

    Returns
    -------
    numpy.ndarray, shape (K,) or ()
    """
    x = np.asarray(x, dtype=np.float64)
    single = x.ndim == 2
    X = x[None] if single else x
    k = X.shape[0]
    diff = X[:, MODULE_EDGES[:, 0]] - X[:, MODULE_EDGES[:, 1]]
    u = diff / np.maximum(np.linalg.norm(diff, axis=2, keepdims=True), TINY)
    R = np.zeros((k, 6, 5, 2))
    rows = np.arange(6)
    R[:, rows, MODULE_EDGES[:, 0]] = u
    R[:, rows, MODULE_EDGES[:, 1]] = -u
    s = np.linalg.svd(R.reshape(k, 6, 10), compute_uv=False)
    out = s[:, 5]
    return out[0] if single else out


def joint_separation(x: np.ndarray) -> np.ndarray:
    """Least distance between two joints of each configuration (..., 5, 2), shape (...)."""
    x = np.asarray(x, dtype=np.float64)
    i, j = np.triu_indices(5, 1)
    return np.linalg.norm(x[..., i, :] - x[..., j, :], axis=-1).min(axis=-1)


def bar_clearance(x: np.ndarray) -> np.ndarray:
    """Least distance from a joint to a bar not ending at it, in configurations (..., 5, 2):
    how close a bar sweeps past another joint's screw.

    Returns
    -------
    numpy.ndarray, shape (...)
    """
    x = np.asarray(x, dtype=np.float64)
    pairs = [(j, e) for j in range(5) for e in range(len(MODULE_EDGES)) if j not in MODULE_EDGES[e]]
    joints = np.array([j for j, _ in pairs])
    a = x[..., MODULE_EDGES[[e for _, e in pairs], 0], :]
    b = x[..., MODULE_EDGES[[e for _, e in pairs], 1], :]
    p = x[..., joints, :]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), TINY), 0, 1)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1).min(axis=-1)


def inside_margin(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Smallest barycentric coordinate of each point in the triangle ``tri`` (3, 2): positive
    inside, negative outside, 0 on a side.

    Parameters
    ----------
    points : array_like, shape (..., P, 2)
    tri : array_like, shape (..., 3, 2)

    Returns
    -------
    numpy.ndarray, shape (..., P)
    """
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(tri, dtype=np.float64)
    a, b, c = t[..., 0, :], t[..., 1, :], t[..., 2, :]
    e1, e2 = b - a, c - a
    det = e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]
    r = p - a[..., None, :]
    l1 = (r[..., 0] * e2[..., None, 1] - r[..., 1] * e2[..., None, 0]) / det[..., None]
    l2 = (e1[..., None, 0] * r[..., 1] - e1[..., None, 1] * r[..., 0]) / det[..., None]
    return np.minimum(np.minimum(1.0 - l1 - l2, l1), l2)


def length_gains(x: np.ndarray) -> tuple[float, np.ndarray]:
    """Exact slope of the map and the rates of d2 per unit change of each bar length, at d1
    held fixed (implicit differentiation of the edge constraints).

    Parameters
    ----------
    x : array_like, shape (5, 2)
        A configuration of the module.

    Returns
    -------
    slope : float
        d(d2)/d(d1) along the motion.
    gains : numpy.ndarray, shape (6,)
        ∂d2/∂L_e for each bar e (d1 fixed).
    """
    x = np.asarray(x, dtype=np.float64)
    J = np.zeros((7, 5, 2))
    diff = x[MODULE_EDGES[:, 0]] - x[MODULE_EDGES[:, 1]]
    u = diff / np.linalg.norm(diff, axis=1, keepdims=True)
    rows = np.arange(6)
    J[rows, MODULE_EDGES[:, 0]] = u
    J[rows, MODULE_EDGES[:, 1]] = -u
    a, b = D1_PAIR
    w1 = (x[a] - x[b]) / np.linalg.norm(x[a] - x[b])
    J[6, a] = w1
    J[6, b] = -w1
    rhs = np.zeros((7, 7))
    rhs[np.arange(7), np.arange(7)] = 1.0  # column e < 6: bar e grows; column 6: d1 grows
    V = np.linalg.lstsq(J.reshape(7, 10), rhs, rcond=None)[0].T.reshape(7, 5, 2)
    i, j = D2_PAIR
    w2 = (x[i] - x[j]) / np.linalg.norm(x[i] - x[j])
    rates = np.einsum("c,kc->k", w2, V[:, i] - V[:, j])
    return float(rates[6]), rates[:6]


def fixed_point_gain(x: np.ndarray) -> float:
    """Worst-case shift of a fixed point per unit of bar-length error: Σ_e |∂D*/∂L_e| with
    ∂D*/∂L_e = (∂f/∂L_e) / (1 - f'(D*)). A laser-cut bar errs by about 0.1 mm, so at 100 mm per
    design unit the fixed point moves by at most gain × 0.001 design units. Infinite for a
    neutral fixed point (slope 1), whose position no bar length pins down.

    Parameters
    ----------
    x : array_like, shape (5, 2)
        The module at its fixed point.
    """
    slope, gains = length_gains(x)
    denom = abs(1.0 - slope)
    if denom <= TINY:
        return float("inf")
    return float(np.sum(np.abs(gains)) / denom)


#: The triangles of the module's construction from the d1 pair: the variable nodes 3 and 4 are
#: placed from nodes 0 and 1 (their only placed neighbours), node 2 from 3 and 4 (its only bars).
#: Their orientations can only change through a flat state, where a branch of the motion ends.
BRANCH_TRIANGLES = np.array([[0, 1, 3], [0, 1, 4], [3, 4, 2]])


def branch_signs(x: np.ndarray) -> np.ndarray:
    """Orientation (+1/-1) of each of ``BRANCH_TRIANGLES`` in configurations (..., 5, 2).

    Two configurations of one module with different signs lie on different branches of its
    motion (one of these triangles must pass through flat between them).
    """
    x = np.asarray(x, dtype=np.float64)
    a = x[..., BRANCH_TRIANGLES[:, 0], :]
    b = x[..., BRANCH_TRIANGLES[:, 1], :]
    c = x[..., BRANCH_TRIANGLES[:, 2], :]
    u, w = b - a, c - a
    return np.sign(u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0])


def _intersect(a, b, ra, rb, sign):
    """The point c with |c - a| = ra, |c - b| = rb on the side ``sign`` of a → b (the sign of
    the cross product (b - a) × (c - a)); NaN where the circles do not meet. Broadcasts."""
    ab = b - a
    d = np.linalg.norm(ab, axis=-1)
    e = ab / np.maximum(d, TINY)[..., None]
    n = np.stack([-e[..., 1], e[..., 0]], axis=-1)
    x = (d * d + ra * ra - rb * rb) / np.maximum(2.0 * d, TINY)
    h2 = ra * ra - x * x
    h = np.sqrt(np.where(h2 >= 0.0, h2, np.nan))
    return a + x[..., None] * e + (sign * h)[..., None] * n


def module_motion(lengths, signs, d1) -> np.ndarray:
    """Configurations of 5-node modules (bars ``MODULE_EDGES``) at the drive values ``d1``,
    placed by circle intersections on the branch given by ``signs`` (vectorised over modules
    and drive values: the constructive model of :mod:`fabkit.kinematics`, for many candidate or
    built modules at once).

    Node 0 sits at the origin and node 1 at (d1, 0); nodes 3 and 4 follow from nodes 0 and 1,
    node 2 from nodes 3 and 4, each on the side of its construction triangle that ``signs``
    gives (see :func:`branch_signs`).

    Parameters
    ----------
    lengths : array_like, shape (P, 6)
        Bar lengths in the order of ``MODULE_EDGES``.
    signs : array_like, shape (P, 3)
        Orientation of each of ``BRANCH_TRIANGLES`` on the branch.
    d1 : array_like, shape (S,) or (P, S)
        Drive values |x0 - x1|.

    Returns
    -------
    numpy.ndarray, shape (P, S, 5, 2)
        NaN where a node cannot be placed: the drive value lies beyond a turning point of
        the branch.

    Examples
    --------
    >>> x = triangle(1.0, 1.0, np.radians(110.0))
    >>> var = np.array([[-0.2, 0.05], [0.2, 0.05]])
    >>> nodes = module_positions(x, var)
    >>> xs = module_motion(bar_lengths(nodes)[None], branch_signs(nodes)[None], [1.0])
    >>> bool(np.allclose(bar_lengths(xs[0, 0]), bar_lengths(nodes)))
    True
    """
    L = np.asarray(lengths, dtype=np.float64)
    sg = np.asarray(signs, dtype=np.float64)
    t = np.asarray(d1, dtype=np.float64)
    if t.ndim == 1:
        t = np.broadcast_to(t, (L.shape[0], t.size))
    p, s = t.shape
    out = np.full((p, s, 5, 2), np.nan)
    out[:, :, 0] = 0.0
    out[:, :, 1, 0] = t
    out[:, :, 1, 1] = 0.0
    a, b = out[:, :, 0], out[:, :, 1]
    col = lambda k: L[:, k][:, None]  # noqa: E731
    out[:, :, 3] = _intersect(a, b, col(0), col(1), sg[:, 0][:, None])
    out[:, :, 4] = _intersect(a, b, col(3), col(4), sg[:, 1][:, None])
    out[:, :, 2] = _intersect(out[:, :, 3], out[:, :, 4], col(2), col(5), sg[:, 2][:, None])
    return out
