"""The bar-and-joint network: node coordinates, edges and named node pairs ("ports").

A :class:`Network` is immutable and does no I/O. Everything else in fabkit (rigidity, motion,
maps, fabrication) derives from it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import cached_property
from collections.abc import Mapping

import numpy as np

from ..errors import ArgumentTypeError, NetworkError

__all__ = ["Network", "Assembly", "checked_network", "chain_port_number", "is_chain_port"]

#: A chain's ports: ``d`` and a number in ASCII digits (d1, d2, ...). Only ASCII: ``str.isdigit``
#: and ``\d`` also take other scripts' digits and signs such as "²", which ``int`` refuses: a
#: port named "d²" is a port like any other, not a place along a chain.
CHAIN_PORT = re.compile(r"d([0-9]+)")


def chain_port_number(name) -> int | None:
    """The number of a chain's port (``"d12"`` -> 12), None for any other name.

    Examples
    --------
    >>> chain_port_number("d12"), chain_port_number("d1_b"), chain_port_number("d²")
    (12, None, None)
    """
    m = CHAIN_PORT.fullmatch(name) if isinstance(name, str) else None
    return int(m.group(1)) if m else None


def is_chain_port(name) -> bool:
    """True for a chain's port, ``d`` and a number (:func:`chain_port_number`)."""
    return chain_port_number(name) is not None

# Edges shorter than this fraction of the network's size are treated as zero-length.
_ZERO_LENGTH_RTOL = 1e-12
#: Coordinates beyond this (design units) are refused: their squares (every length, every
#: rigidity row) would overflow or drown the rest of the network in round-off.
MAX_COORDINATE = 1e9


class ChainPorts(Mapping):
    """A chain's ports ``d1 … d{k+1}`` held as one array of node pairs: a mapping like any
    ports dict (``ports["d7"]``, iteration in order, ``len``, ``in``), without a million names
    and tuples for a million-module chain.

    Parameters
    ----------
    pairs : array_like of int, shape (k + 1, 2)
        ``pairs[i]`` is port ``d{i+1}``.

    Examples
    --------
    >>> p = ChainPorts([[0, 1], [2, 3], [4, 5]])
    >>> p["d2"], list(p), "d4" in p, dict(p) == {"d1": (0, 1), "d2": (2, 3), "d3": (4, 5)}
    ((2, 3), ['d1', 'd2', 'd3'], False, True)
    """

    __slots__ = ("pairs",)

    def __init__(self, pairs):
        arr = np.array(pairs, dtype=np.int64, copy=True).reshape(-1, 2)
        arr.setflags(write=False)
        self.pairs = arr

    def row(self, name) -> int:
        """The row of ``pairs`` that holds a port, -1 for a name that is not one of them."""
        if is_chain_port(name) and name[1] != "0":
            i = chain_port_number(name) - 1
            if i < self.pairs.shape[0]:
                return i
        return -1

    def __getitem__(self, name):
        i = self.row(name)
        if i < 0:
            raise KeyError(name)
        a, b = self.pairs[i]
        return (int(a), int(b))

    def __contains__(self, name) -> bool:
        return self.row(name) >= 0

    def __iter__(self):
        return (f"d{i}" for i in range(1, self.pairs.shape[0] + 1))

    def __len__(self) -> int:
        return int(self.pairs.shape[0])

    def __reduce__(self):
        return (ChainPorts, (self.pairs,))

    def __repr__(self) -> str:
        return f"ChainPorts(d1..d{len(self)})"


def _checked_ports(given, n_nodes: int):
    """Every port as ``name -> (int, int)``, checked: a chain's :class:`ChainPorts` at once on
    its array, a dict of integer pairs at once as one array, else one by one (which names the
    bad one)."""
    if isinstance(given, ChainPorts):
        arr = given.pairs
        if bool(((arr >= 0) & (arr < n_nodes)).all()) and bool((arr[:, 0] != arr[:, 1]).all()):
            return given
        given = dict(given)  # one by one: the message names the port
    names = [str(k) for k in given]
    pairs = list(given.values())
    if pairs and all(type(p) is tuple and len(p) == 2 for p in pairs):
        arr = np.asarray(pairs)
        if arr.dtype.kind in "iu" and arr.shape == (len(pairs), 2) and \
                bool(((arr >= 0) & (arr < n_nodes)).all()) and bool((arr[:, 0] != arr[:, 1]).all()):
            return dict(zip(names, map(tuple, arr.tolist())))
    return {str(name): _as_port(name, pair, n_nodes) for name, pair in dict(given).items()}


def _refuse_duplicate_edges(edges, n: int) -> None:
    """Raise NetworkError naming the first two edges that join the same nodes (its temporaries,
    four integers per edge, freed on return: a million-module chain's build peaked on them)."""
    lo, hi = np.minimum(edges[:, 0], edges[:, 1]), np.maximum(edges[:, 0], edges[:, 1])
    # one integer per unordered pair: sorting a million of them is cheap, unlike rows
    code = lo * np.int64(n) + hi
    del lo, hi
    ordered = np.sort(code)
    same = ordered[1:] == ordered[:-1]
    if same.any():
        dup = ordered[1:][same][0]
        dup_key = (int(dup // n), int(dup % n))
        where = np.flatnonzero(code == dup)
        raise NetworkError(
            f"edges {where[0]} and {where[1]} both join nodes {dup_key[0]} and {dup_key[1]}",
            f"edges[{where[0]}]"
        )


def _edge_lengths(nodes, edges) -> np.ndarray:
    """The edges' lengths, as ``np.linalg.norm`` of the differences gives them, bit for bit
    (squared in place: one temporary of the differences, not two; the squares added column by
    column, as numpy adds two or three numbers, without its slow reduction over a short axis)."""
    diff = nodes[edges[:, 0]]
    diff -= nodes[edges[:, 1]]
    np.multiply(diff, diff, out=diff)
    if diff.shape[1] not in (2, 3):
        return np.sqrt(np.add.reduce(diff, axis=1))
    out = np.add(diff[:, 0], diff[:, 1])
    if diff.shape[1] == 3:
        out += diff[:, 2]
    return np.sqrt(out, out=out)


def _extent(nodes) -> float:
    """The largest extent of the nodes along a coordinate axis, ``max(ptp(nodes, axis=0))``
    (column by column: a strided reduction over a million rows is twenty times slower)."""
    return max((float(np.ptp(nodes[:, k])) for k in range(nodes.shape[1])), default=0.0)


def _as_port(name: str, pair, n_nodes: int) -> tuple[int, int]:
    try:
        i, j = (int(v) for v in pair)
        if any(float(v) != int(v) for v in pair):
            raise ValueError
    except (TypeError, ValueError):
        raise NetworkError(f"port {name!r} must be a pair of node indices, got {pair!r}",
                           f"ports.{name}") from None
    for v in (i, j):
        if not 0 <= v < n_nodes:
            raise NetworkError(
                f"port {name!r} names node {v}, but the network has nodes 0..{n_nodes - 1}",
                f"ports.{name}"
            )
    if i == j:
        raise NetworkError(f"port {name!r} joins node {i} to itself", f"ports.{name}")
    return (i, j)


@dataclass(frozen=True, eq=False)
class Assembly:
    """How a network was assembled from modules, as :func:`fabkit.chain` records it.

    Structure-aware algorithms read it instead of rediscovering it (e.g. a chain's construction
    plan is its modules' plans one after the other); each checks that it still fits the network's
    geometry before using it. It is held as arrays, one row per copy of each distinct module, so
    that a chain of a million modules costs a few arrays, not a million objects.

    Attributes
    ----------
    modules : tuple of Network
        The distinct modules (by identity).
    kind : numpy.ndarray of int, shape (k,)
        Per copy, in chain order: which of ``modules`` it is.
    index : tuple of numpy.ndarray of int
        Per distinct module, shape (its copies, its nodes): where each node of each of its
        copies went in the assembled network, the copies in chain order.
    mirrored : numpy.ndarray of bool, shape (k,)
        Per copy: placed as a mirror image.
    d_in : str
        The module port driven by the previous module's output (the chain's input port name).
    """

    modules: tuple
    kind: np.ndarray
    index: tuple
    mirrored: np.ndarray
    d_in: str

    @classmethod
    def from_copies(cls, copies, d_in: str) -> "Assembly":
        """From one ``(module, node indices, mirrored)`` per copy, in chain order."""
        modules, kind, rows = [], [], {}
        for module, idx, _flag in copies:
            for q, known in enumerate(modules):
                if known is module:
                    break
            else:
                q = len(modules)
                modules.append(module)
                rows[q] = []
            kind.append(q)
            rows[q].append(np.asarray(idx, dtype=np.int64))
        index = tuple(np.stack(rows[q]) if rows[q] else np.zeros((0, m.n_nodes), dtype=np.int64)
                      for q, m in enumerate(modules))
        return cls(tuple(modules), np.asarray(kind, dtype=np.int64), index,
                   np.array([bool(f) for _, _, f in copies], dtype=bool), d_in)

    @property
    def count(self) -> int:
        """How many modules (copies) the network was assembled from."""
        return int(self.kind.size)

    @cached_property
    def copies(self) -> tuple:
        """Per copy, in chain order: ``(module, its nodes' indices, mirrored)`` (made on first
        use: one object per module)."""
        rank = np.zeros(self.kind.size, dtype=np.int64)
        for q in range(len(self.modules)):
            members = np.flatnonzero(self.kind == q)
            rank[members] = np.arange(members.size)
        return tuple((self.modules[q], self.index[q][r], bool(f))
                     for q, r, f in zip(self.kind.tolist(), rank.tolist(),
                                        self.mirrored.tolist()))


@dataclass(frozen=True, eq=False)
class Network:
    """A network of rigid edges (bars) joined at nodes (pin joints).

    Parameters
    ----------
    nodes : array_like, shape (N, d)
        Node coordinates in design units, d = 2 or 3.
    edges : array_like of int, shape (E, 2)
        Pairs of node indices joined by a rigid edge.
    ports : mapping of str to (int, int), optional
        Named node pairs whose distances are read or driven, e.g. ``{"d1": (0, 1)}``.
    labels : sequence of str, optional
        One label per node (for plots and reports).
    assembly : Assembly, optional
        How the network was assembled from modules (set by :func:`fabkit.chain`).

    Raises
    ------
    NetworkError
        Non-finite coordinates, wrong shapes, indices out of range, self-loops, duplicate edges or
        zero-length edges; the message names the node or edge.

    Examples
    --------
    >>> net = Network([[0, 0], [1, 0], [0, 1]], [[0, 1], [1, 2], [2, 0]], ports={"a": (0, 1)})
    >>> net.dim, net.n_nodes, net.n_edges
    (2, 3, 3)
    >>> float(net.port_distance("a"))
    1.0
    """

    nodes: np.ndarray
    edges: np.ndarray
    ports: Mapping[str, tuple[int, int]] = field(default_factory=dict)
    labels: tuple[str, ...] | None = None
    assembly: Assembly | None = None

    def __post_init__(self):
        try:
            complex_ = np.asarray(self.nodes).dtype.kind == "c"
            nodes = np.array(np.real(self.nodes) if complex_ else self.nodes, dtype=np.float64,
                             copy=True)
        except (TypeError, ValueError):
            raise NetworkError("`nodes` must be an array of coordinates, shape (N, 2) or (N, 3) "
                               f"(got {type(self.nodes).__name__} that is not one)",
                               "nodes") from None
        if complex_:  # float64 keeps the real part alone
            raise NetworkError("`nodes` must be real coordinates, shape (N, 2) or (N, 3) (got "
                               "complex numbers: give x and y as two columns)", "nodes")
        if nodes.ndim != 2 or nodes.shape[1] not in (2, 3):
            raise NetworkError(f"`nodes` must have shape (N, 2) or (N, 3), got {nodes.shape}",
                               "nodes")
        if nodes.shape[0] < 2:
            raise NetworkError(f"a network needs at least 2 nodes, got {nodes.shape[0]}", "nodes")
        # each check over the whole array first, rows only to name the first bad one
        if not np.isfinite(nodes).all():
            bad = ~np.isfinite(nodes).all(axis=1)
            i = int(np.flatnonzero(bad)[0])
            raise NetworkError(f"node {i} has a non-finite coordinate {nodes[i].tolist()}",
                               f"nodes[{i}]")
        if (np.abs(nodes) > MAX_COORDINATE).any():
            far = (np.abs(nodes) > MAX_COORDINATE).any(axis=1)
            i = int(np.flatnonzero(far)[0])
            raise NetworkError(f"node {i} lies at {nodes[i].tolist()}, beyond ±{MAX_COORDINATE:g} "
                               "design units (lengths squared would overflow); scale the "
                               "design down", f"nodes[{i}]")
        try:
            raw_edges = np.asarray(self.edges)
        except (TypeError, ValueError):
            raise NetworkError("`edges` must be an array of node-index pairs, shape (E, 2)",
                               "edges") from None
        if raw_edges.size == 0:
            raw_edges = raw_edges.reshape(0, 2)
        if raw_edges.ndim != 2 or raw_edges.shape[1] != 2:
            raise NetworkError(f"`edges` must have shape (E, 2), got {raw_edges.shape}", "edges")
        if raw_edges.dtype.kind == "f":
            frac = raw_edges != np.round(raw_edges)
            if frac.any():
                k = int(np.flatnonzero(frac.any(axis=1))[0])
                raise NetworkError(f"edge {k} has a non-integer node index {raw_edges[k].tolist()}",
                                   f"edges[{k}]")
        elif raw_edges.dtype.kind not in "iu":
            raise NetworkError("`edges` must hold integer node indices, got dtype "
                               f"{raw_edges.dtype}",
                               "edges")
        edges = raw_edges.astype(np.int64)
        n = nodes.shape[0]
        if edges.size and (edges.min() < 0 or edges.max() >= n):
            out = (edges < 0) | (edges >= n)
            k = int(np.flatnonzero(out.any(axis=1))[0])
            raise NetworkError(
                f"edge {k} {edges[k].tolist()} names a node outside 0..{n - 1}", f"edges[{k}]"
            )
        loops = edges[:, 0] == edges[:, 1]
        if loops.any():
            k = int(np.flatnonzero(loops)[0])
            raise NetworkError(f"edge {k} joins node {edges[k, 0]} to itself", f"edges[{k}]")
        _refuse_duplicate_edges(edges, n)
        lengths = _edge_lengths(nodes, edges)
        scale = _extent(nodes) or 1.0
        short = lengths <= _ZERO_LENGTH_RTOL * scale
        if short.any():
            k = int(np.flatnonzero(short)[0])
            raise NetworkError(
                f"edge {k} {edges[k].tolist()} has zero length: nodes {edges[k, 0]} and "
                f"{edges[k, 1]} coincide", f"edges[{k}]"
            )
        if not isinstance(self.ports, Mapping):
            raise NetworkError("`ports` must be a mapping of name to (i, j) node pair, got "
                               f"{type(self.ports).__name__}", "ports")
        ports = _checked_ports(self.ports, n)
        labels = None
        if self.labels is not None:
            labels = tuple(str(s) for s in self.labels)
            if len(labels) != n:
                raise NetworkError(f"`labels` must have one entry per node ({n}), got "
                                   f"{len(labels)}",
                                   "labels")
        if self.assembly is not None and not isinstance(self.assembly, Assembly):
            raise NetworkError(f"`assembly` must be a fabkit.model.network.Assembly or None, got "
                               f"{type(self.assembly).__name__}")
        nodes.setflags(write=False)
        edges.setflags(write=False)
        lengths.setflags(write=False)
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "edges", edges)
        object.__setattr__(self, "ports", ports)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "_lengths", lengths)
        # derived data that is costly to recompute (e.g. construction plans); the network is
        # immutable, so entries never go stale
        object.__setattr__(self, "_cache", {})

    # -- sizes ---------------------------------------------------------------------------------
    @property
    def dim(self) -> int:
        """Spatial dimension d (2 or 3)."""
        return int(self.nodes.shape[1])

    @property
    def n_nodes(self) -> int:
        """Number of nodes N."""
        return int(self.nodes.shape[0])

    @property
    def n_edges(self) -> int:
        """Number of edges E."""
        return int(self.edges.shape[0])

    @property
    def size(self) -> float:
        """Largest extent of the node set along a coordinate axis (design units)."""
        return _extent(self.nodes)

    # -- geometry ------------------------------------------------------------------------------
    @property
    def edge_lengths(self) -> np.ndarray:
        """Rest lengths of the edges in the reference configuration, shape (E,)."""
        return self._lengths

    def lengths_at(self, positions) -> np.ndarray:
        """Edge lengths of a configuration.

        Parameters
        ----------
        positions : array_like, shape (N, d) or (S, N, d)
            One configuration or a stack of S configurations.

        Returns
        -------
        numpy.ndarray, shape (E,) or (S, E)
        """
        x = np.asarray(positions, dtype=np.float64)
        i, j = self.edges[:, 0], self.edges[:, 1]
        return np.linalg.norm(x[..., i, :] - x[..., j, :], axis=-1)

    def edge_error(self, positions) -> np.ndarray:
        """Largest relative edge-length error ``max_e |l_e(x) - L_e| / L_e`` of configurations.

        Parameters
        ----------
        positions : array_like, shape (N, d) or (S, N, d)

        Returns
        -------
        float or numpy.ndarray of shape (S,)
        """
        if self.n_edges == 0:
            x = np.asarray(positions)
            return np.zeros(x.shape[:-2]) if x.ndim == 3 else 0.0
        rel = np.abs(self.lengths_at(positions) / self._lengths - 1.0)
        return rel.max(axis=-1)

    def port(self, name: str) -> tuple[int, int]:
        """The node pair of a named port.

        Raises
        ------
        KeyError
            With the list of known port names.
        """
        try:
            return self.ports[name]
        except KeyError:
            known = ", ".join(sorted(self.ports)) or "none"
            raise KeyError(f"unknown port {name!r}; this network has ports: {known}") from None

    def port_distance(self, name: str, positions=None) -> np.ndarray:
        """Distance between the two nodes of a port.

        Parameters
        ----------
        name : str
            Port name, e.g. ``"d1"``.
        positions : array_like, shape (N, d) or (S, N, d), optional
            Configurations; the reference configuration by default.

        Returns
        -------
        float or numpy.ndarray of shape (S,)
        """
        i, j = self.port(name)
        x = self.nodes if positions is None else np.asarray(positions, dtype=np.float64)
        return np.linalg.norm(x[..., i, :] - x[..., j, :], axis=-1)

    def port_distances(self, positions=None) -> dict[str, np.ndarray]:
        """Distances of every port, as a dict name → value (or array over configurations)."""
        return {name: self.port_distance(name, positions) for name in self.ports}

    # -- derived networks ----------------------------------------------------------------------
    def with_nodes(self, nodes) -> "Network":
        """The same topology and ports with other reference coordinates (lengths re-measured)."""
        return Network(nodes, self.edges, self.ports, self.labels)

    def with_ports(self, ports: Mapping[str, tuple[int, int]]) -> "Network":
        """The same network with other named ports (and the same assembly record)."""
        return Network(self.nodes, self.edges, ports, self.labels, self.assembly)

    def adjacency(self) -> list[list[int]]:
        """Neighbour lists, one per node."""
        nbrs: list[list[int]] = [[] for _ in range(self.n_nodes)]
        for i, j in self.edges.tolist():
            nbrs[i].append(j)
            nbrs[j].append(i)
        return nbrs

    def __repr__(self) -> str:
        ports = ", ".join(f"{k}={v}" for k, v in self.ports.items())
        return f"Network(dim={self.dim}, nodes={self.n_nodes}, edges={self.n_edges}, ports=[{ports}])"


def checked_network(name: str, value) -> Network:
    """``value`` when it is a :class:`Network`; else an
    :class:`~fabkit.errors.ArgumentTypeError` naming the argument ``name``."""
    if not isinstance(value, Network):
        kind = "None" if value is None else type(value).__name__
        raise ArgumentTypeError(name, f"must be a fabkit.Network, got {kind}")
    return value
