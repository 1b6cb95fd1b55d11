"""The origami process's plan: the design's sheets and their fold, decided once.

Every origami writer (the crease SVG and its cut sheets, FOLD, ORIPA .cp) is written from one
plan, so an export of every origami format folds the design once
(:func:`~fabkit.fab.creases.folding.fold_model`: the branch out of a flat start chosen by the
crease assignment, the fold's own samples).
"""

from __future__ import annotations

from dataclasses import dataclass

from .folding import fold_model, FoldResult, OrigamiModel, origami_model
from .layout import crease_layout, CreaseLayout

__all__ = ["OrigamiPlan", "origami_plan"]


@dataclass(frozen=True, eq=False)
class OrigamiPlan:
    """The origami process's plan.

    Attributes
    ----------
    design : Design
    model : OrigamiModel
        The sheets, their crease patterns, assignment and settings.
    fold : FoldResult
        The model folded along the design's motion.
    layout : CreaseLayout
        What the crease SVG and its cut sheets draw: the realised assignment, the fold angles,
        the paper, and a chain's joins and pages (:func:`~fabkit.fab.creases.layout.crease_layout`).
    """

    design: object
    model: OrigamiModel
    fold: FoldResult
    layout: CreaseLayout

    @property
    def panels(self) -> list:
        """The paper's panels as cycles of the design's network nodes (what a drawing of the
        design's motion fills)."""
        n = self.design.network.n_nodes
        return [list(map(int, f)) for f in self.model.faces if max(f) < n]


def origami_plan(design, settings=None, motion=None) -> OrigamiPlan:
    """The origami plan of a design: its model, folded along its motion.

    Parameters
    ----------
    design : Design
    settings : dict, optional
        Overrides nested by section (``{"origami": {"samples": 41}}``).
    motion : TracedMotion, optional
        Not used: a sheet folds along the branch its crease assignment names, which the fold
        chooses itself (:func:`~fabkit.fab.creases.folding.fold_model`).

    Returns
    -------
    OrigamiPlan

    Raises
    ------
    FabricationError
        No [fabrication.origami] table, bad settings, a folding the simulator cannot do, or a
        medium too small for a sheet of a chain with its labels and legend.
    """
    model = origami_model(design, (settings or {}).get("origami"))
    fold = fold_model(model, design.motion.drive, design.motion.to)
    return OrigamiPlan(design, model, fold, crease_layout(model, fold))
