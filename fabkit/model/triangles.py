"""The rigid triangles of a planar network: what a triangle-hinge print is made of.

Its own module because the print settings (which print a network gets) and the hinge geometry
(how it is printed) both ask for them.
"""

from __future__ import annotations

import numpy as np

from ..errors import FabricationError
from ..model.network import Network

__all__ = ["rigid_triangles"]


def rigid_triangles(net: Network, given=None) -> np.ndarray:
    """The rigid triangles of a planar network: the given ones (checked) or every 3-clique.

    Parameters
    ----------
    net : Network
        A 2D network.
    given : array_like of int, shape (M, 3), optional
        Triangles named by a template (``rigid_triangles``); each side must be an edge.

    Returns
    -------
    numpy.ndarray of int, shape (M, 3)
        One row per triangle, sorted node indices, rows sorted.

    Raises
    ------
    FabricationError
        A given triangle that repeats a node or whose side is not an edge; a network without
        triangles; an edge that belongs to no triangle (a printed network is made of triangles
        only).

    Examples
    --------
    >>> net = Network([[0, 0], [1, 0], [0, 1], [1, 1]], [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]])
    >>> rigid_triangles(net).tolist()
    [[0, 1, 2], [1, 2, 3]]
    """
    n = net.n_nodes
    e = np.sort(net.edges, axis=1)
    keys = e[:, 0] * n + e[:, 1]
    if given is not None:
        tri = np.asarray(given, dtype=np.int64)
        if tri.ndim != 2 or tri.shape[1] != 3:
            raise FabricationError(f"rigid_triangles must have shape (M, 3), got {tri.shape}")
        bad = np.flatnonzero((tri < 0).any(1) | (tri >= n).any(1))
        if bad.size:
            raise FabricationError(f"rigid triangle {tri[bad[0]].tolist()} names a node outside "
                                   f"0..{n - 1}")
        tri = np.sort(tri, axis=1)
        rep = np.flatnonzero((tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]))
        if rep.size:
            raise FabricationError(f"rigid triangle {tri[rep[0]].tolist()} repeats a node")
        sides = np.stack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]], axis=1)
        found = np.isin(sides[..., 0] * n + sides[..., 1], keys)
        if not found.all():
            t, s = np.argwhere(~found)[0]
            raise FabricationError(f"rigid triangle {tri[t].tolist()}: its side "
                                   f"{sides[t, s].tolist()} is not an edge of the network")
    else:
        # triangles i < j < k from the upper-triangular adjacency: every 2-path i-j-k closed by i-k
        # (its rows as CSR arrays: the sorted distinct keys are the entries row by row, columns
        # ascending; numpy alone, so reading print settings loads no scipy)
        pairs = np.unique(keys)
        cols = pairs % n
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(pairs // n, minlength=n), out=indptr[1:])
        deg = np.diff(indptr)
        counts = deg[e[:, 1]]
        i = np.repeat(e[:, 0], counts)
        j = np.repeat(e[:, 1], counts)
        starts = np.repeat(indptr[e[:, 1]], counts)
        offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        k = cols[starts + offsets]
        closed = np.isin(i * n + k, keys)
        tri = np.stack([i[closed], j[closed], k[closed]], axis=1)
    if tri.size == 0:
        raise FabricationError("the network has no rigid triangles to print")
    tri = np.unique(tri, axis=0)
    sides = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]])
    covered = np.isin(keys, sides[:, 0] * n + sides[:, 1])
    if not covered.all():
        a, b = e[np.argmin(covered)]
        raise FabricationError(f"edge ({a}, {b}) belongs to no rigid triangle; a printed network "
                               "is made of triangles joined at their vertices")
    return tri
