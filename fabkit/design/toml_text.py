"""Template text written by the designer: plain TOML with comments that say what was wished,
how it was built and what the map recomputed from it gives."""

from __future__ import annotations

import math

import numpy as np

from ..io.toml_writer import TomlDocument
from ..numerics import printed, printed_residual
from .branch import MIN_BRANCH_MARGIN, on_branch
from .curvature import INITIAL_APEX_DEG, LEG_RATIO

__all__ = ["module_template", "curvature_template", "chain_template", "fit_lines",
           "margin_lines", "builds_line"]


def _points(points) -> list[list[float]]:
    """Points as lists of floats (written one a line, to round-trip exactly)."""
    return np.asarray(points, dtype=float).tolist()


def _kind(slope: float) -> str:
    from ..maps import classify_slope

    return classify_slope(slope)


def margin_lines(margins, branch: dict) -> list[str]:
    """The distance of every wished state to the nearest fold of its branch, and every fixed
    point and 2-cycle of the branch with its own distance: lines of text (the command prints
    them, the template's comment holds them).

    Parameters
    ----------
    margins : list of dict
        :func:`fabkit.design.branch.branch_margins` of the wished states.
    branch : dict
        :func:`fabkit.design.branch.on_branch` of the map.
    """
    lo, hi = branch["domain"]
    out = [f"branch: d1 from {lo:.6g} to {hi:.6g} (folds at both ends); every wished state is "
           f"kept at least {100 * MIN_BRANCH_MARGIN:g} % of itself from a fold"]
    for m in margins:
        out.append(f"branch margin of {m['value']:.10g}: {m['margin']:.4g} "
                   f"({100 * m['fraction']:.3g} % of the state) to the fold at {m['fold']:.6g}")
    fps = branch["fixed_points"]
    out.append("fixed points on the branch: " + ("none" if not fps else ", ".join(
        f"{p['value']:.7g} (slope {printed(p['slope'], '.4g')}, {p['kind']}; {100 * p['branch_margin_fraction']:.3g} % "
        "from a fold)" for p in fps)))
    cycles = branch["cycles"]
    out.append("2-cycles on the branch: " + ("none" if not cycles else ", ".join(
        f"{c['values'][0]:.7g} <-> {c['values'][1]:.7g} (multiplier {c['multiplier']:.4g}, "
        f"{c['kind']}; {100 * c['branch_margin_fraction']:.3g} % from a fold)" for c in cycles)))
    return out


def builds_line(builds) -> str:
    """What laser-cut builds keep (a :class:`~fabkit.design.robustness.BuildCheck`)."""
    d = builds.as_dict() if hasattr(builds, "as_dict") else builds
    lost = [f"{k} lost in {100 * v:.3g} %" for k, v in d["lost"].items() if v > 0]
    return (f"laser builds keeping every wish: {100 * d['kept']:.3g} % of {d['builds']} "
            f"simulated at {d['scale_mm_per_unit']:g} mm per unit (need "
            f"{100 * d['needed']:g} %; a state within {100 * d['state_rtol']:g} %, same "
            "stability)" + (f"; {', '.join(lost)}" if lost else ""))


def module_template(name: str, wish, cand, builds=None) -> str:
    """Text of the ``[design]`` template of a module designed from map wishes.

    Parameters
    ----------
    name : str
    wish : MapWish
    cand
        The chosen candidate (its specification, variable nodes and measures).
    builds : BuildCheck, optional
        What laser-cut builds keep, for the comment.

    Returns
    -------
    str
    """
    spec, m = cand.spec, cand.metrics
    met = m["met"]
    ch = spec.choices
    doc = TomlDocument()
    doc.comment(f"Designed by `fabkit design {wish.options()}` from its map wishes.\n"
                "Construction (paper, supplement \"Elaborating on Single Module Design\"): the "
                "designed nodes 0, 1, 2\n"
                "sit at the first wished state (d1 = |x0 - x1|, d2 = |x1 - x2|); their velocities "
                "fix the slope there,\n"
                "their final positions a further point of the map; variable nodes 3 and 4 lie on "
                "the solution spaces\n"
                "of these specifications, each joined to all three designed nodes.")
    free = [f"apex angle {ch['apex_deg']:.0f} deg at the first state"]
    if "apex_final_deg" in ch:
        free.append(f"{ch['apex_final_deg']:.0f} deg at the final state")
    if "apex_fixed_deg" in ch:
        free.append(f"{ch['apex_fixed_deg']:.0f} deg at the fixed point")
    if spec.velocities is not None:
        free.append(f"leg turn {ch['turn']:g}")
        if all(p.slope is None for p in wish.fixed_points[:1]):
            free.append(f"slope {ch['slope_designed']:g} (none was wished)")
    doc.comment("Free choices, made for buildability: " + ", ".join(free) + ";")
    doc.comment(f"variable nodes: points {cand.points[0]} and {cand.points[1]} of the "
                + ("intersection of the two solution spaces." if len(spec.finals)
                   + (spec.velocities is not None) == 2 else "solution space (sampled)."))
    worst = min(m["branch_margins"], key=lambda b: b["fraction"])
    doc.comment(f"Buildability: bar-length ratio {m['bar_length_ratio']:.2f}, joints at least "
                f"{m['joint_separation']:.3f} apart, rigidity margin {m['rigidity_margin']:.3f} "
                f"along the motion, branch margin {worst['margin']:.4g} "
                f"({100 * worst['fraction']:.3g} % of {worst['value']:.6g}) to the nearest fold.")
    for line in margin_lines(m["branch_margins"], on_branch(cand.fmap)):
        doc.comment(f"  {line}")
    if builds is not None:
        doc.comment(f"  {builds_line(builds)}")
    doc.comment("Map recomputed by fabkit.module_map from this file:")
    for p in met["fixed_points"]:
        doc.comment(f"  fixed point {p['value']:.10g}: |f(D) - D| "
                    f"{printed_residual(p['residual'])}, slope {printed(p['slope'], '.10g')} "
                    f"({_kind(p['slope'])})")
    if met["cycle"] is not None:
        c = met["cycle"]
        doc.comment(f"  2-cycle {c['values'][0]:.10g} <-> {c['values'][1]:.10g}: residuals "
                    f"{max(c['residuals']):.1e}, multiplier {c['multiplier']:.6g}")
    doc.value("name", name)
    doc.value("description", f"module designed from its map: {wish.options().replace('--', '')}")
    doc.table("design")
    doc.comment("initial positions of the designed nodes")
    doc.value("designed", _points(spec.designed), per_line=1)
    if spec.velocities is not None:
        s = ch["slope_designed"]
        doc.comment(f"velocities: d1 grows at rate 1, d2 at rate {s:g} (the slope at the first "
                    "state); node 1 stands still")
        doc.value("velocities", _points(spec.velocities), per_line=1)
    if spec.finals:
        f = spec.finals[0]
        d1, d2 = np.linalg.norm(f[0] - f[1]), np.linalg.norm(f[1] - f[2])
        doc.comment(f"final positions: d1 = {d1:.10g}, d2 = {d2:.10g}")
        doc.value("final", _points(f), per_line=1)
    if len(spec.finals) > 1:
        f = spec.finals[1]
        doc.comment("(a second final state, d1 = d2 = "
                    f"{np.linalg.norm(f[0] - f[1]):.10g}, also fixed the variable nodes: "
                    "designed positions " + ", ".join(f"[{float(a):.10g}, {float(b):.10g}]"
                                                      for a, b in f) + ")")
    doc.comment("variable nodes, exact (checked against the solution spaces when loaded)")
    doc.value("variable", _points(cand.variable), per_line=1)
    doc.value("ports", {"d1": [0, 1], "d2": [1, 2]})
    doc.table("motion")
    doc.value("drive", "d1")
    target, why = _motion_target(wish, cand.fmap)
    doc.value("to", target, note=why)
    doc.value("method", "auto")
    return doc.text()


def _motion_target(wish, fmap) -> tuple[float, str]:
    if wish.cycle is not None:
        return float(wish.cycle[1]), "the cycle's other state"
    if len(wish.fixed_points) > 1:
        return float(wish.fixed_points[1].value), "the second fixed point"
    d = wish.fixed_points[0].value
    lo, hi = fmap.domain
    up = min(d * 1.1, d + 0.5 * (hi - d))
    down = max(d * 0.9, d - 0.5 * (d - lo))
    target = up if hi - d >= d - lo else down
    if not math.isfinite(target):
        target = d
    return float(target), "a state beyond the fixed point, inside the branch"


def curvature_template(name: str, ctype) -> str:
    """Text of the ``[design]`` template of a designed curvature module.

    Parameters
    ----------
    name : str
    ctype : CurvatureType
    """
    apex = math.degrees(ctype.apex)
    m = ctype.margins
    doc = TomlDocument()
    doc.comment(
        f"Curvature module designed by `fabkit design --curve`: symmetric map d1 = d2 from "
        f"D1* = 1 to D2* = {LEG_RATIO:g},\n"
        f"final apex angle {apex:.6g} deg (bottom distance {ctype.bottom:.10g} at D2*).\n"
        f"Designed nodes: apex {INITIAL_APEX_DEG:g} deg at the start (every module alike, so the "
        "chain starts straight),\n"
        "the final triangle below; variable nodes: a mirror-symmetric pair on the displacement "
        "solution space,\n"
        "chosen to stay inside the module's own triangle along the motion (modules of a chain "
        "never sweep\n"
        f"over each other): margin {m['inside']:.3f}, variable nodes at least "
        f"{m['separation']:.3f} apart, rigidity margin {m['rigidity']:.3f}, "
        f"bar-length ratio {m['bar_length_ratio']:.2f},\n"
        f"branch margin {m['branch_margin']:.4g} ({100 * m['branch_margin_fraction']:.3g} % of "
        f"the state) from D1* = 1 or D2* = {LEG_RATIO:g} to the nearer fold (the branch runs "
        f"from d1 = {m['branch'][0]:.6g} to {m['branch'][1]:.6g}; every state between is a "
        "fixed point).")
    doc.value("name", name)
    doc.value("description", f"curvature module, final apex {apex:.4g} deg")
    doc.table("design")
    doc.value("designed", _points(ctype.designed), per_line=1)
    doc.value("final", _points(ctype.final), per_line=1)
    doc.value("variable", _points(ctype.variable), per_line=1)
    doc.value("ports", {"d1": [0, 1], "d2": [1, 2], "bottom": [0, 2]})
    doc.table("motion")
    doc.value("drive", "d1")
    doc.value("to", float(LEG_RATIO), note="D2*: the final shape")
    doc.value("method", "constructive")
    return doc.text()


def fit_lines(errors: dict, props: dict) -> list[str]:
    """The fit of a traced chain onto its curve, a few lines of text (the command's summary
    and the chain template's comment say the same): the distances to the curve, the ends, the
    designed nodes, and only the proportions that mean something for this curve (a fitted
    circle only for an arc).

    Examples
    --------
    >>> e = {"rms": 1.0, "max": 2.0, "mean": 0.5, "mean_fraction": 0.001, "start": 0.2,
    ...      "end": 0.3, "start_fraction": 0.0004, "end_fraction": 0.0006, "size": 500.0,
    ...      "nodes_mean": 9.0, "nodes_mean_fraction": 0.018}
    >>> p = {"curve": {"length": 785.4, "chord": 707.1, "turn_deg": 0.0},
    ...      "chain": {"length": 786.0, "chord": 707.0, "turn_deg": 1.2}}
    >>> print("\\n".join(fit_lines(e, p)))
    fit error: rms 1.000 mm, max 2.000 mm, mean 0.500 mm (0.1 % of the curve's size, 500.0 mm)
    ends: start 0.200 mm, end 0.300 mm (0.04 % / 0.06 %)
    designed nodes (the zigzag of the ports): 9.000 mm from the curve on average (1.8 %)
    length: curve 785.40 mm, chain centre line 786.00 mm; chord 707.10 / 707.00 mm; turn 0.0 / 1.2 deg
    """
    c, ch = props["curve"], props["chain"]
    out = [f"fit error: rms {errors['rms']:.3f} mm, max {errors['max']:.3f} mm, mean "
           f"{errors['mean']:.3f} mm ({100 * errors['mean_fraction']:.2g} % of the curve's size, "
           f"{errors['size']:.1f} mm)",
           f"ends: start {errors['start']:.3f} mm, end {errors['end']:.3f} mm "
           f"({100 * errors['start_fraction']:.2g} % / {100 * errors['end_fraction']:.2g} %)"]
    if "nodes_mean" in errors:
        out.append(f"designed nodes (the zigzag of the ports): {errors['nodes_mean']:.3f} mm "
                   f"from the curve on average ({100 * errors['nodes_mean_fraction']:.2g} %)")
    chord = (f"chord {c['chord']:.2f} / {ch.get('chord', 0.0):.2f} mm" if "chord" in c
             else "closed")
    out.append(f"length: curve {c['length']:.2f} mm, chain centre line {ch['length']:.2f} mm; "
               f"{chord}; turn {c['turn_deg']:.1f} / {ch['turn_deg']:.1f} deg")
    if "circle_radius" in c and "circle_radius" in ch:
        out.append(f"fitted circle: curve r = {c['circle_radius']:.2f} mm over "
                   f"{c['circle_sweep_deg']:.2f} deg, chain r = {ch['circle_radius']:.2f} mm "
                   f"over {ch['circle_sweep_deg']:.2f} deg")
    return out


def chain_template(name: str, modules, scale: float, errors: dict, props: dict, curve,
                   module_size: float) -> str:
    """Text of the ``[chain]`` template of a curve-following chain.

    Parameters
    ----------
    name : str
    modules : list of str
        Module template file names, one per module of the chain.
    scale : float
        mm per design unit (the kit's size: the curve's own).
    errors, props : dict
        Fit error (mm) and proportions of the traced final state against the curve.
    curve : Curve
    module_size : float
    """
    doc = TomlDocument()
    doc.comment(
        f"A chain of {len(modules)} curvature modules whose final state follows a drawn curve "
        f"({curve.source}, {curve.length:.1f} mm),\n"
        f"designed by `fabkit design --curve` with modules of {module_size:g} mm; straight at "
        "the start, the curve at the end.\n"
        "Checked by tracing the chain to its final state (constructive) and fitting it onto "
        "the curve (best rigid fit):")
    for line in fit_lines(errors, props):
        doc.comment(f"  {line}")
    doc.value("name", name)
    doc.value("description",
              f"{len(modules)} curvature modules following a {curve.length:.0f} mm curve; fit "
              f"error rms {errors['rms']:.2f} mm, max {errors['max']:.2f} mm, mean "
              f"{100 * errors['mean_fraction']:.2g} % of its size, ends "
              f"{100 * errors['start_fraction']:.2g} / {100 * errors['end_fraction']:.2g} %")
    doc.table("chain")
    doc.value("modules", list(modules), per_line=3)
    doc.value("mirror", "alternate")
    doc.table("motion")
    doc.value("drive", "d1")
    doc.value("to", float(LEG_RATIO), note="D2*: every module in its final shape")
    doc.value("method", "constructive")
    doc.table("fabrication.laser")
    doc.value("scale", float(scale), note="mm per design unit: the kit has the curve's size")
    return doc.text()
