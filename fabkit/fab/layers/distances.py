"""Distances between bars and screws over sampled motions, and the pairs worth measuring."""

from __future__ import annotations

import math

import numpy as np

from .constants import _BLOCK, _BLOCK_ELEMENTS

# -- distances ------------------------------------------------------------------------------

def _node_steps(x: np.ndarray) -> np.ndarray:
    """Largest node displacement between consecutive configurations, shape (S-1,).

    Blocked over samples so that no second array of all positions is made (a long chain's
    sampled motion is the largest array of the laser kit)."""
    if x.shape[0] < 2:
        return np.zeros(0)
    out = np.empty(x.shape[0] - 1)
    block = int(max(1, _BLOCK_ELEMENTS // max(1, x.shape[1])))
    for start in range(0, x.shape[0] - 1, block):
        stop = min(start + block, x.shape[0] - 1)
        d = x[start + 1:stop + 1] - x[start:stop]
        out[start:stop] = np.sqrt(_dot(d, d)).max(axis=-1)  # _dot: no numpy reduction
    return out


def point_segment_distance(x, p, q) -> np.ndarray:
    """Distance from points ``x`` to segments ``p``-``q`` (broadcast over leading axes).

    Examples
    --------
    >>> float(point_segment_distance([0.0, 1.0], [-1.0, 0.0], [1.0, 0.0]))
    1.0
    """
    x, p, q = (np.asarray(a, dtype=np.float64) for a in (x, p, q))
    d = q - p
    dd = _dot(d, d)
    t = np.clip(_dot(x - p, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    e = p + t[..., None] * d - x
    return np.sqrt(_dot(e, e))


def _dot(a, b):
    # a sum over a last axis of length 2 or 3 written out: numpy's reduction over such a short
    # axis costs several times the arithmetic (this is the hot loop of the clearance checks)
    out = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]
    if a.shape[-1] == 3:
        out += a[..., 2] * b[..., 2]
    return out


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def segment_distance(p1, q1, p2, q2) -> np.ndarray:
    """Distance between 2D segments ``p1-q1`` and ``p2-q2`` (0 where they cross).

    Examples
    --------
    >>> float(segment_distance([0, 0], [2, 0], [1, -1], [1, 1]))
    0.0
    >>> float(segment_distance([0, 0], [1, 0], [0, 2], [1, 2]))
    2.0
    """
    p1, q1, p2, q2 = (np.asarray(a, dtype=np.float64) for a in (p1, q1, p2, q2))
    d = np.minimum(np.minimum(point_segment_distance(p1, p2, q2), point_segment_distance(q1, p2, q2)),
                   np.minimum(point_segment_distance(p2, p1, q1), point_segment_distance(q2, p1, q1)))
    r, s = q1 - p1, q2 - p2
    o1 = _cross(r, p2 - p1)
    o2 = _cross(r, q2 - p1)
    o3 = _cross(s, p1 - p2)
    o4 = _cross(s, q1 - p2)
    crossing = (o1 * o2 < 0) & (o3 * o4 < 0)
    return np.where(crossing, 0.0, d)


def _min_over_samples(func, positions, *index_arrays):
    """Minimum over samples (and the sample where it occurs) of ``func(x, *index_arrays)``."""
    n = index_arrays[0].shape[0]
    best = np.full(n, np.inf)
    where = np.zeros(n, dtype=np.int64)
    if n == 0:
        return best, where
    # samples per block so that one (block, n) array stays within the budget: the kernels make
    # about a dozen of them, and n (pairs) grows with the square of the kit
    block = int(max(1, min(_BLOCK, _BLOCK_ELEMENTS // n)))
    for start in range(0, positions.shape[0], block):
        x = positions[start:start + block]
        d = func(x, *index_arrays)  # (block, n)
        k = np.argmin(d, axis=0)
        v = d[k, np.arange(n)]
        better = v < best
        best[better] = v[better]
        where[better] = k[better] + start
    return best, where


def _pruned_min(func, positions, threshold: float, *index_arrays, stride: int = 32):
    """Like :func:`_min_over_samples`, but scans every sample only for index pairs that can come
    below ``threshold``.

    Between a sample and the nearest of every ``stride``-th sample each point moves at most
    ``stride / 2`` largest steps, so a distance between two moving points (or point sets) can
    be at most ``stride x`` the largest node step smaller than at that coarse sample. Pairs whose
    coarse minimum exceeds ``threshold`` by that much are left out of the full scan (their
    reported minimum is the coarse one, an upper bound above the threshold).
    """
    n = index_arrays[0].shape[0]
    s = positions.shape[0]
    if n == 0 or s <= 2 * stride:
        return _min_over_samples(func, positions, *index_arrays)
    step = float(_node_steps(positions).max())
    coarse_idx = np.unique(np.r_[np.arange(0, s, stride), s - 1])
    best, where = _min_over_samples(func, positions[coarse_idx], *index_arrays)
    where = coarse_idx[where]
    maybe = np.flatnonzero(best - stride * step < threshold)
    if maybe.size:
        b2, w2 = _min_over_samples(func, positions, *(a[maybe] for a in index_arrays))
        best[maybe], where[maybe] = b2, w2
    return best, where


def _least(func, positions, offset, *index_arrays, stride: int = 32):
    """The smallest ``func - offset`` over samples and index pairs, exactly, and where.

    Every pair is first measured at every ``stride``-th sample; between those a distance can
    shrink by at most ``stride x`` the largest node step (see :func:`_pruned_min`), so only the
    pairs whose coarse minimum comes that close to the smallest coarse minimum of all can hold
    the overall minimum, and only they are measured at every sample. The result is the full
    scan's (:func:`_min_over_samples`).

    Returns
    -------
    (value, k, sample) : (float, int, int)
        The minimum, the pair (index into ``index_arrays``) and the sample where it occurs;
        ``(inf, -1, -1)`` for no pairs.
    """
    n = index_arrays[0].shape[0]
    if n == 0:
        return math.inf, -1, -1
    offset = np.broadcast_to(np.asarray(offset, dtype=np.float64), (n,))
    s = positions.shape[0]
    if s <= 2 * stride:
        maybe = np.arange(n)
    else:
        step = float(_node_steps(positions).max())
        coarse_idx = np.unique(np.r_[np.arange(0, s, stride), s - 1])
        coarse, _ = _min_over_samples(func, positions[coarse_idx], *index_arrays)
        coarse = coarse - offset
        maybe = np.flatnonzero(coarse - stride * step <= coarse.min())
    best, where = _min_over_samples(func, positions, *(a[maybe] for a in index_arrays))
    best = best - offset[maybe]
    k = int(np.argmin(best))
    return float(best[k]), int(maybe[k]), int(where[k])


def _bar_bar(edges):
    """Kernel: segment distance between bars a and b at every sample of a block."""
    def kernel(x, a, b):
        return segment_distance(x[:, edges[a, 0]], x[:, edges[a, 1]],
                                x[:, edges[b, 0]], x[:, edges[b, 1]])
    return kernel


def _incidence(edges: np.ndarray, n_nodes: int) -> np.ndarray:
    inc = np.zeros((n_nodes, edges.shape[0]), dtype=bool)
    inc[edges[:, 0], np.arange(edges.shape[0])] = True
    inc[edges[:, 1], np.arange(edges.shape[0])] = True
    return inc


def _joint_pairs(edges: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (a < b) of bars that share a joint, in the order of ``np.triu_indices``."""
    ends = np.concatenate([edges[:, 0], edges[:, 1]])
    bars = np.concatenate([np.arange(edges.shape[0])] * 2)
    order = np.lexsort((bars, ends))
    ends, bars = ends[order], bars[order]
    bounds = np.flatnonzero(np.diff(np.r_[-1, ends, n_nodes + 1]))
    pa, pb = [], []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        group = bars[lo:hi]
        if group.size >= 2:
            i, j = np.triu_indices(group.size, k=1)
            pa.append(group[i])
            pb.append(group[j])
    if not pa:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    a, b = np.concatenate(pa), np.concatenate(pb)
    key = np.unique(a * edges.shape[0] + b)  # two bars share at most one joint; sorted as triu
    return key // edges.shape[0], key % edges.shape[0]


def _share_joint(edges: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """True where bars a[k] and b[k] share a joint (from their ends: O(pairs), where an
    incidence-matrix product would hold nodes x pairs booleans)."""
    e0, e1 = edges[:, 0], edges[:, 1]
    return (e0[a] == e0[b]) | (e0[a] == e1[b]) | (e1[a] == e0[b]) | (e1[a] == e1[b])


def _box_pairs(lo_a, hi_a, lo_b, hi_b, reach: float, *, same: bool = False):
    """Index pairs (i, j) whose boxes ``[lo_a[i], hi_a[i]]`` and ``[lo_b[j], hi_b[j]]`` come
    within ``reach`` of each other in x and in y (``same``: one set, i < j).

    Sort and sweep along x: box j can reach box i only if its left edge lies in
    ``[lo_a[i] - reach - W, hi_a[i] + reach]`` with W the widest box of set b, so each box meets
    its neighbours along x, not the whole set: linear in the kit for chains and lattices,
    where the pairs of all bars grow with its square.
    """
    lo_a, hi_a = np.asarray(lo_a, dtype=np.float64), np.asarray(hi_a, dtype=np.float64)
    lo_b, hi_b = np.asarray(lo_b, dtype=np.float64), np.asarray(hi_b, dtype=np.float64)
    if lo_a.shape[0] == 0 or lo_b.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    order = np.argsort(lo_b[:, 0], kind="stable")
    left = lo_b[order, 0]
    widest = float((hi_b[:, 0] - lo_b[:, 0]).max())
    start = np.searchsorted(left, lo_a[:, 0] - reach - widest, side="left")
    stop = np.searchsorted(left, hi_a[:, 0] + reach, side="right")
    counts = np.maximum(stop - start, 0)
    total = int(counts.sum())
    i = np.repeat(np.arange(lo_a.shape[0]), counts)
    first = np.repeat(start - np.cumsum(counts) + counts, counts)
    j = order[first + np.arange(total)]
    near = ((lo_a[i] - reach <= hi_b[j]) & (lo_b[j] - reach <= hi_a[i])).all(axis=1)
    if same:
        near &= i < j
    i, j = i[near], j[near]
    order = np.lexsort((j, i))  # (i, j) ascending: the order of the full enumeration
    return i[order], j[order]


def _exact_least(func, x, offset, pairs_within, lower_bound_reach, start_reach: float,
                 limit_reach: float):
    """The smallest ``func - offset`` over samples and pairs, exactly, looking only at pairs
    whose swept boxes come within a reach that grows until it provably holds the minimum.

    ``pairs_within(reach)`` gives the index arrays of the pairs within ``reach``;
    ``lower_bound_reach(value)`` turns a found minimum into the reach beyond which no pair can
    do better (a distance is never below its boxes' distance). Stops when the found minimum
    lies within the reach searched, or when the reach covers everything (``limit_reach``).

    Returns
    -------
    (value, k, sample, arrays) : the minimum, the pair, the sample, and the index arrays
    searched last (``k`` indexes them); ``(inf, -1, -1, arrays)`` when there is no pair.
    """
    reach = start_reach
    while True:
        arrays = pairs_within(reach)
        value, k, where = _least(func, x, offset(arrays) if callable(offset) else offset,
                                 *arrays)
        if (k >= 0 and lower_bound_reach(value) <= reach) or reach >= limit_reach:
            return value, k, where, arrays
        reach = min(4.0 * reach, limit_reach)


