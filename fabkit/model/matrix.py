"""The rigidity matrix and the linear algebra every rigidity question shares.

:func:`rigidity_matrix` and :func:`rigid_body_basis` describe a configuration; the dense and
sparse singular-value helpers here (:func:`rank_dense`, :func:`sigma_max`,
:func:`smallest_singular`, :class:`Undecided`) and the memory guard of a dense SVD
(:func:`require_dense_memory`) are what the mode count (:mod:`fabkit.model.rigidity`), its
certificate from a construction order (:mod:`fabkit.model.certificate`) and the selection of
independent edges (:mod:`fabkit.model.independent_edges`) compute with. This module imports none
of them, so they import it without a cycle.
"""

from __future__ import annotations

import math
import os

from typing import TYPE_CHECKING

import numpy as np

from ..errors import ResourceError
from .network import Network

if TYPE_CHECKING:
    import scipy.sparse as sp

# scipy is imported where it is used: the command line imports this module to build its
# parser and must start without it (tests/test_cli_startup.py)

__all__ = ["rigidity_matrix", "rigid_body_basis", "rigid_body_count", "available_memory", "require_dense_memory",
           "AMBIGUOUS_GAP", "Undecided", "singular_values_dense", "rank_dense", "sigma_max",
           "smallest_singular", "orthonormal"]


#: A rank decision whose gap (smallest singular value kept / largest dropped) is below this is
#: reported as ambiguous.
AMBIGUOUS_GAP = 1e3



def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (``MemAvailable`` on Linux), or None when
    the system does not say."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None



def require_dense_memory(n_rows: int, n_cols: int, *, vectors: bool = False,
                         what: str = "a dense SVD") -> int:
    """Raise :class:`~fabkit.errors.ResourceError`, before anything is allocated, when a dense
    SVD of an ``n_rows × n_cols`` matrix cannot fit in the available memory.

    The estimate counts the dense copy, LAPACK's copy and workspace, and with ``vectors`` the
    full square factors ``U`` (rows²) and ``Vᵀ`` (cols²), in float64.

    Returns
    -------
    int
        The estimated number of bytes.

    Examples
    --------
    >>> require_dense_memory(10, 12) < 10_000
    True
    """
    m, n = int(n_rows), int(n_cols)
    need = 8 * (2 * m * n + 4 * min(m, n) ** 2 + 8 * max(m, n))
    if vectors:
        need += 8 * (m * m + n * n)
    have = available_memory()
    if have is not None and need > have:
        raise ResourceError(
            f"{what} of the {m} × {n} rigidity matrix needs about {need / 1e9:.1f} GB of memory; "
            f"{have / 1e9:.1f} GB are available (use the sparse path, or a smaller network)"
        )
    return need



def _positions(net_or_positions, positions=None) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(net_or_positions, Network):
        net = net_or_positions
        x = net.nodes if positions is None else np.asarray(positions, dtype=np.float64)
        return x, net.edges
    raise TypeError("expected a Network")



def rigidity_matrix(net: Network, positions=None, *, normalized: bool = False) -> sp.csr_matrix:
    """Sparse rigidity matrix R of a configuration.

    Parameters
    ----------
    net : Network
        Topology (edges) and, by default, the configuration.
    positions : array_like, shape (N, d), optional
        Configuration at which R is evaluated; the reference configuration by default.
    normalized : bool
        Divide each row by its edge's current length, so that the entries are unit vectors and
        the singular values do not depend on the size of the network.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (E, d·N)
        Row e is ``(x_i - x_j)`` at columns ``d·i … d·i+d-1`` and ``(x_j - x_i)`` at node j's.
        Coordinates are ordered node by node: ``[x_0, y_0, (z_0), x_1, ...]``.

    Examples
    --------
    >>> net = Network([[0, 0], [1, 0]], [[0, 1]])
    >>> rigidity_matrix(net).toarray()
    array([[-1.,  0.,  1.,  0.]])
    """
    x, edges = _positions(net, positions)
    n, d = x.shape
    e = edges.shape[0]
    diff = x[edges[:, 0]] - x[edges[:, 1]]
    if normalized:
        diff = diff / np.linalg.norm(diff, axis=1, keepdims=True)
    rows = np.repeat(np.arange(e), 2 * d)
    cols = np.concatenate(
        [d * edges[:, [0]] + np.arange(d), d * edges[:, [1]] + np.arange(d)], axis=1
    ).ravel()
    vals = np.concatenate([diff, -diff], axis=1).ravel()
    import scipy.sparse as sp

    return sp.csr_matrix((vals, (rows, cols)), shape=(e, d * n))



def rigid_body_basis(positions, *, rtol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of the rigid-body velocities of a node set.

    Translations along each axis and rotations (one in 2D, three in 3D) about the centroid,
    orthonormalised; directions that vanish for the node set (a single node; rotation about the
    line of collinear nodes in 3D) are dropped.

    Parameters
    ----------
    positions : array_like, shape (N, d)
    rtol : float
        Singular values below ``rtol`` times the largest one count as absent motions.

    Returns
    -------
    numpy.ndarray, shape (d·N, r)
        r = 3 in 2D and 6 in 3D for a generic node set, fewer for degenerate ones.

    Examples
    --------
    >>> rigid_body_basis([[0, 0], [1, 0]]).shape
    (4, 3)
    >>> rigid_body_basis([[0, 0, 0], [1, 0, 0], [2, 0, 0]]).shape
    (9, 5)
    """
    x = np.asarray(positions, dtype=np.float64)
    n, d = x.shape
    c = x - x.mean(axis=0)
    cols = []
    for a in range(d):
        t = np.zeros((n, d))
        t[:, a] = 1.0
        cols.append(t.ravel())
    if d == 2:
        cols.append(np.column_stack([-c[:, 1], c[:, 0]]).ravel())
    else:
        for axis in np.eye(3):
            cols.append(np.cross(axis, c).ravel())
    basis = np.column_stack(cols)
    u, s, _ = np.linalg.svd(basis, full_matrices=False)
    keep = s > rtol * s.max()
    return u[:, keep]



def rigid_body_count(positions, *, rtol: float = 1e-10) -> int:
    """How many rigid-body velocities a node set has: the column count of
    :func:`rigid_body_basis`, from the node set's own singular values instead of an SVD of the
    whole (d·N × 3 or 6) basis.

    The translations are orthogonal to the rotations about the centroid and each has norm √N;
    the rotations' singular values are ``√(σ_j² + σ_k²)`` over pairs of the centred
    coordinates' singular values σ (in 2D: their norm). A motion counts where its singular value
    exceeds ``rtol`` times the largest, as there.

    Examples
    --------
    >>> rigid_body_count([[0, 0], [1, 0]]), rigid_body_count([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    (3, 5)
    """
    x = np.asarray(positions, dtype=np.float64)
    n, d = x.shape
    c = x - x.mean(axis=0)
    sigma = np.linalg.svd(c, compute_uv=False) if n else np.zeros(0)
    sigma = np.concatenate([sigma, np.zeros(d - sigma.size)]) if sigma.size < d else sigma
    if d == 2:
        rot = np.array([math.hypot(sigma[0], sigma[1])])
    else:
        rot = np.array([math.hypot(sigma[j], sigma[k]) for j, k in ((0, 1), (0, 2), (1, 2))])
    values = np.concatenate([np.full(d, math.sqrt(n)), rot])
    return int((values > rtol * values.max()).sum())


def singular_values_dense(r: sp.csr_matrix) -> np.ndarray:
    require_dense_memory(*r.shape)
    dense = r.toarray()
    import scipy.linalg

    return scipy.linalg.svdvals(dense) if dense.size else np.zeros(0)



def rank_dense(r: sp.csr_matrix, rtol: float) -> tuple[int, float, float, str]:
    s = singular_values_dense(r)
    if s.size == 0:
        return 0, np.inf, np.inf, ""
    tol = rtol * max(s[0], 1.0)
    rank = int((s > tol).sum())
    smallest = float(s[rank - 1]) if rank else 0.0
    largest_zero = float(s[rank]) if rank < s.size else 0.0
    gap = np.inf if largest_zero == 0.0 else smallest / largest_zero
    margin = math.sqrt(AMBIGUOUS_GAP)
    if rank and smallest < margin * tol:
        return rank, gap, smallest, (f"smallest kept singular value {smallest:.1e} within a "
                                     f"factor {margin:.0f} of the threshold {tol:.1e}")
    if largest_zero > tol / margin:
        return rank, gap, smallest, (f"largest dropped singular value {largest_zero:.1e} within "
                                     f"a factor {margin:.0f} of the threshold {tol:.1e}")
    return rank, gap, smallest, ""



class Undecided(Exception):
    """The sparse rank decision could not be certified (see :func:`_rank_sparse`); carries the
    counts found so far: ``rank`` is an upper bound (zero modes found are certainly there)."""

    def __init__(self, reason: str, rank: int, gap: float = 0.0, smallest: float = 0.0):
        super().__init__(reason)
        self.reason, self.rank, self.gap, self.smallest = reason, rank, gap, smallest



def orthonormal(a: np.ndarray) -> np.ndarray:
    return np.linalg.qr(a)[0] if a.shape[1] else a


def sigma_max(r: sp.csr_matrix, iterations: int = 40, seed: int = 0) -> float:
    """Largest singular value of R by power iteration on RᵀR (a few per cent is plenty: it only
    scales the threshold)."""
    v = np.random.default_rng(seed).standard_normal(r.shape[1])
    s = 0.0
    for _ in range(iterations):
        w = r.T @ (r @ v)
        s = float(np.linalg.norm(w))
        if s == 0.0:
            return 0.0
        v = w / s
    return math.sqrt(s)



def smallest_singular(solve, solve_t, size: int, block: int = 3, iterations: int = 6,
                       seed: int = 1) -> float:
    """Estimate of the smallest singular value of a square matrix A from its LU factors:
    subspace iteration on (AᵀA)⁻¹ with a small block, then the smallest ``1/σ`` of the Ritz
    values. It approaches σ_min from above, quickly when σ_min is separated."""
    x = orthonormal(np.random.default_rng(seed).standard_normal((size, block)))
    for _ in range(iterations):
        y = solve(solve_t(x))
        if not np.isfinite(y).all():
            return 0.0
        x = orthonormal(y)
    z = solve_t(x)  # ‖A⁻ᵀ x‖ = 1/σ along the converged directions
    if not np.isfinite(z).all():
        return 0.0
    big = float(np.linalg.svd(z, compute_uv=False)[0])
    return 1.0 / big if big > 0 else math.inf
