"""Rigidity analysis: generalised Maxwell counting, zero modes and states of self-stress.

For a configuration x (N nodes in d dimensions) the rigidity matrix R has one row per edge
(i, j) holding ``(x_i - x_j)`` in node i's columns and ``(x_j - x_i)`` in node j's columns, so that
``R @ v = 0`` for every velocity v that keeps all edge lengths to first order. Its null space holds
the rigid-body motions and the conformational motions; its left null space holds the states of
self-stress. Generalised Maxwell counting: ``M = dN - E + S``. With states of self-stress some
edges are redundant; :func:`fabkit.model.independent_edges.independent_edges` picks a set of
rank(R) edges whose rows are independent, without a dense factorisation. The matrix itself and
the singular-value helpers live in :mod:`fabkit.model.matrix`; the proof of a count from a
construction order in :mod:`fabkit.model.certificate`.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .. import arguments
from ..errors import ConstructionError
from .network import checked_network, Network
from ..numerics import RANK_RTOL
from ..numerics import one_blas_thread, SMALL_DENSE
from .certificate import Uncertified, certify
from .matrix import (AMBIGUOUS_GAP, Undecided, available_memory, orthonormal, rank_dense,
                     require_dense_memory, rigid_body_basis, rigid_body_count, rigidity_matrix,
                     sigma_max,
                     smallest_singular)

if TYPE_CHECKING:
    import scipy.sparse as sp

# scipy is imported where it is used: the command line imports this module to build its
# parser and must start without it (tests/test_cli_startup.py)

__all__ = [
    "rigidity_matrix",
    "rigid_body_basis",
    "ModeCount",
    "count_modes",
    "zero_modes",
    "self_stresses",
    "DENSE_LIMIT",
    "SPARSE_FROM",
    "AMBIGUOUS_GAP",
    "NUMERIC_CHECK_LIMIT",
    "available_memory",
    "require_dense_memory",
]

#: Largest network (in coordinates) whose modes are counted by a dense SVD: always up to
#: ``SPARSE_FROM`` coordinates, and as the fallback when the sparse path cannot certify a count.
DENSE_LIMIT = 4000

#: Networks with more coordinates than this try the certified sparse path first (the dense SVD
#: costs O(N³): 0.15 s at 882 coordinates on one thread, where the sparse path takes 15 ms;
#: the two cross near 300).
SPARSE_FROM = 400

#: Largest network (in coordinates) whose structural count :func:`count_modes` cross-checks by
#: the numeric rank (about 1 s on the sparse path at this size); beyond, the structural
#: certificate stands alone (the 100 000-module chain's numeric rank takes 10 s and is ambiguous).
NUMERIC_CHECK_LIMIT = 100_000

#: Largest number of zeros the sparse path looks for (block size of its subspace iteration).
MAX_BLOCK = 64


#: Shift of RᵀR in the normal-equations path, relative to σ_max²: above its round-off (~1e-16
#: σ_max²), so K + μI is positive definite, and far below the squared threshold it resolves.
NORMAL_SHIFT = 1e-10
#: A zero mode with less than this of its norm outside the rigid motions is rigid, not a
#: conformational motion.
CONFORMATIONAL_PART = 1e-8


@dataclass(frozen=True)
class ModeCount:
    """Result of generalised Maxwell counting, ``M = dN - E + S``.

    Attributes
    ----------
    total : int
        Zero modes M: the dimension of the null space of R.
    rigid : int
        Rigid-body motions among them (3 in 2D, 6 in 3D for generic node sets).
    conformational : int
        ``total - rigid``: motions that change some distance.
    self_stress : int
        States of self-stress S: the dimension of the left null space of R.
    dim, n_nodes, n_edges : int
        d, N and E.
    gap : float
        Ratio between the smallest singular value counted as non-zero and the largest counted as
        zero (``inf`` when none is zero); a large gap means a clear rank decision. On the sparse
        path a lower bound of that ratio (see :func:`count_modes`).
    smallest_nonzero : float
        The smallest singular value counted as non-zero (of the row-normalised R).
    ambiguous : bool
        The rank is numerically ambiguous: a singular value lies within a factor
        ``√AMBIGUOUS_GAP`` of the threshold (so the gap is below :data:`AMBIGUOUS_GAP`), or the
        sparse path could not certify its count. The counts are then not to be trusted (on the sparse
        path ``total`` is a lower bound: the zero modes found are there).
    method : str
        The numeric rank path that measured ``gap`` and ``smallest_nonzero``: ``"dense"`` (SVD)
        or ``"sparse"`` (certified shift-invert, see :func:`count_modes`); ``"structure"`` when
        the count was proved from the network's construction and no numeric path ran (then
        ``gap`` and ``smallest_nonzero`` are NaN).
    note : str
        Why the count is ambiguous (empty otherwise).
    certificate : str
        How the counts were established: ``"structure"`` (proved from a construction order of
        the whole network), ``"substructure"`` (from parts that have one, joined by a small
        interface decided numerically) or ``"numeric"`` (the rank of the rigidity matrix).
    margin : float
        How far the certificate is from failing: for ``"structure"`` and ``"substructure"`` the
        smallest intersection sine of the construction (3D: determinant of unit bar
        directions), for ``"numeric"`` the smallest kept singular value (``smallest_nonzero``).
    detail : str
        One sentence on the certificate (seeds, parts, extra bars), or why no structural
        certificate was found.
    cross_check : str
        The numeric rank's verdict on a structural certificate (``"agrees"``, ``"undecided:
        ..."``, ``"disagrees: ..."``) or why it did not run; empty for numeric counts.
    """

    total: int
    rigid: int
    conformational: int
    self_stress: int
    dim: int
    n_nodes: int
    n_edges: int
    gap: float
    smallest_nonzero: float
    ambiguous: bool = False
    method: str = "dense"
    note: str = ""
    certificate: str = "numeric"
    margin: float = math.nan
    detail: str = ""
    cross_check: str = ""

    @property
    def maxwell(self) -> int:
        """``dN - E``: the count without self-stress."""
        return self.dim * self.n_nodes - self.n_edges

    def __str__(self) -> str:
        head = f"ambiguous rank ({self.note}); at face value: " if self.ambiguous else ""
        return head + (
            f"{self.total} zero modes = {self.rigid} rigid + {self.conformational} conformational; "
            f"{self.self_stress} state(s) of self-stress (dN - E + S = "
            f"{self.dim}*{self.n_nodes} - {self.n_edges} + {self.self_stress})"
        )



def _best_conditioned(q: np.ndarray) -> np.ndarray:
    """Rows of an orthonormal basis q (k columns) on which it is best conditioned: the first k
    pivots of a column-pivoted QR of qᵀ."""
    k = q.shape[1]
    if k == 0:
        return np.zeros(0, dtype=np.int64)
    import scipy.linalg

    return scipy.linalg.qr(q.T, pivoting=True, mode="r")[1][:k]


def _rank_sparse(r: sp.csr_matrix, rtol: float, block: int = 8, iterations: int = 3):
    """Certified rank of a sparse R in near-linear time (see :func:`count_modes`, Notes).

    Returns (rank, gap, smallest_nonzero); raises :class:`Undecided` when the two bounds do not
    bracket the threshold.
    """
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    e, n = r.shape
    smax = sigma_max(r)
    tol = rtol * max(smax, 1.0)
    maxwell = n - e
    # 1. Shift-invert subspace iteration on B = [[0, R], [Rᵀ, 0]] (eigenvalues ±σ_i and one zero
    #    per zero mode and per state of self-stress); a block, not Lanczos, so that the multiple
    #    zero eigenvalue is found with its full multiplicity.
    b = sp.bmat([[None, r], [r.T, None]], format="csc")
    shift = 1e-3 * tol
    try:
        # COLAMD: a minimum-degree ordering of B + Bᵀ fills the factors of some chains
        # densely (the template's mirrored super-stable chain of 1000 modules: 1.8e7 entries and
        # 10 s, 3000 modules 250 s), where COLAMD keeps them linear (1.4e5 entries, 0.03 s)
        lu_b = spla.splu((b - shift * sp.eye(e + n, format="csc")).tocsc(),
                         permc_spec="COLAMD")
    except RuntimeError:
        raise Undecided("the shifted matrix [[0, R], [Rᵀ, 0]] is exactly singular",
                         min(e, n)) from None
    rng = np.random.default_rng(0)
    while True:
        x = orthonormal(rng.standard_normal((e + n, block)))
        for _ in range(iterations):
            x = orthonormal(lu_b.solve(x))
        # k-th smallest singular value of B·X (X orthonormal) ≥ the k-th smallest |eigenvalue|
        # of B: counting those ≤ tol gives a lower bound on the number of zeros.
        _, s, wt = np.linalg.svd(np.asarray(b @ x), full_matrices=False)
        s, w = s[::-1], wt[::-1].T
        zeros = int((s <= tol).sum())
        if zeros < block or block >= e + n:
            break
        if block >= MAX_BLOCK:
            raise Undecided(f"more than {MAX_BLOCK} zero modes and states of self-stress",
                             n - zeros)
        block *= 2  # every vector found was a zero: look for more
    z = x @ w[:, :zeros]
    # 2. Split the zero space into zero modes (v-parts) and self-stresses (u-parts): the blocks of
    #    an orthonormal basis of null(B) = leftnull(R) ⊕ null(R) have singular values 1 or 0.
    uu, su, _ = np.linalg.svd(z[:e], full_matrices=False)
    uv, sv, _ = np.linalg.svd(z[e:], full_matrices=False)
    qu, qv = uu[:, su > 0.5], uv[:, sv > 0.5]
    modes, stresses = qv.shape[1], qu.shape[1]
    if modes - stresses != maxwell:
        raise Undecided(f"{modes} zero modes and {stresses} self-stresses found, which "
                         f"contradicts dN - E = {maxwell}", min(e, n, n - modes, e - stresses))
    rho = max(np.linalg.norm(r @ qv, 2) if modes else 0.0,
              np.linalg.norm(r.T @ qu, 2) if stresses else 0.0)
    # 3. Certificate from above: the bordered matrix A = [[R, U], [Vᵀ, 0]], V pinning the
    #    coordinates and U releasing the edges where the null vectors are best conditioned
    #    (column-pivoted QR). Every matrix within σ_min(A) of R keeps rank ≥ dN - M, so
    #    σ_{dN-M}(R) ≥ σ_min(A); and ‖R Q_v‖ ≤ ρ bounds σ_{dN-M+1}(R) ≤ ρ.
    pins, rel = _best_conditioned(qv), _best_conditioned(qu)
    a = sp.bmat([
        [r, sp.csr_matrix((np.ones(stresses), (rel, np.arange(stresses))), shape=(e, stresses))],
        [sp.csr_matrix((np.ones(modes), (np.arange(modes), pins)), shape=(modes, n)), None],
    ], format="csc")
    try:
        lu_a = spla.splu(a, permc_spec="COLAMD")
    except RuntimeError:
        raise Undecided("the bordered matrix [[R, U], [Vᵀ, 0]] is exactly singular (more "
                         "zero modes than found?)", n - modes) from None
    sigma_a = smallest_singular(lu_a.solve, lambda v: lu_a.solve(v, trans="T"), a.shape[0])
    smallest = float(s[zeros])
    gap = math.inf if rho == 0.0 else sigma_a / rho
    margin = math.sqrt(AMBIGUOUS_GAP)
    if not (rho <= tol / margin and sigma_a >= margin * tol):
        raise Undecided(f"the bounds {rho:.1e} (largest zero) and {sigma_a:.1e} (smallest "
                         f"non-zero) do not bracket the threshold {tol:.1e}", n - modes, gap,
                         smallest)
    return n - modes, gap, smallest, ""


def _rank_sparse_normal(r: sp.csr_matrix, rtol: float, block: int = 8, iterations: int = 5):
    """Certified rank through RᵀR, for networks with many states of self-stress (which would
    all be zeros of B): finds the few zero modes only, S follows from ``M - S = dN - E``.

    Same bounds as :func:`_rank_sparse`, with the certificate ``σ_min([R; Vᵀ])`` read from
    ``λ_min(RᵀR + VVᵀ)``: squaring limits it to singular values above about 1e-7·σ_max, below
    which the count is reported as ambiguous.
    """
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    e, n = r.shape
    smax = sigma_max(r)
    tol = rtol * max(smax, 1.0)
    k = (r.T @ r).tocsc()
    mu = NORMAL_SHIFT * smax ** 2  # above the round-off of RᵀR, so K + μI is positive definite
    try:
        lu_k = spla.splu((k + mu * sp.eye(n, format="csc")).tocsc(), permc_spec="MMD_AT_PLUS_A")
    except RuntimeError:
        raise Undecided("RᵀR + μI is exactly singular", n) from None
    rng = np.random.default_rng(0)
    while True:
        x = orthonormal(rng.standard_normal((n, block)))
        for _ in range(iterations):
            x = orthonormal(lu_k.solve(x))
        _, s, wt = np.linalg.svd(np.asarray(r @ x), full_matrices=False)
        s, w = s[::-1], wt[::-1].T
        modes = int((s <= tol).sum())
        if modes < block or block >= n:
            break
        if block >= MAX_BLOCK:
            raise Undecided(f"more than {MAX_BLOCK} zero modes", n - modes)
        block *= 2
    stresses = modes - (n - e)
    if stresses < 0:
        raise Undecided(f"{modes} zero modes found, fewer than dN - E = {n - e}", n - modes)
    qv = x @ w[:, :modes]
    rho = float(s[modes - 1]) if modes else 0.0
    pins = _best_conditioned(qv)
    kc = (k + sp.csc_matrix((np.ones(modes), (pins, pins)), shape=(n, n))).tocsc()
    try:
        lu_c = spla.splu(kc, permc_spec="MMD_AT_PLUS_A")
    except RuntimeError:
        raise Undecided("RᵀR + VVᵀ is exactly singular (more zero modes than found?)",
                         n - modes) from None
    sigma_c = math.sqrt(smallest_singular(lu_c.solve, lu_c.solve, n))
    floor = math.sqrt(100 * np.finfo(float).eps) * smax
    smallest = float(s[modes])
    gap = math.inf if rho == 0.0 else sigma_c / rho
    margin = math.sqrt(AMBIGUOUS_GAP)
    if not (rho <= tol / margin and sigma_c >= margin * tol and sigma_c > floor):
        raise Undecided(f"the bounds {rho:.1e} (largest zero) and {sigma_c:.1e} (smallest "
                         f"non-zero, resolved above {floor:.1e}) do not bracket the threshold "
                         f"{tol:.1e} with a factor {margin:.0f} to spare", n - modes, gap, smallest)
    return n - modes, gap, smallest, ""


def count_modes(net: Network, positions=None, *, rtol: float = RANK_RTOL,
                method: str = "auto") -> ModeCount:
    """Count zero modes, rigid motions, conformational motions and states of self-stress.

    Parameters
    ----------
    net : Network
    positions : array_like, shape (N, d), optional
        Configuration to analyse; the reference configuration by default.
    rtol : float
        Relative threshold of the rank decision.
    method : {"auto", "structure", "dense", "sparse"}
        ``"auto"``: the counts proved from the network's construction
        (:mod:`fabkit.model.certificate`) where it has one (or is cut into parts that have
        one), cross-checked by the numeric rank up to :data:`NUMERIC_CHECK_LIMIT` coordinates;
        the numeric rank alone otherwise (dense SVD up to ``SPARSE_FROM`` coordinates, the
        sparse path beyond, with the dense SVD as fallback up to ``DENSE_LIMIT`` coordinates
        when it is ambiguous). ``"structure"``: the structural certificate only.
        ``"dense"``, ``"sparse"``: the numeric rank only, by that path.

    Returns
    -------
    ModeCount
        ``certificate`` says how the counts were established and ``margin`` how far from
        failing; ``method``, ``gap`` and ``smallest_nonzero`` describe the numeric rank where
        it ran.

    Raises
    ------
    ValueError
        Unknown ``method``.
    ConstructionError
        ``method="structure"`` and no structural certificate (the message says why).
    ResourceError
        The dense SVD would need more memory than is available (raised before allocating).

    Notes
    -----
    *Structural certificate.* Where a construction order places every node from two (3D: three)
    bars meeting transversally, the rows of those bars are independent (block triangular with
    non-singular diagonal blocks), so the network has the rigid motions plus one motion per free
    seed, and each further bar is either a state of self-stress (it keeps its length along that
    motion) or removes the motion; no singular value is compared with a threshold. Its margin is
    the smallest intersection sine, accepted above ``MIN_SINE`` (3e-8). Networks cut into
    constructible parts get the ``"substructure"`` certificate, whose interface (parts' motions
    that agree on shared nodes and keep the leftover bars) is small and decided numerically.
    Long straight chains are where this matters: the smallest singular value of R̂ of the
    mirrored super-stable chain falls as about N^-1.5 (7e-8 at 10 000 modules, 2.5e-9 at
    100 000), a beam's bending, so the numeric rank becomes ambiguous while the structural count
    stays exact.

    *Numeric rank.*
    The rank decision works on the row-normalised rigidity matrix R̂ (each row divided by its
    edge length, so entries are unit vectors and the singular values are scale-free). A singular
    value σ counts as zero when ``σ <= rtol · max(σ_max, 1)`` with ``rtol = 1e-9`` by default:
    round-off in R̂ is about 1e-16·σ_max, and geometry given to 16 digits puts true zeros below
    1e-13, while a genuinely rigid constraint of a sensible design stays far above 1e-9. The
    result carries the ``gap`` between the smallest kept and the largest dropped singular value.
    Decision rule: the count is clear when every singular value lies at least a factor
    ``√AMBIGUOUS_GAP`` (about 32) away from the threshold, on its side; otherwise (a gap below
    1e3, or a singular value near the threshold) the configuration is too close to singular for
    the count to mean much and the result says so (``ambiguous``, with a ``note``) instead of
    guessing silently.

    Up to ``SPARSE_FROM`` (400) coordinates R̂ is decomposed by a dense SVD (O(N³)). Larger
    networks take a sparse path whose cost is a few sparse LU factorisations and solves (near-linear for
    chains and lattices, whose factors stay sparse), and which brackets the threshold from both
    sides instead of trusting an iterative eigensolver:

    1. *Find the zeros.* ``B = [[0, R̂], [R̂ᵀ, 0]]`` has eigenvalues ±σ_i and one zero per zero mode
       and per state of self-stress (working on B, not R̂ᵀR̂, keeps σ resolved to round-off
       instead of squaring it). ``B - σ₀I`` (σ₀ = 1e-3 × threshold) is factorised once;
       subspace iteration with a block of 8 vectors (doubled while every vector found is a zero)
       amplifies the zero eigenvectors by σ_i/σ₀ per solve. A block rather than Lanczos because
       the zero eigenvalue is multiple, which Lanczos finds with the wrong multiplicity. By
       interlacing, the number of singular values of ``B·X`` below the threshold is at most the
       true number of zeros.
    2. *Split them.* An orthonormal basis of the zeros splits into zero-mode parts (coordinates)
       and self-stress parts (edges); the two blocks have singular values 1 or 0, so M and S are
       read off exactly, and must satisfy ``M - S = dN - E``. ``ρ = ‖R̂ Q‖`` over the orthonormal
       zero modes Q (and ``‖R̂ᵀ P‖`` over the self-stresses) bounds σ_{dN-M+1} ≤ ρ from above.
    3. *Certify from the other side.* The bordered matrix ``A = [[R̂, U], [Vᵀ, 0]]`` pins M
       coordinates (V) and releases S edges (U), picked where the bases found are best
       conditioned (column-pivoted QR). Any matrix within σ_min(A) of R̂ still makes A
       nonsingular and so has rank ≥ dN - M: σ_{dN-M}(R̂) ≥ σ_min(A). σ_min(A) is estimated by
       a few steps of subspace iteration with A's LU factors.

    The count is accepted when ``ρ ≤ threshold/32`` and ``σ_min(A) ≥ 32·threshold``; the gap is
    ``σ_min(A) / ρ``, a lower bound of the true one. Failure modes, all reported as
    ``ambiguous`` rather than guessed: a singular value near the threshold (the bounds cannot
    bracket it); zeros missed by the subspace iteration (M - S contradicts dN - E, or A is
    singular); a poor choice of pins (σ_min(A) far below σ_{dN-M}(R̂), so the certificate fails
    although the rank is clear). The estimate of σ_min(A) approaches it from above; with a
    separated smallest singular value it converges in a few steps, with a cluster it may
    overestimate by the spread of the cluster. With ``method="auto"`` a network of at most
    ``DENSE_LIMIT`` coordinates whose sparse count is ambiguous is counted again by the dense
    SVD. Networks whose Maxwell count implies more than
    ``MAX_BLOCK // 2`` self-stresses (over-braced lattices) find only their zero modes, through
    ``R̂ᵀR̂ + μI``, with S from ``M - S = dN - E`` and the certificate from
    ``λ_min(R̂ᵀR̂ + VVᵀ) = σ_min([R̂; Vᵀ])²``; squaring limits that path to smallest non-zero
    singular values above about 1.5e-7·σ_max (below, ambiguous). More than ``MAX_BLOCK`` (64)
    zeros: ambiguous. The cost grows with the fill of the sparse LU
    factors: O(N) for chains, about O(N^1.5) for 2D lattices.

    The rigid motions are counted as the rank of the rigid-body basis of the node set (3 in 2D,
    6 in 3D, fewer for degenerate sets), S follows from ``M = dN - E + S``.

    Examples
    --------
    >>> tri = Network([[0, 0], [1, 0], [0, 1]], [[0, 1], [1, 2], [2, 0]])
    >>> m = count_modes(tri)
    >>> (m.total, m.rigid, m.conformational, m.self_stress, m.certificate)
    (3, 3, 0, 0, 'structure')
    """
    checked_network("net", net)
    arguments.choice("method", method, ("auto", "structure", "dense", "sparse"))
    if positions is not None:
        return _count_modes(net, arguments.positions("positions", positions, net), rtol, method)
    # the reference configuration's count is remembered on the (immutable) network: an export
    # asks for it when it traces, reports and checks the design
    key = ("count_modes", float(rtol), method)
    if key not in net._cache:
        net._cache[key] = _count_modes(net, net.nodes, rtol, method)
    return net._cache[key]


def _count_modes(net: Network, x: np.ndarray, rtol: float, method: str) -> ModeCount:
    n, d = x.shape
    positions = None if x is net.nodes else x
    cert, why = None, ""
    if method in ("auto", "structure"):
        try:
            cert = certify(net, positions, rtol=rtol)
        except Uncertified as exc:
            why = str(exc)
            if method == "structure":
                raise ConstructionError(f"no structural count: {why}") from None
    numeric = None
    if method in ("dense", "sparse") or (method == "auto" and (
            cert is None or d * n <= NUMERIC_CHECK_LIMIT)):
        numeric = _numeric_rank(net, x, rtol, method)
    rigid = rigid_body_count(x)
    if cert is None:
        used, rank, gap, smallest, note = numeric
        total = d * n - rank
        return ModeCount(total=total, rigid=rigid, conformational=total - rigid,
                         self_stress=net.n_edges - rank, dim=d, n_nodes=n, n_edges=net.n_edges,
                         gap=float(gap), smallest_nonzero=float(smallest),
                         ambiguous=bool(note), method=used, note=note, certificate="numeric",
                         margin=float(smallest),
                         detail=f"no structural certificate: {why}" if why else "")
    if numeric is None:
        used, gap, smallest = "structure", math.nan, math.nan
        check = (f"not run: {d * n} coordinates, above the {NUMERIC_CHECK_LIMIT} up to which "
                 "the numeric rank cross-checks a structural count")
    else:
        used, rank, gap, smallest, note = numeric
        if note:
            check = f"undecided: {note}"
        elif d * n - rank == cert.total:
            check = "agrees"
        else:
            check = (f"disagrees: {d * n - rank} zero modes and {net.n_edges - rank} "
                     "self-stress(es) by the numeric rank")
    return ModeCount(total=cert.total, rigid=rigid, conformational=cert.total - rigid,
                     self_stress=cert.self_stress, dim=d, n_nodes=n, n_edges=net.n_edges,
                     gap=float(gap), smallest_nonzero=float(smallest), ambiguous=False,
                     method=used, note="", certificate=cert.kind, margin=float(cert.margin),
                     detail=cert.detail, cross_check=check)


def _numeric_rank(net: Network, x, rtol: float, method: str):
    """(path, rank, gap, smallest kept singular value, note) of the normalised R by the numeric
    rule of :func:`count_modes`; ``note`` says why the rank is ambiguous (empty otherwise)."""
    n, d = x.shape
    r = rigidity_matrix(net, x, normalized=True)
    note, requested = "", method
    if method == "dense" or method == "auto" and d * n <= min(SPARSE_FROM, DENSE_LIMIT):
        method = "dense"
        rank, gap, smallest, note = rank_dense(r, rtol)
    else:
        method = "sparse"
        try:
            # Dense work here is on tall, thin blocks (8 columns), which threads do not speed
            # up; on a shared machine they slow it down several times.
            with one_blas_thread():
                if net.n_edges - d * n + (3 if d == 2 else 6) > MAX_BLOCK // 2:
                    # surely many self-stresses: count the few zero modes alone
                    rank, gap, smallest, note = _rank_sparse_normal(r, rtol)
                else:
                    rank, gap, smallest, note = _rank_sparse(r, rtol)
        except Undecided as exc:
            if requested == "auto" and d * n <= DENSE_LIMIT:  # small enough for the SVD
                method = "dense"
                rank, gap, smallest, note = rank_dense(r, rtol)
            else:
                rank, gap, smallest, note = exc.rank, exc.gap, exc.smallest, exc.reason
    if not note and gap < AMBIGUOUS_GAP:
        note = f"rank gap {gap:.1e} below {AMBIGUOUS_GAP:.0e}"
    return method, rank, gap, smallest, note


def zero_modes(net: Network, positions=None, *, rtol: float = RANK_RTOL) -> np.ndarray:
    """Orthonormal basis of the conformational motions (zero modes orthogonal to rigid motions).

    Dense; meant for small networks and diagnosis.

    Returns
    -------
    numpy.ndarray, shape (d·N, m)
    """
    x = net.nodes if positions is None else np.asarray(positions, dtype=np.float64)
    r = rigidity_matrix(net, x, normalized=True)
    require_dense_memory(*r.shape, vectors=True)
    _, s, vt = np.linalg.svd(r.toarray(), full_matrices=True)
    tol = rtol * max(s[0] if s.size else 0.0, 1.0)
    rank = int((s > tol).sum())
    null = vt[rank:].T
    rigid = rigid_body_basis(x)
    proj = null - rigid @ (rigid.T @ null)
    u, sv, _ = np.linalg.svd(proj, full_matrices=False)
    return u[:, sv > CONFORMATIONAL_PART]


def self_stresses(net: Network, positions=None, *, rtol: float = RANK_RTOL) -> np.ndarray:
    """Orthonormal basis of the states of self-stress (left null space of the normalised R).

    Returns
    -------
    numpy.ndarray, shape (E, S)
        Column k gives edge tensions (per unit length) in equilibrium with no external load.
    """
    x = net.nodes if positions is None else np.asarray(positions, dtype=np.float64)
    r = rigidity_matrix(net, x, normalized=True)
    require_dense_memory(*r.shape, vectors=True)
    with one_blas_thread() if max(r.shape) <= SMALL_DENSE else contextlib.nullcontext():
        u, s, _ = np.linalg.svd(r.toarray(), full_matrices=True)
    tol = rtol * max(s[0] if s.size else 0.0, 1.0)
    rank = int((s > tol).sum())
    return u[:, rank:]
