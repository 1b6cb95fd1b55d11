"""Stacking layers: which bar sits on which sheet layer so that nothing collides over the motion.

Bars lie flat in parallel layers, one sheet thick each, and turn on Chicago screws through
their holes. Two bars must sit on different layers when

* they share a joint (both are threaded on its screw), or
* their outlines come closer than ``clearance`` at some sampled configuration of the motion.

A screw with its heads is a column at its joint spanning the layers of its bars plus
``head_slots`` layers above and below (the heads). A bar that passes within ``clearance`` of a
column during the motion must lie outside the column's layers, and two columns that come close
must not share a layer. Those two rules depend on the order of the layers, not only on which
bars share one, so the layers are found in two steps: a graph colouring of the conflict graph
(networkx greedy strategies; the fewest colours wins, the largest clique is a lower bound), then
the order of the colour classes that breaks no column rule and needs the shortest screws.
When that breaks a column rule or uses more layers than the clique bound, the whole problem
is solved as a mixed-integer program (:func:`_milp_layers`), which either proves the layer
count minimal or reports the best count found with a proven lower bound.

Sampling guarantee. The motion is sampled (adaptively, see :func:`sample_motion`) so that no
node moves more than ``h = clearance / 2`` between consecutive samples. Every point of a bar is
a convex combination of its two joints, so on the straight-line interpolation between two
samples every bar point is within ``h / 2`` of where it is at the nearer sample, and the gap
between two bars can shrink by at most ``h = clearance / 2`` relative to the nearer sample.
Bars of one layer are at least ``clearance`` apart at every sample, hence at least
``clearance / 2`` apart between samples; the true path deviates from the chord between samples
only to second order in ``h``, far below that margin.
A motion that ends in (or passes) a flat state where nodes move while the drive stands still
cannot be sampled this way; it is refused with the drive value where it happens.

Chains of modules are sampled window by window instead (:func:`sample_chain`): module k moves
exactly as the module alone at its own input distance d_k, so a few consecutive modules are
sampled as a short chain over the range d_k sweeps, where its own drive does not stand still
even when the whole chain's does (a collapse front). The work does not grow with the length.
"""

from __future__ import annotations

import itertools
import math
import sys
from dataclasses import dataclass, field

import numpy as np

from ..errors import FabricationError

__all__ = ["Sweep", "sample_motion", "sample_chain", "segment_distance", "point_segment_distance",
           "Conflicts", "find_conflicts", "JointStack", "Stacking", "plan_layers",
           "stacking_gaps"]

# Samples per block when scanning pairs over the motion (bounds memory to ~block x pairs).
_BLOCK = 256
#: Largest (samples x pairs) block measured at once: 2^20 doubles (8 MB) per array, so the
#: kernels' temporaries stay near 100 MB however many pairs a kit has.
_BLOCK_ELEMENTS = 2**20
# Refuse motions that need more samples than this to meet the step bound.
_MAX_SAMPLES = 200_000
# Time limit of the exact layer search (s); past it the best stacking found and the solver's
# proven lower bound are reported.
_MILP_SECONDS = 20.0
# Larger problems get their bound from a neighbourhood of the largest clique only.
_MILP_BARS = 60
# Smaller neighbourhoods tried first when a valid stacking is at hand (each proves a bound for
# the whole; the bundled chains' counts are proven on 16 bars in a fifth of the time of 60),
# and the time limit of each (s).
_MILP_STEPS = (16, 32)
_MILP_STEP_SECONDS = 5.0


#: A sampled step may exceed its limit by this relative amount (round-off of the bisection).
STEP_RTOL = 1e-9
#: The solver's dual bound counts as an integer within this (HiGHS reports bounds to ~1e-9).
DUAL_BOUND_SLACK = 1e-6
#: Screw heads spanning a whole number of sheets to round-off take that many layers, not one more.
HEAD_LAYERS_SLACK = 1e-12


@dataclass(frozen=True, eq=False)
class Sweep:
    """The motion sampled finely enough for collision checks.

    Attributes
    ----------
    positions : numpy.ndarray, shape (S, N, 2)
        Node positions in mm.
    drive : numpy.ndarray, shape (S,)
        Drive values (design units).
    step_limit : float
        Bound on node displacement between samples (mm).
    max_step : float
        Largest node displacement between consecutive samples actually met (mm).
    method, status, message : str
        From the trace the samples were taken along.
    conflicts : Conflicts or None
        Set by :func:`sample_chain`, which measures the conflicts module window by module
        window; ``positions`` are then the chain's trace (for pictures), not the dense samples.
    stats : dict
        Sampling figures (windows, samples per window kind, ...).
    """

    positions: np.ndarray
    drive: np.ndarray
    step_limit: float
    max_step: float
    method: str
    status: str
    message: str
    conflicts: object = None
    stats: dict = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        return int(self.positions.shape[0])


def _node_steps(x: np.ndarray) -> np.ndarray:
    """Largest node displacement between consecutive configurations, shape (S-1,)."""
    if x.shape[0] < 2:
        return np.zeros(0)
    d = x[1:] - x[:-1]
    return np.sqrt(_dot(d, d)).max(axis=-1)  # _dot: the same sums, without numpy's reduction


def sample_motion(net, motion, scale: float, step_limit: float, *,
                  floor_limit: float | None = None) -> Sweep:
    """Sample a network's motion so that no node moves more than ``step_limit`` mm per sample.

    Parameters
    ----------
    net : Network
        2D network in design units.
    motion : Motion
        Drive, target, method, held ports and options (as in a template).
    scale : float
        mm per design unit.
    step_limit : float
        Bound on node displacement between consecutive samples (mm).
    floor_limit : float, optional
        Where two drive values are adjacent floats and nodes still move more than
        ``step_limit`` (a chain amplifying its drive past float64's resolution), accept steps
        up to this many mm instead of refusing; the sweep's ``max_step`` reports the step met,
        and the stacking widens its clearance by the excess (see :func:`plan_layers`).

    Returns
    -------
    Sweep
        Positions in mm. With the constructive method samples are placed exactly and refined
        by bisection where a step is too long; other methods are re-traced with a maximum
        step small enough.

    Raises
    ------
    FabricationError
        No motion target, or the bound cannot be met within 200 000 samples.
    """
    from ..kinematics import trace
    from ..kinematics.base import align_to_gauge, make_problem
    from ..kinematics.constructive import place, plan_construction

    if motion.to is None:
        raise FabricationError("the template gives no [motion] target (motion.to): the stacking "
                               "layers are planned over the motion, so it must be known")
    traj = trace(net, drive=motion.drive, to=motion.to, method=motion.method, hold=motion.hold,
                 **motion.options)
    limit = step_limit / scale  # design units
    if traj.method == "constructive":
        problem = make_problem(net, motion.drive, motion.to, hold=motion.hold)
        plan = plan_construction(problem.work, problem.drive, problem.start)
        values, x = _refine(
            lambda v: align_to_gauge(place(plan, v)[0], problem.start, problem.gauge),
            np.linspace(traj.drive[0], traj.drive[-1], 65), limit, scale, floor_limit,
            motion.drive)
        drive = values
    else:
        # Re-trace with a step bound in arclength (a node moves at most the arclength), then
        # shrink it while a method's own step measure still lets nodes move too far.
        opts = dict(motion.options)
        key = "max_step" if traj.method == "projected" else "step"
        step = min(limit, opts.get(key) or np.inf)
        for _ in range(6):
            opts[key] = step
            traj = trace(net, drive=motion.drive, to=motion.to, method=traj.method,
                         hold=motion.hold, **opts)
            worst = float(_node_steps(traj.positions).max(initial=0.0))
            if worst <= limit:
                break
            step *= 0.9 * limit / worst
        x, drive = traj.positions, traj.drive
    steps = _node_steps(x)
    max_step = float(steps.max() * scale) if steps.size else 0.0
    if max_step > max(step_limit, floor_limit or 0.0) * (1 + STEP_RTOL):
        raise FabricationError(
            f"the {traj.method} trace moves a node {max_step:.3g} mm between samples, more than "
            f"the {step_limit:g} mm the collision check needs; use method = \"constructive\"")
    return Sweep(positions=np.ascontiguousarray(x * scale), drive=np.asarray(drive),
                 step_limit=float(step_limit), max_step=max_step, method=traj.method,
                 status=str(traj.status), message=traj.message)


def _refine(placer, values, limit: float, scale: float, floor_limit, drive_name: str):
    """Bisect drive values until no node moves more than ``limit`` (design units) per step.

    ``placer(values) -> (S, N, d)`` places configurations. Intervals between adjacent floats
    whose step is within ``floor_limit`` mm are accepted; others raise. Returns values, x.
    """
    for _ in range(80):
        x = placer(values)
        steps = _node_steps(x)
        bad = np.flatnonzero(steps > limit)
        if bad.size == 0:
            return values, x
        # Bisect down to adjacent floats: near an unstable fixed point a chain amplifies its
        # drive by the slope to the power of the module count, so the far modules of a
        # collapse front move between drive values only a few ulps apart.
        stuck = np.nextafter(values[bad], values[bad + 1]) == values[bad + 1]
        if floor_limit is not None:
            accept = stuck & (steps[bad] * scale <= floor_limit)
            bad, stuck = bad[~accept], stuck[~accept]
            if bad.size == 0:
                return values, x
        if stuck.any():
            # Nodes jump while the drive stands still: a flat state the drive cannot
            # parametrise, so no sampling by drive value meets the bound there.
            k = int(bad[stuck][np.argmax(steps[bad[stuck]])])
            raise FabricationError(
                f"the motion passes a flat state at {drive_name} = {values[k]:.10g} where "
                f"nodes move {steps[k] * scale:.3g} mm while the drive stands still; the "
                "collision check cannot sample it: end the motion before it (motion.to)")
        if values.size + bad.size > _MAX_SAMPLES:
            raise FabricationError(
                f"sampling the motion to {limit * scale:g} mm steps needs more than "
                f"{_MAX_SAMPLES} samples; raise the clearance or check the motion")
        values = np.insert(values, bad + 1, 0.5 * (values[bad] + values[bad + 1]))
    raise FabricationError("could not sample the motion finely enough")  # pragma: no cover


def _module_ports(net, copies):
    """The output port name of every distinct module of a chain (by its global node pair)."""
    out = {}
    for c, (m, index, _flag) in enumerate(copies):
        if id(m) in out:
            continue
        pair = net.ports.get(f"d{c + 2}")
        name = next((p for p, (a, b) in m.ports.items()
                     if pair is not None and (int(index[a]), int(index[b])) == tuple(pair)), None)
        if name is None:
            return None
        out[id(m)] = name
    return out


def _unique_rows(a: np.ndarray) -> np.ndarray:
    return np.unique(a.reshape(-1, 2), axis=0) if a.size else a.reshape(0, 2)


def sample_chain(net, motion, scale: float, step_limit: float, *, width: float,
                 clearance: float, column_radius: float, window: int = 3,
                 floor_limit: float | None = None,
                 spacer_radius: float | None = None) -> Sweep | None:
    """Conflicts of a planar chain measured module window by module window (near-linear).

    A chain's module k moves exactly as the module alone with its input distance at d_k, and
    ``window`` consecutive modules move as the same short chain with its d1 at d_k. So the
    clearances inside every window follow from that short chain's motion over the range d_k
    sweeps, sampled by its own d1 so that no node moves more than ``step_limit`` mm per step
    (where the whole chain's drive stands still, the short chain's does not). Windows of the
    same modules and mirror pattern are sampled once over the union of their ranges (a wider
    range only adds conflicts), so the dense work does not grow with the chain's length.
    Bars of modules ``window`` or more apart are checked at the samples of the chain's own
    trace, with one bar width of extra margin.

    Parameters
    ----------
    net : Network
        A 2D chain built by :func:`fabkit.assemble.chain` (it remembers its layout).
    motion : Motion
        Drive ``d1``, no held ports.
    scale : float
        mm per design unit.
    step_limit : float
        Largest node step (mm) between samples of a window.
    width, clearance, column_radius, spacer_radius : float
        As for :func:`find_conflicts`.
    window : int
        Modules per window (>= 2: neighbours share a joint pair).
    floor_limit : float, optional
        See :func:`sample_motion`.

    Returns
    -------
    Sweep or None
        ``conflicts`` set and ``positions`` the chain's trace in mm; None when the network is
        not such a chain (then use :func:`sample_motion`).
    """
    from ..assemble import chain
    from ..kinematics import trace
    from ..kinematics.constructive import place, plan_construction

    layout = net.assembly
    if (layout is None or net.dim != 2 or motion.drive != "d1" or motion.hold
            or motion.to is None):
        return None
    copies = layout.copies
    n = len(copies)
    outs = _module_ports(net, copies)
    if outs is None:
        return None
    traj = trace(net, drive="d1", to=motion.to, method=motion.method, **motion.options)
    edges = np.asarray(net.edges, dtype=np.int64)
    n_e = np.array([m.n_edges for m, _, _ in copies])
    offset = np.concatenate([[0], np.cumsum(n_e)])
    if offset[-1] != edges.shape[0]:
        return None
    degree = np.bincount(edges.ravel(), minlength=net.n_nodes)
    lo = np.array([traj.distance(f"d{c + 1}").min() for c in range(n)])
    hi = np.array([traj.distance(f"d{c + 1}").max() for c in range(n)])
    w = max(2, min(int(window), n))
    starts = range(n - w + 1)
    kinds: dict = {}
    for c in starts:
        mods = copies[c:c + w]
        f0 = bool(mods[0][2])
        key = (tuple(id(m) for m, _, _ in mods), tuple(bool(f) ^ f0 for _, _, f in mods))
        k = kinds.setdefault(key, {"starts": [], "lo": np.inf, "hi": -np.inf})
        k["starts"].append(c)
        k["lo"], k["hi"] = min(k["lo"], lo[c]), max(k["hi"], hi[c])
    limit = step_limit / scale
    pairs, gaps, keep, keep_span, jpairs = [], [], [], [], []
    n_samples, max_step = 0, 0.0
    for key, k in kinds.items():
        c0 = k["starts"][0]
        mods = copies[c0:c0 + w]
        sub = chain([m for m, _, _ in mods], mirror=list(key[1]), d_in=layout.d_in,
                    d_out=outs[id(mods[0][0])])
        sub_layout = sub.assembly.copies
        plan = plan_construction(sub, sub.port("d1"))
        a, b = float(k["lo"]), float(k["hi"])
        values = np.linspace(a, b, 33) if b > a else np.array([a])

        def placer(v, plan=plan):
            x, margin, _ = place(plan, v)
            if np.any(margin < 0):
                raise FabricationError(
                    f"a window of {w} modules has no configuration over d = {a:.10g}..{b:.10g}")
            return x

        values, x = _refine(placer, values, limit, scale, floor_limit, "d")
        n_samples += values.size
        steps = _node_steps(x)
        max_step = max(max_step, float(steps.max() * scale) if steps.size else 0.0)
        xs = x * scale
        # window -> chain numbering, the same for every window of this kind
        maps = []
        for c in k["starts"]:
            node_map = np.full(sub.n_nodes, -1, dtype=np.int64)
            for (_, idx_sub, _), (_, idx_glob, _) in zip(sub_layout, copies[c:c + w]):
                node_map[idx_sub] = idx_glob
            edge_map = np.concatenate([np.arange(offset[j], offset[j + 1]) for j in range(c, c + w)])
            if not np.array_equal(np.sort(node_map[sub.edges], 1), np.sort(edges[edge_map], 1)):
                return None  # numbering differs from what chain() builds: use the whole motion
            maps.append((node_map, edge_map))
        screws = np.flatnonzero(degree[maps[0][0]] >= 2)
        excess = max(0.0, float(steps.max() * scale) - step_limit) if steps.size else 0.0
        conf = find_conflicts(sub.edges, xs, width=width, clearance=clearance + excess,
                              column_radius=column_radius, screw_joints=screws,
                              spacer_radius=spacer_radius)
        for node_map, edge_map in maps:
            pairs.append(edge_map[conf.pairs])
            gaps.append(conf.gap)
            keep.append(np.stack([edge_map[conf.keepout[:, 0]], node_map[conf.keepout[:, 1]]], 1))
            keep_span.append(np.stack([edge_map[conf.keepout_span[:, 0]],
                                       node_map[conf.keepout_span[:, 1]]], 1))
            jpairs.append(node_map[conf.joint_pairs])
    # far field: modules `w` or more apart, at the samples of the chain's own trace
    xg = traj.positions * scale
    far = _far_field(edges, xg, np.repeat(np.arange(n), n_e), w, width=width,
                     clearance=clearance + width,
                     column_radius=max(column_radius, spacer_radius or 0.0),
                     screw_joints=np.flatnonzero(degree >= 2), copies=copies)
    pairs.append(far[0])
    gaps.append(np.full(far[0].shape[0], np.nan))
    keep.append(far[1])
    jpairs.append(far[2])
    P = np.sort(np.concatenate(pairs).reshape(-1, 2), axis=1)
    G = np.concatenate(gaps)
    order = np.lexsort((np.nan_to_num(G, nan=np.inf), P[:, 1], P[:, 0]))
    P, G = P[order], G[order]
    first = np.ones(P.shape[0], dtype=bool)
    first[1:] = np.any(P[1:] != P[:-1], axis=1)
    P, G = P[first], G[first]
    inc_share = np.zeros(P.shape[0], dtype=bool)
    if P.size:
        ea, eb = edges[P[:, 0]], edges[P[:, 1]]
        inc_share = ((ea[:, :1] == eb) | (ea[:, 1:] == eb)).any(axis=1)
    conflicts = Conflicts(
        pairs=P.astype(np.int64),
        kind=np.where(inc_share, "joint", "sweep").astype(object),
        gap=np.where(inc_share, np.nan, G), sample=np.full(P.shape[0], -1, dtype=np.int64),
        keepout=_unique_rows(np.concatenate(keep)).astype(np.int64),
        joint_pairs=_unique_rows(np.sort(np.concatenate(jpairs).reshape(-1, 2), axis=1)
                                 ).astype(np.int64),
        screw_joints=np.flatnonzero(degree >= 2),
        keepout_span=_unique_rows(np.concatenate(keep_span + [np.zeros((0, 2), np.int64)])
                                  ).astype(np.int64))
    steps = _node_steps(traj.positions)
    return Sweep(positions=np.ascontiguousarray(xg), drive=np.asarray(traj.drive),
                 step_limit=float(step_limit), max_step=max_step, method="module windows",
                 status=str(traj.status), message=traj.message, conflicts=conflicts,
                 stats={"modules": n, "window": w, "window_kinds": len(kinds),
                        "window_samples": int(n_samples),
                        "trace_samples": int(traj.positions.shape[0]),
                        "trace_max_step_mm": float(steps.max() * scale) if steps.size else 0.0})


def _far_field(edges, x, module_of_edge, w, *, width, clearance, column_radius, screw_joints,
               copies):
    """Bar pairs, bar-screw and screw-screw pairs of modules ``w`` or more apart that come
    within reach at any of the samples ``x`` (S, N, 2): found module by module with a k-d tree
    on module centres, so a straight strip costs O(modules) per sample."""
    from scipy.spatial import cKDTree

    n = len(copies)
    empty = np.zeros((0, 2), dtype=np.int64)
    if n <= w:
        return empty, empty, empty
    node_module = np.full(x.shape[1], -1, dtype=np.int64)
    for c, (_, idx, _) in enumerate(copies):
        node_module[idx[node_module[idx] < 0]] = c
    reach = width + clearance + 2 * column_radius
    cand = set()
    for xs in x:
        centre = np.zeros((n, 2))
        radius = np.zeros(n)
        for c, (_, idx, _) in enumerate(copies):
            p = xs[idx]
            centre[c] = p.mean(axis=0)
            radius[c] = np.sqrt(((p - centre[c]) ** 2).sum(-1)).max()
        tree = cKDTree(centre)
        close = tree.query_pairs(2 * radius.max() + reach, output_type="ndarray")
        if close.size:
            a, b = close[:, 0], close[:, 1]
            gap = np.sqrt(((centre[a] - centre[b]) ** 2).sum(-1)) - radius[a] - radius[b]
            sel = (np.abs(a - b) >= w) & (gap < reach)
            cand.update(map(tuple, np.sort(close[sel], 1).tolist()))
    if not cand:
        return empty, empty, empty
    eb = [np.flatnonzero(module_of_edge == c) for c in range(n)]
    pa, pb = [], []
    for a, b in sorted(cand):
        g1, g2 = np.meshgrid(eb[a], eb[b], indexing="ij")
        pa.append(g1.ravel())
        pb.append(g2.ravel())
    pa, pb = np.concatenate(pa), np.concatenate(pb)
    d, _ = _min_over_samples(_bar_bar(edges), x, pa, pb)
    close = d - width < clearance
    pairs = np.stack([pa[close], pb[close]], 1)
    is_screw = np.zeros(x.shape[1], dtype=bool)
    is_screw[screw_joints] = True
    bj, jj = [], []
    for a, b in sorted(cand):
        for m1, m2 in ((a, b), (b, a)):
            js = np.flatnonzero(is_screw & (node_module == m2))
            g1, g2 = np.meshgrid(eb[m1], js, indexing="ij")
            bj.append(g1.ravel())
            jj.append(g2.ravel())
    bj, jj = np.concatenate(bj), np.concatenate(jj)
    keep = np.zeros((0, 2), dtype=np.int64)
    if bj.size:
        d, _ = _min_over_samples(
            lambda xs, bi, ji: point_segment_distance(xs[:, ji], xs[:, edges[bi, 0]],
                                                      xs[:, edges[bi, 1]]), x, bj, jj)
        near = d - 0.5 * width - column_radius < clearance
        keep = np.stack([bj[near], jj[near]], 1)
    ja, jb = [], []
    for a, b in sorted(cand):
        j1 = np.flatnonzero(is_screw & (node_module == a))
        j2 = np.flatnonzero(is_screw & (node_module == b))
        g1, g2 = np.meshgrid(j1, j2, indexing="ij")
        ja.append(g1.ravel())
        jb.append(g2.ravel())
    ja, jb = np.concatenate(ja), np.concatenate(jb)
    jp = np.zeros((0, 2), dtype=np.int64)
    if ja.size:
        d, _ = _min_over_samples(
            lambda xs, i1, i2: np.sqrt(((xs[:, i1] - xs[:, i2]) ** 2).sum(-1)), x, ja, jb)
        near = d - 2.0 * column_radius < clearance
        jp = np.stack([ja[near], jb[near]], 1)
    return pairs.astype(np.int64), keep.astype(np.int64), jp.astype(np.int64)


# -- distances ------------------------------------------------------------------------------

def point_segment_distance(x, p, q) -> np.ndarray:
    """Distance from points ``x`` to segments ``p``-``q`` (broadcast over leading axes).

    Examples
    --------
    >>> float(point_segment_distance([0.0, 1.0], [-1.0, 0.0], [1.0, 0.0]))
    1.0
    """
    x, p, q = (np.asarray(a, dtype=np.float64) for a in (x, p, q))
    d = q - p
    dd = _dot(d, d)
    t = np.clip(_dot(x - p, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    e = p + t[..., None] * d - x
    return np.sqrt(_dot(e, e))


def _dot(a, b):
    # a sum over a last axis of length 2 or 3 written out: numpy's reduction over such a short
    # axis costs several times the arithmetic (this is the hot loop of the clearance checks)
    out = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]
    if a.shape[-1] == 3:
        out += a[..., 2] * b[..., 2]
    return out


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def segment_distance(p1, q1, p2, q2) -> np.ndarray:
    """Distance between 2D segments ``p1-q1`` and ``p2-q2`` (0 where they cross).

    Examples
    --------
    >>> float(segment_distance([0, 0], [2, 0], [1, -1], [1, 1]))
    0.0
    >>> float(segment_distance([0, 0], [1, 0], [0, 2], [1, 2]))
    2.0
    """
    p1, q1, p2, q2 = (np.asarray(a, dtype=np.float64) for a in (p1, q1, p2, q2))
    d = np.minimum(np.minimum(point_segment_distance(p1, p2, q2), point_segment_distance(q1, p2, q2)),
                   np.minimum(point_segment_distance(p2, p1, q1), point_segment_distance(q2, p1, q1)))
    r, s = q1 - p1, q2 - p2
    o1 = _cross(r, p2 - p1)
    o2 = _cross(r, q2 - p1)
    o3 = _cross(s, p1 - p2)
    o4 = _cross(s, q1 - p2)
    crossing = (o1 * o2 < 0) & (o3 * o4 < 0)
    return np.where(crossing, 0.0, d)


def _min_over_samples(func, positions, *index_arrays):
    """Minimum over samples (and the sample where it occurs) of ``func(x, *index_arrays)``."""
    n = index_arrays[0].shape[0]
    best = np.full(n, np.inf)
    where = np.zeros(n, dtype=np.int64)
    if n == 0:
        return best, where
    # samples per block so that one (block, n) array stays within the budget: the kernels make
    # about a dozen of them, and n (pairs) grows with the square of the kit
    block = int(max(1, min(_BLOCK, _BLOCK_ELEMENTS // n)))
    for start in range(0, positions.shape[0], block):
        x = positions[start:start + block]
        d = func(x, *index_arrays)  # (block, n)
        k = np.argmin(d, axis=0)
        v = d[k, np.arange(n)]
        better = v < best
        best[better] = v[better]
        where[better] = k[better] + start
    return best, where


def _pruned_min(func, positions, threshold: float, *index_arrays, stride: int = 32):
    """Like :func:`_min_over_samples`, but scans every sample only for index pairs that can come
    below ``threshold``.

    Between a sample and the nearest of every ``stride``-th sample each point moves at most
    ``stride / 2`` largest steps, so a distance between two moving points (or point sets) can
    be at most ``stride x`` the largest node step smaller than at that coarse sample. Pairs whose
    coarse minimum exceeds ``threshold`` by that much are left out of the full scan (their
    reported minimum is the coarse one, an upper bound above the threshold).
    """
    n = index_arrays[0].shape[0]
    s = positions.shape[0]
    if n == 0 or s <= 2 * stride:
        return _min_over_samples(func, positions, *index_arrays)
    step = float(_node_steps(positions).max())
    coarse_idx = np.unique(np.r_[np.arange(0, s, stride), s - 1])
    best, where = _min_over_samples(func, positions[coarse_idx], *index_arrays)
    where = coarse_idx[where]
    maybe = np.flatnonzero(best - stride * step < threshold)
    if maybe.size:
        b2, w2 = _min_over_samples(func, positions, *(a[maybe] for a in index_arrays))
        best[maybe], where[maybe] = b2, w2
    return best, where


def _least(func, positions, offset, *index_arrays, stride: int = 32):
    """The smallest ``func - offset`` over samples and index pairs, exactly, and where.

    Every pair is first measured at every ``stride``-th sample; between those a distance can
    shrink by at most ``stride x`` the largest node step (see :func:`_pruned_min`), so only the
    pairs whose coarse minimum comes that close to the smallest coarse minimum of all can hold
    the overall minimum, and only they are measured at every sample. The result is the full
    scan's (:func:`_min_over_samples`).

    Returns
    -------
    (value, k, sample) : (float, int, int)
        The minimum, the pair (index into ``index_arrays``) and the sample where it occurs;
        ``(inf, -1, -1)`` for no pairs.
    """
    n = index_arrays[0].shape[0]
    if n == 0:
        return math.inf, -1, -1
    offset = np.broadcast_to(np.asarray(offset, dtype=np.float64), (n,))
    s = positions.shape[0]
    if s <= 2 * stride:
        maybe = np.arange(n)
    else:
        step = float(_node_steps(positions).max())
        coarse_idx = np.unique(np.r_[np.arange(0, s, stride), s - 1])
        coarse, _ = _min_over_samples(func, positions[coarse_idx], *index_arrays)
        coarse = coarse - offset
        maybe = np.flatnonzero(coarse - stride * step <= coarse.min())
    best, where = _min_over_samples(func, positions, *(a[maybe] for a in index_arrays))
    best = best - offset[maybe]
    k = int(np.argmin(best))
    return float(best[k]), int(maybe[k]), int(where[k])


def _bar_bar(edges):
    """Kernel: segment distance between bars a and b at every sample of a block."""
    def kernel(x, a, b):
        return segment_distance(x[:, edges[a, 0]], x[:, edges[a, 1]],
                                x[:, edges[b, 0]], x[:, edges[b, 1]])
    return kernel


@dataclass(frozen=True, eq=False)
class Conflicts:
    """Everything the stacking must respect, measured over a sweep.

    Attributes
    ----------
    pairs : numpy.ndarray of int, shape (C, 2)
        Bar pairs that must be on different layers.
    kind : numpy.ndarray of str, shape (C,)
        ``"joint"`` (share a joint) or ``"sweep"`` (come closer than the clearance).
    gap : numpy.ndarray, shape (C,)
        Smallest outline gap over the motion (mm; negative = overlap), NaN for joint pairs.
    sample : numpy.ndarray of int, shape (C,)
        Sample where the gap is smallest (-1 for joint pairs).
    keepout : numpy.ndarray of int, shape (K, 2)
        (bar, joint) pairs: the bar passes the joint's screw column (must avoid its layers).
    joint_pairs : numpy.ndarray of int, shape (J, 2)
        Joints whose screw columns come close (their layer spans must not meet).
    screw_joints : numpy.ndarray of int
        Joints that get a screw (two or more bars).
    keepout_span : numpy.ndarray of int, shape (K2, 2)
        (bar, joint) pairs: the bar passes the joint's spacer rings (wider than its heads) but
        not its heads: it must avoid the layers of the stack itself, not the head layers.
    """

    pairs: np.ndarray
    kind: np.ndarray
    gap: np.ndarray
    sample: np.ndarray
    keepout: np.ndarray
    joint_pairs: np.ndarray
    screw_joints: np.ndarray
    keepout_span: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))


def _incidence(edges: np.ndarray, n_nodes: int) -> np.ndarray:
    inc = np.zeros((n_nodes, edges.shape[0]), dtype=bool)
    inc[edges[:, 0], np.arange(edges.shape[0])] = True
    inc[edges[:, 1], np.arange(edges.shape[0])] = True
    return inc


def _joint_pairs(edges: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (a < b) of bars that share a joint, in the order of ``np.triu_indices``."""
    ends = np.concatenate([edges[:, 0], edges[:, 1]])
    bars = np.concatenate([np.arange(edges.shape[0])] * 2)
    order = np.lexsort((bars, ends))
    ends, bars = ends[order], bars[order]
    bounds = np.flatnonzero(np.diff(np.r_[-1, ends, n_nodes + 1]))
    pa, pb = [], []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        group = bars[lo:hi]
        if group.size >= 2:
            i, j = np.triu_indices(group.size, k=1)
            pa.append(group[i])
            pb.append(group[j])
    if not pa:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    a, b = np.concatenate(pa), np.concatenate(pb)
    key = np.unique(a * edges.shape[0] + b)  # two bars share at most one joint; sorted as triu
    return key // edges.shape[0], key % edges.shape[0]


def _share_joint(edges: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """True where bars a[k] and b[k] share a joint (from their ends: O(pairs), where an
    incidence-matrix product would hold nodes x pairs booleans)."""
    e0, e1 = edges[:, 0], edges[:, 1]
    return (e0[a] == e0[b]) | (e0[a] == e1[b]) | (e1[a] == e0[b]) | (e1[a] == e1[b])


def _box_pairs(lo_a, hi_a, lo_b, hi_b, reach: float, *, same: bool = False):
    """Index pairs (i, j) whose boxes ``[lo_a[i], hi_a[i]]`` and ``[lo_b[j], hi_b[j]]`` come
    within ``reach`` of each other in x and in y (``same``: one set, i < j).

    Sort and sweep along x: box j can reach box i only if its left edge lies in
    ``[lo_a[i] - reach - W, hi_a[i] + reach]`` with W the widest box of set b, so each box meets
    its neighbours along x, not the whole set: linear in the kit for chains and lattices,
    where the pairs of all bars grow with its square.
    """
    lo_a, hi_a = np.asarray(lo_a, dtype=np.float64), np.asarray(hi_a, dtype=np.float64)
    lo_b, hi_b = np.asarray(lo_b, dtype=np.float64), np.asarray(hi_b, dtype=np.float64)
    if lo_a.shape[0] == 0 or lo_b.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    order = np.argsort(lo_b[:, 0], kind="stable")
    left = lo_b[order, 0]
    widest = float((hi_b[:, 0] - lo_b[:, 0]).max())
    start = np.searchsorted(left, lo_a[:, 0] - reach - widest, side="left")
    stop = np.searchsorted(left, hi_a[:, 0] + reach, side="right")
    counts = np.maximum(stop - start, 0)
    total = int(counts.sum())
    i = np.repeat(np.arange(lo_a.shape[0]), counts)
    first = np.repeat(start - np.cumsum(counts) + counts, counts)
    j = order[first + np.arange(total)]
    near = ((lo_a[i] - reach <= hi_b[j]) & (lo_b[j] - reach <= hi_a[i])).all(axis=1)
    if same:
        near &= i < j
    i, j = i[near], j[near]
    order = np.lexsort((j, i))  # (i, j) ascending: the order of the full enumeration
    return i[order], j[order]


def _exact_least(func, x, offset, pairs_within, lower_bound_reach, start_reach: float,
                 limit_reach: float):
    """The smallest ``func - offset`` over samples and pairs, exactly, looking only at pairs
    whose swept boxes come within a reach that grows until it provably holds the minimum.

    ``pairs_within(reach)`` gives the index arrays of the pairs within ``reach``;
    ``lower_bound_reach(value)`` turns a found minimum into the reach beyond which no pair can
    do better (a distance is never below its boxes' distance). Stops when the found minimum
    lies within the reach searched, or when the reach covers everything (``limit_reach``).

    Returns
    -------
    (value, k, sample, arrays) : the minimum, the pair, the sample, and the index arrays
    searched last (``k`` indexes them); ``(inf, -1, -1, arrays)`` when there is no pair.
    """
    reach = start_reach
    while True:
        arrays = pairs_within(reach)
        value, k, where = _least(func, x, offset(arrays) if callable(offset) else offset,
                                 *arrays)
        if (k >= 0 and lower_bound_reach(value) <= reach) or reach >= limit_reach:
            return value, k, where, arrays
        reach = min(4.0 * reach, limit_reach)


def find_conflicts(edges, positions, *, width: float, clearance: float,
                   column_radius: float, screw_joints=None,
                   spacer_radius: float | None = None) -> Conflicts:
    """Measure which bars, screws and columns come close anywhere along a sampled motion.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    positions : array_like, shape (S, N, 2)
        Sampled configurations in mm.
    width : float
        Bar width (mm): outlines are the joint segments grown by ``width / 2``.
    clearance : float
        Least gap allowed between parts of one layer (mm).
    column_radius : float
        Radius of a screw column (largest of head and spacer radius, mm).
    spacer_radius : float, optional
        Radius of the spacer rings inside a stack, when larger than ``column_radius`` (the
        heads): bars that pass them but not the heads go to ``keepout_span``.
    screw_joints : array_like of int, optional
        Joints that carry a screw (default: every joint of two or more of these bars; a piece
        cut out of a larger network passes the joints that have screws in the whole).

    Returns
    -------
    Conflicts
    """
    edges = np.asarray(edges, dtype=np.int64)
    x = np.asarray(positions, dtype=np.float64)
    n_nodes = x.shape[1]
    inc = _incidence(edges, n_nodes)
    # bars that share a joint always conflict (from the joints' bar lists: O(bars))
    ja, jb = _joint_pairs(edges, n_nodes)
    # Only pairs whose swept boxes (over the whole motion) come within reach need the scan,
    # and only those are ever formed (sort and sweep: linear in the kit, not quadratic).
    lo_n, hi_n = x.min(axis=0), x.max(axis=0)                      # (N, 2) each
    r_col = max(column_radius, spacer_radius or 0.0)
    reach = 0.5 * width + clearance + r_col
    bar_lo = np.minimum(lo_n[edges[:, 0]], lo_n[edges[:, 1]]) - reach
    bar_hi = np.maximum(hi_n[edges[:, 0]], hi_n[edges[:, 1]]) + reach
    fa, fb = _box_pairs(bar_lo, bar_hi, bar_lo, bar_hi, 0.0, same=True)
    keep = ~_share_joint(edges, fa, fb)
    fa, fb = fa[keep], fb[keep]
    if fa.size:
        seg_gap, where = _pruned_min(_bar_bar(edges), x, width + clearance, fa, fb)
    else:
        seg_gap, where = np.zeros(0), np.zeros(0, dtype=np.int64)
    gap = seg_gap - width
    close = gap < clearance
    pairs = np.concatenate([np.stack([ja, jb], 1), np.stack([fa[close], fb[close]], 1)]).reshape(-1, 2)
    kind = np.array(["joint"] * ja.size + ["sweep"] * int(close.sum()), dtype=object)
    gaps = np.concatenate([np.full(ja.size, np.nan), gap[close]])
    samples = np.concatenate([np.full(ja.size, -1), where[close]]).astype(np.int64)

    degree = inc.sum(axis=1)
    screw_joints = (np.flatnonzero(degree >= 2) if screw_joints is None
                    else np.asarray(screw_joints, dtype=np.int64))
    # bar vs screw column at a joint the bar does not belong to (near ones only)
    bb, jk = _box_pairs(bar_lo, bar_hi, lo_n[screw_joints], hi_n[screw_joints], reach)
    jj = screw_joints[jk]
    keep = ~inc[jj, bb]
    bb, jj = bb[keep], jj[keep]
    if bb.size:
        d, _ = _pruned_min(
            lambda xs, bi, ji: point_segment_distance(xs[:, ji], xs[:, edges[bi, 0]],
                                                      xs[:, edges[bi, 1]]),
            x, 0.5 * width + r_col + clearance, bb, jj)
        near = d - 0.5 * width - column_radius < clearance
        keepout = np.stack([bb[near], jj[near]], 1)
        span = ~near & (d - 0.5 * width - r_col < clearance)
        keepout_span = np.stack([bb[span], jj[span]], 1)
    else:
        keepout = keepout_span = np.zeros((0, 2), dtype=np.int64)
    # screw column vs screw column
    if screw_joints.size >= 2:
        sl, sh = lo_n[screw_joints], hi_n[screw_joints]
        ia, ib = _box_pairs(sl, sh, sl, sh, 2 * reach, same=True)
        ia, ib = screw_joints[ia], screw_joints[ib]
        d, _ = _pruned_min(
            lambda xs, i1, i2: np.sqrt(((xs[:, i1] - xs[:, i2]) ** 2).sum(-1)),
            x, 2.0 * r_col + clearance, ia, ib)
        near = d - 2.0 * r_col < clearance
        joint_pairs = np.stack([ia[near], ib[near]], 1).reshape(-1, 2)
    else:
        joint_pairs = np.zeros((0, 2), dtype=np.int64)
    return Conflicts(pairs=pairs.astype(np.int64), kind=kind, gap=gaps, sample=samples,
                     keepout=keepout.astype(np.int64), joint_pairs=joint_pairs.astype(np.int64),
                     screw_joints=screw_joints,
                     keepout_span=keepout_span.reshape(-1, 2).astype(np.int64))


# -- layer assignment -----------------------------------------------------------------------

@dataclass(frozen=True)
class JointStack:
    """The screw at one joint, bottom to top.

    Attributes
    ----------
    joint : int
    bars : tuple of int
        Bars threaded on the screw, bottom to top.
    layers : tuple of int
        Their layers.
    spacers : tuple of int
        Layers between the lowest and highest bar that the screw passes without a bar (each
        gets a spacer ring).
    stack_height : float
        Clamped thickness (mm) = layers spanned x sheet thickness.
    screw_length : float
        Post length chosen from the catalogue (mm).
    play : float
        screw_length - stack_height (mm), at the nominal thickness without washers.
    washers : int
        Thin washers that take up play and still let the screw close on the thickest sheets.
    play_range : (float, float)
        Axial play with the washers on the thickest and on the thinnest sheets (mm).
    """

    joint: int
    bars: tuple[int, ...]
    layers: tuple[int, ...]
    spacers: tuple[int, ...]
    stack_height: float
    screw_length: float
    play: float
    washers: int = 0
    play_range: tuple[float, float] = (0.0, 0.0)

    def order(self) -> list[str]:
        """Bottom-to-top description, e.g. ``["bar 3", "spacer", "bar 0"]``."""
        lo, hi = min(self.layers), max(self.layers)
        by_layer = dict(zip(self.layers, self.bars))
        return [f"bar {by_layer[z]}" if z in by_layer else "spacer" for z in range(lo, hi + 1)]


@dataclass(frozen=True, eq=False)
class Stacking:
    """Layer of every bar and the screw stack of every joint.

    Attributes
    ----------
    layer : numpy.ndarray of int, shape (E,)
        Layer of each bar (0 = bottom).
    n_layers : int
    joints : tuple of JointStack
    conflicts : Conflicts
    lower_bound : int
        No stacking has fewer layers: the largest clique of the conflict graph, raised to the
        exact solver's proven bound when colouring alone does not reach it.
    strategy : str
        The colouring strategy that won.
    head_slots : int
        Layers a screw head occupies above and below its stack.
    """

    layer: np.ndarray
    n_layers: int
    joints: tuple[JointStack, ...]
    conflicts: Conflicts
    lower_bound: int
    strategy: str
    head_slots: int
    stats: dict = field(default_factory=dict)

    @property
    def proven_minimal(self) -> bool:
        """True when no stacking has fewer layers: the count meets the proven lower bound.

        False means fewer layers were neither found nor ruled out (the exact solver ran out of
        time): the stacking has ``n_layers``, and at least ``lower_bound`` are needed.
        """
        return self.n_layers <= self.lower_bound

    def proof_text(self) -> str:
        """The layer count with what is proven about it, e.g. ``"6 layers (proven minimal)"``
        or ``"7 layers (at least 6 needed; fewer not ruled out)"``."""
        if self.proven_minimal:
            return f"{self.n_layers} layers (proven minimal)"
        return (f"{self.n_layers} layers (at least {self.lower_bound} needed; fewer not ruled "
                "out)")

    def joint_stack(self, joint: int) -> JointStack:
        for js in self.joints:
            if js.joint == joint:
                return js
        raise KeyError(f"joint {joint} has no screw")


_STRATEGIES = ("saturation_largest_first", "largest_first", "smallest_last", "independent_set",
               "connected_sequential_bfs", "connected_sequential_dfs")
# Strategies (and colour interchange) whose networkx implementation is quadratic in the bars.
_QUADRATIC = ("saturation_largest_first", "independent_set")
_QUADRATIC_BARS = 400


def _colourings(n_bars: int, pairs: np.ndarray):
    import networkx as nx

    g = nx.Graph()
    g.add_nodes_from(range(n_bars))
    g.add_edges_from(map(tuple, pairs.tolist()))
    found = []
    large = n_bars > _QUADRATIC_BARS
    for strategy in _STRATEGIES:
        if large and strategy in _QUADRATIC:
            continue  # networkx implements these in O(n^2): keep long chains near-linear
        col = nx.greedy_color(g, strategy=strategy, interchange=not large and strategy in (
            "largest_first", "smallest_last"))
        colours = np.array([col[k] for k in range(n_bars)], dtype=np.int64)
        # renumber classes by first appearance so equal colourings compare equal
        _, first = np.unique(colours, return_index=True)
        remap = np.empty(colours.max() + 1, dtype=np.int64)
        remap[colours[np.sort(first)]] = np.arange(first.size)
        found.append((strategy, remap[colours]))
    members = max(nx.find_cliques(g), key=len, default=[]) if n_bars else []
    return found, len(members), sorted(members)


def _spans(layer: np.ndarray, joint_bars: list[np.ndarray]):
    """Lowest and highest layer at every screw joint; ``layer`` shape (P, E) -> (P, J) each."""
    lo = np.stack([layer[:, jb].min(axis=1) for jb in joint_bars], axis=1)
    hi = np.stack([layer[:, jb].max(axis=1) for jb in joint_bars], axis=1)
    return lo, hi


def _score(layer, joint_bars, jpos, keepout, joint_pairs, head, keepout_span=None):
    """(violations, total span) for candidate layer assignments ``layer`` (P, E)."""
    lo, hi = _spans(layer, joint_bars)
    viol = np.zeros(layer.shape[0], dtype=np.int64)
    for rows, slack in ((keepout, head), (keepout_span, 0)):
        if rows is None or not rows.size:
            continue
        zb = layer[:, rows[:, 0]]
        j = jpos[rows[:, 1]]
        viol += ((zb >= lo[:, j] - slack) & (zb <= hi[:, j] + slack)).sum(axis=1)
    if joint_pairs.size:
        i, j = jpos[joint_pairs[:, 0]], jpos[joint_pairs[:, 1]]
        overlap = (lo[:, i] - head <= hi[:, j] + head) & (lo[:, j] - head <= hi[:, i] + head)
        viol += overlap.sum(axis=1)
    return viol, (hi - lo).sum(axis=1)


class _ClassScore:
    """:func:`_score` of ``perm[colours]`` for permutations ``perm`` of the colour classes,
    counted over the distinct colour sets of the joints (and distinct rules between them), so
    that scoring a permutation costs the same for a chain of 10 or 10 000 modules."""

    def __init__(self, colours, joint_bars, jpos, keepout, joint_pairs, head, keepout_span):
        sets = [tuple(sorted(set(colours[jb].tolist()))) for jb in joint_bars]
        index: dict = {}
        sid = np.array([index.setdefault(t, len(index)) for t in sets], dtype=np.int64)
        width = max(len(t) for t in index)
        self.pad = np.array([t + (t[0],) * (width - len(t)) for t in index], dtype=np.int64)
        self.count = np.bincount(sid, minlength=len(index))
        rows = [np.stack([colours[r[:, 0]], sid[jpos[r[:, 1]]], np.full(len(r), slack)], axis=1)
                for r, slack in ((keepout, head), (keepout_span, 0)) if r is not None and r.size]
        rows = np.concatenate(rows) if rows else np.zeros((0, 3), dtype=np.int64)
        self.rows, self.row_count = np.unique(rows, axis=0, return_counts=True)
        pairs = np.stack([sid[jpos[joint_pairs[:, 0]]], sid[jpos[joint_pairs[:, 1]]]], axis=1) \
            if joint_pairs.size else np.zeros((0, 2), dtype=np.int64)
        self.pairs, self.pair_count = np.unique(pairs, axis=0, return_counts=True)
        self.head = head

    def __call__(self, perms: np.ndarray):
        """(violations, total span) of every permutation, ``perms`` shape (P, k)."""
        lo = perms[:, self.pad].min(axis=2)
        hi = perms[:, self.pad].max(axis=2)
        viol = np.zeros(perms.shape[0], dtype=np.int64)
        if self.rows.size:
            c, u, slack = self.rows.T
            zb = perms[:, c]
            hit = (zb >= lo[:, u] - slack) & (zb <= hi[:, u] + slack)
            viol += hit.astype(np.int64) @ self.row_count
        if self.pairs.size:
            i, j = self.pairs.T
            h = self.head
            overlap = (lo[:, i] - h <= hi[:, j] + h) & (lo[:, j] - h <= hi[:, i] + h)
            viol += overlap.astype(np.int64) @ self.pair_count
        return viol, (hi - lo) @ self.count


def _best_order(colours, k, joint_bars, jpos, keepout, joint_pairs, head, keepout_span=None):
    """Order of the k colour classes (class -> layer) with no violation and shortest screws."""
    score = _ClassScore(colours, joint_bars, jpos, keepout, joint_pairs, head, keepout_span)
    if k <= 7:
        perms = np.array(list(itertools.permutations(range(k))), dtype=np.int64)
        v, s = score(perms)
        key = v * 10**9 + s
        i = int(np.argmin(key))
        return perms[i], int(v[i])
    # many layers: pairwise swaps from the identity until no swap improves (deterministic)
    perm = np.arange(k)
    v, s = score(perm[None])
    best = (int(v[0]), int(s[0]))
    improved = True
    while improved:
        improved = False
        for i, j in itertools.combinations(range(k), 2):
            cand = perm.copy()
            cand[[i, j]] = cand[[j, i]]
            v, s = score(cand[None])
            if (int(v[0]), int(s[0])) < best:
                perm, best, improved = cand, (int(v[0]), int(s[0])), True
    return perm, best[0]


def _search_layers(n_bars, conf, joint_bars, head, layer_counts, node_limit=60_000):
    """Depth-first search for layers meeting every rule, fewest layers first.

    Every rule is monotone in a partial assignment (a joint's span only grows as its bars get
    layers), so a rule broken by a partial assignment stays broken and the branch is pruned.
    Returns the layers (E,) or None when every layer count fails or the search has visited
    ``node_limit`` partial assignments in all beyond one per bar and layer count tried (a
    bound on time, about 1 s per 20 000).
    """
    screw = conf.screw_joints.tolist()
    n_nodes = max(screw, default=-1) + 1
    bars_of = {j: jb.tolist() for j, jb in zip(screw, joint_bars)}
    joints_of = [[] for _ in range(n_bars)]
    for j, jb in bars_of.items():
        for b in jb:
            joints_of[b].append(j)
    nbrs = [[] for _ in range(n_bars)]
    for a, b in conf.pairs.tolist():
        nbrs[a].append(b)
        nbrs[b].append(a)
    avoid_of_bar = [[] for _ in range(n_bars)]   # joints whose columns bar b must avoid
    avoiders = {j: [] for j in screw}            # bars that must avoid joint j's column
    for rows, slack in ((conf.keepout, head), (conf.keepout_span, 0)):
        for b, j in rows.tolist():
            avoid_of_bar[b].append((j, slack))
            avoiders[j].append((b, slack))
    partners = {j: [] for j in screw}
    for i, j in conf.joint_pairs.tolist():
        partners[i].append(j)
        partners[j].append(i)
    # static order: breadth first through shared joints from the most constrained bar
    weight = [len(nbrs[b]) + len(avoid_of_bar[b]) for b in range(n_bars)]
    order, seen = [], [False] * n_bars
    for start in sorted(range(n_bars), key=lambda b: (-weight[b], b)):
        if seen[start]:
            continue
        queue = [start]
        seen[start] = True
        while queue:
            b = queue.pop(0)
            order.append(b)
            nxt = sorted({c for j in joints_of[b] for c in bars_of[j]} | set(nbrs[b]),
                         key=lambda c: (-weight[c], c))
            for c in nxt:
                if not seen[c]:
                    seen[c] = True
                    queue.append(c)

    budget = [node_limit]
    for k in layer_counts:
        if budget[0] < 0:
            return None
        # a stacking places every bar once: that pass is not backtracking, and the budget
        # bounds only the backtracking (else a long chain could never be placed at all)
        budget[0] += n_bars
        z = [-1] * n_bars
        lo = [None] * n_nodes
        hi = [None] * n_nodes

        def ok(b, v):
            for c in nbrs[b]:
                if z[c] == v:
                    return False
            for j, sl in avoid_of_bar[b]:
                if lo[j] is not None and lo[j] - sl <= v <= hi[j] + sl:
                    return False
            for j in joints_of[b]:
                l2 = v if lo[j] is None else min(lo[j], v)
                h2 = v if hi[j] is None else max(hi[j], v)
                for c, sl in avoiders[j]:
                    if z[c] >= 0 and l2 - sl <= z[c] <= h2 + sl:
                        return False
                for i in partners[j]:
                    if lo[i] is not None and l2 - head <= hi[i] + head and lo[i] - head <= h2 + head:
                        return False
            return True

        def cost(b, v):
            return sum(0 if lo[j] is None else max(lo[j] - v, v - hi[j], 0) for j in joints_of[b])

        def place(pos):
            if pos == len(order):
                return True
            budget[0] -= 1
            if budget[0] < 0:
                return False
            b = order[pos]
            for v in sorted(range(k), key=lambda v: (cost(b, v), v)):
                if not ok(b, v):
                    continue
                saved = [(j, lo[j], hi[j]) for j in joints_of[b]]
                z[b] = v
                for j in joints_of[b]:
                    lo[j] = v if lo[j] is None else min(lo[j], v)
                    hi[j] = v if hi[j] is None else max(hi[j], v)
                if place(pos + 1):
                    return True
                z[b] = -1
                for j, l0, h0 in saved:
                    lo[j], hi[j] = l0, h0
            return False

        limit = sys.getrecursionlimit()
        sys.setrecursionlimit(max(limit, n_bars + 200))  # one frame per bar placed
        try:
            if place(0):
                return np.array(z, dtype=np.int64)
        finally:
            sys.setrecursionlimit(limit)
    return None


def _shorten_screws(layer, conf, joint_bars, jpos, head, max_rounds=100):
    """Shorter screws for a valid stacking without adding layers (deterministic descent).

    First the best order of its layers (as for colour classes), then the single move (a bar to
    another layer) or, up to :data:`_MILP_BARS` bars, the swap of two bars' layers that shortens
    the screws most, until none does. Every candidate is checked against every rule, so the
    result is as valid as ``layer`` and has no more layers.
    """
    k = int(layer.max()) + 1
    perm, viol = _best_order(layer, k, joint_bars, jpos, conf.keepout, conf.joint_pairs, head,
                             conf.keepout_span)
    if viol == 0:
        layer = perm[layer]
    n_bars = layer.size
    adj = np.zeros((n_bars, n_bars), dtype=np.int64)
    adj[conf.pairs[:, 0], conf.pairs[:, 1]] = 1
    adj |= adj.T
    _, span0 = _score(layer[None], joint_bars, jpos, conf.keepout, conf.joint_pairs, head,
                      conf.keepout_span)
    best = int(span0[0])
    bar_v, val_v = np.repeat(np.arange(n_bars), k), np.tile(np.arange(k), n_bars)
    sa, sb = np.triu_indices(n_bars, k=1) if n_bars <= _MILP_BARS else (np.zeros(0, int),) * 2
    for _ in range(max_rounds):
        # conflict partners of every bar on every layer: a bar may go where it has none
        within = adj @ (layer[:, None] == np.arange(k)[None]).astype(np.int64)  # (E, k)
        move = (val_v != layer[bar_v]) & (within[bar_v, val_v] == 0)
        swap = ((layer[sa] != layer[sb]) & (within[sa, layer[sb]] == adj[sa, sb])
                & (within[sb, layer[sa]] == adj[sa, sb]))
        cand = np.repeat(layer[None], int(move.sum() + swap.sum()), axis=0)
        m = int(move.sum())
        cand[np.arange(m), bar_v[move]] = val_v[move]
        rows = np.arange(m, cand.shape[0])
        cand[rows, sa[swap]], cand[rows, sb[swap]] = layer[sb[swap]], layer[sa[swap]]
        if not cand.shape[0]:
            break
        v, span = _score(cand, joint_bars, jpos, conf.keepout, conf.joint_pairs, head,
                         conf.keepout_span)
        span = np.where(v == 0, span, np.iinfo(np.int64).max)
        i = int(np.argmin(span))  # the first of the shortest: deterministic
        if span[i] >= best:
            break
        layer, best = cand[i], int(span[i])
    return layer


def _neighbourhood(n_bars, conf, joint_bars, seed, size):
    """The layer problem restricted to about ``size`` bars nearest ``seed`` (breadth first over
    conflicts, shared screws and keep-outs); returns ``(n, conf, joint_bars)`` renumbered.

    Every rule of the restriction is implied by a rule of the whole (a screw's span over fewer
    bars is shorter), so no stacking of the whole has fewer layers than the restriction needs.
    """
    nbr = [[] for _ in range(n_bars)]
    for a, b in conf.pairs.tolist():
        nbr[a].append(b)
        nbr[b].append(a)
    jpos = {int(j): i for i, j in enumerate(conf.screw_joints.tolist())}
    for b, j in np.concatenate([conf.keepout, conf.keepout_span]).tolist():
        for c in joint_bars[jpos[j]].tolist():
            nbr[b].append(c)
            nbr[c].append(b)
    keep_set, queue = set(seed), list(seed)
    while queue and len(keep_set) < size:
        b = queue.pop(0)
        for c in sorted(set(nbr[b])):
            if c not in keep_set and len(keep_set) < size:
                keep_set.add(c)
                queue.append(c)
    bars = np.array(sorted(keep_set), dtype=np.int64)
    new = np.full(n_bars, -1, dtype=np.int64)
    new[bars] = np.arange(bars.size)
    pairs = new[conf.pairs]
    pairs = pairs[(pairs >= 0).all(axis=1)]
    sub_joints, sub_bars = [], []
    for j, jb in zip(conf.screw_joints.tolist(), joint_bars):
        inside = new[jb]
        inside = inside[inside >= 0]
        if inside.size:
            sub_joints.append(j)
            sub_bars.append(inside)
    has = set(sub_joints)
    def restrict(rows):
        rows = rows[[new[b] >= 0 and j in has for b, j in rows.tolist()]] if rows.size else rows
        return (np.stack([new[rows[:, 0]], rows[:, 1]], 1) if rows.size
                else rows.reshape(0, 2)).astype(np.int64)

    keep = restrict(conf.keepout)
    jp = conf.joint_pairs[[i in has and j in has for i, j in conf.joint_pairs.tolist()]] \
        if conf.joint_pairs.size else conf.joint_pairs
    sub = Conflicts(pairs=pairs, kind=np.zeros(pairs.shape[0], dtype=object),
                    gap=np.zeros(pairs.shape[0]), sample=np.zeros(pairs.shape[0], dtype=np.int64),
                    keepout=keep, joint_pairs=jp.reshape(-1, 2).astype(np.int64),
                    screw_joints=np.array(sub_joints, dtype=np.int64),
                    keepout_span=restrict(conf.keepout_span))
    return int(bars.size), sub, sub_bars


def _milp_layers(n_bars, conf, joint_bars, head, max_layers, *, time_limit=20.0):
    """Fewest layers (at most ``max_layers``) meeting every rule, by mixed-integer programming
    (HiGHS through SciPy).

    Variables: the layer ``z_b`` of every bar, the lowest and highest layer ``lo_j``, ``hi_j``
    of every screw, the top layer ``top``, and one binary per either-or rule (a conflicting
    pair is ordered one way or the other; a bar passing a screw lies below or above its
    column; two close screws stack one above the other). The objective is
    ``top + eps * (total screw span)``: fewest layers first, then shortest screws.

    Returns
    -------
    layer : numpy.ndarray of int or None
        The best assignment found (None when none was found in the time limit).
    bound : int
        A proven lower bound on the number of layers (from the solver's dual bound).
    optimal : bool
        True when the solver proved its answer: the layer count minimal, or (no layer given)
        that no stacking fits in ``max_layers`` layers, ``bound = max_layers + 1``.
    """
    from scipy.optimize import Bounds, LinearConstraint, milp
    from scipy.sparse import coo_matrix

    E, J = n_bars, len(joint_bars)
    K = int(max_layers)
    pairs, jp = conf.pairs, conf.joint_pairs
    keep = np.concatenate([conf.keepout, conf.keepout_span]).reshape(-1, 2)
    slack = np.r_[np.full(conf.keepout.shape[0], head), np.zeros(conf.keepout_span.shape[0])]
    P, Q, R = pairs.shape[0], keep.shape[0], jp.shape[0]
    # variable layout: z (E) | lo (J) | hi (J) | top (1) | y_pairs (P) | y_keep (Q) | y_joint (R)
    iz, ilo, ihi, itop = 0, E, E + J, E + 2 * J
    iyp = itop + 1
    iyq, iyr = iyp + P, iyp + P + Q
    n = iyr + R
    jidx = {int(j): k for k, j in enumerate(conf.screw_joints.tolist())}
    rows, cols, vals, lb, ub = [], [], [], [], []
    r = 0

    def add(terms, lo_, hi_):
        nonlocal r
        for c, v in terms:
            rows.append(r)
            cols.append(c)
            vals.append(v)
        lb.append(lo_)
        ub.append(hi_)
        r += 1

    inf = np.inf
    for b in range(E):
        add([(iz + b, 1.0), (itop, -1.0)], -inf, 0.0)
    for k, jb in enumerate(joint_bars):
        for b in jb.tolist():
            add([(ilo + k, 1.0), (iz + b, -1.0)], -inf, 0.0)
            add([(iz + b, 1.0), (ihi + k, -1.0)], -inf, 0.0)
    M = float(K + 2 * head + 2)
    for t, (a, b) in enumerate(pairs.tolist()):
        y = iyp + t  # y = 1: a above b
        add([(iz + a, 1.0), (iz + b, -1.0), (iyp + t, -M)], 1.0 - M, inf)
        add([(iz + b, 1.0), (iz + a, -1.0), (y, M)], 1.0, inf)
    for t, (b, j) in enumerate(keep.tolist()):
        k, sl = jidx[j], float(slack[t])
        y = iyq + t  # y = 1: bar above the column
        add([(iz + b, 1.0), (ilo + k, -1.0), (y, -M)], -inf, -sl - 1.0)
        add([(iz + b, 1.0), (ihi + k, -1.0), (y, -M)], sl + 1.0 - M, inf)
    for t, (i, j) in enumerate(jp.tolist()):
        ki, kj = jidx[i], jidx[j]
        y = iyr + t  # y = 0: column i above column j, y = 1: j above i
        add([(ihi + kj, 1.0), (ilo + ki, -1.0), (y, -M)], -inf, -2.0 * head - 1.0)
        add([(ihi + ki, 1.0), (ilo + kj, -1.0), (y, M)], -inf, M - 2.0 * head - 1.0)
    if P:
        # turning a stacking upside down keeps every rule: fix the order of one pair
        add([(iyp, 1.0)], 0.0, 0.0)
    A = coo_matrix((vals, (rows, cols)), shape=(r, n)).tocsr()
    eps = 1.0 / (J * K + 1.0)
    c = np.zeros(n)
    c[itop] = 1.0
    c[ihi:ihi + J] = eps
    c[ilo:ilo + J] = -eps
    lower = np.zeros(n)
    upper = np.ones(n)
    upper[:itop + 1] = K - 1
    integrality = np.ones(n)
    integrality[ilo:itop] = 0  # spans follow from the integer layers
    res = milp(c, constraints=LinearConstraint(A, lb, ub), integrality=integrality,
               bounds=Bounds(lower, upper),
               options={"time_limit": float(time_limit), "disp": False})
    if res.status == 2:  # proven infeasible: every stacking needs more than max_layers
        return None, K + 1, True
    dual = getattr(res, "mip_dual_bound", None)
    bound = int(math.floor(dual + DUAL_BOUND_SLACK)) + 1 if dual is not None and np.isfinite(dual) else 0
    if res.x is None:  # no stacking found in the time; a dual bound past K says no more
        return None, min(bound, K + 1), False
    layer = np.rint(res.x[:E]).astype(np.int64)
    k_found = int(layer.max()) + 1 if E else 0
    return layer, min(bound, k_found), res.status == 0


def plan_layers(edges, sweep: Sweep, settings) -> Stacking:
    """Assign every bar a layer so that nothing collides over the sampled motion.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    sweep : Sweep
        The motion, sampled by :func:`sample_motion` (positions in mm).
    settings : LaserSettings
        Bar width, clearance, sheet thickness, screw entry, spacer diameter, max_layers.

    Returns
    -------
    Stacking

    Raises
    ------
    FabricationError
        When no stacking found keeps bars clear of the screws, or it needs more layers than
        ``max_layers``, or a screw longer than the catalogue has.

    Examples
    --------
    >>> import numpy as np
    >>> from fabkit.fab.laser import laser_settings
    >>> x = np.array([[[0, 0], [100, 0], [100, 100]]], dtype=float)
    >>> sw = Sweep(x, np.zeros(1), 0.5, 0.0, "given", "finished", "")
    >>> plan_layers([[0, 1], [1, 2]], sw, laser_settings()).layer.tolist()
    [0, 1]
    """
    edges = np.asarray(edges, dtype=np.int64)
    s = settings
    column_radius = 0.5 * s.screw.head_diameter
    spacer_radius = 0.5 * s.spacer_diameter
    # Where the samples are farther apart than the guarantee assumes (a chain at float
    # resolution, see sample_motion's floor_limit), widen the clearance by the excess so that
    # parts of one layer stay clearance / 2 apart between samples all the same.
    clearance = s.clearance + max(0.0, sweep.max_step - sweep.step_limit)
    conf = sweep.conflicts if sweep.conflicts is not None else find_conflicts(
        edges, sweep.positions, width=s.bar_width, clearance=clearance,
        column_radius=column_radius, spacer_radius=spacer_radius)
    head = int(math.ceil(s.screw.head_height / s.thickness - HEAD_LAYERS_SLACK))
    n_bars = edges.shape[0]
    inc = _incidence(edges, sweep.positions.shape[1])
    joint_bars = [np.flatnonzero(inc[j]) for j in conf.screw_joints]
    jpos = np.full(sweep.positions.shape[1], -1, dtype=np.int64)
    jpos[conf.screw_joints] = np.arange(conf.screw_joints.size)
    colourings, clique, clique_bars = _colourings(n_bars, conf.pairs)
    candidates, seen = [], set()
    for strategy, colours in colourings:
        if colours.tobytes() in seen:  # strategies often agree; order each colouring once
            continue
        seen.add(colours.tobytes())
        k = int(colours.max()) + 1 if n_bars else 0
        if joint_bars:
            perm, viol = _best_order(colours, k, joint_bars, jpos, conf.keepout,
                                     conf.joint_pairs, head, conf.keepout_span)
        else:
            perm, viol = np.arange(k), 0
        layer = perm[colours]
        span = sum(int(layer[jb].max() - layer[jb].min()) for jb in joint_bars)
        candidates.append((viol, k, span, strategy, layer))
    viol, k, span, strategy, layer = min(candidates, key=lambda c: c[:3])
    if viol:
        # The column rules tie layers to their order: search layer numbers directly.
        found = _search_layers(n_bars, conf, joint_bars, head,
                               range(max(int(clique), 1), s.max_layers + 1))
        if found is not None:
            layer, strategy, viol = found, "backtracking", 0
            k = int(layer.max()) + 1
    elif k > clique:
        # The colourings stop above the clique bound; the search often reaches it in a fraction
        # of a second, where the exact solver needs its whole time limit to find the same count
        # (it proves nothing the clique does not already prove once the count meets it).
        found = _search_layers(n_bars, conf, joint_bars, head, range(max(int(clique), 1), k))
        if found is not None:
            layer = _shorten_screws(found, conf, joint_bars, jpos, head)
            strategy, k = "backtracking", int(layer.max()) + 1
    bound, proven = int(clique), (not viol and k == clique)
    if not proven and n_bars:
        # Colouring ignores the column rules and the search stops at its budget: ask the exact
        # solver for a stacking with fewer layers; its dual bound is a proven lower bound.
        fewer = s.max_layers if viol else k - 1
        for size in () if viol else _MILP_STEPS:
            if size >= min(n_bars, _MILP_BARS) or k <= bound:
                break
            sub = _neighbourhood(n_bars, conf, joint_bars, clique_bars, size)
            _, sub_bound, _ = _milp_layers(*sub, head, fewer, time_limit=_MILP_STEP_SECONDS)
            bound = max(bound, sub_bound)
        if viol or k > bound:  # not proven by a small neighbourhood
            if n_bars > _MILP_BARS:
                # A few bars around the largest clique with only the rules among them: a
                # relaxation of the whole problem, so its proven bound holds for the whole.
                sub = _neighbourhood(n_bars, conf, joint_bars, clique_bars, _MILP_BARS)
                _, sub_bound, _ = _milp_layers(*sub, head, fewer, time_limit=_MILP_SECONDS)
                bound = max(bound, sub_bound)
            else:
                found, milp_bound, optimal = _milp_layers(n_bars, conf, joint_bars, head,
                                                          fewer, time_limit=_MILP_SECONDS)
                if found is not None:
                    layer, k, viol, strategy = found, int(found.max()) + 1, 0, "milp"
                bound = max(bound, milp_bound)
        proven = not viol and k == bound
    if viol:
        x0 = sweep.positions[0][conf.screw_joints]
        d0 = np.sqrt(((x0[:, None] - x0[None]) ** 2).sum(-1))
        np.fill_diagonal(d0, np.inf)
        i, j = np.unravel_index(np.argmin(d0), d0.shape) if d0.size else (0, 0)
        if d0.size and d0[i, j] < 2 * column_radius:
            ji, jj = int(conf.screw_joints[i]), int(conf.screw_joints[j])
            raise FabricationError(
                f"joints {ji} and {jj} are {d0[i, j]:.3g} mm apart at the start, closer than "
                f"two screw heads ({2 * column_radius:g} mm), and no stacking within "
                f"max_layers = {s.max_layers} separates their screws; merge them in the "
                "design, or for chains of modules try mirror = \"alternate\"")
        if bound > s.max_layers:
            raise FabricationError(
                f"every stacking of these bars needs at least {bound} layers (proven by exact "
                f"search), more than max_layers = {s.max_layers}: "
                + _violation_message(layer, joint_bars, conf, head, edges))
        raise FabricationError(
            f"no stacking found within max_layers = {s.max_layers} in the {_MILP_SECONDS:g} s "
            f"exact search (at least {bound} layers are needed): "
            + _violation_message(layer, joint_bars, conf, head, edges))
    if k > s.max_layers:
        raise FabricationError(
            f"the bars need {k} stacking layers (more than max_layers = {s.max_layers}); raise "
            "max_layers, or make room: larger scale or narrower bars")
    stacks = []
    from .hardware import fit_screw

    for j, jb in zip(conf.screw_joints.tolist(), joint_bars):
        order = np.argsort(layer[jb], kind="stable")
        bars = tuple(int(v) for v in jb[order])
        layers = tuple(int(v) for v in layer[jb][order])
        lo, hi = layers[0], layers[-1]
        spacers = tuple(z for z in range(lo, hi + 1) if z not in layers)
        height = (hi - lo + 1) * s.thickness
        try:  # the screw must close on the thickest sheets the tolerance allows
            fit = fit_screw(s.screw, hi - lo + 1, s.thickness, s.thickness_tolerance)
        except FabricationError as exc:
            raise FabricationError(f"joint {j}: {exc}") from None
        stacks.append(JointStack(joint=j, bars=bars, layers=layers, spacers=spacers,
                                 stack_height=height, screw_length=fit.length,
                                 play=fit.length - height, washers=fit.washers,
                                 play_range=(fit.play_min, fit.play_max)))
    return Stacking(layer=layer, n_layers=k, joints=tuple(stacks), conflicts=conf,
                    lower_bound=int(bound), strategy=strategy, head_slots=head,
                    stats={"candidates": [(c[3], c[1], c[0]) for c in candidates],
                           "clique": int(clique), "proven_minimal": bool(proven)})


def _violation_message(layer, joint_bars, conf, head, edges) -> str:
    jpos = {int(j): i for i, j in enumerate(conf.screw_joints)}
    lo = {j: int(layer[joint_bars[i]].min()) for j, i in jpos.items()}
    hi = {j: int(layer[joint_bars[i]].max()) for j, i in jpos.items()}
    for b, j, sl in [(b, j, head) for b, j in conf.keepout.tolist()] + \
            [(b, j, 0) for b, j in conf.keepout_span.tolist()]:
        if lo[j] - sl <= layer[b] <= hi[j] + sl:
            i0, i1 = edges[b]
            return (f"bar {b} (joints {i0}-{i1}) passes the screw at joint {j} during the "
                    "motion; use a larger scale or narrower bars, or raise max_layers")
    for i, j in conf.joint_pairs.tolist():
        return (f"the screws at joints {i} and {j} come too close during the motion and no "
                "stacking separates them; the joints may coincide (for chains try mirror = "
                "\"alternate\") or use a larger scale")
    return "no collision-free stacking found"


def stacking_gaps(edges, layer, positions, *, width: float, joints=(), head_slots: int = 1,
                  column_radius: float = 0.0, spacer_radius: float | None = None) -> dict:
    """Smallest gaps between parts that share a layer, over sampled configurations.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    layer : array_like of int, shape (E,)
    positions : array_like, shape (S, N, 2)
        Configurations in mm.
    width : float
    joints : sequence of JointStack
        Screws to check bars and other screws against (none: bars only).
    head_slots : int
    column_radius : float
        Radius of the screw heads (they occupy ``head_slots`` layers above and below a stack).
    spacer_radius : float, optional
        Radius of the spacer rings, checked against bars on the stack's own layers.

    Returns
    -------
    dict
        ``bar_gap`` (mm, smallest outline gap between non-adjacent bars of one layer; inf when
        no two share a layer), ``bar_pair`` and ``sample`` where it occurs; ``screw_gap``
        (smallest gap from a bar to a screw column whose layers it occupies) and
        ``column_gap`` (between screw columns that share layers).
    """
    edges = np.asarray(edges, dtype=np.int64)
    layer = np.asarray(layer)
    x = np.asarray(positions, dtype=np.float64)
    inc = _incidence(edges, x.shape[1])
    out = {"bar_gap": math.inf, "bar_pair": None, "sample": None,
           "screw_gap": math.inf, "column_gap": math.inf}
    # Only the smallest gap of each kind is reported, exactly: pairs are taken from their swept
    # boxes, nearest first (a segment distance is never below its boxes' distance), and of
    # those, pairs that cannot reach the minimum are measured at every 32nd sample only (see
    # _least). The whole kit's pairs, quadratic in its size, are never formed.
    lo_n, hi_n = x.min(axis=0), x.max(axis=0)
    bar_lo = np.minimum(lo_n[edges[:, 0]], lo_n[edges[:, 1]])
    bar_hi = np.maximum(hi_n[edges[:, 0]], hi_n[edges[:, 1]])
    whole = float(np.hypot(*(hi_n.max(axis=0) - lo_n.min(axis=0)))) + 1.0

    def bar_pairs(reach):
        a, b = _box_pairs(bar_lo, bar_hi, bar_lo, bar_hi, reach, same=True)
        keep = (layer[a] == layer[b]) & ~_share_joint(edges, a, b)
        return a[keep], b[keep]

    gap, k, where, (a, b) = _exact_least(_bar_bar(edges), x, width, bar_pairs,
                                         lambda g: g + width, 2.0 * width, whole)
    if k >= 0:
        out.update(bar_gap=gap, bar_pair=[int(a[k]), int(b[k])], sample=where)
    if joints:
        js = list(joints)
        span = {st.joint: (min(st.layers) - head_slots, max(st.layers) + head_slots) for st in js}
        bb, jj = [], []
        for st in js:
            z0, z1 = span[st.joint]
            inside = (layer >= z0) & (layer <= z1) & ~inc[st.joint]
            bb.extend(np.flatnonzero(inside).tolist())
            jj.extend([st.joint] * int(inside.sum()))
        if bb:
            bb, jj = np.array(bb), np.array(jj)
            radius = np.full(bb.size, column_radius)
            if spacer_radius is not None:
                # on the stack's own layers the spacer rings are the wider part of the column
                z0 = np.array([span[j][0] + head_slots for j in jj.tolist()])
                z1 = np.array([span[j][1] - head_slots for j in jj.tolist()])
                inner = (layer[bb] >= z0) & (layer[bb] <= z1)
                radius[inner] = max(column_radius, spacer_radius)
            out["screw_gap"], _, _ = _least(
                lambda xs, bi, ji: point_segment_distance(xs[:, ji], xs[:, edges[bi, 0]],
                                                          xs[:, edges[bi, 1]]),
                x, 0.5 * width + radius, bb, jj)
        pa, pb = [], []
        for s1, s2 in itertools.combinations(js, 2):
            (a0, a1), (b0, b1) = span[s1.joint], span[s2.joint]
            if a0 <= b1 and b0 <= a1:
                pa.append(s1.joint)
                pb.append(s2.joint)
        if pa:
            pa, pb = np.array(pa), np.array(pb)
            out["column_gap"], _, _ = _least(
                lambda xs, i1, i2: np.sqrt(((xs[:, i1] - xs[:, i2]) ** 2).sum(-1)), x,
                2.0 * column_radius, pa, pb)
    return out
