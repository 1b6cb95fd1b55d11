"""Evaluation of a constructive branch: closed-form placement and exact slopes."""

from __future__ import annotations

import dataclasses

import numpy as np

from .. import arguments
from ..errors import ArgumentTypeError, KinematicsError
from ..kinematics import place
from ..model.network import Network
from ..numerics import FLAT_RTOL


#: The velocity solve of implicit differentiation must satisfy its equations to this, relative
#: to the velocity: a solvable system leaves ~1e-14; a singular one (a turning point) far more.
SLOPE_SOLVE_RTOL = 1e-8


class Constructive2D:
    """Values and exact derivatives of d_out(d_in) by the circle-intersection formulas.

    Works in the frame of the paper's analytic map: node a at the origin, node b at (d, 0), so a
    node placed from a and b needs no rotation (x = (d² + r_a² - r_b²) / 2d). The derivative is
    carried alongside every quantity (forward mode), so f' is exact to round-off. Iterating a
    map calls this in a tight loop (Lyapunov exponents), hence the lean arithmetic.

    Parameters
    ----------
    plan : fabkit.kinematics.ConstructionPlan
        The construction order from the input pair (its ``seed``), 2D.
    out_pair : tuple of int
        The nodes whose distance is d_out.

    Calling it with ``(d, signs, derivative=True, margins=True)`` gives ``(f, df, margin,
    worst)``: d_out, its derivative (None without ``derivative``), the smallest squared
    triangle height of the placements relative to the squared radius and the step where it
    occurs (None without ``margins``), each shaped like ``d``.
    """

    def __init__(self, plan, out_pair):
        self.plan = plan
        self.out = out_pair
        a, b = plan.seed
        self.steps = []
        for v, p, r in zip(plan.order, plan.parents, plan.radii):
            p, q = int(p[0]), int(p[1])
            rp2, rq2 = float(r[0]) ** 2, float(r[1]) ** 2
            # placed from the seed pair as (b, a): evaluated as (a, b) with the side flipped
            self.steps.append((int(v), p, q, rp2, rq2, (p, q) == (b, a)))

    def __call__(self, d, signs, derivative=True, margins=True):
        d = np.asarray(d, dtype=np.float64)
        a, b = self.plan.seed
        n = self.plan.n_nodes
        X = [None] * n
        Y = [None] * n
        dXs = [None] * n
        dYs = [None] * n
        X[a], Y[a], X[b], Y[b] = 0.0, 0.0, d, 0.0
        dXs[a], dYs[a], dXs[b], dYs[b] = 0.0, 0.0, 1.0, 0.0
        h2min = np.full(d.shape, np.inf) if margins else None
        worst = np.zeros(d.shape, dtype=np.int64) if margins else None
        with np.errstate(invalid="ignore", divide="ignore"):
            for k, (v, p, q, rp2, rq2, swapped) in enumerate(self.steps):
                s = signs[k]
                if swapped or (p == a and q == b):
                    if swapped:  # parents (b, a): same circle pair seen from b
                        rp2, rq2, s = rq2, rp2, -s
                    # parents a = (0, 0) and b = (d, 0): the triangle in its own frame
                    x = (d * d + rp2 - rq2) / (2.0 * d)
                    h2 = rp2 - x * x
                    h = np.sqrt(np.where(h2 >= -FLAT_RTOL * rp2, np.maximum(h2, 0.0), np.nan))
                    X[v], Y[v] = x, s * h
                    if derivative:
                        dx = 0.5 - (rp2 - rq2) / (2.0 * d * d)
                        dXs[v], dYs[v] = dx, -s * x * dx / h
                else:
                    px, py = X[p], Y[p]
                    Dx, Dy = X[q] - px, Y[q] - py
                    dist2 = Dx * Dx + Dy * Dy
                    dist = np.sqrt(dist2)
                    along = (rp2 - rq2 + dist2) / (2.0 * dist)
                    h2 = rp2 - along * along
                    h = np.sqrt(np.where(h2 >= -FLAT_RTOL * rp2, np.maximum(h2, 0.0), np.nan))
                    al, be = along / dist, s * h / dist
                    X[v], Y[v] = px + al * Dx - be * Dy, py + al * Dy + be * Dx
                    if derivative:
                        dpx, dpy = dXs[p], dYs[p]
                        dDx, dDy = dXs[q] - dpx, dYs[q] - dpy
                        ddist = (Dx * dDx + Dy * dDy) / dist
                        dalong = ddist - along * ddist / dist
                        dh = -along * dalong / h
                        dal = (dalong - al * ddist) / dist
                        dbe = (s * dh - be * ddist) / dist
                        dXs[v] = dpx + dal * Dx + al * dDx - dbe * Dy - be * dDy
                        dYs[v] = dpy + dal * Dy + al * dDy + dbe * Dx + be * dDx
                if margins:
                    rel = h2 / rp2
                    lower = rel < h2min
                    h2min = np.where(lower, rel, h2min)
                    worst = np.where(lower, k, worst)
            i, j = self.out
            ex, ey = X[i] - X[j], Y[i] - Y[j]
            f = np.sqrt(ex * ex + ey * ey)
            df = None
            if derivative:
                df = (ex * (dXs[i] - dXs[j]) + ey * (dYs[i] - dYs[j])) / f
        f = np.broadcast_to(f, d.shape)
        if derivative:
            df = np.broadcast_to(df, d.shape)
        return f, df, h2min, worst


class ConstructiveGeneral:
    """Any dimension: positions by :func:`fabkit.kinematics.place`, slopes by implicit
    differentiation (:func:`slope_at`).

    Parameters
    ----------
    plan : fabkit.kinematics.ConstructionPlan
        The construction order from the input pair.
    net : Network
        The network the plan places.
    in_pair, out_pair : tuple of int
        The nodes whose distances are d_in and d_out.

    Called like :class:`Constructive2D`, with the margins of :func:`fabkit.kinematics.place`.
    """

    def __init__(self, plan, net, in_pair, out_pair):
        self.plan = plan
        self.net = net
        self.inp = in_pair
        self.out = out_pair

    def __call__(self, d, signs, derivative=True, margins=True):
        d = np.asarray(d, dtype=np.float64)
        shape = d.shape
        plan = dataclasses.replace(self.plan, signs=np.asarray(signs, dtype=np.float64))
        with np.errstate(invalid="ignore", divide="ignore"):  # probes beyond a branch's end
            X, margin, worst = place(plan, d.ravel())
        i, j = self.out
        bad = margin < -FLAT_RTOL
        f = np.linalg.norm(X[:, i] - X[:, j], axis=1)
        f[bad] = np.nan
        df = None
        if derivative:
            df = np.full(f.shape, np.nan)
            good = ~bad
            if good.any():
                df[good] = slope_at(self.net, X[good], self.inp, self.out, strict=False)
            df = df.reshape(shape)
        return f.reshape(shape), df, margin.reshape(shape), worst.reshape(shape)


def slope_at(net: Network, positions, d_in="d1", d_out="d2", *, strict: bool = True) -> np.ndarray:
    """Exact slope d(d_out)/d(d_in) of the motion at given configurations (implicit
    differentiation of the edge constraints).

    Parameters
    ----------
    net : Network
        A network with one conformational motion at these configurations.
    positions : array_like, shape (N, d) or (K, N, d)
    d_in, d_out : str or (int, int)
        Ports or node pairs.
    strict : bool
        Raise where the slope is undefined (default); with False, return inf there.

    Returns
    -------
    numpy.ndarray, shape () or (K,)

    Raises
    ------
    KinematicsError
        Where the motion does not change d_in (a turning point of d_in) or the configuration has
        more than one motion.

    Examples
    --------
    >>> import fabkit
    >>> net = fabkit.Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]],
    ...                      ports={"d1": (0, 1), "d2": (2, 3)})
    >>> round(float(slope_at(net, net.nodes)), 12)  # f(d) = 4/d: f'(2) = -1
    -1.0
    """
    X = np.asarray(positions, dtype=np.float64)
    single = X.ndim == 2
    X = X[None] if single else X
    k, n, dim = X.shape
    finite = np.isfinite(X).reshape(k, -1).all(axis=1)
    if not finite.all():
        # configurations beyond the motion (an orbit that left the map's domain) have no slope
        s = np.full(k, np.nan)
        if finite.any():
            s[finite] = slope_at(net, X[finite], d_in, d_out, strict=strict)
        return s[0] if single else s
    a, b = port_pair(net, d_in)
    i, j = port_pair(net, d_out)
    e = net.edges
    m = e.shape[0]
    # Rows: edge constraints (x_i - x_j).(v_i - v_j) = 0, then d(d_in)/dt = 1.
    J = np.zeros((k, m + 1, n, dim))
    diff = X[:, e[:, 0]] - X[:, e[:, 1]]
    rows = np.arange(m)
    J[:, rows, e[:, 0]] = diff
    J[:, rows, e[:, 1]] = -diff
    u = X[:, a] - X[:, b]
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    J[:, m, a] = u
    J[:, m, b] -= u
    J = J.reshape(k, m + 1, n * dim)
    rhs = np.zeros((k, m + 1))
    rhs[:, m] = 1.0
    # Minimum-norm solution: any rigid motion left in it does not change d_out.
    U, S, Vt = np.linalg.svd(J, full_matrices=False)
    tol = S[:, :1] * max(J.shape[1:]) * np.finfo(float).eps * 1e3
    inv = np.where(S > tol, 1.0 / np.where(S > tol, S, 1.0), 0.0)
    V = np.einsum("kji,kj,klj,kl->ki", Vt, inv, U, rhs).reshape(k, n, dim)
    resid = np.einsum("krc,kc->kr", J, V.reshape(k, -1)) - rhs
    bad = np.any(np.abs(resid) > SLOPE_SOLVE_RTOL * np.maximum(1.0, np.abs(V).reshape(k, -1).max(axis=1))[:, None],
                 axis=1)
    if strict and bad.any():
        raise KinematicsError("d_in does not change along the motion at some configuration "
                              "(a turning point of d_in): the slope is infinite there")
    w = X[:, i] - X[:, j]
    w = w / np.linalg.norm(w, axis=1, keepdims=True)
    s = np.einsum("kc,kc->k", w, V[:, i] - V[:, j])
    s = np.where(bad, np.inf, s)
    return s[0] if single else s


def port_pair(net: Network, spec) -> tuple[int, int]:
    """The two nodes of a port, given by name or as a pair of node indices.

    Parameters
    ----------
    net : Network
    spec : str or (int, int)
        A port name of ``net`` or two distinct node indices.

    Returns
    -------
    (int, int)

    Raises
    ------
    KinematicsError
        An unknown port name, or indices that are not two distinct nodes of ``net``.
    ArgumentTypeError
        Anything else than a name or a pair.
    """
    if isinstance(spec, str):
        if spec not in net.ports:
            known = ", ".join(sorted(net.ports)) or "none"
            raise KinematicsError(f"unknown port {spec!r}; the network has ports: {known}")
        i, j = net.ports[spec]
        return int(i), int(j)
    if not isinstance(spec, (list, tuple)) or len(spec) != 2:
        raise ArgumentTypeError("port", f"must be a port name or a pair of node indices, got "
                                        f"{spec!r:.40}")
    i, j = (arguments.whole("node index", v) for v in spec)
    if not (0 <= i < net.n_nodes and 0 <= j < net.n_nodes) or i == j:
        raise KinematicsError(f"node pair ({i}, {j}) is not two distinct nodes of the network")
    return i, j
