"""The part of a design's motion a built kit follows (``motion_from`` / ``motion_to``)."""

from __future__ import annotations

from ..errors import FabricationError
from ..model.network import Network

__all__ = ["motion_window"]


def motion_window(design, start, to, process: str):
    """The design as a kit of ``process`` moves: from drive value ``start`` to ``to``.

    The kit's reference configuration is the design's state at ``start`` (traced along the
    design's own motion), with the bar lengths unchanged, and its target ``to``. A kit may stop
    short of a state that no built kit can follow (an unstable fixed point that magnifies every
    length error) or start where its bars lie apart (a flat start whose bars lie on one another
    admits no stacking).

    Parameters
    ----------
    design : Design
    start, to : float or None
        ``[fabrication.<process>] motion_from`` and ``motion_to``; None: the design's start and
        its ``motion.to``.
    process : str
        ``"laser"`` or ``"print"``, for the messages.

    Returns
    -------
    Design
        ``design`` itself when neither is given.

    Raises
    ------
    FabricationError
        The design has no motion, or ``start`` is not reached along it, or the two do not
        leave a motion between them.
    """
    from dataclasses import replace

    if start is None and to is None:
        return design
    m = design.motion
    if m.to is None:
        raise FabricationError(f"{process} motion_from / motion_to need a design with a motion "
                               "(motion.to)")
    net, motion = design.network, m
    if to is not None:
        motion = replace(motion, to=float(to))
    d0 = float(net.port_distance(m.drive))
    if start is not None:
        start = float(start)
        if not (start - d0) * (float(motion.to) - start) > 0:
            raise FabricationError(
                f"{process} motion_from = {start:g} must lie between the start {m.drive} = "
                f"{d0:.6g} and the kit's target {float(motion.to):.6g}")
        traj = design.trace(to=start)
        if not traj.success:
            raise FabricationError(
                f"{process} motion_from = {start:g}: the design's motion does not reach it from "
                f"{m.drive} = {d0:.6g} ({traj.message}); give a value between the start and "
                "motion.to")
        # the reference configuration moved along the motion; the bars keep their lengths
        net = Network(traj.positions[-1], net.edges, net.ports, net.labels, net.assembly)
    elif float(motion.to) == d0:
        raise FabricationError(f"{process} motion_to = {motion.to:g} is where the design "
                               "starts: the kit would not move")
    return replace(design, network=net, motion=motion)
