"""What every tracing method shares: the problem statement, the gauge, option checking, and
the packaging of results.

A method is a subclass of :class:`Method` that declares its options (name → default) and
implements :meth:`Method.solve`, which returns a :class:`Solved`: configurations, a status, a
message and :class:`Mark` s at configuration indices. Methods that trace step by step
(``projected``, ``rk4-nullspace``) subclass :class:`~.stepping.StepMethod` instead, which owns
the loop (configurations, ``max_steps``, stops and their events) and asks the method only for
its start and one step at a time. :meth:`Method.run` (owned by the base class,
as ``solve_ivp``'s ``OdeSolver.step`` owns its status) aligns the configurations to the gauge,
measures arclength and edge errors, turns marks into :class:`~.trajectory.Event` s at the
marked configurations, and builds the :class:`~.trajectory.Trajectory`. :func:`fabkit.trace`
builds the :class:`Problem` once and hands it to the method named in ``METHODS``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .. import arguments
from ..errors import ArgumentTypeError, ArgumentValueError, KinematicsError, SettingsError
from ..model.network import checked_network, Network
from ..numerics import rigid_fit, START_RTOL, TARGET_AT_TURN_RTOL, TINY
from .record import edge_errors, keep_rule, Record, record_positions
from ..status import Status, TRACE, expect
from .trajectory import Event, EventKind, Trajectory

__all__ = ["Problem", "Mark", "Solved", "Method", "make_problem", "choose_gauge",
           "align_to_gauge", "check_option"]

#: A gauge triangle (3D) must span at least this area, and a third gauge node lie this far off
#: the gauge edge, relative to the network's size (squared for the area): else the nodes are
#: collinear to round-off and fix no rotation.
GAUGE_SPREAD_RTOL = 1e-9


@dataclass(frozen=True)
class Mark:
    """An event as a method reports it: what, at which configuration, and a sentence.

    Attributes
    ----------
    kind : EventKind or str
    index : int
        Index of the configuration in the method's output at (or nearest to) the event; an index
        past the end means the last configuration.
    detail : str
    """

    kind: EventKind
    index: int
    detail: str = ""


@dataclass(frozen=True, eq=False)
class Solved:
    """What :meth:`Method.solve` returns; :meth:`Method.run` makes the Trajectory of it.

    Attributes
    ----------
    positions : numpy.ndarray, shape (S, N, d)
        Configurations in the start's frame (or in the gauge frame when ``aligned``).
    status : Status
    message : str
        One sentence: where and why the trace ended.
    marks : tuple of Mark
    stats : dict
        Method-specific counters.
    arclength : numpy.ndarray of shape (S,), optional
        The method's own arclength (default: the polygon length through the configurations).
    aligned : bool
        True when the positions are already in the gauge frame.
    method : str, optional
        The name to report when a method delegates (e.g. ``"branch/constructive"``).
    record : Record, optional
        The configurations already reduced to what the trace keeps, in the gauge frame
        (``positions`` and ``arclength`` are then not used).
    """

    positions: np.ndarray | None
    status: Status
    message: str
    marks: tuple = ()
    stats: dict = field(default_factory=dict)
    arclength: np.ndarray | None = None
    aligned: bool = False
    method: str | None = None
    record: Record | None = None

    def __post_init__(self):
        object.__setattr__(self, "status", expect(self.status, TRACE, "a trace"))


@dataclass(frozen=True, eq=False)
class Problem:
    """A tracing task after validation.

    Attributes
    ----------
    network : Network
        The network as given by the caller.
    work : Network
        The network actually traced: ``network`` plus one virtual edge per held port.
    start : numpy.ndarray, shape (N, d)
        Start configuration (satisfies the edge lengths of ``work``).
    drive : tuple of int
        Node pair whose distance is driven.
    drive_name : str
    target : float
        Drive value to reach (at most the length of all bars: see ``requested``).
    gauge : tuple of int
        Nodes held still: an edge (2D) or a triangle (3D) of ``work``.
    keep : str or int
        What the trajectory keeps of its configurations: ``"all"``, ``"ports"`` or every k-th
        (see :mod:`.record`).
    ports : tuple of str or None
        With ``keep`` other than ``"all"``: the ports whose distances are kept at every
        configuration (None: every port).
    requested : float or None
        The caller's target when it lies beyond the length of all bars (no configuration
        reaches it); the trajectory reports this one.
    """

    network: Network
    work: Network
    start: np.ndarray
    drive: tuple[int, int]
    drive_name: str
    target: float
    gauge: tuple[int, ...]
    keep: str | int = "all"
    requested: float | None = None
    ports: tuple | None = None

    @property
    def dim(self) -> int:
        return self.work.dim

    def drive_of(self, positions) -> np.ndarray:
        """Drive value(s) of configurations (N, d) or (S, N, d)."""
        i, j = self.drive
        x = np.asarray(positions)
        return np.linalg.norm(x[..., i, :] - x[..., j, :], axis=-1)

    @property
    def start_drive(self) -> float:
        return float(self.drive_of(self.start))

    def trajectory(self, positions, method: str, status: Status, message: str,
                   marks=(), stats=None, arclength=None) -> Trajectory:
        """Package configurations as a :class:`Trajectory` (edge errors against ``network``).

        ``marks`` (:class:`Mark` s) become events whose drive value and arclength are those of
        the marked configuration.
        """
        pos = np.ascontiguousarray(positions, dtype=np.float64)
        if arclength is None:
            steps = np.linalg.norm((pos[1:] - pos[:-1]).reshape(len(pos) - 1, pos[0].size), axis=1)
            arclength = np.concatenate([[0.0], np.cumsum(steps)])
        arclength = np.asarray(arclength, dtype=np.float64)
        record = Record(pos, None, self.drive_of(pos), arclength,
                        edge_errors(self.network, pos), None)
        return self.trajectory_of(record, method, status, message, marks, stats)

    def trajectory_of(self, record: Record, method: str, status: Status, message: str,
                      marks=(), stats=None) -> Trajectory:
        """Package a :class:`~.record.Record` (configurations reduced to what the trace keeps)
        as a :class:`Trajectory`; events take the drive value and arclength of the marked
        configuration."""
        drive, arclength = record.drive, record.arclength
        last = len(drive) - 1
        events = tuple(Event(m.kind, min(int(m.index), last), float(drive[min(int(m.index), last)]),
                             float(arclength[min(int(m.index), last)]), m.detail) for m in marks)
        return Trajectory(
            network=self.network,
            positions=record.positions,
            drive=drive,
            arclength=arclength,
            edge_error=record.edge_error,
            method=method,
            status=status,
            message=message,
            drive_port=self.drive,
            target=self.target if self.requested is None else self.requested,
            events=events,
            stats=dict(stats or {}),
            kept=record.kept,
            port_values=record.ports,
        )


def _resolve_port(net: Network, drive) -> tuple[tuple[int, int], str]:
    if isinstance(drive, str):
        try:
            return net.port(drive), drive
        except KeyError as exc:
            raise KinematicsError(str(exc.args[0])) from None
    if not isinstance(drive, (list, tuple)) or len(drive) != 2:
        raise ArgumentTypeError("drive", f"must be a port name or a pair of node indices, got "
                                         f"{drive!r:.40}")
    i, j = (arguments.whole("drive", v) for v in drive)
    for v in (i, j):
        if not 0 <= v < net.n_nodes:
            raise KinematicsError(f"`drive` names node {v}, outside 0..{net.n_nodes - 1}")
    if i == j:
        raise KinematicsError(f"`drive` joins node {i} to itself")
    return (i, j), f"({i}, {j})"


def choose_gauge(net: Network, positions, drive: tuple[int, int]) -> tuple[int, ...]:
    """Nodes to hold still: a rigid element near the drive's first node.

    In 2D an edge incident to the first drive node (else the longest edge); in 3D a triangle of
    edges through that node if one exists, else any triangle of edges, else an edge and the node
    farthest from its line. Holding a rigid element (not the drive pair) keeps the gauge valid
    over the whole motion: the element never changes shape.
    """
    x = np.asarray(positions, dtype=np.float64)
    edges = net.edges
    if edges.shape[0] == 0:
        raise KinematicsError("the network has no edges: nothing constrains its motion")
    a = drive[0]
    incident = np.flatnonzero((edges == a).any(axis=1))
    lengths = net.lengths_at(x)
    if net.dim == 2:
        k = incident[np.argmax(lengths[incident])] if incident.size else int(np.argmax(lengths))
        return (int(edges[k, 0]), int(edges[k, 1]))
    nbrs = [set() for _ in range(net.n_nodes)]
    for i, j in edges.tolist():
        nbrs[i].add(j)
        nbrs[j].add(i)

    def best_triangle(candidates):
        best, best_area = None, 0.0
        for i in candidates:
            for j in nbrs[i]:
                for k in nbrs[i] & nbrs[j]:
                    area = np.linalg.norm(np.cross(x[j] - x[i], x[k] - x[i]))
                    if area > best_area:
                        best, best_area = (i, j, k), area
        return best, best_area

    tri, area = best_triangle([a])
    if tri is None:
        tri, area = best_triangle(range(net.n_nodes))
    scale = max(net.size, TINY) ** 2
    if tri is not None and area > GAUGE_SPREAD_RTOL * scale:
        return tuple(int(v) for v in tri)
    k = incident[np.argmax(lengths[incident])] if incident.size else int(np.argmax(lengths))
    i, j = int(edges[k, 0]), int(edges[k, 1])
    u = (x[j] - x[i]) / np.linalg.norm(x[j] - x[i])
    off = x - x[i]
    dist = np.linalg.norm(off - np.outer(off @ u, u), axis=1)
    third = int(np.argmax(dist))
    if dist[third] <= GAUGE_SPREAD_RTOL * net.size:
        return (i, j)  # all nodes collinear: rotation about the line is not a motion anyway
    return (i, j, third)


#: Nodes per block of configurations moved at once by :func:`align_to_gauge` (a block's
#: coordinates stay in cache across the d² products and sums).
ALIGN_BLOCK_NODES = 1 << 14


def align_to_gauge(positions, reference, gauge) -> np.ndarray:
    """Move each configuration rigidly so that the gauge nodes best match the reference.

    Parameters
    ----------
    positions : array_like, shape (S, N, d)
    reference : array_like, shape (N, d)
    gauge : sequence of int

    Returns
    -------
    numpy.ndarray, shape (S, N, d)
        Proper rotations only (no reflection), Kabsch fit on the gauge nodes.
    """
    x = np.asarray(positions, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)[list(gauge)]
    fit = rigid_fit(x[:, list(gauge)], ref)
    # x @ Rᵀ + t with the sums written out: a batched matmul with an inner size of 2 or 3 is
    # several times slower (70 ms for 36 configurations of a 30 000-node chain); a block of
    # configurations at a time, whose coordinates stay in cache between the sums (17 ms -> 5 ms)
    rot, shift = fit.rotation, fit.shift
    out = np.empty_like(x)
    d = x.shape[-1]
    step = max(1, ALIGN_BLOCK_NODES // max(1, x.shape[-2]))
    for lo in range(0, x.shape[0], step):
        xs, outs = x[lo:lo + step], out[lo:lo + step]
        r, t = rot[lo:lo + step], shift[lo:lo + step]
        for a in range(d):
            acc = xs[..., 0] * r[:, None, a, 0]
            for b in range(1, d):
                acc += xs[..., b] * r[:, None, a, b]
            acc += t[:, None, a]
            outs[..., a] = acc
    return out


def make_problem(net: Network, drive, to, *, start=None, hold=(), gauge=None,
                 keep="all", ports=None) -> Problem:
    """Validate a tracing request and build the :class:`Problem` every method solves."""
    keep = keep_rule(keep)
    checked_network("net", net)
    ports = _kept_ports(net, keep, ports)
    pair, name = _resolve_port(net, drive)
    target = arguments.real("to", to, positive=True)
    # No two nodes are farther apart than the length of all bars: a target beyond that is traced
    # toward that length instead (the motion turns back before it, and says where), and is
    # still the one the trajectory reports as not reached; numbers like 1e308 never enter a step.
    requested = None
    reach = float(net.edge_lengths.sum())
    if target > reach:
        requested, target = target, reach
    key = tuple(sorted(pair))
    if np.any((np.minimum(net.edges[:, 0], net.edges[:, 1]) == key[0])
              & (np.maximum(net.edges[:, 0], net.edges[:, 1]) == key[1])):
        raise KinematicsError(
            f"the drive {name} joins nodes {pair[0]} and {pair[1]}, which share an edge: "
            "its distance cannot change"
        )
    x0 = net.nodes if start is None else np.asarray(start, dtype=np.float64)
    if x0.shape != net.nodes.shape:
        raise KinematicsError(f"`start` must have shape {net.nodes.shape}, got {x0.shape}")
    if not np.isfinite(x0).all():
        raise KinematicsError("`start` has non-finite coordinates")
    if start is not None:
        err = float(net.edge_error(x0))
        if err > START_RTOL:
            raise KinematicsError(
                f"`start` does not keep the edge lengths (largest relative error {err:.2e})"
            )
    extra = []
    if hold is not None and not isinstance(hold, (str, list, tuple)):
        raise ArgumentTypeError("hold", f"must be a port name or a list of them, got "
                                        f"{type(hold).__name__}")
    for h in ([hold] if isinstance(hold, str) else list(hold or ())):
        hp, hname = _resolve_port(net, h)
        if tuple(sorted(hp)) == key:
            raise KinematicsError(f"cannot both drive and hold {hname}")
        extra.append(hp)
    work = net
    if extra or start is not None:
        # Held ports become virtual edges whose lengths are measured at the start.
        edges = np.vstack([net.edges, np.array(extra, dtype=np.int64).reshape(-1, 2)])
        work = Network(x0, edges, net.ports, net.labels)
    if gauge is None:
        gauge = choose_gauge(work, x0, pair)
    else:
        gauge = tuple(int(v) for v in gauge)
        if any(not 0 <= v < net.n_nodes for v in gauge) or len(set(gauge)) != len(gauge):
            raise KinematicsError(f"`gauge` must name distinct nodes of the network, got {gauge}")
    return Problem(network=net, work=work, start=np.array(x0), drive=pair, drive_name=name,
                   target=target, gauge=gauge, keep=keep, requested=requested, ports=ports)


def _kept_ports(net: Network, keep, ports) -> tuple | None:
    """The ``ports`` of a trace, checked: names of the network's ports, given with a ``keep``
    that keeps port distances."""
    if ports is None:
        return None
    if isinstance(ports, str) or not isinstance(ports, (list, tuple)):
        raise ArgumentTypeError("ports", f"must be a list of port names, got "
                                         f"{type(ports).__name__}")
    if keep == "all":
        raise KinematicsError("`ports` chooses the port distances a trace keeps with "
                              "keep='ports' or keep=k; keep='all' keeps every configuration")
    for name in ports:
        if not isinstance(name, str) or name not in net.ports:
            raise KinematicsError(f"`ports` names {name!r:.40}, which is not a port of the "
                                  f"network ({len(net.ports)} ports: d1, ...)"
                                  if isinstance(name, str) else
                                  f"`ports` must hold port names, got {name!r:.40}")
    return tuple(dict.fromkeys(ports))


def check_option(method: str, name: str, value) -> None:
    """Refuse an option of a built-in method that its declared schema
    (:data:`fabkit.io.schema.METHOD_OPTIONS`) does not allow, before any work, with an
    :class:`~fabkit.errors.ArgumentError` naming it (a NaN ``max_step`` once ended a trace
    after three samples); NumPy scalars count as the Python numbers they hold. Options of a
    method of one's own, and undeclared ones (``plan``), are the method's to check."""
    from ..io.schema import check_method_options

    plain = value.item() if isinstance(value, np.generic) else value
    try:
        check_method_options(method, {name: plain}, where="options")
    except SettingsError as exc:
        if exc.kind == "unknown":
            return  # not declared: the method's own
        # a value of the wrong kind (text, a bool, 2.5 for a count) is a TypeError, as in
        # fabkit.arguments; a number out of range a ValueError
        number = isinstance(plain, (int, float)) and not isinstance(plain, bool)
        wrong_kind = not number or exc.kind == "type"
        raise (ArgumentTypeError if wrong_kind else ArgumentValueError)(name, exc.reason) \
            from None


class Method(ABC):
    """Base class of tracing methods.

    Subclasses set ``name``, ``options`` (a dict of option name → default) and implement
    :meth:`solve`. Unknown options raise ``TypeError`` naming the valid ones, so that a typo in a
    template or a call never passes silently.
    """

    name: str = ""
    options: dict = {}

    def __init__(self, problem: Problem, **options):
        unknown = sorted(set(options) - set(self.options))
        if unknown:
            valid = ", ".join(sorted(self.options)) or "none"
            raise ArgumentTypeError(unknown[0], f"is an unknown option of method {self.name!r} "
                                                f"(unknown option(s): {', '.join(unknown)}); "
                                                f"valid: {valid}")
        for name, value in options.items():
            check_option(self.name, name, value)
        self.problem = problem
        self.opts = {**self.options, **options}

    @abstractmethod
    def solve(self) -> Solved:
        """Trace the motion; return a Solved whatever happens (status and message say how)."""

    def run(self) -> Trajectory:
        """Trace the motion and package it: gauge frame, arclength, events, edge errors, and
        only the configurations ``keep`` asks for."""
        out = self.solve()
        p = self.problem
        name = out.method or self.name
        if out.record is not None:  # the method reduced its configurations itself
            traj = p.trajectory_of(out.record, name, out.status, out.message, out.marks,
                                   out.stats)
        else:
            x = np.asarray(out.positions, dtype=np.float64)
            if not out.aligned:
                x = align_to_gauge(x, p.start, p.gauge)
            if p.keep != "all":
                traj = p.trajectory_of(record_positions(p, x, out.arclength), name, out.status,
                                       out.message, out.marks, out.stats)
            else:
                traj = p.trajectory(x, name, out.status, out.message, out.marks, out.stats,
                                    out.arclength)
        return _target_at_turn(traj, p)

    # Helpers shared by the methods -------------------------------------------------------------
    def direction(self) -> float:
        """+1 when the drive must grow to reach the target, -1 when it must shrink."""
        return 1.0 if self.problem.target >= self.problem.start_drive else -1.0

    def finished_message(self) -> str:
        p = self.problem
        return f"reached {p.drive_name} = {p.target:.10g}"


def _target_at_turn(traj: Trajectory, p) -> Trajectory:
    """A trace that turns back within rounding of its target has reached it (see
    :data:`fabkit.numerics.TARGET_AT_TURN_RTOL`): finished, at the turning point, and saying so.
    Which side of a fold a target 1e-12 past it lies on is a matter of the last bits."""
    if traj.status is not Status.TURNING_POINT or traj.drive.size == 0:
        return traj
    turn = float(traj.drive[-1])
    short = (p.target - turn) * (1.0 if p.target >= p.start_drive else -1.0)
    scale = max(abs(p.target), abs(p.start_drive), 1.0)
    if not 0.0 <= short <= TARGET_AT_TURN_RTOL * scale:
        return traj
    message = (f"reached {p.drive_name} = {turn:.10g}, where the motion turns back, within "
               f"rounding of the target {p.target:.10g} ({short:.1e} short of it)")
    return dataclasses.replace(traj, status=Status.FINISHED, message=message)
