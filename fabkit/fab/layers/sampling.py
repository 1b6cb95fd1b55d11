"""Sampling the motion finely enough that nothing can collide between samples."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...design.assemble import chain
from ...errors import FabricationError
from ...kinematics import trace
from ...kinematics.base import align_to_gauge, make_problem
from ...kinematics.constructive import place, plan_construction
from .conflicts import closer_than, Conflicts, find_conflicts
from .constants import MAX_SAMPLES, STEP_RTOL
from .distances import bar_distance_kernel, min_over_samples, node_steps, point_segment_distance

#: The share of the step limit a projected trace bounds each node's move by: the bound holds to
#: first order, so a tenth inside it is met in one trace (the Motion stage traces a laser kit's
#: motion so, :func:`fabkit.fab.laser_plan.trace_needs`).
NODE_STEP_SHARE = 0.9

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


def sample_motion(net, motion, scale: float, step_limit: float, *,
                  floor_limit: float | None = None, trajectory=None) -> Sweep:
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
    trajectory : Trajectory, optional
        The motion of ``net`` as ``motion`` asks, traced once by the Motion stage
        (:class:`fabkit.motion.TracedMotion`); traced here when not given.

    Returns
    -------
    Sweep
        Positions in mm. With the constructive method samples are placed exactly and refined
        by bisection where a step is too long; other methods are re-traced with a maximum
        step small enough (a denser trace than the motion's own: the collision check needs
        it).

    Raises
    ------
    FabricationError
        No motion target, or the bound cannot be met within 200 000 samples.
    """
    if motion.to is None:
        raise FabricationError("the template gives no [motion] target (motion.to): the stacking "
                               "layers are planned over the motion, so it must be known")
    traj = trajectory if trajectory is not None else trace(
        net, drive=motion.drive, to=motion.to, method=motion.method, hold=motion.hold,
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
    elif trajectory is not None and traj.positions.shape[0] > 1 \
            and float(node_steps(traj.positions).max(initial=0.0)) <= limit:
        # the Motion stage traced it as densely as the stacking needs (fabkit.fab.plans
        # trace_needs): planned along that one trace, never re-traced; a copy, since the
        # samples are scaled to mm in place below and the trace is every stage's
        x, drive = np.array(traj.positions, dtype=np.float64), np.array(traj.drive)
    else:
        # Re-trace with a step bound: the projected method bounds each node's move (fine where
        # a few nodes move fast, coarse elsewhere: the and-gate needs 2 000 samples where a bound
        # on the arclength of the whole network takes 20 000); others bound the arclength (a node
        # moves at most that far). Shrink it while the steps met still move nodes too far (the
        # bound is to first order, and a tracer that holds another gauge refits rigidly).
        opts = dict(motion.options)
        key = "max_node_step" if traj.method == "projected" else "step"
        # the node bound holds to first order: a tenth below the limit, one trace usually meets it
        step = min(NODE_STEP_SHARE * limit if key == "max_node_step" else limit,
                   opts.get(key) or np.inf)
        for _ in range(6):
            opts[key] = step
            traj = trace(net, drive=motion.drive, to=motion.to, method=traj.method,
                         hold=motion.hold, **opts)
            worst = float(node_steps(traj.positions).max(initial=0.0))
            if worst <= limit:
                break
            step *= NODE_STEP_SHARE * limit / worst
        x, drive = traj.positions, traj.drive
    steps = node_steps(x)
    max_step = float(steps.max() * scale) if steps.size else 0.0
    if max_step > max(step_limit, floor_limit or 0.0) * (1 + STEP_RTOL):
        raise FabricationError(
            f"the {traj.method} trace moves a node {max_step:.3g} mm between samples, more than "
            f"the {step_limit:g} mm the collision check needs; use method = \"constructive\"")
    x = np.ascontiguousarray(x, dtype=np.float64)
    x *= scale  # in place: the samples of a long chain are the largest array of the kit
    return Sweep(positions=x, drive=np.asarray(drive),
                 step_limit=float(step_limit), max_step=max_step, method=traj.method,
                 status=str(traj.status), message=traj.message)


def _refine(placer, values, limit: float, scale: float, floor_limit, drive_name: str):
    """Bisect drive values until no node moves more than ``limit`` (design units) per step.

    ``placer(values) -> (S, N, d)`` places configurations. Intervals between adjacent floats
    whose step is within ``floor_limit`` mm are accepted; others raise. Returns values, x.
    """
    x = placer(values)
    for _ in range(80):
        steps = node_steps(x)
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
        if values.size + bad.size > MAX_SAMPLES:
            raise FabricationError(
                f"sampling the motion to {limit * scale:g} mm steps needs more than "
                f"{MAX_SAMPLES} samples; raise the clearance or check the motion")
        # only the new midpoints are placed (each configuration is placed on its own, so the
        # samples are the same as placing all of them again)
        mids = 0.5 * (values[bad] + values[bad + 1])
        x = np.insert(x, bad + 1, placer(mids), axis=0)
        values = np.insert(values, bad + 1, mids)
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
                 spacer_radius: float | None = None, trajectory=None) -> Sweep | None:
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
        A 2D chain built by :func:`fabkit.design.assemble.chain` (it remembers its layout).
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
    floor_limit, trajectory : optional
        See :func:`sample_motion`.

    Returns
    -------
    Sweep or None
        ``conflicts`` set and ``positions`` the chain's trace in mm; None when the network is
        not such a chain (then use :func:`sample_motion`).
    """
    layout = net.assembly
    if (layout is None or net.dim != 2 or motion.drive != "d1" or motion.hold
            or motion.to is None):
        return None
    copies = layout.copies
    n = len(copies)
    outs = _module_ports(net, copies)
    if outs is None:
        return None
    traj = trajectory if trajectory is not None else trace(
        net, drive="d1", to=motion.to, method=motion.method, **motion.options)
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
        steps = node_steps(x)
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
    steps = node_steps(traj.positions)
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
    d, _ = min_over_samples(bar_distance_kernel(edges), x, pa, pb)
    close = closer_than(d - width, clearance)
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
        d, _ = min_over_samples(
            lambda xs, bi, ji: point_segment_distance(xs[:, ji], xs[:, edges[bi, 0]],
                                                      xs[:, edges[bi, 1]]), x, bj, jj)
        near = closer_than(d - 0.5 * width - column_radius, clearance)
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
        d, _ = min_over_samples(
            lambda xs, i1, i2: np.sqrt(((xs[:, i1] - xs[:, i2]) ** 2).sum(-1)), x, ja, jb)
        near = closer_than(d - 2.0 * column_radius, clearance)
        jp = np.stack([ja[near], jb[near]], 1)
    return pairs.astype(np.int64), keep.astype(np.int64), jp.astype(np.int64)


