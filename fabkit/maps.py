"""Modules as 1-D maps d_out = f(d_in): branches, fixed points, cycles, Lyapunov exponents.

A module with one conformational motion traces a closed or open curve (d_in, d_out). Where the
network has a construction order from the d_in pair (the paper's 5-node modules, the 4-bar, and
their chains), every configuration is given in closed form by circle (2D) or sphere (3D)
intersections, with one side (+1/-1) per constructed node. Along a run of fixed sides, d_in is the
parameter of the curve, so that run is a *monotone branch*: a proper map. A branch ends where a
constructed node becomes collinear with its parents (a flat triangle): there d_in turns back, and
the motion continues with that node on the other side. :func:`module_map` walks the whole curve
this way, splitting it into branches, and returns the map on the branch through the reference
configuration.

Derivatives are exact: forward-mode differentiation of the intersection formulas (2D), or
implicit differentiation of the edge constraints (:func:`slope_at`, any network), never finite
differences. :func:`map_from_trajectory` reads a map off a traced motion (e.g. ``projected``) and
corrects every value onto the constraint set by Newton's method, so it agrees with the
constructive map to round-off.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import brentq

from .errors import ConstructionError, DesignError, KinematicsError
from .network import Network

__all__ = [
    "Map1D",
    "Branch",
    "FixedPoint",
    "Cycle",
    "LyapunovResult",
    "module_map",
    "map_from_trajectory",
    "slope_at",
    "classify_slope",
]

#: |slope| below this is "super-stable", above its inverse "super-unstable", within it of 1
#: "neutral".
SLOPE_TOL = 1e-6

# An intersection whose squared height is above -this (relative to the radius squared) is a
# round-off shadow of the flat state itself, not a missing configuration.
_FLAT_SLACK = 1e-12


# --------------------------------------------------------------------------------------------
# Result objects
# --------------------------------------------------------------------------------------------
def classify_slope(slope: float, tol: float = SLOPE_TOL) -> str:
    """Stability class of a fixed point or cycle from its slope (multiplier).

    Returns one of ``"super-stable"`` (|s| < tol), ``"stable"`` (|s| < 1), ``"neutral"``
    (|s| = 1 within tol), ``"unstable"`` (|s| > 1), ``"super-unstable"`` (|s| > 1/tol, or an
    infinite slope at a turning point of d_in).

    Examples
    --------
    >>> classify_slope(0.0), classify_slope(-0.5), classify_slope(2.0)
    ('super-stable', 'stable', 'unstable')
    """
    a = abs(float(slope))
    if a < tol:
        return "super-stable"
    if abs(a - 1.0) <= tol:
        return "neutral"
    if a < 1.0:
        return "stable"
    if a > 1.0 / tol:
        return "super-unstable"
    return "unstable"


@dataclass(frozen=True)
class FixedPoint:
    """A distance D* with f(D*) = D*.

    Attributes
    ----------
    value : float
        D* (design units).
    slope : float
        f'(D*).
    kind : str
        See :func:`classify_slope`.
    residual : float
        |f(D*) - D*|.
    """

    value: float
    slope: float
    kind: str
    residual: float = 0.0

    def as_dict(self) -> dict:
        return {"value": self.value, "slope": self.slope, "kind": self.kind,
                "residual": self.residual}


@dataclass(frozen=True)
class Cycle:
    """A period-m cycle D1 -> D2 -> ... -> Dm -> D1 (values in orbit order, smallest first).

    Attributes
    ----------
    values : tuple of float
    multiplier : float
        Product of the slopes over the cycle.
    kind : str
        See :func:`classify_slope`.
    residual : float
        |f^m(D1) - D1|.
    """

    values: tuple
    multiplier: float
    kind: str
    residual: float = 0.0

    @property
    def period(self) -> int:
        return len(self.values)

    def as_dict(self) -> dict:
        return {"period": self.period, "values": list(self.values), "multiplier": self.multiplier,
                "kind": self.kind, "residual": self.residual}


@dataclass(frozen=True)
class LyapunovResult:
    """Lyapunov exponents of many orbits.

    Attributes
    ----------
    mean, std : float
        Over the orbits that stayed on the branch.
    values : numpy.ndarray, shape (K,)
        Exponent of each orbit (NaN for an orbit that left the branch's domain).
    initial : numpy.ndarray, shape (K,)
        The initial values d1.
    discard, average : int
        Iterations discarded, then averaged.
    escaped : int
        Orbits that left the domain.
    method : str
        ``"exact"`` or ``"table"`` (see :meth:`Map1D.lyapunov`).
    table_error : dict or None
        Largest error of the table in f and f' (measured at every interval's midpoint).
    """

    mean: float
    std: float
    values: np.ndarray
    initial: np.ndarray
    discard: int
    average: int
    escaped: int = 0
    method: str = "exact"
    table_error: dict | None = None

    def as_dict(self) -> dict:
        return {"mean": self.mean, "std": self.std, "orbits": int(self.values.size),
                "discard": self.discard, "average": self.average, "escaped": self.escaped,
                "initial_range": [float(self.initial.min()), float(self.initial.max())],
                "method": self.method, "table_error": self.table_error}


@dataclass(frozen=True)
class Branch:
    """One monotone piece of a module's (d_in, d_out) curve.

    Attributes
    ----------
    index : int
        Position along the walk of the curve (0 = the branch through the reference).
    lo, hi : float
        Domain of d_in.
    signs : tuple of float
        Side of every constructed node (see :func:`fabkit.kinematics.plan_construction`).
    ends : tuple of str
        What ends the branch at lo and at hi (a turning point: which node becomes flat).
    """

    index: int
    lo: float
    hi: float
    signs: tuple
    ends: tuple = ("", "")

    def as_dict(self) -> dict:
        return {"index": self.index, "domain": [self.lo, self.hi], "ends": list(self.ends)}


# --------------------------------------------------------------------------------------------
# Evaluation of a constructive branch
# --------------------------------------------------------------------------------------------
class _Constructive2D:
    """Values and exact derivatives of d_out(d_in) by the circle-intersection formulas.

    Works in the frame of the paper's analytic map: node a at the origin, node b at (d, 0), so a
    node placed from a and b needs no rotation (x = (d² + r_a² - r_b²) / 2d). The derivative is
    carried alongside every quantity (forward mode), so f' is exact to round-off. Iterating a
    map calls this in a tight loop (Lyapunov exponents), hence the lean arithmetic.
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
                    h = np.sqrt(np.where(h2 >= -_FLAT_SLACK * rp2, np.maximum(h2, 0.0), np.nan))
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
                    h = np.sqrt(np.where(h2 >= -_FLAT_SLACK * rp2, np.maximum(h2, 0.0), np.nan))
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


class _ConstructiveGeneral:
    """Any dimension: positions by :func:`fabkit.kinematics.place`, slopes by implicit
    differentiation (:func:`slope_at`)."""

    def __init__(self, plan, net, in_pair, out_pair):
        self.plan = plan
        self.net = net
        self.inp = in_pair
        self.out = out_pair

    def __call__(self, d, signs, derivative=True, margins=True):
        from .kinematics import place

        d = np.asarray(d, dtype=np.float64)
        shape = d.shape
        plan = dataclasses.replace(self.plan, signs=np.asarray(signs, dtype=np.float64))
        with np.errstate(invalid="ignore", divide="ignore"):  # probes beyond a branch's end
            X, margin, worst = place(plan, d.ravel())
        i, j = self.out
        bad = margin < -_FLAT_SLACK
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
    a, b = _pair(net, d_in)
    i, j = _pair(net, d_out)
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
    bad = np.any(np.abs(resid) > 1e-8 * np.maximum(1.0, np.abs(V).reshape(k, -1).max(axis=1))[:, None],
                 axis=1)
    if strict and bad.any():
        raise KinematicsError("d_in does not change along the motion at some configuration "
                              "(a turning point of d_in): the slope is infinite there")
    w = X[:, i] - X[:, j]
    w = w / np.linalg.norm(w, axis=1, keepdims=True)
    s = np.einsum("kc,kc->k", w, V[:, i] - V[:, j])
    s = np.where(bad, np.inf, s)
    return s[0] if single else s


def _pair(net: Network, spec) -> tuple[int, int]:
    if isinstance(spec, str):
        if spec not in net.ports:
            known = ", ".join(sorted(net.ports)) or "none"
            raise KinematicsError(f"unknown port {spec!r}; the network has ports: {known}")
        i, j = net.ports[spec]
        return int(i), int(j)
    i, j = (int(v) for v in spec)
    if not (0 <= i < net.n_nodes and 0 <= j < net.n_nodes) or i == j:
        raise KinematicsError(f"node pair ({i}, {j}) is not two distinct nodes of the network")
    return i, j


# --------------------------------------------------------------------------------------------
# The map
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Map1D:
    """A 1-D map d_out = f(d_in) on one monotone branch of a motion.

    Build one with :func:`module_map` (constructive, exact), :func:`map_from_trajectory`
    (read off a traced motion) or :meth:`from_function` (a closed-form map).

    Attributes
    ----------
    domain : (float, float)
        Interval of d_in on which the branch is a proper map.
    branches : list of Branch
        Every monotone branch of the module's whole motion, in walking order (empty for a
        closed-form map); ``branch`` is the one this map evaluates.
    branch : Branch or None
    source : str
        ``"constructive"``, ``"trajectory"`` or ``"function"``.
    name : str
    """

    fun: Callable = field(repr=False)
    domain: tuple
    branches: list = field(default_factory=list)
    branch: Branch | None = None
    source: str = "function"
    name: str = "f"
    curve_fun: Callable | None = field(default=None, repr=False)
    reference: float | None = None

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def from_function(cls, f, df, domain, name="f") -> "Map1D":
        """A map given in closed form.

        Parameters
        ----------
        f, df : callable
            Vectorised f(d) and f'(d).
        domain : (float, float)

        Examples
        --------
        >>> m = Map1D.from_function(lambda x: 4 * x * (1 - x), lambda x: 4 - 8 * x, (0, 1))
        >>> m(0.5), m.derivative(0.5)
        (1.0, 0.0)
        """
        lo, hi = float(domain[0]), float(domain[1])
        if not lo < hi:
            raise DesignError(f"domain must be an interval (lo, hi) with lo < hi, got {domain}")

        def fun(d, derivative=True):
            d = np.asarray(d, dtype=np.float64)
            return (np.asarray(f(d), dtype=np.float64),
                    np.asarray(df(d), dtype=np.float64) if derivative else None)

        return cls(fun=fun, domain=(lo, hi), source="function", name=name)

    # -- evaluation ---------------------------------------------------------------------------
    def _values(self, d, derivative=False):
        """f (and f') with NaN outside the domain: for vectorised iteration."""
        d = np.asarray(d, dtype=np.float64)
        lo, hi = self.domain
        slack = 1e-12 * max(abs(lo), abs(hi), 1.0)
        inside = (d >= lo - slack) & (d <= hi + slack)
        dc = np.clip(d, lo, hi)
        with np.errstate(invalid="ignore", divide="ignore"):
            f, df = self.fun(dc, derivative)
        f = np.where(inside, f, np.nan)
        if derivative:
            df = np.where(inside, df, np.nan)
        return f, df

    def _check(self, d):
        d = np.asarray(d, dtype=np.float64)
        lo, hi = self.domain
        slack = 1e-12 * max(abs(lo), abs(hi), 1.0)
        outside = ~((d >= lo - slack) & (d <= hi + slack))
        if np.any(outside):
            bad = float(np.atleast_1d(d)[np.atleast_1d(outside)][0])
            raise DesignError(f"d = {bad:.10g} is outside the domain [{lo:.10g}, {hi:.10g}] of "
                              f"the map {self.name}: no configuration on this branch")
        return d

    def __call__(self, d):
        """f(d) for a scalar or array d inside the domain (raises DesignError outside)."""
        d = self._check(d)
        f, _ = self._values(d)
        return float(f) if f.ndim == 0 else f

    def derivative(self, d):
        """Exact f'(d) (infinite at a turning point of d_in at the domain's ends)."""
        d = self._check(d)
        _, df = self._values(d, derivative=True)
        return float(df) if df.ndim == 0 else df

    def iterate(self, d, steps: int) -> np.ndarray:
        """Vectorised iteration.

        Parameters
        ----------
        d : array_like, shape (K,)
        steps : int

        Returns
        -------
        numpy.ndarray, shape (steps + 1, K)
            Row k is f^k(d); NaN from the step an orbit leaves the domain (no configuration:
            the chain cannot be assembled that far).
        """
        x = np.atleast_1d(np.asarray(d, dtype=np.float64))
        out = np.empty((int(steps) + 1, x.size))
        out[0] = x
        for k in range(int(steps)):
            x, _ = self._values(x)
            out[k + 1] = x
        return out

    def orbit(self, d1: float, steps: int) -> np.ndarray:
        """The orbit d1, f(d1), ..., f^steps(d1), cut where it leaves the domain.

        Returns
        -------
        numpy.ndarray, shape (<= steps + 1,)
        """
        o = self.iterate([float(self._check(d1))], steps)[:, 0]
        bad = np.flatnonzero(~np.isfinite(o))
        return o[: bad[0]] if bad.size else o

    # -- fixed points and cycles --------------------------------------------------------------
    def _grid(self, samples):
        lo, hi = self.domain
        return np.linspace(lo, hi, int(samples))

    def is_identity(self, power: int = 1, tol: float = 1e-10) -> bool:
        """True when f^power(d) = d wherever it is defined on the domain (power 1: every point
        is a neutral fixed point; the 4-bar's f(d) = 4/d has f(f(d)) = d: every point lies on
        a 2-cycle)."""
        g = self._grid(401)
        f = self._power(g, int(power))
        ok = np.isfinite(f)
        return bool(ok.sum() > 10 and np.all(np.abs(f[ok] - g[ok]) <= tol * np.maximum(1.0, np.abs(g[ok]))))

    def fixed_points(self, samples: int = 4001) -> list[FixedPoint]:
        """All fixed points f(D*) = D* on the domain, with exact slopes and their class.

        Simple roots are bracketed on a grid of ``samples`` points and refined by Brent's method
        to round-off; touching roots (f - d has a double root) are refined by minimising
        |f(d) - d| and kept when it is below 1e-10. A map that is the identity on its whole
        domain returns one neutral point per domain end (see :meth:`is_identity`).
        """
        lo, hi = self.domain
        scale = max(abs(lo), abs(hi), 1.0)
        if self.is_identity():
            mid = self.reference if self.reference is not None else 0.5 * (lo + hi)
            return [self._fixed(mid)]
        grid = self._grid(samples)
        f, _ = self._values(grid)
        g = f - grid
        roots = []
        ref = None
        if self.reference is not None:  # modules are usually designed at a fixed point
            ref = self._fixed(float(self.reference))
            if ref.residual > 1e-12 * scale:
                ref = None
        for k in np.flatnonzero(np.abs(g) <= 1e-13 * scale):
            roots.append(float(grid[k]))
        sgn = np.sign(g)
        for k in np.flatnonzero(sgn[:-1] * sgn[1:] < 0):
            try:
                roots.append(brentq(lambda x: self._values(x)[0] - x, grid[k], grid[k + 1],
                                    xtol=1e-15 * scale, rtol=4 * np.finfo(float).eps,
                                    maxiter=200))
            except ValueError:  # no value somewhere inside the bracket
                continue
        # touching roots: local minima of |g| not bracketed by a sign change
        ag = np.abs(g)
        mins = np.flatnonzero((ag[1:-1] < ag[:-2]) & (ag[1:-1] <= ag[2:])) + 1
        for k in mins:
            if sgn[k - 1] == sgn[k + 1] and ag[k] < 1e-3 * scale:
                x = self._touching_root(grid[k - 1], grid[k + 1])
                if x is not None:
                    roots.append(x)
        if ref is not None:  # exact; a touching root found next to it is the same point
            roots = [r for r in roots if abs(r - ref.value) > 1e-6 * scale] + [ref.value]
        found = self._dedupe_fixed(roots, scale)
        # f(d) = d on a whole stretch (a degenerate, partly identical branch): keep the ends of
        # each run of roots spaced like the grid
        step = 2.5 * (grid[1] - grid[0])
        if len(found) > 8:
            runs, out = [], []
            for p in found:
                if runs and p.value - runs[-1][-1].value <= step:
                    runs[-1].append(p)
                else:
                    runs.append([p])
            for run in runs:
                out.extend([run[0], run[-1]] if len(run) > 1 else run)
            found = out
        return found

    def _touching_root(self, a, b):
        from scipy.optimize import minimize_scalar

        r = minimize_scalar(lambda x: abs(float(self._values(x)[0]) - x), bounds=(a, b),
                            method="bounded", options={"xatol": 1e-14})
        return float(r.x) if r.fun < 1e-10 else None

    def _fixed(self, x):
        f, df = self._values(x, derivative=True)
        s = float(df)
        if not np.isfinite(s):  # at a turning point of d_in: a vertical tangent
            s = float("inf")
        kind = classify_slope(s)
        return FixedPoint(value=float(x), slope=s, kind=kind, residual=abs(float(f) - float(x)))

    def _dedupe_fixed(self, roots, scale):
        """Keep true roots (residual <= 1e-10), one per cluster (the best resolved)."""
        cands = [p for p in (self._fixed(x) for x in sorted(roots)) if p.residual <= 1e-10 * scale]
        out: list[FixedPoint] = []
        for p in cands:
            if out and abs(p.value - out[-1].value) <= 1e-7 * scale:
                if p.residual < out[-1].residual:
                    out[-1] = p
                continue
            out.append(p)
        return out

    def _power(self, x, m):
        for _ in range(m):
            x, _ = self._values(x)
        return x

    def cycles(self, period: int = 2, samples: int = 4001) -> list[Cycle]:
        """Cycles of exactly this period (fixed points and shorter cycles excluded).

        Roots of f^m(d) - d are bracketed on a grid and refined by Brent's method; the
        multiplier is the product of the exact slopes over the cycle.

        Parameters
        ----------
        period : int
            m >= 2.
        samples : int
            Grid size over the domain.

        Returns
        -------
        list of Cycle, sorted by their smallest value. Empty when f^p is the identity for a
        divisor p of m (every point is periodic: :meth:`is_identity` says so).
        """
        m = int(period)
        if m < 2:
            raise DesignError(f"period must be at least 2 (fixed points: fixed_points()), got {m}")
        if any(self.is_identity(p) for p in range(1, m + 1) if m % p == 0):
            return []  # a continuum of cycles, not isolated ones (see is_identity)
        lo, hi = self.domain
        scale = max(abs(lo), abs(hi), 1.0)
        grid = self._grid(samples)
        g = self._power(grid, m) - grid
        roots = list(grid[np.abs(g) <= 1e-13 * scale])
        ok = np.isfinite(g[:-1]) & np.isfinite(g[1:])
        for k in np.flatnonzero(ok & (np.sign(g[:-1]) * np.sign(g[1:]) < 0)):
            fun = lambda x: float(self._power(x, m)) - x  # noqa: E731
            try:
                roots.append(brentq(fun, grid[k], grid[k + 1], xtol=1e-15 * scale,
                                    rtol=4 * np.finfo(float).eps, maxiter=200))
            except ValueError:  # the orbit leaves the domain inside the bracket
                continue
        found: list[Cycle] = []
        for r in roots:
            orbit = [float(r)]
            for _ in range(m - 1):
                orbit.append(float(self._values(orbit[-1])[0]))
            if not np.all(np.isfinite(orbit)):
                continue
            tol = 1e-9 * scale
            # exclude points of a shorter period dividing m
            if any(m % p == 0 and abs(orbit[p] - orbit[0]) <= tol for p in range(1, m)):
                continue
            start = int(np.argmin(orbit))
            orbit = orbit[start:] + orbit[:start]
            if any(abs(c.values[0] - orbit[0]) <= tol for c in found):
                continue
            _, df = self._values(np.array(orbit), derivative=True)
            mult = float(np.prod(df))
            if not np.isfinite(mult):  # a point of the cycle at a turning point of d_in
                mult = float("inf")
            resid = abs(float(self._power(orbit[0], m)) - orbit[0])
            found.append(Cycle(values=tuple(orbit), multiplier=mult, kind=classify_slope(mult),
                               residual=resid))
        found.sort(key=lambda c: c.values[0])
        # f^m(d) = d on a whole stretch (a degenerate branch): keep the ends of each run
        step = 2.5 * (grid[1] - grid[0])
        if len(found) > 8:
            runs: list[list[Cycle]] = []
            for c in found:
                if runs and c.values[0] - runs[-1][-1].values[0] <= step:
                    runs[-1].append(c)
                else:
                    runs.append([c])
            found = [c for run in runs for c in ([run[0], run[-1]] if len(run) > 1 else run)]
        return found

    # -- invariant range and Lyapunov exponent ------------------------------------------------
    def image(self, lo: float, hi: float, samples: int = 4001) -> tuple[float, float]:
        """The interval f([lo, hi]) (extrema refined where f' changes sign)."""
        x = np.linspace(lo, hi, int(samples))
        f, df = self._values(x, derivative=True)
        vals = [np.nanmin(f), np.nanmax(f)]
        sd = np.sign(df)
        for k in np.flatnonzero(sd[:-1] * sd[1:] < 0):
            try:
                c = brentq(lambda t: float(self._values(t, True)[1]), x[k], x[k + 1], xtol=1e-15)
            except ValueError:
                continue
            vals.append(float(self._values(c)[0]))
        return float(np.nanmin(vals)), float(np.nanmax(vals))

    def invariant_range(self, settle: int = 500, samples: int = 2001) -> tuple[float, float]:
        """The interval I where orbits settle, with f(I) = I (the paper's range r).

        Orbits from ``samples`` values across the domain are iterated ``settle`` times; the hull
        of where the surviving ones end up is then closed exactly by I -> f(I) (for a tent-like
        map this converges to [f(f(c)), f(c)], c the peak).

        Raises
        ------
        DesignError
            When every orbit leaves the domain (no configuration: the chain cannot be built).
        """
        lo, hi = self.domain
        slack = 1e-12 * max(abs(lo), abs(hi), 1.0)
        x = self.iterate(np.linspace(lo, hi, int(samples)), settle)
        tail = x[-min(100, settle):]
        tail = tail[:, np.all(np.isfinite(tail), axis=0)]
        if tail.size == 0:
            raise DesignError(
                f"every orbit of the map {self.name} leaves its domain [{lo:.6g}, {hi:.6g}] within "
                f"{settle} iterations: there is no invariant range (no long chain exists)")
        a, b = float(tail.min()), float(tail.max())
        for _ in range(50):
            na, nb = self.image(a, b)
            if na < lo - slack or nb > hi + slack or not np.isfinite(na + nb):
                break  # the hull is not invariant (orbits near its ends escape): keep the hull
            if abs(na - a) <= slack and abs(nb - b) <= slack:
                a, b = na, nb
                break
            a, b = na, nb
        return a, b

    def lyapunov(self, initial=1000, discard: int = 5000, average: int = 20000,
                 lo: float | None = None, hi: float | None = None,
                 method: str = "auto") -> LyapunovResult:
        """Lyapunov exponents λ = mean of ln|f'(d_i)| along orbits (supplement protocol).

        Parameters
        ----------
        initial : int or array_like
            Number of evenly spaced initial values across the invariant range (or the values).
        discard : int
            Iterations to settle onto the attractor.
        average : int
            Iterations averaged.
        lo, hi : float, optional
            Range of the initial values (default: :meth:`invariant_range`).
        method : {"auto", "exact", "table"}
            ``"exact"`` evaluates the map's own formulas at every iteration. ``"table"``
            iterates a piecewise-cubic Hermite table of the exact f and f' on the invariant
            range (2^15 intervals), about 4x faster; it is used only when its largest error,
            measured against the exact map at every interval's midpoint, is below 1e-11 in f
            and 1e-8 in f' (reported as ``table_error``). ``"auto"`` takes the table when it
            passes that check and the initial values lie in its range. A chaotic orbit in
            float64 is a pseudo-orbit after ~ln(1e16)/λ iterations either way; the exponent,
            an average over the attractor, is not affected.

        Returns
        -------
        LyapunovResult

        Examples
        --------
        >>> tent = Map1D.from_function(lambda x: 1 - abs(2 * x - 1),
        ...                            lambda x: np.where(x < 0.5, 2.0, -2.0), (0, 1))
        >>> round(tent.lyapunov(initial=10, discard=10, average=100).mean, 10)  # ln 2
        0.6931471806
        """
        if method not in ("auto", "exact", "table"):
            raise DesignError(f"unknown method {method!r}; valid: auto, exact, table")
        rng = None
        if np.ndim(initial) == 0:
            if lo is None or hi is None:
                rng = self.invariant_range()
                lo = rng[0] if lo is None else lo
                hi = rng[1] if hi is None else hi
            x0 = np.linspace(lo, hi, int(initial))
        else:
            x0 = np.asarray(initial, dtype=np.float64).ravel()
        table, table_error = None, None
        if method != "exact" and self.source != "function":
            try:
                rng = rng or self.invariant_range()
            except DesignError:
                rng = None
            if rng is not None and rng[1] > rng[0] and np.all((x0 >= rng[0]) & (x0 <= rng[1])):
                table, table_error = _hermite_table(self, *rng)
        if method == "table" and table is None:
            raise DesignError("no accurate table of this map on an invariant range; use "
                              "method='exact'")
        step = table if table is not None else self.fun
        # hot loop: no domain clipping (an orbit that leaves the domain turns NaN and stays NaN,
        # which marks it as escaped)
        x = x0.copy()
        with np.errstate(invalid="ignore", divide="ignore"):
            for _ in range(int(discard)):
                x = step(x, False)[0]
            total = np.zeros_like(x)
            for _ in range(int(average)):
                fx, df = step(x, True)
                total += np.log(np.abs(df))
                x = fx
        lam = total / max(int(average), 1)
        ok = np.isfinite(x0) & ~np.isnan(lam)
        vals = np.where(ok, lam, np.nan)
        good = vals[ok]
        return LyapunovResult(mean=float(np.mean(good)) if good.size else float("nan"),
                              std=float(np.std(good)) if good.size else float("nan"),
                              values=vals, initial=x0, discard=int(discard), average=int(average),
                              escaped=int((~ok).sum()),
                              method="table" if table is not None else "exact",
                              table_error=table_error)

    # -- whole motion -------------------------------------------------------------------------
    def curve(self, samples_per_branch: int = 400):
        """The module's whole (d_in, d_out) curve, branch by branch.

        Returns
        -------
        list of (Branch, numpy.ndarray (S,), numpy.ndarray (S,))
        """
        if self.curve_fun is None:
            g = self._grid(samples_per_branch)
            return [(self.branch, g, self._values(g)[0])]
        return [(br, *self.curve_fun(br, samples_per_branch)) for br in self.branches]

    def on_branch(self, index: int) -> "Map1D":
        """The map on another branch of the same motion (``branches[index]``)."""
        if not self.branches or self.curve_fun is None:
            raise DesignError("this map has no other branches")
        if not 0 <= index < len(self.branches):
            raise DesignError(f"branch index must be in 0..{len(self.branches) - 1}, got {index}")
        br = self.branches[index]
        return dataclasses.replace(self, fun=self.curve_fun(br, None), domain=(br.lo, br.hi),
                                   branch=br)

    def summary(self, periods=(2,), lyapunov: LyapunovResult | None = None) -> dict:
        """JSON-ready summary: domain, branches, fixed points, cycles, (Lyapunov)."""
        fps = self.fixed_points()
        out = {
            "name": self.name,
            "source": self.source,
            "domain": list(self.domain),
            "identity": self.is_identity(),
            "identity_powers": [m for m in sorted({1, *periods}) if self.is_identity(m)],
            "branch": self.branch.as_dict() if self.branch else None,
            "branches": [b.as_dict() for b in self.branches],
            "fixed_points": [p.as_dict() for p in fps],
            "cycles": [c.as_dict() for m in periods for c in self.cycles(m)],
        }
        try:
            out["invariant_range"] = list(self.invariant_range())
        except DesignError as exc:
            out["invariant_range"] = None
            out["invariant_range_note"] = str(exc)
        if lyapunov is not None:
            out["lyapunov"] = lyapunov.as_dict()
        return out


def _hermite_table(fmap: "Map1D", lo: float, hi: float, intervals: int = 1 << 15):
    """A fast stand-in for f on [lo, hi]: piecewise-cubic Hermite interpolation of the exact f
    and f' on a uniform grid. Returns (step, errors) or (None, errors) when it is not accurate
    enough (see :meth:`Map1D.lyapunov`)."""
    n = int(intervals)
    x = np.linspace(lo, hi, n + 1)
    f, df = fmap._values(x, derivative=True)
    xm = 0.5 * (x[:-1] + x[1:])
    fm, dfm = fmap._values(xm, derivative=True)
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(df)) and np.all(np.isfinite(dfm))):
        return None, None
    h = (hi - lo) / n
    f0, f1, g0, g1 = f[:-1], f[1:], h * df[:-1], h * df[1:]
    C = np.stack([f0, g0, 3 * (f1 - f0) - 2 * g0 - g1, 2 * (f0 - f1) + g0 + g1], axis=1)
    pm = C[:, 0] + C[:, 1] / 2 + C[:, 2] / 4 + C[:, 3] / 8
    dpm = (C[:, 1] + C[:, 2] + 0.75 * C[:, 3]) / h
    err = {"f": float(np.max(np.abs(pm - fm))), "derivative": float(np.max(np.abs(dpm - dfm)))}
    scale = max(abs(lo), abs(hi), 1.0)
    if err["f"] > 1e-11 * scale or err["derivative"] > 1e-8 * max(1.0, float(np.max(np.abs(df)))):
        return None, err
    inv_h = 1.0 / h
    C0, C1, C2, C3 = (np.ascontiguousarray(C[:, i]) for i in range(4))

    def step(d, derivative=True):
        # take(mode="clip") is ~10x faster than fancy indexing and keeps the index of a NaN
        # orbit (whose t stays NaN) inside the table
        u = (d - lo) * inv_h
        k = u.astype(np.intp)
        np.minimum(k, n - 1, out=k)  # d = hi exactly: the end of the last interval (t = 1)
        t = u - k
        c1, c2, c3 = C1.take(k, mode="clip"), C2.take(k, mode="clip"), C3.take(k, mode="clip")
        fx = C0.take(k, mode="clip") + t * (c1 + t * (c2 + t * c3))
        if not derivative:
            return fx, None
        return fx, (c1 + t * (2.0 * c2 + 3.0 * t * c3)) * inv_h

    return step, err


# --------------------------------------------------------------------------------------------
# Building maps of networks
# --------------------------------------------------------------------------------------------
def _evaluator(net, plan, in_pair, out_pair):
    if net.dim == 2:
        return _Constructive2D(plan, out_pair)
    return _ConstructiveGeneral(plan, net, in_pair, out_pair)


def _turning_point(ev, signs, inside, outside):
    """The d_in where the branch with these signs ends, between a valid and an invalid value."""
    def margin(x):
        return float(ev(np.array([x]), signs, derivative=False)[2][0])

    if margin(outside) >= -_FLAT_SLACK:
        return outside
    if not margin(inside) > 0.0:  # already flat (to round-off) where the search starts
        return inside
    t = brentq(margin, inside, outside, xtol=1e-15 * max(abs(inside), 1.0),
               rtol=4 * np.finfo(float).eps, maxiter=300)
    # land on the valid side, so the branch end evaluates
    step = np.spacing(t) * (1 if inside > t else -1)
    for _ in range(64):
        if margin(t) >= -_FLAT_SLACK:
            break
        t += step
    return t


def _walk_branch(ev, signs, d0, size, samples):
    """Extent [lo, hi] of the branch with these signs that contains d0, and the step index of
    the node that becomes flat at each end (-1: no end found in range)."""
    ends = []
    for direction in (-1.0, 1.0):
        # geometric search outwards: find the first invalid value
        # fine near d0, coarse far out: up to 4 network sizes away
        grid = d0 + direction * 4.0 * size * np.linspace(0, 1, samples)[1:] ** 2
        grid = grid[grid > 0]
        _, _, m, _ = ev(grid, signs, derivative=False)
        bad = np.flatnonzero(m < -_FLAT_SLACK)
        if bad.size == 0:
            ends.append((float(grid[-1]) if grid.size else d0, -1))
            continue
        k = int(bad[0])
        inside = d0 if k == 0 else float(grid[k - 1])
        t = _turning_point(ev, signs, inside, float(grid[k]))
        _, _, _, w = ev(np.array([t]), signs, derivative=False)
        ends.append((t, int(w[0])))
    (lo, wlo), (hi, whi) = ends
    return lo, hi, wlo, whi


def _flat_nudge(x: np.ndarray, a: int, b: int) -> np.ndarray:
    """A deterministic unit-size perturbation of every node, fixed in the frame of the drive
    pair and of the start's own handedness, so the branch it selects does not depend on where
    (or mirrored how) the network is drawn."""
    n, d = x.shape
    u = x[b] - x[a]
    u = u / np.linalg.norm(u)
    rng = np.random.default_rng(0)
    coef = rng.standard_normal((n, d))
    if d == 2:
        v = np.array([-u[1], u[0]])
        rel = x - x[a]
        cross = rel[:, 0] * u[1] - rel[:, 1] * u[0]
        k = int(np.argmax(np.abs(cross)))
        hand = -np.sign(cross[k]) or 1.0  # the side of the node farthest from the drive axis
        return coef[:, :1] * u + hand * coef[:, 1:2] * v
    # 3D: a frame (u, v, w) from the two nodes farthest from the drive axis
    rel = x - x[a]
    perp = rel - np.outer(rel @ u, u)
    k = int(np.argmax(np.linalg.norm(perp, axis=1)))
    v = perp[k] / max(np.linalg.norm(perp[k]), 1e-300)
    w = np.cross(u, v)
    side = rel @ w
    j = int(np.argmax(np.abs(side)))
    hand = np.sign(side[j]) or 1.0
    return coef[:, :1] * u + coef[:, 1:2] * v + hand * coef[:, 2:3] * w


def module_map(net: Network, d_in="d1", d_out="d2", *, reference=None, toward: float | None = None,
               branch: int | None = None, max_branches: int = 64, name: str | None = None) -> Map1D:
    """The map d_out = f(d_in) of a module on the branch through its reference configuration.

    Parameters
    ----------
    net : Network
        A network with a construction order from the d_in pair (2D or 3D).
    d_in, d_out : str or (int, int)
        Ports (or node pairs) of the map.
    reference : array_like, shape (N, d), optional
        Configuration that selects the branch (``net.nodes`` by default).
    toward : float, optional
        When the reference is itself a turning point of d_in (it lies on two branches), the
        branch that contains this d_in value is taken.
    branch : int, optional
        Take ``branches[branch]`` of the walked motion instead (e.g. a linkage that starts
        flat, such as a collapsed 4-bar, leaves its start on two mirror branches in the same
        direction of d_in; the walk starts on the one given by a deterministic nudge).
    max_branches : int
        Stop walking the whole motion after this many branches.
    name : str, optional

    Returns
    -------
    Map1D
        With ``branches`` listing every monotone branch of the motion found by walking it.

    Raises
    ------
    ConstructionError
        No construction order from d_in (use :func:`map_from_trajectory` with a ``projected``
        trace), or the reference is a flat state.

    Examples
    --------
    >>> import fabkit
    >>> net = fabkit.Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]],
    ...                      ports={"d1": (0, 1), "d2": (2, 3)})
    >>> f = module_map(net)
    >>> round(f(2.5), 12), round(f.derivative(2.5), 12)
    (1.6, -0.64)
    """
    from .kinematics import plan_construction

    a, b = _pair(net, d_in)
    out = _pair(net, d_out)
    x = net.nodes if reference is None else np.asarray(reference, dtype=np.float64)
    d0 = float(np.linalg.norm(x[a] - x[b]))
    size = float(max(net.size, d0))
    try:
        plan = plan_construction(net, (a, b), x)
    except ConstructionError as exc:
        if "flat state" not in str(exc):
            raise
        # A flat reference (e.g. a linkage that starts collapsed) lies at a turning point, on
        # two branches. Sides are taken from a slightly nudged copy; walking the motion finds
        # both branches, and `toward` picks one.
        plan = plan_construction(net, (a, b), x + 1e-7 * size * _flat_nudge(x, a, b))
    ev = _evaluator(net, plan, (a, b), out)
    samples = 2049
    signs0 = tuple(float(s) for s in plan.signs)

    def describe(w):
        if w < 0:
            return "end of the searched range"
        v = int(plan.order[w])
        par = ", ".join(str(int(p)) for p in plan.parents[w] if p >= 0)
        shape = "collinear" if net.dim == 2 else "coplanar"
        return f"turning point: node {v} {shape} with nodes {par}"

    lo, hi, wlo, whi = _walk_branch(ev, signs0, d0, size, samples)
    first = Branch(0, lo, hi, signs0, (describe(wlo), describe(whi)))
    branches = [first]
    # walk the rest of the motion: at each end flip the side of the node that became flat
    seen = {signs0}
    for d_end, wk in ((lo, wlo), (hi, whi)):
        signs = signs0
        while wk >= 0 and len(branches) < max_branches and plan.signs[wk] != 0:
            # (a 3D gauge node has no side to flip: its half-plane is a convention)
            flipped = list(signs)
            flipped[wk] = -flipped[wk]
            signs = tuple(flipped)
            if signs in seen:  # back on a branch already walked: the motion is a closed loop
                break
            nlo, nhi, nwlo, nwhi = _walk_from_end(ev, signs, d_end, size, samples)
            if not nhi > nlo:
                break
            seen.add(signs)
            branches.append(Branch(len(branches), nlo, nhi, signs, (describe(nwlo), describe(nwhi))))
            # continue from the far end of the new branch
            if abs(nhi - d_end) >= abs(nlo - d_end):
                d_end, wk = nhi, nwhi
            else:
                d_end, wk = nlo, nwlo
    # the branch through the reference (or, at a turning reference, the one toward `toward`)
    chosen = first
    if toward is not None and not first.lo <= toward <= first.hi:
        tol = 1e-9 * size
        candidates = [br for br in branches
                      if br.lo - tol <= d0 <= br.hi + tol and br.lo <= toward <= br.hi]
        if not candidates:
            raise DesignError(f"no branch through the reference d_in = {d0:.10g} reaches "
                              f"{toward:.10g}")
        chosen = candidates[0]
    if branch is not None:
        if not 0 <= int(branch) < len(branches):
            raise DesignError(f"branch must be in 0..{len(branches) - 1} (the motion has "
                              f"{len(branches)} monotone branches), got {branch}")
        chosen = branches[int(branch)]
    if not chosen.hi > chosen.lo:
        raise ConstructionError(
            f"the reference configuration is a turning point of d_in = {d0:.10g}: the branch "
            "through it is a single point; pass `toward` to choose the branch on either side")

    def fun_for(br):
        def fun(d, derivative=True):
            f, df, _, _ = ev(np.asarray(d, dtype=np.float64), br.signs, derivative, margins=False)
            return f, df
        return fun

    def curve_fun(br, samples_per_branch):
        if samples_per_branch is None:
            return fun_for(br)
        g = np.linspace(br.lo, br.hi, int(samples_per_branch))
        return g, ev(g, br.signs, derivative=False)[0]

    label = name or f"{_label(net, d_in)} -> {_label(net, d_out)}"
    return Map1D(fun=fun_for(chosen), domain=(chosen.lo, chosen.hi), branches=branches,
                 branch=chosen, source="constructive", name=label, curve_fun=curve_fun,
                 reference=d0 if chosen.lo <= d0 <= chosen.hi else None)


def _walk_from_end(ev, signs, d_end, size, samples):
    """Branch with these signs that starts at the turning value d_end."""
    # The new branch exists on one side of d_end; probe both sides just off the end.
    eps = 1e-9 * size
    for side in (-1.0, 1.0):
        probe = np.array([d_end + side * eps])
        _, _, m, _ = ev(probe, signs, derivative=False)
        if m[0] >= -_FLAT_SLACK:
            lo, hi, wlo, whi = _walk_branch(ev, signs, float(probe[0]), size, samples)
            return lo, hi, wlo, whi
    return d_end, d_end, -1, -1


def _label(net, spec):
    return spec if isinstance(spec, str) else f"|x{spec[0]} - x{spec[1]}|"


# --------------------------------------------------------------------------------------------
# Maps read off a traced motion
# --------------------------------------------------------------------------------------------
def _correct(net, X0, pair, targets, tol=1e-14, max_iter=30):
    """Newton (minimum-norm steps) onto edge lengths and |x_a - x_b| = target, batched."""
    X = np.array(X0, dtype=np.float64)
    k, n, dim = X.shape
    e = net.edges
    m = e.shape[0]
    L2 = net.edge_lengths ** 2
    a, b = pair
    rows = np.arange(m)
    for _ in range(max_iter):
        diff = X[:, e[:, 0]] - X[:, e[:, 1]]
        u = X[:, a] - X[:, b]
        r = np.concatenate([np.einsum("kec,kec->ke", diff, diff) - L2,
                            (np.einsum("kc,kc->k", u, u) - targets ** 2)[:, None]], axis=1)
        scale = np.concatenate([L2, [np.max(targets) ** 2]])
        if np.max(np.abs(r) / scale) < tol:
            break
        J = np.zeros((k, m + 1, n, dim))
        J[:, rows, e[:, 0]] = 2 * diff
        J[:, rows, e[:, 1]] = -2 * diff
        J[:, m, a] = 2 * u
        J[:, m, b] -= 2 * u
        J = J.reshape(k, m + 1, n * dim)
        step = np.einsum("kij,kj->ki", np.linalg.pinv(J, rcond=1e-13), r)
        X = X - step.reshape(k, n, dim)
    else:
        raise KinematicsError("Newton correction onto the constraint set did not converge "
                              "(a value beyond the traced branch?)")
    return X


def map_from_trajectory(traj, d_in="d1", d_out="d2", name: str | None = None) -> Map1D:
    """A map read off a traced motion (e.g. ``method="projected"``).

    The domain is the range of d_in covered by the trajectory (monotone up to a turning point:
    the tracing methods stop there). A value f(d) starts from the configuration interpolated
    between the two nearest samples and is corrected onto the constraint set with d_in = d by
    Newton's method; the slope is exact by implicit differentiation (:func:`slope_at`).

    Parameters
    ----------
    traj : Trajectory
    d_in, d_out : str or (int, int)

    Returns
    -------
    Map1D

    Raises
    ------
    KinematicsError
        When d_in is not monotone along the trajectory.
    """
    net = traj.network
    a, b = _pair(net, d_in)
    out = _pair(net, d_out)
    P = traj.positions
    din = np.linalg.norm(P[:, a] - P[:, b], axis=1)
    inc = np.diff(din)
    if not (np.all(inc > 0) or np.all(inc < 0)):
        raise KinematicsError("d_in is not monotone along this trajectory; split it at its "
                              "turning points first")
    order = np.argsort(din)
    din, P = din[order], P[order]

    def fun(d, derivative=True):
        d = np.asarray(d, dtype=np.float64)
        flat = np.atleast_1d(d).ravel()
        k = np.clip(np.searchsorted(din, flat) - 1, 0, din.size - 2)
        t = ((flat - din[k]) / (din[k + 1] - din[k]))[:, None, None]
        X0 = (1 - t) * P[k] + t * P[k + 1]
        X = _correct(net, X0, (a, b), flat)
        i, j = out
        f = np.linalg.norm(X[:, i] - X[:, j], axis=1)
        df = slope_at(net, X, (a, b), out) if derivative else None
        shape = d.shape
        return f.reshape(shape), (df.reshape(shape) if derivative else None)

    br = Branch(0, float(din[0]), float(din[-1]), (), ("end of the trajectory",) * 2)
    return Map1D(fun=fun, domain=(float(din[0]), float(din[-1])), branches=[br], branch=br,
                 source="trajectory", name=name or f"{_label(net, d_in)} -> {_label(net, d_out)}")
