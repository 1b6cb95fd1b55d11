"""The Monte Carlo of built copies of a design and its verdict."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np

from ..errors import FabkitError, KinematicsError, TemplateError
from ..numerics import EDGE_RTOL, project_to_lengths
from .horizon import MIN_MAP_STEPS, NEUTRAL_LYAPUNOV, lyapunov_estimate
from .placement import (BUILD_RTOL, PROJECTED_SAMPLES_CAP, _chain_ports, _find_plan,
                        _plan_edge_index, _process_geometry, _Runs, _simulate, _to_drive_frame)
from .processes import SOURCES, sample_lengths
from .result import ToleranceResult
from .spec import ToleranceSpec, tolerance_spec


def analyse_tolerance(design, spec: ToleranceSpec | None = None, *, trajectory=None,
                      grid: int = 41, attribute: bool = True) -> ToleranceResult:
    """Monte Carlo of built copies of a design driven to its target (see the module docstring).

    Parameters
    ----------
    design : Design
        With ``motion.to`` set.
    spec : ToleranceSpec, optional
        Default: :func:`tolerance_spec` of the design.
    trajectory : Trajectory, optional
        The nominal motion (traced when not given).
    grid : int
        Drive values checked between the start and the target for every build.
    attribute : bool
        When the design is flagged, also simulate each error source alone (``extra
        ["sources"]``) and name in the verdict the one that stops the design.

    Returns
    -------
    ToleranceResult

    Raises
    ------
    TemplateError
        No target (``motion.to``) or a nominal motion that does not reach it.

    Examples
    --------
    >>> from fabkit.templates import load_template
    >>> from pathlib import Path
    >>> d = load_template(Path(__file__).parents[2] / "templates" / "fourbar.toml")
    >>> res = analyse_tolerance(d, tolerance_spec(d, samples=50))
    >>> res.reached_fraction, res.flagged
    (1.0, False)
    """
    from ..kinematics import make_problem, place

    path = design.path or design.name
    spec = spec or tolerance_spec(design)
    net = design.network
    m = design.motion
    if m.to is None:
        raise TemplateError(path, "motion.to", "the tolerance analysis needs a target value")
    if trajectory is None:
        trajectory = design.trace()
    if not trajectory.success:
        raise TemplateError(path, "motion.to", f"the designed motion does not reach the target: "
                                               f"{trajectory.message}")
    problem = make_problem(net, m.drive, m.to, hold=m.hold)
    ports = _chain_ports(net)
    pairs = np.array([net.port(p) for p in ports])
    a, b = problem.drive
    n_chain = len([p for p in ports if re.fullmatch(r"d\d+", p)])
    end_nodes = sorted(set(pairs[max(n_chain, 1) - 1].tolist()))
    plan = _find_plan(problem, trajectory)
    names = list(SOURCES[spec.process])

    def draw(sources=None):
        return sample_lengths(geo, spec, np.random.default_rng(spec.seed), sources)

    if plan is not None:
        method = "constructive"
        nominal_x = place(plan, [m.to])[0][0]
        geo = _process_geometry(design, spec, problem, nominal_x)
        nominal = np.linalg.norm(nominal_x[pairs[:, 0]] - nominal_x[pairs[:, 1]], axis=-1)
        size_mm = float(np.mean(nominal)) * spec.scale
        limit_mm = spec.limit if spec.limit is not None else spec.limit_fraction * size_mm
        eidx = _plan_edge_index(plan, problem.work)
        values = np.linspace(problem.start_drive, m.to, grid)
        clearance = (2 * spec.hole_clearance if spec.process == "laser" else limit_mm) / spec.scale

        def run(built):
            return _simulate(plan, eidx, problem, net, built, values, pairs,
                             limit_mm / spec.scale, clearance)

        built = draw()
        r = run(built)
        dist, reached, unclosed, locked = r.dist, r.reached, r.unclosed, r.locked
        ref_dir = (plan.reference[b] - plan.reference[a])[:2]
        framed = _to_drive_frame(r.final, a, b, ref_dir)
        nominal_framed = _to_drive_frame(nominal_x[None], a, b, ref_dir)[0]
        end_offsets = framed[:, end_nodes] - nominal_framed[None, end_nodes]
        stops = r.stop
    else:
        from ..kinematics import trace

        method = "projected"
        locked, unclosed = 0, 0
        spec = replace(spec, samples=min(spec.samples, PROJECTED_SAMPLES_CAP))
        nominal_x = trajectory.final
        geo = _process_geometry(design, spec, problem, nominal_x)
        nominal = np.linalg.norm(nominal_x[pairs[:, 0]] - nominal_x[pairs[:, 1]], axis=-1)
        size_mm = float(np.mean(nominal)) * spec.scale
        limit_mm = spec.limit if spec.limit is not None else spec.limit_fraction * size_mm

        def run(built):
            dist = np.full((built.shape[0], len(ports)), np.nan)
            reached = np.zeros(built.shape[0], dtype=bool)
            for s in range(built.shape[0]):
                proj = project_to_lengths(net.edges, built[s], net.nodes, rtol=BUILD_RTOL,
                                          max_iter=30)
                if not proj.converged:
                    continue
                x = proj.positions
                try:
                    tr = trace(net.with_nodes(x), drive=m.drive, to=m.to, method="projected",
                               hold=m.hold)
                except (KinematicsError, FabkitError):
                    continue
                if tr.success:
                    reached[s] = True
                    dist[s] = np.linalg.norm(tr.final[pairs[:, 0]] - tr.final[pairs[:, 1]],
                                             axis=-1)
            return _Runs(dist, reached, None, None, int((~reached).sum()), 0)

        built = draw()
        r = run(built)
        dist, reached, locked = r.dist, r.reached, r.locked
        end_offsets = stops = None

    length_rms = float(np.sqrt(np.mean((built - net.edge_lengths[None, :]) ** 2)) * spec.scale)
    limits = np.full(len(ports), limit_mm)

    def score(dist_, reached_):
        err = np.abs(dist_[reached_] - nominal[None, :]) * spec.scale
        p95 = np.percentile(err, 95, axis=0) if err.shape[0] else np.full(len(ports), np.inf)
        return float(reached_.mean()), p95

    frac, p95 = score(dist, reached)
    budget = {}
    worst = int(np.argmax(p95 / limits))
    if attribute and (frac < spec.min_reached or p95[worst] > limits[worst]):
        for name in names:
            rs = run(draw([name]))
            f_s, p_s = score(rs.dist, rs.reached)
            budget[name] = {"reached_fraction": f_s,
                            "p95_error_mm": float(np.max(p_s)) if np.isfinite(p_s).all()
                            else None}

    # predictability horizon of chains: error e^{λk} reaches the module size
    horizon = None
    lyap = lyapunov_estimate(design, plan) if plan is not None else None
    if lyap is not None:
        lam = lyap["lyapunov"]
        eps = max(length_rms, EDGE_RTOL)
        modules = None
        if lyap["steps"] < MIN_MAP_STEPS:
            detail = (f"the module map leaves the module's range after {lyap['steps']} step(s) "
                      "from the target: too short an orbit to estimate a horizon")
        elif abs(lam) < NEUTRAL_LYAPUNOV:
            detail = "neutral map (λ ≈ 0): errors neither grow nor shrink exponentially"
        elif lam < 0:
            detail = "errors shrink along the chain (λ < 0): no horizon"
        elif size_mm <= eps:
            detail = "the error is already as large as a module"
        else:
            modules = math.log(size_mm / eps) / lam
            detail = (f"a {eps:.3g} mm bar error grows to the {size_mm:.3g} mm module size after "
                      f"about {modules:.1f} modules")
        horizon = {**lyap, "error_mm": eps, "module_size_mm": size_mm, "modules": modules,
                   "detail": detail}
        ok = dist[reached]
        chain = [k for k, p in enumerate(ports) if re.fullmatch(r"d\d+", p)]
        if len(chain) >= 3 and ok.shape[0] >= 5:
            spread = ok[:, chain].std(axis=0)
            kk = np.arange(len(chain))
            good = spread > 0
            if good.sum() >= 3:
                horizon["monte_carlo_slope"] = float(np.polyfit(kk[good], np.log(spread[good]),
                                                                1)[0])
                horizon["monte_carlo_std"] = spread.tolist()

    extra = {"drive": m.drive, "target": float(m.to), "unclosed": unclosed, "locked": locked,
             "module_size_mm": size_mm, "sources": budget}
    if stops is not None:
        short = np.abs(stops - m.to) * spec.scale
        extra["lock_short_p95_mm"] = float(np.percentile(short, 95))
    unit = f"{spec.process} builds"
    if frac < spec.min_reached:
        flagged = True
        why = []
        if locked and method == "projected":
            why.append(f"{locked} stop before it (turning point or no assembly; traced one by "
                       "one)")
        elif locked:
            why.append(f"{locked} lock at a turning point more than {limit_mm:.3g} mm short of "
                       "it")
        if unclosed:
            why.append(f"{unclosed} cannot close their redundant bars (states of self-stress) "
                       "within the joint play")
        verdict = (f"FLAG: only {100 * frac:.1f}% of {unit} reach {m.drive} = {m.to:.6g} "
                   f"(need {100 * spec.min_reached:.0f}%): " + "; ".join(why)
                   + _cause(budget, "reached", spec))
    elif p95[worst] > limits[worst]:
        flagged = True
        verdict = (f"FLAG: {ports[worst]} is off by up to {p95[worst]:.3g} mm (95% of {unit}), "
                   f"more than the {limits[worst]:.3g} mm allowed"
                   + _cause(budget, "error", spec, limits[worst]))
    else:
        flagged = False
        verdict = (f"ok: {100 * frac:.1f}% of {unit} reach the target; every port within "
                   f"{limits[worst]:.3g} mm (worst {ports[worst]}: {p95[worst]:.3g} mm, 95% of "
                   "builds)")
    return ToleranceResult(spec=spec, method=method, ports=ports, nominal=nominal, distances=dist,
                           reached=reached, end_nodes=end_nodes, end_offsets=end_offsets,
                           length_rms=length_rms, limits=limits, horizon=horizon,
                           flagged=flagged, verdict=verdict, extra=extra)


def _cause(budget: dict, kind: str, spec: ToleranceSpec, limit: float | None = None) -> str:
    """``"; cause: <source> ..."``: the error sources that alone stop the design, else the one
    that hurts most alone."""
    if not budget:
        return ""
    if kind == "reached":
        alone = [n for n, v in budget.items() if v["reached_fraction"] < spec.min_reached]
        if alone:
            return "; stopped by " + ", ".join(
                f"{n} (alone {100 * budget[n]['reached_fraction']:.0f}% reach)" for n in alone)
        n = min(budget, key=lambda k: budget[k]["reached_fraction"])
        return (f"; no single source stops it, their sum does (worst alone: {n}, "
                f"{100 * budget[n]['reached_fraction']:.0f}% reach)")

    def err(k):
        e = budget[k]["p95_error_mm"]
        return math.inf if e is None else e

    alone = [n for n in budget if err(n) > limit]
    if alone:
        return "; stopped by " + ", ".join(f"{n} (alone {err(n):.3g} mm)" for n in alone)
    n = max(budget, key=err)
    return f"; no single source exceeds it, their sum does (largest alone: {n}, {err(n):.3g} mm)"
