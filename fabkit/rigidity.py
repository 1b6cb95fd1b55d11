"""Rigidity analysis: the rigidity matrix, rigid-body motions and generalised Maxwell counting.

For a configuration x (N nodes in d dimensions) the rigidity matrix R has one row per edge
(i, j) holding ``(x_i - x_j)`` in node i's columns and ``(x_j - x_i)`` in node j's columns, so that
``R @ v = 0`` for every velocity v that keeps all edge lengths to first order. Its null space holds
the rigid-body motions and the conformational motions; its left null space holds the states of
self-stress. Generalised Maxwell counting: ``M = dN - E + S``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .network import Network

__all__ = [
    "rigidity_matrix",
    "rigid_body_basis",
    "ModeCount",
    "count_modes",
    "zero_modes",
    "self_stresses",
    "DENSE_LIMIT",
]

#: Networks with at most this many coordinates are analysed with a dense SVD; larger ones with a
#: sparse shift-invert eigensolver on RᵀR.
DENSE_LIMIT = 4000

#: Default relative threshold of the rank decision (see :func:`count_modes`).
RANK_RTOL = 1e-9


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
        zero (``inf`` when none is zero); a large gap means a clear rank decision.
    smallest_nonzero : float
        The smallest singular value counted as non-zero (of the row-normalised R).
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

    @property
    def maxwell(self) -> int:
        """``dN - E``: the count without self-stress."""
        return self.dim * self.n_nodes - self.n_edges

    def __str__(self) -> str:
        return (
            f"{self.total} zero modes = {self.rigid} rigid + {self.conformational} conformational; "
            f"{self.self_stress} state(s) of self-stress (dN - E + S = "
            f"{self.dim}*{self.n_nodes} - {self.n_edges} + {self.self_stress})"
        )


def _singular_values_dense(r: sp.csr_matrix) -> np.ndarray:
    dense = r.toarray()
    return scipy.linalg.svdvals(dense) if dense.size else np.zeros(0)


def _rank_dense(r: sp.csr_matrix, rtol: float) -> tuple[int, float, float]:
    s = _singular_values_dense(r)
    if s.size == 0:
        return 0, np.inf, np.inf
    tol = rtol * max(s[0], 1.0)
    rank = int((s > tol).sum())
    smallest = float(s[rank - 1]) if rank else 0.0
    largest_zero = float(s[rank]) if rank < s.size else 0.0
    gap = np.inf if largest_zero == 0.0 else smallest / largest_zero
    return rank, gap, smallest


def _rank_sparse(r: sp.csr_matrix, rtol: float, expected_zero: int) -> tuple[int, float, float]:
    """Rank from the eigenvalues of B = [[0, R], [Rᵀ, 0]] nearest zero (shift-invert Lanczos).

    B's eigenvalues are ±σ_i and, for each state of self-stress and each zero mode, a zero, so
    ``zeros = S + M`` while ``M - S = dN - E``. Working on B rather than RᵀR keeps singular values
    resolved to round-off (RᵀR would square them and blur everything below ~1e-8).
    """
    e, n = r.shape
    b = sp.bmat([[None, r], [r.T, None]], format="csc")
    smax = float(spla.svds(r, k=1, return_singular_vectors=False)[0])
    k = min(e + n - 1, expected_zero + 6)
    ev = np.sort(np.abs(spla.eigsh(b, k=k, sigma=1e-9 * smax, which="LM",
                                   return_eigenvectors=False)))
    tol = rtol * max(smax, 1.0)
    zeros = int((ev <= tol).sum())
    if zeros == k and k < e + n - 1:  # every eigenvalue found was zero: ask for more
        return _rank_sparse(r, rtol, expected_zero + 16)
    rank = (e + n - zeros) // 2
    smallest = float(ev[zeros]) if zeros < ev.size else 0.0
    largest_zero = float(ev[zeros - 1]) if zeros else 0.0
    gap = np.inf if largest_zero == 0.0 else smallest / largest_zero
    return rank, gap, smallest


def count_modes(net: Network, positions=None, *, rtol: float = RANK_RTOL) -> ModeCount:
    """Count zero modes, rigid motions, conformational motions and states of self-stress.

    Parameters
    ----------
    net : Network
    positions : array_like, shape (N, d), optional
        Configuration to analyse; the reference configuration by default.
    rtol : float
        Relative threshold of the rank decision.

    Returns
    -------
    ModeCount

    Notes
    -----
    The rank decision works on the row-normalised rigidity matrix R̂ (each row divided by its
    edge length, so entries are unit vectors and the singular values are scale-free). A singular
    value σ counts as zero when ``σ <= rtol · max(σ_max, 1)`` with ``rtol = 1e-9`` by default:
    round-off in R̂ is about 1e-16·σ_max, and geometry given to 16 digits puts true zeros below
    1e-13, while a genuinely rigid constraint of a sensible design stays far above 1e-9. The
    result carries the ``gap`` between the smallest kept and the largest dropped singular value
    so a caller can see how clear the decision was (a gap below ~1e3 means the configuration is
    close to singular and the count should not be trusted blindly). Up to ``DENSE_LIMIT``
    coordinates R̂ is decomposed by a dense SVD; beyond that the smallest eigenvalues of R̂ᵀR̂
    are found by shift-invert Lanczos on the symmetric matrix ``[[0, R̂], [R̂ᵀ, 0]]`` (whose
    eigenvalues are ±σ and zeros), which keeps the same threshold meaningful; it is slow for very
    long chains, whose many small but non-zero singular values cluster near zero.

    The rigid motions are counted as the rank of the rigid-body basis of the node set (3 in 2D,
    6 in 3D, fewer for degenerate sets), S follows from ``M = dN - E + S``.

    Examples
    --------
    >>> tri = Network([[0, 0], [1, 0], [0, 1]], [[0, 1], [1, 2], [2, 0]])
    >>> m = count_modes(tri)
    >>> (m.total, m.rigid, m.conformational, m.self_stress)
    (3, 3, 0, 0)
    """
    x = net.nodes if positions is None else np.asarray(positions, dtype=np.float64)
    n, d = x.shape
    r = rigidity_matrix(net, x, normalized=True)
    if d * n <= DENSE_LIMIT:
        rank, gap, smallest = _rank_dense(r, rtol)
    else:
        rigid = 3 if d == 2 else 6
        rank, gap, smallest = _rank_sparse(r, rtol, 2 * rigid + abs(d * n - net.n_edges))
    total = d * n - rank
    rigid = rigid_body_basis(x).shape[1]
    self_stress = net.n_edges - rank
    return ModeCount(
        total=total,
        rigid=rigid,
        conformational=total - rigid,
        self_stress=self_stress,
        dim=d,
        n_nodes=n,
        n_edges=net.n_edges,
        gap=float(gap),
        smallest_nonzero=float(smallest),
    )


def zero_modes(net: Network, positions=None, *, rtol: float = RANK_RTOL) -> np.ndarray:
    """Orthonormal basis of the conformational motions (zero modes orthogonal to rigid motions).

    Dense; meant for small networks and diagnosis.

    Returns
    -------
    numpy.ndarray, shape (d·N, m)
    """
    x = net.nodes if positions is None else np.asarray(positions, dtype=np.float64)
    r = rigidity_matrix(net, x, normalized=True).toarray()
    _, s, vt = np.linalg.svd(r, full_matrices=True)
    tol = rtol * max(s[0] if s.size else 0.0, 1.0)
    rank = int((s > tol).sum())
    null = vt[rank:].T
    rigid = rigid_body_basis(x)
    proj = null - rigid @ (rigid.T @ null)
    u, sv, _ = np.linalg.svd(proj, full_matrices=False)
    return u[:, sv > 1e-8]


def self_stresses(net: Network, positions=None, *, rtol: float = RANK_RTOL) -> np.ndarray:
    """Orthonormal basis of the states of self-stress (left null space of the normalised R).

    Returns
    -------
    numpy.ndarray, shape (E, S)
        Column k gives edge tensions (per unit length) in equilibrium with no external load.
    """
    x = net.nodes if positions is None else np.asarray(positions, dtype=np.float64)
    r = rigidity_matrix(net, x, normalized=True).toarray()
    u, s, _ = np.linalg.svd(r, full_matrices=True)
    tol = rtol * max(s[0] if s.size else 0.0, 1.0)
    rank = int((s > tol).sum())
    return u[:, rank:]
