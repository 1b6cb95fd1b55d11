"""Distances between bars and screws over sampled motions, and the pairs worth measuring."""

from __future__ import annotations

import math

import numpy as np

from .constants import BLOCK_ELEMENTS, BLOCK_SAMPLES

# -- distances ------------------------------------------------------------------------------

def node_steps(x: np.ndarray) -> np.ndarray:
    """Largest node displacement between consecutive configurations.

    Blocked over samples so that no second array of all positions is made (a long chain's
    sampled motion is the largest array of the laser kit).

    Parameters
    ----------
    x : numpy.ndarray, shape (S, N, d)
        Sampled configurations of the motion.

    Returns
    -------
    numpy.ndarray, shape (S-1,)
        The largest distance any node moves from sample k to sample k + 1 (empty for S < 2).
    """
    if x.shape[0] < 2:
        return np.zeros(0)
    out = np.empty(x.shape[0] - 1)
    block = int(max(1, BLOCK_ELEMENTS // max(1, x.shape[1])))
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


def min_over_samples(func, positions, *index_arrays):
    """Minimum over samples (and the sample where it occurs) of ``func(x, *index_arrays)``.

    Parameters
    ----------
    func : callable
        Kernel ``func(x, *index_arrays)`` giving an array (block, n) for a block ``x`` of
        samples, e.g. :func:`bar_distance_kernel`.
    positions : numpy.ndarray, shape (S, N, d)
        Sampled configurations, measured a block of samples at a time.
    *index_arrays : numpy.ndarray, shape (n,)
        Index arrays handed to ``func`` (the pairs measured).

    Returns
    -------
    best : numpy.ndarray, shape (n,)
        The minimum of each pair over all samples (``inf`` for none).
    where : numpy.ndarray of int, shape (n,)
        The sample where it occurs.
    """
    n = index_arrays[0].shape[0]
    best = np.full(n, np.inf)
    where = np.zeros(n, dtype=np.int64)
    if n == 0:
        return best, where
    # samples per block so that one (block, n) array stays within the budget: the kernels make
    # about a dozen of them, and n (pairs) grows with the square of the kit
    block = int(max(1, min(BLOCK_SAMPLES, BLOCK_ELEMENTS // n)))
    for start in range(0, positions.shape[0], block):
        x = positions[start:start + block]
        d = func(x, *index_arrays)  # (block, n)
        k = np.argmin(d, axis=0)
        v = d[k, np.arange(n)]
        better = v < best
        best[better] = v[better]
        where[better] = k[better] + start
    return best, where


def pruned_min_over_samples(func, positions, threshold: float, *index_arrays, stride: int = 32):
    """Like :func:`min_over_samples`, but scans every sample only for index pairs that can come
    below ``threshold``.

    Between a sample and the nearest of every ``stride``-th sample each point moves at most
    ``stride / 2`` largest steps, so a distance between two moving points (or point sets) can
    be at most ``stride x`` the largest node step smaller than at that coarse sample. Pairs whose
    coarse minimum exceeds ``threshold`` by that much are left out of the full scan (their
    reported minimum is the coarse one, an upper bound above the threshold).

    Parameters
    ----------
    func, positions, *index_arrays
        As in :func:`min_over_samples`.
    threshold : float
        Pairs that can come below this are measured at every sample.
    stride : int
        Every ``stride``-th sample is measured for all pairs first.

    Returns
    -------
    best, where : numpy.ndarray, shape (n,)
        As in :func:`min_over_samples`: exact below ``threshold``, an upper bound above it.
    """
    n = index_arrays[0].shape[0]
    s = positions.shape[0]
    if n == 0 or s <= 2 * stride:
        return min_over_samples(func, positions, *index_arrays)
    step = float(node_steps(positions).max())
    coarse_idx = np.unique(np.r_[np.arange(0, s, stride), s - 1])
    best, where = min_over_samples(func, positions[coarse_idx], *index_arrays)
    where = coarse_idx[where]
    maybe = np.flatnonzero(best - stride * step < threshold)
    if maybe.size:
        b2, w2 = min_over_samples(func, positions, *(a[maybe] for a in index_arrays))
        best[maybe], where[maybe] = b2, w2
    return best, where


def _least(func, positions, offset, *index_arrays, stride: int = 32):
    """The smallest ``func - offset`` over samples and index pairs, exactly, and where.

    Every pair is first measured at every ``stride``-th sample; between those a distance can
    shrink by at most ``stride x`` the largest node step (see :func:`pruned_min_over_samples`),
    so only the pairs whose coarse minimum comes that close to the smallest coarse minimum of
    all can hold the overall minimum, and only they are measured at every sample. The result is
    the full scan's (:func:`min_over_samples`).

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
        step = float(node_steps(positions).max())
        coarse_idx = np.unique(np.r_[np.arange(0, s, stride), s - 1])
        coarse, _ = min_over_samples(func, positions[coarse_idx], *index_arrays)
        coarse = coarse - offset
        maybe = np.flatnonzero(coarse - stride * step <= coarse.min())
    best, where = min_over_samples(func, positions, *(a[maybe] for a in index_arrays))
    best = best - offset[maybe]
    k = int(np.argmin(best))
    return float(best[k]), int(maybe[k]), int(where[k])


def bar_distance_kernel(edges):
    """Kernel of the segment distance between bars, for :func:`min_over_samples`.

    Parameters
    ----------
    edges : numpy.ndarray of int, shape (E, 2)
        The bars' end nodes.

    Returns
    -------
    callable
        ``kernel(x, a, b)``: the distance between bars ``a[k]`` and ``b[k]`` (centre lines) at
        every sample of a block ``x`` of shape (block, N, d), shape (block, n).
    """
    def kernel(x, a, b):
        return segment_distance(x[:, edges[a, 0]], x[:, edges[a, 1]],
                                x[:, edges[b, 0]], x[:, edges[b, 1]])
    return kernel


def incidence(edges: np.ndarray, n_nodes: int) -> np.ndarray:
    """Node-bar incidence matrix.

    Parameters
    ----------
    edges : numpy.ndarray of int, shape (E, 2)
        The bars' end nodes.
    n_nodes : int
        Number of nodes N.

    Returns
    -------
    numpy.ndarray of bool, shape (N, E)
        True where node i is an end of bar e.
    """
    inc = np.zeros((n_nodes, edges.shape[0]), dtype=bool)
    inc[edges[:, 0], np.arange(edges.shape[0])] = True
    inc[edges[:, 1], np.arange(edges.shape[0])] = True
    return inc


def bars_sharing_joints(edges: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (a < b) of bars that share a joint, in the order of ``np.triu_indices``.

    Parameters
    ----------
    edges : numpy.ndarray of int, shape (E, 2)
        The bars' end nodes.
    n_nodes : int
        Number of nodes.

    Returns
    -------
    a, b : numpy.ndarray of int, shape (P,)
        The bars of each pair, ``a < b``.
    """
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


def share_joint(edges: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """True where bars a[k] and b[k] share a joint.

    Read from the bars' ends: O(pairs), where an incidence-matrix product would hold
    nodes x pairs booleans.

    Parameters
    ----------
    edges : numpy.ndarray of int, shape (E, 2)
        The bars' end nodes.
    a, b : numpy.ndarray of int, shape (n,)
        The bars of each pair.

    Returns
    -------
    numpy.ndarray of bool, shape (n,)
    """
    e0, e1 = edges[:, 0], edges[:, 1]
    return (e0[a] == e0[b]) | (e0[a] == e1[b]) | (e1[a] == e0[b]) | (e1[a] == e1[b])


def box_pairs(lo_a, hi_a, lo_b, hi_b, reach: float, *, same: bool = False):
    """Index pairs (i, j) whose boxes ``[lo_a[i], hi_a[i]]`` and ``[lo_b[j], hi_b[j]]`` come
    within ``reach`` of each other in x and in y (``same``: one set, i < j).

    Sort and sweep along x: box j can reach box i only if its left edge lies in
    ``[lo_a[i] - reach - W, hi_a[i] + reach]`` with W the widest box of set b, so each box meets
    its neighbours along x, not the whole set: linear in the kit for chains and lattices,
    where the pairs of all bars grow with its square.

    Parameters
    ----------
    lo_a, hi_a : array_like, shape (A, 2)
        Lower and upper corners of the boxes of set a.
    lo_b, hi_b : array_like, shape (B, 2)
        Lower and upper corners of the boxes of set b.
    reach : float
        Boxes this far apart (in x and in y) still count as near.
    same : bool
        Sets a and b are one set: each pair once, ``i < j``.

    Returns
    -------
    i, j : numpy.ndarray of int
        The pairs of near boxes, sorted by ``i`` then ``j``.
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


def exact_least(func, x, offset, pairs_within, lower_bound_reach, start_reach: float,
                 limit_reach: float):
    """The smallest ``func - offset`` over samples and pairs, exactly, looking only at pairs
    whose swept boxes come within a reach that grows until it provably holds the minimum.

    ``pairs_within(reach)`` gives the index arrays of the pairs within ``reach``;
    ``lower_bound_reach(value)`` turns a found minimum into the reach beyond which no pair can
    do better (a distance is never below its boxes' distance). Stops when the found minimum
    lies within the reach searched, or when the reach covers everything (``limit_reach``).

    Parameters
    ----------
    func : callable
        Kernel as in :func:`min_over_samples`.
    x : numpy.ndarray, shape (S, N, d)
        Sampled configurations.
    offset : float, array_like or callable
        Subtracted from each pair's distance (e.g. the bar width); a callable gets the index
        arrays and returns the offsets.
    pairs_within : callable
        ``pairs_within(reach)``: the index arrays of the pairs within ``reach``.
    lower_bound_reach : callable
        ``lower_bound_reach(value)``: the reach beyond which no pair can go below ``value``.
    start_reach, limit_reach : float
        The first reach searched (multiplied by 4 each round) and the reach that covers all.

    Returns
    -------
    (value, k, sample, arrays) : (float, int, int, tuple)
        The minimum, the pair, the sample, and the index arrays searched last (``k`` indexes
        them); ``(inf, -1, -1, arrays)`` when there is no pair.
    """
    reach = start_reach
    while True:
        arrays = pairs_within(reach)
        value, k, where = _least(func, x, offset(arrays) if callable(offset) else offset,
                                 *arrays)
        if (k >= 0 and lower_bound_reach(value) <= reach) or reach >= limit_reach:
            return value, k, where, arrays
        reach = min(4.0 * reach, limit_reach)


