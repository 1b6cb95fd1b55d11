"""Where the random errors of a build are attached: an order of the joints and a frame that
belong to the design, not to how it is numbered or where it is drawn.

A simulated build draws one error per joint (a print's xy error, an origami vertex's offset).
Drawn in node order and in the drawing's x, y, z, the same design renumbered, or drawn rotated,
would get other builds from the same seed, and its margin would change by the sampling noise of
the Monte Carlo (10-20 % at 200 builds). Drawn in the canonical order and frame below, every
copy of a design gets the same builds, to round-off:

- **order**: joints in the order they first appear in the bar list (a bar list keeps its order
  when the joints are renumbered); joints on no bar last, by index;
- **frame**: x along the first bar (from its first joint to its second), each next axis along the
  part of the first later bar that leaves the span of the axes so far by at least
  :data:`FRAME_MIN_SINE` (Gram–Schmidt); in 3D the last axis is x × y. The frame turns with the
  design, so an error drawn in it moves with the design too.
"""

from __future__ import annotations

import numpy as np

from ..numerics import TINY

__all__ = ["canonical_order", "canonical_frame", "canonical_vectors", "canonical_scalars",
           "FRAME_MIN_SINE"]

#: A bar sets the next axis of the frame when at least this part of its direction (the sine of
#: its angle to the axes so far) leaves their span: far from round-off, so the choice of bar
#: does not hang on the last bits of a nearly parallel one.
FRAME_MIN_SINE = 0.1


def canonical_order(edges, n: int) -> np.ndarray:
    """Joints in the order they first appear in the bar list, then joints on no bar.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    n : int
        Number of joints.

    Returns
    -------
    numpy.ndarray of int, shape (n,)
        ``order[k]`` is the joint at canonical position k.

    Examples
    --------
    >>> canonical_order([[2, 0], [0, 3]], 5).tolist()
    [2, 0, 3, 1, 4]
    """
    flat = np.asarray(edges, dtype=np.int64).reshape(-1)
    _, first = np.unique(flat, return_index=True)
    seen = flat[np.sort(first)]
    rest = np.setdiff1d(np.arange(n), seen, assume_unique=False)
    return np.concatenate([seen, rest]).astype(np.int64)


def canonical_frame(points, edges) -> np.ndarray:
    """An orthonormal frame that turns with the design (see the module docstring).

    Parameters
    ----------
    points : array_like, shape (N, d)
    edges : array_like of int, shape (E, 2)

    Returns
    -------
    numpy.ndarray, shape (d, d)
        Rows are the axes; a vector with coordinates ``c`` in the frame is ``c @ frame``.
        Proper (determinant +1) in 3D; in 2D it follows the design's own turn from its first
        bar to the next one across it.
    """
    x = np.asarray(points, dtype=np.float64)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    d = x.shape[1]
    vec = x[e[:, 1]] - x[e[:, 0]]
    norm = np.linalg.norm(vec, axis=1)
    vec = vec[norm > 0] / norm[norm > 0, None]
    axes: list[np.ndarray] = []
    want = d if d == 2 else 2
    for v in vec:
        r = v - sum((v @ a) * a for a in axes) if axes else v
        s = float(np.linalg.norm(r))
        if not axes or s >= FRAME_MIN_SINE:
            axes.append(r / max(s, TINY))
        if len(axes) == want:
            break
    if not axes:
        axes.append(np.eye(d)[0])
    if len(axes) < want:  # every bar on one line: a fixed perpendicular
        a = axes[0]
        k = int(np.argmin(np.abs(a)))
        if d == 2:
            axes.append(np.array([-a[1], a[0]]))
        else:
            p = np.cross(a, np.eye(3)[k])
            axes.append(p / np.linalg.norm(p))
    if d == 3:
        axes.append(np.cross(axes[0], axes[1]))
    return np.array(axes)


def canonical_vectors(rng, m: int, points, edges) -> np.ndarray:
    """``m`` draws of a standard normal vector per joint, shape (m, N, d), attached to the
    design: drawn in the canonical order and frame, returned by joint in the drawing's frame."""
    x = np.asarray(points, dtype=np.float64)
    n, d = x.shape
    order = canonical_order(edges, n)
    z = rng.standard_normal((m, n, d)) @ canonical_frame(x, edges)
    out = np.empty_like(z)
    out[:, order] = z
    return out


def canonical_scalars(draws: np.ndarray, edges, n: int) -> np.ndarray:
    """Per-joint draws ``(m, N, ...)`` made in canonical order, put back by joint."""
    order = canonical_order(edges, n)
    out = np.empty_like(draws)
    out[:, order] = draws
    return out
