"""The design's motion traced again on a network rebuilt from files, and compared with the design's."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..kinematics import select_method, trace
from ..motion import motion_for
from ..status import Status

__all__ = ["as_traced", "compare_motion", "design_window", "same_trace"]


def design_window(design, start, to, motion=None, process: str = "laser"):
    """The design as a built kit moves, from drive value ``start`` to ``to`` (the template's
    ``motion_from`` / ``motion_to`` of the process), and its traced motion.

    Both come from the Motion stage (:class:`fabkit.motion.TracedMotion`): the design's motion
    and each window traced once by the simulator, never from a writer's plan, so a writer that
    planned its kit for another window is caught by the comparison that follows.

    Parameters
    ----------
    design : Design
    start, to : float or None
        None: the design's start and its ``motion.to``.
    motion : TracedMotion, optional
        The design's motion, traced once by the pipeline; traced here when not given (a check
        called on its own).
    process : str
        ``"laser"`` or ``"print"``, for the messages.

    Returns
    -------
    design : Design
        ``design`` itself when neither is given; its ``[motion]`` options carry the options
        the Motion stage traced with (:attr:`fabkit.motion.TracedMotion.options`), so the
        rebuilt network is traced as the design was.
    trajectory : Trajectory or None
        Its motion, as traced (None: the template gives no target).

    Raises
    ------
    FabkitError
        The design has no motion, its motion does not reach ``start``, or it cannot be traced.
    """
    kit = motion_for(design, motion).window_motion(start, to, process)
    if kit.trajectory is None and kit.status is not Status.NO_TARGET:
        kit.require()  # the motion's typed failure
    design = kit.design
    if kit.options:
        m = design.motion
        design = replace(design, motion=replace(m, options={**m.options, **kit.options}))
    return design, kit.trajectory


def compare_motion(design, built, rtol: float, reference) -> dict:
    """Trace ``built`` as the design's ``[motion]`` says and compare its ports with the design's.

    Parameters
    ----------
    design : Design
        With a motion target.
    built : Network
        The rebuilt network, numbered and with ports as the design's.
    rtol : float
        Largest port-distance difference accepted, relative to the network's size.
    reference : Trajectory
        The design's motion as the Motion stage traced it (:func:`design_window`).

    Returns
    -------
    dict
        ``ok``, ``worst`` (largest difference of a port distance at the same step, design
        units), ``port`` (where), ``limit``, ``same_end`` (both traces end alike, with as many
        steps), ``status`` (the rebuilt network's), ``trajectory`` (the rebuilt network's
        motion, for the clearance sampling to start from:
        :func:`fabkit.check.clearance.fine_motion`'s ``traced``).
    """
    net, m = design.network, design.motion
    ref = reference
    # the design's own network traced as the design was: that trace, not a repeat of it
    same = same_trace(built, m, ref) and ref.request is not None
    got = ref if same else \
        trace(built, drive=m.drive, to=m.to, method=ref.method, hold=m.hold, **m.options)
    n = min(ref.n_steps, got.n_steps)
    worst, port = 0.0, None
    for p in net.ports:
        if p == m.drive:
            continue
        diff = float(np.abs(ref.distance(p)[:n] - got.distance(p)[:n]).max())
        if diff >= worst:
            worst, port = diff, p
    limit = rtol * net.size
    same_end = ref.n_steps == got.n_steps and ref.status is got.status
    return {"ok": worst <= limit and same_end, "worst": worst, "port": port, "limit": limit,
            "same_end": same_end, "status": str(got.status), "trajectory": got}


def same_trace(net, motion, traced) -> bool:
    """``traced`` is what tracing ``net`` as ``motion`` says gives: the same method (asked for,
    or the one ``"auto"`` chooses) on the same network, drive, target, held ports and
    options, whose trace is deterministic. The drive, target, held ports and options are
    compared where the trajectory records them (:attr:`fabkit.Trajectory.request`).

    Parameters
    ----------
    net : Network
    motion : Motion
        The design's ``[motion]``, with the options the trace was made with.
    traced : Trajectory or None

    Returns
    -------
    bool
    """
    if traced is None or traced.network is not net:
        return False
    asked = traced.request
    if asked is not None and (asked["drive"], asked["to"], _held(asked["hold"]),
                              asked["options"]) != (motion.drive, motion.to, _held(motion.hold),
                                                    dict(motion.options)):
        return False  # traced to another target, or with other options (another step)
    if motion.method == "auto":
        # under auto, held ports (virtual edges) may change the method chosen: traced again
        return not motion.hold and traced.method == select_method(net, motion.drive)
    return traced.method == motion.method


def as_traced(built, reference):
    """The network ``reference`` traced when ``built`` is it to the bit, else ``built``.

    A kit whose files give back the design's own joints (kept when the lengths read back
    agree to the file's resolution) and its bars in the same order, with the same ports and
    labels, is the network the Motion stage traced: tracing it again repeats that trace step
    for step (a trace is deterministic), so the checks take the trace made (the AND gate's
    kit check traced its 2196 steps again).

    Parameters
    ----------
    built : Network
        Rebuilt from the files.
    reference : Trajectory or None
        The design's motion as the Motion stage traced it.

    Returns
    -------
    Network
    """
    net = getattr(reference, "network", None)
    if net is None or net is built:
        return built
    same = (built.nodes.dtype == net.nodes.dtype and built.nodes.shape == net.nodes.shape
            and built.nodes.tobytes() == net.nodes.tobytes()
            and built.edges.shape == net.edges.shape and np.array_equal(built.edges, net.edges)
            and dict(built.ports) == dict(net.ports) and built.labels == net.labels)
    return net if same else built


def _held(hold) -> tuple:
    return (hold,) if isinstance(hold, str) else tuple(hold or ())
