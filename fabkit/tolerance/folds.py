"""Origami states judged in the fold's own terms: by the fold angles of the built sheet.

A sheet of paper's state is its folds. The module criteria (:mod:`fabkit.tolerance.criteria`)
find where each built module has its designed state (its fixed point, or where it locks flat)
as a port distance; for an origami design that state is then judged by what a folder sees: every
crease's fold angle of the built sheet placed there, against the designed state's.

**The threshold.** The designed states are ``apart`` degrees apart: the largest change of any
crease's fold angle between the start state and the end state (165.4° for the paper's sheet,
flat to its folded crystal). A built state is kept while every crease's fold angle stays within
``state_fraction`` (0.25, the tolerance setting every design's states share) of that distance
of the designed state's: 41.4° on the paper's sheet. The reason is the state tolerance's own,
now in the fold's terms: a built state is the designed one while each of its folds lies nearer
to it than to the middle of the way to the other state, by a factor of two. It replaces the
port-distance tolerance (``state_fraction`` of the travel: 22 mm on the paper's 106 mm sheet,
a fifth of its side), which next to the folded crystal let the design's own fold path run to
fully folded (180°) within 2.5 mm, and stays only as the window the built state is looked
for in.

Port distance is a poor proxy next to a flat or a fully folded state: there a fold angle goes
as the square root of the port distance's change, so a millimetre of a built fixed point's
offset may be tens of degrees on the design's fold path, while the built sheet, whose own path
moved with it, folds within a few degrees of the design. Only the built sheet itself tells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fab.creases import fold_angles, origami_model
from ..settings.origami import origami_settings

__all__ = ["FoldStates", "fold_states"]

@dataclass(frozen=True, eq=False)
class FoldStates:
    """The designed states of an origami design's modules, by their fold angles.

    Attributes
    ----------
    faces : tuple of tuple of int
        The first module's paper faces, in its local node order (every module is a copy of
        it, its nodes in the same order).
    edges : numpy.ndarray of int, shape (E, 2)
        The first module's bars, in its local order.
    start, end : numpy.ndarray, shape (E,)
        The fold angle of each bar (degrees, 0 on bars with fewer than two faces) in the
        designed start and end states.
    apart_deg : float
        The designed states' distance apart: the largest |end - start| of a fold angle.
    limit_deg : float
        ``fraction`` of it: how far a built state's fold angle may be from the designed
        state's.
    fraction : float
        The tolerance's ``state_fraction``.
    """

    faces: tuple
    edges: np.ndarray
    start: np.ndarray
    end: np.ndarray
    apart_deg: float
    limit_deg: float
    fraction: float

    def as_dict(self) -> dict:
        return {"apart_deg": self.apart_deg, "limit_deg": self.limit_deg,
                "fraction": self.fraction}


def fold_states(design, spec, modules, x_start, x_end) -> FoldStates | None:
    """The designed states' fold angles of an origami design's first module.

    Parameters
    ----------
    design : Design
    spec : ToleranceSpec
        Its ``origami_settings`` (else the template's) name the sheets and their faces; its
        ``state_fraction`` the fraction of the states' distance apart a fold may be off.
    modules : list of Module
    x_start, x_end : numpy.ndarray, shape (N, 3)
        The design at its start and at its end.

    Returns
    -------
    FoldStates or None
        None when the design is not origami or has no modules.

    Raises
    ------
    FabkitError
        Its origami settings or sheets cannot be read.
    """
    if spec.process != "origami" or not modules:
        return None
    settings = spec.origami_settings or origami_settings(design)
    faces = origami_model(design, settings).faces
    first = modules[0]
    local = {int(g): i for i, g in enumerate(first.nodes)}
    mine = tuple(tuple(local[int(v)] for v in f) for f in faces
                 if all(int(v) in local for v in f))
    edges = np.asarray(first.network.edges)
    if not mine:
        return None
    start = fold_angles(edges, mine, np.asarray(x_start)[first.nodes])
    end = fold_angles(edges, mine, np.asarray(x_end)[first.nodes])
    apart = float(np.max(np.abs(end - start)))
    frac = float(spec.state_fraction)
    return FoldStates(mine, edges, start, end, apart, frac * apart, frac)
