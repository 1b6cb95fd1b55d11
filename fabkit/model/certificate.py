"""Mode counts proved from how a network is built: the structural certificate of count_modes.

A construction order (:mod:`fabkit.model.construction`) places every node from d already placed
neighbours (2D: two, 3D: three; the first 3D node off the seed axis from two). Order the rows of
the rigidity matrix R by placement (the d bars of each node) and the columns by node: the rows the
construction uses form a block lower-triangular matrix whose diagonal blocks are the d × d
matrices of the placed node's bar directions. A block is non-singular exactly when its bars meet
transversally (2D: the sine of the angle between the two bars is non-zero; 3D: the determinant
of the unit bar directions). So, with every intersection transversal:

- the used rows are independent, their null space has dimension ``d·(seed) + gauge`` = 4 in 2D
  (7 in 3D): the rigid motions and one conformational motion, the drive; a seed joined by a bar
  leaves the rigid motions only (3, 6);
- every further bar ("extra") either keeps its length along that one motion (its row lies in the
  span of the used rows: a state of self-stress) or it does not (it removes the motion; the other
  extra bars then add a self-stress each).

The counts follow with no rank decision on R at all: ``M = null - s``, ``S = E_extra - s`` with
s ∈ {0, 1}. The certificate's margin is the smallest sine (determinant) of an intersection; it
is accepted above :data:`MIN_SINE`, the edge of the numeric rule's ambiguous band, so a
configuration that is nearly flat is not given an exact count that means little. Whether an
extra bar keeps its length is read from the construction's velocity (a sparse unit-triangular
solve, the same block structure): its rate of change relative to the relative speed of its two
ends, decided by the numeric rule's threshold and band (a local, well-scaled question).

Where the whole network has no such order, it is cut into parts that have one (a greedy search:
each part grows from a seed over the bars no earlier part took), each part's motions are known
exactly as above (its rigid motions and, if its seed is free, its construction velocity), and
the network's zero modes are the part motions that agree on shared nodes and keep the leftover
bars: a small interface matrix, column-scaled, whose rank is decided by a dense SVD with the
numeric rule. That is the ``"substructure"`` certificate.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from .construction import (ConstructionPlan, EdgeLookup, PartialConstruction, SearchGraph,
                           cached_plan, plan_construction, search_construction)
from ..errors import ConstructionError
from .network import ChainPorts, Network
from ..numerics import RANK_RTOL, TINY, row_norms
from .matrix import AMBIGUOUS_GAP, rank_dense, rigid_body_basis, rigid_body_count

__all__ = ["Certificate", "certify", "construction_velocity", "intersection_sines", "MIN_SINE",
           "Uncertified"]

#: Smallest intersection sine (3D: determinant of unit bar directions) a structural certificate
#: accepts: the edge of the numeric rule's ambiguous band (√AMBIGUOUS_GAP × RANK_RTOL ≈ 3e-8). The
#: proof holds above round-off (~1e-15), but a count of a configuration that close to flat
#: describes a network one nudge away from another count; it is left to the numeric rule, which
#: says so.
MIN_SINE = math.sqrt(AMBIGUOUS_GAP) * RANK_RTOL

#: Construction orders of the whole network tried from this many seeds (the first ports and the
#: last) before the network is cut into parts.
MAX_SEEDS = 3

#: Largest interface (columns: 3-7 per part, d per node in no part) decided by a dense SVD; a
#: network that falls into more pieces is counted numerically.
MAX_INTERFACE = 600

#: A relative speed of an extra bar's two ends below this fraction of the fastest node's speed
#: is measured against that floor: the rate of such a bar is at round-off.
SPEED_FLOOR = 1e-12


class Uncertified(Exception):
    """No structural certificate: the reason, one sentence."""


@dataclass(frozen=True)
class Certificate:
    """Counts proved from a construction order (or from parts that have one).

    Attributes
    ----------
    kind : str
        ``"structure"`` (one construction places every node) or ``"substructure"``.
    total : int
        Zero modes M (with the rigid motions).
    self_stress : int
        States of self-stress S.
    margin : float
        Smallest intersection sine (3D: determinant of unit bar directions) of the construction.
    detail : str
        One sentence: seeds, parts, extra bars and how they were decided.
    """

    kind: str
    total: int
    self_stress: int
    margin: float
    detail: str


def _unit(vec) -> np.ndarray:
    """Unit vectors along the last axis (a zero vector stays zero)."""
    norm = row_norms(vec)
    return vec / np.where(norm > 0, norm, 1.0)[..., None]


def intersection_sines(x, order, parents) -> np.ndarray:
    """Sine of each placement's intersection: 2D, of the angle between the node's two bars;
    3D, the determinant of its three unit bar directions (two for the gauge node, whose sine is
    used).

    Examples
    --------
    >>> x = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.0]])
    >>> intersection_sines(x, np.array([2]), np.array([[0, 1]])).round(12).tolist()
    [1.0]
    """
    x = np.asarray(x, dtype=np.float64)
    order = np.asarray(order, dtype=np.int64)
    parents = np.asarray(parents, dtype=np.int64)
    if order.size == 0:
        return np.zeros(0)
    d = x.shape[1]
    at = np.where(parents >= 0, parents, order[:, None])
    if d == 2:
        # coordinate by coordinate, in place: the operations of the unit-vector formula below
        # (row_norms' sums, the same divisions and products), so the same bits, without its
        # (N, 2) temporaries (a million-module chain's plan has 3·10⁶ rows)
        cx, cy = np.ascontiguousarray(x[:, 0]), np.ascontiguousarray(x[:, 1])
        ox, oy = cx.take(order), cy.take(order)

        def unit(k):
            p = np.ascontiguousarray(at[:, k])
            ux, uy = cx.take(p), cy.take(p)
            ux -= ox
            uy -= oy
            norm = ux * ux
            norm += uy * uy
            np.sqrt(norm, out=norm)
            np.copyto(norm, 1.0, where=~(norm > 0))  # a bar of no length stays zero
            ux /= norm
            uy /= norm
            return ux, uy

        u0x, u0y = unit(0)
        u1x, u1y = unit(1)
        u0x *= u1y
        u0y *= u1x
        u0x -= u0y
        return np.abs(u0x, out=u0x)
    unit = _unit(x[at] - x[order][:, None, :])
    out = np.abs(np.linalg.det(unit))
    gauge = parents[:, 2] < 0
    if gauge.any():
        out[gauge] = np.linalg.norm(np.cross(unit[gauge, 0], unit[gauge, 1]), axis=1)
    return out


def construction_velocity(x, seed, order, parents) -> np.ndarray:
    """The velocity of the construction's motion: the seed's first node still, its second moving
    away at unit speed, every placed node keeping its bars to its parents (3D: the gauge node
    not turning about the seed axis).

    One sparse solve: each placement's block row multiplied by the inverse of its bar directions
    is ``v_node - Σ M_k v_parent_k = 0``, so in placement order the system is unit lower
    triangular.

    Returns
    -------
    numpy.ndarray, shape (N, d)
        Zero at nodes the construction does not place.
    """
    x = np.asarray(x, dtype=np.float64)
    n, d = x.shape
    a, b = (int(v) for v in seed)
    order = np.asarray(order, dtype=np.int64)
    parents = np.asarray(parents, dtype=np.int64)
    k = order.size
    pos = np.full(n, -1, dtype=np.int64)
    pos[a], pos[b] = 0, 1
    pos[order] = 2 + np.arange(k)
    m = d * (k + 2)
    rhs = np.zeros(m)
    u = x[b] - x[a]
    rhs[d:2 * d] = u / np.linalg.norm(u)
    rows, cols, vals = [np.arange(m)], [np.arange(m)], [np.ones(m)]
    if k:
        has = parents >= 0
        dvec = x[order][:, None, :] - x[np.where(has, parents, order[:, None])]  # (k, d, d)
        blocks = dvec.copy()
        gauge = ~has.all(axis=1)
        if gauge.any():  # 3D gauge node: no turn about the seed axis (normal of its plane)
            nrm = np.cross(dvec[gauge, 0], dvec[gauge, 1])
            blocks[gauge, 2] = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
        inv = np.linalg.inv(blocks)  # (k, d, d): v_node = Σ_c inv[:, :, c] (dvec_c · v_parent_c)
        for c in range(d):
            ok = np.flatnonzero(has[:, c])
            if not ok.size:
                continue
            coef = -inv[ok, :, c][:, :, None] * dvec[ok, c][:, None, :]  # (.., i, j)
            r = d * pos[order[ok]][:, None, None] + np.arange(d)[None, :, None]
            q = d * pos[parents[ok, c]][:, None, None] + np.arange(d)[None, None, :]
            rows.append(np.broadcast_to(r, coef.shape).ravel())
            cols.append(np.broadcast_to(q, coef.shape).ravel())
            vals.append(coef.ravel())
    import scipy.sparse as sp  # here, not at the top: the command line starts without scipy
    import scipy.sparse.linalg as spla

    mat = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                        shape=(m, m))
    sol = spla.spsolve_triangular(mat, rhs, lower=True, unit_diagonal=True)
    v = np.zeros((n, d))
    placed = pos >= 0
    v[placed] = sol.reshape(k + 2, d)[pos[placed]]
    return v


@dataclass
class _Part:
    """One piece of the network with a construction order of its own."""

    seed: tuple[int, int]
    bar: bool               # the seed's nodes are joined by a bar: the part is rigid
    order: np.ndarray
    parents: np.ndarray
    used: np.ndarray        # edge ids used by the construction (with the seed bar)
    extra: np.ndarray       # further edges between the part's nodes
    margin: float
    moves: bool = True      # False when rigid (a bar seed, or an extra bar that removes the motion)
    velocity: np.ndarray | None = None
    note: str = ""

    @property
    def nodes(self) -> np.ndarray:
        return np.concatenate([np.array(self.seed, dtype=np.int64), self.order])


def _decide_extras(part: _Part, x, edges, rtol: float) -> None:
    """Whether the part keeps its motion: every extra bar keeps its length along it (each is a
    self-stress), or one of them does not (the part is rigid). Sets ``moves``, ``velocity``,
    ``note``; raises :class:`Uncertified` when a rate lies in the ambiguous band."""
    if part.bar:
        part.moves = False
        return
    if not part.extra.size:
        return
    v = construction_velocity(x, part.seed, part.order, part.parents)
    i, j = edges[part.extra, 0], edges[part.extra, 1]
    dv = v[i] - v[j]
    dx = x[i] - x[j]
    speed = np.linalg.norm(dv, axis=1)
    top = float(np.max(np.linalg.norm(v, axis=1)))
    if not (np.isfinite(dv).all() and np.isfinite(top)):
        raise Uncertified("the construction's velocity overflows (a strongly amplifying chain), "
                          "so its extra bars cannot be told apart")
    rate = np.abs(np.einsum("ij,ij->i", dx, dv)) / np.linalg.norm(dx, axis=1) / np.maximum(
        speed, max(SPEED_FLOOR * top, TINY))
    worst = float(rate.max())
    band = math.sqrt(AMBIGUOUS_GAP)
    if worst >= band * rtol:
        k = int(part.extra[int(np.argmax(rate))])
        part.moves = False
        part.note = (f"bar {k} ({edges[k, 0]}, {edges[k, 1]}) changes length along the "
                     f"construction's motion (relative rate {worst:.1e}): it locks the motion")
    elif worst <= rtol / band:
        part.velocity = v
        part.note = (f"{part.extra.size} extra bar(s) keep their length along the motion "
                     f"(relative rate at most {worst:.1e})")
    else:
        raise Uncertified(f"an extra bar changes length at a relative rate of {worst:.1e}, "
                          f"within a factor {band:.0f} of the threshold {rtol:.0e}")


def _part_from(found, x, edges, find: EdgeLookup, taken, bar: bool,
               used: np.ndarray | None = None) -> _Part:
    """A part from a construction found over the edges not ``taken``; ``used``: the edges of
    its (node, parent) pairs row by row, when already known (checked, see
    :meth:`ConstructionPlan.hinted_edges`), else looked up."""
    n = x.shape[0]
    order, parents = found.order, found.parents
    if used is None:
        has = parents >= 0
        used = find(np.broadcast_to(order[:, None], parents.shape)[has], parents[has])
    if bar:
        used = np.concatenate([find([found.seed[0]], [found.seed[1]]), used])
    inside = np.zeros(n, dtype=bool)
    inside[list(found.seed)] = True
    inside[order] = True
    free = ~taken
    free[used] = False
    extra = np.flatnonzero(free & inside[edges[:, 0]] & inside[edges[:, 1]])
    sines = intersection_sines(x, order, parents)
    margin = float(sines.min()) if sines.size else math.inf
    return _Part(found.seed, bar, order, parents, used, extra, margin)


def _seeds(net: Network, x):
    """Seed pairs, best first: the ports, then two neighbours of each node, then every bar."""
    edges = net.edges
    n = net.n_nodes
    for pair in net.ports.values():
        yield (int(pair[0]), int(pair[1]))
    first = np.full(n, -1, dtype=np.int64)
    second = np.full(n, -1, dtype=np.int64)
    for col, other in ((0, 1), (1, 0)):  # the first two neighbours of each node, by edge order
        for k, v in enumerate(edges[:, col].tolist()):
            w = int(edges[k, other])
            if first[v] < 0:
                first[v] = w
            elif second[v] < 0 and w != first[v]:
                second[v] = w
    for v in range(n):
        if second[v] >= 0:
            yield (int(first[v]), int(second[v]))
    for i, j in edges.tolist():
        yield (i, j)


def _last(mapping):
    """The last key of a mapping (a dict's by insertion; a chain's ports without a walk)."""
    if isinstance(mapping, ChainPorts):
        return f"d{len(mapping)}"
    return next(reversed(mapping))


def _joined(edges: np.ndarray, a: int, b: int) -> bool:
    """Whether a bar joins nodes a and b (a scan: no lookup table is built for one pair)."""
    e0, e1 = edges[:, 0], edges[:, 1]
    return bool(np.any(((e0 == a) & (e1 == b)) | ((e0 == b) & (e1 == a))))


def _whole(net: Network, x, positions_given: bool, find: EdgeLookup):
    """A construction of the whole network from one of the first seeds, or the reason none."""
    edges = net.edges
    n = net.n_nodes
    reasons = []
    tried = 0
    # the first ports, and the last: a chain whose modules are built backwards (from d2 to d1)
    # has an order from its last port only (a million-port chain is not listed for that)
    names = list(itertools.islice(net.ports, MAX_SEEDS - 1))
    if len(net.ports) >= MAX_SEEDS:
        names.append(_last(net.ports))
    ports = [net.ports[p] for p in names]
    for seed in ports:
        if tried >= MAX_SEEDS:
            break
        seed = (int(seed[0]), int(seed[1]))
        if _joined(edges, *seed):
            continue  # a port on a bar: not a seed of a motion
        tried += 1
        try:
            plan: ConstructionPlan = (plan_construction(net, seed, x) if positions_given
                                      else cached_plan(net, seed))
        except ConstructionError as exc:
            reasons.append(str(exc))
            continue
        found = PartialConstruction(seed=plan.seed, order=plan.order, parents=plan.parents,
                                    radii=plan.radii, signs=plan.signs,
                                    gauge_perp=plan.gauge_perp, placed=np.ones(n, dtype=bool))
        part = _part_from(found, x, edges, find, np.zeros(edges.shape[0], dtype=bool), bar=False,
                          used=plan.hinted_edges(edges))
        if part.margin < MIN_SINE:
            reasons.append(f"from {seed} the flattest intersection has a sine of "
                           f"{part.margin:.1e}, below {MIN_SINE:.1e}")
            continue
        return part, reasons
    return None, reasons


def _interface(parts: list[_Part], x, edges, taken, n) -> tuple[np.ndarray, int]:
    """The interface matrix: the parts' motions (rigid, and the construction velocity where the
    part moves) and the nodes in no part as unknowns; rows for nodes shared by parts (they move
    together) and for the bars no part took (they keep their length)."""
    d = x.shape[1]
    owner: list[list[int]] = [[] for _ in range(n)]
    first_col, bases, rows_of = [], [], []
    ncol = 0
    for p, part in enumerate(parts):
        nodes = part.nodes
        basis = rigid_body_basis(x[nodes])  # (d·|nodes|, 3 or 6; 5 for a 3D bar)
        if part.moves and not part.bar:
            if part.velocity is None:
                part.velocity = construction_velocity(x, part.seed, part.order, part.parents)
            basis = np.column_stack([basis, part.velocity[nodes].ravel()])
        local = np.full(n, -1, dtype=np.int64)
        local[nodes] = np.arange(nodes.size)
        first_col.append(ncol)
        bases.append(basis)
        rows_of.append(local)
        for v in nodes.tolist():
            owner[v].append(p)
        ncol += basis.shape[1]
    free_col = np.full(n, -1, dtype=np.int64)
    loose = np.flatnonzero(np.array([not o for o in owner]))
    free_col[loose] = ncol + d * np.arange(loose.size)
    ncol += d * loose.size

    def motion(v: int, p: int | None = None):
        """(d × columns of node v's velocity, first column)."""
        if p is None:
            if not owner[v]:
                return np.eye(d), int(free_col[v])
            p = owner[v][0]
        k = rows_of[p][v]
        return bases[p][d * k:d * k + d], first_col[p]

    rows = []
    for v in range(n):
        if len(owner[v]) < 2:
            continue
        b0, c0 = motion(v)
        for p in owner[v][1:]:
            row = np.zeros((d, ncol))
            row[:, c0:c0 + b0.shape[1]] += b0
            b1, c1 = motion(v, p)
            row[:, c1:c1 + b1.shape[1]] -= b1
            rows.append(row)
    for k in np.flatnonzero(~taken).tolist():
        i, j = int(edges[k, 0]), int(edges[k, 1])
        u = x[i] - x[j]
        u = u / np.linalg.norm(u)
        row = np.zeros((1, ncol))
        bi, ci = motion(i)
        bj, cj = motion(j)
        row[0, ci:ci + bi.shape[1]] += u @ bi
        row[0, cj:cj + bj.shape[1]] -= u @ bj
        rows.append(row)
    mat = np.vstack(rows) if rows else np.zeros((0, ncol))
    norms = np.linalg.norm(mat, axis=0)
    mat = mat / np.where(norms > 0, norms, 1.0)  # column scaling: the rank does not change
    return mat, ncol


def _substructure(net: Network, x, rtol: float, find: EdgeLookup):
    edges = net.edges
    n, d = x.shape
    e = edges.shape[0]
    taken = np.zeros(e, dtype=bool)
    left = np.bincount(edges.ravel(), minlength=n)  # edges not yet taken, per node
    graph = SearchGraph(x, edges, net.edge_lengths)
    parts: list[_Part] = []
    columns = 0
    for seed in _seeds(net, x):
        if not left.any():
            break
        a, b = seed
        if a == b or (left[a] == 0 and left[b] == 0):
            continue
        bar_id = int(find([a], [b])[0])
        bar = bar_id >= 0
        if bar and taken[bar_id]:
            continue
        if bar:
            graph.free[bar_id] = False
        found = search_construction(x, edges, net.edge_lengths, seed, size=net.size,
                                    partial=True, min_sine=MIN_SINE, graph=graph)
        if not found.order.size and not bar:
            continue
        part = _part_from(found, x, edges, find, taken, bar)
        _decide_extras(part, x, edges, rtol)
        taken[part.used] = True
        taken[part.extra] = True
        for k in np.concatenate([part.used, part.extra]).tolist():
            graph.free[k] = False
        np.subtract.at(left, edges[part.used].ravel(), 1)
        np.subtract.at(left, edges[part.extra].ravel(), 1)
        parts.append(part)
        columns += d * (d + 1) // 2 + (1 if part.moves and not part.bar else 0)
        if columns > MAX_INTERFACE:
            raise Uncertified(f"the network falls into more than {len(parts)} parts with "
                              "construction orders of their own")
    if len(parts) == 1 and parts[0].nodes.size == n and taken.all():
        return parts, None
    mat, ncol = _interface(parts, x, edges, taken, n)
    if ncol > MAX_INTERFACE:
        raise Uncertified(f"the interface between {len(parts)} parts has {ncol} unknowns, more "
                          f"than {MAX_INTERFACE}")
    if mat.shape[0]:
        import scipy.sparse as sp

        rank, gap, smallest, note = rank_dense(sp.csr_matrix(mat), rtol)
        if note or gap < AMBIGUOUS_GAP:
            raise Uncertified(f"the interface between {len(parts)} parts is near singular "
                              f"({note or f'rank gap {gap:.1e}'})")
    else:
        rank, gap = 0, math.inf
    return parts, (ncol - rank, ncol, mat.shape[0], gap)


def _count(part: _Part, x) -> tuple[int, int]:
    """(zero modes, self-stresses) of a part that is the whole network."""
    rigid = rigid_body_count(x) if x.shape[1] == 3 else 3
    null = rigid + (0 if part.bar else 1)
    locked = 1 if (not part.bar and not part.moves) else 0
    return null - locked, part.extra.size - locked


def certify(net: Network, positions=None, *, rtol: float = RANK_RTOL) -> Certificate:
    """Prove the zero modes and states of self-stress of a network from its construction.

    Parameters
    ----------
    net : Network
    positions : array_like, shape (N, d), optional
        Configuration to count at; the reference configuration by default (where construction
        plans are cached on the network).
    rtol : float
        Threshold of the decisions that remain numeric: whether an extra bar keeps its length
        along the motion, and the rank of the interface between parts.

    Returns
    -------
    Certificate

    Raises
    ------
    Uncertified
        No construction order and no cut into constructible parts decides the count (a
        construction too close to flat, an extra bar or an interface in the ambiguous band, a
        network of too many pieces). The numeric rank then decides.

    Examples
    --------
    >>> fourbar = Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]],
    ...                   ports={"d1": (0, 1)})
    >>> c = certify(fourbar)
    >>> c.kind, c.total, c.self_stress, round(c.margin, 6)
    ('structure', 4, 0, 0.707107)
    """
    given = positions is not None and not (positions is net.nodes
                                           or np.array_equal(positions, net.nodes))
    x = np.asarray(positions, dtype=np.float64) if given else net.nodes
    n, d = x.shape
    edges = net.edges
    if net.n_edges == 0:
        raise Uncertified("the network has no bars")
    find = EdgeLookup(edges, n)
    part, reasons = _whole(net, x, given, find)
    if part is not None:
        _decide_extras(part, x, edges, rtol)
        total, stress = _count(part, x)
        name = next((k for k, v in net.ports.items() if tuple(v) == part.seed),
                    f"nodes {part.seed}")
        extra = f"; {part.note}" if part.note else "; no extra bars"
        return Certificate("structure", total, stress, part.margin,
                           f"every node placed by transversal intersections from {name}{extra}")
    try:
        parts, interface = _substructure(net, x, rtol, find)
    except Uncertified as exc:
        if not reasons:
            raise
        raise Uncertified(f"{reasons[0]}; cut into parts: {exc}") from None
    margin = min(p.margin for p in parts)
    if interface is None:
        total, stress = _count(parts[0], x)
        seed = parts[0].seed
        how = "a bar" if parts[0].bar else "a free pair"
        extra = f"; {parts[0].note}" if parts[0].note else ""
        return Certificate("structure", total, stress, margin,
                           f"every node placed by transversal intersections from {how} "
                           f"{seed}{extra}")
    total, ncol, nrow, gap = interface
    stress = total - (d * n - net.n_edges)
    if stress < 0:
        raise Uncertified(f"the parts' count ({total} zero modes) contradicts dN - E = "
                          f"{d * n - net.n_edges}")
    sizes = sorted((p.nodes.size for p in parts), reverse=True)
    shown = ", ".join(str(s) for s in sizes[:6]) + (" ..." if len(sizes) > 6 else "")
    locked = sum(1 for p in parts if p.note and not p.moves)
    detail = (f"{len(parts)} parts with construction orders ({shown} nodes), joined by an "
              f"interface of {nrow} equations in {ncol} unknowns (rank gap "
              f"{gap:.1e})" + (f"; {locked} part(s) locked by extra bars" if locked else ""))
    return Certificate("substructure", total, stress, margin, detail)
