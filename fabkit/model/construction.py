"""Construction orders: how a network is built node by node from two of its nodes.

Starting from a seed pair (a, b) every further node is placed from 2 (2D) or 3 (3D) already
placed neighbours whose distances to it are edge lengths, at an intersection of circles
(spheres). The order found here serves two purposes: constructive placement of a motion
(:mod:`fabkit.kinematics.constructive` places nodes along it for many drive values at once) and
exact mode counting (:mod:`fabkit.model.certificate` proves the counts from it). Both need
only the topology, the rest lengths and the reference configuration, so the order lives below
them.

A chain built by :func:`fabkit.chain` records how it was assembled (``Network.assembly``); its
order is its modules' orders one after the other (:func:`cached_plan`), with no search.
"""

from __future__ import annotations

import copy
import math
from collections import deque
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import ConstructionError, FlatStateError
from .network import Network
from ..numerics import FLAT_SIDE_SINE, TINY

__all__ = ["ConstructionPlan", "PartialConstruction", "plan_construction",
           "search_construction", "cached_plan", "edge_ids", "EdgeLookup", "SearchGraph"]

#: A node this close to the seed axis (relative to the network) lies on it and fixes no rotation.
ON_AXIS_RTOL = 1e-9

#: Relative tolerance of the radii a chain's plan takes from its modules' plans against the
#: chain's own bar lengths: a join moves a module rigidly, which changes lengths by round-off
#: (~1e-15) only, so 1e-9 tells a module that does not fit from one that does.
TILE_LENGTH_RTOL = 1e-9


@dataclass(frozen=True)
class ConstructionPlan:
    """Order and data of a construction by intersections.

    Attributes
    ----------
    dim : int
    seed : tuple of int
        The drive's node pair (a, b): a stays at its reference position, b moves along the
        reference direction from a.
    order : numpy.ndarray of int, shape (K,)
        Nodes in the order they are placed.
    parents : numpy.ndarray of int, shape (K, dim)
        Already placed nodes each is placed from (-1 for the free slot of the 3D gauge node).
    radii : numpy.ndarray, shape (K, dim)
        Edge lengths to the parents.
    signs : numpy.ndarray, shape (K,)
        Side of the parents' line (2D) or plane (3D) in the reference: +1 or -1 (0 for the 3D
        gauge node, which is placed in the half-plane it has in the reference).
    reference : numpy.ndarray, shape (N, dim)
    gauge_perp : numpy.ndarray, shape (dim,)
        3D only: unit vector fixing the rotation about the seed axis.
    parent_edges : numpy.ndarray of int, shape (K, dim), or None
        For every (placed node, parent) pair, the index of its edge in the network the plan
        was made for, where the planner knows it without a search (a chain's plan tiled from
        its modules' plans: each copy's bars are its module's, offset); None otherwise. A
        hint: :meth:`hinted_edges` checks it before anything relies on it.
    """

    dim: int
    seed: tuple[int, int]
    order: np.ndarray
    parents: np.ndarray
    radii: np.ndarray
    signs: np.ndarray
    reference: np.ndarray
    gauge_perp: np.ndarray
    parent_edges: np.ndarray | None = None

    @property
    def n_nodes(self) -> int:
        return int(self.reference.shape[0])

    def edge_index(self, net: Network) -> np.ndarray:
        """For every (placed node, parent) pair, the index of its edge in ``net``.

        Returns
        -------
        numpy.ndarray of int, shape (K, dim)
            -1 where a node has no parent in that slot (the 3D gauge node's free slot).
        """
        hinted = self.hinted_edges(net.edges)
        if hinted is not None:  # a tiled chain's plan: its edges known and checked
            idx = np.full(self.parents.shape, -1, dtype=np.int64)
            idx[self.parents >= 0] = hinted
            return idx
        lookup = {(min(i, j), max(i, j)): k for k, (i, j) in enumerate(net.edges.tolist())}
        idx = np.full(self.parents.shape, -1, dtype=np.int64)
        for row, (v, par) in enumerate(zip(self.order.tolist(), self.parents.tolist())):
            for c, p in enumerate(par):
                if p >= 0:
                    idx[row, c] = lookup[(min(v, p), max(v, p))]
        return idx

    def hinted_edges(self, edges: np.ndarray) -> np.ndarray | None:
        """:attr:`parent_edges` of the (placed node, parent) pairs row by row (the parents'
        slots that hold a parent), checked against ``edges``: None when there is no hint or
        one of its edges does not join its pair. Networks refuse duplicate bars, so a checked
        index is the only edge of its pair, as a search (:class:`EdgeLookup`) would find."""
        hint = self.parent_edges
        if hint is None or hint.shape != self.parents.shape:
            return None
        has = self.parents >= 0
        every = bool(has.all())
        ids = hint.reshape(-1) if every else hint[has]
        e = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
        if ids.size and (int(ids.min()) < 0 or int(ids.max()) >= e.shape[0]):
            return None
        child = np.repeat(self.order, has.shape[1]) if every else \
            np.broadcast_to(self.order[:, None], has.shape)[has]
        parent = self.parents.reshape(-1) if every else self.parents[has]
        # each hinted edge joins its node and that parent, in either order (a million-module
        # chain: 6·10⁶ pairs, one column at a time)
        flat = e.reshape(-1)
        at = ids * 2
        end0 = flat.take(at)
        at += 1
        end1 = flat.take(at)
        del at
        ok = (end0 == child) & (end1 == parent)
        ok |= (end0 == parent) & (end1 == child)
        return ids if bool(ok.all()) else None

    @cached_property
    def lists(self) -> tuple[list, list, list, list]:
        """The plan as plain Python lists, made once: the order, the parents and the squared
        radii per parent slot (a list per slot, not a list per node: a 100 000-module chain's
        300 000 small lists kept the garbage collector busy for longer than the conversion),
        and the signs. Placement loops over nodes read them element by element."""
        return (self.order.tolist(), self.parents.T.tolist(), (self.radii ** 2).T.tolist(),
                self.signs.tolist())

    @cached_property
    def run_table(self) -> np.ndarray:
        """Runs of consecutive placements with the same two parents (a module's two variable
        nodes), none a parent of another, placed together: rows (start, stop, p, q)."""
        par = self.parents
        m = par.shape[0]
        if m == 0:
            return np.zeros((0, 4), dtype=np.int64)
        same = (par[1:, 0] == par[:-1, 0]) & (par[1:, 1] == par[:-1, 1])
        starts = np.concatenate([[0], np.flatnonzero(~same) + 1])
        stops = np.concatenate([starts[1:], [m]])
        return np.column_stack([starts, stops, par[starts, 0], par[starts, 1]])

    @cached_property
    def runs(self) -> list[tuple[int, int, int, int]]:
        """:attr:`run_table` as a list of tuples (what the placement loop reads)."""
        return list(zip(*self.run_table.T.tolist()))


@dataclass(frozen=True)
class PartialConstruction:
    """What a search from a seed placed, when it may stop short of the whole network.

    Attributes
    ----------
    seed : tuple of int
    order, parents, radii, signs, gauge_perp
        As in :class:`ConstructionPlan`, for the nodes placed.
    placed : numpy.ndarray of bool, shape (N,)
        The seed's nodes and every node placed.
    """

    seed: tuple[int, int]
    order: np.ndarray
    parents: np.ndarray
    radii: np.ndarray
    signs: np.ndarray
    gauge_perp: np.ndarray
    placed: np.ndarray


class EdgeLookup:
    """Edge indices of node pairs, vectorised: the edge keys sorted once, then binary search.

    Examples
    --------
    >>> find = EdgeLookup(np.array([[0, 1], [2, 1]]), 3)
    >>> find([1, 1, 0], [0, 2, 2]).tolist()
    [0, 1, -1]
    """

    def __init__(self, edges: np.ndarray, n_nodes: int):
        self.edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
        self.n = int(n_nodes)

    @cached_property
    def _sorted(self) -> tuple[np.ndarray, np.ndarray]:
        """(edge order, sorted keys), sorted at the first question: a caller that never asks
        (a chain whose plan knows its edges) never pays for the sort."""
        e = self.edges
        keys = np.minimum(e[:, 0], e[:, 1]) * self.n + np.maximum(e[:, 0], e[:, 1])
        order = np.argsort(keys, kind="stable")
        return order, keys[order]

    def __call__(self, i, j) -> np.ndarray:
        """Indices of the edges joining ``i[k]`` and ``j[k]`` (either order), -1 where none."""
        i, j = np.broadcast_arrays(np.asarray(i, dtype=np.int64), np.asarray(j, dtype=np.int64))
        shape = i.shape
        order, keys = self._sorted
        if keys.size == 0:
            return np.full(shape, -1, dtype=np.int64)
        # flat, and in place where it can be: a million-module chain asks 6·10⁶ pairs at once,
        # and every temporary of that size is fresh memory
        i, j = i.reshape(-1), j.reshape(-1)
        want = np.minimum(i, j)
        want *= self.n
        want += np.maximum(i, j)
        pos = np.searchsorted(keys, want)
        np.minimum(pos, keys.size - 1, out=pos)
        missing = keys.take(pos) != want
        del want
        out = order.take(pos)
        out[missing] = -1
        return out.reshape(shape)


def edge_ids(edges: np.ndarray, n_nodes: int, i, j) -> np.ndarray:
    """Indices of the edges joining nodes ``i[k]`` and ``j[k]`` (either order); -1 where no edge
    joins them (one :class:`EdgeLookup`; build that once to ask many times).

    Examples
    --------
    >>> edge_ids(np.array([[0, 1], [2, 1]]), 3, [1, 1, 0], [0, 2, 2]).tolist()
    [0, 1, -1]
    """
    return EdgeLookup(edges, n_nodes)(i, j)


class SearchGraph:
    """A network's configuration and adjacency as plain Python lists, made once for many
    searches (:func:`search_construction` runs once per part when a network is cut into
    parts); ``free`` marks the edges a search may use (all at first)."""

    def __init__(self, x, edges: np.ndarray, lengths: np.ndarray):
        self.x = np.asarray(x, dtype=np.float64)
        self.xl = self.x.tolist()
        self.lengths = np.asarray(lengths, dtype=np.float64).tolist()
        n = self.x.shape[0]
        self.adj: list[list[tuple[int, int]]] = [[] for _ in range(n)]
        for k, (i, j) in enumerate(np.asarray(edges).tolist()):
            self.adj[i].append((j, k))
            self.adj[j].append((i, k))
        self.free = [True] * len(self.lengths)


def search_construction(x, edges: np.ndarray, lengths: np.ndarray, seed, *, size: float,
                        allowed=None, partial: bool = False, min_sine: float = FLAT_SIDE_SINE,
                        graph: SearchGraph | None = None) -> PartialConstruction:
    """Place nodes one by one from a seed pair, each from its best-conditioned placed neighbours.

    A node is placed once it has 2 (2D) or 3 (3D) placed neighbours; of those it takes the pair
    (triple) whose directions from it are the most independent (largest sine, or largest
    determinant of unit vectors). In 3D the first node off the seed axis is placed from 2
    neighbours and fixes the rotation about the axis.

    Parameters
    ----------
    x : array_like, shape (N, d)
        Configuration that decides the sides (and the conditioning) of the intersections.
    edges : numpy.ndarray of int, shape (E, 2)
    lengths : numpy.ndarray, shape (E,)
        Rest lengths (the radii of the intersections).
    seed : (int, int)
    size : float
        Extent of the network (scale of the on-axis test in 3D).
    allowed : array_like of bool, shape (E,), optional
        Edges the construction may use (all by default; ``graph.free`` with a ``graph``).
    partial : bool
        Stop quietly where no further node can be placed: nodes whose best intersection is
        flatter than ``min_sine`` wait for another neighbour, and nodes never reached stay
        unplaced. Without it, the search raises.
    min_sine : float
        Smallest sine (2D) or determinant of unit vectors (3D) of an intersection.
    graph : SearchGraph, optional
        ``x``, ``edges`` and ``lengths`` already as lists (for many searches on one network).

    Returns
    -------
    PartialConstruction

    Raises
    ------
    FlatStateError
        Not ``partial``: a node's best intersection is flatter than ``min_sine``.
    ConstructionError
        Not ``partial``: some nodes cannot be reached.
    """
    if graph is None:
        graph = SearchGraph(x, edges, lengths)
    x = graph.x
    n, d = x.shape
    a, b = (int(v) for v in seed)
    # plain Python lists: this loop runs once per node and numpy scalar access would dominate
    ok = graph.free if allowed is None else np.asarray(allowed, dtype=bool).tolist()
    adj, xl, lengths_l = graph.adj, graph.xl, graph.lengths

    def nbrs(v):
        return [w for w, k in adj[v] if ok[k]]

    placed = [False] * n
    placed[a] = placed[b] = True
    count = [0] * n
    for s in (a, b):
        for v in nbrs(s):
            count[v] += 1
    gauge_done = d == 2  # in 3D the first node after the seed fixes the rotation about a-b
    queue: deque[int] = deque(v for v in sorted(set(nbrs(a)) | set(nbrs(b)))
                              if not placed[v] and count[v] >= 2)
    queued = [False] * n
    for v in queue:
        queued[v] = True
    order, parents, radii, signs = [], [], [], []
    gauge_perp = np.zeros(d)
    u_seed = (x[b] - x[a]) / np.linalg.norm(x[b] - x[a])

    def sine(v, p, q):
        xv, yv = xl[v][0], xl[v][1]
        ax_, ay_ = xl[p][0] - xv, xl[p][1] - yv
        bx_, by_ = xl[q][0] - xv, xl[q][1] - yv
        return abs(ax_ * by_ - ay_ * bx_) / math.sqrt((ax_ * ax_ + ay_ * ay_)
                                                      * (bx_ * bx_ + by_ * by_))

    while queue:
        v = queue.popleft()
        queued[v] = False
        if placed[v]:
            continue
        links = [(p, k) for p, k in adj[v] if ok[k] and placed[p]]
        cand = [p for p, _ in links]
        radius = {p: lengths_l[k] for p, k in links}
        if d == 2:
            best, best_sin = None, -1.0
            for ii in range(len(cand)):
                for jj in range(ii + 1, len(cand)):
                    s = sine(v, cand[ii], cand[jj])
                    if s > best_sin:
                        best, best_sin = (cand[ii], cand[jj]), s
            p, q = best
            if best_sin < min_sine:
                if partial:
                    continue  # waits for another placed neighbour
                raise FlatStateError(
                    f"node {v} is collinear with nodes {p} and {q} in the start configuration: a flat "
                    "state, where the side of the intersection (and so the branch) is undetermined",
                    v, (p, q))
            side = ((xl[q][0] - xl[p][0]) * (xl[v][1] - xl[p][1])
                    - (xl[q][1] - xl[p][1]) * (xl[v][0] - xl[p][0]))
            order.append(v)
            parents.append((p, q))
            radii.append((radius[p], radius[q]))
            signs.append(1.0 if side > 0 else -1.0)
        elif not gauge_done:
            off = x[v] - x[a]
            perp = off - (off @ u_seed) * u_seed
            if np.linalg.norm(perp) <= ON_AXIS_RTOL * max(size, TINY):
                continue  # on the seed axis: fixes no rotation; placed later from 3 parents
            p, q = cand[0], cand[1]
            if partial:
                dp, dq = x[p] - x[v], x[q] - x[v]
                if (np.linalg.norm(np.cross(dp, dq)) < min_sine * np.linalg.norm(dp)
                        * np.linalg.norm(dq)):
                    continue
            gauge_perp = perp / np.linalg.norm(perp)
            order.append(v)
            parents.append((p, q, -1))
            radii.append((radius[p], radius[q], 0.0))
            signs.append(0.0)
            gauge_done = True
        else:
            if len(cand) < 3:
                continue  # queued again when a third neighbour is placed
            best, best_score = None, -1.0
            for i1 in range(len(cand)):
                for i2 in range(i1 + 1, len(cand)):
                    for i3 in range(i2 + 1, len(cand)):
                        p1, p2, p3 = cand[i1], cand[i2], cand[i3]
                        m = np.stack([x[p1] - x[v], x[p2] - x[v], x[p3] - x[v]])
                        m = m / np.linalg.norm(m, axis=1, keepdims=True)
                        score = abs(np.linalg.det(m))
                        if score > best_score:
                            best, best_score = (p1, p2, p3), score
            p1, p2, p3 = best
            ez = np.cross(x[p2] - x[p1], x[p3] - x[p1])
            nz = np.linalg.norm(ez)
            side = (x[v] - x[p1]) @ ez / (nz * np.linalg.norm(x[v] - x[p1])) if nz > 0 else 0.0
            if abs(side) < min_sine:
                if partial:
                    continue
                raise FlatStateError(
                    f"node {v} lies in the plane of nodes {p1}, {p2} and {p3} in the start "
                    "configuration: a flat state, where the side of the intersection (and so the "
                    "branch) is undetermined", v, (p1, p2, p3))
            order.append(v)
            parents.append((p1, p2, p3))
            radii.append((radius[p1], radius[p2], radius[p3]))
            signs.append(np.sign(side))
        placed[v] = True
        need = 2 if gauge_done is False or d == 2 else 3
        near = nbrs(v)
        for w in near:
            if not placed[w]:
                count[w] += 1
        # every unplaced node with enough placed neighbours gets (another) turn: after the 3D
        # gauge node, those of all three placed nodes (only they can have 3 placed neighbours)
        turn = (sorted(set(nbrs(a)) | set(nbrs(b)) | set(near))
                if (d == 3 and len(order) == 1) else near)
        for w in turn:
            if not placed[w] and not queued[w] and count[w] >= need:
                queue.append(w)
                queued[w] = True
    if not partial:
        missing = np.flatnonzero(~np.array(placed))
        if missing.size:
            shown = ", ".join(str(int(m)) for m in missing[:8]) + (" ..." if missing.size > 8
                                                                   else "")
            raise ConstructionError(
                f"no construction order from the drive pair ({a}, {b}): node(s) {shown} cannot "
                f"be placed from {d} already placed neighbours; use method='projected'"
            )
    return PartialConstruction(
        seed=(a, b),
        order=np.array(order, dtype=np.int64),
        parents=np.array(parents, dtype=np.int64).reshape(len(order), d),
        radii=np.array(radii, dtype=np.float64).reshape(len(order), d),
        signs=np.array(signs, dtype=np.float64),
        gauge_perp=gauge_perp,
        placed=np.array(placed, dtype=bool),
    )


def plan_construction(net: Network, drive: tuple[int, int], reference=None) -> ConstructionPlan:
    """Find an order that places every node by intersections, starting from the drive pair.

    Parameters
    ----------
    net : Network
        Topology and rest lengths.
    drive : (int, int)
        The seed pair.
    reference : array_like, shape (N, d), optional
        Configuration that decides the side of every intersection (``net.nodes`` by default).

    Returns
    -------
    ConstructionPlan

    Raises
    ------
    ConstructionError
        When some nodes cannot be reached (no construction order for this drive), or when a node
        of the reference lies on the line/plane of its parents (a flat state: its side, and so
        the branch, is undetermined).

    Examples
    --------
    >>> fourbar = Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]])
    >>> plan_construction(fourbar, (0, 1)).order.tolist()
    [2, 3]
    """
    x = net.nodes if reference is None else np.asarray(reference, dtype=np.float64)
    found = search_construction(x, net.edges, net.edge_lengths, drive, size=net.size)
    return ConstructionPlan(dim=x.shape[1], seed=found.seed, order=found.order,
                            parents=found.parents, radii=found.radii, signs=found.signs,
                            reference=np.array(x), gauge_perp=found.gauge_perp)


def cached_plan(net: Network, drive: tuple[int, int], reference=None) -> ConstructionPlan:
    """:func:`plan_construction`, remembered on the network for its reference configuration.

    The plan depends only on the topology, the rest lengths, the drive pair and the sides of the
    reference configuration, so tracing the same network again (other targets, repeats) skips
    the search. Other reference configurations are planned afresh.
    """
    if reference is not None and reference is not net.nodes and not np.array_equal(reference, net.nodes):
        return plan_construction(net, drive, reference)
    key = ("construction_plan", tuple(int(v) for v in drive))
    cache = net._cache
    if key not in cache:
        try:
            cache[key] = _tiled_chain_plan(net, drive) or plan_construction(net, drive)
        except ConstructionError as exc:
            cache[key] = exc
    found = cache[key]
    if isinstance(found, ConstructionError):
        raise copy.copy(found)  # a fresh exception per call: the cached one keeps no traceback
    return found


def _tiled_chain_plan(net: Network, drive) -> ConstructionPlan | None:
    """A chain's plan assembled from its modules' plans (2D chains built by fabkit.chain).

    Each module's plan starts from its input pair, which is the previous module's output pair,
    so the chain's plan is the modules' plans one after the other, renumbered. Sides are read
    off the chain's own reference configuration (vectorised), and the result is checked (every
    node placed once, parents placed before, radii equal to the edge lengths); None whenever
    anything does not fit, and the node-by-node search runs instead.
    """
    layout = net.assembly
    if layout is None or net.dim != 2 or net.ports.get("d1") != tuple(drive):
        return None
    # the copies of each distinct module at once (one array of their node indices per kind):
    # a 1 000 000-module chain has one or two kinds
    plans: list[ConstructionPlan] = []
    for module in layout.modules:
        try:
            mp = cached_plan(module, module.port(layout.d_in))
        except ConstructionError:
            return None
        if mp.seed != module.port(layout.d_in):
            return None
        plans.append(mp)
    sizes = np.array([mp.order.size for mp in plans], dtype=np.int64)[layout.kind]
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    total = int(sizes.sum())
    order = np.empty(total, dtype=np.int64)
    par = np.empty((total, 2), dtype=np.int64)
    rad = np.empty((total, 2))
    # fabkit.chain lays each copy's bars out as its module's, after the earlier copies' bars:
    # the edge of a placement is its module's edge, offset (a hint, checked where it is used)
    bars = np.array([m.n_edges for m in layout.modules], dtype=np.int64)[layout.kind]
    bar_starts = np.concatenate([[0], np.cumsum(bars)[:-1]])
    hinted = int(bars.sum()) == net.n_edges
    pedge = np.empty((total, 2), dtype=np.int64) if hinted else None
    for q, mp in enumerate(plans):
        members = np.flatnonzero(layout.kind == q)
        index = layout.index[q]  # (copies, module nodes)
        # one kind of module: its copies fill the plan in order (a slice, not a scatter)
        at = slice(None) if members.size == layout.kind.size else \
            (starts[members][:, None] + np.arange(mp.order.size)).ravel()
        order[at] = index[:, mp.order].ravel()
        par[at] = index[:, mp.parents].reshape(-1, 2)
        rad[at] = np.broadcast_to(mp.radii, (len(members),) + mp.radii.shape).reshape(-1, 2)
        if pedge is not None:
            module = layout.modules[q]
            local = EdgeLookup(module.edges, module.n_nodes)(mp.order[:, None], mp.parents)
            if np.any(local < 0):
                pedge = None
            else:
                pedge[at] = (bar_starts[members][:, None, None] + local).reshape(-1, 2)
    n = net.n_nodes
    a, b = drive
    step = np.full(n, -1, dtype=np.int64)
    step[[a, b]] = 0
    if order.size != n - 2 or np.any(step[order] == 0):
        return None
    step[order] = np.arange(1, order.size + 1)
    # Node and parent columns one at a time (a million-module chain: 3·10⁶ rows, 24 MB a
    # column): the same operations on the same numbers as on pairs of columns, so the same
    # bits, without gathering and reducing (N, 2) temporaries (the plan of a 10⁶-module chain
    # took 0.31-0.34 s of user time instead of 0.44).
    p0, p1 = np.ascontiguousarray(par[:, 0]), np.ascontiguousarray(par[:, 1])
    placed = step.take(order)
    for p in (p0, p1):
        at_parent = step.take(p)
        if np.any(at_parent < 0) or np.any(at_parent >= placed):
            return None  # a parent placed after its child (or never)
    del placed, at_parent
    x = net.nodes
    cx, cy = np.ascontiguousarray(x[:, 0]), np.ascontiguousarray(x[:, 1])
    ox, oy = cx.take(order), cy.take(order)
    ax, ay = cx.take(p0), cy.take(p0)
    vx, vy = ox - ax, oy - ay  # node from its first parent
    r0 = np.sqrt(vx * vx + vy * vy)
    wx, wy = ox - cx.take(p1), oy - cy.take(p1)  # node from its second parent
    del ox, oy
    r1 = np.sqrt(wx * wx + wy * wy)
    del wx, wy
    # |measured - designed| <= rtol·|designed| for every radius: np.allclose's test (atol 0) on
    # finite numbers, without its temporaries
    for col, r in enumerate((r0, r1)):
        off = np.abs(r - rad[:, col])
        if not np.all(off <= TILE_LENGTH_RTOL * np.abs(rad[:, col])):
            return None
    # the chain's own rest lengths (its joins carry their own round-off)
    rad[:, 0], rad[:, 1] = r0, r1
    qx, qy = cx.take(p1) - ax, cy.take(p1) - ay  # second parent from the first
    del ax, ay
    cross = qx * vy - qy * vx
    norm = np.sqrt(qx * qx + qy * qy)
    norm *= r0
    if np.any(np.abs(cross) < FLAT_SIDE_SINE * norm):
        return None  # a flat reference: let the search raise its precise error
    if pedge is not None:
        pedge.setflags(write=False)  # a caller reads the checked hint as its own, not a copy
    return ConstructionPlan(dim=2, seed=(int(a), int(b)), order=order, parents=par, radii=rad,
                            signs=np.where(cross > 0, 1.0, -1.0),
                            # the network's own nodes where they are read-only (a copy of 48 MB
                            # for a million modules otherwise)
                            reference=x if not x.flags.writeable else np.array(x),
                            gauge_perp=np.zeros(2), parent_edges=pedge)
