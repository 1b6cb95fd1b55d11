"""The map on one branch: values, derivatives, fixed points, cycles, Lyapunov exponents."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .. import arguments
from ..errors import ArgumentTypeError, DesignError
from ..numerics import DOMAIN_RTOL, FIXED_POINT_RTOL
from ..io.workload import require
from .results import Branch, Cycle, FixedPoint, LyapunovResult, classify_slope


#: The reference configuration counts as a fixed point when |f(d) - d| is below this (relative
#: to the domain): modules are designed at one, and an exact evaluation leaves round-off.
REFERENCE_RESIDUAL = 1e-12
#: A grid point where |f(d) - d| (or |f^m(d) - d|) is below this is a root itself.
ON_GRID_ROOT = 1e-13
#: Brent's method refines roots to this absolute tolerance (relative to the domain): round-off.
ROOT_XTOL = 1e-15
#: A root within this of the reference fixed point (relative) is the reference itself.
REFERENCE_SEPARATION = 1e-6
#: Roots closer than this (relative) are one root, the best resolved kept.
SAME_ROOT = 1e-7
#: Two neutral fixed points this close (relative) are one touching fixed point (f(d) - d with a
#: double root) split in two: a change ε of the design splits it by ~√ε, 1e-6 for ε = 1e-12.
TANGENT_SPLIT = 1e-5
#: A cycle point that returns within this (relative) after a shorter period has that period.
SHORTER_PERIOD = 1e-9
#: The cubic Hermite table of the map is used only when it reproduces f to this (relative to
#: the domain) and f' to TABLE_SLOPE_RTOL at the interval midpoints; else the exact map is.
TABLE_VALUE_RTOL = 1e-11
TABLE_SLOPE_RTOL = 1e-8
#: A fixed point within this (relative to the domain) of an end of its branch where the motion
#: turns back lies at that end (a flat state); an end whose image misses it by no more than this
#: is such a fixed point itself. A design placed exactly there (the flat origami sheet, a chain
#: of sheets unfolding to flat) moves it off by ~1e-12 when its coordinates change by 1e-12, and
#: by the square root of that (1e-6) where the end is a flat state that branches cross, far
#: below this; 1e-4 of a 100 mm module is 10 µm, far below any fabrication error.
END_FIXED_POINT_RTOL = 1e-4
#: The slope of a fixed point at an end is the limit from inside: f' at these distances from the
#: end (relative to the domain), extrapolated linearly to it; at the end itself the place of a
#: node, and so f', hangs on round-off. A slope that grows like 1/√h between them (a vertical
#: tangent: |f'| at least doubles from the first to the second) is infinite.
END_SLOPE_STEPS = (1e-4, 1e-5)


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
    configuration_fun: Callable | None = field(default=None, repr=False)

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
        slack = DOMAIN_RTOL * max(abs(lo), abs(hi), 1.0)
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
        slack = DOMAIN_RTOL * max(abs(lo), abs(hi), 1.0)
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
        try:
            x = np.atleast_1d(np.asarray(d, dtype=np.float64))
        except (TypeError, ValueError):
            raise ArgumentTypeError("d", f"must be a number or an array of numbers, got "
                                         f"{type(d).__name__}") from None
        steps = arguments.whole("steps", steps, minimum=0)
        require("Map1D.iterate", ("orbit step", steps), ("map evaluation", steps * x.size),
                ("stored value", (steps + 1) * x.size))
        out = np.empty((steps + 1, x.size))
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
        samples = arguments.whole("samples", samples, minimum=3)
        require("Map1D grid", ("map evaluation", samples), ("stored value", 4 * samples))
        lo, hi = self.domain
        return np.linspace(lo, hi, samples)

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
        from scipy.optimize import brentq

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
            if ref.residual > REFERENCE_RESIDUAL * scale:
                ref = None
        for k in np.flatnonzero(np.abs(g) <= ON_GRID_ROOT * scale):
            roots.append(float(grid[k]))
        sgn = np.sign(g)
        for k in np.flatnonzero(sgn[:-1] * sgn[1:] < 0):
            try:
                roots.append(brentq(lambda x: self._values(x)[0] - x, grid[k], grid[k + 1],
                                    xtol=ROOT_XTOL * scale, rtol=4 * np.finfo(float).eps,
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
            roots = [r for r in roots if abs(r - ref.value) > REFERENCE_SEPARATION * scale] + [ref.value]
        found = self._at_ends(self._dedupe_fixed(roots, scale), scale)
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

    def _turning_ends(self) -> list[tuple[float, float]]:
        """The domain's ends where the motion turns back, each with the side (+1 or -1) of the
        branch as seen from it."""
        if self.branch is None:
            return []
        lo, hi = self.domain
        out = []
        for end, side, turning in ((lo, 1.0, self.branch.turning[0]),
                                   (hi, -1.0, self.branch.turning[1])):
            if turning:
                out.append((float(end), side))
        return out

    def _end_slope(self, end: float, side: float) -> float:
        """The limit of f' at a turning end from inside the branch (:data:`END_SLOPE_STEPS`)."""
        width = self.domain[1] - self.domain[0]
        h1, h2 = (s * width for s in END_SLOPE_STEPS)
        _, d = self._values(np.array([end + side * h1, end + side * h2]), derivative=True)
        s1, s2 = float(d[0]), float(d[1])
        if not (np.isfinite(s1) and np.isfinite(s2)):
            return float("inf")
        if abs(s2) >= 2.0 * abs(s1):  # grows like 1/sqrt(h): a vertical tangent
            return float("inf")
        return (s2 * h1 - s1 * h2) / (h1 - h2)

    def _at_ends(self, found: list[FixedPoint], scale: float) -> list[FixedPoint]:
        """Fixed points at a turning end of the branch (see :data:`END_FIXED_POINT_RTOL`):
        marked, with their slope as the limit from inside; an end whose image misses it by no
        more than that tolerance added as one."""
        tol = END_FIXED_POINT_RTOL * scale
        out = list(found)
        for end, side in self._turning_ends():
            near = [k for k, p in enumerate(out) if abs(p.value - end) <= tol]
            slope = self._end_slope(end, side)
            if near:
                for k in near:
                    out[k] = dataclasses.replace(out[k], slope=slope, kind=classify_slope(slope),
                                                 at_end=True)
                continue
            f, _ = self._values(np.array([end]))
            miss = abs(float(f[0]) - end)
            if miss <= tol:
                out.append(FixedPoint(value=end, slope=slope, kind=classify_slope(slope),
                                      residual=miss, at_end=True))
        return sorted(out, key=lambda p: p.value)

    def _touching_root(self, a, b):
        from scipy.optimize import minimize_scalar

        r = minimize_scalar(lambda x: abs(float(self._values(x)[0]) - x), bounds=(a, b),
                            method="bounded", options={"xatol": 1e-14})
        return float(r.x) if r.fun < FIXED_POINT_RTOL else None

    def _fixed(self, x):
        f, df = self._values(x, derivative=True)
        s = float(df)
        if not np.isfinite(s):  # at a turning point of d_in: a vertical tangent
            s = float("inf")
        kind = classify_slope(s)
        return FixedPoint(value=float(x), slope=s, kind=kind, residual=abs(float(f) - float(x)))

    def _dedupe_fixed(self, roots, scale):
        """Keep true roots (residual <= 1e-10), one per cluster (the best resolved); two
        neutral roots within :data:`TANGENT_SPLIT` are one touching fixed point, split by
        round-off (or a change of the design far below any that matters): kept as one, midway."""
        cands = [p for p in (self._fixed(x) for x in sorted(roots)) if p.residual <= FIXED_POINT_RTOL * scale]
        out: list[FixedPoint] = []
        for p in cands:
            if out and abs(p.value - out[-1].value) <= SAME_ROOT * scale:
                if p.residual < out[-1].residual:
                    out[-1] = p
                continue
            if out and abs(p.value - out[-1].value) <= TANGENT_SPLIT * scale \
                    and p.kind == out[-1].kind == "neutral":
                mid = self._fixed(0.5 * (p.value + out[-1].value))
                out[-1] = dataclasses.replace(mid, residual=max(mid.residual, p.residual,
                                                                 out[-1].residual))
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
        from scipy.optimize import brentq

        m = arguments.whole("period", period)
        samples = arguments.whole("samples", samples, minimum=3)
        if m < 2:
            raise DesignError(f"period must be at least 2 (fixed points: fixed_points()), got {m}")
        require("Map1D.cycles", ("map evaluation", m * samples))
        if any(self.is_identity(p) for p in range(1, m + 1) if m % p == 0):
            return []  # a continuum of cycles, not isolated ones (see is_identity)
        lo, hi = self.domain
        scale = max(abs(lo), abs(hi), 1.0)
        grid = self._grid(samples)
        g = self._power(grid, m) - grid
        roots = list(grid[np.abs(g) <= ON_GRID_ROOT * scale])
        ok = np.isfinite(g[:-1]) & np.isfinite(g[1:])
        for k in np.flatnonzero(ok & (np.sign(g[:-1]) * np.sign(g[1:]) < 0)):
            fun = lambda x: float(self._power(x, m)) - x  # noqa: E731
            try:
                roots.append(brentq(fun, grid[k], grid[k + 1], xtol=ROOT_XTOL * scale,
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
            tol = SHORTER_PERIOD * scale
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
        from scipy.optimize import brentq

        x = np.linspace(lo, hi, int(samples))
        f, df = self._values(x, derivative=True)
        vals = [np.nanmin(f), np.nanmax(f)]
        sd = np.sign(df)
        for k in np.flatnonzero(sd[:-1] * sd[1:] < 0):
            try:
                c = brentq(lambda t: float(self._values(t, True)[1]), x[k], x[k + 1], xtol=ROOT_XTOL)
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
        slack = DOMAIN_RTOL * max(abs(lo), abs(hi), 1.0)
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
                 method: str = "auto", progress=None) -> LyapunovResult:
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
        progress : callable, optional
            ``progress(done, total)``: iterations done of ``discard + average``, about a
            hundred times along the way.

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
        arguments.choice("method", method, ("auto", "exact", "table"))
        discard = arguments.whole("discard", discard, minimum=0)
        average = arguments.whole("average", average, minimum=1)
        if np.ndim(initial) == 0:
            count = arguments.whole("initial", initial, minimum=1)
        else:
            count = int(np.size(initial))
        require("Map1D.lyapunov", ("map evaluation", count * (discard + average)),
                ("stored value", 8 * count))
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
        iterations = int(discard) + int(average)
        every = max(1, iterations // 100)
        with np.errstate(invalid="ignore", divide="ignore"):
            for i in range(int(discard)):
                x = step(x, False)[0]
                if progress is not None and i % every == 0:
                    progress(i, iterations)
            total = np.zeros_like(x)
            for i in range(int(discard), iterations):
                fx, df = step(x, True)
                total += np.log(np.abs(df))
                x = fx
                if progress is not None and i % every == 0:
                    progress(i, iterations)
        if progress is not None:
            progress(iterations, iterations)
        lam = total / max(int(average), 1)
        ok = np.isfinite(x0) & ~np.isnan(lam)
        vals = np.where(ok, lam, np.nan)
        good = vals[ok]
        # an orbit through a super-stable point has exponent -inf (log 0): the mean is -inf and
        # the spread undefined (nan), without numpy's warning about inf - inf
        with np.errstate(invalid="ignore"):
            mean = float(np.mean(good)) if good.size else float("nan")
            std = float(np.std(good)) if good.size else float("nan")
        return LyapunovResult(mean=mean, std=std,
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

    def configuration(self, d) -> np.ndarray:
        """The network's configuration(s) on this branch at d_in = d.

        Parameters
        ----------
        d : float or array_like, shape (K,)
            Inside the domain.

        Returns
        -------
        numpy.ndarray, shape (N, dim) for a scalar d, (K, N, dim) for an array
            In the construction's seed frame (see :func:`fabkit.kinematics.place`).

        Raises
        ------
        DesignError
            d outside the domain, or a map without configurations (read off a trajectory or
            given in closed form).
        """
        if self.configuration_fun is None:
            raise DesignError(f"the map {self.name} ({self.source}) has no configurations: "
                              "build it with module_map")
        d = self._check(d)
        x = self.configuration_fun(self.branch, d)
        return x[0] if np.ndim(d) == 0 else x

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
    if err["f"] > TABLE_VALUE_RTOL * scale or err["derivative"] > TABLE_SLOPE_RTOL * max(1.0, float(np.max(np.abs(df)))):
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
