"""As-built check of a printed network, read back from its STL files with trimesh.

Every bed of the export is read (``NAME_bed<k>.stl`` together, :mod:`fabkit.check.beds`) and,
with the design, each piece is moved back from its place on the bed into its own frame. A
print-in-place bar linkage (``linkage = "pins"``) is checked by :mod:`fabkit.check.pinned`; a
triangle-hinge network as follows (a print split into pieces piece by piece, against each
piece's own network, without the transition).

Solid checks: the mesh is watertight, consistently wound, exactly one body, and no feature thinner
than the nozzle
(in the plane: every piece of a cross-section survives an opening by a disc of the nozzle's
width; across the layers: every slab of the solid is a whole number of layers, at least one).
The as-built check does not compare the volume with the writer's analytic volume (that would
recompute the writer's geometry); :func:`check_mesh` does when given one (``fabkit bench``).

As-built linkage: the linkage is rebuilt from the solid alone (with the print settings' gap and
scale): a cross-section above the hinges shows the plates; each plate's three sides (its edges
that no hinge meets), moved out by half the gap, give back the rigid triangle; corners of
different plates that meet are one node; each hinge in a cross-section through the hinges must
hold exactly one node shared by the plates it joins (hinges -> joints). The rebuilt network's mode
count must show one conformational motion, and the sequential transition D1* -> D2* is simulated on
it (see :func:`sequential_transition`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..design.assemble import chain
from ..errors import FabkitError, FabricationError
from ..kinematics import trace
from ..model.network import Network
from ..model.rigidity import count_modes
from ..numerics import START_RTOL
from . import read_set, require_triangles
from .beds import bed_set
from .items import Check, check, finish, not_run, not_run_after
from .register import pieces_of, place_pieces
from .sections import plane_segments, section

__all__ = ["FORMAT", "SUFFIXES", "check_file", "check_meshes", "check_mesh", "slab_sections",
           "rebuild_linkage",
           "module_fixed_points", "sequential_transition", "as_built_tolerance", "VOLUME_RTOL"]

FORMAT = "stl"
#: The sections of ``--set`` this check reads (any other has no effect on it).
READS = ("print",)
SUFFIXES = (".stl",)

#: Relative tolerance between the mesh's volume and the analytic volume.
VOLUME_RTOL = 1e-6
#: Relative tolerance on every d_k at the end of the transition, to which a rebuilt linkage adds
#: its own error (see ``as_built_tolerance``); a wrong branch is off by O(1).
TRANSITION_RTOL = 1e-4
#: Largest distance (mm) between a node rebuilt from the solid and the design's node.
NODE_TOL_MM = 1e-2
#: The checks of each piece of a hinge print, in the order they run (a check an earlier failure
#: leaves without what it needs is reported as not run).
PIECE_CHECKS = ("rebuilt nodes match the design", "rebuilt edges match the design",
                "one conformational motion")
#: The checks of a one-piece print's transition D1* -> D2* (when its design has ports d1, d2).
TRANSITION = ("sequential transition D1* -> D2*", "hinge strain along the transition")


#: Points of a section closer than this (mm) are merged: STL stores float32 coordinates, which
#: split a straight side at ~1e-5 mm (more far from the origin, see the spacing term).
SECTION_MERGE_MM = 1e-4


def _stl_kind(data: bytes, path) -> str:
    """``"binary"`` or ``"ascii"`` from the bytes themselves; FabricationError for anything else
    (a cut-off or corrupt file), so that no reader guesses an encoding for random bytes."""
    if len(data) >= 84:
        count = int.from_bytes(data[80:84], "little")
        if len(data) == 84 + 50 * count:
            return "binary"
    head = data[:5].lower()
    if head == b"solid":
        try:
            data.decode("ascii")
        except UnicodeDecodeError:
            pass
        else:
            return "ascii"
    if len(data) >= 84:
        count = int.from_bytes(data[80:84], "little")
        raise FabricationError(f"{path}: not a complete STL file: {len(data)} bytes, while its "
                               f"header announces {count} triangles ({84 + 50 * count} bytes), "
                               "and it is not ASCII STL (cut off or corrupt?)")
    raise FabricationError(f"{path}: not an STL file ({len(data)} bytes)")


#: One triangle of a binary STL: normal, three vertices, attribute count.
_BINARY_TRIANGLE = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])

#: No printer prints beyond this (mm); vertices farther out are corruption, not a part.
MAX_COORDINATE_MM = 1e5


def stl_triangles(data: bytes, path) -> int:
    """How many triangles an STL file's bytes hold, counted before they are read as a mesh
    (binary: the header's count, which :func:`_stl_kind` checked against the size; ASCII: its
    ``facet`` lines)."""
    if _stl_kind(data, path) == "binary":
        return int.from_bytes(data[80:84], "little")
    return data.count(b"facet")


def _load(data: bytes, path):
    import io

    import trimesh

    if _stl_kind(data, path) == "binary":
        # trimesh drops non-finite triangles while it processes; a file that holds them is
        # corrupt, and is said to be so
        count = int.from_bytes(data[80:84], "little")
        tri = np.frombuffer(data, dtype=_BINARY_TRIANGLE, count=count, offset=84)
        if not np.isfinite(tri["v"]).all():
            raise FabricationError(f"{path}: vertices that are not finite (a corrupt file)")
    try:
        # process: merge the vertices the triangles share, nothing else (validate=True would
        # drop degenerate and repeated triangles and mend the winding: damage the checks report)
        mesh = trimesh.load(io.BytesIO(data), file_type="stl", force="mesh", process=True,
                            validate=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise FabricationError(f"{path}: cannot be read as STL: {exc}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise FabricationError(f"{path}: holds no triangles")
    v = np.asarray(mesh.vertices)
    if not np.isfinite(v).all() or np.abs(v).max() > MAX_COORDINATE_MM:
        raise FabricationError(f"{path}: vertices that are not finite or lie beyond "
                               f"{MAX_COORDINATE_MM:g} mm (a corrupt file)")
    return mesh


# --- cross-sections ------------------------------------------------------------------------------

# the cross-sections live in :mod:`fabkit.check.sections` (shared with the pinned check)
_plane_segments = plane_segments
_section = section


def _thin_pieces(polys, radius: float) -> int:
    """How many pieces vanish or split when opened by a disc of the given radius."""
    import shapely

    if not polys:
        return 0
    opened = shapely.buffer(shapely.buffer(np.asarray(polys), -radius), radius)
    parts = shapely.get_num_geometries(opened)
    empty = shapely.is_empty(opened)
    return int(np.sum(empty | (parts != 1)))


def _drop_straight(polys, tol: float):
    """Polygons without vertices on straight sides of their outlines (within ``tol``).

    A cross-section cuts each side face of a prism in two triangles, so a side comes back in
    two segments. :func:`shapely.simplify` (GEOS's Douglas-Peucker) keeps some of these points
    on closed rings (next to where the ring starts): a triangular plate was read with four
    sides. Each such vertex is removed here, nearest its side first, down to a triangle.
    """
    import shapely

    out = []
    for poly in polys:
        ring = np.asarray(poly.exterior.coords)[:-1]
        start = len(ring)
        while len(ring) > 3:
            a, c = np.roll(ring, 1, axis=0), np.roll(ring, -1, axis=0)
            ac = c - a
            cross = np.abs(ac[:, 0] * (ring - a)[:, 1] - ac[:, 1] * (ring - a)[:, 0])
            off = cross / np.maximum(np.hypot(ac[:, 0], ac[:, 1]), np.finfo(float).tiny)
            k = int(np.argmin(off))
            if off[k] > tol:
                break
            ring = np.delete(ring, k, axis=0)
        if len(ring) < start:
            poly = shapely.Polygon(ring, [r.coords for r in poly.interiors])
        out.append(poly)
    return np.asarray(out, dtype=object)


def slab_sections(mesh, settings) -> dict:
    """Plates (a cross-section above the hinges) and hinges (a cross-section through them, less
    the plates) of a printed solid, as arrays of shapely polygons (mm)."""
    import shapely

    s = settings
    top = np.asarray(_section(mesh, 0.5 * (s.hinge_thickness + s.plate_thickness)))
    low = np.asarray(_section(mesh, 0.5 * s.hinge_thickness))
    # float32 coordinates far from the origin split straight sides at ~1e-4 mm: merge them
    reach = float(np.abs(mesh.bounds).max()) if len(mesh.vertices) else 1.0
    tol = max(SECTION_MERGE_MM, 16.0 * float(np.spacing(np.float32(reach))))
    plates = shapely.orient_polygons(_drop_straight(shapely.simplify(top, tol), tol))
    if len(low) and len(plates):
        region = shapely.difference(shapely.union_all(low), shapely.buffer(
            shapely.union_all(plates), tol))
        hinges = np.asarray(shapely.get_parts(region))
        hinges = hinges[shapely.area(hinges) > 0.05 * s.hinge_width ** 2]
    else:
        hinges = np.asarray([])
    return {"plates": plates, "hinges": hinges, "tolerance": tol}


def check_mesh(mesh, settings=None, expected_volume=None, sections=None, *,
               bodies: int | None = 1) -> list[Check]:
    """Solid checks of a loaded mesh (see the module docstring); one item per check.

    ``bodies``: the number of separate bodies the mesh must have (None: any, reported as
    ``bodies``)."""
    count = int(mesh.body_count)
    checks = [
        check("watertight", mesh.is_watertight, detail="every edge shared by exactly two faces"),
        check("winding consistent", mesh.is_winding_consistent),
        check("one body", count == 1, value=count, limit=1) if bodies == 1 else
        check("bodies", bodies is None or count == bodies, value=count, limit=bodies),
        check("outward normals", mesh.volume > 0, value=float(mesh.volume)),
    ]
    if expected_volume is not None:
        rel = abs(mesh.volume - expected_volume) / expected_volume
        checks.append(check("volume = analytic volume of plates + hinges", rel <= VOLUME_RTOL,
                            value=float(rel), limit=VOLUME_RTOL,
                            detail=f"mesh {mesh.volume:.9g} mm^3, analytic "
                                   f"{expected_volume:.9g} mm^3"))
    if settings is not None:
        layer = settings.layer_height
        z = np.unique(np.round(mesh.vertices[:, 2], 4))
        slabs = np.diff(z)
        layers = slabs / layer
        whole = bool(np.all(np.abs(layers - np.round(layers)) < 1e-3) and np.all(layers > 0.999))
        checks.append(check("slabs are whole layers", whole,
                            value=[round(float(v), 6) for v in slabs], limit=layer,
                            detail=f"heights between the solid's levels; layer {layer:g} mm"))
        if sections is None:
            sections = slab_sections(mesh, settings)
        pieces = list(sections["plates"]) + list(sections["hinges"])
        thin = _thin_pieces(pieces, 0.5 * settings.nozzle_width * 0.999)
        checks.append(check("no feature thinner than the nozzle", thin == 0, value=thin, limit=0,
                            detail=f"plates and hinges (from cross-sections of the solid) that "
                                   f"vanish or split when opened by a {settings.nozzle_width:g} "
                                   "mm disc"))
    return checks


# --- rebuilding the linkage ----------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class AsBuilt:
    """A linkage rebuilt from a printed solid.

    Attributes
    ----------
    nodes : numpy.ndarray, shape (N, 2)
        Joint and corner positions (mm, print frame).
    triangles : numpy.ndarray of int, shape (M, 3)
    edges : numpy.ndarray of int, shape (E, 2)
    joints : numpy.ndarray of int, shape (H,)
        Nodes held by a hinge.
    problems : list of str
    """

    nodes: np.ndarray
    triangles: np.ndarray
    edges: np.ndarray
    joints: np.ndarray
    problems: list
    #: For each triangle, its plate among the cross-section's plates (arm lengths are measured
    #: from them).
    plate_index: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))


def rebuild_linkage(mesh, settings, sections=None) -> AsBuilt:
    """Plates -> rigid triangles, hinges -> joints, from the solid alone (plus gap and widths).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The printed solid (mm).
    settings : PrintSettings
        Gives the gap (plate sides sit half of it inside the triangle's sides), the hinge width
        and the heights of the plates and hinges.
    sections : dict, optional
        From :func:`slab_sections` (computed when not given).

    Returns
    -------
    AsBuilt
    """
    import shapely
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    s = settings
    problems = []
    if sections is None:
        sections = slab_sections(mesh, settings)
    plates, hinges = sections["plates"], sections["hinges"]
    # every plate edge, in ring order; an edge that a hinge meets is a cut corner, not a side
    coords, ring_of = shapely.get_coordinates(shapely.get_exterior_ring(plates), return_index=True)
    same = ring_of[1:] == ring_of[:-1]  # consecutive points of one ring (closing point repeats)
    a, b, plate_of = coords[:-1][same], coords[1:][same], ring_of[:-1][same]
    met_length = np.zeros(len(a))
    if len(hinges):
        segs = shapely.linestrings(np.stack([a, b], axis=1))
        # the hinges were cut back from the plates by the section tolerance: reach past it
        grown = shapely.buffer(hinges, 2.0 * sections["tolerance"] + 1e-3)
        hit = shapely.STRtree(grown).query(segs, predicate="intersects")
        pieces = shapely.length(shapely.intersection(segs[hit[0]], grown[hit[1]]))
        met_length = np.bincount(hit[0], weights=pieces, minlength=len(a))
    free = met_length <= 0.25 * s.hinge_width
    n_sides = np.bincount(plate_of[free], minlength=len(plates))
    for k in np.flatnonzero(n_sides != 3)[:3]:
        problems.append(f"plate {k} has {n_sides[k]} free sides, not 3")
    good = np.isin(plate_of, np.flatnonzero(n_sides == 3)) & free
    side_a, side_b = a[good].reshape(-1, 3, 2), b[good].reshape(-1, 3, 2)
    d = side_b - side_a
    d = d / np.linalg.norm(d, axis=2, keepdims=True)
    out = np.stack([d[..., 1], -d[..., 0]], axis=2)  # outward normal of a counter-clockwise ring
    p0 = side_a + 0.5 * s.gap * out
    q0, e = np.roll(p0, -1, axis=1), np.roll(d, -1, axis=1)  # the next side
    den = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]
    t = ((q0 - p0)[..., 0] * e[..., 1] - (q0 - p0)[..., 1] * e[..., 0]) / den
    corners = (p0 + t[..., None] * d).reshape(-1, 2)  # corner between side i and side i + 1
    if not len(corners):
        return AsBuilt(np.zeros((0, 2)), np.zeros((0, 3), int), np.zeros((0, 2), int),
                       np.zeros(0, int), problems + ["no plates found"])
    pts = corners
    tol = min(0.05, 0.25 * s.gap)
    pairs = cKDTree(pts).query_pairs(tol, output_type="ndarray")
    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(pts),) * 2)
    n_nodes, label = connected_components(adj, directed=False)
    counts = np.bincount(label, minlength=n_nodes)
    nodes = np.stack([np.bincount(label, weights=pts[:, c], minlength=n_nodes) / counts
                      for c in range(2)], axis=1)
    tri = label.reshape(-1, 3)
    edges = np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]]),
                              axis=1), axis=0)
    shared = np.flatnonzero(counts >= 2)
    # hinges -> joints: each hinge holds exactly one shared node
    inside = shapely.STRtree(hinges).query(shapely.points(nodes[shared]), predicate="within") \
        if len(hinges) else np.zeros((2, 0), int)
    per_hinge = np.bincount(inside[1], minlength=len(hinges))
    per_node = np.bincount(inside[0], minlength=len(shared))
    if (per_hinge != 1).any():
        problems.append(f"{int(np.sum(per_hinge != 1))} hinge(s) hold no joint or several")
    if (per_node != 1).any():
        problems.append(f"{int(np.sum(per_node != 1))} shared corner(s) lie in no hinge")
    return AsBuilt(nodes, tri, edges, shared, problems, np.flatnonzero(n_sides == 3))


# --- the module's fixed points and the sequential transition -------------------------------------

def module_fixed_points(module: Network, d_in="d1", d_out="d2", max_branches=6) -> dict:
    """The printed state's fixed point D1* and the next fixed point D2* along the motion.

    The module's map (:func:`fabkit.maps.module_map`) walks its whole motion from the
    reference configuration, which must be a fixed point (d_out = d_in), branch by branch. From
    D1* the motion is followed in both directions of d_in, onto the next branch at each turning
    point (at most ``max_branches`` branches each way); the first fixed point met each way is
    a candidate, and D2* is the one reached with less travel of d_in. Slopes are the map's
    exact derivatives.

    Returns
    -------
    dict
        ``D1``, ``slope1`` (f'(D1*)), ``D2``, ``slope2``, ``d_in_turning`` (d_in at the last
        turning point passed on the way, if any) and ``positions`` (module configuration at
        D2*, (N, d)).

    Raises
    ------
    FabkitError
        The reference is not a fixed point, or no second fixed point is found.
    """
    from ..maps import module_map
    from ..maps.map1d import REFERENCE_SEPARATION

    d1 = float(module.port_distance(d_in))
    d2 = float(module.port_distance(d_out))
    if abs(d2 - d1) > START_RTOL * d1:  # typed coordinates: ~10 significant digits
        raise FabkitError(f"the printed state is not a fixed point: {d_in} = {d1:.9g}, "
                          f"{d_out} = {d2:.9g}")
    fmap = module_map(module, d_in, d_out)
    scale = max(fmap.domain[1], 1.0)
    found = []  # (d_in travelled, root, slope, turning value passed, configuration)
    for direction in (-1.0, 1.0):
        index, start, walked, turn = 0, d1, 0.0, None
        for _ in range(max_branches):
            br = fmap.branches[index]
            end = br.lo if direction < 0 else br.hi
            branch_map = fmap.on_branch(index)
            ahead = [p for p in branch_map.fixed_points()
                     if direction * (p.value - start) > (REFERENCE_SEPARATION * scale
                                                         if index == 0 else 0.0)]
            if ahead:
                p = min(ahead, key=lambda q: abs(q.value - start))
                found.append((walked + abs(p.value - start), p.value, p.slope, turn,
                              branch_map.configuration(p.value)))
                break
            walked += abs(end - start)
            nxt = [b for b in fmap.branches if b.previous == index and b.entered_at == end]
            if not nxt:
                break
            index, start, turn = nxt[0].index, end, end
            # on the next branch the walk goes on towards its other end
            other = nxt[0].hi if abs(nxt[0].lo - end) <= abs(nxt[0].hi - end) else nxt[0].lo
            direction = 1.0 if other > end else -1.0
    if not found:
        raise FabkitError("no second fixed point along the module's motion")
    walked, root, sl, turn, x = min(found, key=lambda f: f[0])
    return {"D1": d1, "slope1": float(fmap.derivative(d1)), "D2": float(root), "slope2": sl,
            "d_in_turning": turn, "positions": x}


def sequential_transition(net: Network, module: Network, copies: int, fixed: dict,
                          design_index=None, keep_positions: bool = False,
                          tolerance: float | None = None) -> dict:
    """Simulate the transition D1* -> D2* of a chain of ``copies`` modules (or one module).

    The two hinges farthest apart are pulled apart (or pushed together) towards their distance
    in the all-D2* state, as in the paper's experiment (hold one hinge, pull another). Near the
    far end that distance turns back (the last module has no neighbour to pass the motion to);
    the trace stops there and the last port d_{k+1} is driven on to D2*.

    Parameters
    ----------
    net : Network
        The chain (as built), with ports d1 ... d{copies+1}.
    module : Network
        The module.
    copies : int
    fixed : dict
        From :func:`module_fixed_points`.
    design_index : array_like of int, shape (N,), optional
        For each node of ``net``, its index in the design's chain (identity by default).
    keep_positions : bool
        Also return ``positions`` (S, N, 2): every configuration of every stage.
    tolerance : float, optional
        Largest |d_k - D2*| accepted at the end (design units); ``TRANSITION_RTOL * D2*`` by
        default. A linkage rebuilt from a file carries the file's rounding, and its own D2*
        moves with it (see :func:`as_built_tolerance`).

    Returns
    -------
    dict
        ``ok``, ``stages`` (drive, target, status, message), ``final`` (every d_k at the end),
        ``max_deviation`` from D2*, ``order`` (arclength at which each d_k passes halfway from
        D1* to D2*; increasing = sequential), ``sequential``, ``max_edge_error``.
    """
    d1s, d2s = fixed["D1"], fixed["D2"]
    final_module = module.with_nodes(fixed["positions"])
    final = final_module if copies == 1 else chain(final_module, copies)
    idx = np.arange(net.n_nodes) if design_index is None else np.asarray(design_index)
    owners = np.bincount(triangles_of(net).ravel(), minlength=net.n_nodes)
    joints = np.flatnonzero(owners >= 2)  # nodes held by a hinge
    xj = net.nodes[joints]
    dist = np.linalg.norm(xj[:, None] - xj[None], axis=2)
    a, b = np.unravel_index(np.argmax(dist), dist.shape)
    pa, pb = int(joints[a]), int(joints[b])
    target = float(np.linalg.norm(final.nodes[idx[pa]] - final.nodes[idx[pb]]))
    names = [f"d{k}" for k in range(1, copies + 2)]
    last = names[-1]

    tol = TRANSITION_RTOL * d2s if tolerance is None else float(tolerance)

    def settled(t):
        end = np.array([t.distance(n)[-1] for n in names])
        return bool(np.all(np.abs(end - d2s) <= tol))

    stages = [trace(net, drive=(pa, pb), to=target, method="projected")]
    labels = [f"({pa}, {pb})"]
    start = float(stages[0].drive[0])
    if stages[0].success and not settled(stages[0]):
        # the pulled distance passes its all-D2* value on the way: pull on to its turning point
        stages.append(trace(net, drive=(pa, pb), to=max(target + (target - start), 1e-3 * target),
                            method="projected", start=stages[-1].positions[-1]))
        labels.append(labels[0])
    if not settled(stages[-1]):
        stages.append(trace(net, drive=last, to=d2s, method="projected",
                            start=stages[-1].positions[-1]))
        labels.append(last)
    dist_k = np.concatenate([np.stack([t.distance(n) for n in names], axis=1) for t in stages])
    arc = np.concatenate([stages[0].arclength] + [
        t.arclength + sum(s.arclength[-1] for s in stages[:i]) for i, t in enumerate(stages)
        if i > 0])
    half = 0.5 * (d1s + d2s)
    crossed = dist_k < half if d2s < d1s else dist_k > half
    order = [float(arc[np.argmax(c)]) if c.any() else None for c in crossed.T]
    seq = all(o is not None for o in order) and bool(np.all(np.diff(order) >= 0))
    end = dist_k[-1]
    dev = float(np.abs(end - d2s).max())
    ok = stages[-1].success and dev <= tol and seq
    result = {
        "ok": bool(ok),
        "pulled": [pa, pb],
        "stages": [{"drive": label, "from": float(t.drive[0]), "to": float(t.drive[-1]),
                    "status": str(t.status), "message": t.message, "steps": int(t.n_steps)}
                   for label, t in zip(labels, stages)],
        "final": [float(v) for v in end],
        "D1": d1s, "D2": d2s,
        "max_deviation": dev,
        "tolerance": tol,
        "order": order,
        "sequential": bool(seq),
        "max_edge_error": float(max(t.max_edge_error for t in stages)),
    }
    if keep_positions:
        result["positions"] = np.concatenate([t.positions for t in stages])
    return result


# --- the check -----------------------------------------------------------------------------------

def as_built_tolerance(fixed: dict, node_deviation: float) -> float:
    """Tolerance on the final d_k of a transition simulated on a rebuilt linkage (design units).

    ``TRANSITION_RTOL * D2*`` plus ten times the largest distance of a rebuilt node from its
    design position: the rebuilt module's own D2* moves with its lengths (measured: 3-4 times
    the node error for the printed module, whose D2* lies next to a turning point); a wrong
    branch is off by O(1).
    """
    return TRANSITION_RTOL * fixed["D2"] + 10.0 * node_deviation


def _transition_checks(report, asbuilt, module, copies, fixed, arms, s,
                       node_deviation) -> list[Check]:
    """Simulate D1* -> D2* on the rebuilt linkage; the transition and hinge-strain checks.

    ``arms``: from :func:`hinge_arms` (the hinges' free lengths measured on the file)."""
    name = TRANSITION[0]
    tol = as_built_tolerance(fixed, node_deviation)
    try:
        tr = sequential_transition(asbuilt, module, copies, fixed, keep_positions=True,
                                   tolerance=tol)
    except FabkitError as exc:
        return [check(name, False, detail=str(exc))]
    turn, strain = hinge_strain(arms, tr.pop("positions"), s.hinge_width)
    worst = int(np.argmax(strain))
    report["transition"] = dict(tr, status="simulated")
    report["fixed_points"] = {k: fixed[k] for k in ("D1", "slope1", "D2", "slope2",
                                                   "d_in_turning")}
    return [
        check(name, tr["ok"], value=tr["max_deviation"], limit=tol,
              detail=f"D1* = {fixed['D1']:.6g} (slope {fixed['slope1']:.2g}) -> D2* = "
                     f"{fixed['D2']:.9g} (slope {fixed['slope2']:.4g}); "
                     f"{'sequential' if tr['sequential'] else 'not sequential'}"),
        check(TRANSITION[1], strain[worst] <= s.strain_limit,
              value=float(strain[worst]), limit=s.strain_limit,
              detail=f"largest hinge rotation {np.degrees(turn.max()):.1f} degrees (joint "
                     f"{int(arms['joint'][worst])}); {s.material} hinges {s.hinge_width:g} mm "
                     f"wide, {2 * arms['length'][worst]:.3g} mm free length (measured)"),
    ]


def triangles_of(net) -> np.ndarray:
    """Every triangle of a network's edges (3-cliques), sorted node indices, rows sorted."""
    nbr = [set() for _ in range(net.n_nodes)]
    for i, j in net.edges.tolist():
        nbr[i].add(j)
        nbr[j].add(i)
    out = sorted({tuple(sorted((i, j, k))) for i, j in net.edges.tolist()
                  for k in nbr[i] & nbr[j]})
    return np.array(out, dtype=np.int64).reshape(-1, 3)


def hinge_arms(built: AsBuilt, sections, triangles, match) -> dict:
    """The hinge arms of a rebuilt linkage, measured on the file: for every plate at every
    hinge joint, its free length (the distance from the joint to the plate, mm) and the next
    plate around the joint (counter-clockwise).

    ``triangles``: the rebuilt triangles in the design's numbering; ``match``: the design node
    of each rebuilt node. Returns ``plate`` (triangle row), ``joint`` (design node),
    ``partner`` (arm index) and ``length``.
    """
    import shapely

    plates = np.asarray(sections["plates"])[built.plate_index]
    owners: dict[int, list[int]] = {}
    for t, tri in enumerate(built.triangles.tolist()):
        for v in tri:
            owners.setdefault(v, []).append(t)
    plate, joint, length, partner = [], [], [], []
    for v, ts in sorted(owners.items()):
        if len(ts) < 2:
            continue
        centre = built.nodes[v]
        ang = [np.arctan2(*(built.nodes[built.triangles[t]].mean(0) - centre)[::-1]) for t in ts]
        ts = [t for _, t in sorted(zip(ang, ts))]
        first = len(plate)
        for k, t in enumerate(ts):
            plate.append(t)
            joint.append(int(match[v]))
            length.append(float(shapely.distance(shapely.Point(*centre), plates[t])))
            partner.append(first + (k + 1) % len(ts))
    return {"plate": np.array(plate, dtype=np.int64), "joint": np.array(joint, dtype=np.int64),
            "partner": np.array(partner, dtype=np.int64), "length": np.array(length),
            "triangles": np.asarray(triangles)}


def hinge_strain(arms: dict, positions, hinge_width: float):
    """Largest rotation of each hinge arm against the next plate over a motion, and the
    bending strain of a neck of ``hinge_width`` bent uniformly over the two arms' free length
    (``hinge_width * rotation / (2 * length)``).

    ``positions``: (S, N, 2) configurations in the design's numbering. Returns (rotation,
    strain), one value per arm."""
    x = np.asarray(positions, dtype=np.float64)
    tri = arms["triangles"]
    d = x[:, tri[:, 1]] - x[:, tri[:, 0]]
    ang = np.unwrap(np.arctan2(d[..., 1], d[..., 0]), axis=0)
    rel = ang - ang[:1]
    p, q = arms["plate"], arms["plate"][arms["partner"]]
    turn = np.abs(rel[:, p] - rel[:, q]).max(0)
    free = arms["length"] + arms["length"][arms["partner"]]
    return turn, hinge_width * turn / (2.0 * free)


def _module_of(design):
    """(module network, copies) of a design: a [chain] of one module template, or the design."""
    raw = design.raw or {}
    section = raw.get("chain")
    mod = getattr(design, "references", {}).get("chain.module")
    if isinstance(section, dict) and mod is not None:
        return mod.network, int(section.get("copies", 1))
    return design.network, 1


#: Words in a binary STL's header that mark a print-in-place linkage (one body per bar).
PINNED_HEADER = b"print-in-place"


def check_file(path, design=None, settings=None, *, motion=None, folder=None) -> dict:
    """Read an exported STL back (with the other beds of its export) and check it (see the
    module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        ``NAME.stl``, or one ``NAME_bed<k>.stl`` (every bed of the export is read).
    design : Design, optional
        Without it only the solid checks run (the volume, the rebuilt linkage and the motion
        need the design).
    settings : dict, optional
        The command-line overrides used for the export (``{"print": {...}}``).
    motion : TracedMotion, optional
        The design's motion traced once by the pipeline (a linkage's window and the design's
        trace to compare with are taken from it).
    folder : OutputFolder or ReadBack, optional
        Where the beds are read from (:func:`fabkit.check.check_file`): by path when None.

    Returns
    -------
    dict
        ``ok``, ``checks`` (name, ok, value, limit, detail), and with a design ``as_built``
        (modes, node deviation) and ``transition`` (hinges) or ``motion`` (pins); ``files``
        when several beds were read.

    Raises
    ------
    FabricationError
        A file cannot be read as an STL mesh.
    """
    paths = bed_set(path, folder)
    data = read_set(paths, folder)
    require_triangles(path, sum(stl_triangles(d, p) for p, d in data.items()), design)
    meshes = [_load(d, p) for p, d in data.items()]
    pinned = all(PINNED_HEADER in d[:80] for d in data.values())
    # where the beds lie (an STL is centred on its bed's centre) does not matter: every piece
    # is found in the design by its own geometry
    return check_meshes(meshes, [p.name for p in paths], design, settings, pinned=pinned,
                        motion=motion)


def check_meshes(meshes, names, design=None, settings=None, *, fmt: str = FORMAT,
                 pinned: bool = False, motion=None) -> dict:
    """Check the beds of one export, read back as meshes in bed coordinates (mm).

    Parameters
    ----------
    meshes : list of trimesh.Trimesh
        One per bed, in bed order.
    names : list of str
        Their file names.
    design, settings, motion
        As for :func:`check_file`.
    fmt : str
        Format name for the report.
    pinned : bool
        Without a design: the file says it is a print-in-place linkage (one body per bar), so
        the solid checks do not ask for one body.

    Returns
    -------
    dict
    """
    from ..settings.design import design_settings

    report = {"file": names[0], "format": fmt}
    if len(names) > 1:
        report["files"] = list(names)
    if design is None:
        checks = []
        for name, mesh in zip(names, meshes):
            checks += [c.named(name) if len(names) > 1 else c
                       for c in check_mesh(mesh, bodies=None if pinned else 1)]
        report["not_checked"] = ("no design given: the rebuilt linkage, its modes and its motion "
                                 "need the design's template")
        return finish(report, checks)
    s = design_settings(design, settings).require("print")
    if s.linkage == "pins":
        from .pinned import check_pinned

        return check_pinned(meshes, names, design, s, report, motion)
    return _check_hinge_beds(meshes, names, design, s, report)


def _check_hinge_beds(meshes, names, design, s, report) -> dict:
    """The hinge print's beds: every piece rebuilt from the solid, laid onto the design by its
    own geometry (:mod:`fabkit.check.register`), and checked against the part of the design
    it builds; a print of one piece is also driven through its transition."""
    net = design.network
    checks, found = [], []  # found: (bed, sections, rebuilt linkage, its nodes in one piece)
    for b, mesh in enumerate(meshes):
        sections = slab_sections(mesh, s)
        built = rebuild_linkage(mesh, s, sections)
        pieces = pieces_of(len(built.nodes), built.edges) if len(built.nodes) else []
        # one body per piece: a body split where the design is whole, or joined where a
        # hinge should not be, does not match the plates found in its cross-sections
        checks += [c.named(names[b]) if len(meshes) > 1 else c
                   for c in check_mesh(mesh, s, None, sections, bodies=max(1, len(pieces)))]
        name = "plates -> triangles, hinges -> joints"
        checks.append(check(name if len(meshes) == 1 else f"{names[b]}: {name}",
                            not built.problems,
                            value=[len(built.triangles), len(built.joints)], limit=None,
                            detail="; ".join(built.problems) or "every hinge holds one joint"))
        found += [(b, sections, built, members) for members in pieces]
    if not found:  # no plate could be read: nothing to lay onto the design
        return finish(report, checks, PIECE_CHECKS, "no plate of the print could be read as a "
                                                    "triangle")
    # plates that could not be read are reported above; the rest are rebuilt and compared, so
    # that what they build (a brace, a missing bar) is said too
    pieces = []
    for _, _, built, members in found:
        local = np.full(len(built.nodes), -1, dtype=np.int64)
        local[members] = np.arange(len(members))
        edges = built.edges[np.isin(built.edges[:, 0], members)]
        pieces.append((built.nodes[members], local[edges]))
    placed = place_pieces(pieces, net.nodes * s.scale, net.edges, tol=NODE_TOL_MM)
    single = len(found) == 1
    built_pieces = []
    for k, ((b, sections, built, members), place) in enumerate(zip(found, placed)):
        sub = {}
        piece_checks = _check_hinge_piece(design, s, sections, built, members, place, sub,
                                          transition=single)
        checks += [c if single else c.named(f"piece {k + 1} on {names[b]}")
                   for c in piece_checks]
        built_pieces.append({"piece": k + 1, "bed": b + 1, **sub.get("as_built", {})})
        if single:
            report.update({key: v for key, v in sub.items()})
    if not single:
        matched = [p for p in placed if p is not None]
        held = np.bincount(np.concatenate([p.match for p in matched] + [np.zeros(0, int)]),
                           minlength=net.n_nodes)
        whole = bool((held >= 1).all())
        checks.append(check("pieces build the design", whole and len(matched) == len(placed),
                            value=int(np.sum(held == 0)), limit=0,
                            detail=f"{len(found)} pieces laid onto the design; nodes built by "
                                   f"no piece: {int(np.sum(held == 0))}"))
        report["as_built"] = {"pieces": built_pieces}
        report["transition"] = {"status": f"not simulated: the print is split into "
                                          f"{len(found)} pieces, each checked on its own; "
                                          "joined, they are the design"}
    return finish(report, checks)


def _check_hinge_piece(design, s, sections, built, members, place, report, *,
                       transition: bool) -> list[Check]:
    """One piece rebuilt from a bed: its nodes and edges against the part of the design it
    lies on, its modes, and (with ``transition``) the D1* -> D2* transition; the checks it
    could not reach are reported as not run."""
    checks = _hinge_piece_checks(design, s, sections, built, members, place, report,
                                 transition=transition)
    return checks + not_run_after(checks, PIECE_CHECKS)


def _hinge_piece_checks(design, s, sections, built, members, place, report, *,
                        transition: bool) -> list[Check]:
    net = design.network
    if place is None:
        return [check("rebuilt nodes match the design", False, value=None, limit=NODE_TOL_MM,
                      detail=f"the piece fits nowhere in the design {design.name}")]
    worst = int(np.argmax(place.deviation))
    dev = float(place.deviation[worst])
    match = place.match
    bijective = np.unique(match).size == len(match)
    matched = bijective and dev <= NODE_TOL_MM and (not transition or len(match) == net.n_nodes)
    if matched:
        detail = "largest distance (mm) between a rebuilt node and its design node"
    elif not bijective:
        detail = "two rebuilt nodes match one design node"
    elif dev > NODE_TOL_MM:
        detail = (f"the node at design node {match[worst]} lies {dev:.3f} mm from where the "
                  "design has it (the piece laid onto the design by its best rigid fit)")
    else:
        detail = f"the piece builds {len(match)} of the design's {net.n_nodes} nodes"
    checks = [check("rebuilt nodes match the design", matched, value=dev, limit=NODE_TOL_MM,
                    detail=detail)]
    if not matched:  # the file was not made from this design with these settings
        return checks
    # the piece in the design's frame and numbering: its nodes where the fit puts them
    keep = np.sort(match)
    index = np.full(net.n_nodes, -1, dtype=np.int64)
    index[keep] = np.arange(len(keep))
    local = np.full(len(built.nodes), -1, dtype=np.int64)
    local[members] = np.arange(len(members))
    in_design = (built.nodes[members] @ place.rotation.T + place.shift) / s.scale
    nodes = np.empty((len(keep), 2))
    nodes[index[match]] = in_design
    edges = index[match[local[built.edges[np.isin(built.edges[:, 0], members)]]]]
    sub_net = net if len(keep) == net.n_nodes else _sub_network(net, keep)
    ports = dict(net.ports) if len(keep) == net.n_nodes else {}
    try:
        asbuilt = Network(nodes, edges, ports=ports)
    except FabkitError as exc:
        checks.append(check("rebuilt edges match the design", False, detail=str(exc)))
        return checks
    have = {tuple(e) for e in np.sort(edges, 1).tolist()}
    want = {tuple(e) for e in np.sort(sub_net.edges, 1).tolist()}
    extra, missing = sorted(have - want), sorted(want - have)
    checks.append(check("rebuilt edges match the design", have == want,
                        value=asbuilt.n_edges, limit=sub_net.n_edges,
                        detail="edges (bars between nodes) rebuilt from the plates; the design's"
                        if have == want else
                        f"edges the design lacks {extra[:4]}, design edges not built "
                        f"{missing[:4]} (design nodes)"))
    modes = count_modes(asbuilt)
    detail = str(modes)
    ok_modes = modes.conformational == 1
    if not ok_modes:  # a print is faithful when it moves as its design does
        designed = count_modes(sub_net)
        ok_modes = designed.conformational == modes.conformational
        detail += f"; the design has {designed.conformational}"
    checks.append(check("one conformational motion", ok_modes,
                        value=int(modes.conformational), limit=1, detail=detail))
    report["as_built"] = {"nodes": asbuilt.n_nodes, "edges": asbuilt.n_edges,
                          "triangles": int(len(built.triangles)), "joints": int(len(built.joints)),
                          "node_deviation_mm": dev, "modes": str(modes)}
    if not transition:
        return checks
    if modes.conformational != 1 or "d1" not in net.ports or "d2" not in net.ports:
        report["transition"] = {"status": "not applicable: needs one motion and ports d1, d2"}
        if not ok_modes and "d1" in net.ports and "d2" in net.ports:
            checks += [not_run(n, f"the rebuilt linkage has {modes.conformational} "
                                  "conformational motions, the design 1") for n in TRANSITION]
    else:
        try:
            module, copies = _module_of(design)
            fixed = module_fixed_points(module)
        except FabkitError as exc:  # not a module between two fixed points: nothing to simulate
            report["transition"] = {"status": f"not applicable: {exc}"}
        else:
            arms = hinge_arms(built, sections, match[local[built.triangles]], match)
            checks.extend(_transition_checks(report, asbuilt, module, copies, fixed, arms, s,
                                             dev / s.scale))
    return checks


def _sub_network(net, nodes):
    """The part of ``net`` on ``nodes`` (sorted), renumbered in their order."""
    keep = np.zeros(net.n_nodes, dtype=bool)
    keep[nodes] = True
    index = np.cumsum(keep) - 1
    return Network(net.nodes[keep], index[net.edges[keep[net.edges].all(axis=1)]])
