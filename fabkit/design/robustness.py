"""Do built modules keep what was wished? Judging a Monte Carlo of builds.

A module from map wishes is a paper design: its fixed points and cycle sit exactly where they
were asked, but a built module has bars a little off. Given the bar lengths of many builds (a
process's error model draws them: the laser's in :mod:`fabkit.tolerance.processes` — bar
length, kerf, hole play, sheet thickness at the kit's scale — which the command line hands to
the designer as a ``sample_builds`` function, see :func:`fabkit.design.design_map`), each
build is placed on the branch of the design by circle intersections
(:func:`~fabkit.design.geometry.module_motion`, all builds at once) over the wished states,
and it *keeps* the wish when its map has

* every wished fixed point within ``STATE_RTOL`` of the wished value, with the same stability
  (|slope| below or above 1),
* the wished 2-cycle within ``STATE_RTOL`` of both values, with the same stability,

all on the branch of the design (a build whose fold has moved past a wished state has lost it).
The fraction of builds that keep the wish is what a suggestion must reach (``MIN_KEPT``, the
tolerance analysis's default: 95 %) before it is printed; a design reports it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry import bar_lengths, branch_signs, module_motion

__all__ = ["BuildCheck", "check_builds", "STATE_RTOL", "MIN_KEPT", "BUILDS"]

#: A built fixed point (or cycle value) within this fraction of the wished one is the wished
#: one: a 2 % change of a module's shape is about what a maker sees by eye (the tolerance
#: analysis's default limit).
STATE_RTOL = 0.02
#: Fraction of builds that must keep the wish.
MIN_KEPT = 0.95
#: Builds simulated, and drive values per build.
BUILDS = 200
GRID = 1601
#: The drive is sampled this far (fraction) beyond the wished states.
REACH = 0.1
#: Relative step of the central difference for the design's own slope (its map is exact).
SLOPE_STEP = 1e-6


@dataclass(frozen=True)
class BuildCheck:
    """What laser-cut builds of a module keep.

    Attributes
    ----------
    kept : float
        Fraction of builds that keep every wish.
    builds : int
    scale : float
        mm per design unit of the builds.
    model : str
        The process's errors, one sentence.
    lost : dict of str to float
        Per wished feature (``"fixed point 1.6"``, ``"2-cycle 1.3,1.8"``): the fraction of
        builds that lose it.
    """

    kept: float
    builds: int
    scale: float
    model: str
    lost: dict

    @property
    def passed(self) -> bool:
        return self.kept >= MIN_KEPT

    def as_dict(self) -> dict:
        return {"kept": self.kept, "builds": self.builds, "scale_mm_per_unit": self.scale,
                "process": self.model, "lost": dict(self.lost), "needed": MIN_KEPT,
                "state_rtol": STATE_RTOL}


def _roots(g: np.ndarray, grid: np.ndarray):
    """Sign changes of g (B, G) along the grid: (build index, root) by linear interpolation."""
    s = np.sign(g)
    hit = (s[:, :-1] * s[:, 1:] < 0) & np.isfinite(g[:, :-1]) & np.isfinite(g[:, 1:])
    b, k = np.nonzero(hit)
    t = g[b, k] / (g[b, k] - g[b, k + 1])
    return b, grid[k] + t * (grid[k + 1] - grid[k])


def _slope(f: np.ndarray, grid: np.ndarray, b: np.ndarray, x: np.ndarray) -> np.ndarray:
    """f'(x) of build b by the grid's central differences, interpolated."""
    df = np.gradient(f, grid, axis=1)
    k = np.clip(np.searchsorted(grid, x) - 1, 0, grid.size - 2)
    t = (x - grid[k]) / (grid[k + 1] - grid[k])
    return (1 - t) * df[b, k] + t * df[b, k + 1]


def _interp_rows(f: np.ndarray, grid: np.ndarray, x: np.ndarray) -> np.ndarray:
    """f_b(x_b) for every row b of f (B, G) at points x (B, P); NaN off the grid."""
    k = np.clip(np.searchsorted(grid, x) - 1, 0, grid.size - 2)
    t = (x - grid[k]) / (grid[k + 1] - grid[k])
    rows = np.arange(f.shape[0])[:, None]
    out = (1 - t) * f[rows, k] + t * f[rows, k + 1]
    return np.where((x >= grid[0]) & (x <= grid[-1]), out, np.nan)


def check_builds(nodes, wish, built, *, scale: float, model: str = "") -> BuildCheck:
    """Count the builds of a 5-node module that keep the wish.

    Parameters
    ----------
    nodes : array_like, shape (5, 2)
        The designed module (bars ``MODULE_EDGES``; d1 = |x0 - x1|, d2 = |x1 - x2|), at a
        configuration on the designed branch.
    wish : MapWish
    built : array_like, shape (M, 6)
        Bar lengths of M builds, in the order of ``MODULE_EDGES`` (design units).
    scale : float
        mm per design unit of the builds (for the report).
    model : str
        The process's errors, one sentence (for the report).

    Returns
    -------
    BuildCheck

    Examples
    --------
    >>> from fabkit.design import design_map
    >>> from fabkit.design.wishes import check_wish
    >>> result = design_map([(1.6, 0.0), 1.1])
    >>> x = result.network.nodes
    >>> rng = np.random.default_rng(0)
    >>> built = bar_lengths(x) + 5e-4 * rng.standard_normal((200, 6))   # 0.05 mm at 100 mm/unit
    >>> check_builds(x, check_wish([(1.6, 0.0), 1.1]), built, scale=100.0).passed
    True
    """
    x = np.asarray(nodes, dtype=np.float64)
    built = np.asarray(built, dtype=np.float64)
    signs = np.broadcast_to(branch_signs(x), (built.shape[0], 3))
    values = [p.value for p in wish.fixed_points] + list(wish.cycle or ())
    lo, hi = min(values) * (1 - REACH), max(values) * (1 + REACH)
    grid = np.linspace(lo, hi, GRID)
    with np.errstate(invalid="ignore", divide="ignore"):
        xs = module_motion(built, signs, grid)
        f = np.linalg.norm(xs[:, :, 1] - xs[:, :, 2], axis=-1)             # (B, G)
    m = built.shape[0]
    keep = np.ones(m, dtype=bool)
    lost = {}
    for p in wish.fixed_points:
        b, r = _roots(f - grid[None, :], grid)
        slope_design = _design_slope(x, p.value)
        near = np.abs(r - p.value) <= STATE_RTOL * p.value
        same = (np.abs(_slope(f, grid, b, r)) < 1) == (abs(slope_design) < 1)
        ok = np.zeros(m, dtype=bool)
        ok[b[near & same]] = True
        lost[f"fixed point {p.value:.10g}"] = float(1 - ok.mean())
        keep &= ok
    if wish.cycle is not None:
        a, c = sorted(wish.cycle)
        with np.errstate(invalid="ignore"):
            ff = _interp_rows(f, grid, f)                                   # f(f(d))
        b, r = _roots(ff - grid[None, :], grid)
        fr = np.array([np.interp(rv, grid, f[bv]) for bv, rv in zip(b, r)]) if r.size else r
        hit = (np.abs(r - a) <= STATE_RTOL * a) & (np.abs(fr - c) <= STATE_RTOL * c)
        design_mult = _design_multiplier(x, a, c)
        mult = _slope(f, grid, b, r) * _slope(f, grid, b, np.clip(fr, grid[0], grid[-1]))
        same = (np.abs(mult) < 1) == (abs(design_mult) < 1)
        ok = np.zeros(m, dtype=bool)
        ok[b[hit & same]] = True
        lost[f"2-cycle {a:.10g},{c:.10g}"] = float(1 - ok.mean())
        keep &= ok
    return BuildCheck(kept=float(keep.mean()), builds=m, scale=float(scale), model=model,
                      lost=lost)


def _design_map(x: np.ndarray, d: np.ndarray) -> np.ndarray:
    L = bar_lengths(x)[None]
    s = branch_signs(x)[None]
    xs = module_motion(L, s, np.asarray(d, dtype=np.float64))[0]
    return np.linalg.norm(xs[:, 1] - xs[:, 2], axis=-1)


def _design_slope(x: np.ndarray, d: float) -> float:
    h = SLOPE_STEP * d
    f = _design_map(x, np.array([d - h, d + h]))
    return float((f[1] - f[0]) / (2 * h))


def _design_multiplier(x: np.ndarray, a: float, b: float) -> float:
    s = _design_slope(x, a) * _design_slope(x, b)
    return s if math.isfinite(s) else math.inf
