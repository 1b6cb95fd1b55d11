"""Lyapunov exponent of a design's module map and the predictability horizon of its chains."""

from __future__ import annotations


import numpy as np

from ..errors import ConstructionError, DesignError, KinematicsError
from ..kinematics import make_problem, place, plan_construction
from ..maps import module_map
from .placement import chain_ports
from ..model.network import is_chain_port

#: |λ| below this (per module) counts as a neutral map: no exponential growth or decay.
NEUTRAL_LYAPUNOV = 1e-6

#: Map slopes below this are taken as this (the resolution of a central difference), so that a
#: super-stable point gives λ ≈ -27.6 instead of -inf.
SLOPE_FLOOR = 1e-12

#: Fewest map iterations from which a Lyapunov exponent is reported as a horizon.
MIN_MAP_STEPS = 3


#: Step of the central differences that read a chain's slopes off the traced plan (relative to
#: the target): the map is smooth there, and 1e-6 balances truncation and round-off.
SLOPE_STEP = 1e-6


def lyapunov_estimate(design, plan=None, *, iterations: int = 400, orbits: int = 64,
                      transient: int = 50) -> dict | None:
    """Lyapunov exponent λ of the module map of a design, per module.

    Chains (ports d1, d2, d3, ...): λ is the mean of ``log |∂d_{k+1}/∂d_k|`` along the chain at
    the target, the gains measured by a central difference of the drive. A single module (ports
    d1 and d2): the map ``d2 = f(d1)`` is iterated from the target for up to ``iterations``
    steps while it stays in the module's range, λ = mean ``log |f'(d_k)|``.

    Parameters
    ----------
    design : Design
    plan : ConstructionPlan, optional
    iterations, orbits, transient : int

    Returns
    -------
    dict or None
        ``lyapunov`` (per module), ``source`` ("chain gains" / "iterated module map"),
        ``steps``; None when the design has no construction order or no d1/d2 ports.
    """
    net = design.network
    chain = [p for p in chain_ports(net) if is_chain_port(p)]
    if len(chain) < 2 or design.motion.drive != chain[0] or design.motion.to is None:
        return None
    problem = make_problem(net, design.motion.drive, design.motion.to, hold=design.motion.hold)
    if plan is None:
        try:
            plan = plan_construction(problem.work, problem.drive, problem.start)
        except ConstructionError:
            return None
    pairs = np.array([net.port(p) for p in chain])
    to = float(design.motion.to)
    if len(chain) >= 3:
        h = SLOPE_STEP * to
        X, margin, _ = place(plan, [to - h, to + h])
        if (margin < 0).any():
            return None
        d = np.linalg.norm(X[:, pairs[:, 0]] - X[:, pairs[:, 1]], axis=-1)  # (2, K)
        gains = (d[1] - d[0]) / (2 * h)
        slopes = np.abs(gains[1:] / np.where(gains[:-1] == 0, np.finfo(float).tiny, gains[:-1]))
        logs = np.log(np.maximum(slopes, SLOPE_FLOOR))
        return {"lyapunov": float(np.mean(logs)), "source": "chain gains",
                "steps": int(logs.size), "local": logs.tolist()}
    # a single module: the module's exact map (fabkit.maps), a bundle of orbits started next to
    # the target; orbits that leave the map's domain are dropped
    try:
        fmap = module_map(net, chain[0], chain[1])
        d0 = np.clip(to * (1.0 + 1e-3 * np.linspace(-1.0, 1.0, orbits)), *fmap.domain)
        res = fmap.lyapunov(initial=d0, discard=transient, average=max(iterations - transient, 1),
                            method="exact")
    except (ConstructionError, KinematicsError, DesignError):
        return None
    vals = res.values[~np.isnan(res.values)]
    if not vals.size:
        return None
    # a super-stable orbit has log|f'| -> -inf; slopes below the floor count as the floor
    vals = np.maximum(vals, np.log(SLOPE_FLOOR))
    return {"lyapunov": float(vals.mean()), "source": "iterated module map",
            "steps": int(res.discard + res.average), "orbits": int(vals.size),
            "transient": int(res.discard)}
