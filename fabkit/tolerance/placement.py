"""Placing simulated builds: many builds and drive values in one pass, locks at turning points."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..numerics import EDGE_RTOL
from .processes import ProcessGeometry

#: Builds whose lengths must be realised and traced one by one (no construction order) are
#: slow; their number is capped at this.
PROJECTED_SAMPLES_CAP = 40

#: Bisection steps that find where a build locks (a turning point short of the target).
LOCK_BISECTIONS = 26

#: A simulated build is projected onto its own bar lengths to this relative error (its bars
#: carry process errors of ~1e-3, so a tighter fit adds nothing).
BUILD_RTOL = 1e-9


def _chain_ports(net) -> list[str]:
    """Ports named d1, d2, ... in order, followed by the other ports."""
    chain = sorted((p for p in net.ports if re.fullmatch(r"d\d+", p)), key=lambda p: int(p[1:]))
    return chain + sorted(p for p in net.ports if p not in chain)


def _plan_edge_index(plan, net) -> np.ndarray:
    """For every (placed node, parent) pair of a plan, the index of its edge in ``net``."""
    lookup = {(min(i, j), max(i, j)): k for k, (i, j) in enumerate(net.edges.tolist())}
    idx = np.full(plan.parents.shape, -1, dtype=np.int64)
    for row, (v, par) in enumerate(zip(plan.order.tolist(), plan.parents.tolist())):
        for c, p in enumerate(par):
            if p >= 0:
                idx[row, c] = lookup[(min(v, p), max(v, p))]
    return idx


def _to_drive_frame(x, a, b, ref_dir) -> np.ndarray:
    """Rigidly move configurations (..., N, 2) so node a is at the origin and a→b along ref_dir
    (2D only; 3D configurations are returned relative to node a)."""
    x = np.asarray(x) - np.asarray(x)[..., a:a + 1, :]
    if x.shape[-1] != 2:
        return x
    u = x[..., b, :] / np.linalg.norm(x[..., b, :], axis=-1, keepdims=True)
    ang = np.arctan2(ref_dir[1], ref_dir[0]) - np.arctan2(u[..., 1], u[..., 0])
    c, s = np.cos(ang)[..., None], np.sin(ang)[..., None]
    return np.stack([c * x[..., 0] - s * x[..., 1], s * x[..., 0] + c * x[..., 1]], axis=-1)


def _place_builds(plan, values, radii) -> tuple[np.ndarray, np.ndarray]:
    """Place every build at its own drive values in one pass of :func:`fabkit.kinematics.place`,
    one column per (build, drive value) carrying its build's radii.

    Parameters
    ----------
    plan : ConstructionPlan
    values : numpy.ndarray, shape (M, G)
        Drive values of each build.
    radii : numpy.ndarray, shape (M, K, dim)
        Each build's distances of every placed node to its parents.

    Returns
    -------
    positions : numpy.ndarray, shape (M, G, N, d)
    margin : numpy.ndarray, shape (M, G)
        Smallest ``h² / r²`` over the intersections; negative where one does not exist.
    """
    m, g = values.shape
    from ..kinematics import place

    x, margin, _ = place(plan, values.reshape(m * g), radii=np.repeat(radii, g, axis=0))
    return x.reshape((m, g) + x.shape[1:]), margin.reshape(m, g)


def _joint_turn(net, start, final) -> np.ndarray:
    """Largest turn (radians) between two bars at every joint from ``start`` to ``final`` (2D)."""
    i, j = net.edges[:, 0], net.edges[:, 1]
    if net.dim != 2:
        return np.zeros(net.n_nodes)
    ang = []
    for x in (start, final):
        dx = x[j] - x[i]
        ang.append(np.arctan2(dx[:, 1], dx[:, 0]))
    turn = np.angle(np.exp(1j * (ang[1] - ang[0])))  # each bar's own turn, wrapped
    hi = np.full(net.n_nodes, -np.inf)
    lo = np.full(net.n_nodes, np.inf)
    for ends in (i, j):
        np.maximum.at(hi, ends, turn)
        np.minimum.at(lo, ends, turn)
    return np.where(np.isfinite(hi), np.minimum(hi - lo, 2 * np.pi), 0.0)


def _process_geometry(design, spec, problem, final) -> ProcessGeometry:
    net = design.network
    turn = boundary = None
    if spec.process == "print" and final is not None:
        turn = _joint_turn(net, problem.start, final)
    if spec.process == "origami":
        fab = design.fabrication if isinstance(design.fabrication, dict) else {}
        assignment = (fab.get("origami") or {}).get("assignment") \
            if isinstance(fab.get("origami"), dict) else None
        if isinstance(assignment, list) and len(assignment) == net.n_edges:
            cut = net.edges[[a in ("B", "C") for a in assignment]]
            boundary = np.zeros(net.n_nodes, dtype=bool)
            boundary[cut.ravel()] = True
    return ProcessGeometry(net.nodes, net.edges, net.edge_lengths, turn, boundary)


@dataclass
class _Runs:
    """Results of one batch of simulated builds (constructive placement)."""

    dist: np.ndarray
    reached: np.ndarray
    final: np.ndarray
    stop: np.ndarray
    locked: int
    unclosed: int


def _simulate(plan, eidx, problem, net, built, values, pairs, limit_units, clearance_units):
    """Drive every build towards the target; a build that locks stops where it locks."""
    m = built.shape[0]
    n_virtual = problem.work.n_edges - net.n_edges
    work = np.concatenate([built, np.broadcast_to(problem.work.edge_lengths[net.n_edges:],
                                                  (m, n_virtual))], axis=1)
    mask = eidx >= 0
    radii = np.where(mask[None], work[:, np.maximum(eidx, 0)], 0.0)  # (M, K, dim)
    grid = np.broadcast_to(values, (m, values.size))
    X, margin = _place_builds(plan, grid, radii)
    bad = margin[:, 1:] < 0
    fails = bad.any(axis=1)
    final = X[:, -1].copy()
    stop = np.full(m, values[-1])
    if fails.any():
        f = np.flatnonzero(fails)
        first = np.argmax(bad[f], axis=1) + 1
        lo, hi = values[first - 1], values[first]
        for _ in range(LOCK_BISECTIONS):  # where each failing build locks
            mid = 0.5 * (lo + hi)
            _, mm = _place_builds(plan, mid[:, None], radii[f])
            ok = mm[:, 0] >= 0
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
        Xl, _ = _place_builds(plan, lo[:, None], radii[f])
        final[f] = Xl[:, 0]
        stop[f] = lo
    # a build that locks within the limit of the target has reached it (it stops there)
    reached = np.abs(stop - values[-1]) <= limit_units
    locked = int((~reached).sum())
    # redundant edges (self-stress) are not used by the construction: a build that cannot
    # close them does not assemble
    used = np.zeros(problem.work.n_edges, dtype=bool)
    used[eidx[mask]] = True
    unused = np.flatnonzero(~used[:net.n_edges])
    moving = reached.copy()
    if unused.size:
        i, j = net.edges[unused, 0], net.edges[unused, 1]
        got = np.linalg.norm(final[:, i] - final[:, j], axis=-1)
        reached &= np.abs(got - built[:, unused]).max(axis=1) <= clearance_units + EDGE_RTOL
    dist = np.linalg.norm(final[:, pairs[:, 0]] - final[:, pairs[:, 1]], axis=-1)
    dist[~reached] = np.nan
    return _Runs(dist, reached, final, stop, locked, int((moving & ~reached).sum()))


def _find_plan(problem, trajectory):
    """The cached construction plan from the start; from the target's sides when the start is a
    flat state (a flat origami sheet); None when there is no construction order."""
    from ..errors import ConstructionError
    from ..kinematics import plan_construction
    from ..kinematics.constructive import cached_plan

    try:
        return cached_plan(problem.work, problem.drive, problem.start)
    except ConstructionError:
        pass
    final = getattr(trajectory, "final", None)
    if final is None or np.shape(final) != problem.start.shape:
        return None
    try:
        return plan_construction(problem.work, problem.drive, final)
    except ConstructionError:
        return None
