"""The STL file itself: binary STL bytes of a mesh, where its origin lies on the bed, and
whether a mesh stays closed once stored as an STL stores it (float32, merged by position).

Shared by the hinge print (:mod:`fabkit.writers.stl`) and the print-in-place linkage
(:mod:`fabkit.writers.pinned`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["binary_stl", "stl_origin", "stored_mesh_is_closed"]

_STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])


def binary_stl(vertices, faces, header: str = "fabkit printed network, units mm") -> bytes:
    """Binary STL bytes of a triangle mesh.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        Millimetres.
    faces : array_like of int, shape (F, 3)
        Counter-clockwise seen from outside.
    header : str
        ASCII text for the 80-byte header (must not start with "solid").

    Returns
    -------
    bytes
        84 + 50 F bytes.

    Examples
    --------
    >>> data = binary_stl([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> len(data)
    134
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    rec = np.zeros(len(f), dtype=_STL_RECORD)
    rec["normal"] = n
    rec["vertices"] = tri
    head = header.encode("ascii")[:80].ljust(80, b" ")
    return head + np.uint32(len(f)).tobytes() + rec.tobytes()


def stl_origin(printer) -> np.ndarray:
    """Where an STL's origin lies on the bed: its centre. An STL carries no placement (slicers
    put it mid-bed), and float32 keeps more digits near the origin."""
    return np.array([0.5 * printer.width, 0.5 * printer.depth, 0.0])


def stored_mesh_is_closed(vertices, faces) -> bool:
    """True when the mesh is still closed and consistently wound after its vertices are rounded
    to float32 (as in an STL file) and merged by position (as readers do).

    Every directed edge must occur once and its reverse once; no triangle may collapse.
    """
    v = np.asarray(vertices, dtype=np.float32)
    _, inverse = np.unique(v, axis=0, return_inverse=True)
    f = inverse.reshape(-1)[np.asarray(faces, dtype=np.int64)]
    if np.any((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])):
        return False
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    n = int(f.max()) + 1
    key = directed[:, 0] * n + directed[:, 1]
    rev = directed[:, 1] * n + directed[:, 0]
    if np.unique(key).size != key.size:
        return False
    return bool(np.isin(rev, key).all())
