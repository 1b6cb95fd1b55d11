"""Independent edges: a set of rank(R) edges whose rows of the rigidity matrix are independent,
found without a dense factorisation (a windowed echelon selection along the band of R), checked,
with a dense column-pivoted QR as the fallback for small networks.

A network with states of self-stress has more edges than a square system has room for; the
continuation (:mod:`fabkit.kinematics.projected`) keeps these and watches the others.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import rigidity
from ..errors import KinematicsError, NetworkError
from .network import Network
from ..numerics import RANK_RTOL
from ..numerics import one_blas_thread
from .matrix import (AMBIGUOUS_GAP, Undecided, require_dense_memory, rigidity_matrix, sigma_max,
                     smallest_singular)
from .rigidity import count_modes

__all__ = ["independent_edges", "BLOCK_PER_BAND", "MIN_BLOCK", "DEFER_RTOL", "DEFER_BANDS"]

#: Rows (edges) per block of the windowed selection in :func:`independent_edges`, as a fraction
#: of the band (in columns), and at least ``MIN_BLOCK``: a block much wider than the band lets
#: the pivoted QR keep rows far ahead first and left the 100 × 100 lattice's kept rows 20 times
#: worse conditioned (measured); a much narrower one repeats the SVD on the window too often.
BLOCK_PER_BAND = 1 / 3
MIN_BLOCK = 32

#: A row whose distance from the span of the rows kept so far is below this fraction of its norm
#: (but above the rank threshold) waits for later rows: kept at once, such nearly dependent rows
#: made the kept set of random over-braced networks 100-1000 times worse conditioned than a
#: global column-pivoted QR's; waiting brings it within a factor of about 3 (measured).
DEFER_RTOL = 0.3

#: How far, in bands of columns, the window may move past a waiting row before it is decided.
DEFER_BANDS = 4.0


def _band_positions(edges: np.ndarray, n: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """First column of each edge's two end nodes once the nodes are ordered by reverse
    Cuthill-McKee (the order ``projected`` factorises in) and coordinates node by node."""
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    e = edges.shape[0]
    graph = sp.coo_matrix((np.ones(e), (edges[:, 0], edges[:, 1])), shape=(n, n))
    order = reverse_cuthill_mckee((graph + graph.T).tocsr(), symmetric_mode=True)
    pos = np.empty(n, dtype=np.int64)
    pos[order] = np.arange(n)
    return d * pos[edges[:, 0]], d * pos[edges[:, 1]]


def _windowed_rows(u: np.ndarray, p0: np.ndarray, p1: np.ndarray, rtol: float,
                   block: int | None = None, defer: float = DEFER_RTOL,
                   reach: float = DEFER_BANDS) -> np.ndarray:
    """Independent rows of the normalised rigidity matrix, one block of rows at a time.

    Row i holds ``u[i]`` at columns ``p0[i] … p0[i]+d-1`` and ``-u[i]`` at ``p1[i] …``. Rows are
    taken in order of their first column ``lo``. ``c`` is an orthonormal basis of the complement,
    within the window of columns ``[wlo, whi)``, of W = span(kept rows) ∩ {supported on columns ≥
    wlo}; a row supported on columns ≥ wlo lies in the span of the kept rows iff it lies in W, iff
    ``cᵀ r = 0``; ``|cᵀ r|`` is its distance from W. Rows farther than ``defer·|r|``
    are kept at once (best first, by a column-pivoted QR); rows between ``rtol·|r|`` and that wait
    for later blocks, whose rows may span their direction better, until the window has moved
    ``reach`` bands past them; rows within ``rtol·|r|`` are dropped. Moving the window to the
    lowest column of the rows still to decide replaces ``c`` by an orthonormal basis (an SVD) of
    its rows on the columns that remain (the complement of W ∩ {supported on columns ≥ lo}).
    """
    e, d = u.shape
    lo, hi = np.minimum(p0, p1), np.maximum(p0, p1) + d
    order = np.lexsort((hi, lo))
    lo_sorted = lo[order]
    band = int((hi - lo).max())
    wait = int(math.ceil(reach * band))  # columns a weak row may wait
    if block is None:
        block = max(MIN_BLOCK, int(math.ceil(BLOCK_PER_BAND * band)))
    offsets = np.arange(d)
    hard, soft = rtol * math.sqrt(2.0), max(defer, rtol) * math.sqrt(2.0)  # rows have norm √2
    wlo = whi = int(lo_sorted[0])
    c = np.zeros((0, 0))
    kept, pending = [], np.zeros(0, dtype=np.int64)

    def project(rows):  # cᵀ r for each row, from c's rows at the row's 2d columns
        a = c[(p0[rows] - wlo)[:, None] + offsets] - c[(p1[rows] - wlo)[:, None] + offsets]
        return np.einsum("md,mdk->km", u[rows], a)

    def keep_above(rows, floor):
        """Keep the rows that add more than ``floor`` to the span, best first; return the rest."""
        nonlocal c
        if not rows.size or not c.shape[1]:
            return rows
        q, r, piv = scipy.linalg.qr(project(rows), mode="full", pivoting=True)
        low = np.flatnonzero(np.abs(np.diag(r)) <= floor)
        added = int(low[0]) if low.size else min(c.shape[1], rows.size)
        kept.append(rows[piv[:added]])
        c = c @ q[:, added:]
        return rows[piv[added:]]

    for start in range(0, e, block):
        rows = order[start:start + block]
        top = int(hi[rows].max())
        if top > whi:  # new coordinates: outside the span of every row kept so far
            grow = top - whi
            c = np.block([[c, np.zeros((c.shape[0], grow))],
                          [np.zeros((grow, c.shape[1])), np.eye(grow)]])
            whi = top
        rest = keep_above(np.concatenate([pending, rows]), soft)
        if rest.size and c.shape[1]:  # distances from the grown span, one row at a time
            rest = rest[np.linalg.norm(project(rest), axis=0) > hard]
        elif not c.shape[1]:
            rest = rest[:0]
        nxt = int(lo_sorted[start + block]) if start + block < e else whi
        due = lo[rest] < nxt - wait if nxt < whi else np.ones(rest.size, dtype=bool)
        keep_above(rest[due], hard)  # what they leave out now lies in the span: dropped
        pending = rest[~due]
        nxt = min(nxt, int(lo[pending].min())) if pending.size else nxt
        if nxt >= whi:  # the next rows start past the window: nothing carries over
            c, wlo, whi = np.zeros((0, 0)), nxt, nxt
        elif nxt > wlo:
            uu, sv, _ = np.linalg.svd(c[nxt - wlo:], full_matrices=False)
            c = uu[:, sv > rtol]
            wlo = nxt
    return np.sort(np.concatenate(kept)) if kept else np.zeros(0, dtype=np.int64)


def _dense_rows(r: sp.csr_matrix, rank: int) -> np.ndarray:
    """The first ``rank`` pivots of a column-pivoted QR of the dense Rᵀ."""
    require_dense_memory(r.shape[1], r.shape[0], what="a dense column-pivoted QR")
    _, _, piv = scipy.linalg.qr(r.T.toarray(), pivoting=True, mode="economic")
    return np.sort(piv[:rank])


def _check_rows(r: sp.csr_matrix, keep: np.ndarray, rank: int, rtol: float) -> float:
    """σ_min of the kept rows, certified well above the rank threshold; raises
    :class:`Undecided` otherwise. Read from ``λ_min(R_S R_Sᵀ)`` (one sparse LU of a matrix of
    the kept edges' size): squaring resolves σ_min above about 1.5e-7·σ_max."""
    if keep.size != rank:
        raise Undecided(f"{keep.size} edges were found independent where the rank is {rank}",
                         keep.size)
    if rank == 0:
        return math.inf
    rs = r[keep]
    smax = sigma_max(rs)
    tol = rtol * max(smax, 1.0)
    try:
        lu = spla.splu((rs @ rs.T).tocsc(), permc_spec="MMD_AT_PLUS_A")
    except RuntimeError:
        raise Undecided("the kept rows are exactly dependent", rank) from None
    sigma = math.sqrt(smallest_singular(lu.solve, lu.solve, rank))
    floor = math.sqrt(100 * np.finfo(float).eps) * smax
    margin = math.sqrt(AMBIGUOUS_GAP)
    if not (sigma >= margin * tol and sigma > floor):
        raise Undecided(f"the kept rows have a smallest singular value of {sigma:.1e}, not "
                         f"above {max(margin * tol, floor):.1e}", rank)
    return sigma


def independent_edges(net: Network, positions=None, *, rank: int | None = None,
                      rtol: float = RANK_RTOL, method: str = "auto",
                      block: int | None = None) -> np.ndarray:
    """Indices of a set of edges whose rows of the rigidity matrix are linearly independent and
    span all its rows (as many as its rank).

    Parameters
    ----------
    net : Network
    positions : array_like, shape (N, d), optional
        Configuration; the reference configuration by default.
    rank : int, optional
        Rank of the rigidity matrix, ``E - S``, when the caller has certified it already (from
        :func:`count_modes`); counted here otherwise.
    rtol : float
        A row counts as dependent on the rows kept before it when its distance from their span
        is at most ``rtol`` times its norm (and the rank decision of :func:`count_modes`).
    method : {"auto", "windowed", "dense"}
        ``"windowed"``: the banded selection below, O(E·b²); ``"dense"``: the first ``rank``
        pivots of a column-pivoted QR of the dense Rᵀ, O(E·(dN)²); ``"auto"``: windowed, and
        dense when the windowed selection fails its check on a network of at most
        :data:`fabkit.model.rigidity.DENSE_LIMIT` coordinates.
    block : int, optional
        Rows per block of the windowed selection; by default a third of the band (at least
        :data:`MIN_BLOCK`).

    Returns
    -------
    numpy.ndarray of int
        ``rank`` edge indices, in increasing order.

    Raises
    ------
    ValueError
        Unknown ``method``.
    NetworkError
        An edge has zero length at ``positions``.
    KinematicsError
        The rank is ambiguous (:func:`count_modes` says so), or the windowed selection fails its
        check where the dense one cannot be used.
    ResourceError
        The dense QR would need more memory than is available.

    Notes
    -----
    Rule (windowed). Nodes are ordered by reverse Cuthill-McKee and coordinates node by node,
    so every row of the row-normalised R̂ lives in a band of columns of width b; rows are taken
    in order of their first column lo. A row r supported on columns ≥ lo lies in the span V of
    the rows kept before it iff it lies in W = V ∩ {vectors supported on columns ≥ lo}: write
    r = a + c with a a combination of the rows kept in earlier blocks and c of this block's
    (supported on columns ≥ lo), then a is supported there too. So the selection carries only
    an orthonormal basis of the complement of W within the window of columns between lo and
    the last column seen. Each block of rows (a third of the band) is projected on that
    complement (the length of a projection is the row's distance from W, at least its distance
    from V); a column-pivoted QR of the projections keeps, best first, the rows whose distance
    exceeds ``DEFER_RTOL`` (0.3) times their norm, and the basis loses their directions.
    Rows closer than that but farther than ``rtol`` times their norm are nearly dependent: they
    wait, and are projected again with the next blocks (whose rows may cover their direction
    better), until the window has moved ``DEFER_BANDS`` (4) bands past them; then they are
    kept by the same QR with the threshold ``rtol``. Rows within ``rtol`` are dropped. When lo
    advances, the basis becomes an orthonormal basis (an SVD) of its rows on the columns that
    remain. Exact in exact arithmetic; the work per block is dense on the window, O(b²) per row,
    so O(E·b²) in all (2D lattices: b ~ √N).

    Check. The number of rows kept must equal the rank, and the smallest singular value of the
    kept rows, from ``λ_min(R̂_S R̂_Sᵀ)`` (one sparse LU and a few solves), must exceed 32 times
    the rank threshold and the resolution of the squared matrix (about 1.5e-7·σ_max).

    Failure mode. Round-off is amplified where the intersection with the remaining columns is
    ill-conditioned (a direction of the complement lying almost entirely on dropped columns), so
    a nearly dependent row can pass the threshold, or the kept rows can be poorly conditioned
    although a better choice exists. The check catches both; ``"auto"`` then falls back to the
    dense QR up to :data:`fabkit.model.rigidity.DENSE_LIMIT` coordinates and raises beyond.
    Short of failing, a choice made along a sweep is worse conditioned than the dense QR's global
    one: on the k × k lattice
    of 4-bars the smallest singular value of the kept rows is 4e-4 at k = 30 (dense QR: 6.5e-3,
    all rows: 6.1e-2) and 1.8e-5 at k = 100, the weakest direction lying where the sweep ends.

    Examples
    --------
    >>> k4 = Network([[0, 0], [1, 0], [1, 1], [0, 1]],
    ...              [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3]])
    >>> independent_edges(k4).tolist()  # one state of self-stress: 5 of the 6 edges
    [0, 1, 2, 3, 4]
    """
    if method not in ("auto", "windowed", "dense"):
        raise ValueError(f"unknown method {method!r}; valid: auto, windowed, dense")
    x = net.nodes if positions is None else np.asarray(positions, dtype=np.float64)
    n, d = x.shape
    edges = net.edges
    e = edges.shape[0]
    if e == 0:
        return np.zeros(0, dtype=np.int64)
    diff = x[edges[:, 0]] - x[edges[:, 1]]
    length = np.linalg.norm(diff, axis=1)
    bad = np.flatnonzero(~(np.isfinite(length) & (length > 0)))
    if bad.size:
        k = int(bad[0])
        raise NetworkError(f"edge {k} ({edges[k, 0]}, {edges[k, 1]}) has zero or undefined "
                           "length in this configuration", key=f"edges[{k}]")
    if rank is None:
        m = count_modes(net, x, rtol=rtol)
        if m.ambiguous:
            raise KinematicsError(f"the rank of the rigidity matrix is ambiguous ({m.note}): "
                                  "no set of independent edges can be told apart")
        rank = e - m.self_stress
    r = rigidity_matrix(net, x, normalized=True)
    if method == "dense":
        return _dense_rows(r, rank)
    p0, p1 = _band_positions(edges, n, d)
    try:
        with one_blas_thread():  # small dense blocks: threads only contend
            keep = _windowed_rows(diff / length[:, None], p0, p1, rtol,
                                  None if block is None else int(block))
            _check_rows(r, keep, rank, rtol)
        return keep
    except Undecided as exc:
        if method == "auto" and d * n <= rigidity.DENSE_LIMIT:
            return _dense_rows(r, rank)
        raise KinematicsError(f"no independent set of {rank} edges could be certified: "
                              f"{exc.reason}") from None
