"""Constructive placement: nodes placed one by one by circle (2D) or sphere (3D) intersections.

Starting from the two nodes of the drive, every further node is placed from 2 (2D) or 3 (3D)
already placed neighbours whose distances to it are edge lengths. Of the two intersection points
the one on the same side as in the reference configuration is taken, so the construction follows
the branch of the reference. Exact to round-off; the motion ends where an intersection vanishes
(a node becomes collinear/coplanar with its parents: a flat state, where the drive turns back).
"""

from __future__ import annotations

import numpy as np

# the construction order lives below kinematics (mode counting proves counts from it too); its
# names stay importable from here
from ..model.construction import (ON_AXIS_RTOL, ConstructionPlan, cached_plan,  # noqa: F401
                                  plan_construction)
from ..errors import KinematicsError
from ..numerics import COLLINEAR_PARENTS_RTOL, rigid_fit
from .base import Mark, Method, Solved
from .record import kept_indices, port_table, PortValues, Record
from ..status import Status
from .trajectory import EventKind

__all__ = ["ConstructionPlan", "plan_construction", "cached_plan", "place", "Constructive"]

#: Edges the construction does not use (a state of self-stress) must keep their length to this
#: relative error along the trace; beyond it the self-stress does not persist and they break.
UNUSED_EDGE_RTOL = 1e-9


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
    rows, margins = _place_columns(plan, drive_values, radii)
    margin, worst = _margin_of(margins)
    return _positions(rows), margin, worst


def _positions(rows) -> np.ndarray:
    """Configurations (K, N, d) from the placement's rows: complex z (N, K) in 2D, X (3, N, K)
    in 3D."""
    if np.iscomplexobj(rows):
        out = np.empty((rows.shape[1], rows.shape[0], 2))
        out[..., 0] = rows.real.T
        out[..., 1] = rows.imag.T
        return out
    return np.ascontiguousarray(rows.transpose(2, 1, 0))


def _place_columns(plan: ConstructionPlan, drive_values, radii=None):
    """The placement of :func:`place`: one row of K values per node (2D: complex coordinates
    z (N, K); 3D: X (3, N, K)) and the margins of every intersection (shape (M, K))."""
    dv = np.atleast_1d(np.asarray(drive_values, dtype=np.float64))
    k = dv.size
    ref = plan.reference
    n, d = ref.shape
    a, b = plan.seed
    u = ref[b] - ref[a]
    u = u / np.linalg.norm(u)
    # One contiguous row of K values per node (and coordinate): the loop below runs once per
    # node (in construction order) and does a dozen ufunc calls on rows of length K. Every node
    # but the seed is written once by the loop (a plan places them all).
    margins = np.empty((plan.order.size, k))
    order, parents, sq, signs = plan.lists
    if radii is None:
        pass  # Python floats: the common case stays scalar arithmetic on each row
    else:
        rad = np.asarray(radii, dtype=np.float64)
        if rad.shape != (k,) + plan.radii.shape:
            raise ValueError(f"radii must have shape {(k,) + plan.radii.shape} (drive values, "
                             f"placements, parents), got {rad.shape}")
        sq = list(np.ascontiguousarray((rad ** 2).transpose(2, 1, 0)))  # per parent: (M, K)
    r0s = sq[0]
    c0s = [r0 - r1 for r0, r1 in zip(sq[0], sq[1])]
    r2s = sq[2] if d == 3 else None
    if d == 2:
        z = np.empty((n, k), dtype=np.complex128)
        z[a] = complex(ref[a, 0], ref[a, 1])
        z[b] = (ref[a, 0] + dv * u[0]) + 1j * (ref[a, 1] + dv * u[1])
        with np.errstate(invalid="ignore", divide="ignore"):  # beyond a flat state: NaN
            _place_loop_2d(z, margins, 0, order, plan.runs, r0s, c0s, signs,
                           _radii_rows(r0s, c0s, signs))
        return z, margins
    X = np.empty((d, n, k))
    for c in range(d):
        X[c, a] = ref[a, c]
        X[c, b] = ref[a, c] + dv * u[c]
    with np.errstate(invalid="ignore", divide="ignore"):  # beyond a flat state: margin < 0, NaN
        _place_loop_3d(X, margins, 0, order, parents, r0s, c0s, r2s, signs, plan, 0, len(order))
    return X, margins


def _margin_of(margins) -> tuple[np.ndarray, np.ndarray]:
    """Smallest margin per column (-inf where it is NaN) and the placement that has it."""
    k = margins.shape[1]
    if not margins.size:
        return np.full(k, np.inf), np.zeros(k, dtype=np.int64)
    worst = np.argmin(margins, axis=0)  # a NaN margin is the minimum
    margin = margins[worst, np.arange(k)]
    margin[np.isnan(margin)] = -np.inf
    return margin, worst


def _radii_rows(r0s, c0s, signs):
    """The per-placement radii and signs as arrays for the placements placed together (made
    once per placement, not once per block)."""
    r0a = np.asarray(r0s)
    c0a = np.asarray(c0s)
    sa = np.asarray(signs)[:, None]
    if r0a.ndim == 1:  # one radius per placement: a column against the row of K values
        r0a, c0a = r0a[:, None], c0a[:, None]
    return r0a, c0a, sa


def _place_loop_2d(z, margins, base, order, runs, r0s, c0s, signs, rows):
    """The intersections of :func:`place` in 2D, in construction order, on complex coordinates
    z (rows, K): a node is p + (along + i·height)·(q - p)/|pq|, a handful of ufunc calls;
    consecutive nodes with the same parents (a module's two variable nodes) are placed together,
    sharing the work on their parents. ``order`` and the parents in ``runs`` are rows of z;
    ``r0s`` and ``c0s`` hold one float per placement, or one row of K values per placement
    (radii per column); ``rows`` are the same as arrays (:func:`_radii_rows`). The margin of
    placement i goes to ``margins[i - base]``."""
    sqrt, maximum = np.sqrt, np.maximum
    r0a, c0a, sa = rows
    for start, stop, p, q in runs:
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
        margins[start - base:stop - base] = h2 / r0


def _place_loop_3d(X, margins, base, order, parents, r0s, c0s, r2s, signs, plan, first, last):
    """The intersections of :func:`place` in 3D, node by node in construction order (placements
    ``first`` to ``last - 1``; ``order`` and ``parents`` are rows of X)."""
    sqrt, maximum = np.sqrt, np.maximum
    par0, par1, par2 = parents  # one list per parent slot
    for idx in range(first, last):
        v = order[idx]
        r0 = r0s[idx]
        p1 = X[:, par0[idx]]
        e12 = X[:, par1[idx]] - p1
        dist2 = (e12 * e12).sum(axis=0)
        dd = sqrt(dist2)
        ex = e12 / dd
        xx = (c0s[idx] + dist2) / (2.0 * dd)
        if par2[idx] < 0:  # 3D gauge node: circle about the seed axis, in the reference half-plane
            g = plan.gauge_perp[:, None] - (ex * plan.gauge_perp[:, None]).sum(axis=0) * ex
            g = g / sqrt((g * g).sum(axis=0))
            h2 = r0 - xx * xx
            X[:, v] = p1 + xx * ex + sqrt(maximum(h2, 0.0)) * g
            margins[idx - base] = h2 / r0
            continue
        w = X[:, par2[idx]] - p1
        i = (ex * w).sum(axis=0)
        ey = w - i * ex
        j = sqrt((ey * ey).sum(axis=0))
        # parents on one line fix no plane: no place (not a place decided by round-off)
        j = np.where(j > COLLINEAR_PARENTS_RTOL * dd, j, np.nan)
        ey = ey / j
        ez = np.stack([ex[1] * ey[2] - ex[2] * ey[1], ex[2] * ey[0] - ex[0] * ey[2],
                       ex[0] * ey[1] - ex[1] * ey[0]])
        yy = (r0 - r2s[idx] + i * i + j * j) / (2.0 * j) - (i / j) * xx
        z2 = r0 - xx * xx - yy * yy
        X[:, v] = p1 + xx * ex + yy * ey + (signs[idx] * sqrt(maximum(z2, 0.0))) * ez
        margins[idx - base] = z2 / r0


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

    def solve(self) -> Solved:
        p = self.problem
        samples = int(self.opts["samples"])
        if samples < 2:
            raise KinematicsError(f"`samples` must be at least 2, got {samples}")
        plan = self.opts["plan"] or cached_plan(p.work, p.drive, p.start)
        d0 = p.start_drive
        values = np.linspace(d0, p.target, samples)
        record, margin, err = _sweep(plan, values, p)
        valid = margin >= 0.0  # a NaN margin (no intersection at all) is not valid either
        valid[0] = True  # the start exists by definition; round-off must not say otherwise
        status, message, marks = Status.FINISHED, self.finished_message(), []
        if not valid.all():
            k = int(np.argmin(valid))
            lo, hi = values[k - 1], values[k]
            for _ in range(8):  # vectorised bisection: 32^8 ≈ 1e12 refinement of the bracket
                grid = np.linspace(lo, hi, 33)
                _, m = _place_columns(plan, grid)
                ok = m.min(axis=0) >= 0.0
                ok[0] = True
                if ok.all():
                    lo = grid[-1]
                    break
                last = int(np.argmin(ok)) - 1
                lo, hi = grid[last], grid[last + 1]
            _, m_end = _place_columns(plan, [lo])
            we = _margin_of(m_end)[1]
            node = int(plan.order[we[0]])
            par = [int(v) for v in plan.parents[we[0]] if v >= 0]
            shape = "collinear" if plan.dim == 2 else "coplanar"
            what = "smallest" if p.target < d0 else "largest"
            detail = (
                f"node {node} becomes {shape} with nodes {', '.join(map(str, par))} "
                f"(a flat state): {p.drive_name} = {lo:.10g} is its {what} value on this branch"
            )
            values = np.append(values[:k], lo)
            record, _, err = _sweep(plan, values, p)  # the configurations up to the turn
            status = Status.TURNING_POINT
            message = f"stopped at a turning point of {p.drive_name} = {lo:.10g}: {detail}"
            marks.append(Mark(EventKind.TURNING_POINT, values.size - 1, detail))
        stats = {"samples": int(values.size), "nodes_placed": int(plan.order.size)}
        # Over-constrained networks: edges not used by the construction must still hold.
        bad = np.flatnonzero(err > UNUSED_EDGE_RTOL)
        if bad.size and bad[0] > 0:
            k = int(bad[0])
            record, _, _ = _sweep(plan, values[:k], p)
            drive = float(record.drive[-1])
            marks = [m for m in marks if m.index < k]
            status = Status.FAILED
            message = (f"the construction breaks edges beyond {p.drive_name} = {drive:.10g} "
                       "(the network is over-constrained along this drive)")
        return Solved(None, status, message, tuple(marks), stats, record=record)


#: Placements per block of the streamed sweep (:func:`_sweep`): after each block the nodes it
#: placed are reduced (moved to the gauge frame, measured, kept or not) and rows no later block
#: needs are reused, so a chain's sweep holds a few thousand rows of K values instead of all of
#: them (0.5 GB for 101 configurations of a 100 000-module chain, whose first touch alone took
#: a second).
BLOCK = 2048


def _sweep(plan: ConstructionPlan, values, p) -> tuple[Record, np.ndarray, np.ndarray]:
    """Constructive placement of every drive value in one pass over the plan, reduced as it goes.

    The placements run in blocks. Each node needs its row until the last block that places a
    child of it, or completes an edge or a port with it; rows are a ring of ``W`` rows (a node
    at position i of the construction lives in row ``i mod W``), ``W`` the longest such life:
    a few blocks for chains, the whole network for a network whose nodes are needed far apart.
    After each block the nodes it placed are moved to the gauge frame (one rigid fit per drive
    value, from the gauge nodes, which the first block places), their steps add to the
    arclength and the kept configurations take their positions; the edges and ports they
    complete are measured. The plan's radii, signs and rows are made Python numbers a block at
    a time (the whole plan as lists took 0.9 GB for a million modules).

    Returns
    -------
    record : Record
        What ``p.keep`` asks for, for every value.
    margin : numpy.ndarray, shape (K,)
        Smallest intersection margin per value (NaN where an intersection does not exist).
    edge_error : numpy.ndarray, shape (K,)
        Largest relative length error over the network's edges.
    """
    dv = np.atleast_1d(np.asarray(values, dtype=np.float64))
    k = dv.size
    ref = plan.reference
    n, d = ref.shape
    a, b = plan.seed
    m = plan.order.size
    pos = np.empty(n, dtype=np.int64)
    pos[[a, b]] = 0, 1
    pos[plan.order] = np.arange(2, m + 2)
    gauge = list(p.gauge)
    ends = _block_ends(plan, max(BLOCK, int(pos[gauge].max()) - 1))
    run_ends = np.searchsorted(plan.run_table[:, 1], ends, side="right") if d == 2 else None
    block_end = np.array(ends, dtype=np.int64) + 2  # in positions
    edges, rest = p.network.edges, p.network.edge_lengths
    names, pairs = port_table(p.network, p.ports)
    width = _ring_width(plan, pos, block_end, (edges, pairs))
    row = (pos % width).astype(np.int32 if n < 2 ** 31 else np.int64)
    at = np.empty(n, dtype=np.int64)  # the node at each position
    at[pos] = np.arange(n)
    u = ref[b] - ref[a]
    u = u / np.linalg.norm(u)
    if d == 2:
        z = np.empty((width, k), dtype=np.complex128)
        z[row[a]] = complex(ref[a, 0], ref[a, 1])
        z[row[b]] = (ref[a, 0] + dv * u[0]) + 1j * (ref[a, 1] + dv * u[1])
    else:
        X = np.empty((d, width, k))
        for c in range(d):
            X[c, row[a]] = ref[a, c]
            X[c, row[b]] = ref[a, c] + dv * u[c]
    # what each block completes: edges and ports by their later node, nodes by position
    # (sorted once into contiguous rows: gathering them per block from a large edge array was
    # the one part that did not scale linearly)
    e_cut, e_rows, e_rest = _by_block(pos, row, edges, block_end, rest)
    p_cut, p_rows, p_sorted = _by_block(pos, row, pairs, block_end)
    del pos
    kept = kept_indices(k, p.keep)
    out = np.empty((kept.size, n, d))
    squares = np.zeros(max(k - 1, 0))
    margin = np.full(k, np.inf)
    err = np.zeros(k)
    dist = np.empty((len(pairs), k))
    buf = np.empty((max(int(np.diff(np.concatenate([[0], ends])).max()), 1), k))
    fit = None
    lo_place = lo_pos = lo_edge = lo_port = 0
    lo_run = 0

    def coords(rows_):
        """(K, len, d) positions of some rows."""
        if d == 2:
            zz = z[rows_]
            return np.stack([zz.real.T, zz.imag.T], axis=-1)
        return X[:, rows_].transpose(2, 1, 0)

    def lengths(ri, rj):
        """Distances between the nodes in rows ri[m] and rj[m], shape (len, K)."""
        if d == 2:
            return np.abs(z[ri] - z[rj])
        diff = X[:, ri] - X[:, rj]
        return np.sqrt(np.einsum("cmk,cmk->mk", diff, diff))

    with np.errstate(invalid="ignore", divide="ignore"):  # beyond a flat state: NaN
        for blk, stop in enumerate(ends):
            order_rows, r0s, c0s, r2s, signs = _block_lists(plan, row, lo_place, stop)
            if d == 2:
                table = plan.run_table[lo_run:run_ends[blk]]
                runs = list(zip(*np.column_stack([table[:, :2] - lo_place,
                                                  row[table[:, 2:]]]).T.tolist()))
                _place_loop_2d(z, buf, 0, order_rows, runs, r0s, c0s, signs,
                               _radii_rows(r0s, c0s, signs))
                lo_run = int(run_ends[blk])
            else:
                par = plan.parents[lo_place:stop]
                par_rows = np.where(par >= 0, row[np.maximum(par, 0)], -1).T.tolist()
                _place_loop_3d(X, buf, 0, order_rows, par_rows, r0s, c0s, r2s, signs, plan, 0,
                               stop - lo_place)
            if stop > lo_place:
                np.minimum(margin, buf[:stop - lo_place].min(axis=0), out=margin)
            lo_place = stop
            if fit is None:
                fit = rigid_fit(coords(row[gauge]), p.start[gauge])  # one fit per value
            hi_pos = int(block_end[blk])
            nodes = at[lo_pos:hi_pos]
            if d == 2:
                rot = fit.rotation[:, 0, 0] + 1j * fit.rotation[:, 1, 0]
                w = z[row[nodes]] * rot + (fit.shift[:, 0] + 1j * fit.shift[:, 1])
                step = w[:, 1:] - w[:, :-1]
                squares += (step.real * step.real + step.imag * step.imag).sum(axis=0)
                out[:, nodes, 0] = w[:, kept].real.T
                out[:, nodes, 1] = w[:, kept].imag.T
            else:
                w = np.einsum("sij,jms->ims", fit.rotation, X[:, row[nodes]]) \
                    + fit.shift.T[:, None, :]
                step = w[:, :, 1:] - w[:, :, :-1]
                squares += np.einsum("cms,cms->s", step, step)
                out[:, nodes] = w[:, :, kept].transpose(2, 1, 0)
            lo_pos = hi_pos
            hi_edge = int(e_cut[blk])
            if hi_edge > lo_edge:
                got = lengths(e_rows[lo_edge:hi_edge, 0], e_rows[lo_edge:hi_edge, 1])
                rel = np.abs(got / e_rest[lo_edge:hi_edge, None] - 1.0)
                np.maximum(err, rel.max(axis=0), out=err)
            lo_edge = hi_edge
            hi_port = int(p_cut[blk])
            if hi_port > lo_port:
                dist[p_sorted[lo_port:hi_port]] = lengths(p_rows[lo_port:hi_port, 0],
                                                          p_rows[lo_port:hi_port, 1])
            lo_port = hi_port
            if blk == 0:
                drive = lengths(row[[p.drive[0]]], row[[p.drive[1]]])[0]
    arclength = np.concatenate([[0.0], np.cumsum(np.sqrt(squares))])
    if p.keep == "all":
        record = Record(out, None, drive, arclength, err, None)
    else:
        record = Record(out, kept, drive, arclength, err, PortValues(names, dist))
    return record, margin, err


def _block_ends(plan: ConstructionPlan, first: int) -> list[int]:
    """Where the blocks of :func:`_sweep` end (placement indices): every :data:`BLOCK`
    placements from ``first`` on (the gauge nodes placed in the first block), in 2D at the end
    of a run of placements."""
    m = plan.order.size
    if plan.dim != 2:
        return sorted(set(list(range(first, m, BLOCK)) + [m]))
    run_stop = plan.run_table[:, 1]
    ends, last = [], 0
    for want in list(range(first, m, BLOCK)) + [m]:
        i = int(np.searchsorted(run_stop, max(want, last + 1)))
        stop = int(run_stop[min(i, run_stop.size - 1)]) if run_stop.size else 0
        if stop > last:
            ends.append(stop)
            last = stop
    return ends or [0]


def _ring_width(plan: ConstructionPlan, pos, block_end, pair_sets) -> int:
    """The rows of :func:`_sweep`'s ring: the longest a node is needed, from its own block to
    the last block that places a child of it or completes one of ``pair_sets`` (edges, ports)
    with it."""
    need = pos.copy()
    has = plan.parents >= 0
    np.maximum.at(need, plan.parents[has],
                  np.broadcast_to(pos[plan.order][:, None], plan.parents.shape)[has])
    del has
    for pr in pair_sets:
        later = pos[pr].max(axis=1)
        np.maximum.at(need, pr[:, 0], later)
        np.maximum.at(need, pr[:, 1], later)
    alive_to = block_end[np.searchsorted(block_end, need, side="right")]
    del need
    alive_to -= pos
    return int(min(pos.size, alive_to.max()))


def _by_block(pos, row, pairs, block_end, rest=None):
    """Node pairs (edges or ports) sorted by the later of their nodes' positions: where each
    block's pairs end, their rows in the ring, and (ports) the sorting order or (edges) their
    rest lengths in that order."""
    if not len(pairs):
        return (np.zeros(block_end.size, dtype=np.int64), np.zeros((0, 2), dtype=row.dtype),
                np.zeros(0, dtype=np.int64) if rest is None else np.zeros(0))
    later = pos[pairs].max(axis=1)
    order = np.argsort(later, kind="stable")
    cut = np.searchsorted(later[order], block_end)
    del later
    rows = row[pairs[order]]
    return cut, rows, (order if rest is None else rest[order])


def _block_lists(plan: ConstructionPlan, row, lo: int, hi: int):
    """Placements ``lo`` to ``hi - 1`` as the placement loops read them, Python numbers: the
    rows of the nodes placed, the squared radii to the first parent, their differences to the
    second's, the third's (3D) and the signs."""
    sq = (plan.radii[lo:hi] ** 2).T.tolist()
    r0s = sq[0]
    c0s = [r0 - r1 for r0, r1 in zip(sq[0], sq[1])]
    return (row[plan.order[lo:hi]].tolist(), r0s, c0s, sq[2] if plan.dim == 3 else None,
            plan.signs[lo:hi].tolist())
