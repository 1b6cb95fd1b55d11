"""Judging built copies against a design's behaviour (:mod:`fabkit.tolerance.behaviour`).

Each criterion gives, for every build, whether it keeps that part of the behaviour and the
number it was judged on (mm, the worst of its modules or ports):

- ``crystals``: every built module has a fixed point within the state tolerance of each start
  crystal, with the same stability (attracting |f'| < 1 or repelling |f'| > 1; a neutral one
  only has to exist); a crystal at a turning point (a flat state) is kept where the built module
  locks (its branch end and its output there both within the tolerance);
- ``order``: every built module, between its start state and its end, stays on the designed side
  of the diagonal (f(d) > d, or f(d) < d) and its map rises (or falls) as designed, so that each
  module switches after its neighbour and the chain keeps one front (a chain of such maps has a
  monotone profile at every instant: d_{k+1} = f(d_k) lies on the same side of d_k for all k);
- ``end state``: every built module ends in the designed state: the end crystal (as above), or
  its lock next to the designed one;
- ``end ports``: every port distance where the build ends (the target, or where it locks) lies
  within the limit of the design's;
- ``end shape``: every node, after the best rigid fit of the built end state onto the design's,
  lies within the shape limit;
- ``driven state`` and ``still ports`` (a network traced build by build, whose motion switches
  the driven port between two states: the AND gate's branch collapsing while the trunk and the
  junction stay still): where the build ends (the target, or where it locks as a maker's pull
  stops), the driven port is within the state tolerance of its designed end state, and every
  port off the driven chain that the design keeps still (it moves less than the limit) has
  moved less than the limit from where the build started. How far the driven chain's front got
  (its ports that changed state) is reported, not judged: next to a super-stable state it
  depends on the built fixed point, not on the design's target.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..fab.creases import fold_angles
from ..numerics import FIXED_POINT_RTOL, rigid_fit

__all__ = ["Judged", "judge_modules", "judge_ports", "judge_port_states", "judge_shape",
           "profile_order"]

#: d_in values per window around a state (a crystal or a lock), across twice the state
#: tolerance: roots of f(d) - d are bracketed between them and placed by linear interpolation.
WINDOW_POINTS = 9

#: Bisections of a built fixed point whose folds are judged (an origami state): 2^-30 of a
#: window's step, far below round-off of a fold angle.
ROOT_BISECTIONS = 30

#: A designed origami state whose every fold angle is below this (degrees) is flat: a fold
#: angle goes as the square root of the drive's distance to the flat turning point, so a flat
#: end traced to within 1e-10 of its way still folds by about 0.002°.
FLAT_DEG = 0.01

#: Where a sheet locks flat it is placed this far (design units) inside its branch: a fold
#: angle there is about 150° times the square root of it, 0.005°.
LOCK_INSET = 1e-9

#: d_in values across the interval each module crosses between its states.
TRANSIT_POINTS = 9


@dataclass
class Judged:
    """One criterion over M builds.

    Attributes
    ----------
    name : str
    ok : numpy.ndarray of bool, shape (M,)
    value_mm : numpy.ndarray, shape (M,)
        The number each build is judged on (mm; inf: the state does not exist).
    limit_mm : float
        ``ok`` is ``value_mm <= limit_mm`` (the order: value < 0 mm on the wrong side).
    detail : dict
        Extra figures (slopes of the built crystals, ...).
    per_part : numpy.ndarray, shape (M, K) or None
        The number per module (module criteria) or per port (``end ports``), mm.
    unit : str
        The unit of ``value_mm``, ``limit_mm`` and ``per_part``: ``"mm"``, or ``"°"`` for an
        origami state judged by its folds (:mod:`fabkit.tolerance.folds`).
    """

    name: str
    ok: np.ndarray
    value_mm: np.ndarray
    limit_mm: float
    detail: dict = field(default_factory=dict)
    per_part: np.ndarray | None = field(default=None, repr=False)
    unit: str = "mm"


def _window(center: float, tol: float) -> np.ndarray:
    return center + tol * np.linspace(-1.0, 1.0, WINDOW_POINTS)


def _crystal_distance(maps, builds, crystal, tol: float, toward: float):
    """Distance of each built module's nearest fixed point of the crystal's stability from it
    (design units, inf if none in the window), that fixed point's slope, and where the state
    is (its d_in; for a turning-point crystal the branch end where the module locks, when it
    locks within the window; NaN if none), each (M, n)."""
    q = _window(crystal.value, tol)
    f, _ = maps.evaluate(builds, q)
    g = f - q
    ga, gb = g[..., :-1], g[..., 1:]
    xa, xb = np.broadcast_to(q[:-1], ga.shape), np.broadcast_to(q[1:], gb.shape)
    fa, fb = f[..., :-1], f[..., 1:]
    if crystal.branch_end is not None:
        # a root between the last valid value and the branch end (a fixed point next to a
        # turning point) is bracketed by the branch end itself
        end, f_end, last, f_last = maps.branch_end(builds, q, toward)
        ga = np.concatenate([ga, (f_last - last)[..., None]], axis=-1)
        gb = np.concatenate([gb, (f_end - end)[..., None]], axis=-1)
        xa = np.concatenate([xa, last[..., None]], axis=-1)
        xb = np.concatenate([xb, end[..., None]], axis=-1)
        fa = np.concatenate([fa, f_last[..., None]], axis=-1)
        fb = np.concatenate([fb, f_end[..., None]], axis=-1)
    cross = np.isfinite(ga) & np.isfinite(gb) & (np.sign(ga) != np.sign(gb))
    with np.errstate(invalid="ignore", divide="ignore"):
        root = xa - ga * (xb - xa) / (gb - ga)
        slope = (fb - fa) / (xb - xa)
    if crystal.side < 0:
        cross &= np.abs(slope) < 1.0
    elif crystal.side > 0:
        cross &= np.abs(slope) > 1.0
    dist = np.where(cross, np.abs(root - crystal.value), np.inf)
    # a root met on a sampled value itself (a touching fixed point, as designed, is no sign
    # change: f(d) - d only reaches zero)
    on = np.isfinite(g) & (np.abs(g) <= FIXED_POINT_RTOL * max(abs(crystal.value), 1.0))
    dist = np.concatenate([dist, np.where(on, np.abs(q - crystal.value), np.inf)], axis=-1)
    slope = np.concatenate([slope, np.full(g.shape, np.nan)], axis=-1)
    cross = np.concatenate([cross, on], axis=-1)
    best = np.argmin(dist, axis=-1)
    d = np.take_along_axis(dist, best[..., None], axis=-1)[..., 0]
    s = np.take_along_axis(np.where(cross, slope, np.nan), best[..., None], axis=-1)[..., 0]
    where = np.concatenate([root, np.broadcast_to(q, g.shape)], axis=-1)
    at = np.where(np.isfinite(d),
                  np.take_along_axis(where, best[..., None], axis=-1)[..., 0], np.nan)
    if crystal.at_turning:
        lock = np.maximum(np.abs(end - crystal.value), np.abs(f_end - crystal.value))
        lock = np.where(np.isfinite(lock), lock, np.inf)
        # where the built sheet locks (flat) it is in the designed state whatever its fixed
        # point does: that is where its folds are judged
        at = np.where(np.isfinite(lock), end, at)
        d = np.fmin(d, lock)
    return d, s, at


def judge_modules(behaviour, maps, builds) -> dict:
    """The module-level criteria (``crystals``, ``order``, ``end state``) of M builds.

    Parameters
    ----------
    behaviour : Behaviour
    maps : ModuleMaps
    builds : BuildLengths

    Returns
    -------
    dict of str to Judged
    """
    b = behaviour
    scale, tol = b.scale, b.state_tol
    m = builds.base.shape[0]
    out = {}
    starts = [c for c in b.crystals if c.role == "start"]
    if starts:
        per = np.zeros((m, len(maps.modules)))
        slopes = {}
        for c in starts:
            d, s, at = _crystal_distance(maps, builds, c, tol, b.module_end)
            if b.folds is not None:  # origami: the built sheet's folds there (degrees)
                d = _fold_off(maps, builds, c, tol, b.module_end, at, b.folds.start, b.folds)
            per = np.maximum(per, d)
            slopes[f"{c.value:.6g}"] = [float(np.nanmin(s)), float(np.nanmax(s))] \
                if np.isfinite(s).any() else None
        out["crystals"] = _state_judged("crystals", b, per, {"slopes": slopes})
    if b.order and b.transit is not None:
        lo, hi, sign, rise = b.transit
        q = np.linspace(lo, hi, TRANSIT_POINTS)
        f, margin = maps.evaluate(builds, q)
        side = sign * (f - q)  # > 0 on the designed side
        # the map rises (or falls) as designed: the chain's profile keeps its direction
        slope_ok = np.all(rise * np.diff(f, axis=-1) > 0, axis=-1) if rise else True
        valid = np.all(margin >= 0, axis=-1)
        closest = np.where(valid, np.min(side, axis=-1), -np.inf)  # (M, n)
        worst = np.min(closest, axis=1)
        ok = np.all(valid & slope_ok & (closest > 0), axis=1)
        out["order"] = Judged("order", ok, -worst * scale, 0.0,
                              {"interval": [lo, hi], "side": int(sign), "rise": int(rise)},
                              -closest * scale)
    ends = [c for c in b.crystals if c.role == "end"]
    if b.end == "state":
        if ends:
            per, s, at = _crystal_distance(maps, builds, ends[0], tol, b.module_start)
            detail = {"crystal": ends[0].value,
                      "slopes": [float(np.nanmin(s)), float(np.nanmax(s))]
                      if np.isfinite(s).any() else None}
        else:
            t, ft = b.end_lock
            end, f_end, _, _ = maps.branch_end(builds, _window(t, tol), b.module_start)
            lock = np.maximum(np.abs(end - t), np.abs(f_end - ft))
            per = np.where(np.isfinite(lock), lock, np.inf)
            at = np.where(np.isfinite(lock), end, np.nan)
            detail = {"lock": [t, ft]}
        if b.folds is not None:
            per = _fold_off(maps, builds, ends[0] if ends else None, tol, b.module_start, at,
                            b.folds.end, b.folds)
        out["end state"] = _state_judged("end state", b, per, detail)
    return out


def _state_judged(name: str, b, per, detail: dict) -> "Judged":
    """A state criterion of (M, n) numbers: by port distance (design units, judged in mm
    within the state tolerance), or for origami by the built sheet's fold angles (degrees,
    within the folds' limit)."""
    worst = per.max(axis=1)
    if b.folds is not None:
        lim = b.folds.limit_deg
        return Judged(name, worst <= lim, worst, lim, {**detail, "folds": b.folds.as_dict()},
                      per, unit="°")
    return Judged(name, worst <= b.state_tol, worst * b.scale, b.state_tol * b.scale, detail,
                  per * b.scale)


def _refine_root(maps, builds, at, half: float) -> np.ndarray:
    """Fixed points found by linear interpolation across a window's step, bisected to
    round-off (a fold angle next to a folded state changes by tens of degrees per design unit:
    the interpolation's error would show): the sign change of f(d) - d nearest ``at`` among
    :data:`WINDOW_POINTS` values within ``half`` of it (some may be off the branch) is
    bisected. NaN stays NaN; a root without a sign change around it stays where it was."""
    q = at[..., None] + half * np.linspace(-1.0, 1.0, WINDOW_POINTS)
    f, _ = maps.evaluate(builds, np.where(np.isfinite(q), q, 0.0))
    g = f - q
    cross = np.isfinite(g[..., :-1]) & np.isfinite(g[..., 1:]) \
        & (np.sign(g[..., :-1]) != np.sign(g[..., 1:]))
    gap = np.where(cross, np.abs(0.5 * (q[..., :-1] + q[..., 1:]) - at[..., None]), np.inf)
    k = np.argmin(gap, axis=-1)[..., None]
    ok = np.isfinite(np.take_along_axis(gap, k, axis=-1)[..., 0])
    if not ok.any():
        return at
    lo = np.where(ok, np.take_along_axis(q[..., :-1], k, axis=-1)[..., 0], at)
    hi = np.where(ok, np.take_along_axis(q[..., 1:], k, axis=-1)[..., 0], at)
    g_lo = np.take_along_axis(g[..., :-1], k, axis=-1)[..., 0]
    for _ in range(ROOT_BISECTIONS):
        mid = 0.5 * (lo + hi)
        fm, _ = maps.evaluate(builds, mid[..., None])
        same = np.sign(fm[..., 0] - mid) == np.sign(g_lo)
        lo, hi = np.where(ok & same, mid, lo), np.where(ok & ~same, mid, hi)
    return np.where(ok, 0.5 * (lo + hi), at)


def _fold_off(maps, builds, crystal, tol, toward, at, designed, folds) -> np.ndarray:
    """Largest |fold angle - designed| of each built module in its state (degrees, shape
    (M, n); inf where it has no such state or cannot be placed there).

    The state is at ``at`` (d_in, (M, n); ``crystal`` None: a lock, placed there). A flat
    crystal at a turning point is where the sheet, unfolded, locks flat: no crease is folded
    there and none gives, so the sheet as made (without the crease compliance of a folded
    state) is placed where it locks. Any other crystal's fixed point is first bisected to
    round-off."""
    flat = crystal is not None and crystal.at_turning and \
        not np.any(np.abs(designed) > FLAT_DEG)
    if flat:
        _, _, at = _crystal_distance(maps.as_made(), builds, crystal, tol, toward)
        # a hair inside the branch: at its end itself a node's place hangs on round-off
        at = at + np.sign(toward - at) * LOCK_INSET
    elif crystal is not None:
        at = _refine_root(maps, builds, at, 2.0 * tol / (WINDOW_POINTS - 1))
    x, margin = maps.place_at(builds, at, bend=not flat)
    theta = fold_angles(folds.edges, folds.faces, x)  # (M, n, E)
    off = np.max(np.abs(theta - designed), axis=-1)
    return np.where(np.isfinite(at) & (margin >= 0) & np.isfinite(off), off, np.inf)


def judge_ports(behaviour, driven, limit_mm: float) -> "Judged":
    """``end ports``: every port distance at the end within the limit of the design's."""
    err = np.abs(driven.ports - behaviour.end_ports[None, :]) * behaviour.scale
    err = np.where(driven.closed[:, None], np.nan_to_num(err, nan=np.inf), np.inf)
    worst = err.max(axis=1)
    return Judged("end ports", worst <= limit_mm, worst, limit_mm,
                  {"p95_by_port_mm": np.percentile(err, 95, axis=0, method="higher").tolist()}, err)


def judge_port_states(starts, finals, nominal_start, nominal_end, driven: int, free,
                      scale: float, limit_mm: float,
                      state_mm: float) -> tuple["Judged", "Judged"]:
    """``driven state`` and ``still ports`` of builds traced one by one.

    Parameters
    ----------
    starts, finals : numpy.ndarray, shape (M, P)
        Each build's port distances where it was put together and where its motion ended
        (design units; NaN: the build did not get there).
    nominal_start, nominal_end : numpy.ndarray, shape (P,)
        The design's.
    driven : int
        Column of the driven port.
    free : numpy.ndarray of bool, shape (P,)
        Ports whose state may switch: the driven chain's (its front may run on past where the
        design's target stops it, up to where the build locks). Every other port the design
        keeps still must stay still.
    scale : float
        mm per design unit.
    limit_mm, state_mm : float
        The limit (still ports) and the state tolerance (the driven port's end state).

    Returns
    -------
    (Judged, Judged)
        ``driven state``: distance of the driven port from its designed end (mm); ``still
        ports``: the largest motion of a port the design keeps still (mm; per port in
        ``per_part``, the columns ``detail["still_columns"]``). Both carry ``detail["switched"]``, the ports per build that ended in
        their designed end state (within the state tolerance), and ``detail["designed"]``,
        those of the design.
    """
    starts = np.asarray(starts, dtype=np.float64)
    finals = np.asarray(finals, dtype=np.float64)
    there = np.isfinite(finals).all(axis=1) & np.isfinite(starts).all(axis=1)
    off = np.abs(finals[:, driven] - nominal_end[driven]) * scale
    off = np.where(there, off, np.inf)
    travel = np.abs(nominal_end - nominal_start) * scale
    free = np.asarray(free, dtype=bool)
    still = (travel <= limit_mm) & ~free
    moved = np.abs(finals - starts) * scale
    moved = np.where(there[:, None], moved, np.inf)[:, still]
    worst = moved.max(axis=1) if moved.shape[1] else np.where(there, 0.0, np.inf)
    # a port ends in the designed end state when it lies nearer to it than the state tolerance
    switching = travel > limit_mm
    at_end = np.abs(finals - nominal_end[None, :]) * scale <= state_mm
    switched = np.where(there, np.sum(at_end & switching[None, :], axis=1), -1)
    designed = int(np.sum(switching))
    detail = {"switched": switched.tolist(), "designed": designed}
    return (Judged("driven state", off <= state_mm, off, state_mm, dict(detail)),
            Judged("still ports", worst <= limit_mm, worst, limit_mm,
                   {**detail, "still_columns": np.flatnonzero(still).tolist()}, moved))


def judge_shape(behaviour, driven) -> "Judged":
    """``end shape``: every node within the shape limit after the best rigid fit."""
    fit = rigid_fit(driven.final, behaviour.end_config[None])
    moved = driven.final @ np.swapaxes(fit.rotation, -1, -2) + fit.shift[:, None, :]
    dev = np.linalg.norm(moved - behaviour.end_config[None], axis=-1).max(axis=1)
    worst = np.where(driven.closed & np.isfinite(dev), dev * behaviour.scale, np.inf)
    return Judged("end shape", worst <= behaviour.shape_limit_mm, worst,
                  behaviour.shape_limit_mm)


def profile_order(behaviour, sampled, chain_cols) -> np.ndarray:
    """Largest lead of a module over its neighbour behind the front, per build, as a fraction of
    the travel, over every sampled instant of the driven motion (the observed order)."""
    d0 = behaviour.crystals[0].value if behaviour.crystals else behaviour.start_drive
    d1 = behaviour.end_lock[0] if behaviour.end_lock else \
        [c.value for c in behaviour.crystals if c.role == "end"][0]
    p = np.clip((sampled[..., chain_cols] - d0) / (d1 - d0), 0.0, 1.0)
    lead = behaviour.order * np.diff(p, axis=-1)  # > 0: a module ahead of the one before it
    with np.errstate(invalid="ignore"):
        return np.nanmax(np.where(np.isfinite(lead), lead, -np.inf), axis=(1, 2))
