"""The origami process's plan: the design's sheets and their fold, decided once.

Every origami writer (the crease SVG and its cut sheets, FOLD, ORIPA .cp) is written from one
plan, so an export of every origami format folds the design once
(:func:`~fabkit.fab.creases.folding.fold_model`: the branch out of a flat start chosen by the
crease assignment, the fold's own samples), and the plan lays out what the crease SVG draws
(:mod:`fabkit.fab.creases.layout`).

The fold is the design's one trace: :func:`trace_needs` asks the Motion stage to trace the
motion as the fold does (:mod:`fabkit.fab.creases.tracing`), and the fold is made of that trace.
It traces for itself only where the Motion stage does not: a flat start the design's motion
does not leave (the Motion stage's singular start, where the fold chooses the branch), a
sheet whose panels need apex nodes (the fold's network is not the design's), a motion whose
method or options the template fixes otherwise, and the Python API without a pipeline.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...settings.design import design_settings
from .folding import fold_model, fold_trace, FoldResult, OrigamiModel, origami_model
from .layout import crease_layout, CreaseLayout

__all__ = ["OrigamiPlan", "origami_plan", "trace_needs"]

#: The motion methods a chain's fold (constructive placement) stands in for.
CONSTRUCTIVE = ("auto", "constructive")


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
    settings : DesignSettings, optional
        The design's settings, resolved once (:func:`fabkit.settings.design.design_settings`;
        a dict of overrides nested by section, ``{"origami": {"samples": 41}}``, is resolved
        here).
    motion : TracedMotion, optional
        The design's motion, traced once by the Motion stage: the fold is made of its trace
        when that is the trace the fold asks for (:func:`trace_needs`); else (a singular start,
        a trace made otherwise, or none given) the fold traces the motion itself.

    Returns
    -------
    OrigamiPlan

    Raises
    ------
    FabricationError
        No [fabrication.origami] table, bad settings, a folding the simulator cannot do, or a
        medium too small for a sheet of a chain with its labels and legend.
    """
    model = origami_model(design, design_settings(design, settings).require("origami"))
    traj = motion.trajectory if motion is not None and motion.traced else None
    fold = fold_model(model, design.motion.drive, design.motion.to, trajectory=traj)
    return OrigamiPlan(design, model, fold, crease_layout(model, fold))


def trace_needs(design, settings=None) -> dict:
    """What the Motion stage's trace must be for the origami plan to need no trace of its own:
    the fold's own tracing method and options (:func:`~fabkit.fab.creases.folding.fold_trace`).

    Parameters
    ----------
    design : Design
    settings : DesignSettings or dict, optional
        The design's settings (a dict of overrides is resolved here).

    Returns
    -------
    dict
        ``method`` (a :class:`~fabkit.kinematics.base.Method` subclass) and its options, or
        ``{}`` where the Motion stage traces as the template says and the fold traces for
        itself: a flat start whose motion does not leave it (``method`` other than
        ``"branch"``: the fold chooses the branch), a chain whose motion names a method other
        than a constructive one, held ports, options of the template's motion that the fold's
        method would not take as they are, or panels that need apex nodes.

    Raises
    ------
    FabricationError
        No [fabrication.origami] table, or bad settings (:func:`fabkit.fab.plans.trace_needs`
        then asks nothing: the planner refuses them with its reason).
    """
    m = design.motion
    if m.to is None or not m.drive or m.hold:
        return {}
    model = origami_model(design, design_settings(design, settings).require("origami"))
    if model.network is not design.network:
        return {}
    if m.method not in (("branch",) if model.flat_start else CONSTRUCTIVE):
        return {}
    method, options = fold_trace(model)
    if any(k not in options or options[k] != v for k, v in m.options.items()):
        return {}
    return {"method": method, **options}
