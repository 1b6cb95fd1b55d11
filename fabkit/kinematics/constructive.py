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
from ..construction import (ON_AXIS_RTOL, ConstructionPlan, _tiled_chain_plan,  # noqa: F401
                            cached_plan, plan_construction)
from ..errors import KinematicsError
from .base import Mark, Method, Outcome
from .trajectory import EventKind, Status

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
