"""Curvature modules designed from their map for buildable curve-following chains.

Fig 4's modules share the fixed points D1* and D2* of a symmetric map (d1 = d2 all along the
motion); they differ in the apex angle of their final triangle, which sets how a chain of them,
mirrored every second module, turns. Here such modules are designed, one per wished final apex
angle, with the displacement construction: the designed nodes go from an isosceles triangle with
legs D1* = 1 and apex ``INITIAL_APEX_DEG`` to one with legs D2* = ``LEG_RATIO`` and the wished
apex; the variable nodes are a mirror-symmetric pair on the displacement solution space, so the
module is symmetric and its map is the identity (every state a fixed point, d1 = d2).

The free choices are made so that a chain can be laser cut: a chain's modules are the triangles
of a strip, and a module whose variable nodes stay inside its own designed triangle along the
whole motion never sweeps over another module's bars; of those, the pair with the largest margin
(barycentric distance to the triangle's sides, half the distance between the two variable
nodes) and a well-conditioned rigidity matrix is taken. A scan over initial apex angles 70-140°
and leg ratios 0.8-1.25 (docs/design.md) found the widest range of final apex angles with such
designs at an initial apex of 110° and a leg ratio of 1.1: final apex angles 50-90° (50-86° are
used, see ``APEX_RANGE_DEG``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import DesignError, FabkitError
from ..model.network import Network
from ..model.rigidity import count_modes
from ..numerics import TINY
from .geometry import (bar_clearance, bar_lengths, branch_signs, inside_margin, joint_separation,
                       MODULE_EDGES, module_motion, module_positions, rigidity_margin, triangle)
from .solution_space import displacement_space

__all__ = ["CurvatureType", "design_curvature_type", "joint_room", "lowest_apex",
           "INITIAL_APEX_DEG", "LEG_RATIO", "APEX_RANGE_DEG", "MIN_PAIR_APEX_DEG"]

#: Apex angle of every curvature module's initial triangle (legs D1* = 1): all modules start
#: alike, so the chain starts straight.
INITIAL_APEX_DEG = 110.0
#: D2* / D1*: the legs' length in the final state (D1* = 1 design unit).
LEG_RATIO = 1.1
#: Final apex angles used: the scan above finds buildable modules from 50 to 90 deg; above
#: 86 deg the rigidity margin falls below 0.1 and the bars pass within 0.03 design units of the
#: joints, and laser kits of arcs with 88.6 and 89.2 deg modules found no stacking (or took the
#: 20 s exact search), while every arc tried with the range capped at 86 stacked in 8 layers
#: within a second (docs/design.md).
APEX_RANGE_DEG = (50.0, 86.0)
#: Two neighbouring modules of a chain must have final apex angles averaging at least this: two
#: narrow modules side by side crowd their joints so that the bars at a designed joint stack
#: higher than a screw reaches (laser kits of 8-module chains, default settings, 79 mm/unit:
#: pairs 66/66, 66/70, 63/63, 58.5/58.5 find no stacking; 58/74 and 58.5/70 need the 20 s exact
#: search; every pair averaging 70 or more (54/86, 62/78, 66/78, 70/74, 72/72, 66/90, ...)
#: stacks in 8 layers within 0.5 s).
MIN_PAIR_APEX_DEG = 70.0
#: Rays cast to sample the displacement solution space, and how far out (design units).
RAYS = 400
RADIUS = 3.0
#: Candidates confirmed with the module's own map (all are measured along the motion first).
VERIFY = 24
#: Least margin inside the own triangle (barycentric) along the motion.
MIN_INSIDE = 0.02
#: Least conditioning of the rigidity matrix along the motion.
MIN_RIGIDITY = 0.03
#: Largest bar-length ratio.
MAX_BAR_RATIO = 4.0
#: The final triangle must match the wished apex to this (relative bottom length).
APEX_RTOL = 1e-9
#: Weight of the least joint-to-bar distance against the other margins in the score: a bar
#: that sweeps close past another joint's screw must be stacked clear of it.
CLEARANCE_WEIGHT = 2.0
#: Configurations sampled along the motion for the margins.
SAMPLES = 25
#: Slack (degrees) that keeps the top of a grid of apex angles on it despite round-off.
GRID_SLACK_DEG = 1e-9


@dataclass(frozen=True, eq=False)
class CurvatureType:
    """A designed curvature module.

    Attributes
    ----------
    apex : float
        Final apex angle (radians).
    network : Network
        The module at its initial state (ports d1 = (0, 1), d2 = (1, 2), bottom = (0, 2)).
    designed, final, variable : numpy.ndarray
        The specification written to its template.
    bottom : float
        |x0 - x2| in the final state (design units).
    margins : dict
        ``inside`` (least barycentric margin of the variable nodes in their triangle along the
        motion), ``separation`` (least distance between the variable nodes), ``rigidity``,
        ``bar_clearance`` (least joint-to-bar distance), ``joints`` (least distance between
        any two joints), ``bar_length_ratio``, ``branch_margin`` (design units) and
        ``branch_margin_fraction`` (of the state): the distance of D1* and D2* to the nearer
        fold of the branch, ``branch`` (its d1 range).
    score : float
        min(inside, separation / 2, 2 x bar clearance), scaled down where the rigidity margin
        is below 0.2: what the choice of the variable nodes maximises.
    """

    apex: float
    network: Network
    designed: np.ndarray
    final: np.ndarray
    variable: np.ndarray
    bottom: float
    margins: dict
    score: float = 0.0


def _mirror(p: np.ndarray) -> np.ndarray:
    return p * np.array([-1.0, 1.0])


@dataclass(frozen=True)
class _Screened:
    """Every sampled symmetric pair of variable nodes of one final apex, measured along the
    whole motion (vectorised): what the choice and the joint room are made from."""

    x0: np.ndarray
    x1: np.ndarray
    variable: np.ndarray      # (P, 2, 2)
    ok: np.ndarray            # (P,) bool: on the branch, margins above the floors
    joints: np.ndarray        # (P,) least distance between two joints along the motion
    score: np.ndarray         # (P,)
    margins: list             # (P,) dicts
    bottom: np.ndarray        # (P,)


@lru_cache(maxsize=256)
def _screen(apex_deg: float) -> _Screened:
    x0 = triangle(1.0, 1.0, math.radians(INITIAL_APEX_DEG))
    x1 = triangle(LEG_RATIO, LEG_RATIO, math.radians(apex_deg))
    space = displacement_space(x0, x1)
    pts = space.sample(RAYS, radius=RADIUS)
    pts = pts[pts[:, 0] < 0.0]
    var = np.stack([pts, _mirror(pts)], axis=1)
    nodes = np.concatenate([np.broadcast_to(x0, (len(pts), 3, 2)), var], axis=1)
    d1 = np.linspace(1.0, LEG_RATIO, SAMPLES)
    xs = module_motion(bar_lengths(nodes), branch_signs(nodes), d1)
    placed = np.all(np.isfinite(xs), axis=(1, 2, 3))
    # unplaced candidates measured on a stand-in triangle (they are refused below)
    xs = np.where(placed[:, None, None, None], xs, np.concatenate([x0, var[0]])[None, None])
    target = 2.0 * LEG_RATIO * math.sin(math.radians(apex_deg) / 2)
    bottom = np.linalg.norm(xs[:, -1, 0] - xs[:, -1, 2], axis=-1)
    d2 = np.linalg.norm(xs[:, :, 1] - xs[:, :, 2], axis=-1)
    symmetric = np.all(np.abs(d2 - d1) <= APEX_RTOL * LEG_RATIO, axis=1)
    on_branch = placed & symmetric & (np.abs(bottom - target) <= APEX_RTOL * target)
    inside = inside_margin(xs[:, :, 3:], xs[:, :, :3]).min(axis=(1, 2))
    sep = np.linalg.norm(xs[:, :, 3] - xs[:, :, 4], axis=-1).min(axis=1)
    clear = bar_clearance(xs).min(axis=1)
    joints = joint_separation(xs).min(axis=1)
    rig = rigidity_margin(xs.reshape(-1, 5, 2)).reshape(len(pts), SAMPLES).min(axis=1)
    lengths = bar_lengths(nodes)
    ratio = lengths.max(axis=1) / np.maximum(lengths.min(axis=1), TINY)
    ok = (on_branch & (inside >= MIN_INSIDE) & (rig >= MIN_RIGIDITY) & (ratio <= MAX_BAR_RATIO))
    score = np.minimum(np.minimum(inside, 0.5 * sep), CLEARANCE_WEIGHT * clear) \
        * np.minimum(1.0, rig / 0.2)
    margins = [{"inside": float(inside[i]), "separation": float(sep[i]), "rigidity": float(rig[i]),
                "bar_clearance": float(clear[i]), "joints": float(joints[i]),
                "bar_length_ratio": float(ratio[i])} for i in range(len(pts))]
    return _Screened(x0, x1, var, ok, np.where(ok, joints, 0.0), np.where(ok, score, 0.0),
                     margins, bottom)


def joint_room(apex_deg: float) -> float:
    """The largest least distance between two joints (design units, along the whole motion)
    of any buildable curvature module with this final apex angle: modules of this apex keep
    screws ``min_joint`` apart only when ``min_joint`` is at most this.

    Examples
    --------
    >>> round(joint_room(70.0), 3) > round(joint_room(50.0), 3)
    True
    """
    s = _screen(round(float(apex_deg), 9))
    return float(s.joints.max()) if s.ok.any() else 0.0


def lowest_apex(min_joint: float, step: float = 1.0) -> float | None:
    """The smallest final apex angle (degrees, on a grid of ``step`` from the bottom of
    ``APEX_RANGE_DEG``) whose modules keep their joints ``min_joint`` apart; None when the
    widest of the range does not.

    The room grows with the apex angle (measured: 0.095 design units at 46 deg, 0.36 at 70,
    0.55 at 78, then level within 0.51-0.55 up to 90), so the grid is bisected: a few module
    designs, not one per angle.
    """
    lo, hi = APEX_RANGE_DEG
    grid = np.arange(lo, hi + GRID_SLACK_DEG, step)
    if joint_room(float(grid[-1])) < min_joint:
        return None
    a, b = 0, len(grid) - 1          # room(grid[b]) >= min_joint
    if joint_room(float(grid[a])) >= min_joint:
        return float(grid[a])
    while b - a > 1:
        mid = (a + b) // 2
        if joint_room(float(grid[mid])) >= min_joint:
            b = mid
        else:
            a = mid
    return float(grid[b])


def design_curvature_type(apex_deg: float, min_joint: float = 0.0) -> CurvatureType:
    """Design the curvature module with this final apex angle.

    Parameters
    ----------
    apex_deg : float
        Final apex angle in degrees (within ``APEX_RANGE_DEG`` for a buildable module).
    min_joint : float
        Least distance between two joints along the motion (design units; a screw head's
        room at the kit's scale).

    Returns
    -------
    CurvatureType

    Raises
    ------
    DesignError
        No symmetric pair of variable nodes keeps inside its triangle with the margins asked.

    Examples
    --------
    >>> t = design_curvature_type(70.0)
    >>> round(float(np.degrees(2 * np.arcsin(t.bottom / (2 * LEG_RATIO)))), 9)
    70.0
    """
    from ..maps import module_map

    s = _screen(round(float(apex_deg), 9))
    score = np.where(s.ok & (s.joints >= min_joint), s.score, 0.0)
    # every screened pair was measured along the whole motion by the vectorised construction;
    # the best few are confirmed with the module's own map (one motion, the final state on the
    # branch through the initial one)
    for i in np.argsort(-score)[:VERIFY]:
        if score[i] <= 0:
            break
        net = Network(module_positions(s.x0, s.variable[i]), MODULE_EDGES,
                      ports={"d1": (0, 1), "d2": (1, 2), "bottom": (0, 2)})
        modes = count_modes(net)
        if modes.conformational != 1 or modes.self_stress != 0:
            continue
        try:
            fmap = module_map(net)
        except FabkitError:
            continue
        if not (fmap.domain[0] <= 1.0 and LEG_RATIO <= fmap.domain[1]):
            continue
        # the distance of its two states to the folds of the branch (every state of the
        # motion is a fixed point of this identity map; a build whose fold moves past D1* or
        # D2* cannot start straight or reach its shape)
        lo, hi = fmap.domain
        fold = min((1.0 - lo) / 1.0, (hi - LEG_RATIO) / LEG_RATIO)
        margins = {**s.margins[i], "branch_margin": float(min(1.0 - lo, hi - LEG_RATIO)),
                   "branch_margin_fraction": float(fold), "branch": [float(lo), float(hi)]}
        return CurvatureType(apex=math.radians(apex_deg), network=net, designed=s.x0,
                             final=s.x1, variable=s.variable[i], bottom=float(s.bottom[i]),
                             score=float(score[i]), margins=margins)
    room = f" and its joints {min_joint:.3g} apart" if min_joint > 0 else ""
    raise DesignError(f"no curvature module with final apex {apex_deg:g} deg keeps its "
                      f"variable nodes inside its triangle{room} (buildable range "
                      f"{APEX_RANGE_DEG[0]:g}-{APEX_RANGE_DEG[1]:g} deg)")
