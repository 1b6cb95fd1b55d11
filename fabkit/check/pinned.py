"""As-built check of a print-in-place bar linkage, read back from its STL or 3MF beds.

From the meshes alone (the template gives the print settings: layer pitch, bar size, pin
clearance, nozzle; nothing of the writer's plan or layout is used):

* **bodies**: one closed, consistently wound shell per bar, nothing fused (trimesh);
* **bars**: each body's lowest slab is a bar: its height a whole number of layers on a layer of
  the stack (``z = layer x pitch``); a cross-section through it gives the outline (its width)
  and the holes; a cross-section just above it the pins the bar carries; every bar has two
  joints, each a hole or a pin;
* **pieces**: holes and pins that share a centre on one bed are one joint; bars joined at
  joints are one piece; each piece is laid onto the design's nodes by a rigid motion found from
  its own bars (:mod:`fabkit.check.register`), every design edge built once; a design node held
  by two pieces is a joint where the print is cut, to be joined by hand. A piece of one bar with
  a plain hole at each end is a bar laid flat (no printed pin joins it): the stacked pieces are
  laid onto the design first, and the flat bars take the edges left over, shortest with
  shortest;
* **pins -> joints**: every joint of two or more bars has exactly one pin, but the joints
  where the print is cut (plain holes);
* **pin clearance**: the smallest radial gap between a pin and a hole around it (the hole's
  inscribed circle less the pin's circumscribed one less their offset), at least
  ``pin_clearance``;
* **caps hold**: above the top bar of every pin a cap wider than that bar's hole;
* **layer gaps**: one ``layer_gap`` above and below every bar on a pin, the pin's body is no
  wider than the pin (its collars and cap keep clear of the bars), and stacked bars are a gap
  apart (pitch less thickness);
* **rebuilt network**: the joints match the design's nodes (:data:`NODE_TOL_MM`), the bars
  join the designed joints with the designed lengths (:data:`LENGTH_TOL_MM`), and the network
  has the design's conformational motion;
* **motion**: the motion is re-simulated on the rebuilt network (its joints refitted to the
  read-back lengths where they differ from the design's by more than the files' float32
  resolution) and compared with the design's; then, sampled more finely than a quarter of the
  clearance per step, no two bars of one layer of a piece come closer than half the
  clearance, and no bar enters the layers of a pin's collars or cap nearby
  (:mod:`fabkit.check.clearance`, with the layers, widths and cap radii read back).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import FabkitError
from ..model.network import Network
from ..model.rigidity import count_modes
from ..numerics import apply_fit, project_to_lengths, rigid_fit
from .beds import split_bodies
from .clearance import fine_motion, point_gap, same_layer_gaps
from .items import Check, check, finish
from .motion import compare_motion, design_window
from .register import pieces_of, place_pieces
from .sections import section as _section

__all__ = ["check_pinned", "read_bar", "NODE_TOL_MM", "LENGTH_TOL_MM"]

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

#: Every check of a print-in-place linkage, in the order they run: a check that an earlier
#: failure leaves without what it needs is reported as not run.
CHECKS = ("one closed body per bar", "bars read back", "pins -> joints", "pin clearance",
          "caps hold the bars", "layer gaps", "rebuilt joints match the design", "topology",
          "lengths", "modes", "motion re-simulated", "clearances over the motion")


#: Work shared by the checks of one export's files (its STL and its 3MF rebuild the same
#: network): results of pure functions, keyed by everything they depend on; a few entries only
#: (one export's design window, re-simulation and clearances, and the next one's).
_MEMO: dict = {}
_MEMO_SIZE = 6


def _memo(key, compute):
    if key not in _MEMO:
        value = compute()  # may memoise work of its own first
        while len(_MEMO) >= _MEMO_SIZE:
            _MEMO.pop(next(iter(_MEMO)))
        _MEMO[key] = value
    return _MEMO[key]


def _design_key(design, s) -> tuple:
    net = design.network
    m = design.motion
    return (design.name, str(design.path), net.nodes.tobytes(), net.edges.tobytes(),
            repr(sorted(net.ports.items())), repr((m.drive, m.to, m.method, m.hold, m.options)), s)


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

    d = point_gap(ext, a[None], b[None])
    out["width"] = 2.0 * float(np.max(d))
    return out


def _gap_probe(carrier, centre, z, s) -> float:
    """How far from the pin's axis the carrier's body reaches at height ``z`` near the pin (mm);
    0 when it has nothing there."""
    import shapely

    reach = 0.0
    disc = shapely.Point(*centre).buffer(0.5 * s.cap_diameter + s.nozzle_width)
    for poly in _section(carrier, z):
        part = poly.intersection(disc)
        if part.is_empty:
            continue
        pts = shapely.get_coordinates(part.boundary)
        reach = max(reach, float(np.hypot(*(pts - centre).T).max()))
    return reach


def _bodies(meshes):
    """Every body read back, with its bed: (bed, trimesh.Trimesh) in bed coordinates."""
    return [(b, body) for b, mesh in enumerate(meshes) for body in split_bodies(mesh)]


def _joints(bars, beds):
    """Cluster holes and pins by centre, bed by bed: each cluster is a joint.

    Returns
    -------
    joints : list of list of features
        A feature is (bar, kind, centre, inner radius, outer radius).
    bar_joints : numpy.ndarray of int, shape (B, 2)
        The two joints of each bar.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    feats = []  # (bar, kind, centre, inner, outer)
    for k, bar in enumerate(bars):
        feats += [(k, "hole", c, r_in, r_out) for c, r_in, r_out in bar["holes"]]
        feats += [(k, "pin", c, r_out, r_out) for c, r_out in bar["pins"]]
    # beds apart along a third axis: features of two beds never share a joint
    points = np.array([[*f[2], 1e7 * beds[f[0]]] for f in feats]).reshape(-1, 3)
    pairs = cKDTree(points).query_pairs(JOINT_TOL_MM, output_type="ndarray")
    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                     shape=(len(feats),) * 2)
    n, label = connected_components(adj, directed=False)
    joints = [[feats[i] for i in np.flatnonzero(label == j)] for j in range(n)]
    bar_joints = np.zeros((len(bars), 2), dtype=np.int64)
    seen = np.zeros(len(bars), dtype=np.int64)
    for i, f in enumerate(feats):
        bar_joints[f[0], min(seen[f[0]], 1)] = label[i]
        seen[f[0]] += 1
    return joints, bar_joints


def _place(joints, bar_joints, design, s):
    """Each joint's design node and each bar's design edge, from the pieces laid onto the
    design (:func:`fabkit.check.register.place_pieces`).

    A piece of one bar with a hole at each end and nothing else at them is a bar laid flat (no
    printed pin joins it): the stacked pieces are laid onto the design first, then the flat
    bars go to the edges left over, matched by length (shortest with shortest).

    Returns
    -------
    dict
        ``node`` (design node of each joint, -1 where its piece fits nowhere), ``deviation``
        (mm), ``piece`` (of each joint), ``edge`` (design edge of each bar, -1: none).
    """
    net = design.network
    design_xy = net.nodes * s.scale
    centres = np.array([np.mean([f[2] for f in jf], axis=0) for jf in joints]).reshape(-1, 2)
    pieces = pieces_of(len(joints), bar_joints)
    local = np.empty(len(joints), dtype=np.int64)
    piece_of = np.empty(len(joints), dtype=np.int64)
    for p, members in enumerate(pieces):
        local[members] = np.arange(len(members))
        piece_of[members] = p
    bars_of = [np.flatnonzero(piece_of[bar_joints[:, 0]] == p) for p in range(len(pieces))]
    pinned = np.array([any(f[1] == "pin" for f in jf) for jf in joints])
    holes = np.array([sum(f[1] == "hole" for f in jf) for jf in joints])
    flat = [p for p, m in enumerate(pieces)
            if len(bars_of[p]) == 1 and len(m) == 2 and (holes[m] == 1).all()]
    stacked = [p for p in range(len(pieces)) if p not in set(flat)]
    flat_len = np.array([float(np.linalg.norm(np.subtract(*centres[pieces[p]])))
                         for p in flat])

    def left_over(places):
        """The design edges no stacked piece builds, and each stacked joint's node."""
        node = np.full(len(joints), -1, dtype=np.int64)
        used = set()
        for p, pl in zip(stacked, places):
            node[pieces[p]] = pl.match
            used |= {tuple(e) for e in np.sort(pl.match[local[bar_joints[bars_of[p]]]],
                                               axis=1).tolist()}
        rest = [k for k, e in enumerate(np.sort(net.edges, axis=1).tolist())
                if tuple(e) not in used]
        return node, np.asarray(rest, dtype=np.int64)

    def pins_agree(places, lengths: bool = True) -> bool:
        """The flat bars are the edges left over (by their lengths too, with ``lengths``), and
        a joint is cut between pieces exactly where it has plain holes and no pin."""
        node, rest = left_over(places)
        if len(rest) != len(flat) or (lengths and not _lengths_pair(flat_len,
                                                                     _edge_mm(net, rest, s))):
            return False
        held = np.bincount(np.concatenate([node[node >= 0], net.edges[rest].ravel()]),
                           minlength=net.n_nodes)
        at = node >= 0
        cut = np.zeros(len(joints), dtype=bool)
        cut[at] = held[node[at]] >= 2
        return bool(not (cut & pinned).any() and not (at & ~cut & ~pinned & (holes >= 2)).any())

    stacks = [(centres[pieces[p]], local[bar_joints[bars_of[p]]]) for p in stacked]
    # a joint is cut between pieces exactly where it has plain holes and no pin: kept while
    # the pieces are placed (a pin alone always; plain holes met by another piece only when
    # no bar lies flat, since a flat bar may be what meets them)
    rule = np.where(pinned, -1, np.where((holes >= 2) & (not flat), 1, 0))
    shared = [rule[pieces[p]] for p in stacked]
    placed = place_pieces(stacks, design_xy, net.edges, tol=NODE_TOL_MM, accept=pins_agree,
                          shared=shared, partial=bool(flat))
    if flat and None not in placed and not pins_agree(placed):
        # no flat bar is as long as its edge: the stacks placed by their pins alone, and the
        # flat bars' lengths left for the checks to measure
        placed = place_pieces(stacks, design_xy, net.edges, tol=NODE_TOL_MM, partial=True,
                              shared=shared,
                              accept=lambda places: pins_agree(places, lengths=False))
    node = np.full(len(joints), -1, dtype=np.int64)
    dev = np.full(len(joints), np.inf)
    for p, pl in zip(stacked, placed):
        if pl is not None:
            node[pieces[p]], dev[pieces[p]] = pl.match, pl.deviation
    if flat and all(pl is not None for pl in placed):
        _place_flat(flat, pieces, centres, left_over(placed)[1], flat_len, design_xy, net,
                    node, dev)
    designed = {tuple(e): k for k, e in enumerate(np.sort(net.edges, axis=1).tolist())}
    ends = np.sort(node[bar_joints], axis=1)
    edge = np.array([designed.get(tuple(e), -1) if e[0] >= 0 else -1 for e in ends.tolist()],
                    dtype=np.int64)
    return {"node": node, "deviation": dev, "piece": piece_of, "edge": edge,
            "pieces": len(pieces), "centres": centres, "flat": len(flat)}


def _edge_mm(net, edges, s) -> np.ndarray:
    x = net.nodes * s.scale
    e = net.edges[edges]
    return np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1)


def _lengths_pair(a, b) -> bool:
    """The lengths ``a`` and ``b`` pair up, shortest with shortest, within twice the joint
    tolerance (each end of a bar within it of its node)."""
    return bool(len(a) == len(b) and (np.abs(np.sort(a) - np.sort(b)) <= 2 * NODE_TOL_MM).all())


def _place_flat(flat, pieces, centres, rest, flat_len, design_xy, net, node, dev) -> None:
    """The flat bars onto the edges left over, shortest with shortest; fills ``node`` and
    ``dev`` (the distance of each end from its node once the bar is laid onto its edge)."""
    lengths = np.linalg.norm(design_xy[net.edges[rest, 0]] - design_xy[net.edges[rest, 1]],
                             axis=1)
    for p, k in zip(np.asarray(flat)[np.argsort(flat_len, kind="stable")],
                    rest[np.argsort(lengths, kind="stable")]):
        m = pieces[p]
        fit = rigid_fit(centres[m], design_xy[net.edges[k]])
        node[m] = net.edges[k]
        dev[m] = np.linalg.norm(apply_fit(fit, centres[m]) - design_xy[net.edges[k]], axis=1)


def _bars_check(meshes, names, net, s, checks):
    """The closed bodies of the beds read back as bars: one per design bar, each on a layer,
    of the asked thickness and width. Appends two checks; returns the bodies, the bed of each,
    the bars read and each bar's layer, or None when the bodies are not the design's bars."""
    placed = _bodies(meshes)
    bodies = [b for _, b in placed]
    beds = [bed for bed, _ in placed]
    closed = [b.is_watertight and b.is_winding_consistent and b.volume > 0 for b in bodies]
    checks.append(check("one closed body per bar", len(bodies) == net.n_edges and all(closed),
                        value=len(bodies), limit=net.n_edges,
                        detail=f"{sum(closed)} of {len(bodies)} bodies watertight, consistently "
                               f"wound, outward; none shares a vertex with another; the design "
                               f"has {net.n_edges} bars"))
    bars = [read_bar(b, s) for b in bodies]
    bad = [f"body {k} on {names[beds[k]]}: {b['problem']}" for k, b in enumerate(bars)
           if b["problem"]]
    pitch = s.layer_pitch
    layer = np.array([round(b["z0"] / pitch) for b in bars], dtype=np.int64)
    off_layer = max((abs(b["z0"] - lz * pitch) for b, lz in zip(bars, layer)), default=0.0)
    thick = max((abs(b["thickness"] - s.bar_thickness) for b in bars
                 if b["thickness"] is not None), default=0.0)
    wide = max((abs(b["width"] - s.bar_width) for b in bars if b["width"] is not None),
               default=0.0)
    checks.append(check(
        "bars read back", not bad and max(off_layer, thick, wide) <= MEASURE_TOL_MM,
        value=round(max(off_layer, thick, wide), 9), limit=MEASURE_TOL_MM,
        detail="; ".join(bad[:3]) or f"{len(bars)} bars on {int(layer.max(initial=-1)) + 1} "
                                      f"layers of {pitch:g} mm; largest error of height, "
                                      f"thickness and width (mm)"))
    if bad or len(bodies) != net.n_edges:
        return None
    return bodies, beds, bars, layer


def _pins_at_joints(joints, node, cut, bars, bodies, s) -> dict:
    """Every joint's pin and holes measured: the problems found, the smallest pin clearance and
    cap overlap (each with its joint), the cap radius and the layers the heads take, and the
    printed pin of each joint."""
    def at(j) -> str:
        return f"the joint at node {node[j]}" if node[j] >= 0 else f"joint {j} (at no node)"

    problems, clear, hold = [], (math.inf, None), (math.inf, None)
    cap_radius, head_slots = 0.0, 1
    pin_of = {}
    for j, jfeats in enumerate(joints):
        pins = [f for f in jfeats if f[1] == "pin"]
        holes = [f for f in jfeats if f[1] == "hole"]
        if len(pins) > 1:
            problems.append(f"{at(j)} has {len(pins)} pins")
            continue
        if not pins:
            if len(holes) >= 2 and int(node[j]) not in cut:
                problems.append(f"{at(j)} has {len(holes)} holes and no pin")
            continue
        if int(node[j]) in cut:
            problems.append(f"{at(j)} is cut between pieces but has a pin")
        pk, _, pc, _, pr = pins[0]
        pin_of[j] = (pk, pc, jfeats)
        for hk, _, hc, hin, hout in holes:
            gap = hin - pr - float(np.hypot(*(hc - pc)))
            if gap < clear[0]:
                clear = (gap, j)
        if holes:
            top = max(holes, key=lambda f: bars[f[0]]["z0"])
            cap_top, cap_in, cap_out = _cap(bodies[pk], pc, s)
            if cap_in - top[4] < hold[0]:
                hold = (cap_in - top[4], j)
            cap_radius = max(cap_radius, cap_out)
            above = cap_top - bars[top[0]]["z0"] - bars[top[0]]["thickness"]
            head_slots = max(head_slots, math.ceil(above / s.layer_pitch - MEASURE_TOL_MM))
    return {"problems": problems, "clear": clear, "hold": hold, "cap_radius": cap_radius,
            "head_slots": head_slots, "pin_of": pin_of, "at": at}


def _pin_checks(pins, joints, node, where, cut, net, s) -> list[Check]:
    """The checks of the pins: every joint built, the clearance around each pin, the caps."""
    problems, clear, hold, at = pins["problems"], pins["clear"], pins["hold"], pins["at"]
    built_nodes = int(np.unique(node[node >= 0]).size)
    out = [check("pins -> joints", not problems,
                 value=[built_nodes, len(pins["pin_of"])], limit=[net.n_nodes, None],
                 detail="; ".join(problems[:3]) or
                        f"{len(joints)} joints from the holes and pins of "
                        f"{where['pieces']} piece(s); {len(pins['pin_of'])} printed pins, "
                        f"{len(cut)} joints cut between pieces (plain holes)")]
    # a gap of zero or less is a pin fused to its hole, whatever tolerance the measure has
    c_ok = clear[0] >= s.pin_clearance - MEASURE_TOL_MM and clear[0] > 0
    out.append(check("pin clearance", c_ok,
                     value=None if math.isinf(clear[0]) else round(clear[0], 6),
                     limit=s.pin_clearance,
                     detail="smallest radial gap (mm) between a pin and a hole around it"
                            if c_ok else
                            f"{at(clear[1])}: its pin leaves {clear[0]:.3f} mm to the hole "
                            f"around it, {s.pin_clearance:g} mm wanted"
                            + ("; the pin touches or overlaps its hole" if clear[0] <= 0
                               else "")))
    need_hold = 0.5 * s.nozzle_width
    out.append(check("caps hold the bars", hold[0] >= need_hold,
                     value=None if math.isinf(hold[0]) else round(hold[0], 6),
                     limit=need_hold,
                     detail="smallest overlap (mm) of a cap over the top bar's hole on its "
                            "pin" if hold[0] >= need_hold else
                            f"{at(hold[1])}: its cap overlaps the top bar's hole by "
                            f"{hold[0]:.3f} mm, {need_hold:g} mm wanted"))
    return out


def _moved_checks(design, reference, rebuilt, read, pins, where, bar_joints, s):
    """The rebuilt network moved as the design moves (:func:`_motion_checks`, memoised): the
    checks and the facts they report."""
    bars, layer = read["bars"], read["layer"]
    order, lengths, dev = rebuilt
    # layers count within a piece: each piece is lowered onto its bed, and pieces joined by
    # hand stack as their bill of materials says; the pieces' layers are kept apart here
    band = int(layer.max(initial=0)) + 2 * pins["head_slots"] + 2
    edge_layer = layer[order] + band * _piece_bands(where["piece"][bar_joints[order, 0]])
    # sizes to the files' resolution: the STL and 3MF of one export then share one simulation
    widths = [b["width"] for b in bars if b["width"] is not None]
    measured = {"width": _to_resolution(max(widths)),
                "cap_radius": _to_resolution(pins["cap_radius"] or 0.5 * s.cap_diameter),
                "head_slots": pins["head_slots"], "band": band}
    x_mm = _joints_mm(design.network, lengths, s)
    key = ("motion",) + _design_key(design, s) + (
        x_mm.tobytes(), edge_layer.tobytes(), tuple(sorted(measured.items())))
    try:
        return _memo(key, lambda: _motion_checks(design, edge_layer, x_mm, s, measured,
                                                 reference))
    except FabkitError as exc:  # the rebuilt network cannot be simulated or sampled
        return [check("motion re-simulated", False, detail=str(exc))], {}


def _piece_bands(piece) -> np.ndarray:
    """Each design edge's piece (``piece``, as numbered read back), numbered again in the order
    of the design's edges: the pieces of one design the same whatever order a file holds its
    bodies in (the STL and the 3MF of one export then share one simulation)."""
    _, first, inverse = np.unique(piece, return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    return rank[inverse.ravel()]


def check_pinned(meshes, names, design, s, report, motion=None) -> dict:
    """The as-built check of a print-in-place linkage (see the module docstring).

    Parameters
    ----------
    meshes : list of trimesh.Trimesh
        The beds as read back (mm), in bed order.
    names : list of str
    design : Design
    s : PrintSettings
        ``linkage = "pins"``, from the template (and the overrides of the export).
    report : dict
        Filled in and returned, with ``ok`` and ``checks``.
    motion : TracedMotion, optional
        The design's motion, traced once by the pipeline: the window the linkage follows and
        its trace are taken from it (traced here when not given).

    Returns
    -------
    dict
    """
    try:
        # the linkage is judged against the design as it prints: its motion from motion_from
        # to motion_to, where the template sets them (the Motion stage's window, traced once)
        design, reference = _memo(("window",) + _design_key(design, s),
                                  lambda: design_window(design, s.motion_from, s.motion_to,
                                                        motion, "print"))
    except FabkitError as exc:
        return finish(report, [check("design prints", False, detail=str(exc))], CHECKS,
                      "the design's own motion cannot be traced for the print")
    net = design.network
    checks = []
    read = _bars_check(meshes, names, net, s, checks)
    if read is None:
        return finish(report, checks, CHECKS)
    bodies, beds, bars, layer = read
    joints, bar_joints = _joints(bars, beds)
    where = _place(joints, bar_joints, design, s)
    node = where["node"]
    held = np.bincount(node[node >= 0], minlength=net.n_nodes)
    cut = {int(v) for v in np.flatnonzero(held >= 2)}  # a node built on two pieces
    pins = _pins_at_joints(joints, node, cut, bars, bodies, s)
    checks += _pin_checks(pins, joints, node, where, cut, net, s)
    checks.append(_layer_gap_check(pins["pin_of"], bars, bodies, s))
    rebuilt = _rebuilt_network(design, where, bar_joints, checks, s)
    if rebuilt is None:
        return finish(report, checks, CHECKS)
    clear, hold = pins["clear"], pins["hold"]
    report["as_built"] = {"bars": len(bars), "joints": len(joints),
                          "printed_pins": len(pins["pin_of"]), "pieces": where["pieces"],
                          "cut_joints": sorted(cut), "layers": int(layer.max()) + 1,
                          "node_deviation_mm": rebuilt[2],
                          "pin_clearance_mm": None if math.isinf(clear[0]) else clear[0],
                          "cap_overlap_mm": None if math.isinf(hold[0]) else hold[0]}
    moved, facts = _moved_checks(design, reference, rebuilt, {"bars": bars, "layer": layer},
                                 pins, where, bar_joints, s)
    checks += moved
    report.update(facts)
    return finish(report, checks, CHECKS)


def _cap(carrier, centre, s) -> tuple[float, float, float]:
    """The cap on the pin at ``centre``: its top (mm), inscribed and circumscribed radii (the
    carrier's cross-section half a layer below the top); radii 0 when there is none."""
    import shapely

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


def _layer_gap_check(pin_of, bars, bodies, s) -> Check:
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
    return check("layer gaps", ok, value=round(worst, 6), limit=round(limit, 6),
                 detail=f"widest reach (mm) of a pin's body from its axis within "
                        f"{s.layer_gap - eps:g} mm above or below a bar on the pin (the pin's "
                        f"radius: collars and caps keep their gap)"
                        f"{'' if ok or where is None else f', exceeded at {where[1]:.3f} mm'}; "
                        f"stacked bars {pitch_gap:.4g} mm apart")


def _rebuilt_network(design, where, bar_joints, checks, s):
    """The joints matched to the design's nodes, the bars to its edges, the lengths read back.

    Returns (order, lengths, deviation): ``order[e]`` the bar read back as design edge ``e``,
    ``lengths`` (E,) the distance between its joints (mm); None when the file is not this
    design's (the failed checks added)."""
    net = design.network
    node, dev = where["node"], where["deviation"]
    held = np.bincount(node[node >= 0], minlength=net.n_nodes)
    worst = int(np.argmax(dev)) if len(dev) else 0
    d = float(dev[worst]) if len(dev) else 0.0
    ok = bool(np.isfinite(dev).all()) and d <= NODE_TOL_MM and bool((held >= 1).all())
    if ok:
        detail = "largest distance (mm) between a rebuilt joint and its design node"
    elif not np.isfinite(dev).all():
        detail = (f"{int(np.sum(~np.isfinite(dev)))} joints belong to a piece that fits nowhere "
                  f"in the design {design.name}")
    elif d > NODE_TOL_MM:
        detail = (f"the joint at node {node[worst]} lies {d:.3f} mm from where the design has "
                  "it (the piece laid onto the design by its best rigid fit)")
    else:
        detail = f"{int(np.sum(held == 0))} design nodes are built by no joint"
    checks.append(check("rebuilt joints match the design", ok,
                        value=d if np.isfinite(d) else None, limit=NODE_TOL_MM, detail=detail))
    if not ok:
        return None
    edge = where["edge"]
    same = bool((edge >= 0).all()) and np.unique(edge).size == net.n_edges == len(edge)
    checks.append(check("topology", same, value=len(edge), limit=net.n_edges,
                        detail="the bars join the designed joints" if same else
                               "the bars read back join other joints than the design's"))
    if not same:
        return None
    order = np.empty(net.n_edges, dtype=np.int64)
    order[edge] = np.arange(len(edge))
    centres = where["centres"]
    lengths = np.linalg.norm(centres[bar_joints[order, 0]] - centres[bar_joints[order, 1]], axis=1)
    want = net.edge_lengths * s.scale
    k = int(np.argmax(np.abs(lengths - want)))
    dl = float(abs(lengths[k] - want[k]))
    i, j = net.edges[k]
    checks.append(check("lengths", dl <= LENGTH_TOL_MM, value=dl, limit=LENGTH_TOL_MM,
                        detail="largest |read-back - designed| distance (mm) between a bar's "
                               "joints" if dl <= LENGTH_TOL_MM else
                               f"the bar between nodes {i} and {j}: its joints are "
                               f"{lengths[k]:.3f} mm apart, the design's {want[k]:.3f} mm"))
    return order, lengths, d


def _to_resolution(mm: float) -> float:
    return round(mm / FILE_RESOLUTION_MM) * FILE_RESOLUTION_MM


def _joints_mm(net, lengths, s) -> np.ndarray:
    """The rebuilt network's joints (mm): the design's where the read-back lengths are the
    design's to the files' resolution (a refit would only add the files' rounding), else the
    design's joints refitted to the read-back lengths."""
    x_mm = net.nodes * s.scale
    err = np.abs(np.linalg.norm(x_mm[net.edges[:, 0]] - x_mm[net.edges[:, 1]], axis=1) - lengths)
    if err.max() > FILE_RESOLUTION_MM:  # not the design's lengths: the joints as read back
        x_mm = project_to_lengths(net.edges, lengths, x_mm).positions
    return np.ascontiguousarray(x_mm)


def _simulated(design, x_mm, s, reference):
    """The rebuilt network (joints ``x_mm``) simulated: its modes, the design's conformational
    motions, its motion compared with the design's (``reference``) and sampled for the
    clearances. FabkitError when it cannot be simulated or sampled."""
    net = design.network
    built = Network(x_mm / s.scale, net.edges, net.ports, net.labels)
    modes = count_modes(built)
    # a print is faithful when it moves as its design does
    designed = modes.conformational if modes.conformational == 1 else count_modes(
        net).conformational
    cmp = compare_motion(design, built, MAP_RTOL, reference)
    fine = fine_motion(built, design.motion, s.scale, 0.25 * s.clearance, floor=s.clearance,
                       traced=cmp["trajectory"])
    return modes, designed, cmp, fine


def _motion_checks(design, layer, x_mm, s, measured, reference) -> tuple[list[Check], dict]:
    """Modes, the re-simulated motion and every clearance along it (see the module docstring);
    the checks and the report's ``motion`` facts. ``reference``: the design's motion as the
    Motion stage traced it."""
    net = design.network
    out = []
    # the rebuilt network's motion does not depend on the layers read back: the STL and the
    # 3MF of one export share it even where they lay identical pieces in other places
    modes, designed, cmp, fine = _memo(("simulated",) + _design_key(design, s) + (
        x_mm.tobytes(),), lambda: _simulated(design, x_mm, s, reference))
    out.append(check("modes", modes.conformational == designed,
                     modes.conformational, designed,
                     f"conformational motions of the rebuilt network ({modes.self_stress} states "
                     "of self-stress)"))
    out.append(check("motion re-simulated", cmp["ok"], cmp["worst"], cmp["limit"],
                     f"largest port-distance difference (design units, at {cmp['port']}) "
                     f"between the design's motion and the rebuilt network's; the rebuilt one "
                     f"{cmp['status']}" + ("" if cmp["same_end"] else ", the design's not")))
    # widths and cap radii as read back; caps and collars above and below every stack
    gaps = same_layer_gaps(net.edges, layer, fine.positions, measured["width"],
                           columns=_pin_columns(net.edges, layer, measured["band"],
                                                measured["head_slots"], measured["cap_radius"]))
    need = 0.5 * s.clearance + max(0.0, fine.max_step - 0.25 * s.clearance)
    worst_gap = min(gaps["bar_gap"], gaps["joint_gap"], gaps["screw_gap"], gaps["column_gap"])

    def mm(v):
        return "none" if math.isinf(v) else f"{v:.3f}"

    where = ""
    if gaps["joint_gap"] < need:  # bars on one joint lie on different layers, or fill one space
        p, q = (net.edges[k].tolist() for k in gaps["joint_pair"])
        where = (f"; the bars between nodes {p[0]}-{p[1]} and {q[0]}-{q[1]} share a joint and a "
                 "layer: their round ends overlap")

    facts = {"motion": {"samples": fine.n_samples, "max_node_step_mm": fine.max_step,
                        **{k: (None if isinstance(v, float) and math.isinf(v) else v)
                           for k, v in gaps.items()}}}
    out.append(check(
        "clearances over the motion", worst_gap >= need,
        None if math.isinf(worst_gap) else round(worst_gap, 6), need,
        f"smallest gap (mm) between parts sharing a layer over {fine.n_samples} samples (bar to "
        f"bar {mm(gaps['bar_gap'])}, two bars on one joint {mm(gaps['joint_gap'])}, bar to a "
        f"pin's cap or collar {mm(gaps['screw_gap'])}, cap to cap {mm(gaps['column_gap'])})"
        + where))
    return out, facts


def _pin_columns(edges, layer, band: int, head_slots: int, radius: float) -> dict:
    """A column at every joint of two or more bars of one piece (pieces lie in layer bands of
    their own): its bars' layers, and its collars and cap ``head_slots`` layers beyond."""
    spans: dict[tuple, list[int]] = {}
    for b, (i, j) in enumerate(edges.tolist()):
        for v in (i, j):
            spans.setdefault((v, int(layer[b]) // band), []).append(int(layer[b]))
    keys = sorted(k for k, zs in spans.items() if len(zs) >= 2)
    lo = np.array([min(spans[k]) for k in keys], dtype=np.int64)
    hi = np.array([max(spans[k]) for k in keys], dtype=np.int64)
    return {"joints": np.array([k[0] for k in keys], dtype=np.int64), "low": lo - head_slots,
            "high": hi + head_slots, "inner_low": lo, "inner_high": hi, "radius": radius,
            "inner_radius": radius}
