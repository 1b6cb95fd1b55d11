"""Result objects of a 1-D map: branches, fixed points, cycles, Lyapunov exponents."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..numerics import NEUTRAL_SLOPE_TOL, SLOPE_TOL


def classify_slope(slope: float, tol: float = SLOPE_TOL) -> str:
    """Stability class of a fixed point or cycle from its slope (multiplier).

    Returns one of ``"super-stable"`` (|s| < tol), ``"stable"`` (|s| < 1), ``"neutral"``
    (|s| = 1 within :data:`~fabkit.numerics.NEUTRAL_SLOPE_TOL`), ``"unstable"`` (|s| > 1),
    ``"super-unstable"`` (|s| > 1/tol, or an infinite slope at a turning point of d_in).

    Examples
    --------
    >>> classify_slope(0.0), classify_slope(-0.5), classify_slope(2.0)
    ('super-stable', 'stable', 'unstable')
    """
    a = abs(float(slope))
    if a < tol:
        return "super-stable"
    if abs(a - 1.0) <= max(tol, NEUTRAL_SLOPE_TOL):
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
    at_end : bool
        D* lies at an end of its branch, where the motion turns back (a flat state): within
        :data:`fabkit.maps.map1d.END_FIXED_POINT_RTOL` of it, or the end itself when its image
        misses it by no more than that. Its slope is then the limit from inside the branch.
    """

    value: float
    slope: float
    kind: str
    residual: float = 0.0
    at_end: bool = False

    def as_dict(self) -> dict:
        return {"value": self.value, "slope": self.slope, "kind": self.kind,
                "residual": self.residual, "at_end": self.at_end}


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
        What ends the branch at lo and at hi, in words (a turning point: which node becomes
        flat).
    turning : tuple of bool
        Whether the branch ends at a turning point of d_in at lo and at hi (what code reads;
        ``ends`` is for people).
    previous : int or None
        Index of the branch the walk came from (None for the branch through the reference).
    entered_at : float or None
        The d_in of the turning point where the walk passed onto this branch from
        ``previous``; it walks on towards the other end.
    """

    index: int
    lo: float
    hi: float
    signs: tuple
    ends: tuple = ("", "")
    previous: int | None = None
    entered_at: float | None = None
    turning: tuple = (False, False)

    def as_dict(self) -> dict:
        return {"index": self.index, "domain": [self.lo, self.hi], "ends": list(self.ends)}
