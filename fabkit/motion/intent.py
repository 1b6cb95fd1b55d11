"""What a design's motion is meant to do: its stated intent, where its modules' map is fixed,
where it locks.

The motion stage judges whether a traced motion reached the ends its design is for
(:mod:`fabkit.motion.ends`); the tolerance analysis judges builds by the same intent
(:mod:`fabkit.tolerance.behaviour`). Both read it here.
"""

from __future__ import annotations

import numpy as np

from ..errors import TemplateError
from ..kinematics import place

__all__ = ["INTENTS", "STATE_FRACTION", "LIMIT_FRACTION", "template_intent", "nominal_lock",
           "map_fixed_points", "end_fixed_point"]

#: Values of ``[motion] intent``.
INTENTS = ("auto", "target", "lock", "state", "shape")

#: The default of ``state_fraction``: a module is in a state (a crystal, its lock) within a
#: quarter of its travel from it, nearer that state than the middle of the transition by a
#: factor of two (so a state that merely moves stays the same state; one that vanishes or
#: moves past that is another).
STATE_FRACTION = 0.25

#: Default limit of a port distance as a fraction of the mean designed port distance: a 2 %
#: change of a module's shape is about what a maker sees by eye.
LIMIT_FRACTION = 0.02


def template_intent(design) -> str:
    """``[motion] intent`` of a design's template, checked ("auto" when absent)."""
    motion = design.raw.get("motion") if isinstance(design.raw, dict) else None
    value = motion.get("intent", "auto") if isinstance(motion, dict) else "auto"
    if value not in INTENTS:
        raise TemplateError(design.path or design.name, "motion.intent",
                            f"must be one of {', '.join(INTENTS)}, got {value!r}")
    return value


def nominal_lock(plan, to: float, start: float, reach: float) -> float | None:
    """Where the nominal motion, continued past the target, locks, if within ``reach`` of it."""
    sgn = 1.0 if to >= start else -1.0
    values = to + sgn * reach * np.linspace(0.0, 1.0, 65)
    _, margin, _ = place(plan, values)
    bad = np.flatnonzero(margin < 0)
    if bad.size == 0 or bad[0] == 0:
        return None
    lo, hi = values[bad[0] - 1], values[bad[0]]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if place(plan, [mid])[1][0] >= 0:
            lo = mid
        else:
            hi = mid
    return float(lo)


def map_fixed_points(fmap, d_start: float, d_end: float, limit: float) -> tuple[bool, list]:
    """The fixed points of a module map that can be crystals of a motion of its d_in from
    ``d_start`` to ``d_end``.

    Returns
    -------
    near_identity : bool
        The map lies within ``limit`` of the identity over that travel: every state is fixed
        there (a curvature module), so no state is a crystal of its own.
    fixed : list of FixedPoint
        ``fmap.fixed_points()``, or ``[]`` when ``near_identity``.
    """
    lo_d, hi_d = sorted((float(d_start), float(d_end)))
    grid = np.clip(np.linspace(lo_d, hi_d, 65), *fmap.domain)
    dev = np.abs(fmap(grid) - grid)
    near_identity = bool(np.all(dev <= limit)) and hi_d > lo_d
    return near_identity, ([] if near_identity else fmap.fixed_points())


def end_fixed_point(fixed, end_ports, limit: float):
    """The fixed point D* the first module of a chain ends at, or None.

    It ends at D* when its ports d_in and d_out (``end_ports[:2]``, the first two chain ports at
    the end) both lie within ``limit`` of D*: since d_out = f(d_in), that is a state the map
    keeps, and a chain designed so is designed to end with every module at D*.
    """
    end_ports = np.asarray(end_ports, dtype=np.float64)
    for fp in fixed:
        if end_ports.size >= 2 and np.all(np.abs(end_ports[:2] - fp.value) <= limit):
            return fp
    return None
