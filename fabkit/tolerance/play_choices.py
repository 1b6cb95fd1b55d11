"""Which bars take up a loop's play: every choice the design's states of self-stress leave open.

A kit with play is traced without one bar per state of self-stress (the loop closes within its
play instead, watched along the motion). At first order any bar a stress loads is as good as
another, but the motion they allow differs at second order: the AND gate's junction is a flat
quadrilateral whose four bars carry the stress equally (every tension on one line); left without
one of the trunk's bars, the trunk swings up to 0.7 mm within the play as the branch locks,
left without one of the branch's, it stays still. A pivoted QR picks among such equals by
round-off (a different bar with one BLAS thread than with two), so a reported number depended
on the machine.

Here the choice is explicit: the bars a stress loads most, to within :data:`PLAY_TIE_RTOL`, are
equal candidates, and every set of them that removes all states of self-stress is returned (in
index order, at most :data:`PLAY_CHOICES_MAX`). The tolerance analysis traces a build under each
and keeps the one that disturbs its still parts least: the swing happens with the drive standing
still (1e-8 of drive for 0.1 mm of swing), a motion no push on the drive makes, and along which
the tracer's way is itself chosen by round-off.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PLAY_CHOICES_MAX", "PLAY_TIE_RTOL", "redundant_choices"]

#: Two bars load a state of self-stress equally when their coefficients (after the bars chosen
#: before are projected out) differ by less than this, relative to the largest: the flat
#: junction's four coefficients agree to 1e-15, a generic loop's differ at the first digits.
PLAY_TIE_RTOL = 1e-9

#: At most this many sets of bars are traced per build (a single flat loop gives four; several
#: tied loops multiply, and past this the first sets in index order stand for the rest).
PLAY_CHOICES_MAX = 8


def redundant_choices(stresses: np.ndarray) -> list[np.ndarray]:
    """Sets of bars, one bar per state of self-stress, that together leave a network with none.

    Parameters
    ----------
    stresses : ndarray, shape (n_edges, k)
        A basis of the states of self-stress (columns), ``k >= 1``.

    Returns
    -------
    list of ndarray
        Sorted edge indices, ``k`` each; distinct sets in the order of their smallest differing
        index, at most :data:`PLAY_CHOICES_MAX`. The greedy choice is a column-pivoted QR whose
        ties are explicit: each step takes a bar the remaining stresses load most, and every
        tied bar is a branch.

    Examples
    --------
    >>> import numpy as np
    >>> [c.tolist() for c in redundant_choices(np.array([[1.0], [-1.0], [0.5], [1.0]]))]
    [[0], [1], [3]]
    """
    basis = np.asarray(stresses, dtype=float).T
    found: list[tuple[int, ...]] = []
    _branch(basis, (), found)
    return [np.array(c, dtype=np.intp) for c in sorted(found)]


def _branch(residual: np.ndarray, chosen: tuple[int, ...], found: list) -> None:
    """Depth-first over tied pivots; ``residual`` holds the stresses with ``chosen`` removed."""
    if len(found) >= PLAY_CHOICES_MAX:
        return
    if len(chosen) == residual.shape[0]:
        key = tuple(sorted(chosen))
        if key not in found:
            found.append(key)
        return
    norms = np.linalg.norm(residual, axis=0)
    norms[list(chosen)] = 0.0
    top = norms.max()
    for e in np.flatnonzero(norms >= top * (1.0 - PLAY_TIE_RTOL)):
        q = residual[:, e] / norms[e]
        _branch(residual - np.outer(q, q @ residual), chosen + (int(e),), found)
