"""The pictures the command line writes, as matplotlib Figures: ``fabkit.plot.cobweb(design)``.

Each function returns a :class:`matplotlib.figure.Figure` of its own (never pyplot's, and the
session's backend is left as it is): show it in a notebook as it is, or save it with
``fig.savefig("cobweb.png")``. They draw with the same code as the files of ``fabkit map``
(``cobweb.png``), ``fabkit simulate`` (``motion.png``), ``fabkit tolerance`` (``tolerance.png``)
and ``fabkit export`` (``laser_assembly.png``, ``NAME_print.png``).
"""

from __future__ import annotations

from ..errors import ArgumentTypeError
from ..fab.guide import guide_plan
from ..fab.guide.pictures import assembly_figure
from ..fab.laser_plan import LaserPlan
from ..fab.print_plan import PrintPlan
from ..kinematics import Trajectory
from ..maps import Map1D
from ..maps.of_design import cobweb_starts, map_of
from ..plots.mapplots import cobweb_figure
from ..plots.viz import motion_figure
from ..tolerance import ToleranceResult, tolerance_figure
from ..writers.dxf import bill_of_materials
from ..writers.pinned import preview_figure as pinned_figure
from ..writers.stl import preview_figure

__all__ = ["cobweb", "motion", "tolerance", "kit"]


def cobweb(source, d1=None, steps: int = 16, *, d_in: str = "d1", d_out: str = "d2",
           title: str | None = None):
    """Cobweb diagram of a module's map: orbits d_{k+1} = f(d_k), a chain's states module by
    module (``fabkit map``'s ``cobweb.png``).

    Parameters
    ----------
    source : Design or Map1D
        A module (a template, the result of :func:`fabkit.design_map`), or its map.
    d1 : float or sequence of float, optional
        Initial values (default: the fixed points and a value between them, as ``fabkit map``).
    steps : int
        Iterations (modules of the chain).
    d_in, d_out : str
        The module's input and output ports (for a design).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import fabkit
    >>> fig = fabkit.plot.cobweb(fabkit.load_template("chaotic"), steps=8)
    >>> type(fig).__name__, len(fig.axes)
    ('Figure', 1)
    """

    name = getattr(source, "name", "")
    if isinstance(source, Map1D):
        fmap = source
    elif isinstance(getattr(source, "map", None), Map1D) and (d_in, d_out) == ("d1", "d2"):
        fmap = source.map  # a designed module carries its map
    elif hasattr(source, "network") and hasattr(source, "motion"):
        fmap = map_of(source, d_in, d_out)
    else:
        raise ArgumentTypeError("source", f"must be a fabkit Design or a Map1D, got "
                                          f"{type(source).__name__}")
    values = cobweb_starts(fmap) if d1 is None else d1
    return cobweb_figure(fmap, values, steps, title=title or f"{name or fmap.name}: cobweb")


def motion(trajectory, *, frames: int = 3, title: str | None = None):
    """A traced motion: the network at a few moments and its port distances along the drive
    (``fabkit simulate``'s ``motion.png``).

    Parameters
    ----------
    trajectory : Trajectory
        From :func:`fabkit.trace` or :meth:`fabkit.Design.trace`.
    frames : int
        Configurations drawn.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """

    if not isinstance(trajectory, Trajectory):
        raise ArgumentTypeError("trajectory", f"must be a fabkit Trajectory (fabkit.trace), got "
                                              f"{type(trajectory).__name__}")
    return motion_figure(trajectory, frames=frames, title=title)


def tolerance(result, *, title: str | None = None):
    """What built copies keep: the keep chart, each criterion per build, the margin
    (``fabkit tolerance``'s ``tolerance.png``).

    Parameters
    ----------
    result : ToleranceResult
        From :func:`fabkit.tolerance.analyse_tolerance`.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """

    if not isinstance(result, ToleranceResult):
        raise ArgumentTypeError("result", f"must be a ToleranceResult "
                                          f"(fabkit.tolerance.analyse_tolerance), got "
                                          f"{type(result).__name__}")
    return tolerance_figure(result, title=title)


def kit(plan, *, title: str | None = None):
    """A fabrication plan's kit: a laser kit's bars by layer as its guide pages them
    (``laser_assembly.png``), or a print's beds or hinged solid seen from above
    (``NAME_print.png``).

    Parameters
    ----------
    plan : LaserPlan or PrintPlan
        From :func:`fabkit.fab.plans.make_plan` (``make_plan("laser", design)``).
    title : str, optional
        For a print (a laser kit's heading says its layers and scale).

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ArgumentTypeError
        Any other object (an origami plan's pictures are its crease-pattern SVG files).
    """

    if isinstance(plan, LaserPlan):

        return assembly_figure(plan, guide_plan(plan, bill_of_materials(plan, {})))[0]
    if isinstance(plan, PrintPlan):
        name = title or plan.design.name
        if plan.pinned is not None:

            return pinned_figure(plan.pinned, name)

        return preview_figure(plan.geo, name)
    raise ArgumentTypeError("plan", f"must be a laser or print plan "
                                    f"(fabkit.fab.plans.make_plan), got {type(plan).__name__}")
