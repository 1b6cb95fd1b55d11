"""One point of a sweep: the template with the point's values, its map, its measures."""

from __future__ import annotations

import copy
import importlib
import math

import numpy as np

from ..errors import ConstructionError, DesignError, FabkitError, KinematicsError
from ..templates import BUILDERS, TemplateContext
from ..kinematics import plan_construction
from ..maps import map_from_trajectory, module_map
from ..model.rigidity import count_modes
from ..status import Status
from .model import (ATTRACTOR_RTOL, FLAT_NUDGE, FLAT_START_RTOL, Protocol, SweepError,
                    SweepSpec, assign_value, key_path, lookup_number)

# --------------------------------------------------------------------------------------------
# One point
# --------------------------------------------------------------------------------------------
def _build(raw: dict, path: str):
    """Network of a (modified) parsed template, through the template's own builder."""
    ctx = TemplateContext(path, raw)
    key = next(k for k in BUILDERS if k in raw)
    module_name, func_name = BUILDERS[key].split(":")
    builder = getattr(importlib.import_module(module_name), func_name)
    return builder(raw[key], ctx)


def failed_record(index: int, params: dict) -> dict:
    """A point's record before (or without) its measures: failed, with no domain yet.

    Parameters
    ----------
    index : int
        The point's index in the grid.
    params : dict
        The point's parameter values, by ``--vary`` key.

    Returns
    -------
    dict
        A record that :class:`~fabkit.sweep.chunks.SweepRecord` accepts, status ``failed`` and
        an empty reason.
    """
    return {"index": int(index), "params": params, "status": Status.FAILED.value, "reason": "",
            "domain_lo": None, "domain_hi": None, "reference": None}


def evaluate_point(spec: SweepSpec, index: int) -> dict:
    """Evaluate one point of a sweep.

    Parameters
    ----------
    spec : SweepSpec
    index : int
        Flat index into the grid (C order).

    Returns
    -------
    dict
        JSON-ready record: ``index``, ``params``, ``status`` (a :class:`Status` value),
        ``reason``, the map's domain and reference d1, and the requested measures (scalars
        under the names in ``COLUMNS``, full lists under ``fixed_points``, ``cycles``,
        ``attractor_values``). Never raises for a point that cannot be evaluated: its status
        and reason say why.
    """
    params = spec.point(index)
    rec = failed_record(index, params)
    raw = copy.deepcopy(spec.raw)
    for key, value in params.items():
        tokens = key_path(key, raw)
        old = lookup_number(raw, tokens, key)
        assign_value(raw, tokens, int(round(value)) if isinstance(old, int) else float(value))
    try:
        _measure(spec, raw, rec)
    except FabkitError as exc:  # the geometry at this point cannot be evaluated as asked
        rec["status"] = Status.FAILED.value
        rec["reason"] = str(exc)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        # numerics that broke down at this geometry: one failed point, not a failed sweep
        rec["status"] = Status.FAILED.value
        rec["reason"] = f"{type(exc).__name__}: {exc}"
    return _finite(rec)


def _finite(o):
    """The record with every non-finite float as None (an infinite slope at a turning point is
    still told by its ``kind``), so it is strict JSON."""
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, (float, np.floating)):
        v = float(o)
        return v if math.isfinite(v) else None
    if isinstance(o, np.integer):
        return int(o)
    return o


def _measure(spec: SweepSpec, raw: dict, rec: dict) -> None:
    p = spec.protocol
    want = set(spec.measures)
    net = _build(raw, spec.template)
    modes = count_modes(net)
    if "modes" in want:
        rec["modes_conformational"] = int(modes.conformational)
        rec["modes_self_stress"] = int(modes.self_stress)
    if modes.conformational == 0:
        rec["status"] = Status.RIGID.value
        rec["reason"] = "no conformational motion (the geometry is rigid)"
        return
    for port in (p.d_in, p.d_out):
        if port not in net.ports:
            known = ", ".join(sorted(net.ports)) or "none"
            raise SweepError(f"no port {port!r} (the network has: {known})")
    a, b = net.ports[p.d_in]
    d0 = float(np.linalg.norm(net.nodes[a] - net.nodes[b]))
    motion = raw.get("motion") if isinstance(raw.get("motion"), dict) else {}
    toward = motion.get("to")
    status = Status.OK
    try:
        try:
            fmap = module_map(net, p.d_in, p.d_out, toward=toward)
        except DesignError:  # `to` lies beyond the branch: the start's own branch
            fmap = module_map(net, p.d_in, p.d_out)
    except ConstructionError as exc:
        if _flat_start(net, (a, b)):
            rec["status"] = Status.FLAT.value
            rec["reason"] = f"the start is a flat state: {exc}"
            return
        # no construction order from d1: read the map off a traced motion instead
        if toward is None:
            rec["status"] = Status.NO_MOTION.value
            rec["reason"] = f"{exc}; and the template gives no motion.to to trace instead"
            return
        from ..kinematics import trace

        try:
            traj = trace(net, drive=p.d_in, to=float(toward), method="projected")
            fmap = map_from_trajectory(traj, p.d_in, p.d_out)
        except KinematicsError as exc2:
            rec["status"] = Status.NO_MOTION.value
            rec["reason"] = str(exc2)
            return
    lo, hi = fmap.domain
    rec["domain_lo"], rec["domain_hi"], rec["reference"] = float(lo), float(hi), d0
    size = max(float(net.size), d0)
    if min(abs(d0 - lo), abs(d0 - hi)) <= FLAT_START_RTOL * size:
        status = Status.FLAT
        rec["reason"] = (f"the start d1 = {d0:.10g} is a turning point of d1 (a flat state); "
                         "measures are those of the branch toward motion.to")
    if want & {"fixed_points", "slopes"}:
        fps = fmap.fixed_points()
        near = min(fps, key=lambda q: abs(q.value - d0)) if fps else None
        rec["fixed_points"] = [q.as_dict() for q in fps]
        if "fixed_points" in want:
            rec["fixed_count"] = len(fps)
            rec["fixed_value"] = near.value if near else None
        if "slopes" in want:
            rec["fixed_slope"] = near.slope if near else None
            rec["slope_reference"] = (float(fmap.derivative(d0)) if lo <= d0 <= hi else None)
    if "cycles" in want:
        cyc = fmap.cycles(2)
        rec["cycles"] = [c.as_dict() for c in cyc]
        rec["cycle2_count"] = len(cyc)
        best = min(cyc, key=lambda c: abs(c.multiplier)) if cyc else None
        rec["cycle2_low"] = best.values[0] if best else None
        rec["cycle2_high"] = best.values[-1] if best else None
        rec["cycle2_multiplier"] = best.multiplier if best else None
    if "attractor" in want:
        values, period = _attractor(fmap, p)
        rec["attractor_values"] = values
        rec["attractor_period"] = period
        rec["attractor_min"] = min(values) if values else None
        rec["attractor_max"] = max(values) if values else None
        if not values:
            status = Status.ESCAPES if status is Status.OK else status
            rec["reason"] = rec["reason"] or (
                f"every orbit leaves the domain [{lo:.6g}, {hi:.6g}] within {p.discard} "
                "iterations: no long chain of this module can be assembled")
    if "lyapunov" in want:
        try:
            ly = fmap.lyapunov(initial=p.lyapunov_orbits, discard=p.lyapunov_discard,
                               average=p.lyapunov_average)
            rec["lyapunov"] = ly.mean if math.isfinite(ly.mean) else None
            rec["lyapunov_std"] = ly.std if math.isfinite(ly.std) else None
        except DesignError as exc:  # no invariant range: every orbit escapes
            rec["lyapunov"] = rec["lyapunov_std"] = None
            if status is Status.OK:
                status = Status.ESCAPES
                rec["reason"] = str(exc)
    rec["status"] = status.value


def _flat_start(net, pair) -> bool:
    """True when the start has no construction order only because it is flat: a slightly
    moved copy of it (1e-7 of the size, every node) has one."""
    x = net.nodes
    rng = np.random.default_rng(0)
    nudged = x + FLAT_NUDGE * max(float(net.size), 1.0) * rng.standard_normal(x.shape)
    try:
        plan_construction(net, pair, nudged)
    except ConstructionError:
        return False
    return True


def _attractor(fmap, p: Protocol) -> tuple[list, int]:
    """Values the orbits settle on, and the period of the first surviving orbit (0: no period
    up to ``keep // 2``, e.g. chaos; -1: every orbit escapes)."""
    lo, hi = fmap.domain
    x0 = lo + (np.arange(p.orbits) + 0.5) / p.orbits * (hi - lo)
    orbits = fmap.iterate(x0, p.discard + p.keep - 1)[p.discard:]
    alive = np.all(np.isfinite(orbits), axis=0)
    if not alive.any():
        return [], -1
    tail = orbits[:, alive]
    scale = max(abs(lo), abs(hi), 1.0)
    tol = ATTRACTOR_RTOL * scale
    first = tail[:, 0]
    period = 0
    for m in range(1, p.keep // 2 + 1):
        if np.all(np.abs(first[m:] - first[:-m]) <= tol):
            period = m
            break
    # one value per cluster: a periodic attractor keeps its few values, a chaotic one many
    vals = np.sort(tail.ravel())
    keep = np.concatenate([[True], np.diff(vals) > tol])
    return [float(v) for v in vals[keep]], period


