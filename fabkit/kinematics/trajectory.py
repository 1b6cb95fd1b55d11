"""The result of tracing a motion: :class:`Trajectory`, with its status and the events met."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from ..errors import KinematicsError
from ..model.network import Network
from ..status import Status, TRACE, expect

__all__ = ["EventKind", "Event", "Trajectory"]


class EventKind(str, Enum):
    """What a trace met on its way."""

    TURNING_POINT = "turning_point"  #: the drive reaches an extremum (d(drive)/ds changes sign)
    BRANCH_POINT = "branch_point"    #: the bordered Jacobian's determinant changes sign
    BIFURCATION = "bifurcation"      #: the trace left a singular state on a chosen branch
    #: a state of self-stress the motion relied on vanishes: an edge it made redundant would
    #: have to change length to go on, so the network locks there (a maker's pull stops)
    SELF_STRESS_LOST = "self_stress_lost"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class Event:
    """Something a trace met on its way, at one of its configurations.

    Made by :meth:`fabkit.kinematics.base.Problem.trajectory` from a method's :class:`Mark`, so
    the drive value and arclength are always those of the configuration at ``index``.

    Attributes
    ----------
    kind : EventKind
    index : int
        Index of the configuration in the trajectory at (or nearest to) the event.
    drive : float
        Drive value at that configuration.
    arclength : float
        Arclength at that configuration.
    detail : str
        A sentence that says what happened.
    """

    kind: EventKind
    index: int
    drive: float
    arclength: float
    detail: str = ""

    def __post_init__(self):
        object.__setattr__(self, "kind", EventKind(self.kind))  # unknown kinds raise ValueError
        if not (np.isfinite(self.drive) and np.isfinite(self.arclength)):
            raise ValueError(f"an event's drive and arclength must be finite, got {self.drive} "
                             f"and {self.arclength}")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Configurations along a one-parameter motion, as returned by :func:`fabkit.trace`.

    Attributes
    ----------
    network : Network
        The network traced (with any held ports added as virtual edges removed).
    positions : numpy.ndarray, shape (S, N, d)
        Node positions at each accepted step, in the gauge frame (the gauge edge held still).
        With ``keep`` other than ``"all"`` (see :func:`fabkit.trace`), only the configurations
        listed in ``kept`` (always the first and the last): shape (len(kept), N, d).
    drive : numpy.ndarray, shape (S,)
        Value of the driven distance at each step.
    arclength : numpy.ndarray, shape (S,)
        Arclength of the path in configuration space (design units), 0 at the start.
    edge_error : numpy.ndarray, shape (S,)
        Largest relative edge-length error ``max |l - L| / L`` at each step.
    method : str
        Name of the method that produced the trajectory.
    status : Status
        ``finished``, ``turning_point``, ``branch_point`` or ``failed``.
    message : str
        One sentence: where and why the trace ended.
    drive_port : tuple of int
        The node pair whose distance is the drive.
    target : float
        The drive value asked for.
    events : tuple of Event
    stats : dict
        Method-specific counters (steps, rejected steps, factorisations, ...).
    kept : numpy.ndarray of int or None
        Indices of the configurations held in ``positions``; None when every one is.
    port_values : Mapping of str to numpy.ndarray, or None
        With ``keep`` other than ``"all"``: the distance of every port of the network (or of the
        ports ``trace(..., ports=...)`` named) at every configuration, shape (S,) each (what
        :meth:`distance` reads for a port name).
    request : Mapping or None
        What :func:`fabkit.trace` was asked: ``drive``, ``to``, ``method``, ``hold`` and the
        method ``options`` as given (None for a trajectory made otherwise). A check that would
        trace a network again as it was traced reads here whether it was.
    """

    network: Network
    positions: np.ndarray
    drive: np.ndarray
    arclength: np.ndarray
    edge_error: np.ndarray
    method: str
    status: Status
    message: str
    drive_port: tuple[int, int]
    target: float
    events: tuple[Event, ...] = ()
    stats: dict = field(default_factory=dict)
    kept: np.ndarray | None = None
    port_values: Mapping | None = None
    request: Mapping | None = None

    def __post_init__(self):
        object.__setattr__(self, "status", expect(self.status, TRACE, "a trace"))

    @property
    def success(self) -> bool:
        """True when the trace reached its target."""
        return self.status is Status.FINISHED

    @property
    def n_steps(self) -> int:
        """Number of configurations S (also those whose positions were not kept)."""
        return int(self.drive.shape[0])

    @property
    def max_edge_error(self) -> float:
        """Largest relative edge-length error over the whole trajectory."""
        return float(self.edge_error.max()) if self.edge_error.size else 0.0

    @property
    def final(self) -> np.ndarray:
        """The last configuration, shape (N, d)."""
        return self.positions[-1]

    def distance(self, port) -> np.ndarray:
        """Distance of a port (name or node pair) at every step, shape (S,).

        Raises
        ------
        KinematicsError
            A node pair that is not a port, asked of a trace that kept only some positions.
        """
        if isinstance(port, str) and self.port_values is not None:
            self.network.port(port)  # an unknown name raises with the list of ports
            if port not in self.port_values:
                raise KinematicsError(
                    f"the trace kept the distances of {len(self.port_values)} ports (ports=...), "
                    f"not of {port}; trace with ports that include it")
            return self.port_values[port]
        i, j = self.network.port(port) if isinstance(port, str) else port
        if self.kept is not None:
            raise KinematicsError(
                f"the trace kept the positions of {len(self.kept)} of its {self.n_steps} "
                f"configurations (keep=...): the distance of nodes ({i}, {j}) is not known at "
                "the others; ask for a port by name, or trace with keep='all'")
        return np.linalg.norm(self.positions[:, i] - self.positions[:, j], axis=-1)

    def distances(self, names=None) -> dict[str, np.ndarray]:
        """Distances of several ports (all by default) along the trajectory."""
        names = list(self.network.ports) if names is None else list(names)
        return {n: self.distance(n) for n in names}

    def summary(self, *, status: str | None = None, message: str | None = None) -> str:
        """A few lines for a terminal.

        ``status`` and ``message`` stand in for the trace's own where a later judgement says
        more (a trace that finished while the design's ends were missed).
        """
        lines = [
            f"method        {self.method}",
            f"status        {status or self.status}: {message or self.message}",
            f"steps         {self.n_steps}",
            f"drive         {self.drive[0]:.10g} -> {self.drive[-1]:.10g} (target {self.target:.10g})",
            f"arclength     {self.arclength[-1]:.6g}",
            f"max edge err  {self.max_edge_error:.3e} (relative)",
        ]
        for ev in self.events:
            lines.append(f"event         {ev.kind} at drive {ev.drive:.10g}: {ev.detail}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (
            f"Trajectory(method={self.method!r}, status={self.status.value!r}, steps={self.n_steps}, "
            f"drive={self.drive[0]:.6g}->{self.drive[-1]:.6g}, max_edge_error={self.max_edge_error:.2e})"
        )
