"""The Plan stage's planners: one plan per process, built once.

A plan is everything decided about a design's fabrication by one process, from the design, its
settings and its traced motion: the laser plan (:mod:`fabkit.fab.laser_plan`: bars, layers,
parts, sheets), the print plan (:mod:`fabkit.fab.print_plan`: bodies, pins, beds) and
the origami plan (:mod:`fabkit.fab.creases.plan`: the sheets and their
fold). The writers of a process (:mod:`fabkit.writers`) turn its plan into files and nothing
else; the batch engine builds each process's plan once for all of that process's formats.
"""

from __future__ import annotations

import importlib

from ..errors import FabkitError
from ..settings.design import design_settings

__all__ = ["PLANNERS", "TRACE_NEEDS", "make_plan", "trace_needs"]

#: Process → ``module:function`` of its planner, ``(design, settings, motion) -> plan``, with
#: the design's resolved :class:`~fabkit.settings.design.DesignSettings` (imported when the
#: process is used).
PLANNERS: dict[str, str] = {
    "laser": "fabkit.fab.laser_plan:laser_plan",
    "origami": "fabkit.fab.creases.plan:origami_plan",
    "print": "fabkit.fab.print_plan:print_plan",
}


#: Process → ``module:function`` of what its plan asks of the Motion stage's trace,
#: ``(design, settings) -> dict`` of trace options (``settings``: resolved) (a projected laser kit's node step), so that
#: the plan is made along that one trace instead of tracing again.
TRACE_NEEDS: dict[str, str] = {
    "laser": "fabkit.fab.laser_plan:trace_needs",
    "origami": "fabkit.fab.creases.plan:trace_needs",
}


def trace_needs(processes, design, settings=None) -> dict:
    """The trace options the plans of ``processes`` need of the design's one trace.

    Parameters
    ----------
    processes : iterable of str
        The processes whose plans will be made.
    design : Design
    settings : DesignSettings, optional
        The design's settings, resolved once (a dict of overrides is resolved here).

    Returns
    -------
    dict
        Options for :func:`fabkit.motion.trace_motion`; ``{}`` when no plan needs any, when
        two plans would need different ones (each then samples for itself), or when a plan's
        settings are bad (the planner refuses them with its reason).
    """
    settings = design_settings(design, settings)
    needs: list[dict] = []
    for process in sorted(set(processes) & set(TRACE_NEEDS)):
        module, name = TRACE_NEEDS[process].split(":")
        try:
            needs.append(getattr(importlib.import_module(module), name)(design, settings))
        except FabkitError:
            return {}
    wanted = [n for n in needs if n]
    return wanted[0] if len(wanted) == 1 else {}


def make_plan(process: str, design, settings=None, motion=None):
    """The plan of one process for a design.

    Parameters
    ----------
    process : str
        A key of :data:`PLANNERS`.
    design : Design
    settings : DesignSettings, optional
        The design's settings, resolved once (:func:`fabkit.settings.design.design_settings`);
        a dict of overrides nested by section (``{"laser": {"kerf": 0.2}}``) is resolved here.
    motion : TracedMotion, optional
        The design's motion, traced once by the Motion stage; a planner that needs it and is
        not given it traces it (the Python API without a pipeline).

    Returns
    -------
    object
        The process's plan (:class:`~fabkit.fab.laser_plan.LaserPlan`,
        :class:`~fabkit.fab.creases.plan.OrigamiPlan`).

    Raises
    ------
    FabkitError
        ``process`` has no planner.
    FabricationError
        The planner's refusal (bad settings or geometry), one line.
    """
    if process not in PLANNERS:
        raise FabkitError(f"no planner for process {process!r}; valid: {', '.join(PLANNERS)}")
    module, name = PLANNERS[process].split(":")
    return getattr(importlib.import_module(module), name)(
        design, design_settings(design, settings), motion)
