"""Did the design happen? Each port's designed end state, and whether the traced motion got there.

Reaching the drive's target is not the same as reaching the design: a chain whose modules must
pass their target and come back, driven from d1, can reach d1's target while every other port
turns back or never leaves its start. So a traced motion is also judged port by port against
the end the design asks for, where that end is known:

- **stated**: the template's ``[motion] ends = { d2 = 1.3, d3 = 1.25 }`` (designed end values
  of ports, in design units);
- **implied**: a chain (ports d1, d2, ...) whose first module ends at a fixed point D* of its
  module map (a crystal, as the tolerance analysis infers it:
  :func:`fabkit.motion.intent.end_fixed_point`) is designed to end with every module at D*
  (the super-stable chain's collapse to D2*): each module's input port d_1 ... d_n at D* (the
  last module's output is a free end that may fold on past D* where the chain locks). A map that is the identity over the travel (a
  curvature module) keeps every state: no end is implied.

Where the motion, continued past the target, locks within the limit of it (the super-stable
chain driven to D2* + 1e-12 locks 1e-12 later with every module at D2*), the ends are judged at
that lock, as the tolerance analysis judges builds: a maker pulls until it stops. A port reached
its end when it lies within the **state tolerance** of it (a quarter of the first module's
travel, never less than the limit, :data:`fabkit.motion.intent.STATE_FRACTION`). A port that
missed is named with what its motion did (it never left its start, it turned back, it ended
elsewhere) and why, read from the trace: the first port that went wrong names the module whose
map stopped it (its output turned back while its input went on: a turning point of that module's
map; or it did not move while its input did), and, when the module's map is at hand, whether its
designed end lies on another branch of that map.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConstructionError, DesignError, FabkitError, KinematicsError, TemplateError
from ..kinematics import place
from ..model.network import chain_port_number, is_chain_port

__all__ = ["PortEnd", "MotionEnds", "judge_ends", "stated_ends"]

@dataclass(frozen=True)
class PortEnd:
    """One port's designed end and where the motion left it.

    Attributes
    ----------
    port : str
    start, end : float
        Its distance at the start and where the motion ends (design units).
    designed : float
        The end the design asks for.
    reached : bool
        ``end`` lies within the state tolerance of ``designed``.
    motion : str
        What it did: ``"reached"``; ``"stayed"`` (never farther from its start than the state
        tolerance); ``"turned back"`` (went out, then came back by more than it); ``"short"``
        (went one way and ended elsewhere).
    extreme : float
        The distance farthest from its start that it reached on the way.
    """

    port: str
    start: float
    end: float
    designed: float
    reached: bool
    motion: str
    extreme: float

    def as_dict(self) -> dict:
        return {"port": self.port, "start": self.start, "end": self.end,
                "designed": self.designed, "reached": self.reached, "motion": self.motion,
                "extreme": self.extreme}


@dataclass(frozen=True)
class MotionEnds:
    """Every designed end of a design's motion, judged.

    Attributes
    ----------
    source : str
        ``"stated"`` (``[motion] ends``) or ``"implied"`` (a chain ending at a crystal).
    basis : str
        How the designed ends were found, in words.
    ports : tuple of PortEnd
    tolerance : float
        The state tolerance (design units).
    judged_at : str
        ``"target"`` or ``"lock"`` (where the motion, continued past the target, locks).
    reason : str
        One sentence naming the ports that missed and why; ``""`` when all were reached.
    """

    source: str
    basis: str
    ports: tuple
    tolerance: float
    judged_at: str
    reason: str = ""
    missed: tuple = field(default=())

    @property
    def reached(self) -> bool:
        return not self.missed

    def as_dict(self) -> dict:
        return {"source": self.source, "basis": self.basis, "tolerance": self.tolerance,
                "judged_at": self.judged_at, "reached": self.reached,
                "missed": list(self.missed), "reason": self.reason,
                "ports": [p.as_dict() for p in self.ports]}


def stated_ends(design) -> dict | None:
    """``[motion] ends`` of a design's template (checked when the template is read), or None."""
    motion = design.raw.get("motion") if isinstance(design.raw, dict) else None
    ends = motion.get("ends") if isinstance(motion, dict) else None
    if not ends:
        return None
    return {str(k): float(v) for k, v in ends.items()}


def _chain_ports(net) -> list[str]:
    return sorted((p for p in net.ports if is_chain_port(p)), key=chain_port_number)


def _ranges(names) -> str:
    """``d2, d3, d4, d7`` → ``d2–d4, d7`` (consecutive chain ports folded)."""
    nums = [chain_port_number(n) for n in names]
    if any(k is None for k in nums):
        return ", ".join(names)
    out, run = [], [nums[0]]
    for k in nums[1:]:
        if k == run[-1] + 1:
            run.append(k)
        else:
            out.append(run)
            run = [k]
    out.append(run)
    return ", ".join(f"d{r[0]}" if len(r) == 1 else f"d{r[0]}, d{r[1]}" if len(r) == 2
                     else f"d{r[0]}–d{r[-1]}" for r in out)


def _modules_of(names) -> str:
    """The modules whose output ports these are (d_{k+1} is the output of module k)."""
    ks = [k - 1 for k in map(chain_port_number, names) if k is not None and k >= 2]
    if not ks:
        return ""
    if len(ks) == 1:
        return f"module {ks[0]}"
    if ks == list(range(ks[0], ks[-1] + 1)):
        return f"modules {ks[0]}–{ks[-1]}"
    return "modules " + ", ".join(str(k) for k in ks)


def _nominal(design, trajectory):
    """(problem, construction plan or None) of the design's motion."""
    from ..kinematics import make_problem
    from .modules import find_plan

    m = design.motion
    problem = make_problem(design.network, m.drive, float(trajectory.drive[-1]), hold=m.hold)
    return problem, find_plan(problem, trajectory)


def judge_ends(design, trajectory) -> MotionEnds | None:
    """The designed end of every port that has one, and whether the motion reached it.

    Parameters
    ----------
    design : Design
    trajectory : Trajectory
        The design's traced motion, every configuration kept (it reached its target).

    Returns
    -------
    MotionEnds or None
        None when the design states no ends and implies none.

    Raises
    ------
    TemplateError
        ``[motion] ends`` names a port the network does not have.
    """
    from .intent import (end_fixed_point, LIMIT_FRACTION, map_fixed_points, nominal_lock,
                         STATE_FRACTION, template_intent)

    net = design.network
    stated = stated_ends(design)
    chain = _chain_ports(net)
    if stated is None and len(chain) < 3:
        return None  # a single module or no chain: nothing implied beyond its target
    unknown = sorted(set(stated or {}) - set(net.ports))
    if unknown:
        raise TemplateError(design.path or design.name, f"motion.ends.{unknown[0]}",
                            f"is not a port of the network; ports: {', '.join(sorted(net.ports))}")
    try:
        problem, plan = _nominal(design, trajectory)
    except FabkitError:
        problem, plan = None, None
    names = list(stated) if stated is not None else chain
    start = {p: trajectory.distance(p) for p in set(names) | set(chain[:2])}
    p0 = np.array([start[p][0] for p in chain[:2]]) if len(chain) >= 2 else np.zeros(0)
    # the limit of the tolerance analysis (a fraction of the first module's size at the end)
    sized = [start[p][-1] for p in chain[:2]] or [float(net.size)]
    limit = LIMIT_FRACTION * float(np.mean(sized))
    to = float(trajectory.drive[-1])
    judged_at, final = "target", {p: float(start[p][-1]) for p in start}
    intent = template_intent(design)
    if plan is not None and problem is not None and intent not in ("target", "shape"):
        lock = nominal_lock(plan, to, float(problem.start_drive), limit)
        if lock is not None:
            x = place(plan, [lock])[0][0]
            judged_at = "lock"
            final = {p: float(np.linalg.norm(x[net.port(p)[0]] - x[net.port(p)[1]]))
                     for p in start}
    p1 = np.array([final[p] for p in chain[:2]]) if len(chain) >= 2 else np.zeros(0)
    travel = abs(float(p1[0] - p0[0])) if p0.size else abs(to - float(trajectory.drive[0]))
    tol = max(STATE_FRACTION * travel, limit)

    if stated is not None:
        source, designed = "stated", stated
        basis = "stated in the template ([motion] ends)"
    else:
        if intent in ("target", "lock", "shape"):
            return None  # the template says what it is for: its port distances or its shape
        fmap = _first_module_map(design, trajectory)
        if fmap is None:
            return None
        near_identity, fixed = map_fixed_points(fmap, float(p0[0]), float(p1[0]), limit)
        crystal = None if near_identity else end_fixed_point(fixed, p1, limit)
        if crystal is None:
            return None
        # a module's state is its input port's distance (its output is the next one's input);
        # the last module's output is a free end, which may fold on past D* where the chain locks
        source, designed = "implied", {p: float(crystal.value) for p in chain[:-1]}
        basis = (f"implied: its first module ends at the fixed point D* = {crystal.value:.6g} "
                 f"({crystal.kind}) of its map, so every module (its input port) is designed to "
                 "end there")
    ports = []
    for p, want in designed.items():
        hist = start[p]
        s, e = float(hist[0]), final[p]
        k = int(np.argmax(np.abs(hist - s)))
        extreme = float(hist[k])
        ok = abs(e - want) <= tol
        if ok:
            how = "reached"
        elif abs(extreme - s) <= tol:  # never farther from its start than a state's reach
            how = "stayed"
        elif abs(e - extreme) > tol:  # went out, then came back by more than that
            how = "turned back"
        else:
            how = "short"
        ports.append(PortEnd(p, s, e, float(want), bool(ok), how, extreme))
    missed = tuple(pe.port for pe in ports if not pe.reached)
    reason = _reason(design, trajectory, ports, start, final, tol) if missed else ""
    return MotionEnds(source, basis, tuple(ports), float(tol), judged_at, reason, missed)


def _first_module_map(design, trajectory):
    """The map of a chain's first module on the branch its motion takes, or None."""
    from ..maps import module_map
    from .modules import chain_modules

    x0, x1 = np.asarray(trajectory.positions[0]), np.asarray(trajectory.final)
    try:
        modules = chain_modules(design, [x0, x1])
    except (ConstructionError, DesignError, KinematicsError, FabkitError):
        return None
    if not modules:
        return None
    try:
        return module_map(modules[0].network, "in", "out")
    except (ConstructionError, DesignError, KinematicsError, FabkitError):
        return None


def _reason(design, trajectory, ports, hist, final, tol) -> str:
    """One sentence: which ports missed their end, what they did, and why (read from the
    trace, and from the map of the module that stopped them when it is at hand)."""
    missed = [pe for pe in ports if not pe.reached]
    groups: dict[str, list] = {}
    for pe in missed:
        groups.setdefault(pe.motion, []).append(pe.port)
    words = {"stayed": "never left their start" if len(groups.get("stayed", [])) > 1
             else "never left its start",
             "turned back": "turned back on the way", "short": "ended away from it"}
    what = "; ".join(f"{_ranges(v)} {words[k]}" for k, v in groups.items())
    mods = _modules_of([pe.port for pe in missed])
    head = (f"{_ranges([pe.port for pe in missed])}"
            + (f" ({mods})" if mods else "") + " did not reach their designed end"
            if len(missed) > 1 else
            f"{missed[0].port}" + (f" ({mods})" if mods else "")
            + " did not reach its designed end")
    why = _cause(design, trajectory, ports, hist, final, tol)
    return f"{head}: {what}" + (f"; {why}" if why else "")


def _cause(design, trajectory, ports, hist, final, tol) -> str:
    """Why the first port of the chain that missed its end did: its input went on while it
    turned back (a turning point of its module's map) or did not move; and whether its
    designed end lies on another branch of that map."""
    first = next((pe for pe in sorted(ports, key=lambda q: _index(q.port)) if not pe.reached),
                 None)
    if first is None or _index(first.port) < 2:
        return ""
    k = _index(first.port)
    up = f"d{k - 1}"
    if up not in design.network.ports:
        return ""
    h_in = trajectory.distance(up)
    h_out = hist.get(first.port)
    if h_out is None:
        h_out = trajectory.distance(first.port)
    module = f"module {k - 1}"
    d_in = np.diff(h_in)
    d_out = np.diff(h_out)
    moving = np.abs(d_in) > 0
    if first.motion == "turned back":
        # the output's direction flips while the input keeps its own: a turning point of the map
        flip = np.flatnonzero(np.sign(d_out[1:]) * np.sign(d_out[:-1]) < 0)
        at = float(h_in[flip[0] + 1]) if flip.size else float(h_in[int(np.argmax(
            np.abs(h_out - h_out[0])))])
        why = (f"{first.port} turned back at {first.extreme:.6g} while {up} went on "
               f"(at {up} = {at:.6g}): a turning point of {module}'s map")
    elif first.motion == "stayed" and moving.any():
        why = (f"{first.port} stayed within {tol:.3g} of its start while {up} went from "
               f"{float(h_in[0]):.6g} to {float(h_in[-1]):.6g}: {module} holds it on the branch "
               "traced")
    else:
        why = (f"{first.port} ended at {first.end:.6g}, {abs(first.end - first.designed):.3g} "
               f"from its designed {first.designed:.6g}")
    branch = _other_branch(design, trajectory, first, up, final, tol)
    return why + (f"; {branch}" if branch else "")


def _other_branch(design, trajectory, first, up, final, tol) -> str:
    """Whether the designed end of ``first`` lies on the branch of its module's map that the
    motion takes: the map where the input ended (as judged) against it."""
    from ..maps import module_map
    from .modules import chain_modules

    try:
        modules = chain_modules(design, [np.asarray(trajectory.positions[0]),
                                         np.asarray(trajectory.final)])
    except FabkitError:
        return ""
    k = _index(first.port) - 2  # d_{k+2} is the output of the (k+1)-th module, modules[k]
    if not modules or k >= len(modules):
        return ""
    try:
        fmap = module_map(modules[k].network, "in", "out")
    except (ConstructionError, DesignError, KinematicsError, FabkitError):
        return ""
    # where the input ended as judged (at the target, or where the motion locks past it)
    want_in = final.get(up, float(trajectory.distance(up)[-1]))
    lo, hi = fmap.domain
    grid = np.linspace(lo, hi, 801)
    values = fmap(grid)
    want = first.designed
    if not float(values.min()) - tol <= want <= float(values.max()) + tol:
        return (f"the map of that module on the branch the motion takes spans {first.port} = "
                f"{float(values.min()):.6g} to {float(values.max()):.6g}: its designed end "
                f"{want:.6g} lies on another branch")
    got = float(fmap(np.clip(want_in, lo, hi)))
    if abs(got - want) <= tol:
        return ""
    cross = np.flatnonzero(np.diff(np.sign(values - want)) != 0)
    need = grid[cross] if cross.size else grid[[int(np.argmin(np.abs(values - want)))]]
    near = float(need[int(np.argmin(np.abs(need - want_in)))])
    return (f"on the branch the motion takes, {up} = {want_in:.6g} gives {first.port} = "
            f"{got:.6g}; its designed {want:.6g} needs {up} near {near:.6g}")


def _index(port: str) -> int:
    k = chain_port_number(port)
    return 10**9 if k is None else k
