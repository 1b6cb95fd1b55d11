"""What a trace keeps of its configurations (``trace(..., keep=...)``), the rest streamed.

A trace of a 100 000-module chain has 300 000 nodes; its 101 configurations weigh about 0.5 GB,
while a caller often wants only the ports (the map d₁ → d₂ → …) and the end state. So the
configurations are reduced as they are made:

- ``keep="all"`` (the default): every configuration (``Trajectory.positions`` of shape (S, N, d)).
- ``keep="ports"``: at every configuration the drive, the arclength, the edge error and the
  distance of every port (``Trajectory.port_values``); positions of the first and the last only.
- ``keep=k`` (an integer ≥ 1): as ``"ports"``, and the positions of every k-th configuration.

With ``"ports"`` or ``k``, ``trace(..., ports=[...])`` keeps the distances of the ports named
only: a million-module chain's million ports at 101 configurations weigh 0.8 GB, its two ends
nothing. The distances are held as one array, a row per port (:class:`PortValues`), not as a
dict of a million arrays.

:class:`Recorder` takes configurations one at a time (step-by-step methods); constructive
placement reduces its columns of configurations itself (:mod:`.constructive`); both give a
:class:`Record`, from which :meth:`~.base.Problem.trajectory_of` builds the Trajectory.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import KinematicsError
from ..model.network import ChainPorts
from ..numerics import apply_fit, rigid_fit

__all__ = ["Record", "Recorder", "PortValues", "keep_rule", "kept_indices", "port_table",
           "record_positions", "edge_errors"]


def keep_rule(keep) -> str | int:
    """Check a ``keep`` argument: ``"all"``, ``"ports"`` or a positive integer (every k-th).

    Raises
    ------
    KinematicsError
        Anything else, with the valid values.

    Examples
    --------
    >>> keep_rule("ports"), keep_rule(10)
    ('ports', 10)
    """
    if isinstance(keep, str):
        if keep in ("all", "ports"):
            return keep
    elif isinstance(keep, (int, np.integer)) and not isinstance(keep, bool) and keep >= 1:
        return int(keep)
    raise KinematicsError(f"`keep` must be 'all', 'ports' or a positive integer (every k-th "
                          f"configuration), got {keep!r}")


def kept_indices(n: int, rule) -> np.ndarray:
    """Indices of the configurations whose positions a rule keeps out of ``n``: always the
    first and the last."""
    if n <= 0:
        return np.zeros(0, dtype=np.int64)
    if rule == "all":
        return np.arange(n)
    step = n if rule == "ports" else int(rule)
    return np.union1d(np.arange(0, n, step), [n - 1]).astype(np.int64)


def port_table(network, names=None) -> tuple:
    """The ports whose distances a trace keeps and their node pairs.

    Parameters
    ----------
    network : Network
    names : sequence of str or None
        Port names (None: every port of the network).

    Returns
    -------
    names : ChainPorts or tuple of str
        A chain's own port table when every port of a chain is kept (no million names made).
    pairs : numpy.ndarray of int, shape (P, 2)
    """
    ports = network.ports
    if names is None:
        if isinstance(ports, ChainPorts):
            return ports, ports.pairs
        names = list(ports)
    names = tuple(names)
    pairs = np.array([ports[n] for n in names], dtype=np.int64).reshape(len(names), 2)
    return names, pairs


class PortValues(Mapping):
    """The distances of some ports at every configuration of a trace: a mapping of port name to
    an array of shape (S,), held as one array with a row per port.

    Parameters
    ----------
    names : ChainPorts or sequence of str
        The ports, in the order of the rows.
    values : numpy.ndarray, shape (P, S)

    Examples
    --------
    >>> v = PortValues(("d1", "d2"), np.array([[1.0, 1.5], [2.0, 2.5]]))
    >>> v["d2"].tolist(), list(v), len(v)
    ([2.0, 2.5], ['d1', 'd2'], 2)
    """

    __slots__ = ("names", "values", "_rows")

    def __init__(self, names, values):
        self.names = names
        self.values = values
        self._rows = None if isinstance(names, ChainPorts) else \
            {n: i for i, n in enumerate(names)}

    def _row(self, name) -> int:
        if self._rows is None:
            return self.names.row(name)
        return self._rows.get(name, -1)

    def __getitem__(self, name) -> np.ndarray:
        i = self._row(name)
        if i < 0:
            raise KeyError(name)
        return self.values[i]

    def __contains__(self, name) -> bool:
        return self._row(name) >= 0

    def __iter__(self):
        return iter(self.names)

    def __len__(self) -> int:
        return int(self.values.shape[0])

    def __repr__(self) -> str:
        return f"PortValues({len(self)} ports x {self.values.shape[1]} configurations)"


@dataclass(frozen=True, eq=False)
class Record:
    """Configurations reduced to what a trace keeps.

    Attributes
    ----------
    positions : numpy.ndarray, shape (len(kept), N, d)
        In the gauge frame.
    kept : numpy.ndarray of int or None
        Indices of the configurations in ``positions``; None when every one is there.
    drive, arclength, edge_error : numpy.ndarray, shape (S,)
    ports : PortValues or None
        The kept ports' distances at every configuration (None with ``keep="all"``).
    """

    positions: np.ndarray
    kept: np.ndarray | None
    drive: np.ndarray
    arclength: np.ndarray
    edge_error: np.ndarray
    ports: dict | None


#: Edge lengths per block when edge errors of many configurations are measured: a few MB at a
#: time instead of one temporary of configurations × edges (1 GB for 101 configurations of a
#: 100 000-module chain), which made the measuring cost more than the tracing.
BLOCK_LENGTHS = 1 << 18


def edge_errors(net, positions) -> np.ndarray:
    """``net.edge_error`` of configurations (S, N, d), a block of configurations at a time
    (the sums of squares written out: numpy's reduction over an axis of 2 or 3 is slower)."""
    pos = np.asarray(positions, dtype=np.float64)
    if net.n_edges == 0:
        return np.zeros(len(pos))
    i = np.ascontiguousarray(net.edges[:, 0])
    j = np.ascontiguousarray(net.edges[:, 1])
    rest = net.edge_lengths
    out = np.empty(len(pos))
    step = max(1, BLOCK_LENGTHS // net.n_edges)
    planar = pos.shape[-1] == 2
    if planar:  # a node as one complex number: one gather per edge end (3x faster)
        z = np.ascontiguousarray(pos).reshape(len(pos), -1).view(np.complex128)
    for lo in range(0, len(pos), step):
        if planar:
            dz = z[lo:lo + step].take(i, axis=1)
            dz -= z[lo:lo + step].take(j, axis=1)
            parts = dz.view(np.float64)
            diff = parts.reshape(parts.shape[0], -1, 2)
        else:
            diff = pos[lo:lo + step, i] - pos[lo:lo + step, j]
        sq = diff[..., 0] * diff[..., 0]
        for c in range(1, diff.shape[-1]):
            sq += diff[..., c] * diff[..., c]
        np.sqrt(sq, out=sq)
        sq /= rest
        sq -= 1.0
        np.abs(sq, out=sq)
        out[lo:lo + step] = sq.max(axis=-1)
    return out


def record_positions(problem, positions, arclength=None) -> Record:
    """A Record of configurations given all at once, shape (S, N, d), in the gauge frame."""
    pos = np.ascontiguousarray(positions, dtype=np.float64)
    s = len(pos)
    if arclength is None:
        steps = np.linalg.norm((pos[1:] - pos[:-1]).reshape(s - 1, pos[0].size), axis=1)
        arclength = np.concatenate([[0.0], np.cumsum(steps)])
    drive = problem.drive_of(pos)
    err = edge_errors(problem.network, pos)
    rule = problem.keep
    if rule == "all":
        return Record(pos, None, drive, np.asarray(arclength, dtype=np.float64), err, None)
    names, pairs = port_table(problem.network, problem.ports)
    dist = np.linalg.norm(pos[:, pairs[:, 0]] - pos[:, pairs[:, 1]], axis=-1)
    kept = kept_indices(s, rule)
    return Record(pos[kept], kept, drive, np.asarray(arclength, dtype=np.float64), err,
                  PortValues(names, np.ascontiguousarray(dist.T)))


class Recorder:
    """Configurations one at a time, reduced to what ``problem.keep`` asks for.

    Parameters
    ----------
    problem : Problem
    aligned : bool
        True when the configurations come in the gauge frame already; else each is moved
        there (a rigid fit on the gauge nodes, as :func:`~.base.align_to_gauge` does).
    """

    def __init__(self, problem, *, aligned: bool):
        self.problem = problem
        self.aligned = aligned
        self.names, self.pairs = port_table(problem.network, problem.ports)
        self.every = None if problem.keep == "ports" else int(problem.keep)
        self.ref = problem.start[list(problem.gauge)]
        self.kept, self.positions = [], []
        self.drive, self.arclength, self.error, self.ports = [], [], [], []
        self.last = None

    def add(self, x, aligned: bool | None = None) -> None:
        """One more configuration (flat or (N, d)); ``aligned`` overrides the recorder's
        setting for this one (a method may change its gauge along the way)."""
        p = self.problem
        y = np.asarray(x, dtype=np.float64).reshape(p.start.shape)
        if not (self.aligned if aligned is None else aligned):
            g = list(p.gauge)
            y = apply_fit(rigid_fit(y[None, g], self.ref), y[None])[0]
        i = len(self.drive)
        step = 0.0 if self.last is None else float(np.linalg.norm((y - self.last).ravel()))
        self.arclength.append(step + (self.arclength[-1] if self.arclength else 0.0))
        self.drive.append(float(p.drive_of(y)))
        self.error.append(float(p.network.edge_error(y)))
        self.ports.append(np.linalg.norm(y[self.pairs[:, 0]] - y[self.pairs[:, 1]], axis=-1))
        if i == 0 or (self.every is not None and i % self.every == 0):
            self.kept.append(i)
            self.positions.append(y)
        self.last = y

    def finish(self) -> Record:
        """The Record of every configuration added (the last one's positions kept)."""
        n = len(self.drive)
        if n and (not self.kept or self.kept[-1] != n - 1):
            self.kept.append(n - 1)
            self.positions.append(self.last)
        ports = np.array(self.ports).reshape(n, len(self.pairs))
        return Record(np.array(self.positions), np.array(self.kept, dtype=np.int64),
                      np.array(self.drive), np.array(self.arclength), np.array(self.error),
                      PortValues(self.names, np.ascontiguousarray(ports.T)))
