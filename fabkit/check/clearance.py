"""Clearances over a re-simulated motion, measured between the parts read back from a file.

The checks do not reuse the stacking planner of the writers (:mod:`fabkit.fab.layers`): a
planner's mistake in sampling or in measuring would then be repeated by its check. Here the
rebuilt network's motion is traced again by the simulator (:func:`fabkit.kinematics.trace`, or
placed exactly by :func:`fabkit.kinematics.place` for the constructive method), sampled until no
joint moves more than a bound between two samples, and every gap is measured on its own:

* two bars of one layer that share no joint: the distance between the segments joining their
  joints, less half the width of each (a round-ended bar is the set of points within half its
  width of that segment);
* two bars of one layer that share a joint: their round ends fill the same disc around it at
  every moment (solid in solid), so their gap is minus the sum of their half widths; bars on a
  joint must lie on different layers;
* a bar and a column (a screw with its heads, a printed pin with its cap) whose layers the bar
  occupies and which it is not threaded on: the distance from the joint to the bar's segment,
  less half the bar's width and the column's radius;
* two columns that share a layer: the distance between their joints, less both radii.

Between two samples no point of a bar moves more than the larger move of its two joints, so a
gap can shrink by at most twice the largest joint step between samples; the checks ask for a
margin that covers it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import FabkitError
from ..kinematics import place, plan_construction, trace

__all__ = ["FineMotion", "fine_motion", "same_layer_gaps", "segment_gap", "point_gap"]

#: Most samples of one motion (the samples of a long chain are the largest array of a check).
MAX_SAMPLES = 200_000
#: Elements of one block of pair-by-sample distances (bounds the memory of a measurement).
BLOCK_ELEMENTS = 2**21


@dataclass(frozen=True)
class FineMotion:
    """A motion sampled for clearance checks.

    Attributes
    ----------
    positions : numpy.ndarray, shape (S, N, 2)
        Joint positions, mm.
    max_step : float
        Largest move of a joint between two consecutive samples, mm (measured here).
    status : str
        Of the trace the samples follow.
    """

    positions: np.ndarray
    max_step: float
    status: str

    @property
    def n_samples(self) -> int:
        return int(self.positions.shape[0])


def joint_steps(x: np.ndarray) -> np.ndarray:
    """Largest joint move between consecutive configurations, shape (S - 1,)."""
    if x.shape[0] < 2:
        return np.zeros(0)
    d = np.diff(x, axis=0)
    return np.sqrt((d * d).sum(axis=-1)).max(axis=-1)


def fine_motion(net, motion, scale: float, limit: float, *, floor: float | None = None
                ) -> FineMotion:
    """The network's motion, sampled so that no joint moves more than ``limit`` mm per sample.

    Parameters
    ----------
    net : Network
        Rebuilt network, design units.
    motion : Motion
        Drive, target, method, held ports and options.
    scale : float
        mm per design unit.
    limit : float
        Largest joint move between samples (mm).
    floor : float, optional
        Where two drive values are adjacent floats and joints still move more than ``limit``
        (a long chain amplifies its drive past float64's resolution), steps up to ``floor`` mm
        are accepted; :attr:`FineMotion.max_step` says what was met.

    Raises
    ------
    FabkitError
        No target; a state the drive cannot parametrise (joints jump while the drive stands
        still); more than :data:`MAX_SAMPLES` samples.
    """
    if motion.to is None:
        raise FabkitError("the design gives no motion target (motion.to): nothing to sample")
    traj = trace(net, drive=motion.drive, to=motion.to, method=motion.method, hold=motion.hold,
                 **motion.options)
    bound = limit / scale
    if traj.method == "constructive":
        x = _placed_fine(net, motion, traj, bound, (floor or 0.0) / scale)
    else:
        opts = dict(motion.options)
        key = "max_node_step" if traj.method == "projected" else "step"
        step = min(0.9 * bound, opts.get(key) or np.inf)
        x = traj.positions
        for _ in range(6):
            if float(joint_steps(x).max(initial=0.0)) <= bound:
                break
            opts[key] = step
            traj = trace(net, drive=motion.drive, to=motion.to, method=traj.method,
                         hold=motion.hold, **opts)
            x = traj.positions
            worst = float(joint_steps(x).max(initial=0.0))
            step *= 0.9 * bound / max(worst, bound)
    x = np.asarray(x, dtype=np.float64) * scale
    steps = joint_steps(x)
    return FineMotion(positions=x, max_step=float(steps.max(initial=0.0)),
                      status=str(traj.status))


def _placed_fine(net, motion, traj, bound: float, floor: float) -> np.ndarray:
    """Exact placements at drive values bisected until joints move at most ``bound``."""
    from ..kinematics.base import align_to_gauge, make_problem

    problem = make_problem(net, motion.drive, motion.to, hold=motion.hold)
    plan = plan_construction(problem.work, problem.drive, problem.start)

    def placer(v):
        return align_to_gauge(place(plan, v)[0], problem.start, problem.gauge)

    values = np.linspace(traj.drive[0], traj.drive[-1], 65)
    x = placer(values)
    for _ in range(80):
        steps = joint_steps(x)
        bad = np.flatnonzero(steps > bound)
        adjacent = np.nextafter(values[bad], values[bad + 1]) == values[bad + 1]
        accepted = adjacent & (steps[bad] <= floor)
        bad, adjacent = bad[~accepted], adjacent[~accepted]
        if bad.size == 0:
            return x
        if adjacent.any():
            k = int(bad[adjacent][0])
            raise FabkitError(f"the rebuilt network passes a state at {motion.drive} = "
                              f"{values[k]:.10g} where joints jump while the drive stands still: "
                              "its clearances cannot be sampled")
        if values.size + bad.size > MAX_SAMPLES:
            raise FabkitError(f"sampling the motion needs more than {MAX_SAMPLES} samples")
        mids = 0.5 * (values[bad] + values[bad + 1])
        x = np.insert(x, bad + 1, placer(mids), axis=0)
        values = np.insert(values, bad + 1, mids)
    raise FabkitError("could not sample the rebuilt network's motion finely enough")


def point_gap(x, p, q) -> np.ndarray:
    """Distance from points ``x`` to segments ``p``-``q`` (broadcast over leading axes)."""
    d = q - p
    dd = (d * d).sum(-1)
    t = np.clip(((x - p) * d).sum(-1) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    e = p + t[..., None] * d - x
    return np.sqrt((e * e).sum(-1))


def segment_gap(p1, q1, p2, q2) -> np.ndarray:
    """Distance between segments ``p1``-``q1`` and ``p2``-``q2`` in the plane (0 where they
    cross), broadcast over leading axes."""
    d = np.minimum(np.minimum(point_gap(p1, p2, q2), point_gap(q1, p2, q2)),
                   np.minimum(point_gap(p2, p1, q1), point_gap(q2, p1, q1)))

    def side(a, b, c):  # sign of the turn a -> b -> c
        return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - \
            (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])

    crossing = (side(p1, q1, p2) * side(p1, q1, q2) < 0) & (side(p2, q2, p1) * side(p2, q2, q1) < 0)
    return np.where(crossing, 0.0, d)


def _least(pairs, lower, measure, x):
    """Smallest gap over samples among candidate pairs, nearest bounds first.

    ``lower``: a lower bound of each pair's gap (from swept boxes); ``measure(x, idx)``: the
    gaps (S, P) of the pairs ``idx``. Returns (gap, pair index, sample) or (inf, -1, -1).
    """
    best, where, sample = math.inf, -1, -1
    if pairs == 0:
        return best, where, sample
    order = np.argsort(lower, kind="stable")
    block = max(1, BLOCK_ELEMENTS // max(1, x.shape[0]))
    for start in range(0, pairs, block):
        idx = order[start:start + block]
        if lower[idx[0]] >= best:
            break
        g = measure(x, idx)
        k = np.unravel_index(int(np.argmin(g)), g.shape)
        if g[k] < best:
            best, where, sample = float(g[k]), int(idx[k[1]]), int(k[0])
    return best, where, sample


def _layer_pairs(layer):
    """Every pair of bars (a < b) on one layer, formed layer by layer."""
    out_a, out_b = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for z in np.unique(layer):
        idx = np.flatnonzero(layer == z)
        i, j = np.triu_indices(idx.size, k=1)
        out_a.append(idx[i])
        out_b.append(idx[j])
    return np.concatenate(out_a), np.concatenate(out_b)


def _box_gap(lo_a, hi_a, lo_b, hi_b) -> np.ndarray:
    """Distance between axis-aligned boxes (0 when they overlap)."""
    d = np.maximum(0.0, np.maximum(lo_a - hi_b, lo_b - hi_a))
    return np.sqrt((d * d).sum(-1))


def same_layer_gaps(edges, layer, x, widths, *, columns=None) -> dict:
    """Smallest gaps between parts that share a layer over sampled configurations (mm).

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
        The bars, by their joints.
    layer : array_like of int, shape (E,)
        Each bar's layer, as read back.
    x : numpy.ndarray, shape (S, N, 2)
        Configurations, mm.
    widths : float or array_like, shape (E,)
        Each bar's width as read back.
    columns : dict, optional
        What stands at the joints: ``joints`` (int array, the joints with a column), ``low``
        and ``high`` (the lowest and highest layer each occupies, heads included), ``inner_low``
        and ``inner_high`` (the layers of its stack, where ``inner_radius`` applies),
        ``radius`` and ``inner_radius`` (mm).

    Returns
    -------
    dict
        ``bar_gap``, ``bar_pair`` (bar indices), ``sample``; ``joint_gap``, ``joint_pair`` (two
        bars of one layer on one joint: always overlapping, see the module docstring);
        ``screw_gap``, ``screw_at`` (bar, joint); ``column_gap``, ``column_pair`` (joints).
        ``inf`` / None where nothing shares a layer.
    """
    edges = np.asarray(edges, dtype=np.int64)
    layer = np.asarray(layer, dtype=np.int64)
    half = 0.5 * np.broadcast_to(np.asarray(widths, dtype=np.float64), (len(edges),))
    lo_n, hi_n = x.min(axis=0), x.max(axis=0)
    bar_lo = np.minimum(lo_n[edges[:, 0]], lo_n[edges[:, 1]])
    bar_hi = np.maximum(hi_n[edges[:, 0]], hi_n[edges[:, 1]])
    out = {"bar_gap": math.inf, "bar_pair": None, "sample": None, "joint_gap": math.inf,
           "joint_pair": None, "screw_gap": math.inf, "screw_at": None, "column_gap": math.inf,
           "column_pair": None}
    # bar pairs of one layer (formed layer by layer); those on a shared joint overlap there
    a, b = _layer_pairs(layer)
    keep = (edges[a, 0] != edges[b, 0]) & (edges[a, 0] != edges[b, 1]) \
        & (edges[a, 1] != edges[b, 0]) & (edges[a, 1] != edges[b, 1])
    if not keep.all():
        overlap = -(half[a[~keep]] + half[b[~keep]])
        k = int(np.argmin(overlap))
        out.update(joint_gap=float(overlap[k]),
                   joint_pair=[int(a[~keep][k]), int(b[~keep][k])])
    a, b = a[keep], b[keep]
    lower = _box_gap(bar_lo[a], bar_hi[a], bar_lo[b], bar_hi[b]) - half[a] - half[b]

    def bars(xs, idx):
        ia, ib = edges[a[idx]], edges[b[idx]]
        return segment_gap(xs[:, ia[:, 0]], xs[:, ia[:, 1]], xs[:, ib[:, 0]],
                           xs[:, ib[:, 1]]) - half[a[idx]] - half[b[idx]]

    gap, k, s = _least(len(a), lower, bars, x)
    if k >= 0:
        out.update(bar_gap=gap, bar_pair=[int(a[k]), int(b[k])], sample=s)
    if not columns or not len(columns["joints"]):
        return out
    jid = np.asarray(columns["joints"], dtype=np.int64)
    low, high = np.asarray(columns["low"]), np.asarray(columns["high"])
    in_lo, in_hi = np.asarray(columns["inner_low"]), np.asarray(columns["inner_high"])
    r, r_in = float(columns["radius"]), float(columns["inner_radius"])
    # a bar and a column whose layers it occupies, the column not at one of its joints
    bb_parts, jk_parts = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for z in np.unique(layer):
        on, over = np.flatnonzero(layer == z), np.flatnonzero((low <= z) & (high >= z))
        bb_parts.append(np.repeat(on, over.size))
        jk_parts.append(np.tile(over, on.size))
    bb, jk = np.concatenate(bb_parts), np.concatenate(jk_parts)
    keep = (edges[bb, 0] != jid[jk]) & (edges[bb, 1] != jid[jk])
    bb, jk = bb[keep], jk[keep]
    radius = np.where((layer[bb] >= in_lo[jk]) & (layer[bb] <= in_hi[jk]), max(r, r_in), r)
    lower = _box_gap(bar_lo[bb], bar_hi[bb], lo_n[jid[jk]], hi_n[jid[jk]]) - half[bb] - radius

    def screws(xs, idx):
        e = edges[bb[idx]]
        return point_gap(xs[:, jid[jk[idx]]], xs[:, e[:, 0]], xs[:, e[:, 1]]) \
            - half[bb[idx]] - radius[idx]

    gap, k, _ = _least(len(bb), lower, screws, x)
    if k >= 0:
        out.update(screw_gap=gap, screw_at=[int(bb[k]), int(jid[jk[k]])])
    ia, ib = np.triu_indices(len(jid), k=1)
    keep = (low[ia] <= high[ib]) & (low[ib] <= high[ia])
    ia, ib = ia[keep], ib[keep]
    lower = _box_gap(lo_n[jid[ia]], hi_n[jid[ia]], lo_n[jid[ib]], hi_n[jid[ib]]) - 2.0 * r

    def cols(xs, idx):
        d = xs[:, jid[ia[idx]]] - xs[:, jid[ib[idx]]]
        return np.sqrt((d * d).sum(-1)) - 2.0 * r

    gap, k, _ = _least(len(ia), lower, cols, x)
    if k >= 0:
        out.update(column_gap=gap, column_pair=[int(jid[ia[k]]), int(jid[ib[k]])])
    return out
