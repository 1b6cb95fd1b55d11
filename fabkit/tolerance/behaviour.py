"""What a design is for: the behaviour a build must keep, inferred from its map and its motion.

A design's nominal motion and its module map (:mod:`fabkit.tolerance.modules`) say what it does
(the intent, the state tolerance and the fixed points are read in :mod:`fabkit.motion.intent`,
which the motion stage shares):

- **crystal states**: the motion starts (every module) or ends (the first module) at fixed points
  of the module map, D* with f(D*) = D*;
- **end state**: where the motion ends. The target, unless the motion, continued past it, locks
  within the limit of it (a turning point: the maker pulls until it stops), then that lock. A
  module that ends at a crystal, or a chain whose front ends where its first module locks, ends
  in a *state* of its modules; a chain whose module map is the identity over the motion (d1 = d2
  throughout: curvature designs) ends in a *shape*; anything else ends at the *port distances*
  of that end, today's measure; a network without module maps (traced build by build) whose
  driven port switches between two states ends in that *switch*, with what it keeps still;
- **order**: in a chain, the modules' progress from start to end is monotone along the chain at
  every instant of the motion (a front runs left to right, or right to left), one front;
- **chaos**: the module map has a positive Lyapunov exponent, so errors grow as e^{λk} along the
  chain and a far-end port distance is unpredictable past the predictability horizon.

Where inference cannot know, the template says it: ``[motion] intent`` = ``"auto"`` (default),
``"target"`` (the port distances at the target are what the design is for), ``"lock"`` (those
at the end of the motion, where it locks), ``"state"`` (the state its modules end in) or
``"shape"`` (the final shape).

Tolerances: a crystal or an end state is kept within the **state tolerance**,
``state_fraction`` (0.25) of the first module's travel between its start and end values and
never less than the limit: a built state is the designed one when it lies nearer to it than
to the middle of the transition, by a factor of two (a state that merely moves by a fabrication
error is still that state; one that vanishes, or moves farther, is not). Port distances are
kept within the **limit** (a fraction of the module size, what shows by eye), a shape within
that fraction of the shape's own size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConstructionError, DesignError, FabkitError, KinematicsError
from ..kinematics import place
from ..maps import module_map
from ..motion.intent import end_fixed_point, map_fixed_points, nominal_lock, template_intent
from ..motion.modules import chain_modules
from .folds import fold_states, FoldStates
from ..model.network import is_chain_port

__all__ = ["Behaviour", "Crystal", "infer_behaviour"]

#: The nominal profile counts as monotone along the chain when no module is ahead of its left
#: neighbour by more than this fraction of the travel (round-off of the exact placement).
MONOTONE_SLACK = 1e-6

#: A front exists when at some instant the modules' progress spans at least this fraction.
FRONT_SPAN = 0.5

#: Positive Lyapunov exponents below this (per module) are not chaos (round-off, neutral maps).
CHAOS_LYAPUNOV = 0.05

#: Drive values sampled along the nominal motion to read its order, evenly, then geometrically
#: towards the end (the front of a soliton crosses a module per factor of its slope).
ORDER_SAMPLES = 41
ORDER_GEOMETRIC = 30


@dataclass(frozen=True)
class Crystal:
    """A designed crystal state: a fixed point D* of the module map that the motion visits.

    Attributes
    ----------
    value : float
        D* (design units).
    slope : float
        f'(D*) of the design (infinite at a turning point).
    kind : str
        Its class (:func:`fabkit.maps.classify_slope`).
    role : str
        ``"start"`` (every module starts there) or ``"end"`` (the first module ends there).
    at_turning : bool
        D* lies at the end of its branch (a flat state): a build keeps it where it locks.
    branch_end : float or None
        The end of D*'s branch when it lies within the state tolerance of D* (a built fixed
        point may sit between the last sampled value and that end).
    """

    value: float
    slope: float
    kind: str
    role: str
    at_turning: bool
    branch_end: float | None = None

    @property
    def side(self) -> int:
        """-1 attracting (|f'| < 1), +1 repelling (|f'| > 1), 0 neutral: what a build keeps."""
        if self.kind == "neutral":
            return 0
        return -1 if abs(self.slope) < 1.0 else 1

    def as_dict(self) -> dict:
        return {"value": self.value, "slope": self.slope, "kind": self.kind, "role": self.role,
                "at_turning_point": self.at_turning, "branch_end": self.branch_end}


@dataclass(frozen=True, eq=False)
class Behaviour:
    """What a design is for (see the module docstring).

    Attributes
    ----------
    intent : str
        The template's ``[motion] intent`` (``"auto"`` when not given).
    end : str
        ``"state"``, ``"ports"``, ``"shape"`` or ``"switch"`` (the driven port's end state and
        the ports kept still, of builds traced one by one): what is judged at the end.
    end_at : str
        ``"target"`` or ``"lock"``: where the motion ends.
    end_drive : float
        Drive value at the end (design units).
    start_drive : float
    module_start, module_end : float
        The first module's d_in at the start and at the end (design units).
    crystals : tuple of Crystal
    end_lock : tuple of float or None
        (T, f(T)): the first module's turning point and its output there, when a chain ends
        where its first module locks.
    order : int
        +1: the front runs from d1 along the chain; -1: from the far end; 0: not sequential.
    travel : float
        |d1 at the start - d1 at the end| (design units).
    state_tol : float
        The state tolerance (design units).
    limit_mm, shape_limit_mm : float
    transit : tuple or None
        (lo, hi, sign, rise): the d_in interval every module crosses between its states, the
        designed sign of f(d) - d on it and of f' (0: both signs).
    chaos : dict or None
        ``lyapunov`` (per module), ``modules`` (chain length) when the module map is chaotic.
    modules : list of Module or None
    notes : list of str
        One sentence per inference.
    folds : FoldStates or None
        An origami design's designed states by their fold angles: its states (crystals, the
        end state) are then judged by the built sheet's folds (:mod:`fabkit.tolerance.folds`),
        the state tolerance only bounding where they are looked for.
    """

    intent: str
    end: str
    end_at: str
    end_drive: float
    start_drive: float
    module_start: float
    module_end: float
    crystals: tuple
    end_lock: tuple | None
    order: int
    travel: float
    state_tol: float
    limit_mm: float
    shape_limit_mm: float
    transit: tuple | None
    chaos: dict | None
    modules: list | None
    scale: float
    end_config: np.ndarray = field(repr=False, default=None)
    end_ports: np.ndarray = field(repr=False, default=None)
    notes: list = field(default_factory=list)
    folds: FoldStates | None = None

    @property
    def criteria(self) -> list[str]:
        """The criteria a build is judged by, in report order."""
        out = []
        if any(c.role == "start" for c in self.crystals):
            out.append("crystals")
        if self.order:
            out.append("order")
        if self.end == "switch":
            return out + ["driven state", "still ports"]
        out.append({"state": "end state", "ports": "end ports", "shape": "end shape"}[self.end])
        return out

    def as_dict(self) -> dict:
        return {
            "intent": self.intent, "criteria": self.criteria, "end": self.end,
            "end_at": self.end_at, "end_drive": self.end_drive,
            "crystals": [c.as_dict() for c in self.crystals],
            "end_lock": None if self.end_lock is None else list(self.end_lock),
            "order": {1: "left to right", -1: "right to left", 0: None}[self.order],
            "travel": self.travel, "state_tolerance_mm": self.state_tol * self.scale,
            "limit_mm": self.limit_mm, "shape_limit_mm": self.shape_limit_mm,
            "chaos": self.chaos, "modules": 0 if self.modules is None else len(self.modules),
            "notes": list(self.notes),
            "folds": None if self.folds is None else self.folds.as_dict(),
        }


def _ports(x, pairs) -> np.ndarray:
    return np.linalg.norm(x[..., pairs[:, 0], :] - x[..., pairs[:, 1], :], axis=-1)


def _order(plan, chain_pairs, start, end, d_start, d_end) -> tuple[int, float]:
    """Direction of the nominal front (+1, -1, 0) and the largest span of the profile."""
    q = np.concatenate([np.linspace(start, end, ORDER_SAMPLES),
                        end + (start - end) * 0.5 ** np.arange(1, ORDER_GEOMETRIC + 1)])
    x, margin, _ = place(plan, q)
    x = x[margin >= 0]
    if x.shape[0] == 0 or abs(d_end - d_start) == 0:
        return 0, 0.0
    # progress from the start state (0) to the end state (1); a module past its end state (the
    # free end of a chain folding on to its lock) is done
    p = np.clip((_ports(x, chain_pairs) - d_start) / (d_end - d_start), 0.0, 1.0)
    span = float(np.max(p.max(axis=1) - p.min(axis=1)))
    steps = np.diff(p, axis=1)
    if span < FRONT_SPAN:
        return 0, span
    if np.all(steps <= MONOTONE_SLACK):
        return 1, span
    if np.all(steps >= -MONOTONE_SLACK):
        return -1, span
    return 0, span


def _chaos(fmap, to: float, n: int) -> dict | None:
    """λ of the module map from a bundle of orbits started next to the target, if chaotic."""
    try:
        lyap = fmap.lyapunov(initial=np.clip(to * (1.0 + 1e-3 * np.linspace(-1.0, 1.0, 64)),
                                             *fmap.domain),
                             discard=50, average=350, method="exact")
        lam = float(lyap.mean)
    except (ConstructionError, DesignError, KinematicsError, ValueError):
        return None
    if not math.isfinite(lam) or lam <= CHAOS_LYAPUNOV:
        return None
    return {"lyapunov": lam, "modules": n}


def infer_behaviour(design, spec, trajectory, problem, plan, ports, pairs,
                    limit_mm: float) -> Behaviour:
    """The behaviour a build must keep (see the module docstring).

    Parameters
    ----------
    design : Design
    spec : ToleranceSpec
    trajectory : Trajectory
        The nominal motion.
    problem : Problem
    plan : ConstructionPlan or None
        None when the design has no construction order (builds are traced one by one).
    ports : list of str
    pairs : numpy.ndarray of int, shape (P, 2)
    limit_mm : float

    Returns
    -------
    Behaviour

    Raises
    ------
    TemplateError
        An unknown ``[motion] intent``.
    """
    intent = template_intent(design)
    scale = spec.scale
    limit = limit_mm / scale
    to = float(design.motion.to)
    start = float(problem.start_drive)
    notes = []
    x_start = np.asarray(problem.start)
    end_at, end_drive = "target", to
    lock = None
    if plan is not None and intent != "target":
        lock = nominal_lock(plan, to, start, limit)
        if lock is not None and intent != "target":
            end_at, end_drive = "lock", lock
            notes.append(f"the motion locks {abs(lock - to) * scale:.3g} mm past the target "
                         "(within the limit): its end is that lock, where a maker's pull stops")
    if intent == "lock" and end_at != "lock":
        notes.append("intent = lock, but the motion does not lock within the limit of the "
                     "target: judged at the target")
    if plan is not None:
        x_end = place(plan, [end_drive])[0][0]
    else:
        x_end = np.asarray(trajectory.final)
    end_ports = _ports(x_end, pairs)
    chain_idx = [k for k, p in enumerate(ports) if is_chain_port(p)]
    chain_pairs = pairs[chain_idx]
    p0 = _ports(x_start, chain_pairs)
    p1 = _ports(x_end, chain_pairs)
    modules = chain_modules(design, [x_start, x_end]) if plan is not None else None
    n = 0 if modules is None else len(modules)
    travel = abs(float(p1[0] - p0[0])) if p0.size else abs(end_drive - start)
    state_tol = max(spec.state_fraction * travel, limit)
    size = float(np.linalg.norm(np.ptp(x_end, axis=0))) * scale
    shape_limit = spec.limit if spec.limit is not None else spec.limit_fraction * size

    crystals, end_lock, transit, chaos = [], None, None, None
    order, near_identity, fmap = 0, False, None
    if modules:
        first = modules[0]
        try:
            fmap = module_map(first.network, "in", "out")
        except (ConstructionError, DesignError, KinematicsError):
            fmap = None
        if fmap is not None:
            near_identity, fixed = map_fixed_points(fmap, float(p0[0]), float(p1[0]), limit)

            def crystal(fp, role):
                ends = [e for e in fmap.domain if abs(e - fp.value) <= state_tol]
                turning = bool(fp.at_end)  # the map's rule: within a stated tolerance of it
                near = min(ends, key=lambda e: abs(e - fp.value)) if ends else None
                return Crystal(fp.value, fp.slope, fp.kind, role, turning,
                               None if near is None else float(near))

            for fp in fixed:
                if np.all(np.abs(p0 - fp.value) <= limit):
                    crystals.append(crystal(fp, "start"))
            ending = end_fixed_point(fixed, p1, limit)
            if ending is not None:
                crystals.append(crystal(ending, "end"))
            if n >= 2 and plan is not None:
                # progress runs from the start state to the end state (the end crystal when
                # there is one: a free end that folds on past it counts as done)
                ends = [c.value for c in crystals if c.role == "end"]
                order, _ = _order(plan, chain_pairs, start, end_drive, float(p0[0]),
                                  ends[0] if ends else float(p1[0]))
            has_end = any(c.role == "end" for c in crystals)
            if not has_end and (order or n == 1):
                for t in fmap.domain:
                    if abs(float(p1[0]) - t) <= limit:
                        end_lock = (float(t), float(fmap(t)))
            starts = [c for c in crystals if c.role == "start"]
            ends = [c.value for c in crystals if c.role == "end"] + \
                ([end_lock[0]] if end_lock else [])
            if starts and ends:
                a, b = starts[0].value, ends[0]
                sgn = 1.0 if b > a else -1.0
                lo_t, hi_t = sorted((a + sgn * state_tol, b - sgn * state_tol))
                if hi_t > lo_t:
                    q = np.linspace(lo_t, hi_t, 33)
                    qc = np.clip(q, *fmap.domain)
                    g = fmap(qc) - q
                    slope = fmap.derivative(qc)
                    rise = 1 if np.all(slope > 0) else -1 if np.all(slope < 0) else 0
                    if np.all(g > 0) or np.all(g < 0):
                        transit = (float(lo_t), float(hi_t), float(np.sign(g[0])), rise)

    if intent in ("target", "lock"):
        end = "ports"
    elif intent == "shape":
        end = "shape"
    elif intent == "state":
        end = "state" if (any(c.role == "end" for c in crystals) or end_lock) else "ports"
        if end == "ports":
            notes.append("intent = state, but no module ends at a crystal or a lock: judged "
                         "by its port distances")
    elif near_identity and n >= 2:
        end = "shape"
    elif any(c.role == "end" for c in crystals) or end_lock:
        end = "state"
    else:
        end = "ports"
    if end == "ports" and plan is None and intent in ("auto", "state"):
        # builds traced one by one have no module maps: a motion that switches its driven
        # port between two states (the AND gate's branch collapsing) is judged by that switch
        # and by what it keeps still, not by port distances at a target tuned to round-off
        drive = tuple(sorted(design.network.port(design.motion.drive)))
        rows = [tuple(sorted(map(int, p))) for p in pairs]
        if drive in rows:
            k = rows.index(drive)
            moved = abs(float(end_ports[k]) - float(_ports(x_start, pairs[k:k + 1])[0]))
            if moved > limit:
                end = "switch"
                notes = [t for t in notes if not t.startswith("intent = state")]
                travel = moved
                state_tol = max(spec.state_fraction * moved, limit)
    if order and (not transit or not transit[3]):
        order = 0  # a front without states to run between: judged by its end alone
    if end == "ports" and n >= 2 and fmap is not None:
        chaos = _chaos(fmap, to, n)
    if end == "shape" and end_at == "lock":
        # a shape is designed at the target (all modules at D2*), not where a module locks
        end_at, end_drive = "target", to
        x_end = place(plan, [to])[0][0]
        end_ports = _ports(x_end, pairs)
        notes = [t for t in notes if not t.startswith("the motion locks")]
    folds = None
    if end == "state" or any(c.role == "start" for c in crystals):
        try:
            folds = fold_states(design, spec, modules, x_start, x_end)
        except FabkitError as e:  # said, not hidden: the states fall back to port distance
            notes.append(f"the sheets' faces could not be read ({e}): its states are judged "
                         "by port distance, not by their folds")
    return Behaviour(intent=intent, end=end, end_at=end_at, end_drive=float(end_drive),
                     start_drive=start, module_start=float(p0[0]) if p0.size else start,
                     module_end=float(p1[0]) if p1.size else float(end_drive),
                     crystals=tuple(crystals), end_lock=end_lock,
                     order=order, travel=travel, state_tol=state_tol, limit_mm=limit_mm,
                     shape_limit_mm=float(shape_limit), transit=transit, chaos=chaos,
                     modules=modules, scale=scale, end_config=x_end, end_ports=end_ports,
                     notes=notes, folds=folds)
