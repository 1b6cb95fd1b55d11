"""How an origami design's motion is traced for its fold: two tracing methods
(:class:`~fabkit.kinematics.base.Method` subclasses) that the origami plan asks the Motion stage
for (:func:`fabkit.fab.creases.plan.trace_needs`), so that the design's one trace is its fold.

* :class:`SheetFold`: a sheet that starts flat (a bifurcation) leaves it on the branch its
  mountain/valley assignment names (or the branch and sign its settings name), then is traced
  with ``samples`` configurations (:func:`~fabkit.kinematics.branching.fold_through`).
* :class:`ChainFold`: a chain of sheets that starts folded (a regular start) is placed
  constructively at ``samples`` drive values, spaced evenly or geometrically towards the target
  (``spacing``), handing the drive to the far end (``relay``) once it moves, so that the end of
  a motion that speeds up towards it is resolved; every configuration in the frame of the first
  face (the trace's ``gauge``).

Each trajectory says in ``stats["origami_fold"]`` what it was traced for (:func:`fold_key`): the
fold takes a trajectory whose key is its own and traces only when it is given none.
"""

from __future__ import annotations

import numpy as np

from ...errors import FabricationError
from ...kinematics import place, plan_construction
from ...kinematics.base import align_to_gauge, Mark, Method, Solved
from ...kinematics.branching import fold_through
from ...status import Status
from ...numerics import TINY
from .pattern import assignment_score, fold_angles

__all__ = ["SheetFold", "ChainFold", "fold_key", "GEOMETRIC_END", "RELAY_END", "RELAY_SWITCH"]

#: Geometric spacing runs from the start to this fraction of the way left to the target (the
#: last frames resolve the approach to a flat or folded state).
GEOMETRIC_END = 1e-12
#: The relay's share of its way is spaced in logit up to this fraction short of the target.
RELAY_END = 1e-6
#: The relay port takes over the drive once it has moved by this fraction of its way.
RELAY_SWITCH = 1e-6

#: The key of a trajectory's ``stats`` that says which fold it was traced for.
KEY = "origami_fold"


def fold_key(method: type, options: dict) -> tuple:
    """What a trace for a fold is traced for: the method and its options, comparable (two
    traces with one key are the same trace)."""
    out = []
    for name in sorted(options):
        v = options[name]
        if name == "pattern" and v is not None:  # (assignment, edges, faces)
            v = (tuple(v[0]), tuple(map(tuple, np.asarray(v[1]).tolist())),
                 tuple(tuple(map(int, f)) for f in v[2]))
        out.append((name, v))
    return (method.name, tuple(out))


class SheetFold(Method):
    """A flat sheet folded out of its flat state on the branch its assignment names.

    Options
    -------
    samples : int
        Configurations of the fold, the flat start included.
    branch, sign : int or None
        The branch (1-based) and direction named by the settings; None: chosen by ``pattern``.
    step_off : float
        Step off the flat state, relative to the median edge length.
    pattern : (assignment, edges, faces) or None
        The crease assignment whose fold angles choose the branch (when ``branch`` is None).
    """

    name = "origami-sheet"
    options = {"samples": 41, "branch": None, "sign": None, "step_off": 1e-3, "pattern": None}

    def solve(self) -> Solved:
        p, o = self.problem, self.opts
        score = None
        if o["branch"] is None and o["pattern"] is not None:
            assignment, edges, faces = o["pattern"]

            def score(x):
                return assignment_score(assignment, fold_angles(edges, faces, x))

        traj = fold_through(p.network, p.drive_name, p.target, branch=o["branch"],
                            sign=o["sign"], score=score, step_off_size=float(o["step_off"]),
                            method="auto", samples=int(o["samples"]) - 1)
        stats = {**traj.stats, KEY: fold_key(type(self), dict(o))}
        marks = tuple(Mark(e.kind, e.index, e.detail) for e in traj.events)
        return Solved(traj.positions, traj.status, traj.message, marks, stats, traj.arclength,
                       aligned=True, method=traj.method)


class ChainFold(Method):
    """A chain of sheets placed from a regular start (see the module docstring).

    Options
    -------
    samples : int
    spacing : "uniform" or "geometric"
    relay : str or None
        The port that takes over the drive once it moves.
    name : str
        The design, for the messages.

    Every configuration is aligned to the trace's gauge (:func:`fabkit.trace`'s ``gauge``:
    the fold asks for its first face's corners).
    """

    name = "origami-chain"
    options = {"samples": 41, "spacing": "uniform", "relay": None, "name": "the chain"}

    def solve(self) -> Solved:
        p, o = self.problem, self.opts
        net, drive, to = p.network, p.drive_name, float(p.target)
        samples = int(o["samples"])
        plan = plan_construction(net, net.port(drive))
        d0 = float(net.port_distance(drive))
        if o["spacing"] == "geometric":
            frac = 1.0 - np.geomspace(1.0, GEOMETRIC_END, samples)
            frac[0] = 0.0
        else:
            frac = np.linspace(0.0, 1.0, samples)
        values = d0 + frac * (to - d0)
        pos, margin, _ = place(plan, values)
        if (margin[1:] < 0).any():
            k = int(np.argmax(margin[1:] < 0)) + 1
            raise FabricationError(f"{o['name']}: the motion ends before {drive} = "
                                   f"{values[k]:.10g}")
        method, message = "constructive", f"reached {drive} = {to:.10g}"
        relay = o["relay"]
        if relay is not None:
            pos, message = _relay(net, o["name"], pos, relay, to, samples)
            method = f"constructive ({drive}, then {relay})"
        gauge = tuple(int(i) for i in p.gauge)
        pos = align_to_gauge(pos, net.nodes, gauge)
        stats = {"samples": int(pos.shape[0]), KEY: fold_key(type(self), {**o, "gauge": gauge})}
        return Solved(pos, Status.FINISHED, message, (), stats, aligned=True, method=method)


def _relay(net, name: str, pos, relay: str, to: float, samples: int):
    """Hand the drive over to another port part way (see ``relay`` in the docs).

    Driving one end of a chain whose map contracts towards that end resolves the start of the
    motion but not its end: the far end's distance is then the drive's error times the map's
    slope to the power k. Once the relay port (the far end) has moved by ``RELAY_SWITCH`` of its
    way, the remaining frames are placed from the relay port instead, where the map contracts
    the other way and the end of the motion is resolved to round-off.
    """
    if relay not in net.ports:
        raise FabricationError(f"{name}: fabrication.origami.relay: unknown port {relay!r}")
    r = net.port_distance(relay, pos)
    moved = np.abs(r - r[0]) / max(abs(to - r[0]), TINY)
    hits = np.flatnonzero(moved >= RELAY_SWITCH)
    if hits.size == 0 or hits[0] >= samples - 1:
        return pos, f"reached {relay} = {r[-1]:.10g} without handing over"
    k = int(hits[0])
    plan = plan_construction(net, net.port(relay), pos[k])
    # the relay's share of its way, spaced evenly in logit from the handover to 1 - 1e-6 (small
    # first steps resolve the front leaving the middle), then the target itself
    start = min(float(moved[k]), 0.5)
    t = np.linspace(np.log(start / (1.0 - start)), np.log((1.0 - RELAY_END) / RELAY_END),
                    samples - k - 1)
    values = np.append(r[0] + (to - r[0]) / (1.0 + np.exp(-t[1:])), to)
    more, margin, _ = place(plan, values)
    if (margin < 0).any():
        raise FabricationError(f"{name}: the relay port {relay} cannot reach {to:.10g}")
    # the relay's frames are in its own seed frame; the caller aligns every frame to the gauge
    out = np.concatenate([pos[: k + 1], more], axis=0)
    return out, f"handed the drive to {relay} at frame {k}; reached {relay} = {values[-1]:.10g}"
