"""A chain whose final state follows a drawn curve: the letters design
(:mod:`fabkit.design.letters`) generalised to any curve, with curvature modules designed for it.

The curve (mm) and the module size (mm per module along the curve) fix everything:

1. the scale (mm per design unit) makes a module of the reference apex angle one module size
   long; at that scale the joints of every module must stay ``MIN_JOINT_MM`` apart, which
   leaves the apex angles from :func:`~fabkit.design.curvature.lowest_apex` to the top of
   ``APEX_RANGE_DEG`` (small modules leave fewer, and so turn less sharply);
2. :func:`~fabkit.design.sequence.track` chooses every module's final apex angle on a grid
   of one degree over that range: the zigzag of the chain follows the curve end to end, turning
   as fast as its apex angles allow where the curve turns faster (a corner is cut), and
   :func:`~fabkit.design.sequence.refine` lets every angle take any value in the range
   (least squares on the distances to the curve; with one module more and one fewer too);
3. the angles are binned into a few module types (:func:`~fabkit.design.sequence.bin_apexes`,
   as few as keep the fit, or ``types``), each module takes the type that reproduces the
   refined chain, and the types' angles are refitted to the curve;
4. one curvature module is designed per type (:func:`design_curvature_type`), its joints kept
   ``MIN_JOINT_MM`` apart at the kit's scale;
5. the chain is built from the written module templates, traced to its final state
   (``constructive``) and fitted onto the curve (:func:`~fabkit.design.fit.fit_to_curve`):
   the distance of its centre line to the curve (mean, RMS, largest), of its ends to the
   curve's ends, and of its designed nodes (the zigzag) to the curve, in mm and as fractions of
   the curve's size (the diagonal of its bounding box); with the proportions that mean
   something for this curve (length, chord, total turn; a fitted circle only for an arc).

A chain is accepted when its centre line lies within ``FIT_TOLERANCE`` of the curve's size
(mean) and its ends within ``END_TOLERANCE``. A curve that turns faster than modules of this
size can (or has corners sharper than they can cut within the tolerance) is refused, naming
the nearest wish that builds and lays the whole chain on the drawing: its centre line and ends
within the tolerances and its designed nodes within ``NODES_TOLERANCE`` of the size on average
(measured against the drawn curve itself: a chain is a strip whose nodes lie half a module's
width off its centre line, and nodes within 1 % say the strip is narrow against the drawing).
That is a smaller module size at the drawing's size, else the least enlargement of the drawing
(with the smallest modules that turn well, and at the size asked and half of it), modelled,
then built and measured on the drawing. No module size turns a chain tighter than
:func:`tightest_radius` (about 122 mm: the narrow apex angles need room for the screws), so a
sharper turn is always cut; the refusal says so. The report carries the chain as measured on
the drawing by :func:`~fabkit.design.drawing_fit.fit_final_state` (its own fit of the traced
port midpoints, and the designed nodes).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import DesignError, FabkitError
from ..templates import parse_template
from ..kinematics import trace
from ..model.network import Network
from .assemble import chain
from .curvature import (APEX_RANGE_DEG, design_curvature_type, GRID_SLACK_DEG, LEG_RATIO,
                        lowest_apex, MIN_PAIR_APEX_DEG)
from .curve_files import Curve, resampled_curve
from .drawing_fit import fit_final_state
from .fit import (arclength, curve_size, describe_curve, fit_to_curve, point_at,
                  polyline_distance)
from .letters import chain_centerline, curvature_modules
from .sequence import (BEAM_WIDTH, bin_apexes, follow, refine, refit_bins, strip_centreline,
                       strip_nodes, track)
from .toml_text import chain_template, curvature_template
from .wishes import WishError

__all__ = ["CurveDesign", "design_curve_chain", "needed_turn", "scaled", "chain_plan",
           "tightest_radius", "curve_radius", "MAX_MODULES", "MAX_TYPES", "MIN_JOINT_MM",
           "FIT_TOLERANCE", "END_TOLERANCE", "REFERENCE_APEX_DEG"]

#: The most modules a curve may need (each is 6 bars and 2 variable joints).
MAX_MODULES = 2000
#: The most module types a chain is binned into (the authors' binned curvature designs used
#: 15).
MAX_TYPES = 15
#: Type counts tried, fewest first, when none is asked.
TYPE_COUNTS = (1, 2, 3, 4, 5, 7, 9, 11, 15)
#: Least distance (mm) between two joints of a module along its motion: an M3 Chicago screw's
#: heads are 8.5 mm across (FABRICATION.md), plus the laser kit's default 1 mm clearance; the
#: laser export refuses joints closer than two heads.
MIN_JOINT_MM = 9.5
#: The module size is the centre-line step of a module of this final apex angle (degrees): the
#: middle of the angles a chain uses on straight stretches (neighbours average at least
#: ``MIN_PAIR_APEX_DEG``); the search prefers it where other angles do as well.
REFERENCE_APEX_DEG = MIN_PAIR_APEX_DEG + 2.0
#: Spacing (degrees) of the apex angles on offer to the search before binning.
APEX_STEP_DEG = 1.0
#: Accepted fit of the traced chain: mean distance of its centre line to the curve, and of
#: each end to the curve's end, as fractions of the curve's size (bounding-box diagonal).
FIT_TOLERANCE = 0.01
END_TOLERANCE = 0.02
#: A suggested wish also keeps the chain's designed nodes (the ends of its ports, half a
#: module's width off the centre line) within this fraction of the curve's size on average,
#: measured against the drawn curve itself: the whole chain, not only its centre line, lies on
#: the drawing (docs/design.md).
NODES_TOLERANCE = 0.01
#: The nodes of a straight stretch at the widest apex angle (:func:`_node_offset`) lie at
#: least about this share of a chain's mean node distance from its curve (the quadrifolium's
#: chains: 0.97; a half circle's: 0.87): below it no size is modelled, and enlargements are
#: sought from there.
NODE_BOUND_SLACK = 0.8
#: When only the nodes miss, the next enlargement tried is the one they ask, times this.
NODE_JUMP = 1.02
#: A suggestion's nodes are held to this share of ``NODES_TOLERANCE``: the model's nodes lie
#: as far from the curve as the traced chain's, on average, to within 0.01 % of the size (and
#: the pasted wish designs the same chain), so the share is kept small.
NODES_SHARE = 0.95
#: A binned chain is as good as the unbinned one when its errors are within this factor of
#: the unbinned chain's, or within this fraction of the tolerances.
BIN_SLACK = 1.25
BIN_GOOD = 0.1
#: Rounds of refitting the bins' angles and choosing the types again.
BIN_ROUNDS = 2
#: Bins this close (degrees) after the refit are one type, when that costs the fit at most
#: MERGE_SLACK (as a factor on its errors against the tolerances).
MERGE_DEG = 1.0
MERGE_SLACK = 1.25
#: Points per module length at which a curve's turn is measured.
SAMPLES_PER_MODULE = 8
#: A suggested enlargement is sought where the curve needs at most this share of the sharpest
#: turn the modules give (the rest is left for the search to follow the curve closely).
TURN_SHARE = 0.8
#: Suggestions: smaller module sizes tried (factors of the one asked) and the largest
#: enlargement of the drawing sought.
SIZE_FACTORS = (0.9, 0.8, 0.7, 0.6, 0.5)
MAX_CURVE_SCALE = 10000.0
#: A suggestion must fit within this share of the tolerances (the full design is then built
#: to it, so a suggestion pasted alone designs with room to spare).
SUGGEST_SHARE = 0.75
#: Enlargements are also sought at this share of the module size asked and at
#: ``TIGHT_SIZE_FLOOR`` times the smallest module size: modules of 20-30 mm turn along about
#: the tightest radius any size turns along (:func:`tightest_radius`), cut sharp turns more
#: closely than 50 mm ones, and their nodes lie closer to the curve.
TIGHT_SIZE_FACTOR = 0.5
TIGHT_SIZE_FLOOR = 1.3
#: The least enlargement is bisected (in ratio) this many times, down to at most
#: ``BISECT_RANGE`` times below the first that fits.
BISECT_STEPS = 4
BISECT_RANGE = 3.0
#: tightest_radius(): module sizes scanned (mm), and their step.
RADIUS_SIZES_TO = 80.0
RADIUS_SIZE_STEP = 0.5
#: curve_radius(): the window (fraction of the curve's size) its turn is measured over.
RADIUS_WINDOW = 0.01
#: Enlargements tried, each 1.2 times the last, from the one computed.
SCALE_TRIES = 12
#: The search for a nearest feasible wish models chains of at most this many modules (0.05 to
#: 0.1 s a module, each), or of the drawing enlarged at most ``SUGGEST_GROWTH`` times when
#: that is more: a drawing that needs a far longer chain to be followed (a 70-byte corner, 320
#: times larger: 360 modules) is refused with its reason, not searched for minutes. The
#: bundled suggestions need 2 to 310 modules (quadrifolium: 4 times larger, with 19.9 mm
#: modules whose nodes lie within 1 %).
MAX_SUGGEST_MODULES = 250
SUGGEST_GROWTH = 20.0
#: A bin that holds no module still counts this much when bins are merged (its own angle).
EMPTY_BIN_WEIGHT = 1e-12
#: Round-off forgiven when a scale is rounded up to two digits (2.2 stays 2.2).
ROUND_SLACK = 1e-9


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
        mm: the centre-line step of a module of the reference apex angle.
    centerline : numpy.ndarray, shape (K + 1, 2)
        The traced final state's centre line (midpoints of the chain's ports), in mm, moved
        onto the curve by the best rigid fit.
    final : numpy.ndarray, shape (N, 2)
        The traced final state of every node, in mm, in the same frame.
    errors : dict
        Distances to the curve, mm and fractions of its size (see
        :func:`~fabkit.design.fit.fit_to_curve`), with ``nodes_mean`` / ``nodes_max``: the
        designed nodes (the zigzag of the ports) against the curve.
    proportions : dict
        :func:`~fabkit.design.fit.describe_curve` of the curve and of the chain.
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
        mid = at(np.array([0.5 * length]))[0]
        a, b = mid - p[0], p[-1] - mid
        return float(abs(math.atan2(a[0] * b[1] - a[1] * b[0], float(a @ b))))
    count = min(200_000, max(2, int(SAMPLES_PER_MODULE * length / module)))
    centres = np.linspace(module, length - module, count)
    before = at(centres - 0.5 * module) - at(centres - 1.5 * module)
    after = at(centres + 1.5 * module) - at(centres + 0.5 * module)
    cross = before[:, 0] * after[:, 1] - before[:, 1] * after[:, 0]
    dot = np.sum(before * after, axis=1)
    return float(np.max(np.abs(np.arctan2(cross, dot))))


def scaled(curve: Curve, factor: float) -> Curve:
    """The curve drawn ``factor`` times larger."""
    return Curve(points=curve.points * factor, length=curve.length * factor, source=curve.source,
                 strokes=curve.strokes)


def _pitch(apex_deg: float) -> float:
    """Centre-line step (design units) of a module of this final apex angle."""
    return LEG_RATIO * math.sin(math.radians(apex_deg) / 2)


@dataclass(frozen=True)
class _Plan:
    module_size: float
    scale: float            # mm per design unit
    min_joint: float        # design units
    low: float | None       # lowest apex angle with room for the screws, degrees

    @property
    def apexes(self) -> np.ndarray:
        hi = APEX_RANGE_DEG[1]
        return np.arange(hi, self.low - GRID_SLACK_DEG, -APEX_STEP_DEG)[::-1]

    @property
    def turn_deg(self) -> float:
        """The sharpest turn per two modules: the widest pair of angles on offer that
        neighbours may form."""
        hi = APEX_RANGE_DEG[1]
        return max(0.0, min(hi - self.low, 2.0 * (hi - MIN_PAIR_APEX_DEG)))


def chain_plan(module_size: float) -> dict:
    """What modules of this size can do: the scale, the joints' room in design units, the
    apex angles with that room, and the sharpest turn per two modules (degrees).

    Examples
    --------
    >>> p = chain_plan(50.0)
    >>> round(p["scale"], 2), p["lowest_apex_deg"], p["turn_deg"]
    (77.33, 51.0, 32.0)
    """
    p = _plan(module_size)
    return {"module_size": module_size, "scale": p.scale, "min_joint": p.min_joint,
            "lowest_apex_deg": p.low, "turn_deg": p.turn_deg if p.low is not None else 0.0}


def _plan(module_size: float) -> _Plan:
    scale = module_size / _pitch(REFERENCE_APEX_DEG)
    min_joint = MIN_JOINT_MM / scale
    low = lowest_apex(min_joint)
    if low is not None and low > REFERENCE_APEX_DEG:
        low = None  # not even a straight chain of the reference angle keeps its joints apart
    return _Plan(module_size, scale, min_joint, low)


def smallest_module_size() -> float:
    """The smallest module size (mm, to 0.1 mm) whose modules keep their joints
    ``MIN_JOINT_MM`` apart on a straight stretch (the reference apex angle has room)."""
    lo, hi = 1.0, 500.0
    while hi - lo > 0.05:
        mid = 0.5 * (lo + hi)
        if _plan(mid).low is None:
            lo = mid
        else:
            hi = mid
    return math.ceil(hi * 10) / 10


@dataclass(frozen=True)
class _Model:
    """A chain chosen in the zigzag model, before any module is designed."""

    plan: _Plan
    apexes: np.ndarray      # type apex angles, degrees
    types: np.ndarray       # per module
    centre: np.ndarray      # mm, the model's centre line fitted onto the curve
    errors: dict
    nodes: np.ndarray       # mm, the model's designed nodes (the zigzag), by the same fit

    def fits(self, tolerance: float, end_tolerance: float,
             nodes_tolerance: float | None = None) -> bool:
        e = self.errors
        return (e["mean_fraction"] <= tolerance and e["start_fraction"] <= end_tolerance
                and e["end_fraction"] <= end_tolerance
                and (nodes_tolerance is None or e["nodes_mean_fraction"] <= nodes_tolerance))


def _with_nodes(curve: Curve, model: _Model | None) -> _Model | None:
    """The model with the mean distance of its designed nodes to the curve in its errors
    (``nodes_mean_fraction``, of the curve's size)."""
    if model is None:
        return None
    near = polyline_distance(model.nodes, curve.points)
    errors = dict(model.errors, nodes_mean_fraction=float(near.mean()) / model.errors["size"])
    return _Model(model.plan, model.apexes, model.types, model.centre, errors, model.nodes)


def _model(curve: Curve, plan: _Plan, types, beam: int, stop=None) -> _Model | None:
    """The chain of the zigzag model for this plan: every module's apex angle chosen on the
    grid by the search, refined to any angle in the range, then binned into ``types`` types (or
    as few as keep the fit) and chosen again among the types, following the refined chain;
    None when no chain reaches the curve's end within ``MAX_MODULES``."""
    target = curve.points / plan.scale
    limit = min(MAX_MODULES, int(math.ceil(curve.length / (plan.scale * _pitch(plan.low))))
                + 4)
    kw = {"reference_deg": REFERENCE_APEX_DEG, "width": beam, "limit": limit, "stop": stop}
    hi = APEX_RANGE_DEG[1]
    turn = math.radians(plan.turn_deg)
    fastest = TURN_SHARE * turn / (_pitch(hi) + _pitch(hi - plan.turn_deg))
    fine = track(target, plan.apexes, LEG_RATIO, max_curvature=fastest, **kw)
    if fine.types.size == 0:
        return None
    # the search fixes the number of modules; one more or one fewer may fit the curve's
    # length better (a chain's pitch depends on its apex angles): each is refined, the best kept
    refined = None
    for start in _counts_around(fine.apexes):
        apexes_k, centre_k = refine(target, start, LEG_RATIO, low_deg=plan.low, high_deg=hi,
                                    stop=stop)
        fit_k = fit_to_curve(centre_k * plan.scale, curve.points)
        if refined is None or _worse(refined[2].errors, fit_k.errors):
            refined = (apexes_k, centre_k, fit_k)
    apexes, centre, fine_fit = refined
    counts = [int(types)] if types is not None else TYPE_COUNTS
    best = None
    for count in counts:
        bins = bin_apexes(apexes, count)
        if types is None and bins.size < count and best is not None:
            break  # the refined chain has no more distinct angles to bin
        # bins at the clusters' means, and with the extreme angles kept (the sharpest turn)
        found = [_binned(curve, plan, target, centre, b, beam, stop)
                 for b in (bins, bin_apexes(apexes, count, pin=True))]
        for model in found:
            if model is not None and (best is None or _worse(best.errors, model.errors)):
                best = model
        if types is None and best is not None and _as_good(best.errors, fine_fit.errors):
            return _with_nodes(curve, best)
    return _with_nodes(curve, best)


def _counts_around(apexes: np.ndarray) -> list[np.ndarray]:
    """The search's apex angles, and the same with the last module dropped or one more added
    (a copy of the module two back, so that the zigzag keeps its rhythm)."""
    out = [apexes]
    if apexes.size > 2:
        out.append(apexes[:-1])
    if apexes.size >= 2:
        out.append(np.append(apexes, apexes[-2]))
    return out


def _binned(curve, plan, target, centre, bins, beam, stop) -> _Model | None:
    """The refined chain reproduced with the binned types only: each module's type chosen to
    follow the refined chain point by point, then the bins' angles refitted to the curve with
    the types held, and the types chosen again (``BIN_ROUNDS`` times)."""
    hi = APEX_RANGE_DEG[1]
    types = follow(centre, bins, LEG_RATIO, width=beam, stop=stop)
    if types.size == 0:
        return None

    def measured(bins, types):
        nodes = strip_nodes(bins[types], LEG_RATIO, start=target[0],
                            heading=_first_heading(target, bins[types]))
        f = fit_to_curve(0.5 * (nodes[:-1] + nodes[1:]) * plan.scale, curve.points)
        return _Model(plan, bins, types, f.points, f.errors, f.apply(nodes * plan.scale))

    best = measured(bins, types)
    for _ in range(BIN_ROUNDS):
        bins = refit_bins(target, bins, types, LEG_RATIO, low_deg=plan.low, high_deg=hi,
                          stop=stop)
        types = follow(centre, bins, LEG_RATIO, width=beam, stop=stop)
        if types.size == 0:
            break
        model = measured(bins, types)
        if _worse(best.errors, model.errors):
            best = model
    # bins the refit brought within MERGE_DEG of each other become one type, unless that
    # costs more than MERGE_SLACK of the fit
    merged_bins, merged_types = _merged(best.apexes, best.types)
    if merged_bins.size < best.apexes.size:
        model = measured(merged_bins, merged_types)
        if _badness(model.errors) <= MERGE_SLACK * _badness(best.errors):
            best = model
    used = np.unique(best.types)
    remap = np.full(best.apexes.size, -1)
    remap[used] = np.arange(used.size)
    return _Model(plan, best.apexes[used], remap[best.types], best.centre, best.errors,
                  best.nodes)


def _first_heading(target, apexes) -> float:
    """The start heading that lays a chain's first point on the curve's start and its second
    near the curve (the fit moves it onto the curve anyway)."""
    first = strip_centreline(apexes[:2], LEG_RATIO)
    r = float(np.linalg.norm(first[1] - first[0]))
    p = point_at(target, arclength(target), r) - target[0]
    return math.atan2(p[1], p[0])


def _badness(e: dict) -> float:
    """A fit's errors against the tolerances (the mean, and the worse end, against theirs)."""
    return max(e["mean_fraction"] / FIT_TOLERANCE,
               max(e["start_fraction"], e["end_fraction"]) / END_TOLERANCE)


def _worse(a: dict, b: dict) -> bool:
    """Is fit ``a`` worse than fit ``b``?"""
    return _badness(a) > _badness(b)


def _merged(bins: np.ndarray, types: np.ndarray):
    """Bins within ``MERGE_DEG`` of their neighbour (in angle) joined into one, at the mean
    of the modules they hold; the types renumbered."""
    order = np.argsort(bins)
    groups, current = [], [order[0]]
    for i in order[1:]:
        if bins[i] - bins[current[-1]] <= MERGE_DEG:
            current.append(i)
        else:
            groups.append(current)
            current = [i]
    groups.append(current)
    label = np.empty(bins.size, dtype=int)
    new = np.empty(len(groups))
    for g, members in enumerate(groups):
        label[members] = g
        counts = np.array([np.sum(types == m) for m in members], dtype=float)
        new[g] = float(np.average(bins[members], weights=counts + EMPTY_BIN_WEIGHT))
    return new, label[types]


def _as_good(binned: dict, fine: dict) -> bool:
    ends = max(binned["start_fraction"], binned["end_fraction"])
    fine_ends = max(fine["start_fraction"], fine["end_fraction"])
    mean_ok = (binned["mean_fraction"] <= BIN_SLACK * fine["mean_fraction"]
               or binned["mean_fraction"] <= BIN_GOOD * FIT_TOLERANCE)
    ends_ok = ends <= BIN_SLACK * fine_ends or ends <= BIN_GOOD * END_TOLERANCE
    return mean_ok and ends_ok


def _say(progress, text: str) -> None:
    if progress is not None:
        progress(text)


def tightest_radius() -> float:
    """The tightest radius (mm) a chain of curvature modules turns along, over every module
    size: 2 m / (sharpest turn per two modules) at module size m, least over the sizes from
    :func:`smallest_module_size` up to ``RADIUS_SIZES_TO`` mm. Small modules leave the
    narrow apex angles no room for the screws (9.5 mm apart) and large ones turn over a long
    stretch, so it is about 125 mm whatever the size: a drawing that turns tighter (a corner,
    a petal's tip) is cut there, and only an enlargement brings it within the tolerance."""
    return _tightest()[0]


@lru_cache(maxsize=1)
def _tightest() -> tuple[float, float]:
    best = (math.inf, math.nan)
    m = smallest_module_size()
    while m <= RADIUS_SIZES_TO:
        turn = _plan(m).turn_deg
        if turn > 0:
            best = min(best, (2.0 * m / math.radians(turn), m))
        m = round(m + RADIUS_SIZE_STEP, 6)
    return best


def curve_radius(points, size: float) -> float:
    """The tightest radius of curvature (mm) of a drawn curve, measured over ``window``-long
    chords (:func:`needed_turn`) with a window of ``RADIUS_WINDOW`` of its size: about the
    radius of its sharpest round, and a few windows for a corner."""
    window = RADIUS_WINDOW * size
    turn = needed_turn(points, window)
    return 2.0 * window / turn if turn > 0 else math.inf


def _node_offset(module_size: float) -> float:
    """How far (mm) the designed nodes of a straight stretch of modules of this size lie from
    its centre line at the widest apex angle on offer (half the height of its triangle, legs
    D2*): about the least mean distance of a chain's nodes to the curve it follows (every node
    is a port's end, half a module's width off the centre line)."""
    hi = math.radians(APEX_RANGE_DEG[1])
    return 0.5 * LEG_RATIO * math.cos(hi / 2) * _plan(module_size).scale


def _nearest(curve: Curve, module_size: float, types, beam: int, tolerance: float,
             end_tolerance: float, progress, stop) -> str | None:
    """The nearest wish that builds: a smaller module size at the drawing's own size, else the
    least enlargement of the drawing, at this module size and at ``TIGHT_SIZE_FACTOR`` of it
    (smaller modules cut a sharp turn more closely, and their nodes lie closer to the curve);
    the least of them is named. Each is found in the zigzag model first (cheap), fitting within
    ``SUGGEST_SHARE`` of the tolerances (a suggestion is not a knife edge): its centre line and
    ends within the tolerances and its designed nodes within ``NODES_TOLERANCE`` of the
    drawing's size on average; it is then designed in full and measured on the drawing
    (:func:`~fabkit.design.drawing_fit.fit_final_state`, the same three criteria): the
    suggestion is one that was built and measured."""
    share = (SUGGEST_SHARE * tolerance, SUGGEST_SHARE * end_tolerance,
             NODES_SHARE * NODES_TOLERANCE)

    def builds(c, m) -> bool:
        _say(progress, f"trying --module-size {m:g}" + (
            "" if c is curve else f" with the drawing {c.length / curve.length:.4g}x larger"))
        try:
            design = design_curve_chain(c, module_size=m, types=types, beam=beam,
                                        tolerance=share[0], end_tolerance=share[1],
                                        progress=None, _suggest=False, _stop=stop)
        except FabkitError:
            return False
        drawn = design.report["drawing_fit_percent_of_size"]
        return (drawn["mean"] <= 100 * share[0] and drawn["nodes_mean"] <= 100 * share[2]
                and max(drawn["start"], drawn["end"]) <= 100 * share[1])

    def model(c, m) -> _Model | None:
        if c.length < 2 * m or c.length / m > MAX_MODULES:
            return None
        plan = _plan(m)
        if plan.low is None:
            return None
        return _model(c, plan, types, beam, stop)

    smallest = smallest_module_size()
    size = curve_size(curve.points)
    # smaller modules at the drawing's own size: they cut corners and sharp turns more
    # closely (down to the tightest radius any module turns along, tightest_radius()); none
    # whose nodes lie too far off the centre line for this drawing is modelled
    for f in SIZE_FACTORS:
        m = float(f"{module_size * f:.3g}")
        if m < smallest:
            break
        if NODE_BOUND_SLACK * _node_offset(m) > share[2] * size:
            continue
        _say(progress, f"modelling --module-size {m:g}")
        found = model(curve, m)
        if found is not None and found.fits(*share) and builds(curve, m):
            return f"--module-size {m:g}"
    # enlargements, smallest modules first (they follow sharp turns more closely, and their
    # nodes lie closer to the curve, so the drawing grows less) and at this size
    floor = float(f"{TIGHT_SIZE_FLOOR * smallest:.3g}")
    tight = float(f"{max(TIGHT_SIZE_FACTOR * module_size, floor):.3g}")
    sizes = sorted({m for m in (floor, tight) if m < module_size} | {module_size})
    found = []
    for m in sizes:
        below = min(found)[0] if found else math.inf
        factor = _least_enlargement(curve, m, model, share, progress, below)
        if factor is not None:
            found.append((factor, -m))
    for factor, neg_m in sorted(found):
        m = -neg_m
        if builds(scaled(curve, factor), m):
            if m == module_size:
                return f"--curve-scale {factor:g} (the drawing {factor:g}x larger)"
            return (f"--curve-scale {factor:g} --module-size {m:g} (the drawing {factor:g}x "
                    "larger)")
    return None


def _least_enlargement(curve: Curve, module_size: float, model, share, progress,
                       below: float = math.inf) -> float | None:
    """The least enlargement (two digits) of the drawing whose chain of this module size fits
    in the zigzag model within ``share`` (mean, ends, nodes): from the one where the curve turns
    no faster than ``TURN_SHARE`` of what the modules turn (or 1.25 for a corner), and where
    its nodes (:func:`_node_offset` off the centre line) lie close enough, up by 1.2 until one
    fits (straight to the enlargement the measured nodes ask when they alone miss: their
    distance in mm hardly changes with the drawing's size), then bisected down toward the last
    that did not (a sharp turn cut within the tolerance needs less). None when none fits, or
    none below ``below`` (an enlargement already found at another module size)."""
    plan = _plan(module_size)
    if plan.low is None:
        return None
    give = math.radians(TURN_SHARE * plan.turn_deg)
    lo, hi = 1.0, MAX_CURVE_SCALE
    if needed_turn(curve.points * hi, module_size) <= give:
        while hi / lo > 1.02:
            mid = math.sqrt(lo * hi)
            if needed_turn(curve.points * mid, module_size) <= give:
                hi = mid
            else:
                lo = mid
        start = hi
    else:  # a corner: no enlargement makes it a curve; cut it, relatively smaller
        start = 1.25
    # the curve at least two modules long, and large enough for the nodes
    size = curve_size(curve.points)
    least = max(1.0, 2.0 * module_size / curve.length,
                NODE_BOUND_SLACK * _node_offset(module_size) / (share[2] * size))
    factor = _round_up(max(start, least, _node_offset(module_size) / (share[2] * size)))
    if factor >= below:
        return None

    def fits(f):
        _say(progress, f"modelling --curve-scale {f:g} --module-size {module_size:g}")
        return model(scaled(curve, f), module_size)

    def nodes_need(f, got) -> float:
        # the nodes' distance (mm) stays as the drawing grows: below this they miss
        return f * got.errors["nodes_mean_fraction"] / share[2] / NODE_JUMP

    failed = max(least, factor / BISECT_RANGE)
    for _ in range(SCALE_TRIES):
        if factor > MAX_CURVE_SCALE or factor >= below or curve.length * factor / \
                module_size > min(MAX_MODULES, max(MAX_SUGGEST_MODULES, SUGGEST_GROWTH *
                                                   curve.length / module_size)):
            return None
        got = fits(factor)
        if got is not None and got.fits(*share):
            failed = max(failed, nodes_need(factor, got))
            break
        failed = factor
        if got is not None and got.fits(share[0], share[1]):  # the nodes alone miss
            failed = max(failed, nodes_need(factor, got))
            factor = _round_up(max(failed * NODE_JUMP ** 2, factor * NODE_JUMP))
        else:
            factor = _round_up(factor * 1.2)
    else:
        return None
    # bisect (in ratio) between the last that failed (or a lower bound) and the first that fit
    for _ in range(BISECT_STEPS):
        mid = _round_up(math.sqrt(failed * factor))
        if mid >= factor or mid <= failed:
            break
        got = fits(mid)
        if got is not None and got.fits(*share):
            factor = mid
        else:
            failed = max(mid, nodes_need(mid, got)) if got is not None else mid
    return factor


def _round_up(x: float) -> float:
    """``x`` rounded up to two significant digits (a scale a maker types)."""
    e = math.floor(math.log10(x)) - 1
    return math.ceil(x / 10 ** e - ROUND_SLACK) * 10 ** e if x > 0 else x


def _check_arguments(curve, module_size, types) -> Curve:
    if not isinstance(curve, Curve):
        curve = resampled_curve(np.asarray(curve, dtype=np.float64), "points", 1)
    if not (isinstance(module_size, (int, float)) and math.isfinite(module_size)
            and module_size > 0):
        raise WishError(f"--module-size {module_size}", "must be a positive number of mm")
    if types is not None and (isinstance(types, bool) or not isinstance(types, (int, np.integer))
                              or not 1 <= int(types) <= MAX_TYPES):
        raise WishError(f"--types {types}", f"must be a whole number from 1 to {MAX_TYPES}")
    return curve


def design_curve_chain(curve, *, module_size: float = 50.0, types: int | None = None,
                       name: str = "curve", beam: int = BEAM_WIDTH,
                       tolerance: float = FIT_TOLERANCE, end_tolerance: float = END_TOLERANCE,
                       progress=None, _suggest: bool = True, _stop=None) -> CurveDesign:
    """Design a chain of curvature modules whose final state follows ``curve``.

    Parameters
    ----------
    curve : Curve or array_like, shape (M, 2)
        The curve in mm (from :func:`read_curve`, or points).
    module_size : float
        mm per module along the curve (the step of a module of the reference apex angle).
    types : int, optional
        Number of module types (1 to ``MAX_TYPES``); default: as few as keep the fit.
    name : str
        Stem of the written templates.
    beam : int
        Partial chains kept per module by the search.
    tolerance, end_tolerance : float
        Largest mean distance of the chain's centre line to the curve, and of each end to the
        curve's end, as fractions of the curve's size.
    progress : callable, optional
        Called with a line of text at each stage of a long search (suggestions).

    Returns
    -------
    CurveDesign

    Raises
    ------
    WishError
        The module size is below the smallest whose joints keep apart, the curve is shorter
        than two modules or needs more than ``MAX_MODULES``, or no chain of these modules
        follows it within the tolerance; the nearest module size (or enlargement of the
        drawing) that builds is named.
    """
    start = time.perf_counter()
    curve = _check_arguments(curve, module_size, types)
    pts = curve.points
    wish = f"--curve with --module-size {module_size:g}"

    def refuse(why: str) -> WishError:
        """The refusal, with the nearest wish that builds and what it was held to."""
        nearest = _nearest(curve, module_size, types, beam, tolerance, end_tolerance,
                           progress, _stop) if _suggest else None
        if nearest:
            why += (f"; the nearest wish traced keeps the chain's port midpoints within "
                    f"{100 * tolerance:g} % of the drawing's size on average (ends "
                    f"{100 * end_tolerance:g} %) and its designed nodes within "
                    f"{100 * NODES_TOLERANCE:g} %")
        return WishError(wish, why, nearest)

    smallest = smallest_module_size()
    if module_size < smallest:
        raise refuse(f"modules under {smallest:g} mm cannot keep their joints "
                     f"{MIN_JOINT_MM:g} mm apart (Chicago screw heads); module sizes from "
                     f"{smallest:g} mm to {curve.length / 2:.4g} mm (half the curve) build")
    if curve.length < 2 * module_size:
        fit = (f"module sizes from {smallest:g} mm to {curve.length / 2:.4g} mm (half the "
               "curve) fit it" if curve.length >= 2 * smallest else
               f"even the smallest modules ({smallest:g} mm) need a curve of at least "
               f"{2 * smallest:g} mm")
        raise refuse(f"the curve ({curve.length:.4g} mm) is shorter than two modules; {fit}")
    if curve.length / module_size > MAX_MODULES:
        raise WishError(wish, f"the curve ({curve.length:.0f} mm) needs more than {MAX_MODULES} "
                              f"modules of {module_size:g} mm; module sizes from "
                              f"{curve.length / MAX_MODULES:.3g} mm build it")
    plan = _plan(module_size)
    _say(progress, f"following the curve with modules of {module_size:g} mm (apex angles "
                   f"{plan.low:g}-{APEX_RANGE_DEG[1]:g} deg)")
    model = _model(curve, plan, types, beam, _stop)
    turn = math.degrees(needed_turn(pts, module_size))
    if model is None or not model.fits(tolerance, end_tolerance):
        e = model.errors if model is not None else None
        why = (f"the curve turns by {turn:.1f} deg within two modules "
               f"({2 * module_size:g} mm); modules of {module_size:g} mm turn a chain by at "
               f"most {plan.turn_deg:g} deg per two")
        sharp, tightest = curve_radius(pts, curve_size(pts)), tightest_radius()
        if sharp < tightest:
            why += (f"; its sharpest turn has a radius of about {sharp:.3g} mm, and no module "
                    f"size turns a chain tighter than {tightest:.0f} mm (the narrow apex "
                    f"angles need room for screws {MIN_JOINT_MM:g} mm apart), so the chain "
                    "cuts it")
        if e is not None:
            why += (f", and the closest chain misses it by {100 * e['mean_fraction']:.2g} % of "
                    f"its size on average (ends {100 * e['start_fraction']:.2g} % / "
                    f"{100 * e['end_fraction']:.2g} %; accepted: {100 * tolerance:g} %, ends "
                    f"{100 * end_tolerance:g} %)")
        raise refuse(why)
    # the module types, designed with their joints MIN_JOINT_MM apart at the kit's scale
    designed = []
    for apex in model.apexes:
        try:
            designed.append(design_curvature_type(float(apex), plan.min_joint))
        except DesignError as exc:
            raise refuse(f"no curvature module of {module_size:g} mm with final apex "
                         f"{apex:.4g} deg keeps its joints {MIN_JOINT_MM:g} mm apart "
                         f"({exc})") from None
    files = {f"{name}_m{j + 1}.toml": curvature_template(f"{name}_m{j + 1}", t)
             for j, t in enumerate(designed)}
    nets = {f: parse_template(text, f"<{f}>").network for f, text in files.items()}
    modules = curvature_modules(nets, LEG_RATIO)
    names = [modules[t].name for t in model.types]
    net = chain([nets[n] for n in names], mirror="alternate")
    traj = trace(net, "d1", to=LEG_RATIO, method="constructive", samples=2)
    if not traj.success:
        raise DesignError(f"the designed chain does not reach its final state: {traj.message}")
    k = len(names)
    center_units = chain_centerline(net, traj.positions[-1], k)
    fit = fit_to_curve(center_units * plan.scale, pts)
    final = fit.apply(traj.positions[-1] * plan.scale)
    center = fit.points
    errors = dict(fit.errors)
    ports = np.array([net.port(f"d{i}") for i in range(1, k + 2)])
    zigzag = final[np.unique(ports)]
    nodes = polyline_distance(zigzag, pts)
    errors["nodes_mean"], errors["nodes_max"] = float(nodes.mean()), float(nodes.max())
    errors["nodes_mean_fraction"] = errors["nodes_mean"] / errors["size"]
    props = {"curve": describe_curve(pts), "chain": describe_curve(center)}
    drawn = fit_final_state(net, traj.positions[-1] * plan.scale, k, pts)
    counts = {n: names.count(n) for n in files}
    report = {
        "curve": {"source": curve.source, "length_mm": curve.length, "strokes": curve.strokes,
                  "size_mm": errors["size"], "sharpest_turn_deg_per_two_modules": turn},
        "module_size_mm": module_size, "scale_mm_per_unit": plan.scale, "modules": k,
        "reference_apex_deg": REFERENCE_APEX_DEG,
        "apex_range_deg": [plan.low, APEX_RANGE_DEG[1]],
        "sharpest_chain_turn_deg_per_two_modules": plan.turn_deg,
        "types": [{"template": f, "final_apex_deg": math.degrees(t.apex), "count": counts[f],
                   "margins": t.margins} for f, t in zip(files, designed)],
        "fit_error_mm": {k2: v for k2, v in errors.items() if not k2.endswith("_fraction")},
        "fit_error_fraction_of_size": {k2[:-9]: v for k2, v in errors.items()
                                       if k2.endswith("_fraction")},
        "tolerance": {"mean_fraction": tolerance, "end_fraction": end_tolerance},
        "model_fit_fraction_of_size": {k2[:-9]: v for k2, v in model.errors.items()
                                       if k2.endswith("_fraction")},
        "proportions": props,
        "drawing_fit_percent_of_size": drawn.percent(),
        "trace": {"method": traj.method, "status": str(traj.status),
                  "max_edge_error": float(traj.max_edge_error)},
        "seconds": time.perf_counter() - start,
    }
    files[f"{name}.toml"] = chain_template(name, names, plan.scale, errors, props, curve,
                                           module_size)
    return CurveDesign(curve=curve, types=designed, names=names, network=net, scale=plan.scale,
                       module_size=module_size, centerline=center, final=final, errors=errors,
                       proportions=props, templates=files, report=report)

