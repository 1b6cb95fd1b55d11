"""The bordered linear system of :mod:`fabkit.kinematics.projected` and its factorisations.

``A = [R; G; e_j]``: the rigidity rows of the bars, the gauge rows that hold one rigid element
still, and a last row that fixes the coordinate the step parametrises by. Its coordinates are
ordered node by node along a reverse Cuthill-McKee ordering and its rows by where their entries
lie, computed once per trace; a network of bounded width then fits a band of at most
:data:`BAND_LIMIT` diagonals and is factorised by banded LAPACK (``gbtrf``, O(N) with a small
constant), any other by SuperLU. Both factor objects answer ``solve(b, trans)`` (several
right-hand sides at once) and ``det_sign()`` (the sign of det A, for the branch test).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import KinematicsError

# scipy is imported in the functions that use it: the command line imports the kinematics to
# build its parser and must start without it (tests/test_cli_startup.py)

__all__ = ["BAND_LIMIT", "BorderedSystem", "gauge_rows", "permutation_parity"]

def permutation_parity(perm: np.ndarray) -> int:
    """+1 for an even permutation, -1 for an odd one: parity = (n - number of cycles) mod 2,
    the cycles counted as connected components of the graph i -> perm[i]."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    perm = np.asarray(perm, dtype=np.int64)
    n = perm.size
    graph = sp.csr_matrix((np.ones(n, dtype=np.int8), (np.arange(n), perm)), shape=(n, n))
    cycles = connected_components(graph, directed=True, connection="weak", return_labels=False)
    return 1 if (n - cycles) % 2 == 0 else -1


def gauge_rows(x: np.ndarray, gauge) -> np.ndarray:
    """Columns (flat coordinate indices) fixed to hold the gauge element still.

    2D, edge (g0, g1): both coordinates of g0 and the coordinate of g1 along which a rotation
    about g0 moves it most. 3D, triangle (g0, g1, g2): g0's three coordinates, the two of g1 most
    perpendicular to g1 - g0, and the coordinate of g2 along the triangle's normal that is
    largest (the direction a rotation about g0-g1 moves g2).
    """
    n, d = x.shape
    g = list(gauge)
    cols = [d * g[0] + c for c in range(d)]
    if d == 2:
        u = x[g[1]] - x[g[0]]
        rot = np.array([-u[1], u[0]])
        cols.append(d * g[1] + int(np.argmax(np.abs(rot))))
        return np.array(cols, dtype=np.int64)
    u = x[g[1]] - x[g[0]]
    for c in np.argsort(np.abs(u))[:2]:
        cols.append(d * g[1] + int(c))
    if len(g) > 2:
        normal = np.cross(u, x[g[2]] - x[g[0]])
        cols.append(d * g[2] + int(np.argmax(np.abs(normal))))
    return np.array(cols, dtype=np.int64)


#: Largest ``kl + ku`` for which the banded LAPACK factorisation is used (else SuperLU).
BAND_LIMIT = 64


#: Systems of at most this many rows leave their orderings (:class:`BorderedSystem`) for the
#: next system of the same bars and gauge: the tolerance analysis traces a hundred builds of one
#: design, and the orderings cost a tenth of each short trace. Larger ones are traced once.
STRUCTURE_CACHE_ROWS = 20_000

#: Orderings kept (the most recent; a design's builds use a few choices of bars and gauges).
STRUCTURE_CACHE_SIZE = 16

_STRUCTURES: dict = {}

#: Placements of the last row kept per system of at most STRUCTURE_CACHE_ROWS rows (one per
#: coordinate that parametrised a step, each a row permutation).
PLACEMENTS_KEPT = 32


def _cached(key, make):
    """``make()``, kept under ``key`` (None: not kept) among the last
    :data:`STRUCTURE_CACHE_SIZE` results."""
    if key is None:
        return make()
    got = _STRUCTURES.pop(key, None)
    if got is None:
        got = make()
    _STRUCTURES[key] = got  # the most recent last
    while len(_STRUCTURES) > STRUCTURE_CACHE_SIZE:
        _STRUCTURES.pop(next(iter(_STRUCTURES)))
    return got


_LAPACK: list = []


def _band_lapack() -> tuple:
    """LAPACK's ``dgbtrf`` and ``dgbtrs``, imported at the first factorisation (scipy is not
    imported with the module) and then looked up once, not at every solve."""
    if not _LAPACK:
        from scipy.linalg.lapack import dgbtrf, dgbtrs

        _LAPACK.extend((dgbtrf, dgbtrs))
    return _LAPACK[0], _LAPACK[1]


def _frozen(a: np.ndarray) -> np.ndarray:
    """``a``, read-only: a kept ordering is shared by every system of its network."""
    a.setflags(write=False)
    return a


class _BandLU:
    """LU with partial pivoting (LAPACK ``gbtrf``) of ``A[rowperm][:, colperm]``, a permutation
    of A into a band of ``kl`` sub- and ``ku`` superdiagonals.

    Chains, strips and anything of bounded width are banded once their nodes are ordered along
    the structure (reverse Cuthill-McKee); the band factorisation then costs O(N·kl·(kl+ku)) with
    a small constant, several times cheaper than a general sparse LU of the same matrix.
    Interface of SuperLU's factor object as used here: ``solve(b, trans)``, ``det_sign()``.
    """

    def __init__(self, lub, piv, kl, ku, rowperm, colperm, colpos, perm_sign):
        self.lub, self.piv, self.kl, self.ku = lub, piv, kl, ku
        self.rowperm, self.colperm, self.colpos = rowperm, colperm, colpos
        self.perm_sign = perm_sign
        self._rowpos = self._det = None

    def solve(self, b, trans="N"):
        """Solve A x = b (or Aᵀ x = b); b of shape (m,), or (k, m) for k right-hand sides solved
        in one pass over the factors (the band is read once for all of them)."""
        b = np.asarray(b, dtype=np.float64)
        if trans == "N":  # A x = b  ⇔  A' x[colperm] = b[rowperm]
            into, back = self.rowperm, self.colpos
        else:  # Aᵀ x = b  ⇔  A'ᵀ x[rowperm] = b[colperm]
            if self._rowpos is None:
                self._rowpos = np.empty_like(self.rowperm)
                self._rowpos[self.rowperm] = np.arange(self.rowperm.size)
            into, back = self.colperm, self._rowpos
        # take (a fresh array, which the solve then overwrites) rather than fancy indexing, and
        # the inverse permutation by take rather than a scatter: the permutations cost a few
        # percent of a solve instead of a tenth
        y = b.take(into, axis=-1)
        sol, _ = _band_lapack()[1](self.lub, self.kl, self.ku, y.T, self.piv,
                                   trans=int(trans != "N"), overwrite_b=1)
        return sol.T.take(back, axis=-1)

    def det_sign(self) -> int:
        if self._det is None:
            diag = self.lub[self.kl + self.ku].copy()  # one strided pass over the band
            steps = np.arange(self.piv.size, dtype=self.piv.dtype)
            swaps = int(np.count_nonzero(self.piv != steps))
            negative = int(np.count_nonzero(diag < 0))
            s = 0 if not diag.all() else (-1 if negative % 2 else 1)
            self._det = s * self.perm_sign * (-1 if swaps % 2 else 1)
        return self._det


class _SuperLU:
    """SuperLU's factor object with the same interface as :class:`_BandLU`."""

    def __init__(self, lu):
        self.lu = lu

    def solve(self, b, trans="N"):
        b = np.asarray(b, dtype=np.float64)
        return self.lu.solve(b.T, trans=trans).T

    def det_sign(self) -> int:
        diag = self.lu.U.diagonal()
        s = int(np.prod(np.sign(diag)))
        return s * permutation_parity(self.lu.perm_r) * permutation_parity(self.lu.perm_c)


class BorderedSystem:
    """The square sparse system A = [R; gauge rows; last row] and its factorisation.

    Parameters
    ----------
    edges : numpy.ndarray of int, shape (E, 2)
        The bars' end nodes.
    rest2 : numpy.ndarray, shape (E,)
        The bars' squared rest lengths.
    n, d : int
        Number of nodes and dimension.
    gcols : numpy.ndarray of int
        Flat coordinate indices held by the gauge rows (:func:`gauge_rows`).
    gvals : numpy.ndarray
        The values those coordinates are held at.
    rows_keep : numpy.ndarray of int or None
        The bars whose rows make the system square (the others are redundant at the start);
        None: all of them.

    Raises
    ------
    KinematicsError
        When the rows kept and the gauge rows do not make the system square.
    """

    def __init__(self, edges: np.ndarray, rest2: np.ndarray, n: int, d: int, gcols: np.ndarray,
                 gvals: np.ndarray, rows_keep: np.ndarray | None):
        self.edges = edges if rows_keep is None else edges[rows_keep]
        self.rest2 = rest2 if rows_keep is None else rest2[rows_keep]
        self.n, self.d = n, d
        self.gcols, self.gvals = gcols, gvals
        e = self.edges.shape[0]
        self.n_rows = e + gcols.size + 1
        if self.n_rows != d * n:
            raise KinematicsError("internal: the bordered system is not square")
        # the edge rows' entries block by block: the x_i-coordinates of every edge, then the
        # next coordinate, ..., then those of x_j (values x_i - x_j, then x_j - x_i), so that
        # :meth:`_entries` writes contiguous blocks
        self._rows = np.tile(np.arange(e), 2 * d)
        self._cols = np.concatenate([d * self.edges[:, end] + c for end in (0, 1)
                                     for c in range(d)])
        self._grow = np.arange(e, e + gcols.size)
        self._e0 = np.ascontiguousarray(self.edges[:, 0])
        self._e1 = np.ascontiguousarray(self.edges[:, 1])
        # Band structure, fixed for the whole trace except the last row: coordinates ordered by
        # node along the structure (reverse Cuthill-McKee), rows by the mean position of their
        # entries; the last row is inserted where its own entries lie. Both orderings depend on
        # the bars and the gauge only, and are kept for the next system of the same network.
        self._key = None
        if self.n_rows <= STRUCTURE_CACHE_ROWS:
            self._key = (n, d, np.ascontiguousarray(self.edges, dtype=np.int64).tobytes())
        self._colperm, self._colpos, self._colperm_parity = _cached(
            None if self._key is None else ("columns",) + self._key, self._order_columns)
        self._order_rows()

    def _order_columns(self) -> tuple:
        """The coordinates ordered node by node along a reverse Cuthill-McKee ordering: the
        permutation, its inverse and its parity."""
        import scipy.sparse as sp
        from scipy.sparse.csgraph import reverse_cuthill_mckee

        n, d, m, e = self.n, self.d, self.n_rows, self.edges.shape[0]
        graph = sp.coo_matrix((np.ones(e), (self.edges[:, 0], self.edges[:, 1])), shape=(n, n))
        order = reverse_cuthill_mckee((graph + graph.T).tocsr(), symmetric_mode=True)
        colperm = (d * order[:, None] + np.arange(d)).ravel()
        colpos = np.empty(m, dtype=np.int64)
        colpos[colperm] = np.arange(m)
        return _frozen(colperm), _frozen(colpos), permutation_parity(colperm)

    def _order_rows(self):
        """Rows ordered by the mean position of their entries (the gauge rows by their one
        entry); the last row is inserted at each factorisation."""
        key = None if self._key is None else ("rows", self.gcols.tobytes()) + self._key
        (self._base_order, self._base_keys, self._fixed_rows, self._fixed_cpos, self._perm_sign,
         self._entry_bpos, self._lower_head, self._lower_tail, self._upper_head,
         self._upper_tail) = _cached(key, self._row_structure)
        self._flat_key = self._flat = self._last_insert = None
        self._placements = {}

    def _row_structure(self) -> tuple:
        """The row order of :meth:`_order_rows` and what the band assembly derives from it."""
        m = self.n_rows
        fixed_rows = np.concatenate([self._rows, self._grow])
        fixed_cpos = self._colpos[np.concatenate([self._cols, self.gcols])]
        key = (np.bincount(fixed_rows, weights=fixed_cpos, minlength=m - 1)
               / np.maximum(np.bincount(fixed_rows, minlength=m - 1), 1))
        base_order = np.argsort(key, kind="stable")
        perm_sign = permutation_parity(base_order) * self._colperm_parity
        # Band assembly without re-deriving the fixed entries at every factorisation: inserting
        # the last row at position ins moves the rows at or after it down by one, so an entry's
        # row is its base position plus (base position >= ins), and the band widths follow from
        # prefix and suffix maxima, over the rows in base order, of each row's reach below and
        # above the diagonal.
        bpos = np.empty(m - 1, dtype=np.int64)
        bpos[base_order] = np.arange(m - 1)
        e, d = self.rest2.size, self.d
        edge_cpos = fixed_cpos[:2 * d * e].reshape(2 * d, e)  # the entries' block layout
        gauge_cpos = fixed_cpos[2 * d * e:]
        first = np.concatenate([edge_cpos.min(axis=0), gauge_cpos])[base_order]
        last = np.concatenate([edge_cpos.max(axis=0), gauge_cpos])[base_order]
        position = np.arange(m - 1)
        lower, upper = position - first, last - position
        arrays = (base_order, key[base_order], fixed_rows, fixed_cpos, perm_sign,
                  bpos[fixed_rows], np.maximum.accumulate(lower),
                  np.maximum.accumulate(lower[::-1])[::-1], np.maximum.accumulate(upper),
                  np.maximum.accumulate(upper[::-1])[::-1])
        return tuple(_frozen(a) if isinstance(a, np.ndarray) else a for a in arrays)

    def regauge(self, gcols: np.ndarray, gvals: np.ndarray) -> None:
        """Hold other coordinates still (as many as before): the gauge rows and the row order
        change, the column order (along the structure) does not."""
        if gcols.size != self.gcols.size:
            raise KinematicsError("internal: a new gauge must fix as many coordinates")
        self.gcols, self.gvals = gcols, gvals
        self._order_rows()

    def diff(self, x: np.ndarray) -> np.ndarray:
        """Edge vectors ``x_i - x_j`` (``take`` on contiguous index arrays: several times faster
        than fancy indexing with a column of the edge array)."""
        out = x.take(self._e0, axis=0)
        out -= x.take(self._e1, axis=0)
        return out

    def residual(self, xf: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Edge and gauge residuals (without the last row), shape (n_rows - 1,); written into
        ``out[:n_rows - 1]`` when ``out`` (shape (n_rows,)) is given, the last entry left to the
        caller (a right-hand side assembled without a concatenation)."""
        xf = np.ascontiguousarray(xf, dtype=np.float64)
        e = self.rest2.size
        r = np.empty(self.n_rows - 1) if out is None else out[:-1]
        fe = r[:e]
        if self.d == 2:
            # a node as one complex number: one gather per edge end instead of two, and no
            # einsum (this is evaluated at every Newton iteration)
            z = xf.view(np.complex128)
            dz = z.take(self._e0)
            dz -= z.take(self._e1)
            parts = dz.view(np.float64)
            np.multiply(parts[0::2], parts[0::2], out=fe)
            im = parts[1::2]
            np.multiply(im, im, out=im)
            fe += im
        else:
            diff = self.diff(xf.reshape(self.n, self.d))
            np.einsum("ij,ij->i", diff, diff, out=fe)
        fe -= self.rest2
        fe *= 0.5
        np.subtract(xf.take(self.gcols), self.gvals, out=r[e:])
        return r

    def rel_from_residual(self, r: np.ndarray) -> float:
        """Relative edge residual max |l² - L²| / (2 L²) from a residual vector."""
        rel = np.abs(r[:self.rest2.size])
        rel /= self.rest2
        return float(np.maximum.reduce(rel))  # NaN as max() gives it, without its wrapper

    def rel_edge_residual(self, xf: np.ndarray) -> float:
        x = xf.reshape(self.n, self.d)
        diff = self.diff(x)
        return float(np.max(np.abs(np.einsum("ij,ij->i", diff, diff) / self.rest2 - 1.0)) / 2.0)

    def _entries(self, xf: np.ndarray) -> np.ndarray:
        """Values of the fixed entries (edge and gauge rows), in the order of ``_rows``."""
        xf = np.ascontiguousarray(xf, dtype=np.float64)
        e, d = self.rest2.size, self.d
        fixed = np.empty(e * 2 * d + self.gcols.size)
        if d == 2:  # as in :meth:`residual`
            z = xf.view(np.complex128)
            dz = z.take(self._e0)
            dz -= z.take(self._e1)
            parts = dz.view(np.float64)
            fixed[:e] = parts[0::2]
            fixed[e:2 * e] = parts[1::2]
        else:
            diff = self.diff(xf.reshape(self.n, d))
            for c in range(d):
                fixed[c * e:(c + 1) * e] = diff[:, c]
        np.negative(fixed[:d * e], out=fixed[d * e:2 * d * e])
        fixed[e * 2 * d:] = 1.0
        return fixed

    def factorize(self, xf: np.ndarray, last_cols: np.ndarray, last_vals: np.ndarray):
        """LU factors of A(x) with the given last row (banded LAPACK where the band is narrow,
        else SuperLU), or None when the matrix is exactly singular."""
        m = self.n_rows
        fixed = self._entries(xf)
        ins, rowperm, kl, ku, last_cpos, flat = self._placement(last_cols)
        if kl + ku <= BAND_LIMIT:
            ldab = 2 * kl + ku + 1
            ab = np.zeros((ldab, m), order="F")
            band = ab.T.reshape(-1)  # a view: the band's columns one after the other
            band[flat] = fixed
            ab[kl + ku + ins - last_cpos, last_cpos] = last_vals
            lub, piv, info = _band_lapack()[0](ab, kl, ku, overwrite_ab=1)
            if info != 0:
                return None
            # moving the last row from the end to position ins is a cycle of m - ins entries
            sign = self._perm_sign * (-1 if (m - 1 - ins) % 2 else 1)
            return _BandLU(lub, piv, kl, ku, rowperm, self._colperm, self._colpos, sign)
        rows = np.concatenate([self._rows, self._grow, np.full(last_cols.size, m - 1)])
        cols = np.concatenate([self._cols, self.gcols, last_cols])
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        a = sp.csc_matrix((np.concatenate([fixed, last_vals]), (rows, cols)), shape=(m, m))
        try:
            return _SuperLU(spla.splu(a, permc_spec="COLAMD"))
        except RuntimeError:
            return None

    def _placement(self, last_cols: np.ndarray) -> tuple:
        """Where a last row with entries in ``last_cols`` goes: (its row position, the row
        permutation, kl, ku, the entries' column positions, the fixed entries' flat indices in
        the band or None), kept for the next factorisations with the same columns (the step's
        parametrising coordinate changes rarely)."""
        key = last_cols.tobytes()
        got = self._placements.get(key)
        if got is not None:
            return got
        m = self.n_rows
        last_cpos = self._colpos[last_cols]
        ins = int(np.searchsorted(self._base_keys, last_cpos.mean(), side="right"))
        if self._last_insert is not None and self._last_insert[0] == ins:
            rowperm = self._last_insert[1]
        else:
            rowperm = np.insert(self._base_order, ins, m - 1)
            self._last_insert = (ins, rowperm)
        # rows before the new one keep their position, those from it on move down by one
        kl = max(0, int((ins - last_cpos).max()),
                 int(self._lower_head[ins - 1]) if ins > 0 else 0,
                 int(self._lower_tail[ins]) + 1 if ins < m - 1 else 0)
        ku = max(0, int((last_cpos - ins).max()),
                 int(self._upper_head[ins - 1]) if ins > 0 else 0,
                 int(self._upper_tail[ins]) - 1 if ins < m - 1 else 0)
        flat = None
        if kl + ku <= BAND_LIMIT:
            ldab = 2 * kl + ku + 1
            # successive factorisations mostly hold the same coordinate (same ins and band):
            # the entries' positions in the band are kept for the next one
            band_key = (ldab, ins, kl + ku)
            if self._flat_key == band_key:
                flat = self._flat
            else:  # flat index in the Fortran-ordered band
                flat = self._entry_bpos + self._fixed_cpos * (ldab - 1)
                flat += self._entry_bpos >= ins  # the rows from ins on move down by one
                flat += kl + ku
                self._flat_key, self._flat = band_key, flat
        got = (ins, rowperm, kl, ku, last_cpos, flat)
        if self._key is not None:  # a small system: a few of them are kept
            if len(self._placements) >= PLACEMENTS_KEPT:
                self._placements.pop(next(iter(self._placements)))
            self._placements[key] = got
        return got

    @staticmethod
    def det_sign(lu) -> int:
        return lu.det_sign()

    @staticmethod
    def sigma_min(lu, n: int, iterations: int = 4, seed: int = 0) -> float:
        """Estimate of the smallest singular value of A by inverse iteration on AᵀA."""
        v = np.random.default_rng(seed).standard_normal(n)
        v /= np.linalg.norm(v)
        growth = 1.0
        for _ in range(iterations):
            w = lu.solve(lu.solve(v, trans="T"))
            growth = np.linalg.norm(w)
            if not np.isfinite(growth) or growth == 0:
                return 0.0
            v = w / growth
        return float(1.0 / math.sqrt(growth))
