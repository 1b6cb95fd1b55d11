"""The design's motion traced again on a network rebuilt from files, and compared with the design's."""

from __future__ import annotations

import numpy as np

__all__ = ["compare_motion", "design_window"]


def design_window(design, start, to):
    """The design as a built kit moves: from drive value ``start`` to ``to`` (the template's
    ``motion_from`` / ``motion_to`` of the process), traced here by the simulator.

    The kit's reference configuration is the design's state at ``start`` along its own motion,
    with the bar lengths unchanged. Nothing of a writer's plan is used: a writer that planned
    its kit for another window is caught by the comparison that follows.

    Parameters
    ----------
    design : Design
    start, to : float or None
        None: the design's start and its ``motion.to``.

    Returns
    -------
    Design
        ``design`` itself when neither is given.

    Raises
    ------
    FabkitError
        The design has no motion, or its motion does not reach ``start``.
    """
    from dataclasses import replace

    from ..errors import FabkitError
    from ..network import Network

    if start is None and to is None:
        return design
    m = design.motion
    if m.to is None:
        raise FabkitError("motion_from / motion_to need a design with a motion (motion.to)")
    motion = m if to is None else replace(m, to=float(to))
    net = design.network
    if start is not None:
        traj = design.trace(to=float(start))
        if not traj.success:
            raise FabkitError(f"motion_from = {float(start):g}: the design's motion does not "
                              f"reach it ({traj.message})")
        net = Network(traj.positions[-1], net.edges, net.ports, net.labels, net.assembly)
    return replace(design, network=net, motion=motion)


def compare_motion(design, built, rtol: float) -> dict:
    """Trace ``built`` as the design's ``[motion]`` says and compare its ports with the design's.

    Parameters
    ----------
    design : Design
        With a motion target.
    built : Network
        The rebuilt network, numbered and with ports as the design's.
    rtol : float
        Largest port-distance difference accepted, relative to the network's size.

    Returns
    -------
    dict
        ``ok``, ``worst`` (largest difference of a port distance at the same step, design
        units), ``port`` (where), ``limit``, ``same_end`` (both traces end alike, with as many
        steps), ``status`` (the rebuilt network's).
    """
    from ..kinematics import trace

    net, m = design.network, design.motion
    ref = design.trace()
    got = trace(built, drive=m.drive, to=m.to, method=ref.method, hold=m.hold, **m.options)
    n = min(ref.n_steps, got.n_steps)
    worst, port = 0.0, None
    for p in net.ports:
        if p == m.drive:
            continue
        diff = float(np.abs(ref.distance(p)[:n] - got.distance(p)[:n]).max())
        if diff >= worst:
            worst, port = diff, p
    limit = rtol * net.size
    same_end = ref.n_steps == got.n_steps and str(ref.status) == str(got.status)
    return {"ok": worst <= limit and same_end, "worst": worst, "port": port, "limit": limit,
            "same_end": same_end, "status": str(got.status)}
