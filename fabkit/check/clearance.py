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

Only the pairs that come near are measured, and only where they do: the samples are taken in
windows of a few (:data:`WINDOW_SAMPLES`), each part boxed over a window, and a sort and sweep
per window and layer keeps the pairs whose boxes come within a reach; the reach grows until the
smallest gap found lies within it, each time measuring only what the smaller reach left out. A
gap is never below the distance of the parts' boxes, so the answer (smallest gap, which parts,
which sample; ties to the earliest sample, then the lowest pair) is that of measuring every
pair at every sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import FabkitError
from ..kinematics import place, trace
from ..kinematics.constructive import cached_plan
from .motion import same_trace

__all__ = ["FineMotion", "fine_motion", "same_layer_gaps", "segment_gap", "point_gap"]

#: Most samples of one motion (the samples of a long chain are the largest array of a check).
MAX_SAMPLES = 200_000
#: Elements of one block of pair-by-sample distances (bounds the memory of a measurement).
BLOCK_ELEMENTS = 2**21
#: Pairs at samples measured at once (a dozen temporaries of this length).
MEASURE_ELEMENTS = 2**18
#: Slack (mm) on the box distances that choose the pairs to measure: far above the rounding of
#: coordinates of a few metres, so rounding never leaves out a pair that holds the minimum.
BOX_SLACK = 1e-6
#: Samples boxed together: a part's box over a window is little larger than at one sample
#: (joints move a quarter of the clearance per sample), and the boxes to sort are that many times
#: fewer. Measured on the bundled laser kits' checks: 16 samples 0.8 s, 64 samples 0.4 s, 128
#: no better (the boxes then take in more pairs than the sort saves).
WINDOW_SAMPLES = 64
#: Growth of the reach searched per round when no gap is found within it.
REACH_GROWTH = 4.0


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
    return _step_lengths(np.diff(x, axis=0))


def _pair_steps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Largest joint move from each configuration of ``a`` to the same one of ``b``, as
    :func:`joint_steps` measures it."""
    return _step_lengths(b - a)


def _step_lengths(d: np.ndarray) -> np.ndarray:
    """Largest length of the moves ``d`` (..., N, 2) over their joints, shape (...,): the two
    components squared and added (the bits of a sum over the last axis, without numpy's slow
    reduction over an axis of two)."""
    return np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]).max(axis=-1)


def _extent(a: np.ndarray, reduce) -> np.ndarray:
    """``reduce`` (``np.min`` or ``np.max``) of ``a`` (..., 2) over every axis but the last,
    component by component (a reduction that keeps an axis of two is ten times slower)."""
    return np.array([reduce(a[..., 0]), reduce(a[..., 1])])


def fine_motion(net, motion, scale: float, limit: float, *, floor: float | None = None,
                traced=None) -> FineMotion:
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
    traced : Trajectory, optional
        The network's motion as traced already (the re-simulation the check compared with the
        design's, :func:`fabkit.check.motion.compare_motion`): sampled from, not traced again,
        when its method is the one ``motion`` traces with (under ``"auto"``, the one chosen).

    Raises
    ------
    FabkitError
        No target; a state the drive cannot parametrise (joints jump while the drive stands
        still); more than :data:`MAX_SAMPLES` samples.
    """
    if motion.to is None:
        raise FabkitError("the design gives no motion target (motion.to): nothing to sample")
    traj = traced if same_trace(net, motion, traced) else \
        trace(net, drive=motion.drive, to=motion.to, method=motion.method, hold=motion.hold,
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
    # the plan the trace found (remembered on the network), not a second search for it
    plan = cached_plan(problem.work, problem.drive, problem.start)

    def placer(v):
        return align_to_gauge(place(plan, v)[0], problem.start, problem.gauge)

    values = np.linspace(traj.drive[0], traj.drive[-1], 65)
    x = placer(values)
    steps = joint_steps(x)
    for _ in range(80):
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
        new = placer(mids)
        # only the steps on either side of a new sample change: measured, not every step again
        # (a chain's 40 rounds of bisection measured all of its samples 40 times)
        left, right = _pair_steps(x[bad], new), _pair_steps(new, x[bad + 1])
        x = np.insert(x, bad + 1, new, axis=0)
        values = np.insert(values, bad + 1, mids)
        steps[bad] = left
        steps = np.insert(steps, bad + 1, right)
    raise FabkitError("could not sample the rebuilt network's motion finely enough")


def point_gap(x, p, q) -> np.ndarray:
    """Distance from points ``x`` to segments ``p``-``q`` (broadcast over leading axes)."""
    x, p, q = np.asarray(x), np.asarray(p), np.asarray(q)
    return _point_gap_xy(x[..., 0], x[..., 1], p[..., 0], p[..., 1], q[..., 0], q[..., 1])


def segment_gap(p1, q1, p2, q2) -> np.ndarray:
    """Distance between segments ``p1``-``q1`` and ``p2``-``q2`` in the plane (0 where they
    cross), broadcast over leading axes."""
    p1, q1, p2, q2 = (np.asarray(v) for v in (p1, q1, p2, q2))
    return _segment_gap_xy(p1[..., 0], p1[..., 1], q1[..., 0], q1[..., 1],
                           p2[..., 0], p2[..., 1], q2[..., 0], q2[..., 1])


# The distances are computed on x and y components apart: the same operations in the same order
# as on (..., 2) arrays summed over their last axis (a + b of two terms), so the same bits, but
# without numpy's slow reduction over an axis of two.

def _segment_frame(px, py, qx, qy):
    """(dx, dy, dd) of segments ``p``-``q``: their direction and its squared length (1 for a
    segment of no length, whose parameter is then 0)."""
    dx, dy = qx - px, qy - py
    dd = dx * dx + dy * dy
    return dx, dy, np.where(dd > 0, dd, 1.0)


def _point_gap_xy(xx, xy, px, py, qx, qy, frame=None) -> np.ndarray:
    """:func:`point_gap` on components; ``frame``: :func:`_segment_frame` of the segments."""
    dx, dy, dd = _segment_frame(px, py, qx, qy) if frame is None else frame
    t = np.clip(((xx - px) * dx + (xy - py) * dy) / dd, 0.0, 1.0)
    ex, ey = px + t * dx - xx, py + t * dy - xy
    return np.sqrt(ex * ex + ey * ey)


def _segment_gap_xy(p1x, p1y, q1x, q1y, p2x, p2y, q2x, q2y) -> np.ndarray:
    """:func:`segment_gap` on components."""
    f1, f2 = _segment_frame(p1x, p1y, q1x, q1y), _segment_frame(p2x, p2y, q2x, q2y)
    d = np.minimum(np.minimum(_point_gap_xy(p1x, p1y, p2x, p2y, q2x, q2y, f2),
                              _point_gap_xy(q1x, q1y, p2x, p2y, q2x, q2y, f2)),
                   np.minimum(_point_gap_xy(p2x, p2y, p1x, p1y, q1x, q1y, f1),
                              _point_gap_xy(q2x, q2y, p1x, p1y, q1x, q1y, f1)))

    def side(ax, ay, bx, by, cx, cy):  # sign of the turn a -> b -> c
        return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)

    crossing = ((side(p1x, p1y, q1x, q1y, p2x, p2y) * side(p1x, p1y, q1x, q1y, q2x, q2y) < 0)
                & (side(p2x, p2y, q2x, q2y, p1x, p1y) * side(p2x, p2y, q2x, q2y, q1x, q1y) < 0))
    return np.where(crossing, 0.0, d)


def _components(x):
    """The x and y coordinates of ``x`` (S, N, 2), each flat and contiguous (gathered by flat
    index ``s * N + joint``, :func:`_at`)."""
    return np.ascontiguousarray(x[..., 0]).ravel(), np.ascontiguousarray(x[..., 1]).ravel()


def _at(xs, row, joint):
    """``x[s, joint]`` as (x, y) components of :func:`_components` ``xs``, given ``row = s * N``:
    one gather by flat index each, several times faster than indexing two axes."""
    flat = row + joint
    return np.take(xs[0], flat), np.take(xs[1], flat)


def _windows(x):
    """Each joint's box over each window of :data:`WINDOW_SAMPLES` samples of ``x``: (lo, hi),
    shape (W, N, 2) each. At every sample of a window a segment lies within the box of its two
    joints' boxes."""
    starts = np.arange(0, x.shape[0], WINDOW_SAMPLES)
    return np.minimum.reduceat(x, starts, axis=0), np.maximum.reduceat(x, starts, axis=0)


def _near(lo, hi, group, rad, reach: float, allowed, done: float = -math.inf):
    """The parts that come near in a window: (window, a, b), a < b, of one group, whose boxes
    ``lo``, ``hi`` (W, M, 2) lie within ``reach + rad[a] + rad[b]`` of each other in x and in y
    in that window, and not within ``done + rad[a] + rad[b]`` (taken at a smaller reach
    already).

    Sort and sweep per window and group along the axis the parts spread most: each box meets
    the boxes that start within its reach along that axis, not the whole layer. Returns None
    when the block of windows would give more than :data:`BLOCK_ELEMENTS` pairs at samples
    (the caller splits it).
    """
    n_s, n_m = lo.shape[:2]
    axis = int(np.argmax(_extent(hi, np.max) - _extent(lo, np.min)))
    run = (np.arange(n_s)[:, None] * (int(group.max() - group.min()) + 1)
           + (group - group.min())[None, :]).ravel()
    start = lo[..., axis].ravel()
    stop = (hi[..., axis] + (rad + reach + float(rad.max()) + 2.0 * BOX_SLACK)[None, :]).ravel()
    order, last = _sweep_order(run, start, stop)
    pos = np.empty_like(order)
    pos[order] = np.arange(order.size)
    counts = np.maximum(last - pos - 1, 0)
    total = int(counts.sum())
    if total * WINDOW_SAMPLES > BLOCK_ELEMENTS and n_s > 1:
        return None
    fi = np.repeat(np.arange(order.size), counts)
    fj = order[np.repeat(pos + 1 - np.cumsum(counts) + counts, counts) + np.arange(total)]
    flat_lo, flat_hi = lo.reshape(-1, 2), hi.reshape(-1, 2)
    a, b = np.minimum(fi % n_m, fj % n_m), np.maximum(fi % n_m, fj % n_m)
    lo_i, lo_j = np.take(flat_lo, fi, axis=0), np.take(flat_lo, fj, axis=0)
    sep = np.maximum(lo_j - np.take(flat_hi, fi, axis=0), lo_i - np.take(flat_hi, fj, axis=0))
    sep = np.maximum(sep[:, 0], sep[:, 1])  # not a reduction over an axis of two: slow
    ok = (sep <= reach + rad[a] + rad[b] + BOX_SLACK) & allowed(a, b)
    if done > -math.inf:
        ok &= ~(sep <= done + rad[a] + rad[b] + BOX_SLACK)
    return fi[ok] // n_m, a[ok], b[ok]


def _sweep_order(run, start, stop):
    """The boxes sorted by run, then start (ties in index order), and where each box's reach
    ends among them: the number of boxes of earlier runs, or of its run starting at or before
    its ``stop``.

    One stable sort of the starts and stops together ranks them (a stop after the starts it
    equals); a run and a rank make one whole-number key, so the boxes sort on it alone, and each
    stop's place among the sorted starts is a binary search: the order of sorting on run, start
    and index, without sorts on several keys.
    """
    n = start.size
    rank = np.empty(2 * n, dtype=np.int64)
    rank[np.argsort(np.concatenate([start, stop]), kind="stable")] = np.arange(2 * n)
    base = run.astype(np.int64) * (2 * n)
    keys = base + rank[:n]
    order = np.argsort(keys, kind="stable")
    return order, np.searchsorted(keys[order], base + rank[n:])


def _least(x, ends, group, rad, allowed, measure, reach: float, windows=None):
    """Smallest gap over samples and pairs of parts, exactly, and where.

    Parts are segments between joints (``ends``, a column from its joint to itself) in
    ``group`` (a layer), ``rad`` the half width each part adds to its segment; ``allowed(a, b)``
    says which pairs count and ``measure(x, s, a, b)`` gives their gaps at samples ``s``, never
    below the distance of their boxes less ``rad[a] + rad[b]``. Per block of samples only the
    pairs whose boxes come within a reach in a window of samples (:func:`_near`) are measured,
    and only at the samples of that window; the reach grows until the smallest gap found lies
    within it (no pair left out can then do better) or it covers the whole motion, or no pair
    within it can beat the smallest gap of the blocks before. A grown reach measures only the
    pairs and windows the smaller one left out, and so do the halves of a block split at a
    grown reach. Ties go to the earliest sample, then the lowest pair. ``windows``:
    :func:`_windows` of ``x`` when the caller boxed it already.

    Returns
    -------
    (gap, sample, a, b)
        ``(inf, -1, -1, -1)`` when no pair counts.
    """
    best = (math.inf, -1, -1, -1)
    if ends.shape[0] < 2:
        return best
    lo_all, hi_all = _extent(x, np.min), _extent(x, np.max)
    limit = float((hi_all - lo_all).max())
    joint_lo, joint_hi = _windows(x) if windows is None else windows
    size = WINDOW_SAMPLES * max(1, BLOCK_ELEMENTS // (8 * ends.shape[0]))
    # (first sample, end, reach measured already, reach to measure next)
    todo = [(s, min(s + size, x.shape[0]), -math.inf, reach)
            for s in range(0, x.shape[0], size)][::-1]
    while todo:
        s0, s1, done, r = todo.pop()
        if done >= best[0]:  # no pair farther than done apart can beat best
            continue
        w0, w1 = s0 // WINDOW_SAMPLES, -(-s1 // WINDOW_SAMPLES)
        lo = np.minimum(joint_lo[w0:w1, ends[:, 0]], joint_lo[w0:w1, ends[:, 1]])
        hi = np.maximum(joint_hi[w0:w1, ends[:, 0]], joint_hi[w0:w1, ends[:, 1]])
        r = min(r, best[0])
        while True:
            near = _near(lo, hi, group, rad, r, allowed, done)
            if near is None:  # too many candidates at once: half the windows each
                mid = s0 + (lo.shape[0] // 2) * WINDOW_SAMPLES
                todo += [(mid, s1, done, r), (s0, mid, done, r)]
                break
            w, a, b = near
            s = (s0 + WINDOW_SAMPLES * w)[:, None] + np.arange(WINDOW_SAMPLES)
            inside = s < s1
            per = inside.sum(1)
            s, a, b = s[inside], np.repeat(a, per), np.repeat(b, per)
            best = _smallest(measure, x, s, a, b, best)
            # every pair within r measured: none left out can beat best once it lies within r
            if r >= min(best[0], limit):
                break
            done, r = r, min(REACH_GROWTH * max(r, BOX_SLACK), best[0], limit)
    return best


def _smallest(measure, x, s, a, b, best):
    """``best`` (gap, sample, a, b) updated with the gaps measured at (s, a, b)."""
    for k in range(0, s.size, MEASURE_ELEMENTS):
        g = measure(x, s[k:k + MEASURE_ELEMENTS], a[k:k + MEASURE_ELEMENTS],
                    b[k:k + MEASURE_ELEMENTS])
        i = np.flatnonzero(g == g.min()) + k
        first = i[np.lexsort((b[i], a[i], s[i]))[0]]
        best = min(best, (float(g.min()), int(s[first]), int(a[first]), int(b[first])))
    return best


def _layer_pairs(layer):
    """Every pair of bars (a < b) on one layer, formed layer by layer."""
    out_a, out_b = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for z in np.unique(layer):
        idx = np.flatnonzero(layer == z)
        i, j = np.triu_indices(idx.size, k=1)
        out_a.append(idx[i])
        out_b.append(idx[j])
    return np.concatenate(out_a), np.concatenate(out_b)


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
    x = np.ascontiguousarray(x)
    comps = _components(x)  # gathered by flat index (:func:`_at`)
    n_joints = x.shape[1]
    reach = 2.0 * float(half.max(initial=0.0))  # a bar's width: where neighbours stand
    out = {"bar_gap": math.inf, "bar_pair": None, "sample": None, "joint_gap": math.inf,
           "joint_pair": None, "screw_gap": math.inf, "screw_at": None, "column_gap": math.inf,
           "column_pair": None}
    # bar pairs of one layer (formed layer by layer) on a shared joint overlap there
    a, b = _layer_pairs(layer)
    keep = _apart(edges[a], edges[b])
    if not keep.all():
        overlap = -(half[a[~keep]] + half[b[~keep]])
        k = int(np.argmin(overlap))
        out.update(joint_gap=float(overlap[k]),
                   joint_pair=[int(a[~keep][k]), int(b[~keep][k])])

    def bars(_, s, i, j):
        ei, ej, row = np.take(edges, i, axis=0), np.take(edges, j, axis=0), s * n_joints
        return _segment_gap_xy(*_at(comps, row, ei[:, 0]), *_at(comps, row, ei[:, 1]),
                               *_at(comps, row, ej[:, 0]), *_at(comps, row, ej[:, 1])) \
            - half[i] - half[j]

    boxes = _windows(x)  # the joints boxed once for the three searches
    gap, s, i, j = _least(x, edges, layer, half, lambda i, j: _apart(edges[i], edges[j]), bars,
                          reach, boxes)
    if i >= 0:
        out.update(bar_gap=gap, bar_pair=[i, j], sample=s)
    if not columns or not len(columns["joints"]):
        return out
    jid = np.asarray(columns["joints"], dtype=np.int64)
    low, high = np.asarray(columns["low"]), np.asarray(columns["high"])
    in_lo, in_hi = np.asarray(columns["inner_low"]), np.asarray(columns["inner_high"])
    r, r_in = float(columns["radius"]), float(columns["inner_radius"])
    # a column stands on every layer from its low to its high one: one part per layer
    col = np.repeat(np.arange(len(jid)), np.maximum(high - low + 1, 0))
    z = low[col] + np.arange(col.size) - np.repeat(np.cumsum(high - low + 1) - (high - low + 1),
                                                   np.maximum(high - low + 1, 0))
    radius = np.where((z >= in_lo[col]) & (z <= in_hi[col]), max(r, r_in), r)
    # a bar and a column whose layers it occupies, the column not at one of its joints
    n_e = len(edges)
    ends = np.concatenate([edges, np.stack([jid[col], jid[col]], axis=1)])

    def bar_and_column(i, j):  # i < j: i a bar, j a column
        return (i < n_e) & (j >= n_e) & _apart(ends[i], ends[j])

    def screws(_, s, i, j):
        e, row = np.take(edges, i, axis=0), s * n_joints
        return _point_gap_xy(*_at(comps, row, ends[j, 0]), *_at(comps, row, e[:, 0]),
                             *_at(comps, row, e[:, 1])) - half[i] - radius[j - n_e]

    gap, s, i, j = _least(x, ends, np.concatenate([layer, z]), np.concatenate([half, radius]),
                          bar_and_column, screws, reach, boxes)
    if i >= 0:
        out.update(screw_gap=gap, screw_at=[i, int(jid[col[j - n_e]])])
    # two columns that share a layer (met on each layer they share; the first is kept)

    def cols(_, s, i, j):
        row = s * n_joints
        (ax, ay), (bx, by) = _at(comps, row, jid[col[i]]), _at(comps, row, jid[col[j]])
        dx, dy = ax - bx, ay - by
        return np.sqrt(dx * dx + dy * dy) - 2.0 * r

    gap, s, i, j = _least(x, ends[n_e:], z, np.full(col.size, r), lambda i, j: col[i] != col[j],
                          cols, reach, boxes)
    if i >= 0:
        out.update(column_gap=gap, column_pair=[int(jid[col[i]]), int(jid[col[j]])])
    return out


def _apart(e, f) -> np.ndarray:
    """True where segments with joints ``e`` (K, 2) and ``f`` (K, 2) share no joint."""
    return (e[:, 0] != f[:, 0]) & (e[:, 0] != f[:, 1]) & (e[:, 1] != f[:, 0]) \
        & (e[:, 1] != f[:, 1])
