"""Flat node sets: the plane coordinates of a sheet given in 3D, and its largest extent.

An origami sheet is given as a 3D network whose nodes lie in one plane; its crease pattern is
drawn in that plane's own coordinates, and its size is measured corner to corner.
"""

from __future__ import annotations

import numpy as np

from ..numerics import canonical_frame, FLAT_SHEET_RTOL, TINY

__all__ = ["flat_coords", "point_diameter"]


def point_diameter(points) -> float:
    """Largest distance between two of the points (on their convex hull when there are many).

    Parameters
    ----------
    points : array_like, shape (N, D)

    Returns
    -------
    float

    Examples
    --------
    >>> point_diameter([[0, 0], [3, 0], [0, 4], [1, 1]])
    5.0
    """
    p = np.asarray(points, dtype=np.float64)
    if p.shape[0] > 64:
        from scipy.spatial import ConvexHull, QhullError

        try:
            p = p[ConvexHull(p).vertices]
        except QhullError:  # all on one line
            pass
    diff = p[:, None, :] - p[None, :, :]
    return float(np.sqrt((diff * diff).sum(axis=-1)).max())


def flat_coords(x: np.ndarray, edges=None, tol: float = FLAT_SHEET_RTOL):
    """2D coordinates of a planar node set (in its own plane), or None when it is not planar.

    A sheet drawn in the xy plane keeps its coordinates and orientation; any other plane gets
    the frame of its own bars (:func:`fabkit.numerics.canonical_frame`: x along the first bar),
    so the pattern does not turn with the last bits of an eigenvector.

    Parameters
    ----------
    x : numpy.ndarray, shape (N, 3)
    edges : numpy.ndarray, shape (E, 2), optional
        The bars, whose first one sets the frame of a sheet outside the xy plane.
    tol : float
        Out-of-plane distance allowed, as a fraction of the set's extent.

    Returns
    -------
    numpy.ndarray, shape (N, 2), or None
    """
    c = x - x.mean(axis=0)
    size = max(float(np.ptp(x, axis=0).max()), TINY)
    normal = np.linalg.svd(c, full_matrices=False)[2][2]
    if np.abs(c @ normal).max() > tol * size:
        return None
    if np.ptp(x[:, 2]) <= tol * size:
        return x[:, :2].copy()  # already in the xy plane: keep its coordinates and orientation
    frame = canonical_frame(x, edges if edges is not None else np.array([[0, 1]]))
    return c @ frame[:2].T
