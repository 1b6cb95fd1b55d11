"""A chain whose final state follows a drawn curve: the letters design (:mod:`fabkit.letters`)
generalised to any curve, with curvature modules designed for it.

The curve (mm) and the module size (the chain's pitch along the curve, mm) fix everything:

1. the sharpest turn of the curve over two module pitches sets the spread of final apex angles
   the modules need (a chain mirrored every second module turns by the difference of two
   neighbours' apex angles, see :mod:`fabkit.letters`);
2. one curvature module is designed per apex angle (:func:`design_curvature_type`): the types
   are evenly spaced over the spread, so a circular arc is followed by alternating the extreme
   two, which turn the chain by exactly the arc's angle per two pitches; the spread's centre
   (the straight type) is chosen for the best margins, with its joints kept ``MIN_JOINT_MM``
   apart at the kit's scale;
3. the scale (mm per design unit) makes the straight type's pitch the module size;
4. :func:`fabkit.designer.sequence.choose_types` chooses every module's type (the letters'
   beam search among others), so the number of modules follows from the curve's length and the
   module size;
5. the chain is built from the written module templates, traced to its final state
   (``constructive``), moved onto the curve by a rigid best fit and compared with it: the fit
   error in mm (largest and RMS distance of the chain's centre line to the curve, and of its ends
   to the curve's ends), and the proportions (length, chord, and a circle fitted to each).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import DesignError
from ..network import Network
from ..numerics import apply_fit, rigid_fit
from .curvature import APEX_RANGE_DEG, LEG_RATIO, MIN_PAIR_APEX_DEG, design_curvature_type
from .curve_files import Curve
from .sequence import choose_types
from .toml_text import curvature_template, chain_template
from .wishes import WishError

__all__ = ["CurveDesign", "design_curve_chain", "circle_fit", "needed_turn", "scaled",
           "MAX_MODULES"]

#: Turns below this (degrees per two modules) are straight: one module type does.
STRAIGHT_TURN_DEG = 0.05
#: The most modules a curve may need (each is 6 bars and 2 variable joints).
MAX_MODULES = 2000
#: Beam width of the type search (partial designs kept per module).
BEAM = 96
#: Least distance (mm) between two joints of a module along its motion: an M3 Chicago screw's
#: heads are 8.5 mm across (FABRICATION.md), plus the laser kit's default 1 mm clearance; the
#: laser export refuses joints closer than two heads.
MIN_JOINT_MM = 9.5
#: Enlargements of a drawing tried when no module size can follow it.
CURVE_SCALES = (1.25, 1.5, 2.0, 2.5, 3.0, 4.0)
#: Points per module length at which a curve's turn is measured.
SAMPLES_PER_MODULE = 8
#: Spacing (degrees) of the straight type's final apex angles tried.
CENTRE_STEP_DEG = 4.0


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


def needed_turn(points: np.ndarray, module: float) -> float:
    """The largest turn (radians) of a curve over two modules: the angle between the chords of
    one module length centred a module before and a module after each point (exactly 2m/R on
    a circle of radius R, whatever polyline approximates it)."""
    p = np.asarray(points, dtype=np.float64)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    length = float(s[-1])

    def at(t):
        t = np.clip(t, 0.0, length)
        return np.column_stack([np.interp(t, s, p[:, 0]), np.interp(t, s, p[:, 1])])

    if length <= 2 * module:
        d = p[-1] - p[0]
        mid = at(np.array([0.5 * length]))[0]
        a, b = mid - p[0], p[-1] - mid
        return float(abs(math.atan2(a[0] * b[1] - a[1] * b[0], float(a @ b)))) if np.any(d) else 0.0
    centres = np.linspace(module, length - module, max(2, int(SAMPLES_PER_MODULE * length / module)))
    before = at(centres - 0.5 * module) - at(centres - 1.5 * module)
    after = at(centres + 1.5 * module) - at(centres + 0.5 * module)
    cross = before[:, 0] * after[:, 1] - before[:, 1] * after[:, 0]
    dot = np.sum(before * after, axis=1)
    return float(np.max(np.abs(np.arctan2(cross, dot))))


def scaled(curve: Curve, factor: float) -> Curve:
    """The curve drawn ``factor`` times larger."""
    return Curve(points=curve.points * factor, length=curve.length * factor, source=curve.source,
                 strokes=curve.strokes)


def _nearest(curve: Curve, module_size: float, types: int, sizes) -> str | None:
    """The first module size of ``sizes`` with which the curve can be built, else the smallest
    enlargement of the drawing (``--curve-scale``) with which it can at this module size."""
    def builds(c, m):
        try:
            design_curve_chain(c, module_size=m, types=types, name="probe", _suggest=False)
        except WishError:
            return False
        return True

    for m in sizes:
        m = float(f"{m:.3g}")
        if m > 0 and builds(curve, m):
            return f"--module-size {m:g}"
    for f in CURVE_SCALES:
        if builds(scaled(curve, f), module_size):
            return f"--curve-scale {f:g} (the drawing {f:g}x larger)"
    return None


def _module_types(need: float, n: int, module_size: float):
    """The straight type's apex and the designed types, spread over ``need`` degrees, or
    (None, []) when no spread keeps the joints ``MIN_JOINT_MM`` apart at this module size.

    The spread's centre is free: at least ``MIN_PAIR_APEX_DEG`` (neighbours must not both be
    narrow; where the range allows, high enough for every two adjacent types to neighbour each
    other), and chosen, on a grid, where the worse of the two extreme types has the best score
    (variable nodes farthest inside their triangle, from each other and from the bars, see
    :func:`design_curvature_type`). The centre sets the scale (its pitch is the module size),
    and with it how far apart, in design units, the joints must stay."""
    lo, hi = APEX_RANGE_DEG
    straight_only = need < STRAIGHT_TURN_DEG
    last = hi - need / 2
    every_pair = MIN_PAIR_APEX_DEG + need / 2 - (0.0 if straight_only else need / (2 * (n - 1)))
    first = every_pair if every_pair <= last else max(lo + need / 2, MIN_PAIR_APEX_DEG)
    count = max(1, int(math.floor((last - first) / CENTRE_STEP_DEG)) + 1)
    centres = np.linspace(first, last, count) if count > 1 else [0.5 * (first + last)]
    cache: dict = {}

    def room(centre):
        # joints MIN_JOINT_MM apart, in design units at the scale this centre gives
        return MIN_JOINT_MM * LEG_RATIO * math.sin(math.radians(centre) / 2) / module_size

    def typ(apex, centre):
        key = (round(float(apex), 9), round(room(centre), 12))
        if key not in cache:
            try:
                cache[key] = design_curvature_type(key[0], key[1])
            except DesignError:
                cache[key] = None
        return cache[key]

    def score(apex, centre):
        t = typ(apex, centre)
        return -1.0 if t is None else t.score

    ends = (0.0,) if straight_only else (-need / 2, need / 2)
    worst = [min(score(c + e, c) for e in ends) for c in centres]
    if max(worst) <= 0:
        return None, []
    centre = float(centres[int(np.argmax(worst))])
    apexes = [centre] if straight_only else centre + need * (np.arange(n) / (n - 1) - 0.5)
    types = [typ(a, centre) for a in apexes]
    if any(t is None for t in types):
        return None, []
    return centre, types


def _proportions(curve_pts: np.ndarray, center: np.ndarray) -> dict:
    def describe(p):
        length = float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))
        r, _, sweep = circle_fit(p)
        return {"length": length, "chord": float(np.linalg.norm(p[-1] - p[0])),
                "circle_radius": r, "circle_sweep_deg": math.degrees(sweep)}

    return {"curve": describe(curve_pts), "chain": describe(center)}


def design_curve_chain(curve, *, module_size: float = 50.0, types: int = 3,
                       name: str = "curve", beam: int = BEAM, _suggest: bool = True) -> CurveDesign:
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
        The curve turns more sharply than modules of this size can follow, modules of this size
        would bring joints closer than a screw head allows, or the curve is shorter than two
        modules; the nearest module size (or enlargement of the drawing) that builds is named.
    """
    from ..assemble import chain
    from ..kinematics import trace
    from ..letters import (_point_at, _resample, chain_centerline, curvature_modules,
                           polyline_distance)
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

    def suggest(sizes):
        return _nearest(curve, module_size, int(types), sizes) if _suggest else None

    if curve.length < 2 * module_size:
        raise WishError(wish, f"the curve ({curve.length:.1f} mm) is shorter than two modules",
                        suggest([curve.length / 2.5, curve.length / 3, curve.length / 4]))
    turn = needed_turn(pts, module_size)
    span = APEX_RANGE_DEG[1] - APEX_RANGE_DEG[0]
    need = math.degrees(turn)
    if need > span:
        bound = module_size * span / need
        raise WishError(wish, f"the curve turns by {need:.1f} deg within two modules "
                              f"({2 * module_size:g} mm); the modules turn a chain by at most "
                              f"{span:g} deg per two",
                        suggest([bound * f for f in (0.98, 0.9, 0.8, 0.7)]))
    straight, designed = _module_types(need, int(types), module_size)
    if straight is None:
        raise WishError(wish, f"no curvature modules of {module_size:g} mm keep their joints "
                              f"{MIN_JOINT_MM:g} mm apart (Chicago screw heads) while turning "
                              f"the chain by {need:.1f} deg per two",
                        suggest([module_size * 1.1 ** k for k in range(1, 8)]))
    files = {f"{name}_m{j + 1}.toml": curvature_template(f"{name}_m{j + 1}", t)
             for j, t in enumerate(designed)}
    nets = {}
    for fname, text in files.items():
        nets[fname] = parse_template(text, f"<{fname}>").network
    modules = curvature_modules(nets, LEG_RATIO)
    pitch = LEG_RATIO * math.sin(math.radians(straight) / 2)
    scale = module_size / pitch
    target = pts / scale
    max_modules = int(math.ceil(2.5 * curve.length / module_size)) + 4
    if max_modules > MAX_MODULES:
        raise WishError(wish, f"the curve ({curve.length:.0f} mm) needs more than {MAX_MODULES} "
                              "modules", suggest([curve.length / MAX_MODULES * f
                                                  for f in (2.5, 3, 4)]))
    chosen = choose_types(target, modules, beam=int(beam), limit=max_modules)
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
        "straight_apex_deg": straight,
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

