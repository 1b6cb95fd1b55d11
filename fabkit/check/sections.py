"""Cross-sections of a mesh read back: where a plane cuts it, and the material it shows."""

from __future__ import annotations

import numpy as np

__all__ = ["plane_segments", "section"]


def plane_segments(mesh, z: float) -> np.ndarray:
    """Where the plane at height z cuts the mesh's triangles: segments (S, 2, 2) in x-y.

    Each crossing point is computed once per edge, from its lower-numbered vertex, so the two
    triangles beside an edge end their segments at the same point bit for bit and the segments
    close into loops whatever the coordinates' digits (a vertex on the plane counts as below
    it). Computed per triangle, the two ends could differ by one rounding, and the outline of
    a bar written with decimal coordinates fell apart into pieces.
    """
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    above = v[:, 2] > z
    up = above[f]
    cut = up.any(axis=1) & ~up.all(axis=1)
    if not cut.any():
        return np.zeros((0, 2, 2))
    f = f[cut]
    a = f[:, [0, 1, 2]].ravel()
    b = f[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    crosses = above[lo] != above[hi]  # two of a cut triangle's three edges
    lo, hi = lo[crosses], hi[crosses]
    t = (z - v[lo, 2]) / (v[hi, 2] - v[lo, 2])
    pts = v[lo, :2] + t[:, None] * (v[hi, :2] - v[lo, :2])
    return pts.reshape(-1, 2, 2)


def section(mesh, z: float):
    """The solid's material in the plane at height z, as shapely polygons (even-odd rule)."""
    import shapely

    seg = plane_segments(mesh, z)
    if len(seg) == 0:
        return []
    faces = np.asarray(shapely.get_parts(shapely.polygonize(shapely.linestrings(seg))))
    # polygonize gives one face per region between boundary loops; a face is material when an
    # even number of other faces' outlines encloses it (0: outside shell, 1: a hole, 2: an island)
    shells = shapely.polygons(shapely.get_exterior_ring(faces))
    probes = shapely.point_on_surface(faces)
    hits = shapely.STRtree(shells).query(probes, predicate="within")
    hits = hits[:, hits[0] != hits[1]]
    depth = np.bincount(hits[0], minlength=len(faces))
    return list(faces[depth % 2 == 0])
