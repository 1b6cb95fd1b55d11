"""The margin of a verdict: how far every process error may grow before builds stop keeping the
design's behaviour.

Each simulated build keeps its own random draws while all its error parameters are multiplied
by a common scale s (``gain``: the same draws, scaled). A build's *critical scale* is the largest
s at which it still keeps the behaviour, found by bisection on log s between 0.1 and 10 (one
Monte Carlo run per bisection step, every build at its own trial scale). The fraction of builds
that keep the behaviour at scale s is then the fraction whose critical scale is at least s, and
the **margin** is the scale at which that fraction falls to ``min_reached``: at s = 1 (the
process's own errors) the verdict is ok exactly when the margin is at least 1, and a margin below
1 says how much more precise the process must be (errors × margin).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["critical_scales", "keep_curve", "margin_of", "margin_text", "SCALE_RANGE",
           "CURVE_SCALES"]

#: Error scales searched (×: the process's own errors are 1).
SCALE_RANGE = (0.1, 10.0)

#: Bisection steps on log s: the first bracket is a factor of 10, so 4 steps place each build's
#: critical scale within a factor of 10^(1/16) = 1.15 (from below: a margin is never
#: overstated).
SCALE_BISECTIONS = 4

#: Slack on the count of builds needed (``min_reached × M`` is computed in floating point).
COUNT_SLACK = 1e-9

#: Scales at which the chart's curves are drawn and stored.
CURVE_SCALES = np.logspace(-1.0, 1.0, 41)


def critical_scales(run, keep1: np.ndarray, bisections: int = SCALE_BISECTIONS) -> np.ndarray:
    """Largest error scale at which each build keeps the behaviour.

    Parameters
    ----------
    run : callable
        ``run(gains, rows) -> keep``: the builds ``rows`` (indices) judged with their errors
        scaled by ``gains`` (one per row); returns one bool per row.
    keep1 : numpy.ndarray of bool, shape (M,)
        Which builds keep the behaviour at scale 1.
    bisections : int

    Returns
    -------
    numpy.ndarray, shape (M,)
        Each build's critical scale: 10 where it keeps the behaviour even there, 0 where it
        fails already at 0.1, else within a factor 10^(1/2^(bisections+1)) of the true scale
        (assuming a build that fails at some scale fails at every larger one).

    Examples
    --------
    >>> limits = np.array([0.05, 0.5, 2.0, 20.0])   # each build fails past its own scale
    >>> crit = critical_scales(lambda g, rows: g <= limits[rows], limits >= 1)
    >>> step = 10 ** (1 / 2 ** (SCALE_BISECTIONS + 1))  # the resolution: a factor of 1.07
    >>> float(crit[0]), float(crit[3]), bool(0.5 / step**2 < crit[1] <= 0.5)
    (0.0, 10.0, True)
    """
    lo_s, hi_s = SCALE_RANGE
    keep1 = np.asarray(keep1, dtype=bool)
    m = keep1.size
    lo = np.where(keep1, 1.0, lo_s)
    hi = np.where(keep1, hi_s, 1.0)
    crit = np.full(m, np.nan)
    rows = np.arange(m)
    k = np.asarray(run(np.where(keep1, hi_s, lo_s), rows), dtype=bool)
    crit[keep1 & k] = hi_s
    crit[~keep1 & ~k] = 0.0
    open_ = np.flatnonzero(np.isnan(crit))
    for _ in range(int(bisections)):
        if open_.size == 0:
            break
        mid = np.sqrt(lo[open_] * hi[open_])
        k = np.asarray(run(mid, open_), dtype=bool)
        lo[open_] = np.where(k, mid, lo[open_])
        hi[open_] = np.where(k, hi[open_], mid)
    crit[open_] = lo[open_]
    return crit


def keep_curve(crit: np.ndarray, scales=CURVE_SCALES) -> np.ndarray:
    """Fraction of builds that keep the behaviour at each error scale."""
    crit = np.asarray(crit, dtype=np.float64)
    return (crit[None, :] >= np.asarray(scales)[:, None]).mean(axis=1)


def margin_of(crit: np.ndarray, min_reached: float) -> tuple[float, str | None]:
    """The largest scale at which at least ``min_reached`` of the builds keep the behaviour.

    Returns
    -------
    margin : float
    bound : str or None
        ``"at least"`` when the margin is the top of the searched range (10), ``"below"`` when
        even 0.1 fails.

    Examples
    --------
    >>> margin_of(np.array([0.5, 2.0, 3.0, 4.0]), 0.75)
    (2.0, None)
    """
    crit = np.sort(np.asarray(crit, dtype=np.float64))[::-1]
    need = max(int(math.ceil(min_reached * crit.size - COUNT_SLACK)), 1)
    value = float(crit[min(need, crit.size) - 1])
    lo_s, hi_s = SCALE_RANGE
    if value >= hi_s:
        return hi_s, "at least"
    if value < lo_s:
        return lo_s, "below"
    return value, None


def margin_text(value: float, bound: str | None) -> str:
    """A margin as printed: ``"2.4"``, ``"≥ 10"`` or ``"< 0.1"``.

    Examples
    --------
    >>> margin_text(2.37, None), margin_text(10.0, "at least"), margin_text(0.1, "below")
    ('2.4', '≥ 10', '< 0.1')
    """
    return {"at least": "≥ ", "below": "< "}.get(bound, "") + f"{value:.2g}"
