"""Map wishes: fixed points (with slopes) and a 2-cycle, read, checked and refused when they
cannot be met.

On one branch of a module's motion (where d1 parametrises it, what :func:`fabkit.module_map`
returns) the map is a continuous function, and the construction designs a module's states:

* a map has one slope at each point;
* on a 2-cycle f(A) = B, f(B) = A, f(d) - d changes sign between A and B, so the map crosses
  d2 = d1 between them: a wished fixed point beside a cycle must be that one, and a second one
  would be a third designed state;
* the construction fixes the designed nodes at the first wished state, their velocities there
  (one slope) and their positions at one or two further states: more fixed points, a slope at a
  second one, or a slope beside a cycle, are beyond it;
* states too close together (the map would have to bend sharply) or too far apart (the bars
  that keep their length at both would be far out of proportion) are refused with limits found
  by measurement.

Wishes that break these rules raise :class:`WishError` (exit status 2) with one line that names
the wish and says why; :func:`fabkit.design.design_map` adds the nearest wish it can build.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass

import numpy as np

from ..errors import DesignError

__all__ = ["WishError", "FixedPointWish", "MapWish", "parse_fixed_point", "parse_cycle",
           "parse_decimal", "check_wish", "MAX_REACH", "MAX_SLOPE", "MIN_GAP", "CYCLE_MIN_GAP",
           "WISH_RANGE"]

#: Two wished distances closer than this (relative) are one point.
SAME_POINT_RTOL = 1e-9
#: Two wished fixed points must differ by at least this fraction of the larger: the map must
#: cross d2 = d1 at both with its slopes in between, and closer pairs need sharply bent maps
#: that no buildable candidate of the search gives (measured with slopes free, 0, -0.5 and 2 at
#: the first: every ratio within 5 % fails; 10 % up builds for all four, 10 % down for three;
#: see docs/design.md).
MIN_GAP = 0.1
#: The same for the two values of a 2-cycle (measured: 3 % fails, 5 % builds).
CYCLE_MIN_GAP = 0.05
#: The largest ratio between two wished distances of one module: its designed triangles at the
#: two states differ this much in size, and bars that keep their length at both grow out of
#: proportion (measured: ratios 0.4 to 2.5 build for slopes free, 0, -0.5 and 2, and cycles up
#: to 2.5; the search checks each case).
MAX_REACH = 2.5
#: Wished distances (fixed points, a cycle's values) are accepted in this range of design
#: units. A kit is cut at 100 mm per design unit unless its template says otherwise, so the
#: range is 5 mm to 2 m: below it a module's joints (at least 0.12 of its size apart, the
#: designer's rule) come closer than 0.6 mm, about the least gap a 3D printer keeps open between
#: parts (fabkit's print gaps are 0.4-0.5 mm), and above it a module outgrows any laser sheet or
#: printer bed (a 600 mm sheet holds bars of 2.5 units). Within it the designer's absolute
#: floors (joint room, rigidity, tolerances of 1e-9) mean what they say; the paper's modules
#: lie at 0.57-2.9 units. Numbers far outside (1e160, 1e308) would overflow in the squares of
#: the construction.
WISH_RANGE = (0.05, 20.0)
#: A decimal number as typed: digits with an optional point and exponent (no ``1_5``, ``inf``,
#: ``nan``, hexadecimal or spaces inside).
DECIMAL = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
#: The largest |slope| designed: steeper slopes put the variable nodes next to the designed
#: ones (a nearly flat module); 10 is already a chain that amplifies errors 10x per module.
MAX_SLOPE = 10.0
#: Most fixed points a wish may list (read before any is checked: a module designs two, and
#: the nearby pairs offered instead grow as the square of the count).
MAX_GIVEN = 16


class WishError(DesignError):
    """A map wish that no module can meet (exit status 2).

    Parameters
    ----------
    wish : str
        The wish as typed on the command line (``"--fixed-point 1.6:-0.5"``).
    reason : str
        Why it cannot be met.
    nearest : str, optional
        The nearest wish that can, as command-line options.
    candidates : sequence of MapWish, optional
        Nearby wishes to try when the nearest is not known yet.
    """

    code = "wish"
    exit_code = 2

    def __init__(self, wish: str, reason: str, nearest: str | None = None, candidates=()):
        self.wish = wish
        self.reason = reason
        self.nearest = nearest
        #: Nearby wishes (MapWish) to try, nearest first, when ``nearest`` is not yet known: the
        #: designer keeps the first one it can build (see :func:`fabkit.design.design_map`).
        self.candidates = tuple(candidates)
        tail = f"; nearest feasible: {nearest}" if nearest else ""
        super().__init__(f"{wish}: {reason}{tail}")


def _num(v: float) -> str:
    return f"{float(v):.10g}"


@dataclass(frozen=True)
class FixedPointWish:
    """A wished fixed point D* = f(D*), with the slope f'(D*) when one is asked."""

    value: float
    slope: float | None = None

    def option(self) -> str:
        tail = "" if self.slope is None else f":{_num(self.slope)}"
        return f"--fixed-point {_num(self.value)}{tail}"


@dataclass(frozen=True)
class MapWish:
    """Everything asked of one module's map.

    Attributes
    ----------
    fixed_points : tuple of FixedPointWish
        In the order asked (after :func:`check_wish`: at most two, the one with a slope first).
    cycle : (float, float) or None
        A 2-cycle f(A) = B, f(B) = A.
    """

    fixed_points: tuple = ()
    cycle: tuple | None = None

    def options(self) -> str:
        """The wish as command-line options."""
        parts = [p.option() for p in self.fixed_points]
        if self.cycle is not None:
            parts.append(f"--cycle {_num(self.cycle[0])},{_num(self.cycle[1])}")
        return " ".join(parts)


def parse_decimal(text: str) -> float:
    """A decimal number as typed (``1.5``, ``-2``, ``.5``, ``1e-3``), and nothing else:
    Python's ``float`` would also take ``1_5`` (as 15), ``inf``, ``nan`` and spaces.

    Raises
    ------
    ValueError
        Not a decimal number, or one too large for a float (``1e400``).

    Examples
    --------
    >>> parse_decimal("1.5e-1")
    0.15
    >>> parse_decimal("1_5")
    Traceback (most recent call last):
    ...
    ValueError: '1_5' is not a decimal number (digits, an optional point and exponent)
    """
    raw = str(text)
    if not DECIMAL.fullmatch(raw):
        raise ValueError(f"{raw!r} is not a decimal number (digits, an optional point and "
                         "exponent)")
    value = float(raw)
    if not math.isfinite(value):
        raise ValueError(f"{raw!r} is too large for a number")
    return value


def parse_fixed_point(text: str) -> FixedPointWish:
    """``"D"`` or ``"D:SLOPE"`` → :class:`FixedPointWish` (decimal numbers only).

    Raises
    ------
    WishError
        Not decimal numbers.

    Examples
    --------
    >>> parse_fixed_point("1.6:0")
    FixedPointWish(value=1.6, slope=0.0)
    """
    raw = str(text).strip()
    head, sep, tail = raw.partition(":")
    try:
        value = parse_decimal(head)
        slope = parse_decimal(tail) if sep else None
    except ValueError as exc:
        raise WishError(f"--fixed-point {raw}", f"must be D or D:SLOPE with numbers, e.g. 1.6 "
                                                f"or 1.6:0, written as decimals ({exc})") from None
    return FixedPointWish(value, slope)


def parse_cycle(text: str) -> tuple[float, float]:
    """``"A,B"`` → (A, B).

    Raises
    ------
    WishError
        Not two numbers.
    """
    raw = str(text).strip()
    parts = raw.split(",")
    try:
        if len(parts) != 2:
            raise ValueError("not two numbers")
        return parse_decimal(parts[0].strip()), parse_decimal(parts[1].strip())
    except ValueError as exc:
        raise WishError(f"--cycle {raw}", f"must be two numbers A,B, e.g. 1.3,2.0, written "
                                          f"as decimals ({exc})") from None


def _number(value, what: str) -> float:
    """A number given in Python: a string is read as a decimal only (as on the command line)."""
    try:
        return parse_decimal(value) if isinstance(value, str) else float(value)
    except (TypeError, ValueError) as exc:
        raise WishError(what, f"must be a number ({exc})") from None


def _fp(value) -> FixedPointWish:
    if isinstance(value, FixedPointWish):
        return value
    if isinstance(value, str):
        return parse_fixed_point(value)
    what = f"fixed point {value!r}"
    if isinstance(value, (tuple, list)):
        if len(value) != 2:
            raise WishError(what, "must be D or (D, slope)")
        return FixedPointWish(_number(value[0], what),
                              None if value[1] is None else _number(value[1], what))
    return FixedPointWish(_number(value, what))


def _close(a: float, b: float, rtol: float) -> bool:
    return abs(a - b) <= rtol * max(abs(a), abs(b))


def _ratio_steps(anchor: float, value: float, limit: float) -> list[float]:
    """Values from ``anchor`` toward ``value``, the largest ratio allowed first, then closer."""
    up = value > anchor
    out = []
    for r in (limit, 0.9 * limit, 0.8 * limit, 0.7 * limit, 0.6 * limit, 0.5 * limit):
        r = max(r, 1.0 + MIN_GAP)
        v = anchor * r if up else anchor / r
        v = float(f"{v:.4g}")
        if v not in out:
            out.append(v)
    return out


def check_wish(fixed_points=(), cycle=None) -> MapWish:
    """Read and check a wish; the result has at most two fixed points, the one with a slope
    first (it becomes the designed initial state).

    Parameters
    ----------
    fixed_points : sequence
        Each a number D, a pair (D, slope) (slope None: free), a ``"D[:SLOPE]"`` string or a
        :class:`FixedPointWish`.
    cycle : (float, float) or str, optional

    Returns
    -------
    MapWish

    Raises
    ------
    WishError
        A wish that cannot be met; its ``candidates`` are nearby wishes (the designer names the
        nearest one it can build).

    Examples
    --------
    >>> check_wish(["1.1", "1.6:0"]).options()
    '--fixed-point 1.6:0 --fixed-point 1.1'
    >>> check_wish(["1.6:0", "1.6:0.5"])
    Traceback (most recent call last):
    ...
    fabkit.design.wishes.WishError: --fixed-point 1.6:0 --fixed-point 1.6:0.5: two slopes at one point: a map has one slope at each point
    """
    if isinstance(fixed_points, (str, bytes)) or not hasattr(fixed_points, "__iter__"):
        fixed_points = [fixed_points]  # one wish given alone
    given = list(itertools.islice(iter(fixed_points), MAX_GIVEN + 1))
    if len(given) > MAX_GIVEN:
        raise WishError("fixed_points", f"more than {MAX_GIVEN} fixed points given: one "
                                        "module's construction designs two states (its "
                                        "initial one and one more)")
    fps = [_fp(v) for v in given]
    if isinstance(cycle, str):
        cycle = parse_cycle(cycle)
    if cycle is not None:
        what = f"cycle {cycle!r}"
        try:
            a, b = cycle
        except (TypeError, ValueError):
            raise WishError(what, "must be two values (A, B)") from None
        cycle = (_number(a, what), _number(b, what))
    asked = MapWish(tuple(fps), cycle).options()
    if not fps and cycle is None:
        raise WishError("design", "give at least one --fixed-point D[:SLOPE] or a --cycle A,B")
    lo_w, hi_w = WISH_RANGE
    for p in fps:
        if not math.isfinite(p.value) or p.value <= 0:
            raise WishError(p.option(), "a fixed point is a distance between two joints: it must "
                                        "be a positive number")
        if not lo_w <= p.value <= hi_w:
            raise WishError(p.option(), _out_of_range("the fixed point", p.value))
        if p.slope is not None and not math.isfinite(p.slope):
            raise WishError(p.option(), "the slope must be a finite number")
    for p in fps:
        if p.slope is not None and abs(p.slope) > MAX_SLOPE:
            others = tuple(q for q in fps if q is not p)
            cands = [MapWish((FixedPointWish(p.value, math.copysign(m, p.slope)),) + others, cycle)
                     for m in (MAX_SLOPE, 0.8 * MAX_SLOPE, 0.6 * MAX_SLOPE, 0.4 * MAX_SLOPE)]
            raise WishError(asked, f"|slope| above {MAX_SLOPE:g} needs a nearly flat module "
                                   "(variable nodes next to the designed ones)",
                            candidates=cands)
    # one point asked twice: merge, unless the slopes differ
    merged: list[FixedPointWish] = []
    for p in fps:
        same = [q for q in merged if _close(q.value, p.value, SAME_POINT_RTOL)]
        if not same:
            merged.append(p)
            continue
        q = same[0]
        if p.slope is not None and q.slope is not None and p.slope != q.slope:
            rest = tuple(r for r in fps if r is not p and r is not q
                         and not _close(r.value, p.value, SAME_POINT_RTOL))
            raise WishError(asked, "two slopes at one point: a map has one slope at each point",
                            candidates=[MapWish((q,) + rest, cycle), MapWish((p,) + rest, cycle)])
        if q.slope is None and p.slope is not None:
            merged[merged.index(q)] = p
    fps = merged
    if len(fps) > 2:
        pairs = [(fps[i], fps[j]) for i in range(len(fps)) for j in range(i + 1, len(fps))]
        raise WishError(asked, f"{len(fps)} fixed points: one module's construction designs two "
                               "states (its initial one and one more)",
                        candidates=[MapWish(pr, cycle) for pr in pairs])
    if cycle is not None:
        _check_cycle(fps, cycle, asked)
    if len(fps) == 2:
        a, b = fps
        if a.slope is None and b.slope is not None:
            a, b = b, a  # the fixed point with a slope is the designed initial state
        if b.slope is not None:
            raise WishError(asked, "slopes at two fixed points: the construction designs the "
                                   "velocities at one state only (the slope at the other comes out "
                                   "of the design and is reported)",
                            candidates=[MapWish((a, FixedPointWish(b.value)), None),
                                        MapWish((b, FixedPointWish(a.value)), None)])
        if _close(a.value, b.value, MIN_GAP):
            up = b.value >= a.value
            steps = [float(f"{a.value * ((1 + g) if up else 1 - g):.4g}")
                     for g in (1.01 * MIN_GAP, 1.2 * MIN_GAP, 1.5 * MIN_GAP, 2 * MIN_GAP,
                               2.5 * MIN_GAP, 3 * MIN_GAP, 4 * MIN_GAP)]
            raise WishError(asked, f"the fixed points differ by less than {MIN_GAP:.0%}: the map "
                                   "would have to bend too sharply between them",
                            candidates=[MapWish((a, FixedPointWish(v)), None) for v in steps])
        ratio = max(a.value, b.value) / min(a.value, b.value)
        if ratio > MAX_REACH:
            steps = _ratio_steps(a.value, b.value, MAX_REACH)
            raise WishError(asked, f"the fixed point {_num(b.value)} is outside the module's "
                                   f"reach from {_num(a.value)} (a ratio of {ratio:.3g}; one "
                                   f"module's states differ by at most {MAX_REACH:g}x)",
                            candidates=[MapWish((a, FixedPointWish(v)), None) for v in steps])
        fps = [a, b]
    return MapWish(tuple(fps), cycle)


def _out_of_range(what: str, value: float) -> str:
    lo, hi = WISH_RANGE
    side = "below" if value < lo else "above"
    return (f"{what} {_num(value)} is {side} the range of a module's distances, {lo:g} to "
            f"{hi:g} design units (5 mm to 2 m at the kit's default 100 mm per unit: "
            + ("joints closer than a printable gap" if value < lo else
               "bars longer than a laser sheet or printer bed") + ")")


def _check_cycle(fps, cycle, asked) -> None:
    lo, hi = sorted(cycle)
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo <= 0:
        raise WishError(asked, "the cycle's values are distances between joints: they must be "
                               "positive numbers")
    for v in (lo, hi):
        if not WISH_RANGE[0] <= v <= WISH_RANGE[1]:
            raise WishError(asked, _out_of_range("the cycle's value", v))
    if _close(lo, hi, CYCLE_MIN_GAP):
        raise WishError(asked, f"a 2-cycle needs two distinct values (these differ by less than "
                               f"{CYCLE_MIN_GAP:.0%}); one value repeating is a fixed point",
                        candidates=[MapWish((FixedPointWish(0.5 * (lo + hi)),), None)]
                        + [MapWish((), (lo, float(f"{lo * (1 + g):.4g}")))
                           for g in (1.01 * CYCLE_MIN_GAP, 2 * CYCLE_MIN_GAP)])
    if hi / lo > MAX_REACH:
        raise WishError(asked, f"the cycle's values {_num(lo)} and {_num(hi)} cannot lie on one "
                               f"branch of a module (a ratio of {hi / lo:.3g}; one module's "
                               f"states differ by at most {MAX_REACH:g}x)",
                        candidates=[MapWish(tuple(fps[:1]) if fps and lo < fps[0].value < v
                                            else (), (lo, v))
                                    for v in _ratio_steps(lo, hi, MAX_REACH)])
    if len(fps) > 1:
        inside = [p for p in fps if lo < p.value < hi]
        raise WishError(asked, "f(A) - A and f(B) - B have opposite signs on a cycle, so the map "
                               "crosses d2 = d1 between the cycle's values: with a second fixed "
                               "point it would have three designed states",
                        candidates=[MapWish((FixedPointWish(p.value),), cycle) for p in inside]
                        + [MapWish((), cycle)])
    if fps:
        p = fps[0]
        if not lo < p.value < hi:
            ts = sorted(np.linspace(0.1, 0.9, 9), key=lambda t: abs(lo + t * (hi - lo) - p.value))
            raise WishError(asked, f"the fixed point {_num(p.value)} is not between the cycle's "
                                   f"values: f(A) - A and f(B) - B have opposite signs, so the map "
                                   f"also crosses d2 = d1 between {_num(lo)} and {_num(hi)}, at a "
                                   "fixed point that was not asked for",
                            candidates=[MapWish((FixedPointWish(float(f"{lo + t * (hi - lo):.4g}")),),
                                                cycle) for t in ts] + [MapWish((), cycle)])
        if p.slope is not None:
            raise WishError(asked, "a slope beside a cycle: the construction uses its two "
                                   "designed states for the cycle and the fixed point (the slope "
                                   "comes out of the design and is reported)",
                            candidates=[MapWish((FixedPointWish(p.value),), cycle)])
