"""Constructive placement: nodes placed one by one by circle (2D) or sphere (3D) intersections.

Starting from the two nodes of the drive, every further node is placed from 2 (2D) or 3 (3D)
already placed neighbours whose distances to it are edge lengths. Of the two intersection points
the one on the same side as in the reference configuration is taken, so the construction follows
the branch of the reference. Exact to round-off; the motion ends where an intersection vanishes
(a node becomes collinear/coplanar with its parents: a flat state, where the drive turns back).
"""

from __future__ import annotations

import copy
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from ..errors import ConstructionError, FlatStateError, KinematicsError
from ..network import Network
from ..numerics import FLAT_RTOL, TINY
from .base import Mark, Method, Outcome
from .trajectory import EventKind, Status

__all__ = ["ConstructionPlan", "plan_construction", "cached_plan", "place", "Constructive"]

#: A node this close to the seed axis (relative to the network) lies on it and fixes no rotation.
ON_AXIS_RTOL = 1e-9
#: Edges the construction does not use (a state of self-stress) must keep their length to this
#: relative error along the trace; beyond it the self-stress does not persist and they break.
UNUSED_EDGE_RTOL = 1e-9


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
    """

    dim: int
    seed: tuple[int, int]
    order: np.ndarray
    parents: np.ndarray
    radii: np.ndarray
    signs: np.ndarray
    reference: np.ndarray
    gauge_perp: np.ndarray

    @property
    def n_nodes(self) -> int:
        return int(self.reference.shape[0])


def _edge_index(net: Network) -> dict[tuple[int, int], int]:
    e = net.edges
    return {(min(i, j), max(i, j)): k for k, (i, j) in enumerate(e.tolist())}


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
    """
    x = net.nodes if reference is None else np.asarray(reference, dtype=np.float64)
    n, d = x.shape
    a, b = drive
    nbrs = net.adjacency()
    eidx = _edge_index(net)
    lengths = net.edge_lengths
    # plain Python lists: this loop runs once per node and numpy scalar access would dominate
    placed = [False] * n
    placed[a] = placed[b] = True
    count = [0] * n
    for s in (a, b):
        for v in nbrs[s]:
            count[v] += 1
    gauge_done = d == 2  # in 3D the first node after the seed fixes the rotation about a-b
    queue: deque[int] = deque(v for v in range(n) if not placed[v] and count[v] >= 2)
    queued = [False] * n
    for v in queue:
        queued[v] = True
    order, parents, radii, signs = [], [], [], []
    gauge_perp = np.zeros(d)
    u_seed = (x[b] - x[a]) / np.linalg.norm(x[b] - x[a])

    xl = x.tolist()

    def radius(v, p):
        return lengths[eidx[(min(v, p), max(v, p))]]

    while queue:
        v = queue.popleft()
        queued[v] = False
        if placed[v]:
            continue
        cand = [p for p in nbrs[v] if placed[p]]
        if d == 2:
            best, best_sin = None, -1.0
            xv, yv = xl[v]
            for ii in range(len(cand)):
                for jj in range(ii + 1, len(cand)):
                    p, q = cand[ii], cand[jj]
                    ax_, ay_ = xl[p][0] - xv, xl[p][1] - yv
                    bx_, by_ = xl[q][0] - xv, xl[q][1] - yv
                    sin = abs(ax_ * by_ - ay_ * bx_) / math.sqrt(
                        (ax_ * ax_ + ay_ * ay_) * (bx_ * bx_ + by_ * by_))
                    if sin > best_sin:
                        best, best_sin = (p, q), sin
            p, q = best
            if best_sin < FLAT_RTOL:
                raise FlatStateError(
                    f"node {v} is collinear with nodes {p} and {q} in the start configuration: a flat "
                    "state, where the side of the intersection (and so the branch) is undetermined",
                    v, (p, q))
            side = ((xl[q][0] - xl[p][0]) * (xl[v][1] - xl[p][1])
                    - (xl[q][1] - xl[p][1]) * (xl[v][0] - xl[p][0]))
            order.append(v)
            parents.append((p, q))
            radii.append((radius(v, p), radius(v, q)))
            signs.append(1.0 if side > 0 else -1.0)
        elif not gauge_done:
            off = x[v] - x[a]
            perp = off - (off @ u_seed) * u_seed
            if np.linalg.norm(perp) <= ON_AXIS_RTOL * max(net.size, TINY):
                continue  # on the seed axis: fixes no rotation; placed later from 3 parents
            p, q = cand[0], cand[1]
            gauge_perp = perp / np.linalg.norm(perp)
            order.append(v)
            parents.append((p, q, -1))
            radii.append((radius(v, p), radius(v, q), 0.0))
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
            if abs(side) < FLAT_RTOL:
                raise FlatStateError(
                    f"node {v} lies in the plane of nodes {p1}, {p2} and {p3} in the start "
                    "configuration: a flat state, where the side of the intersection (and so the "
                    "branch) is undetermined", v, (p1, p2, p3))
            order.append(v)
            parents.append((p1, p2, p3))
            radii.append(tuple(radius(v, p) for p in (p1, p2, p3)))
            signs.append(np.sign(side))
        placed[v] = True
        need = 2 if gauge_done is False or d == 2 else 3
        for w in nbrs[v]:
            if not placed[w]:
                count[w] += 1
        # every unplaced node with enough placed neighbours gets (another) turn
        for w in (range(n) if (d == 3 and len(order) == 1) else nbrs[v]):
            if not placed[w] and not queued[w] and count[w] >= need:
                queue.append(w)
                queued[w] = True
    missing = np.flatnonzero(~np.array(placed))
    if missing.size:
        shown = ", ".join(str(int(m)) for m in missing[:8]) + (" ..." if missing.size > 8 else "")
        raise ConstructionError(
            f"no construction order from the drive pair ({a}, {b}): node(s) {shown} cannot be "
            f"placed from {d} already placed neighbours; use method='projected'"
        )
    return ConstructionPlan(
        dim=d,
        seed=(a, b),
        order=np.array(order, dtype=np.int64),
        parents=np.array(parents, dtype=np.int64).reshape(len(order), d),
        radii=np.array(radii, dtype=np.float64).reshape(len(order), d),
        signs=np.array(signs, dtype=np.float64),
        reference=np.array(x),
        gauge_perp=gauge_perp,
    )


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
    orders, parents, radii = [], [], []
    for module, index, _flag in layout.copies:
        try:
            mp = cached_plan(module, module.port(layout.d_in))
        except ConstructionError:
            return None
        if mp.seed != module.port(layout.d_in):
            return None
        orders.append(index[mp.order])
        parents.append(index[mp.parents])
        radii.append(mp.radii)
    order = np.concatenate(orders)
    par = np.concatenate(parents)
    rad = np.concatenate(radii)
    n = net.n_nodes
    a, b = drive
    step = np.full(n, -1, dtype=np.int64)
    step[[a, b]] = 0
    if order.size != n - 2 or np.any(step[order] == 0):
        return None
    step[order] = np.arange(1, order.size + 1)
    if np.any(step[par] < 0) or np.any(step[par] >= step[order][:, None]):
        return None  # a parent placed after its child (or never)
    x = net.nodes
    measured = np.linalg.norm(x[order][:, None, :] - x[par], axis=2)
    if not np.allclose(measured, rad, rtol=1e-9, atol=0.0):
        return None
    rad = measured  # the chain's own rest lengths (its joins carry their own round-off)
    dpq = x[par[:, 1]] - x[par[:, 0]]
    dpv = x[order] - x[par[:, 0]]
    cross = dpq[:, 0] * dpv[:, 1] - dpq[:, 1] * dpv[:, 0]
    norm = np.linalg.norm(dpq, axis=1) * np.linalg.norm(dpv, axis=1)
    if np.any(np.abs(cross) < FLAT_RTOL * norm):
        return None  # a flat reference: let the search raise its precise error
    return ConstructionPlan(dim=2, seed=(int(a), int(b)), order=order, parents=par, radii=rad,
                            signs=np.where(cross > 0, 1.0, -1.0), reference=np.array(x),
                            gauge_perp=np.zeros(2))


def place(plan: ConstructionPlan, drive_values, *,
          radii=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Place all nodes for many drive values at once.

    Parameters
    ----------
    plan : ConstructionPlan
    drive_values : array_like, shape (K,)
    radii : array_like, shape (K, M, dim), optional
        Distances of each placed node to its parents for each drive value, instead of the
        plan's ``radii`` (shape (M, dim)) for all of them: built networks whose bars differ from
        build to build (:mod:`fabkit.tolerance`) are placed in one pass, a column per (build,
        drive value).

    Returns
    -------
    positions : numpy.ndarray, shape (K, N, d)
        In the seed frame (node a at its reference position, b along the reference direction).
    margin : numpy.ndarray, shape (K,)
        Smallest ``h² / r²`` over the intersections (h: distance of the node from its parents'
        line/plane); negative where some intersection does not exist (``-inf`` where it is not
        even defined: a parent already missing, or coincident parents).
    worst : numpy.ndarray of int, shape (K,)
        Index into ``plan.order`` of the intersection with the smallest margin.

    Raises
    ------
    ValueError
        ``radii`` of another shape.
    """
    dv = np.atleast_1d(np.asarray(drive_values, dtype=np.float64))
    k = dv.size
    ref = plan.reference
    n, d = ref.shape
    a, b = plan.seed
    u = ref[b] - ref[a]
    u = u / np.linalg.norm(u)
    # One contiguous row of K values per node and coordinate: the loop below runs once per node
    # (in construction order) and does a dozen ufunc calls on rows of length K.
    X = np.full((d, n, k), np.nan)
    for c in range(d):
        X[c, a] = ref[a, c]
        X[c, b] = ref[a, c] + dv * u[c]
    margins = np.empty((plan.order.size, k))
    order = plan.order.tolist()
    parents = plan.parents.tolist()
    if radii is None:
        # Python floats: the common case stays scalar arithmetic on each row
        sq = (plan.radii ** 2).T.tolist()
    else:
        rad = np.asarray(radii, dtype=np.float64)
        if rad.shape != (k,) + plan.radii.shape:
            raise ValueError(f"radii must have shape {(k,) + plan.radii.shape} (drive values, "
                             f"placements, parents), got {rad.shape}")
        sq = list(np.ascontiguousarray((rad ** 2).transpose(2, 1, 0)))  # per parent: (M, K)
    r0s = sq[0]
    c0s = [r0 - r1 for r0, r1 in zip(sq[0], sq[1])]
    r2s = sq[2] if d == 3 else None
    signs = plan.signs.tolist()
    with np.errstate(invalid="ignore", divide="ignore"):  # beyond a flat state: margin < 0, NaN
        _place_loop(X, margins, order, parents, r0s, c0s, r2s, signs, plan, d)
    positions = np.ascontiguousarray(X.transpose(2, 1, 0))
    if margins.size:
        worst = np.argmin(margins, axis=0)  # a NaN margin is the minimum
        margin = margins[worst, np.arange(k)]
        margin[np.isnan(margin)] = -np.inf
    else:
        worst = np.zeros(k, dtype=np.int64)
        margin = np.full(k, np.inf)
    return positions, margin, worst


def _groups(order, parents):
    """Runs of consecutive placements with the same parents and no parent among themselves:
    (start, stop, p, q) per run."""
    runs = []
    start = 0
    n = len(order)
    while start < n:
        p, q = parents[start]
        stop = start + 1
        while stop < n and parents[stop][0] == p and parents[stop][1] == q:
            stop += 1
        runs.append((start, stop, p, q))
        start = stop
    return runs


def _place_loop(X, margins, order, parents, r0s, c0s, r2s, signs, plan, d):
    """The intersections of :func:`place`, in construction order. ``r0s``, ``c0s`` and ``r2s``
    hold one float per placement, or one row of K values per placement (radii per column)."""
    sqrt, maximum = np.sqrt, np.maximum
    if d == 2:
        # complex coordinates z = x + iy: a node is p + (along + i·height)·(q - p)/|pq|, a
        # handful of ufunc calls; consecutive nodes with the same parents (a module's two
        # variable nodes) are placed together, sharing the work on their parents
        z = X[0] + 1j * X[1]
        r0a = np.asarray(r0s)
        c0a = np.asarray(c0s)
        sa = np.asarray(signs)[:, None]
        if r0a.ndim == 1:  # one radius per placement: a column against the row of K values
            r0a, c0a = r0a[:, None], c0a[:, None]
        for start, stop, p, q in _groups(order, parents):
            zp = z[p]
            D = z[q] - zp
            dist2 = D.real * D.real + D.imag * D.imag
            if stop - start == 1:
                r0, c0, sg = r0s[start], c0s[start], signs[start]
            else:
                r0, c0, sg = r0a[start:stop], c0a[start:stop], sa[start:stop]
            along = (c0 + dist2) / (2.0 * dist2)
            h2 = r0 - along * along * dist2
            hs = sg * sqrt(maximum(h2, 0.0) / dist2)
            z[order[start:stop] if stop - start > 1 else order[start]] = zp + (along + 1j * hs) * D
            margins[start:stop] = h2 / r0
        X[0] = z.real
        X[1] = z.imag
    else:
        for idx, v in enumerate(order):
            par = parents[idx]
            r0 = r0s[idx]
            p1 = X[:, par[0]]
            e12 = X[:, par[1]] - p1
            dist2 = (e12 * e12).sum(axis=0)
            dd = sqrt(dist2)
            ex = e12 / dd
            xx = (c0s[idx] + dist2) / (2.0 * dd)
            if par[2] < 0:  # 3D gauge node: circle about the seed axis, in the reference half-plane
                g = plan.gauge_perp[:, None] - (ex * plan.gauge_perp[:, None]).sum(axis=0) * ex
                g = g / sqrt((g * g).sum(axis=0))
                h2 = r0 - xx * xx
                X[:, v] = p1 + xx * ex + sqrt(maximum(h2, 0.0)) * g
                margins[idx] = h2 / r0
                continue
            w = X[:, par[2]] - p1
            i = (ex * w).sum(axis=0)
            ey = w - i * ex
            j = sqrt((ey * ey).sum(axis=0))
            ey = ey / j
            ez = np.stack([ex[1] * ey[2] - ex[2] * ey[1], ex[2] * ey[0] - ex[0] * ey[2],
                           ex[0] * ey[1] - ex[1] * ey[0]])
            yy = (r0 - r2s[idx] + i * i + j * j) / (2.0 * j) - (i / j) * xx
            z2 = r0 - xx * xx - yy * yy
            X[:, v] = p1 + xx * ex + yy * ey + (signs[idx] * sqrt(maximum(z2, 0.0))) * ez
            margins[idx] = z2 / r0


class Constructive(Method):
    """Exact placement by intersections, vectorised over drive values (see module docstring).

    Options
    -------
    samples : int
        Number of configurations from the start to the target (default 101).
    plan : ConstructionPlan or None
        A plan to reuse (skips the search for a construction order).
    """

    name = "constructive"
    options = {"samples": 101, "plan": None}

    def solve(self) -> Outcome:
        p = self.problem
        samples = int(self.opts["samples"])
        if samples < 2:
            raise KinematicsError(f"`samples` must be at least 2, got {samples}")
        plan = self.opts["plan"] or cached_plan(p.work, p.drive, p.start)
        d0 = p.start_drive
        values = np.linspace(d0, p.target, samples)
        X, margin, worst = place(plan, values)
        valid = margin >= 0.0
        valid[0] = True  # the start exists by definition; round-off must not say otherwise
        status, message, marks = Status.FINISHED, self.finished_message(), []
        if not valid.all():
            k = int(np.argmin(valid))
            lo, hi = values[k - 1], values[k]
            for _ in range(8):  # vectorised bisection: 32^8 ≈ 1e12 refinement of the bracket
                grid = np.linspace(lo, hi, 33)
                _, m, _ = place(plan, grid)
                ok = m >= 0.0
                ok[0] = True
                if ok.all():
                    lo = grid[-1]
                    break
                last = int(np.argmin(ok)) - 1
                lo, hi = grid[last], grid[last + 1]
            Xe, _, we = place(plan, [lo])
            node = int(plan.order[we[0]])
            par = [int(v) for v in plan.parents[we[0]] if v >= 0]
            shape = "collinear" if plan.dim == 2 else "coplanar"
            what = "smallest" if p.target < d0 else "largest"
            detail = (
                f"node {node} becomes {shape} with nodes {', '.join(map(str, par))} "
                f"(a flat state): {p.drive_name} = {lo:.10g} is its {what} value on this branch"
            )
            X = np.concatenate([X[:k], Xe], axis=0)
            status = Status.TURNING_POINT
            message = f"stopped at a turning point of {p.drive_name} = {lo:.10g}: {detail}"
            marks.append(Mark(EventKind.TURNING_POINT, len(X) - 1, detail))
        stats = {"samples": int(X.shape[0]), "nodes_placed": int(plan.order.size)}
        # Over-constrained networks: edges not used by the construction must still hold.
        err = np.atleast_1d(p.network.edge_error(X))
        bad = np.flatnonzero(err > UNUSED_EDGE_RTOL)
        if bad.size and bad[0] > 0:
            k = int(bad[0])
            drive = p.drive_of(X[k - 1])
            X = X[:k]
            marks = [m for m in marks if m.index < k]
            status = Status.FAILED
            message = (f"the construction breaks edges beyond {p.drive_name} = {drive:.10g} "
                       "(the network is over-constrained along this drive)")
        return Outcome(X, status, message, tuple(marks), stats)
