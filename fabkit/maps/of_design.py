"""A design's map, as ``fabkit map`` computes it, and where its cobweb starts."""

from __future__ import annotations

from ..errors import ConstructionError, DesignError, FabkitError, MotionError
from ..kinematics import Status
from .from_trajectory import map_from_trajectory
from .map1d import Map1D
from .walk import module_map

__all__ = ["map_of", "cobweb_starts"]


def map_of(design, d_in: str = "d1", d_out: str = "d2") -> Map1D:
    """The map of a design (``fabkit map``'s): constructive where possible, else read off a
    projected trace of the design's motion.

    Parameters
    ----------
    design : Design
    d_in, d_out : str
        The module's input and output ports.

    Returns
    -------
    Map1D

    Raises
    ------
    FabkitError
        A port the network does not have; no construction and no motion to trace.
    MotionError
        The trace failed.
    """
    net = design.network
    for port in (d_in, d_out):
        if port not in net.ports:
            known = ", ".join(sorted(net.ports)) or "none"
            raise FabkitError(f"{design.path}: no port {port!r} (the network has: {known})")
    try:
        try:
            # `toward` only matters when the start is a turning point of d1 (on two branches)
            return module_map(net, d_in, d_out, toward=design.motion.to, name=design.name)
        except DesignError:  # the target lies beyond the branch: still map the start's branch
            return module_map(net, d_in, d_out, name=design.name)
    except ConstructionError as exc:
        if design.motion.to is None:
            raise FabkitError(f"{design.path}: {exc}; and the template gives no motion.to to "
                              "trace instead") from None
        traj = design.trace(method="projected")
        if traj.status is Status.FAILED:  # a failed trace is no map, not even of a stretch
            raise MotionError(design.path, "motion", f"the trace failed: {traj.message}",
                              status=str(traj.status)) from None
        return map_from_trajectory(traj, d_in, d_out, name=design.name)


def cobweb_starts(fmap: Map1D, fixed=None) -> list[float]:
    """The initial d1 of ``fabkit map``'s cobweb: the fixed points (up to three) with a value
    between the first two, or one beside a single fixed point, or the middle of the domain.

    Parameters
    ----------
    fmap : Map1D
    fixed : sequence of FixedPoint, optional
        Default: ``fmap.fixed_points()``.

    Returns
    -------
    list of float
    """
    fixed = fmap.fixed_points() if fixed is None else fixed
    lo, hi = fmap.domain
    vals = [p.value for p in fixed if lo <= p.value <= hi][:3]
    if len(vals) >= 2:
        vals.insert(1, 0.5 * (vals[0] + vals[1]))
    elif vals:
        v = vals[0]
        vals.append(v + (0.02 if v + 0.02 * (hi - lo) < hi else -0.02) * (hi - lo))
    else:
        vals = [0.5 * (lo + hi)]
    return vals
