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

from ..numerics import canonical_frame, canonical_order

__all__ = ["canonical_vectors", "canonical_scalars"]


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
