"""Designing a module from its map: fixed points, their slope, a 2-cycle.

The paper's construction (supplement, "Elaborating on Single Module Design"): the designed nodes
0, 1, 2 form a triangle with d1 = |x0 - x1| and d2 = |x1 - x2|; at a wished fixed point D* both
legs are D*. Their velocities there fix the slope of the map (d1 changes at rate 1, d2 at rate s);
their positions at a second state (legs D2*, or the swapped legs of a 2-cycle) fix a second point
of the map. Each specification puts a variable node on a conic
(:mod:`fabkit.design.solution_space`); two variable nodes on the intersection of two conics meet
both, two on one conic meet that one.

What the construction leaves free is chosen for a module that can be built:

* the apex angle of each designed triangle, and the turn of the designed velocity (how fast the
  apex angle opens), from a small grid;
* which intersection points (two specifications) or which points of the conic (one) carry the
  variable nodes.

Every candidate is screened at its reference (one motion, no state of self-stress, bar-length
ratio, joint separation, conditioning of the rigidity matrix), then the best are verified with
:func:`fabkit.module_map` (each wish met to 1e-9 on the branch through the reference, the second
state reached on that branch) and scored over the designed motion (the smallest conditioning and
joint separation along it, the bar-length ratio, the shift of each fixed point per unit of
bar-length error, no fixed point that was not asked for).
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from ..errors import DesignError, FabkitError
from ..io.outputs import write_atomic
from ..templates import Design, parse_template
from ..model.network import Network
from ..numerics import TINY
from .branch import branch_margins, MIN_BRANCH_MARGIN, on_branch
from .geometry import (bar_lengths, branch_signs, fixed_point_gain, joint_separation, MODULE_EDGES,
                       module_positions, rigidity_margin, slope_velocities, triangle)
from .robustness import check_builds
from .solution_space import displacement_space, velocity_space
from .toml_text import module_template
from .wishes import check_wish, FixedPointWish, MapWish, WishError

__all__ = ["MapDesign", "design_map", "branch_margins", "on_branch", "APEX_DEGREES", "TURNS", "FREE_SLOPES",
           "MIN_BRANCH_MARGIN"]

#: Apex angles (degrees) tried for each designed triangle.
APEX_DEGREES = (45.0, 60.0, 75.0, 90.0, 105.0, 120.0)
#: Turns of the designed velocity tried (node 2's speed across its leg per unit rate of d1).
TURNS = (-1.0, -0.5, 0.0, 0.5, 1.0)
#: Slopes tried at a fixed point wished without one: a stable point, of either sign.
FREE_SLOPES = (0.5, -0.5)
#: Rays cast from the designed triangle's centroid to find points of a single conic.
CONIC_RAYS = 24
#: Candidate points of a conic farther than this many wished distances from the centroid are
#: not used (their bars would dwarf the module).
CONIC_RADIUS = 2.5
#: Largest bar-length ratio within a module (longest / shortest bar).
MAX_BAR_RATIO = 4.0
#: Least distance between two joints, as a fraction of the module's designed distance, along
#: the whole designed motion (a screw head and its spacer need room: 14.2 mm at 100 mm/unit).
MIN_SEPARATION = 0.12
#: Joint separations above this fraction count as fully comfortable in the score.
GOOD_SEPARATION = 0.3
#: Least conditioning (smallest non-zero singular value of the row-normalised rigidity matrix)
#: along the designed motion: below it the module is close to a flat state.
MIN_RIGIDITY = 0.03
#: Candidates per specification kept from the screen, and candidates verified in all.
KEEP_PER_SPEC = 3
VERIFY_LIMIT = 48
#: Finalists checked for fixed points that were not asked for.
FINALISTS = 6
#: A wish is met when the map misses it by at most this, relative to the wished distance
#: (the issue asks 1e-8; exact intersections leave ~1e-15).
WISH_RTOL = 1e-9
#: Slopes are met to this absolute error (exact derivatives leave ~1e-13).
SLOPE_ATOL = 1e-9
#: Half-width of the motion window scored around a lone fixed point (fraction of D*).
WINDOW = 0.15
#: Configurations sampled along the designed motion for the scores.
MOTION_SAMPLES = 25
#: A fixed point of the map farther than this (relative) from every wished one is an extra.
EXTRA_RTOL = 1e-6
#: Between two wished fixed points the map must leave the diagonal by at least this fraction
#: of their distance (else it hugs d2 = d1 and nearly every state between is a fixed point);
#: bulges above GOOD_BULGE count as fully clear in the score.
MIN_BULGE = 0.01
GOOD_BULGE = 0.1
#: Grid on which extra fixed points are bracketed (sign changes of f(d) - d).
EXTRA_GRID = 2001
#: A wished slope nearer ±1 than this (in |slope|) is nearly neutral: its fixed point moves
#: by the bars' errors over (1 - slope), and a nearest wish may ease it toward ±NEAR_NEUTRAL.
NEAR_NEUTRAL = 0.5


@dataclass(frozen=True)
class _Spec:
    """One way of using the construction's free choices: designed nodes, what they do."""

    designed: np.ndarray
    velocities: np.ndarray | None
    finals: tuple  # final positions of the designed nodes, one array per further state
    choices: dict


@dataclass
class _Candidate:
    spec: _Spec
    variable: np.ndarray
    screen: float
    points: tuple = ()          # which intersection points / conic samples
    score: float = -1.0
    metrics: dict = field(default_factory=dict)
    fmap: object = None


@dataclass(frozen=True, eq=False)
class MapDesign(Design):
    """A module designed from map wishes: a :class:`~fabkit.Design` (trace it, chain its
    network, export it, save it) that also carries what its design found.

    Unpacking gives the same object and its report, ``design, report = fabkit.design_map(...)``,
    so ``design`` has every attribute below whether the result was unpacked or not.

    Attributes
    ----------
    report : dict
        The wishes, what the map recomputed by :func:`fabkit.module_map` gives for each (value,
        residual, slope), every fixed point and 2-cycle of the branch, the free choices made and
        the buildability measures; JSON-ready.
    template : str
        The template text (TOML, commented): what :meth:`save` writes.
    map : Map1D
        The designed module's map on the branch through its reference.
    wish : MapWish
    design : MapDesign
        The object itself (the design it is).

    Examples
    --------
    >>> design, report = design_map([(1.6, 0.0), 1.1])
    >>> design.map.fixed_points()[0].value == report["map"]["fixed_points"][0]["value"]
    True
    >>> design.design is design, design.network.n_nodes
    (True, 5)
    """

    report: dict = field(default_factory=dict)
    template: str = ""
    map: object = None
    wish: MapWish | None = None

    @classmethod
    def of(cls, design: Design, **found) -> "MapDesign":
        """The design parsed from the designer's template, with what the design found."""
        return cls(**{f.name: getattr(design, f.name) for f in fields(Design)}, **found)

    @property
    def design(self) -> "MapDesign":
        return self

    def save(self, path) -> Path:
        """Write :attr:`template` (the commented template) to ``path``; returns the path.
        Written whole or not at all, and a failure names the file
        (:func:`fabkit.io.outputs.write_atomic`)."""
        path = Path(path)
        write_atomic(path, self.template.encode("utf-8"))
        return path

    def __iter__(self):
        return iter((self, self.report))


def _specs(wish: MapWish) -> list[_Spec]:
    """Every combination of the free choices for this wish."""
    apex = [math.radians(a) for a in APEX_DEGREES]
    fps, cyc = list(wish.fixed_points), wish.cycle
    out = []
    if cyc is None:
        first = fps[0]
        slopes = FREE_SLOPES if first.slope is None else (first.slope,)
        second = fps[1] if len(fps) > 1 else None
        for a0 in apex:
            x0 = triangle(first.value, first.value, a0)
            finals_sets = [((), {})]
            if second is not None:
                finals_sets = [((triangle(second.value, second.value, a1),),
                                {"apex_final_deg": math.degrees(a1)}) for a1 in apex]
            for s in slopes:
                for t in TURNS:
                    v = slope_velocities(x0, s, t)
                    for finals, extra in finals_sets:
                        out.append(_Spec(x0, v, finals, {"apex_deg": math.degrees(a0),
                                                         "slope_designed": s, "turn": t, **extra}))
        return out
    a, b = cyc
    for a0, a1 in itertools.product(apex, apex):
        if a0 == a1:  # the swapped triangle would be a mirror image: no condition at all
            continue
        x0 = triangle(a, b, a0)
        finals = [triangle(b, a, a1)]
        choices = {"apex_deg": math.degrees(a0), "apex_final_deg": math.degrees(a1)}
        if fps:
            for a2 in apex[1::2]:
                out.append(_Spec(x0, None, (finals[0], triangle(fps[0].value, fps[0].value, a2)),
                                 {**choices, "apex_fixed_deg": math.degrees(a2)}))
        else:
            out.append(_Spec(x0, None, tuple(finals), choices))
    return out


def _spaces(spec: _Spec):
    spaces = []
    if spec.velocities is not None:
        spaces.append(velocity_space(spec.designed, spec.velocities))
    for f in spec.finals:
        spaces.append(displacement_space(spec.designed, f))
    return spaces


def module_positions_batch(designed, pairs) -> np.ndarray:
    """Configurations (P, 5, 2) of designed nodes (3, 2) with variable-node pairs (P, 2, 2)."""
    return np.concatenate([np.broadcast_to(designed, (pairs.shape[0], 3, 2)), pairs], axis=1)


def _screen(designed, pairs, size):
    """Screen score of variable-node pairs (P, 2, 2) at the reference; -1 where refused."""
    x = module_positions_batch(designed, pairs)
    lengths = bar_lengths(x)
    ratio = lengths.max(axis=1) / np.maximum(lengths.min(axis=1), TINY)
    sep = joint_separation(x) / size
    rig = rigidity_margin(x)
    score = rig * np.minimum(1.0, sep / GOOD_SEPARATION) / ratio
    bad = (ratio > MAX_BAR_RATIO) | (sep < MIN_SEPARATION) | (rig < MIN_RIGIDITY)
    return np.where(bad, -1.0, score)


def _candidates(spec: _Spec, size: float) -> list[_Candidate]:
    try:
        spaces = _spaces(spec)
    except DesignError:  # a specification that puts no condition (a rigid designed motion)
        return []
    if len(spaces) == 2:
        pts = spaces[0].intersect(spaces[1])
        combos = list(itertools.combinations(range(len(pts)), 2))
    else:
        pts = spaces[0].sample(CONIC_RAYS, radius=CONIC_RADIUS * size)
        combos = list(itertools.combinations(range(len(pts)), 2))
    if not combos:
        return []
    idx = np.array(combos)
    pairs = pts[idx]
    score = _screen(spec.designed, pairs, size)
    # every further designed state must lie on the branch of the first: same orientation of
    # each triangle that can only flip through a flat state
    start = branch_signs(module_positions_batch(spec.designed, pairs))
    for space, final in zip([s for s in spaces if s.kind == "displacement"], spec.finals):
        moved = space.partner(pairs.reshape(-1, 2)).reshape(pairs.shape)
        same = np.all(branch_signs(module_positions_batch(final, moved)) == start, axis=1)
        score = np.where(same, score, -1.0)
    order = np.argsort(-score)[:KEEP_PER_SPEC]
    return [_Candidate(spec, pairs[k], float(score[k]), tuple(int(i) for i in idx[k]))
            for k in order if score[k] > 0]


def _ports():
    return {"d1": (0, 1), "d2": (1, 2)}


def _wished_values(wish: MapWish) -> list[float]:
    vals = [p.value for p in wish.fixed_points]
    if wish.cycle is not None:
        vals += list(wish.cycle)
    return vals


def _motion_range(wish: MapWish, domain) -> tuple[float, float]:
    vals = _wished_values(wish)
    lo, hi = min(vals), max(vals)
    if lo == hi:
        lo, hi = lo * (1 - WINDOW), hi * (1 + WINDOW)
    return max(lo, domain[0]), min(hi, domain[1])


def _meets(fmap, wish: MapWish) -> dict | None:
    """Residuals of every wish on the map's branch, or None when one is not met."""
    lo, hi = fmap.domain
    out = {"fixed_points": [], "cycle": None}
    for p in wish.fixed_points:
        if not lo <= p.value <= hi:
            return None
        fv, s = fmap(p.value), fmap.derivative(p.value)
        r = abs(fv - p.value)
        if r > WISH_RTOL * p.value:
            return None
        if p.slope is not None and abs(s - p.slope) > SLOPE_ATOL * max(1.0, abs(p.slope)):
            return None
        out["fixed_points"].append({"value": p.value, "wished_slope": p.slope,
                                    "residual": r, "slope": s})
    if wish.cycle is not None:
        a, b = wish.cycle
        if not (lo <= a <= hi and lo <= b <= hi):
            return None
        ra, rb = abs(fmap(a) - b), abs(fmap(b) - a)
        if max(ra, rb) > WISH_RTOL * max(a, b):
            return None
        out["cycle"] = {"values": [a, b], "residuals": [ra, rb],
                        "multiplier": fmap.derivative(a) * fmap.derivative(b)}
    return out


def _verify(c: _Candidate, wish: MapWish, size: float) -> bool:
    from ..maps import module_map
    from ..model.rigidity import count_modes

    net = Network(module_positions(c.spec.designed, c.variable), MODULE_EDGES, ports=_ports())
    modes = count_modes(net)
    if modes.conformational != 1 or modes.self_stress != 0 or modes.ambiguous:
        return False
    try:
        fmap = module_map(net)
    except FabkitError:
        return False
    met = _meets(fmap, wish)
    if met is None:
        return False
    lo, hi = _motion_range(wish, fmap.domain)
    xs = fmap.configuration(np.linspace(lo, hi, MOTION_SAMPLES))
    rig = float(rigidity_margin(xs).min())
    sep = float(joint_separation(xs).min()) / size
    lengths = bar_lengths(net.nodes)
    ratio = float(lengths.max() / lengths.min())
    if rig < MIN_RIGIDITY or sep < MIN_SEPARATION:
        return False
    gains = [fixed_point_gain(fmap.configuration(p.value)) for p in wish.fixed_points]
    finite = [g for g in gains if math.isfinite(g)]
    gain = max(finite) if finite else 0.0
    vals = _wished_values(wish)
    margins = branch_margins(fmap, vals)
    if min(m["fraction"] for m in margins) < MIN_BRANCH_MARGIN:
        return False  # a wished state next to a fold: builds lose it (see robustness.py)
    edge = min(m["margin"] for m in margins) / size
    bulge = 1.0
    if len(wish.fixed_points) == 2:
        # between two fixed points the map must leave the diagonal, or every state between
        # them is nearly a fixed point too (a map that hugs d2 = d1)
        a, b = sorted(p.value for p in wish.fixed_points)
        inner = np.linspace(a, b, MOTION_SAMPLES)[1:-1]
        bulge = float(np.max(np.abs(fmap._values(inner)[0] - inner))) / (b - a)
        if bulge < MIN_BULGE:
            return False
    c.score = (rig * min(1.0, sep / GOOD_SEPARATION) / ratio / math.sqrt(1.0 + gain)
               * min(1.0, edge / WINDOW) * min(1.0, bulge / GOOD_BULGE))
    c.metrics = {"rigidity_margin": rig, "map_bulge": bulge, "joint_separation": sep * size,
                 "bar_length_ratio": ratio, "bar_lengths": [float(v) for v in lengths],
                 "fixed_point_gains": gains, "branch_margin": edge * size,
                 "branch_margins": margins, "met": met}
    c.fmap = fmap
    return True


def _extras(fmap, wish: MapWish) -> list[float]:
    """Fixed points of the branch that were not asked for: sign changes of f(d) - d on a grid,
    refined by Brent's method (a cycle's branch must cross the diagonal between its values:
    that one fixed point is implied, not extra)."""
    from scipy.optimize import brentq

    wished = [p.value for p in wish.fixed_points]
    lo, hi = fmap.domain
    grid = np.linspace(lo, hi, EXTRA_GRID)
    g = fmap._values(grid)[0] - grid
    found = []
    for k in np.flatnonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0):
        x = brentq(lambda t: float(fmap._values(t)[0]) - t, grid[k], grid[k + 1])
        if all(abs(x - w) > EXTRA_RTOL * w for w in wished):
            found.append(float(x))
    if wish.cycle is not None and not wished:
        a, b = sorted(wish.cycle)
        between = [x for x in found if a < x < b]
        if between:
            found.remove(between[0])
    return found


def _search(wish: MapWish):
    size = float(np.mean(_wished_values(wish)))
    cands = []
    specs = _specs(wish)
    for spec in specs:
        cands.extend(_candidates(spec, size))
    cands.sort(key=lambda c: -c.screen)
    valid = []
    for c in cands[:VERIFY_LIMIT]:
        if _verify(c, wish, size):
            valid.append(c)
    if not valid:
        return None, len(specs), len(cands)
    valid.sort(key=lambda c: -c.score)
    best = None
    for c in valid[:FINALISTS]:
        extra = _extras(c.fmap, wish)
        c.metrics["extra_fixed_points"] = extra
        if not extra:
            best = c
            break
    return (best or valid[0]), len(specs), len(cands)


def _relaxed(wish: MapWish) -> list[MapWish]:
    """Wishes between the asked one and easier ones, nearest first.

    Fixed points alone: a second fixed point toward the first, slopes steeper than 1 toward 1;
    and at each step the same with a slope near ±1 (nearly neutral: builds move such a fixed
    point far) eased toward ±``NEAR_NEUTRAL``. A fixed point beside a cycle: the fixed point
    elsewhere between the cycle's values (nearest first), then the cycle's values toward each
    other with the fixed point where it was between them, then the cycle alone. A cycle: its
    values toward each other, then apart."""
    fps = list(wish.fixed_points)
    out: list[MapWish] = []

    def add(cand):
        if cand not in out:
            out.append(cand)

    def num(v):
        return float(f"{v:.4g}")

    if wish.cycle is not None:
        lo, hi = sorted(wish.cycle)
        if fps:
            u = (fps[0].value - lo) / (hi - lo)
            for t in sorted(np.linspace(0.1, 0.9, 9), key=lambda t: abs(t - u)):
                add(MapWish((FixedPointWish(num(lo + t * (hi - lo))),), wish.cycle))
        m = math.sqrt(lo * hi)
        cycles = [(num(m / (hi / lo) ** (0.5 * t)), num(m * (hi / lo) ** (0.5 * t)))
                  for t in (0.9, 0.75, 0.5, 1.25, 1.5)]
        if fps:
            for a, b in cycles:
                add(MapWish((FixedPointWish(num(a + u * (b - a))),), (a, b)))
            add(MapWish((), wish.cycle))
        for c in cycles:
            add(MapWish((), c))
        return out
    for t in (0.9, 0.75, 0.5, 0.25):
        for ease in (False, True):
            new = []
            for k, p in enumerate(fps):
                s = p.slope
                if s is not None and abs(s) > 1:
                    s = math.copysign(1 + (abs(s) - 1) * t, s)
                elif s is not None and ease and abs(s) > NEAR_NEUTRAL:
                    s = math.copysign(NEAR_NEUTRAL + (abs(s) - NEAR_NEUTRAL) * t, s)
                v = p.value
                if k == 1:
                    v = fps[0].value * (p.value / fps[0].value) ** t
                new.append(FixedPointWish(num(v), None if s is None else num(s)))
            add(MapWish(tuple(new), None))
    return out


def _parsed(wish: MapWish, best, name: str, builds=None):
    text = module_template(name, wish, best, builds)
    return text, parse_template(text, f"<{name}.toml>")


def _builds(design, wish: MapWish, sample_builds):
    """What simulated builds keep (:mod:`fabkit.design.robustness`), or None without a
    sampler of builds."""
    if sample_builds is None:
        return None

    built, scale, model = sample_builds(design)
    net = design.network
    index = {tuple(sorted(map(int, e))): k for k, e in enumerate(net.edges)}
    order = [index[tuple(sorted(map(int, e)))] for e in MODULE_EDGES]
    return check_builds(net.nodes, wish, np.asarray(built)[:, order], scale=scale, model=model)


def _nearest(candidates, progress=None, sample_builds=None) -> str | None:
    """The first of ``candidates`` (nearest first) that passes the rules, can be built with
    every wished state ``MIN_BRANCH_MARGIN`` from a fold, and (given a sampler of builds)
    whose simulated builds keep it (a quick Monte Carlo, :mod:`fabkit.design.robustness`)."""
    for cand in candidates:
        try:
            checked = check_wish(cand.fixed_points, cand.cycle)
        except WishError:
            continue
        if progress is not None:
            progress(f"trying {checked.options()}")
        best = _search(checked)[0]
        if best is None:
            continue
        if sample_builds is None:
            return checked.options()
        _, design = _parsed(checked, best, "suggested")
        if _builds(design, checked, sample_builds).passed:
            return checked.options()
    return None


def design_map(fixed_points=(), cycle=None, *, name: str = "designed_module",
               progress=None, sample_builds=None) -> MapDesign:
    """Design a module whose map has the wished fixed points, slope and 2-cycle.

    Parameters
    ----------
    fixed_points : sequence
        Up to two fixed points, each a number D, a pair (D, slope) (slope None: free), a
        ``"D[:SLOPE]"`` string or a :class:`~fabkit.design.FixedPointWish`. A slope may be
        asked at one of them (it becomes the designed initial state).
    cycle : (float, float), optional
        A 2-cycle f(A) = B, f(B) = A; with it, at most one fixed point, strictly between.
    name : str
        Template name.
    progress : callable, optional
        Called with a line of text for each nearer wish tried after a refusal.
    sample_builds : callable, optional
        ``sample_builds(design) -> (lengths, scale, model)``: the bar lengths (M, E) of M
        simulated builds of a template (in its network's edge order), mm per design unit and the
        error model in words. Given, the design reports what the builds keep and a nearest
        wish is named only when at least 95 % of its builds keep it. ``fabkit design`` passes
        the laser process's errors (:func:`fabkit.laser_builds`).

    Returns
    -------
    MapDesign
        A :class:`~fabkit.Design` with ``report``, ``template``, ``map`` and ``wish``;
        ``design, report = design_map(...)`` unpacks it into itself and its report.

    Raises
    ------
    WishError
        A wish that cannot be met (exit status 2), with the nearest one that can.

    Examples
    --------
    >>> design, report = design_map([(1.6, 0.0), 1.1])
    >>> [round(p["value"], 12) for p in report["wishes_met"]["fixed_points"]]
    [1.6, 1.1]
    >>> abs(report["wishes_met"]["fixed_points"][0]["slope"]) < 1e-9
    True
    """
    from ..maps import module_map

    start = time.perf_counter()
    try:
        wish = check_wish(fixed_points, cycle)
    except WishError as exc:
        if exc.nearest is None and exc.candidates:
            raise WishError(exc.wish, exc.reason,
                            _nearest(exc.candidates, progress, sample_builds)) from None
        raise
    best, n_specs, n_cands = _search(wish)
    if best is None:
        raise WishError(wish.options(), f"no buildable module among {n_specs} constructions "
                                        f"({n_cands} screened candidates) meets this wish with "
                                        "all its states on one branch, each at least "
                                        f"{100 * MIN_BRANCH_MARGIN:g} % of itself from a fold",
                       _nearest(_relaxed(wish), progress, sample_builds))
    text, design = _parsed(wish, best, name)
    # independent check: the map recomputed from the network the template builds
    fmap = module_map(design.network)
    met = _meets(fmap, wish)
    if met is None:
        raise DesignError(f"{wish.options()}: the written template does not reproduce the "
                          "designed map (a bug in fabkit)")
    builds = _builds(design, wish, sample_builds)
    if builds is not None:  # the template again, its comment now saying what the builds keep
        text, design = _parsed(wish, best, name, builds)
    report = _report(wish, best, fmap, met, design, n_specs, n_cands,
                     time.perf_counter() - start)
    report["builds"] = builds.as_dict() if builds is not None else None
    return MapDesign.of(replace(design, path=None), report=report, template=text, map=fmap,
                        wish=wish)


def _report(wish, best, fmap, met, design, n_specs, n_cands, seconds) -> dict:
    m = best.metrics
    return {
        "wish": wish.options(),
        "wishes_met": met,
        "map": on_branch(fmap),
        "extra_fixed_points": m.get("extra_fixed_points", []),
        "choices": {**best.spec.choices, "variable_points": list(best.points),
                    "specifications": (["velocity"] if best.spec.velocities is not None else [])
                    + ["displacement"] * len(best.spec.finals)},
        "buildability": {k: m[k] for k in ("rigidity_margin", "joint_separation", "map_bulge",
                                             "bar_length_ratio", "bar_lengths",
                                             "fixed_point_gains", "branch_margin",
                                             "branch_margins")},
        "score": best.score,
        "constructions": n_specs,
        "candidates_screened": n_cands,
        "design_residuals": design.meta.get("design", {}).get("residuals", {}),
        "seconds": seconds,
    }
