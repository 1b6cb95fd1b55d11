"""The laser process's plan: bars, stacking layers, parts and sheets, decided once.

From the design, its ``[fabrication.laser]`` settings resolved once and its traced motion (the
Motion stage's, or traced here for the Python API), the plan decides everything the laser
writers draw (:mod:`fabkit.writers.dxf`, :mod:`fabkit.writers.laser_svg`) and the guide lays out
(:mod:`fabkit.fab.guide`): no writer plans, and no writer traces.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import FabricationError
from ..motion import motion_for
from .bars import bar_set
from ..settings.design import design_settings
from .layers import plan_layers, sample_chain, sample_motion
from .layers.sampling import NODE_STEP_SHARE
from .nest import make_parts, nest_parts, place_like

__all__ = ["LaserPlan", "laser_plan", "uncompensated_plan", "trace_needs"]


@dataclass(eq=False)
class LaserPlan:
    """Everything decided before files are written."""

    design: object
    settings: object
    bars: object
    sweep: object
    stacking: object
    parts: list
    sheets: list
    #: ``""`` for the kit as cut; ``"uncompensated"`` for its copy drawn at true size
    variant: str = ""


def laser_plan(design, settings=None, motion=None) -> LaserPlan:
    """Decide bars, layers, parts and sheets for a design (no files).

    Parameters
    ----------
    design : Design
        A loaded template with a 2D network and a motion target.
    settings : DesignSettings, optional
        The design's settings, resolved once (:func:`fabkit.settings.design.design_settings`;
        a dict of overrides nested by section, ``{"laser": {"kerf": 0.2}}``, is resolved here).
    motion : TracedMotion, optional
        The design's motion, traced once by the pipeline (:func:`fabkit.motion.trace_motion`);
        traced here when not given. A kit's window (``motion_from`` / ``motion_to``) is asked of
        it, so the print of the same window shares its trace.

    Returns
    -------
    LaserPlan

    Raises
    ------
    FabricationError
        Bad settings, bars that cannot be cut, no collision-free stacking, parts larger than
        a sheet; one line each with a suggested fix.
    """
    net = design.network
    if net.dim != 2:
        raise FabricationError(f"laser-cut bars need a 2D network; {design.name} is {net.dim}D")
    s = design_settings(design, settings).require("laser")
    lengths = net.edge_lengths * s.scale  # the design's own, wherever the kit starts
    kit = motion_for(design, motion).window_motion(s.motion_from, s.motion_to, "laser")
    design, traj = kit.design, kit.planning_trajectory()
    net = design.network
    bars = bar_set(lengths, net.edges, s, scale=s.scale)
    # Module windows are sampled over the union of the ranges their modules sweep in the whole
    # motion: from a start part way along it (motion_from) one module sweeps most of the map
    # while the others hardly move, and the union would count every module's neighbours as
    # sweeping it all; such a kit is sampled along its own motion.
    sweep = None if s.motion_from is not None else sample_chain(
        net, design.motion, s.scale, s.sample_step, width=s.bar_width, clearance=s.clearance,
        column_radius=0.5 * s.screw.head_diameter, spacer_radius=0.5 * s.spacer_diameter,
        floor_limit=s.clearance, trajectory=traj)
    if sweep is None:  # not a chain of modules: sample the whole motion
        sweep = sample_motion(net, design.motion, s.scale, s.sample_step,
                              floor_limit=s.clearance, trajectory=traj)
    stacking = plan_layers(net.edges, sweep, s)
    parts = make_parts(bars, stacking, s)
    sheets = nest_parts(parts, s)
    return LaserPlan(design, s, bars, sweep, stacking, parts, sheets)


def uncompensated_plan(plan: LaserPlan) -> LaserPlan:
    """The same kit drawn at true size (kerf 0), every part where it was nested, for a
    cutting service that compensates kerf itself."""
    from dataclasses import replace

    s = replace(plan.settings, kerf=0.0)
    bars = bar_set(plan.bars.lengths, plan.bars.edges, s, scale=s.scale)
    sheets = place_like(make_parts(bars, plan.stacking, s), plan.sheets)
    return replace(plan, settings=s, bars=bars, sheets=sheets, variant="uncompensated")


def trace_needs(design, settings=None) -> dict:
    """What the Motion stage's trace must give for the laser plan to need no trace of its own.

    The stacking layers are planned over samples at which no node moves more than the laser's
    sample step (:attr:`~fabkit.fab.laser.LaserSettings.sample_step`). A constructive motion is
    placed at any drive value, so it is refined without tracing; a projected trace bounds each
    node's move by ``max_node_step``, so traced with that bound (a tenth inside the step: the
    bound holds to first order) once, it serves the design's motion and its kit alike. A kit
    with a window (``motion_from`` / ``motion_to``) is traced for its window.

    Parameters
    ----------
    design : Design
    settings : DesignSettings, optional
        The design's settings, resolved once (a dict of overrides is resolved here).

    Returns
    -------
    dict
        Options for the Motion stage's trace (``{"max_node_step": ...}``), or ``{}``.
    """
    m = design.motion
    if m.to is None or m.method != "projected" or design.network.dim != 2:
        return {}
    s = design_settings(design, settings).laser
    if s is None:
        return {}  # the plan refuses them, with their reason
    if s.motion_from is not None or s.motion_to is not None:
        return {}
    step = NODE_STEP_SHARE * s.sample_step / s.scale
    stated = m.options.get("max_node_step")
    return {"max_node_step": min(step, stated) if stated else step}
