"""The design's motion traced again on a network rebuilt from files, and compared with the design's."""

from __future__ import annotations

import numpy as np

__all__ = ["compare_motion"]


def compare_motion(design, built, rtol: float, reference=None) -> dict:
    """Trace ``built`` as the design's ``[motion]`` says and compare its ports with the design's.

    Parameters
    ----------
    design : Design
        With a motion target.
    built : Network
        The rebuilt network, numbered and with ports as the design's.
    rtol : float
        Largest port-distance difference accepted, relative to the network's size.
    reference : Trajectory, optional
        The design's motion, traced once by the pipeline (:class:`fabkit.motion.TracedMotion`);
        traced here when not given.

    Returns
    -------
    dict
        ``ok``, ``worst`` (largest difference of a port distance at the same step, design
        units), ``port`` (where), ``limit``, ``same_end`` (both traces end alike, with as many
        steps), ``status`` (the rebuilt network's).
    """
    from ..kinematics import trace

    net, m = design.network, design.motion
    ref = reference if reference is not None else design.trace()
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
