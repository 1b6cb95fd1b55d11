"""As-built check of a print-in-place bar linkage, read back from its STL or 3MF beds.

From the meshes alone (with the design for its settings and its placement on the beds,
:mod:`fabkit.check.beds`):

* **bodies**: one closed, consistently wound shell per bar, nothing fused (trimesh), with the
  exact volume of the bars and pins (relative :data:`VOLUME_RTOL`);
* **bars**: each body's lowest slab is a bar: its height a whole number of layers on a layer of
  the stack (``z = layer x pitch``); a cross-section through it gives the outline (its width)
  and the holes; a cross-section just above it the pins the bar carries; every bar has two
  joints, each a hole or a pin;
* **pins -> joints**: holes and pins that share a centre are one joint; every joint of two or
  more bars has exactly one pin (but the joints where the print is cut between pieces);
* **pin clearance**: the smallest radial gap between a pin and a hole around it (the hole's
  inscribed circle less the pin's circumscribed one less their offset), at least
  ``pin_clearance``;
* **caps hold**: above the top bar of every pin a cap wider than that bar's hole;
* **layer gaps**: one ``layer_gap`` above and below every bar on a pin, the pin's body is no
  wider than the pin (its collars and cap keep clear of the bars), and stacked bars are a gap
  apart (pitch less thickness);
* **rebuilt network**: the joints, moved back from the bed into the design's frame, match the
  design's nodes (:data:`NODE_TOL_MM`), the bars join the designed joints with the designed
  lengths (:data:`LENGTH_TOL_MM`), and the network has the design's conformational motion;
* **motion**: the motion is re-simulated on the rebuilt network (its joints refitted to the
  read-back lengths where they differ from the design's by more than the files' float32
  resolution) and compared with the design's; then, sampled more finely than the stacking was
  planned (no node moves more than a quarter of the clearance between samples), no two bars of
  one layer come closer than half the clearance, and no bar enters the layers of a pin's
  collars or cap nearby (:func:`fabkit.fab.layers.stacking_gaps`, with the layers, widths and
  cap radii read back).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import FabkitError

__all__ = ["check_pinned", "read_bar", "VOLUME_RTOL", "NODE_TOL_MM", "LENGTH_TOL_MM"]

#: Relative tolerance between the bodies' volume and the exact volume of bars and pins.
VOLUME_RTOL = 1e-6
#: Largest distance (mm) between a rebuilt joint and the design's node.
NODE_TOL_MM = 1e-2
#: Largest difference (mm) between a read-back bar length and the design's: STL and 3MF store
#: float32, whose rounding at 300 mm from the origin is 3e-5 mm.
LENGTH_TOL_MM = 1e-3
#: Read-back lengths within this of the design's (mm) are the design's: float32 rounding of
#: coordinates on a bed, averaged over a hole's or pin's polygon.
FILE_RESOLUTION_MM = 2e-4
#: Heights and radii read back agree with the settings within this (mm): float32 rounding.
MEASURE_TOL_MM = 1e-3
#: Feature centres closer than this (mm) are one joint.
JOINT_TOL_MM = 0.05
#: Largest difference between the re-simulated and the designed port distances, relative to the
#: network's size (design units).
MAP_RTOL = 1e-6


#: Work shared by the checks of one export's files (its STL and its 3MF rebuild the same
#: network): results of pure functions, keyed by everything they depend on; a few entries only.
_MEMO: dict = {}
_MEMO_SIZE = 4


def _memo(key, compute):
    if key not in _MEMO:
        while len(_MEMO) >= _MEMO_SIZE:
            _MEMO.pop(next(iter(_MEMO)))
        _MEMO[key] = compute()
    return _MEMO[key]


def _design_key(design, s) -> tuple:
    net = design.network
    m = design.motion
    return (design.name, str(design.path), net.nodes.tobytes(), net.edges.tobytes(),
            repr(sorted(net.ports.items())), repr((m.drive, m.to, m.method, m.hold, m.options)), s)


def _check(name, ok, value=None, limit=None, detail=""):
    return {"name": name, "ok": bool(ok), "value": value, "limit": limit, "detail": detail}


def _ring_centre(coords) -> np.ndarray:
    return np.asarray(coords, dtype=np.float64)[:-1, :2].mean(axis=0)


def read_bar(body, s) -> dict:
    """What one body says about its bar (mm, print frame).

    Returns
    -------
    dict
        ``z0`` (underside), ``thickness``, ``width``, ``holes`` (list of (centre, inradius,
        circumradius)), ``pins`` (list of (centre, circumradius)), ``outline`` (shapely
        polygon), ``problem`` (str or None).
    """
    import shapely

    from .stl import _section

    z = np.asarray(body.vertices)[:, 2]
    z0 = float(z.min())
    levels = np.unique(np.round(z, 4))
    out = {"z0": z0, "thickness": None, "width": None, "holes": [], "pins": [],
           "outline": None, "problem": None}
    if len(levels) < 2:
        out["problem"] = "flat body"
        return out
    t = float(levels[1] - levels[0])
    out["thickness"] = t
    slab = _section(body, z0 + 0.5 * t)
    if len(slab) != 1:
        out["problem"] = f"{len(slab)} pieces in the bar's cross-section, not 1"
        return out
    poly = slab[0]
    out["outline"] = poly
    for ring in poly.interiors:
        c = _ring_centre(ring.coords)
        pts = np.asarray(ring.coords)[:-1, :2]
        inner = float(shapely.distance(shapely.points(c), shapely.LineString(ring.coords)))
        out["holes"].append((c, inner, float(np.hypot(*(pts - c).T).max())))
    for pin in _section(body, z0 + t + 0.5 * s.layer_gap):
        c = _ring_centre(pin.exterior.coords)
        pts = np.asarray(pin.exterior.coords)[:-1, :2]
        out["pins"].append((c, float(np.hypot(*(pts - c).T).max())))
    ends = [h[0] for h in out["holes"]] + [p[0] for p in out["pins"]]
    if len(ends) != 2:
        out["problem"] = f"{len(out['holes'])} holes and {len(out['pins'])} pins, not two joints"
        return out
    a, b = ends
    ext = np.asarray(poly.exterior.coords)[:-1, :2]
    from ..fab.layers import point_segment_distance

    d = point_segment_distance(ext[None], a[None], b[None])
    out["width"] = 2.0 * float(np.max(d))
    return out


def _unplaced_bodies(meshes, names, plan, checks):
    """Every body read back, moved from its bed into the print frame, with its piece."""
    from .beds import assign_bodies, split_bodies, unplace

    bodies = []
    for b, mesh in enumerate(meshes):
        on_bed = [p for p in plan.layout if p.bed == b]
        owners = assign_bodies(split_bodies(mesh), on_bed)
        stray = owners.pop(-1, [])
        if stray:
            checks.append(_check(f"{names[b]}: bodies in place", False, len(stray), 0,
                                 "bodies outside every piece's place on the bed"))
        for piece, found in owners.items():
            m = plan.placement_matrix(piece)
            bodies += [(piece, unplace(body, m)) for body in found]
    return bodies


def _joints(bars, plan):
    """Cluster holes and pins by centre: each cluster is a joint."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    feats = []  # (bar, kind, centre, inner, outer)
    for k, bar in enumerate(bars):
        feats += [(k, "hole", c, r_in, r_out) for c, r_in, r_out in bar["holes"]]
        feats += [(k, "pin", c, r_out, r_out) for c, r_out in bar["pins"]]
    centres = np.array([f[2] for f in feats]).reshape(-1, 2)
    pairs = cKDTree(centres).query_pairs(JOINT_TOL_MM, output_type="ndarray")
    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                     shape=(len(feats),) * 2)
    n, label = connected_components(adj, directed=False)
    joints = [[feats[i] for i in np.flatnonzero(label == j)] for j in range(n)]
    return joints, label, feats


def _gap_probe(carrier, centre, z, s) -> float:
    """How far from the pin's axis the carrier's body reaches at height ``z`` near the pin (mm);
    0 when it has nothing there."""
    import shapely

    from .stl import _section

    reach = 0.0
    disc = shapely.Point(*centre).buffer(0.5 * s.cap_diameter + s.nozzle_width)
    for poly in _section(carrier, z):
        part = poly.intersection(disc)
        if part.is_empty:
            continue
        pts = shapely.get_coordinates(part.boundary)
        reach = max(reach, float(np.hypot(*(pts - centre).T).max()))
    return reach


def check_pinned(meshes, names, design, s, report, motion=None) -> dict:
    """The as-built check of a print-in-place linkage (see the module docstring).

    Parameters
    ----------
    meshes : list of trimesh.Trimesh
        The beds as read back (bed coordinates, mm), in bed order.
    names : list of str
    design : Design
    s : PrintSettings
        ``linkage = "pins"``.
    report : dict
        Filled in and returned, with ``ok`` and ``checks``.
    motion : TracedMotion, optional
        The design's motion traced once by the pipeline (its window, and the trace the rebuilt
        linkage's motion is compared with); traced here when not given.

    Returns
    -------
    dict
    """
    from ..fab.pinned import pinned_print, printed_design

    try:
        plan = _memo(("plan",) + _design_key(design, s), lambda: pinned_print(design, s, motion))
        # the linkage is judged against the design as it prints: its motion from motion_from
        # to motion_to, where the template sets them (the pipeline's window, traced once)
        kit = None if motion is None else motion.window_motion(s.motion_from, s.motion_to,
                                                               "print")
        design = kit.design if kit is not None else _memo(
            ("window",) + _design_key(design, s), lambda: printed_design(design, s))
    except FabkitError as exc:
        report.update(ok=False, checks=[_check("design prints", False, detail=str(exc))])
        return report
    checks = []
    if len(meshes) != plan.beds:
        checks.append(_check("bed files", False, len(meshes), plan.beds,
                             f"the design prints on {plan.beds} bed(s) with these settings"))
        report.update(ok=False, checks=checks)
        return report
    placed = _unplaced_bodies(meshes, names, plan, checks)
    bodies = [b for _, b in placed]
    closed = [b.is_watertight and b.is_winding_consistent and b.volume > 0 for b in bodies]
    checks.append(_check("one closed body per bar", len(bodies) == plan.n_bars and all(closed),
                         value=len(bodies), limit=plan.n_bars,
                         detail=f"{sum(closed)} of {len(bodies)} bodies watertight, consistently "
                                "wound, outward; none shares a vertex with another"))
    volume = float(sum(b.volume for b in bodies))
    exact = float(plan.volumes.sum())
    rel = abs(volume - exact) / exact
    checks.append(_check("volume = bars and pins", rel <= VOLUME_RTOL, value=rel,
                         limit=VOLUME_RTOL,
                         detail=f"bodies {volume:.9g} mm^3, exact {exact:.9g} mm^3"))
    bars = [read_bar(b, s) for b in bodies]
    bad = [f"body {k}: {b['problem']}" for k, b in enumerate(bars) if b["problem"]]
    pitch = s.layer_pitch
    layer = np.array([round(b["z0"] / pitch) for b in bars], dtype=np.int64)
    off_layer = max((abs(b["z0"] - lz * pitch) for b, lz in zip(bars, layer)), default=0.0)
    thick = max((abs(b["thickness"] - s.bar_thickness) for b in bars
                 if b["thickness"] is not None), default=0.0)
    widths = [b["width"] for b in bars if b["width"] is not None]
    wide = max((abs(w - s.bar_width) for w in widths), default=0.0)
    checks.append(_check(
        "bars read back", not bad and max(off_layer, thick, wide) <= MEASURE_TOL_MM,
        value=round(max(off_layer, thick, wide), 9), limit=MEASURE_TOL_MM,
        detail="; ".join(bad[:3]) or f"{len(bars)} bars on {int(layer.max(initial=-1)) + 1} "
                                      f"layers of {pitch:g} mm; largest error of height, "
                                      f"thickness and width (mm)"))
    if bad or len(bodies) != plan.n_bars:
        report.update(ok=False, checks=checks)
        return report
    joints, label, feats = _joints(bars, plan)
    problems, clear, hold = [], math.inf, math.inf
    cap_radius, head_slots = 0.0, 1
    pin_of = {}
    for jfeats in joints:
        pins = [f for f in jfeats if f[1] == "pin"]
        holes = [f for f in jfeats if f[1] == "hole"]
        if len(pins) > 1:
            problems.append(f"{len(pins)} pins in one joint")
            continue
        if not pins:
            continue
        pk, _, pc, _, pr = pins[0]
        pin_of[tuple(np.round(pc, 3))] = (pk, pc, jfeats)
        for hk, _, hc, hin, hout in holes:
            clear = min(clear, hin - pr - float(np.hypot(*(hc - pc))))
        if holes:
            top = max(holes, key=lambda f: bars[f[0]]["z0"])
            cap_top, cap_in, cap_out = _cap(bodies[pk], pc, s)
            hold = min(hold, cap_in - top[4])
            cap_radius = max(cap_radius, cap_out)
            above = cap_top - bars[top[0]]["z0"] - bars[top[0]]["thickness"]
            head_slots = max(head_slots, math.ceil(above / pitch - MEASURE_TOL_MM))
    unpinned = [jf for jf in joints if len(jf) >= 2 and not any(f[1] == "pin" for f in jf)]
    ok = (not problems and len(joints) == design.network.n_nodes
          and len(pin_of) == len(plan.carrier) and len(unpinned) == len(plan.cut_joints))
    checks.append(_check("pins -> joints", ok,
                         value=[len(joints), len(pin_of)],
                         limit=[design.network.n_nodes, len(plan.carrier)],
                         detail="; ".join(problems[:3]) or
                                f"{len(joints)} joints from {len(feats)} holes and pins; "
                                f"{len(pin_of)} printed pins, {len(unpinned)} joints without "
                                "one (cut between pieces)"))
    # a gap of zero or less is a pin fused to its hole, whatever tolerance the measure has
    checks.append(_check("pin clearance", clear >= s.pin_clearance - MEASURE_TOL_MM and clear > 0,
                         value=None if math.isinf(clear) else round(clear, 6),
                         limit=s.pin_clearance,
                         detail="smallest radial gap (mm) between a pin and a hole around it"
                                + ("; none: the pin touches or overlaps its hole" if clear <= 0
                                   else "")))
    need_hold = 0.5 * s.nozzle_width
    checks.append(_check("caps hold the bars", hold >= need_hold,
                         value=None if math.isinf(hold) else round(hold, 6), limit=need_hold,
                         detail="smallest overlap (mm) of a cap over the top bar's hole on its "
                                "pin"))
    checks.append(_layer_gap_check(pin_of, bars, bodies, s))
    net = _rebuilt_network(design, plan, joints, bars, checks, s)
    if net is None:
        report.update(ok=False, checks=checks)
        return report
    _, edge_layer, lengths, dev = net
    report["as_built"] = {"bars": len(bars), "joints": len(joints), "printed_pins": len(pin_of),
                          "layers": int(layer.max()) + 1, "node_deviation_mm": dev,
                          "pin_clearance_mm": None if math.isinf(clear) else clear,
                          "cap_overlap_mm": None if math.isinf(hold) else hold}
    # sizes to the files' resolution: the STL and 3MF of one export then share one simulation
    measured = {"width": _to_resolution(max(widths)),
                "cap_radius": _to_resolution(cap_radius or 0.5 * s.cap_diameter),
                "head_slots": head_slots}
    x_mm = _joints_mm(design.network, lengths, s)
    key = ("motion",) + _design_key(design, s) + (
        x_mm.tobytes(), edge_layer.tobytes(), tuple(sorted(measured.items())))
    try:
        reference = None if kit is None else kit.trajectory
        moved, facts = _memo(key, lambda: _motion_checks(design, edge_layer, x_mm, s,
                                                        measured, reference))
    except FabkitError as exc:  # the rebuilt network cannot be simulated or sampled
        moved, facts = [_check("motion re-simulated", False, detail=str(exc))], {}
    checks += moved
    report.update(facts)
    report.update(ok=all(c["ok"] for c in checks), checks=checks)
    return report


def _cap(carrier, centre, s) -> tuple[float, float, float]:
    """The cap on the pin at ``centre``: its top (mm), inscribed and circumscribed radii (the
    carrier's cross-section half a layer below the top); radii 0 when there is none."""
    import shapely

    from .stl import _section

    v = np.asarray(carrier.vertices)
    near = np.hypot(*(v[:, :2] - centre).T) <= 0.5 * s.cap_diameter + MEASURE_TOL_MM
    top = float(v[near, 2].max())
    point = shapely.Point(*centre)
    for poly in _section(carrier, top - 0.5 * s.layer_height):
        if poly.contains(point):
            ring = np.asarray(poly.exterior.coords)[:-1, :2]
            return (top, float(shapely.distance(point, poly.exterior)),
                    float(np.hypot(*(ring - centre).T).max()))
    return top, 0.0, 0.0


def _layer_gap_check(pin_of, bars, bodies, s) -> dict:
    """Within one layer gap of every bar on a pin, the pin's body is no wider than the pin."""
    eps = 0.25 * s.layer_height
    worst, where = 0.0, None
    for pk, pc, jfeats in pin_of.values():
        for hk, kind, *_ in jfeats:
            if kind != "hole":
                continue
            z0 = bars[hk]["z0"]
            for z in (z0 + bars[hk]["thickness"] + s.layer_gap - eps, z0 - s.layer_gap + eps):
                reach = _gap_probe(bodies[pk], pc, z, s)
                if reach > worst:
                    worst, where = reach, (hk, z)
    pitch_gap = s.layer_pitch - max(b["thickness"] for b in bars)
    limit = 0.5 * s.pin_diameter + MEASURE_TOL_MM
    ok = worst <= limit and pitch_gap >= s.layer_gap - MEASURE_TOL_MM
    return _check("layer gaps", ok, value=round(worst, 6), limit=round(limit, 6),
                  detail=f"widest reach (mm) of a pin's body from its axis within "
                         f"{s.layer_gap - eps:g} mm above or below a bar on the pin (the pin's "
                         f"radius: collars and caps keep their gap)"
                         f"{'' if ok or where is None else f', exceeded at {where[1]:.3f} mm'}; "
                         f"stacked bars {pitch_gap:.4g} mm apart")


def _rebuilt_network(design, plan, joints, bars, checks, s):
    """Joints back in the design's frame, matched to its nodes; the bars as edges."""
    from scipy.spatial import cKDTree


    net = design.network
    centres = np.array([np.mean([f[2] for f in jf], axis=0) for jf in joints])
    design_mm = net.nodes * s.scale - plan.offset
    dist, match = cKDTree(design_mm).query(centres)
    bijective = np.unique(match).size == net.n_nodes == len(joints)
    ok = bijective and float(dist.max()) < NODE_TOL_MM
    checks.append(_check("rebuilt joints match the design", ok, value=float(dist.max()),
                         limit=NODE_TOL_MM,
                         detail="largest distance (mm) between a rebuilt joint and its design "
                                "node" + ("" if bijective else "; joints and nodes do not pair "
                                                               "up one to one")))
    if not ok:
        return None
    feat_joint = {}
    for j, jf in enumerate(joints):
        for f in jf:
            feat_joint.setdefault(f[0], []).append(int(match[j]))
    edges = np.array([sorted(feat_joint[k]) for k in range(len(bars))], dtype=np.int64)
    designed = {tuple(e): k for k, e in enumerate(np.sort(net.edges, axis=1).tolist())}
    found = [designed.get(tuple(e)) for e in edges.tolist()]
    same = None not in found and len(set(found)) == net.n_edges
    checks.append(_check("topology", same, value=len(edges), limit=net.n_edges,
                         detail="the bars join the designed joints" if same else
                                "the bars read back join other joints than the design's"))
    if not same:
        return None
    order = np.empty(net.n_edges, dtype=np.int64)
    order[found] = np.arange(len(edges))
    joint_xy = np.empty((net.n_nodes, 2))
    joint_xy[match] = centres
    lengths = np.linalg.norm(joint_xy[net.edges[:, 0]] - joint_xy[net.edges[:, 1]], axis=1)
    want = net.edge_lengths * s.scale
    dl = float(np.abs(lengths - want).max())
    checks.append(_check("lengths", dl <= LENGTH_TOL_MM, value=dl, limit=LENGTH_TOL_MM,
                         detail="largest |read-back - designed| distance (mm) between a bar's "
                                "joints"))
    layer = np.array([round(bars[k]["z0"] / s.layer_pitch) for k in order], dtype=np.int64)
    return (joint_xy, layer, lengths, float(dist.max()))


def _to_resolution(mm: float) -> float:
    return round(mm / FILE_RESOLUTION_MM) * FILE_RESOLUTION_MM


def _joints_mm(net, lengths, s) -> np.ndarray:
    """The rebuilt network's joints (mm): the design's where the read-back lengths are the
    design's to the files' resolution (a refit would only add the files' rounding), else the
    design's joints refitted to the read-back lengths."""
    from ..numerics import project_to_lengths

    x_mm = net.nodes * s.scale
    err = np.abs(np.linalg.norm(x_mm[net.edges[:, 0]] - x_mm[net.edges[:, 1]], axis=1) - lengths)
    if err.max() > FILE_RESOLUTION_MM:  # not the design's lengths: the joints as read back
        x_mm = project_to_lengths(net.edges, lengths, x_mm).positions
    return np.ascontiguousarray(x_mm)


def _motion_checks(design, layer, x_mm, s, measured, reference=None) -> tuple[list[dict], dict]:
    """Modes, the re-simulated motion and every clearance along it (see the module docstring);
    the checks and the report's ``motion`` facts."""
    from ..fab.layers import JointStack, sample_motion, stacking_gaps
    from ..network import Network
    from ..rigidity import count_modes
    from .motion import compare_motion

    net = design.network
    out = []
    built = Network(x_mm / s.scale, net.edges, net.ports, net.labels)
    modes = count_modes(built)
    # a print is faithful when it moves as its design does
    designed = modes.conformational if modes.conformational == 1 else count_modes(
        net).conformational
    out.append(_check("modes", modes.conformational == designed,
                      modes.conformational, designed,
                      f"conformational motions of the rebuilt network ({modes.self_stress} states "
                      "of self-stress)"))
    m = design.motion
    cmp = compare_motion(design, built, MAP_RTOL, reference)
    out.append(_check("motion re-simulated", cmp["ok"], cmp["worst"], cmp["limit"],
                      f"largest port-distance difference (design units, at {cmp['port']}) "
                      f"between the design's motion and the rebuilt network's; the rebuilt one "
                      f"{cmp['status']}" + ("" if cmp["same_end"] else ", the design's not")))
    fine = sample_motion(built, m, s.scale, 0.25 * s.clearance, floor_limit=s.clearance)
    inc = {}
    for b, (i, j) in enumerate(net.edges.tolist()):
        inc.setdefault(i, []).append(b)
        inc.setdefault(j, []).append(b)
    joints = [JointStack(j, tuple(bs), tuple(int(layer[b]) for b in bs), (), 0.0, 0.0, 0.0)
              for j, bs in sorted(inc.items()) if len(bs) >= 2]
    # widths and cap radii as read back; caps and collars above and below every stack
    gaps = stacking_gaps(net.edges, layer, fine.positions, width=measured["width"],
                         joints=joints, head_slots=measured["head_slots"],
                         column_radius=measured["cap_radius"],
                         spacer_radius=measured["cap_radius"])
    need = 0.5 * s.clearance + max(0.0, fine.max_step - 0.25 * s.clearance)
    worst_gap = min(gaps["bar_gap"], gaps["screw_gap"], gaps["column_gap"])

    def mm(v):
        return "none" if math.isinf(v) else f"{v:.3f}"

    facts = {"motion": {"samples": fine.n_samples, "max_node_step_mm": fine.max_step,
                        **{k: (None if isinstance(v, float) and math.isinf(v) else v)
                           for k, v in gaps.items()}}}
    out.append(_check(
        "clearances over the motion", worst_gap >= need,
        None if math.isinf(worst_gap) else round(worst_gap, 6), need,
        f"smallest gap (mm) between parts sharing a layer over {fine.n_samples} samples (bar to "
        f"bar {mm(gaps['bar_gap'])}, bar to a pin's cap or collar {mm(gaps['screw_gap'])}, cap "
        f"to cap {mm(gaps['column_gap'])})"))
    return out, facts
