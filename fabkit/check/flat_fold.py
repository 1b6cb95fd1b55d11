"""Maekawa and Kawasaki at the interior vertices of a FOLD file's crease pattern.

A vertex is interior when no boundary (B) or cut (C) edge meets it. Its folds are the mountain
(M) and valley (V) creases at it: a facet diagonal (F) is flat, and fabkit writes U for a crease
that stays flat all along the motion. At a vertex with folds, a sheet that folds flat needs

- Maekawa: ``|#M - #V| = 2``;
- Kawasaki: the sector angles between consecutive folds, taken alternately, sum to pi.

A vertex without folds (every crease at it flat) is not a vertex of the folding and is skipped.
"""

from __future__ import annotations

import numpy as np

__all__ = ["KAWASAKI_TOL", "vertex_folds"]

#: Largest difference (radians) between the alternate sector angles' sum and pi. The file stores
#: coordinates to 12 significant digits, so a sector of a crease a thousandth of the sheet long
#: is known to about 1e-9 rad; 1e-8 leaves margin and refuses any vertex visibly off.
KAWASAKI_TOL = 1e-8


def vertex_folds(xy, edges, assignment) -> list[dict]:
    """Maekawa and Kawasaki at every interior vertex with folds.

    Parameters
    ----------
    xy : array_like, shape (V, 2)
        The flat pattern's vertices.
    edges : array_like of int, shape (E, 2)
    assignment : sequence of str, length E

    Returns
    -------
    list of dict
        One per interior vertex with folds, in vertex order: ``vertex``, ``mountains``,
        ``valleys``, ``maekawa`` (bool), ``kawasaki`` (the alternate sectors' sum minus pi,
        radians; ``None`` for an odd number of folds, which cannot alternate).

    Examples
    --------
    A square with its centre creased to the four corners, three valleys and a mountain:

    >>> xy = [[0, 0], [2, 0], [2, 2], [0, 2], [1, 1]]
    >>> e = [[0, 1], [1, 2], [2, 3], [3, 0], [4, 0], [4, 1], [4, 2], [4, 3]]
    >>> (v,) = vertex_folds(xy, e, "BBBBVVVM")
    >>> v["vertex"], v["mountains"], v["valleys"], v["maekawa"], abs(v["kawasaki"]) < 1e-12
    (4, 1, 3, True, True)
    """
    x = np.asarray(xy, dtype=np.float64)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    labels = list(assignment)
    edge_of_boundary = np.array([a in ("B", "C") for a in labels], dtype=bool)
    boundary = set(e[edge_of_boundary].ravel().tolist())
    folds_at: dict[int, list[int]] = {}
    for k, (a, b) in enumerate(e.tolist()):
        if labels[k] in ("M", "V"):
            folds_at.setdefault(a, []).append(k)
            folds_at.setdefault(b, []).append(k)
    out = []
    for vert in sorted(folds_at):
        if vert in boundary:
            continue
        at = folds_at[vert]
        far = np.where(e[at, 0] == vert, e[at, 1], e[at, 0])
        d = x[far] - x[vert]
        heading = np.arctan2(d[:, 1], d[:, 0])
        order = np.argsort(heading)
        turns = np.diff(np.append(heading[order], heading[order[0]] + 2.0 * np.pi))
        m = sum(labels[k] == "M" for k in at)
        v = len(at) - m
        out.append({"vertex": vert, "mountains": m, "valleys": v, "maekawa": abs(m - v) == 2,
                    "kawasaki": float(turns[0::2].sum() - np.pi) if len(at) % 2 == 0 else None})
    return out
