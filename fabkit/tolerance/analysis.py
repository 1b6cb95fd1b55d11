"""The Monte Carlo of built copies of a design, judged against what the design is for, and its
margin."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace

import numpy as np

from ..errors import FabkitError, KinematicsError, TemplateError
from ..io.workload import require
from ..kinematics import make_problem, place, trace
from ..status import Status
from ..kinematics.trajectory import EventKind
from ..model.network import is_chain_port, Network
from ..numerics import EDGE_RTOL, printed, project_to_lengths, TINY
from ..builds.assembly import SETTLE_RTOL
from ..builds.closure import COMPATIBLE_RTOL, play_ratio, self_stress_basis
from .assembled import Assemblies, assemble_builds, MODEL_NAMES, slop_summary
from .behaviour import infer_behaviour
from .criteria import (judge_modules, judge_port_states, judge_ports, judge_shape, Judged,
                       profile_order)
from .horizon import lyapunov_estimate, MIN_MAP_STEPS, NEUTRAL_LYAPUNOV
from .margin import (critical_scales, CURVE_SCALES, keep_curve, margin_of, margin_text,
                     SCALE_BISECTIONS)
from .modules import ModuleMaps
from ..motion.modules import find_plan
from .placement import (BUILD_RTOL, chain_ports, Driver, process_geometry,
                        PROJECTED_SAMPLES_CAP, to_drive_frame)
from .pins import pin_play
from .play_choices import redundant_choices
from .processes import nominal_room_mm, sample_builds, spec_sources
from .result import ToleranceResult
from .spec import tolerance_spec, ToleranceSpec

__all__ = ["analyse_tolerance"]

#: A build's loops run out of play where its play ratio passes 1 (or its start's, for a build
#: forced together) by more than this (round-off of the ratio along a traced motion, whose other
#: bars keep their lengths to the tracer's tolerance).
PLAY_RTOL = 1e-6

#: A build's trace stops where its play ratio passes the limit of :data:`PLAY_RTOL` by this
#: much more (relative): the ratio of a configuration as the tracer holds it and as the trace
#: returns it (moved rigidly into the caller's gauge) differ by round-off, and the trace must
#: reach the configuration where the returned one runs out.
PLAY_WATCH_MARGIN = 1e-9

#: Coordinates of the build traces an analysis keeps for builds that go together alike (80 MB;
#: the AND gate's 188 traces hold 2e6).
MEMO_FLOATS = 10_000_000

#: Builds per error source in the chart's curves (the first ones of the sample, same draws):
#: the curves show where each source starts to matter; the margin itself uses every build.
SOURCE_SAMPLES = 32

#: Bisection steps of each source's curve: within a factor 10^(1/16) = 1.15 of the scale.
SOURCE_BISECTIONS = 3

#: Builds per error source when each build is traced on its own (no construction order).
PROJECTED_SOURCE_SAMPLES = 6

#: A choice of the bars that take up a build's play that moves its still ports by no more than
#: this fraction of the network's size leaves them as still as round-off lets a traced build be
#: (the tracer holds lengths to ~1e-10): no other choice can be judged stiller, so the build's
#: remaining choices are not traced (the AND gate: 64 of 104 builds still at the first choice).
UNDISTURBED_RTOL = 1e-12

#: Extra drive values past a lock, in limits: a build may lock a little later than the design.
LOCK_OVERSHOOT = (0.25, 0.5, 1.0, 2.0)

#: Geometric samples towards each build's own end (the observed order of a soliton, whose front
#: crosses a module per factor of the end crystal's slope).
OBSERVE_GEOMETRIC = 30


@dataclass
class _Run:
    """One Monte Carlo run: which builds keep the behaviour, judged how, and how they went
    together (None where the network has no state of self-stress or the process no play)."""

    keep: np.ndarray
    judged: dict
    driven: object = None
    assembly: Assemblies | None = None


class _Constructive:
    """Runs of builds placed by intersections (the design has a construction order)."""

    def __init__(self, design, spec, behaviour, plan, problem, pairs, geo, grid, limit_mm,
                 clearance_mm):
        self.spec, self.behaviour, self.geo = spec, behaviour, geo
        self.limit_mm = limit_mm
        b = behaviour
        self.maps = ModuleMaps(b.modules, geo, spec.process) if b.modules else None
        start, end = b.start_drive, b.end_drive
        self.driver = Driver(plan, problem, design.network, pairs, geo, spec.process,
                             (start, end))
        values = np.linspace(start, end, grid)
        if b.end_at == "lock":
            sgn = 1.0 if end >= start else -1.0
            over = end + sgn * (limit_mm / spec.scale) * np.asarray(LOCK_OVERSHOOT)
            values = np.concatenate([values, over])
        self.values = values
        self.clearance = clearance_mm / spec.scale

    def builds(self, gains, rows, sources):
        g = np.ones(self.spec.samples)
        g[rows] = gains
        return sample_builds(self.geo, self.spec, np.random.default_rng(self.spec.seed),
                             sources, gain=g).select(rows)

    def __call__(self, gains, rows, sources=None, observe=False) -> _Run:
        b = self.behaviour
        builds = self.builds(gains, rows, sources)
        judged = judge_modules(b, self.maps, builds) if self.maps is not None else {}
        driven = None
        if b.end != "state" or observe:
            driven = self.driver.drive(builds, self.values, self.clearance)
            if b.end == "ports":
                judged["end ports"] = judge_ports(b, driven, self.limit_mm)
            elif b.end == "shape":
                judged["end shape"] = judge_shape(b, driven)
        keep = np.ones(len(rows), dtype=bool)
        for j in judged.values():
            keep &= j.ok
        return _Run(keep, judged, driven)

    def observe_order(self, run: _Run, rows, chain_cols) -> dict | None:
        """The order seen along the driven motion: every build driven again geometrically
        towards its own end, the profile read at every instant."""
        b = self.behaviour
        if not b.order or run.driven is None:
            return None
        builds = self.builds(np.ones(len(rows)), rows, None)
        stop = run.driven.stop
        start = b.start_drive
        geo = stop[:, None] + (start - stop[:, None]) * 0.5 ** np.arange(1, OBSERVE_GEOMETRIC + 1)
        again = self.driver.drive(builds, geo[:, ::-1], self.clearance)
        sampled = np.concatenate([run.driven.sampled, again.sampled], axis=1)
        lead = profile_order(b, sampled, chain_cols)
        return {"monotone_fraction": float(np.mean(lead <= self.spec.state_fraction)),
                "worst_lead": float(np.max(lead)), "samples": int(sampled.shape[1])}


#: A chain's port name: ``d`` and the module number, then the chain's suffix (``_b``) if any.
_CHAIN_PORT = re.compile(r"d(\d+)(_\w+)?")


class _Projected:
    """Runs of builds realised one by one (Gauss-Newton) and traced by projected continuation.

    A motion that switches its driven port between two states (the AND gate's branch
    collapsing) is judged by ``driven state`` and ``still ports``; any other by ``end ports``.
    """

    def __init__(self, design, spec, behaviour, geo, ports, pairs, limit_mm):
        self.design, self.spec, self.behaviour, self.geo = design, spec, behaviour, geo
        self.pairs, self.limit_mm = pairs, limit_mm
        self.free = _same_chain(ports, design.motion.drive)
        net = design.network
        self.nominal_start = _port_lengths(net.nodes, pairs)
        # a kit with play: its builds are traced without the edges the design's states of
        # self-stress make redundant, and the loops' play is watched along the motion instead
        # (every choice of those edges the stresses leave open: see _least_disturbed)
        self.stresses = self_stress_basis(net, net.nodes)
        self.loop_free: list[np.ndarray] = []
        for left_out in (redundant_choices(self.stresses) if self.stresses.shape[1] else []):
            keep = np.ones(net.n_edges, dtype=bool)
            keep[left_out] = False
            self.loop_free.append(net.edges[keep])
        self.states = behaviour.end == "switch"
        # traces kept for builds that go together alike (see _traced)
        self._memo: dict = {}
        self._memo_floats = 0
        if self.states:
            drive = tuple(sorted(net.port(design.motion.drive)))
            self.driven = [tuple(sorted(map(int, p))) for p in pairs].index(drive)

    def __call__(self, gains, rows, sources=None, observe=False) -> _Run:
        g = np.ones(self.spec.samples)
        g[rows] = gains
        net, m = self.design.network, self.design.motion
        builds = sample_builds(self.geo, self.spec, np.random.default_rng(self.spec.seed),
                               sources, gain=g).select(rows)
        assembly = None
        if builds.room is not None:
            # a kit of parts: each build put together with its play, forced where it must be
            # a run that is only asked which builds keep the behaviour (the margin's) lets them
            # settle sooner once they close: where exactly within their play is not reported
            assembly = assemble_builds(net, builds, self.spec, net.nodes, self.geo.play_ends,
                                       settle=None if observe else SETTLE_RTOL)
            starts = [assembly.positions[s] if assembly.buildable[s] else None
                      for s in range(len(rows))]
        else:
            starts = []
            for s in range(len(rows)):
                proj = project_to_lengths(net.edges, builds.base[s], net.nodes, rtol=BUILD_RTOL,
                                          max_iter=30)
                starts.append(proj.positions if proj.converged else None)
        dist = np.full((len(rows), self.pairs.shape[0]), np.nan)
        began = np.full_like(dist, np.nan)
        jammed, locked_count, why = 0, 0, ""
        for s, x in enumerate(starts):
            if x is None:
                continue
            outcome = self._least_disturbed(net, m, x, builds, s)
            if isinstance(outcome, str):
                jammed += 1
                why = why or outcome
            elif outcome is not None:
                final, locked = outcome
                locked_count += int(locked)
                began[s] = _port_lengths(x, self.pairs)
                dist[s] = _port_lengths(final, self.pairs)
        detail = {"assembled": int(sum(x is not None for x in starts)),
                  "moved": int(np.isfinite(dist).all(axis=1).sum()), "locked": locked_count,
                  "jammed": jammed, "jam_reason": why}
        driven = _Traced(dist)
        if self.states:
            state, still = judge_port_states(began, dist, self.nominal_start,
                                             self.behaviour.end_ports, self.driven, self.free,
                                             self.spec.scale, self.limit_mm,
                                             self.behaviour.state_tol * self.spec.scale)
            state.detail.update(detail)
            state.detail["front"] = _front_sentence(state.detail)
            still.detail.update(detail)
            judged = {"driven state": state, "still ports": still}
            return _Run(state.ok & still.ok, judged, driven, assembly)
        err = np.abs(dist - self.behaviour.end_ports[None]) * self.spec.scale
        worst = np.nan_to_num(err, nan=np.inf).max(axis=1)
        j = Judged("end ports", worst <= self.limit_mm, worst, self.limit_mm, detail,
                   per_part=err)
        return _Run(j.ok, {"end ports": j}, driven, assembly)

    def _least_disturbed(self, net, m, x, builds, s):
        """Where build ``s`` (assembled at ``x``) ends: ``(final nodes, locked)``, a jam's reason,
        or None when no trace could be made.

        A build with play is traced once per choice of the bars that take up its loops' play
        (:func:`redundant_choices`): a real build has play in all of them, and nothing pushes
        its still parts, so it moves the way that disturbs them least: it is judged by the
        choice that moves its still ports least (or, for ``end ports``, ends nearest the
        design), and it jams only if it jams under every one. A choice that leaves the still
        ports still (to :data:`UNDISTURBED_RTOL`) ends the search: none can do better."""
        played = builds.room is not None and bool(self.loop_free)
        best, best_score, jam = None, np.inf, None
        still = UNDISTURBED_RTOL * float(net.size) if self.states else -np.inf
        for edges in (self.loop_free if played else [None]):
            got = self._trace_build(net, m, x, builds, s, edges)
            if isinstance(got, str):
                jam = jam or got
                continue
            if got is None:
                continue
            score = self._disturbance(x, got[0])
            if score < best_score:
                best, best_score = got, score
            if best_score <= still:
                break
        return best if best is not None else jam

    def _disturbance(self, x, final) -> float:
        """How far a traced build strays from the design: its still ports' largest motion, or
        its ports' largest distance from their designed end."""
        dist = _port_lengths(final, self.pairs)
        if self.states:
            still = ~np.asarray(self.free, dtype=bool)
            still[self.driven] = False
            moved = np.abs(dist - _port_lengths(x, self.pairs))[still]
            return float(moved.max()) if moved.size else 0.0
        return float(np.max(np.abs(dist - self.behaviour.end_ports)))

    def _trace_build(self, net, m, x, builds, s, edges):
        """One build traced without ``edges``' complement (its loops' play watched instead) or,
        with ``edges`` None, as the design's network: ``(final, locked)``, a jam's reason, or
        None when the tracer could not run."""
        # a build with play moves without the bars its loops make redundant; they take their
        # lengths within the loops' play until it runs out (checked below)
        moving = net.with_nodes(x) if edges is None else Network(x, edges, net.ports)
        # the trace stops once the loops are clearly out of play: the build is judged before
        # that configuration, and tracing on (often to a turning or branch point, whose search
        # costs several steps) only made configurations no maker's pull reaches
        watch = None if edges is None else self._play_watch(net, x, builds, s)
        tr = self._traced(moving, m, edges, watch, net, builds, s)
        if tr is None:
            return None
        # a build that locks short of the target is judged where it locks, as a maker pushing
        # the drive until it stops would find it: at its own turning point (a built module's
        # crystal a little off the designed one), where a state of self-stress it moved with
        # vanishes, or where its loops run out of play (the AND gate's branch collapsed up to
        # the junction). Where the play runs out comes first: what the tracer met beyond it (a
        # failure, or the stop asked for above) is no part of the build's motion.
        stop = None if edges is None else self._play_runs_out(net, tr.positions, builds, s)
        if stop:
            return tr.positions[stop - 1], True
        last = tr.events[-1].kind if tr.events else None
        locked = last in (EventKind.TURNING_POINT, EventKind.SELF_STRESS_LOST)
        if tr.status is Status.FAILED and last is not EventKind.SELF_STRESS_LOST:
            return tr.message or "its trace failed"
        if stop == 0:
            return "its loops leave their play as it starts to move"
        return (tr.positions[-1], locked) if tr.success or locked else None

    def _traced(self, moving, m, edges, watch, net, builds, s):
        """The trace of ``moving`` (None where the tracer refuses it), stopped by ``watch``.

        Builds that go together alike share it: a run of one error source leaves the other
        sources' parts nominal, so its builds often sit where another run's did, with other
        play. The steps do not depend on the watch, which only cuts the trace short; a trace
        cut by another build's watch serves this one when its own play runs out within it."""
        key = (moving.nodes.tobytes(), None if edges is None else edges.tobytes())
        kept = self._memo.get(key)
        if kept is not None and (not kept[1]
                                 or self._play_runs_out(net, kept[0].positions, builds, s)):
            return kept[0]
        fired = []

        def until(y) -> bool:
            if watch(y):
                fired.append(True)
                return True
            return False

        extra = {} if watch is None else {"until": until}
        try:
            tr = trace(moving, drive=m.drive, to=m.to, method="projected", hold=m.hold, **extra)
        except (KinematicsError, FabkitError):
            return None
        size = tr.positions.size
        if self._memo_floats + size <= MEMO_FLOATS:
            self._memo[key] = (tr, bool(fired))
            self._memo_floats += size
        return tr

    def _play_watch(self, net, x, builds, s):
        """``until(y)`` for a build's trace: True once its loops are out of play by more than
        :func:`_play_runs_out` asks (by :data:`PLAY_WATCH_MARGIN`, so that the configuration it
        finds lies within the trace), None where that test costs a linear program per
        configuration (several states of self-stress)."""
        if self.stresses.shape[1] != 1:
            return None
        base, room = builds.base[s], builds.room[s]
        start = float(play_ratio(self.stresses, net.lengths_at(x) - base, room))
        limit = max(1.0, start) * (1.0 + PLAY_RTOL) * (1.0 + PLAY_WATCH_MARGIN)
        # play_ratio's closed form for one state of self-stress, asked after every step
        w = self.stresses[:, 0]
        have = float(np.abs(w) @ room)
        e0, e1 = (np.ascontiguousarray(net.edges[:, k]) for k in (0, 1))

        def until(y) -> bool:
            diff = y.take(e0, axis=0)
            diff -= y.take(e1, axis=0)
            gap = np.sqrt(np.einsum("ij,ij->i", diff, diff))
            gap -= base
            need = abs(float(gap @ w))
            if need <= COMPATIBLE_RTOL * max(float(np.abs(gap).max()), TINY):
                return False  # compatible: a ratio of 0
            return need > limit * have

        return until

    def _play_runs_out(self, net, positions, builds, s) -> int | None:
        """Index of the first configuration of a build's motion where its loops no longer close
        within its play (first order over the design's states of self-stress), else None.

        The play the build used to go together counts: the ratio is of each bar's length
        there against the length it was cut to. A build forced together (ratio > 1 at the
        start) runs out where its ratio grows past the start's."""
        gap = net.lengths_at(positions) - builds.base[s][None, :]
        ratio = play_ratio(self.stresses, gap, builds.room[s])
        over = np.flatnonzero(ratio > max(1.0, float(ratio[0])) * (1.0 + PLAY_RTOL))
        return int(over[0]) if over.size else None


def _front_sentence(detail: dict) -> str:
    """How far the driven chain's front got, over the builds that moved."""
    got = [k for k in detail["switched"] if k >= 0]
    if not got:
        return "no build moved"
    span = f"{min(got)}" if min(got) == max(got) else f"{min(got)} to {max(got)}"
    locked = detail.get("locked", 0)
    return (f"the driven chain's front ends {span} ports along ({detail['designed']} move in the "
            f"design, to its target); {locked} of {len(got)} builds lock before the target, "
            "where a maker's pull stops")


def _same_chain(ports, drive: str) -> np.ndarray:
    """Ports of the chain the drive port belongs to (``d3_b`` with ``d1_b``: the same suffix
    after the module number), as a mask over ``ports``; only the drive itself when its name
    is not a chain port's."""
    m = _CHAIN_PORT.fullmatch(drive)
    if m is None:
        return np.array([p == drive for p in ports], dtype=bool)
    return np.array([(q := _CHAIN_PORT.fullmatch(p)) is not None and q.group(2) == m.group(2)
                     for p in ports], dtype=bool)


def _port_lengths(x, pairs) -> np.ndarray:
    """Distances of the port pairs in configuration ``x``."""
    return np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=-1)


@dataclass
class _Traced:
    ports: np.ndarray


def analyse_tolerance(design, spec: ToleranceSpec | None = None, *, trajectory=None,
                      grid: int = 41, attribute: bool = True, progress=None) -> ToleranceResult:
    """Monte Carlo of built copies of a design, judged against what it is for.

    The design's behaviour (:mod:`fabkit.tolerance.behaviour`) is inferred from its map and
    motion (or read from ``[motion] intent``); every build is judged by its criteria
    (:mod:`fabkit.tolerance.criteria`), and the verdict is ok when at least ``min_reached`` of
    the builds keep it. The margin (:mod:`fabkit.tolerance.margin`) says by how much every error
    may grow before that changes.

    Parameters
    ----------
    design : Design
        With ``motion.to`` set.
    spec : ToleranceSpec, optional
        Default: :func:`tolerance_spec` of the design.
    trajectory : Trajectory, optional
        The nominal motion (traced when not given).
    grid : int
        Drive values checked between the start and the end for every build.
    attribute : bool
        Also find each error source's own margin and curve (``margin["sources"]``), and name
        in a flagged verdict the sources that stop the design.
    progress : callable, optional
        ``progress(done, total, what)`` as each step of the analysis starts (the builds, the
        margin, each source's own margin, the horizon).

    Returns
    -------
    ToleranceResult

    Raises
    ------
    TemplateError
        No target (``motion.to``), a nominal motion that does not reach it, or an unknown
        ``[motion] intent``.

    Examples
    --------
    >>> from fabkit.templates import load_template
    >>> from pathlib import Path
    >>> d = load_template(Path(__file__).parents[2] / "templates" / "fourbar.toml")
    >>> res = analyse_tolerance(d, tolerance_spec(d, samples=50), attribute=False)
    >>> res.keep_fraction, res.flagged, res.margin["value"] >= 1
    (1.0, False, True)
    """
    path = design.path or design.name
    spec = spec or tolerance_spec(design)
    given = design  # the design its process's plan was made for (shared with the export)
    net = design.network
    m = design.motion
    # builds x nodes over every run (main, the margin's bisections, each source's own): one
    # estimate of the work before any of it
    sources = len(spec_sources(spec)) if attribute else 0
    builds = (spec.samples + SOURCE_SAMPLES * sources) * (2 + SCALE_BISECTIONS)
    require(f"{path}: tolerance ({spec.samples} builds)", ("build node", builds * net.n_nodes))
    if m.to is None:
        raise TemplateError(path, "motion.to", "the tolerance analysis needs a target value")
    if trajectory is None:
        trajectory = design.trace()
    if not trajectory.success:
        raise TemplateError(path, "motion.to", f"the designed motion does not reach the target: "
                                               f"{trajectory.message}")
    requested = float(m.to)
    if trajectory.events and trajectory.events[-1].kind is EventKind.TURNING_POINT \
            and float(trajectory.drive[-1]) != requested:
        # the target lies within rounding past a turning point (the trace says so): the design
        # is judged where its motion ends, as every copy of it that rounds the other way is
        m = replace(m, to=float(trajectory.drive[-1]))
        design = replace(design, motion=m)
    problem = make_problem(net, m.drive, m.to, hold=m.hold)
    ports = chain_ports(net)
    pairs = np.array([net.port(p) for p in ports])
    chain_cols = [k for k, p in enumerate(ports) if is_chain_port(p)]
    a, b = problem.drive
    n_chain = len(chain_cols)
    end_nodes = sorted(set(pairs[max(n_chain, 1) - 1].tolist()))
    plan = find_plan(problem, trajectory)
    if plan is None:
        spec = replace(spec, samples=min(spec.samples, PROJECTED_SAMPLES_CAP))
    # the module size: the mean port distance at the target; in a chain of modules, of the
    # first module's two ports (every module is a copy of it). A chain's far modules may sit
    # where they hang on the last bits (the super-stable chain driven into its collapse): their
    # ports would make the limit a matter of round-off
    target_x = place(plan, [m.to])[0][0] if plan is not None else trajectory.final
    sized = pairs[chain_cols[:2]] if n_chain >= 3 else pairs
    at_target = np.linalg.norm(target_x[sized[:, 0]] - target_x[sized[:, 1]], axis=-1)
    size_mm = float(np.mean(at_target)) * spec.scale
    limit_mm = spec.limit if spec.limit is not None else spec.limit_fraction * size_mm
    behaviour = infer_behaviour(design, spec, trajectory, problem, plan, ports, pairs, limit_mm)
    geo = process_geometry(design, spec, problem, behaviour.end_config)
    play_note = ""
    if spec.process == "print" and spec.linkage == "pins" and spec.print_settings is not None:
        # the print's plan (shared with its export) says which bar carries each pin
        pins = pin_play(given, spec.print_settings)
        geo, play_note = replace(geo, play_ends=pins.ends), pins.note
    room = nominal_room_mm(spec, net.n_edges, geo.play_ends)
    clearance_mm = 2 * float(room.max()) if room is not None and room.size else limit_mm
    if plan is not None:
        method = "constructive"
        run = _Constructive(design, spec, behaviour, plan, problem, pairs, geo, grid, limit_mm,
                            clearance_mm)
    else:
        method = "projected"
        run = _Projected(design, spec, behaviour, geo, ports, pairs, limit_mm)

    M = spec.samples
    rows = np.arange(M)
    names = list(spec_sources(spec))
    steps = 3 + (len(names) if attribute else 0)
    say = progress or (lambda done, total, what: None)
    say(0, steps, f"{M} builds ({method})")
    main = run(np.ones(M), rows, observe=True)
    keep = main.keep
    say(1, steps, "the margin: every error scaled")
    crit = critical_scales(lambda g, r: run(g, r).keep, keep)
    margin, bound = margin_of(crit, spec.min_reached)
    curves = {"scales": CURVE_SCALES.tolist(), "all": keep_curve(crit).tolist()}
    source_margins = {}
    if attribute:
        k = min(M, SOURCE_SAMPLES if method == "constructive" else PROJECTED_SOURCE_SAMPLES)
        few = np.arange(k)
        for i, name in enumerate(names):
            say(2 + i, steps, f"the margin of {name} alone")
            one = run(np.ones(k), few, [name]).keep
            c = critical_scales(lambda g, r, name=name: run(g, few[r], [name]).keep, one,
                                SOURCE_BISECTIONS)
            curves[name] = keep_curve(c).tolist()
            source_margins[name] = margin_of(c, spec.min_reached)
    say(steps - 1, steps, "order, ports and horizon")
    observed = run.observe_order(main, rows, chain_cols) if method == "constructive" else None

    # the builds at their end, for the ports table and the pictures
    driven = main.driven
    built = sample_builds(geo, spec, np.random.default_rng(spec.seed)).base
    length_rms = float(np.sqrt(np.mean((built - net.edge_lengths[None, :]) ** 2)) * spec.scale)
    nominal = behaviour.end_ports
    end_offsets = None
    if driven is not None:
        dist = np.array(driven.ports, dtype=np.float64)
        if method == "constructive":
            near = np.abs(driven.stop - behaviour.end_drive) <= limit_mm / spec.scale
            reached = near & driven.closed
            ref_dir = (plan.reference[b] - plan.reference[a])[:2]
            framed = to_drive_frame(driven.final, a, b, ref_dir)
            nominal_framed = to_drive_frame(behaviour.end_config[None], a, b, ref_dir)[0]
            end_offsets = framed[:, end_nodes] - nominal_framed[None, end_nodes]
        else:
            reached = np.isfinite(dist).all(axis=1)
        dist[~reached] = np.nan
    else:
        dist = np.full((M, len(ports)), np.nan)
        reached = np.zeros(M, dtype=bool)

    horizon = _horizon(design, plan, dist, reached, ports, length_rms, size_mm, limit_mm,
                       behaviour)
    frac = float(keep.mean())
    flagged = frac < spec.min_reached
    margin_info = {"value": margin, "bound": bound, "min_reached": spec.min_reached,
                   "curves": curves,
                   "sources": {n: {"value": v, "bound": bd} for n, (v, bd) in
                               source_margins.items()},
                   "source_samples": min(M, SOURCE_SAMPLES if method == "constructive"
                                         else PROJECTED_SOURCE_SAMPLES) if attribute else 0}
    verdict = _verdict(spec, behaviour, main.judged, frac, flagged, margin, bound,
                       source_margins, horizon, ports)
    assembly = _assembly_summary(spec, main, run, M)
    if assembly is not None and assembly["model"] != "rigid":
        verdict += f"; {assembly['sentence']}"
    held = [problem.drive] + [net.port(h) for h in (m.hold or ())]
    states = {"start": problem.start}
    if behaviour.end_config is not None:
        states["end"] = behaviour.end_config
    slop = slop_summary(net, spec, ports, pairs, held, states, geo.play_ends)
    extra = {"drive": m.drive, "target": float(m.to), "requested_target": requested,
             "module_size_mm": size_mm,
             "end_drive": behaviour.end_drive, "end_at": behaviour.end_at,
             "model_level": (assembly or {}).get("model", "rigid"),
             "assembly": assembly, "slop": slop}
    if play_note:
        extra["play_note"] = play_note
    if observed is not None:
        extra["observed_order"] = observed
    return ToleranceResult(spec=spec, method=method, ports=ports, nominal=nominal, distances=dist,
                           reached=reached, keep=keep, end_nodes=end_nodes,
                           end_offsets=end_offsets, length_rms=length_rms,
                           limits=np.full(len(ports), limit_mm), horizon=horizon,
                           flagged=flagged, verdict=verdict, behaviour=behaviour,
                           judged=main.judged, margin=margin_info, critical=crit, extra=extra)


def _assembly_summary(spec, main: _Run, run, samples: int) -> dict | None:
    """How the main run's builds went together (kits of parts with play only: a laser kit, a
    pin-jointed print; a hinge print and a sheet are made in one piece)."""
    if main.assembly is not None:
        return main.assembly.as_dict()
    if nominal_room_mm(spec, 0) is None:
        return None
    unused = getattr(getattr(run, "driver", None), "unused", np.zeros(0))
    closed = getattr(main.driven, "closed", None)
    if not len(unused) or closed is None:
        return {"model": "rigid", "model_name": MODEL_NAMES["rigid"], "self_stresses": 0,
                "builds": samples, "assemble": samples, "forced": 0, "not_buildable": 0,
                "sentence": f"all {samples} builds go together: the network has no state of "
                            "self-stress, so any bar lengths fit (model: rigid bars)"}
    n = int(np.sum(closed))
    return {"model": "play", "model_name": MODEL_NAMES["play"], "builds": samples,
            "assemble": n, "forced": 0, "not_buildable": samples - n,
            "sentence": f"{n} of {samples} builds assemble within their play (first order over "
                        f"the states of self-stress; model: {MODEL_NAMES['play']})"}


def _horizon(design, plan, dist, reached, ports, length_rms, size_mm, limit_mm, behaviour):
    """Lyapunov exponent and predictability horizon of a chain (None without a plan)."""
    lyap = lyapunov_estimate(design, plan) if plan is not None else None
    if lyap is None:
        return None
    lam = lyap["lyapunov"]
    eps = max(length_rms, EDGE_RTOL)
    modules = None
    if lyap["steps"] < MIN_MAP_STEPS:
        detail = (f"the module map leaves the module's range after {lyap['steps']} step(s) "
                  "from the target: too short an orbit to estimate a horizon")
    elif abs(lam) < NEUTRAL_LYAPUNOV:
        detail = "neutral map (λ ≈ 0): errors neither grow nor shrink exponentially"
    elif lam < 0:
        detail = "errors shrink along the chain (λ < 0): no horizon"
    elif size_mm <= eps:
        detail = "the error is already as large as a module"
    else:
        modules = math.log(size_mm / eps) / lam
        detail = (f"a {eps:.3g} mm bar error grows to the {size_mm:.3g} mm module size after "
                  f"about {modules:.1f} modules")
    out = {**lyap, "error_mm": eps, "module_size_mm": size_mm, "modules": modules,
           "detail": detail}
    if behaviour.chaos is not None:
        lam_map = behaviour.chaos["lyapunov"]
        out["map_lyapunov"] = lam_map
        out["limit_modules"] = math.log(limit_mm / eps) / lam_map if limit_mm > eps else 0.0
    chain = [k for k, p in enumerate(ports) if is_chain_port(p)]
    ok = dist[reached]
    if len(chain) >= 3 and ok.shape[0] >= 5:
        spread = ok[:, chain].std(axis=0)
        kk = np.arange(len(chain))
        good = spread > 0
        if good.sum() >= 3:
            out["monte_carlo_slope"] = float(np.polyfit(kk[good], np.log(spread[good]), 1)[0])
            out["monte_carlo_std"] = spread.tolist()
    return out


def _switch_failure(name, j, ports) -> str | None:
    """The clause of ``driven state`` or ``still ports``: builds that never reach an end (said
    once, with the driven state), then those that end wrong."""
    d, v = j.detail, j.value_mm
    there = np.isfinite(v)
    wrong = there & ~j.ok
    clauses = []
    if name == "driven state" and (~there).any():
        unbuilt = j.ok.size - d.get("assembled", j.ok.size)
        jammed = d.get("jammed", 0)
        parts = []
        if unbuilt:
            parts.append(f"{unbuilt} cannot be put together, even forced within the material's "
                         "allowable stress")
        if jammed:
            parts.append(f"{jammed} jam (the first: {d.get('jam_reason') or 'its loops leave their play'})")
        rest = int((~there).sum()) - unbuilt - jammed
        if rest > 0:
            parts.append(f"{rest} cannot be traced from where they go together")
        clauses.append(f"{int((~there).sum())} of {j.ok.size} builds never reach an end: "
                       + "; ".join(parts))
    if wrong.any():
        p95 = float(np.percentile(v[there], 95, method="higher"))
        share = 100.0 * float(wrong.mean())
        if name == "driven state":
            clauses.append(f"{share:.1f}% of builds stop short of the driven port's end state, "
                           f"up to {p95:.3g} mm from it (95% of those that end; allowed "
                           f"{j.limit_mm:.3g} mm)")
        else:
            k = int(np.argmax(np.percentile(j.per_part[there], 95, axis=0, method="higher")))
            clauses.append(f"{share:.1f}% of builds move {ports[d['still_columns'][k]]}, which "
                           f"the design keeps still, by up to {p95:.3g} mm (95% of those that "
                           f"end; allowed {j.limit_mm:.3g} mm)")
    return "; ".join(clauses) or None


def _failure(name, j, spec, behaviour, ports) -> str | None:
    """A clause for a criterion that some builds fail (None: said by another's clause)."""
    lost = 100.0 * (1.0 - float(j.ok.mean()))
    v = j.value_mm
    p95 = float(np.percentile(v, 95, method="higher")) if v.size else math.inf
    u = " mm" if j.unit == "mm" else j.unit
    folds = j.unit != "mm"  # an origami state, judged by the built sheet's folds
    if name == "crystals":
        missing = int(np.sum(~np.isfinite(v)))
        what = ", ".join(f"{c.value:.6g} ({c.kind})" for c in behaviour.crystals
                         if c.role == "start")
        tail = (f"in {missing} builds a module has none of its kind" if missing else
                f"a sheet there folds up to {p95:.3g}{u} off the designed fold angles (95% of "
                f"builds; allowed {j.limit_mm:.3g}{u})" if folds else
                f"they move by up to {p95:.3g} mm (95% of builds; allowed {j.limit_mm:.3g} mm)")
        if missing and not folds:
            tail += f" within {j.limit_mm:.3g} mm"
        return f"{lost:.1f}% of builds lose a crystal at {what}: {tail}"
    if name == "order":
        return (f"{lost:.1f}% of builds lose the order: a module meets the diagonal, turns "
                "back or locks between its states (a second front, or a stalled one)")
    if name == "end state":
        end = [c for c in behaviour.crystals if c.role == "end"]
        what = f"the crystal {end[0].value:.6g} ({end[0].kind})" if end else \
            f"its lock at {behaviour.end_lock[0]:.6g}"
        missing = int(np.sum(~np.isfinite(v)))
        tail = (f"in {missing} builds some module has none" + ("" if folds else
                f" within {j.limit_mm:.3g} mm") if missing
                else f"a sheet ends folded up to {p95:.3g}{u} off its designed fold angles (95% "
                     f"of builds; allowed {j.limit_mm:.3g}{u})" if folds
                else f"a module ends up to {p95:.3g} mm from it (95% of builds; allowed "
                     f"{j.limit_mm:.3g} mm)")
        return f"{lost:.1f}% of builds miss the end state, {what}: {tail}"
    if name == "end shape":
        return (f"the end shape is off by up to {p95:.3g} mm after the best rigid fit (95% of "
                f"builds; allowed {j.limit_mm:.3g} mm)")
    if name in ("driven state", "still ports"):
        return _switch_failure(name, j, ports)
    # end ports: the worst port
    if j.detail.get("assembled") == 0:
        return (f"none of the {j.ok.size} builds goes together, even forced within the "
                "material's allowable stress")
    jam = ""
    if j.detail.get("jammed"):
        jam = (f"{j.detail['jammed']} of {j.ok.size} builds, put together, stop before the "
               f"target (the first: {j.detail.get('jam_reason') or 'its loops leave its play'})")
    if j.detail.get("moved") == 0:
        return jam or f"none of the {j.ok.size} builds, as put together, moves to the target"
    where = "at the target" if behaviour.end_at == "target" else "where the motion locks"
    by_port = np.asarray(j.detail.get("p95_by_port_mm", [p95]))
    if j.per_part is not None and j.per_part.size:  # the worst port among builds that moved
        moved = np.isfinite(j.per_part).all(axis=1)
        if moved.any():
            by_port = np.percentile(j.per_part[moved], 95, axis=0, method="higher")
    k = int(np.argmax(by_port))
    name = ports[k] if k < len(ports) else "a port"
    worst = float(by_port[k])
    off = "cannot be reached" if not math.isfinite(worst) else f"is off by up to {worst:.3g} mm"
    text = f"{name} {where} {off} (95% of builds that get there; allowed {j.limit_mm:.3g} mm)"
    return f"{jam}; {text}" if jam else text


def _verdict(spec, behaviour, judged, frac, flagged, margin, bound, source_margins, horizon,
             ports) -> str:
    unit = f"{spec.process} builds"
    names = list(judged)
    head_margin = margin_text(margin, bound)
    if not flagged:
        parts = []
        for name, j in judged.items():
            fin = j.value_mm[np.isfinite(j.value_mm)]
            if name == "order" or not fin.size:
                parts.append(name)
            else:
                front = f", {j.detail['front']}" if "front" in j.detail else ""
                u = " mm" if j.unit == "mm" else j.unit
                parts.append(f"{name} within {printed(np.percentile(j.value_mm, 95), '.3g')} "
                             f"of {j.limit_mm:.3g}{u}{front}")
        return (f"ok, margin {head_margin}: {100 * frac:.1f}% of {unit} keep the behaviour "
                f"({'; '.join(parts)})")
    shrink = "" if bound == "below" else f"; errors must shrink to {margin:.2g}×"
    if bound == "below":
        shrink = "; errors must shrink more than tenfold"
    clauses = [_failure(n, judged[n], spec, behaviour, ports) for n in names
               if not judged[n].ok.all()]
    clauses = [c for c in clauses if c]
    if behaviour.chaos is not None and horizon and horizon.get("limit_modules") is not None:
        lam = behaviour.chaos["lyapunov"]
        clauses.append(f"chaotic (λ = {lam:.2f} per module): a {horizon['error_mm']:.3g} mm "
                       f"error outgrows the limit after about {horizon['limit_modules']:.1f} "
                       f"modules, and the design asks for {ports[behaviour.chaos['modules']]} "
                       f"{behaviour.chaos['modules']} modules on")
    cause = ""
    if source_margins:
        alone = {n: v for n, (v, bd) in source_margins.items() if v < 1.0}
        if alone:
            cause = "; stopped by " + ", ".join(
                f"{n} (alone margin {margin_text(*source_margins[n])})"
                for n in sorted(alone, key=alone.get))
        else:
            n = min(source_margins, key=lambda k: source_margins[k][0])
            cause = (f"; no single source stops it, their sum does (smallest margin alone: {n}, "
                     f"{margin_text(*source_margins[n])})")
    return (f"FLAG, margin {head_margin}{shrink}: only {100 * frac:.1f}% of {unit} keep the "
            f"behaviour (need {100 * spec.min_reached:.0f}%): " + "; ".join(clauses) + cause)
