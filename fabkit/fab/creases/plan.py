"""The origami process's plan: the design's sheets and their fold, decided once.

Every origami writer (the crease SVG and its cut sheets, FOLD, ORIPA .cp) is written from one
plan, so an export of every origami format folds the design once
(:func:`~fabkit.fab.creases.folding.fold_model`: the branch out of a flat start chosen by the
crease assignment, the fold's own samples).
"""

from __future__ import annotations

from dataclasses import dataclass

from ...settings.design import design_settings
from .folding import fold_model, FoldResult, OrigamiModel, origami_model

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
    """

    design: object
    model: OrigamiModel
    fold: FoldResult


def origami_plan(design, settings=None, motion=None) -> OrigamiPlan:
    """The origami plan of a design: its model, folded along its motion.

    Parameters
    ----------
    design : Design
    settings : DesignSettings, optional
        The design's settings, resolved once (:func:`fabkit.settings.design.design_settings`;
        a dict of overrides nested by section, ``{"origami": {"samples": 41}}``, is resolved
        here).
    motion : TracedMotion, optional
        Not used: a sheet folds along the branch its crease assignment names, which the fold
        chooses itself (:func:`~fabkit.fab.creases.folding.fold_model`).

    Returns
    -------
    OrigamiPlan

    Raises
    ------
    FabricationError
        No [fabrication.origami] table, bad settings, or a folding the simulator cannot do.
    """
    model = origami_model(design, design_settings(design, settings).require("origami"))
    return OrigamiPlan(design, model, fold_model(model, design.motion.drive, design.motion.to))
