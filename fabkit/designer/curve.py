"""A chain whose final state follows a drawn curve: the letters design (:mod:`fabkit.letters`)
generalised to any curve, with curvature modules designed for it.

The curve (mm) and the module size (the chain's pitch along the curve, mm) fix everything:

1. the sharpest turn of the curve over two module pitches sets the spread of final apex angles
   the modules need (a chain mirrored every second module turns by the difference of two
   neighbours' apex angles, see :mod:`fabkit.letters`), centred on the straight type's apex;
2. one curvature module is designed per apex angle (:func:`design_curvature_type`): the types
   are evenly spaced over the spread, so a circular arc is followed by alternating the extreme
   two, which turn the chain by exactly the arc's angle per two pitches;
3. the scale (mm per design unit) makes the straight type's pitch the module size;
4. the beam search of :func:`fabkit.letters.design_curve` chooses every module's type, so the
   number of modules follows from the curve's length and the module size;
5. the chain is built from the written module templates, traced to its final state
   (``constructive``), moved onto the curve by a rigid best fit and compared with it: the fit
   error in mm (largest and RMS distance of the chain's centre line to the curve, and of its end
   to the curve's end), and the proportions (length, and a circle fitted to each).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import DesignError
from ..network import Network
from ..numerics import apply_fit, rigid_fit
from .curvature import (APEX_RANGE_DEG, LEG_RATIO, STRAIGHT_APEX_DEG, CurvatureType,
                        design_curvature_type)
from .curve_files import Curve
from .toml_text import curvature_template, chain_template
from .wishes import WishError

__all__ = ["CurveDesign", "design_curve_chain", "circle_fit", "needed_turn", "MAX_MODULES"]

#: Turns below this (degrees per two modules) are straight: one module type does.
STRAIGHT_TURN_DEG = 0.05
#: The most modules a curve may need (each is 6 bars and 2 variable joints).
MAX_MODULES = 2000
#: Beam width of the type search (partial designs kept per module).
BEAM = 96


@dataclass(frozen=True, eq=False)
class CurveDesign:
    """A chain designed to follow a curve.

    Attributes
    ----------
    curve : Curve
    types : list of CurvatureType
    names : list of str
        The module type (template stem) of every module of the chain, in order.
    network : Network
        The chain, built from the module templates as written.
    scale : float
        mm per design unit (written as ``[fabrication.laser] scale``).
    module_size : float
        mm: the straight type's pitch along the curve.
    centerline : numpy.ndarray, shape (K + 1, 2)
        The traced final state's centre line (midpoints of the chain's ports), in mm, moved
        onto the curve by a rigid best fit.
    final : numpy.ndarray, shape (N, 2)
        The traced final state of every node, in mm, in the same frame.
    errors : dict
        ``rms``, ``max`` (distance of the centre line to the curve), ``end`` (of its last point
        to the curve's end), ``start``: mm.
    proportions : dict
        Lengths, chords and fitted circles of the curve and of the chain's centre line.
    templates : dict of str to str
        File name → text: the chain template and one template per module type.
    report : dict
        JSON-ready summary of all of the above.
    """

    curve: Curve
    types: list
    names: list
    network: Network
    scale: float
    module_size: float
    centerline: np.ndarray
    final: np.ndarray
    errors: dict
    proportions: dict
    templates: dict
    report: dict


def circle_fit(points) -> tuple[float, np.ndarray, float]:
    """Least-squares circle through points (algebraic fit, refined by Gauss-Newton on the
    geometric distances).

    Parameters
    ----------
    points : array_like, shape (M, 2)

    Returns
    -------
    radius : float
    centre : numpy.ndarray, shape (2,)
    sweep : float
        Angle (radians) the points sweep around the centre, first to last.

    Examples
    --------
    >>> t = np.linspace(0, np.pi / 2, 50)
    >>> r, c, a = circle_fit(np.column_stack([3 + 2 * np.cos(t), 1 + 2 * np.sin(t)]))
    >>> round(r, 9), [round(float(v), 9) for v in c], round(float(np.degrees(a)), 6)
    (2.0, [3.0, 1.0], 90.0)
    """
    p = np.asarray(points, dtype=np.float64)
    A = np.column_stack([2 * p, np.ones(len(p))])
    sol = np.linalg.lstsq(A, np.sum(p * p, axis=1), rcond=None)[0]
    c = sol[:2]
    r = math.sqrt(max(sol[2] + c @ c, 0.0))
    for _ in range(20):
        d = p - c
        dist = np.linalg.norm(d, axis=1)
        J = np.column_stack([-d / dist[:, None], -np.ones(len(p))])
        step = np.linalg.lstsq(J, -(dist - r), rcond=None)[0]
        c, r = c + step[:2], r + step[2]
    ang = np.unwrap(np.arctan2(p[:, 1] - c[1], p[:, 0] - c[0]))
    return float(r), c, float(abs(ang[-1] - ang[0]))


def _headings(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = np.diff(p, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(d, axis=1))])
    th = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return 0.5 * (s[:-1] + s[1:]), th


def needed_turn(points: np.ndarray, window: float) -> float:
    """The largest turn (radians) of a curve over any stretch of arclength ``window``."""
    s, th = _headings(points)
    if s[-1] - s[0] <= window:
        return float(abs(th[-1] - th[0]))
    ahead = np.interp(s + window, s, th)
    valid = s + window <= s[-1]
    return float(np.max(np.abs(ahead[valid] - th[valid])))


def _greedy(target: np.ndarray, modules, first: int) -> np.ndarray:
    """Module types that keep the chain's centre line on ``target`` (design units), chosen
    module by module: the type whose new centre-line point lies nearest the target point at the
    same arclength, with the heading error weighted in (a step ahead of the position error)."""
    from ..letters import _point_at, _resample, strip_model

    s_nodes = _resample(target)
    length = float(s_nodes[-1])
    chord = target[np.searchsorted(s_nodes, min(0.05 * length, s_nodes[-1]))] - target[0]
    heading0 = math.atan2(chord[1], chord[0])
    apex0 = modules[first].apex
    start = heading0 + 0.5 * (math.pi - apex0)  # module 1 turns clockwise (strip_model)
    types = [first]
    for _ in range(MAX_MODULES):
        best, best_cost, done = None, math.inf, False
        for t in range(len(modules)):
            m = strip_model(types + [t], modules, start_heading=start, origin=target[0])
            c = 0.5 * (m[:-1] + m[1:])
            seg = np.linalg.norm(np.diff(c, axis=0), axis=1)
            s = float(seg.sum())
            here = _point_at(target, s_nodes, np.array([s]))[0]
            ahead = _point_at(target, s_nodes, np.array([s + seg[-1]]))[0]
            want = ahead - here
            step = c[-1] - c[-2]
            cross = step[0] * want[1] - step[1] * want[0]
            err = math.atan2(cross, float(step @ want)) if np.any(want) else 0.0
            cost = float(np.sum((c[-1] - here) ** 2)) + (seg[-1] * err) ** 2
            if cost < best_cost:
                best, best_cost, done = t, cost, s >= length - 0.5 * seg[-1]
        types.append(best)
        if done:
            break
    return np.array(types, dtype=int)


def _strip_error(types, modules, target) -> float:
    """RMS distance of a type sequence's centre line, rigidly fitted, to the target."""
    from ..letters import polyline_distance, strip_model

    m = strip_model(types, modules)
    c = 0.5 * (m[:-1] + m[1:])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
    from ..letters import _point_at, _resample

    ref = _point_at(target, _resample(target), s)
    moved = apply_fit(rigid_fit(c, ref, handedness="proper"), c)
    d = polyline_distance(moved, target)
    return float(np.sqrt(np.mean(d ** 2)) + np.linalg.norm(moved[-1] - target[-1]))


def _proportions(curve_pts: np.ndarray, center: np.ndarray) -> dict:
    def describe(p):
        length = float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))
        r, _, sweep = circle_fit(p)
        return {"length": length, "chord": float(np.linalg.norm(p[-1] - p[0])),
                "circle_radius": r, "circle_sweep_deg": math.degrees(sweep)}

    return {"curve": describe(curve_pts), "chain": describe(center)}


def design_curve_chain(curve, *, module_size: float = 50.0, types: int = 3,
                       name: str = "curve", beam: int = BEAM) -> CurveDesign:
    """Design a chain of curvature modules whose final state follows ``curve``.

    Parameters
    ----------
    curve : Curve or array_like, shape (M, 2)
        The curve in mm (from :func:`read_curve`, or points).
    module_size : float
        The chain's pitch along the curve (mm) for the straight module type.
    types : int
        Number of module types (odd; 3 gives turns of 0, half and all of the sharpest turn per
        two modules).
    name : str
        Stem of the written templates.
    beam : int
        Beam width of the type search.

    Returns
    -------
    CurveDesign

    Raises
    ------
    WishError
        The curve turns more sharply than modules of this size can follow (the nearest module
        size that can is named), or is shorter than two modules.
    """
    from ..assemble import chain
    from ..kinematics import trace
    from ..letters import (_point_at, _resample, chain_centerline, curvature_modules,
                           design_curve, polyline_distance)
    from ..templates import parse_template

    start = time.perf_counter()
    if not isinstance(curve, Curve):
        from .curve_files import _resampled

        curve = _resampled(np.asarray(curve, dtype=np.float64), "points", 1)
    if not (math.isfinite(module_size) and module_size > 0):
        raise WishError(f"--module-size {module_size:g}", "must be a positive number of mm")
    if isinstance(types, bool) or int(types) < 3 or int(types) % 2 == 0:
        raise WishError(f"--types {types}", "must be an odd number, at least 3 (a straight type "
                                            "and pairs either side)")
    pts = curve.points
    wish = f"--curve with --module-size {module_size:g}"
    if curve.length < 2 * module_size:
        raise WishError(wish, f"the curve ({curve.length:.1f} mm) is shorter than two modules",
                        f"--module-size {curve.length / 4:.3g}")
    turn = needed_turn(pts, 2 * module_size)
    half = min(STRAIGHT_APEX_DEG - APEX_RANGE_DEG[0], APEX_RANGE_DEG[1] - STRAIGHT_APEX_DEG)
    need = math.degrees(turn)
    if need > 2 * half:
        size = module_size * (2 * half) / need
        raise WishError(wish, f"the curve turns by {need:.1f} deg within two modules "
                              f"({2 * module_size:g} mm); the modules turn a chain by at most "
                              f"{2 * half:g} deg per two", f"--module-size {math.floor(size):g}")
    if need < STRAIGHT_TURN_DEG:
        apexes = [STRAIGHT_APEX_DEG]
    else:
        n = int(types)
        apexes = [float(a) for a in STRAIGHT_APEX_DEG + need * (np.arange(n) / (n - 1) - 0.5)]
    designed: list[CurvatureType] = [design_curvature_type(a) for a in apexes]
    files = {f"{name}_m{j + 1}.toml": curvature_template(f"{name}_m{j + 1}", t)
             for j, t in enumerate(designed)}
    nets = {}
    for fname, text in files.items():
        nets[fname] = parse_template(text, f"<{fname}>").network
    modules = curvature_modules(nets, LEG_RATIO)
    pitch = LEG_RATIO * math.sin(math.radians(STRAIGHT_APEX_DEG) / 2)
    scale = module_size / pitch
    target = pts / scale
    max_modules = int(math.ceil(2.5 * curve.length / module_size)) + 4
    if max_modules > MAX_MODULES:
        raise WishError(wish, f"the curve ({curve.length:.0f} mm) needs more than {MAX_MODULES} "
                              "modules", f"--module-size {curve.length / MAX_MODULES * 2.5:.3g}")
    # Two searches: the letters' beam search, and a module-by-module one from each first type;
    # the sequence whose centre line, fitted onto the curve, lies closest to it is taken.
    options = [design_curve(target, modules, beam=int(beam), max_modules=max_modules).types]
    options += [_greedy(target, modules, t) for t in range(len(modules))]
    scores = [_strip_error(o, modules, target) for o in options]
    chosen = options[int(np.argmin(scores))]
    names = [modules[t].name for t in chosen]
    net = chain([nets[n] for n in names], mirror="alternate")
    traj = trace(net, "d1", to=LEG_RATIO, method="constructive", samples=2)
    if str(traj.status) != "finished":
        raise DesignError(f"the designed chain does not reach its final state: {traj.message}")
    k = len(names)
    center_units = chain_centerline(net, traj.positions[-1], k)
    # the traced chain onto the curve: a rigid best fit of its centre line to the curve's points
    # at the same arclength
    seg = np.linalg.norm(np.diff(center_units, axis=0), axis=1)
    s_c = np.concatenate([[0.0], np.cumsum(seg)])
    ref = _point_at(target, _resample(target), s_c)
    move = rigid_fit(center_units, ref, handedness="proper")
    final = apply_fit(move, traj.positions[-1]) * scale
    center = chain_centerline(net, final, k)
    dist = polyline_distance(center, pts)
    errors = {"rms": float(np.sqrt(np.mean(dist ** 2))), "max": float(dist.max()),
              "start": float(np.linalg.norm(center[0] - pts[0])),
              "end": float(np.linalg.norm(center[-1] - pts[-1]))}
    props = _proportions(pts, center)
    counts = {n: names.count(n) for n in files}
    report = {
        "curve": {"source": curve.source, "length_mm": curve.length, "strokes": curve.strokes,
                  "sharpest_turn_deg_per_two_modules": need},
        "module_size_mm": module_size, "scale_mm_per_unit": scale, "modules": k,
        "types": [{"template": f, "final_apex_deg": math.degrees(t.apex), "count": counts[f],
                   "margins": t.margins} for f, t in zip(files, designed)],
        "fit_error_mm": errors, "proportions": props,
        "trace": {"method": traj.method, "status": str(traj.status),
                  "max_edge_error": float(traj.max_edge_error)},
        "seconds": time.perf_counter() - start,
    }
    files[f"{name}.toml"] = chain_template(name, names, scale, errors, props, curve, module_size)
    return CurveDesign(curve=curve, types=designed, names=names, network=net, scale=scale,
                       module_size=module_size, centerline=center, final=final, errors=errors,
                       proportions=props, templates=files, report=report)

