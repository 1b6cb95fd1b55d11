"""Printed triangle-hinge networks: rigid plates joined only by thin hinges, as one solid.

A planar network of rigid triangles that share vertices becomes one printable body:

* every triangle is a **plate** of ``plate_thickness``, inset from its own edges by ``gap / 2``
  (so two plates are never closer than ``gap``: plates that touch would make a solid that is not
  watertight, and could not move);
* at every vertex shared by two or more triangles a **hinge** is the only material joining them:
  one straight arm per plate along the bisector of the plate's corner, from the joint to the
  plate, of width ``hinge_width``, and a small hub at the joint. Each plate corner at a joint is
  cut off square to its bisector at ``hinge_length / 2`` from the joint (further out at a corner
  so sharp that the plate would be narrower than the hinge plus one nozzle width there), so
  that every hinge has at least ``hinge_length`` of free material to bend. A ``"bridge"`` hinge
  is ``hinge_layers`` layers thick on the build plate, a ``"neck"`` hinge as tall as the plates
  less their top layer.

The plates and hinges are 2D outlines (exact polygons); the solid is their extrusion, joined by
manifold3d. The analytic volume (plates by the shoelace formula, exposed hinge outline by exact
polygon clipping) is what the STL is checked against.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import FabricationError
from ..model.network import Network
from ..model.triangles import rigid_triangles
from ..settings.printing import PrintSettings

__all__ = ["rigid_triangles", "PrintGeometry", "print_geometry", "print_solid", "solid_mesh",
           "hinge_bending", "manifold3d"]

#: Sides of the polygon standing for a hub (circle) at a joint.
_HUB_SIDES = 24
#: Hub inradius as a fraction of the hinge width (more than 1/2, so that the square ends of the
#: arms lie strictly inside the hub and no sliver of an arm's corner pokes out of it).
_HUB_RATIO = 0.6


#: A triangle whose signed area is below this, relative to the plate's extent squared, is flat
#: (collinear corners to round-off).
FLAT_TRIANGLE_RTOL = 1e-12
#: Parts exactly one gap apart are not neighbours: the gap's query distance is shrunk by this
#: relative amount so that round-off does not make them touch.
GAP_SLACK = 1e-9


@dataclass(frozen=True, eq=False)
class PrintGeometry:
    """The 2D outlines of a printable triangle-hinge network (mm, print frame).

    Attributes
    ----------
    settings : PrintSettings
    triangles : numpy.ndarray of int, shape (M, 3)
        Node indices, counter-clockwise in the print frame.
    positions : numpy.ndarray, shape (N, 2)
        Joint positions (mm): the network's nodes scaled and moved so that the bounding box of
        the nodes is centred on the origin.
    plates : list of numpy.ndarray, shape (k_i, 2)
        Plate outlines, counter-clockwise (k_i = 3 + number of cut corners).
    plate_areas : numpy.ndarray, shape (M,)
    joints : numpy.ndarray of int, shape (H,)
        Nodes where a hinge joins two or more plates.
    arms : numpy.ndarray, shape (A, 4, 2)
        Hinge arm rectangles (counter-clockwise), one per plate corner at a joint.
    arm_plate, arm_joint : numpy.ndarray of int, shape (A,)
        The plate (triangle row) and the joint (node) of each arm.
    arm_length : numpy.ndarray, shape (A,)
        Free length of each arm, from the joint to its plate (mm): ``hinge_length / 2``, or
        more at a corner too sharp to be as wide as the hinge there.
    hubs : numpy.ndarray, shape (H, S, 2)
        Hub polygons at the joints.
    hinge_area : float
        Area of the hinge outline outside the plates (mm^2).
    min_feature : dict
        Narrowest features: ``hinge_width``, ``plate_neck`` (plate width where a hinge meets
        it), ``plate_edge`` (shortest remaining plate side), ``plate_gap`` (smallest distance
        between plates).
    """

    settings: PrintSettings
    triangles: np.ndarray
    positions: np.ndarray
    plates: list
    plate_areas: np.ndarray
    joints: np.ndarray
    arms: np.ndarray
    arm_plate: np.ndarray
    arm_joint: np.ndarray
    arm_length: np.ndarray
    hubs: np.ndarray
    hinge_area: float
    min_feature: dict = field(default_factory=dict)

    @property
    def plate_volume(self) -> float:
        return float(self.plate_areas.sum() * self.settings.plate_thickness)

    @property
    def hinge_volume(self) -> float:
        return float(self.hinge_area * self.settings.hinge_thickness)

    @property
    def volume(self) -> float:
        """Analytic volume of the solid (mm^3): plates plus the hinge material outside them."""
        return self.plate_volume + self.hinge_volume

    @property
    def size(self) -> tuple[float, float, float]:
        """Bounding box of the solid (mm)."""
        pts = np.concatenate([np.concatenate(self.plates), self.arms.reshape(-1, 2),
                              self.hubs.reshape(-1, 2)])
        ext = pts.max(0) - pts.min(0)
        return float(ext[0]), float(ext[1]), float(self.settings.plate_thickness)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _shoelace(poly):
    """Signed area of polygons (..., k, 2) (repeated points contribute nothing)."""
    nxt = np.roll(poly, -1, axis=-2)
    return 0.5 * _cross(poly, nxt).sum(-1)


def _fmt_tri(t) -> str:
    return "(" + ", ".join(str(int(v)) for v in t) + ")"


def print_geometry(net: Network, settings: PrintSettings, positions=None) -> PrintGeometry:
    """Plates and hinges of a planar triangle network, ready to extrude.

    Parameters
    ----------
    net : Network
        A 2D network made of rigid triangles (``settings.rigid_triangles`` or its 3-cliques).
    settings : PrintSettings
    positions : array_like, shape (N, 2), optional
        Configuration to print (design units); ``net.nodes`` by default.

    Returns
    -------
    PrintGeometry

    Raises
    ------
    FabricationError
        A 3D network; edges outside triangles; triangles too small for the gap or the hinges;
        a hinge length too short for the gap at a sharp corner; plates that would come closer
        than the gap (overlapping triangles); hinge material that would reach another plate;
        triangles that fall apart into separate pieces. Each message names the triangle or
        node and the setting to change.

    Examples
    --------
    >>> from fabkit.settings.printing import print_settings
    >>> net = Network([[0, 0], [10, 0], [5, 8], [15, 8]], [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]])
    >>> geo = print_geometry(net, print_settings({"scale": 3.0, "hinge_length": 4.0}))
    >>> geo.joints.tolist(), len(geo.plates)
    ([1, 2], 2)
    """
    s = settings
    if net.dim != 2:
        raise FabricationError(f"printed triangle networks are planar; this network is {net.dim}D")
    x = net.nodes if positions is None else np.asarray(positions, dtype=np.float64)
    if x.shape != net.nodes.shape:
        raise FabricationError(f"positions must have shape {net.nodes.shape}, got {x.shape}")
    tri = rigid_triangles(net, s.rigid_triangles)
    p = x * s.scale
    # centre the outline on the origin: an STL stores float32, whose rounding grows with the
    # distance from the origin (1 m away it is 6e-5 mm)
    p = p - 0.5 * (p.min(0) + p.max(0))
    # counter-clockwise triangles
    signed = _shoelace(p[tri])
    flat = np.flatnonzero(np.abs(signed) <= FLAT_TRIANGLE_RTOL * max(float(np.ptp(p)), 1.0) ** 2)
    if flat.size:
        raise FabricationError(f"triangle {_fmt_tri(tri[flat[0]])} is flat (its nodes are "
                               "collinear) in the configuration to print")
    tri = np.where((signed < 0)[:, None], tri[:, [0, 2, 1]], tri)
    m = len(tri)
    v = p[tri]  # (M, 3, 2)
    nxt, prv = np.roll(v, -1, axis=1), np.roll(v, 1, axis=1)
    side = np.linalg.norm(np.roll(v, -1, axis=1) - np.roll(v, 1, axis=1), axis=2)  # opposite
    perim = side.sum(1)
    area = 0.5 * np.abs(_cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]))
    inradius = 2.0 * area / perim
    half_gap = 0.5 * s.gap
    too_small = np.flatnonzero(inradius - half_gap < s.nozzle_width)
    if too_small.size:
        t = too_small[0]
        raise FabricationError(
            f"triangle {_fmt_tri(tri[t])} is too small to print with a {s.gap:g} mm gap: its "
            f"inscribed circle has radius {inradius[t]:.3g} mm; raise scale above "
            f"{s.scale * (half_gap + s.nozzle_width) / inradius[t]:.3g}")
    incenter = (side[..., None] * v).sum(1) / perim[:, None]
    inset = incenter[:, None] + (v - incenter[:, None]) * (1.0 - half_gap / inradius)[:, None, None]
    to_next, to_prev = _unit(nxt - v), _unit(prv - v)
    bisector = _unit(to_next + to_prev)  # into the triangle
    cos_full = np.clip((to_next * to_prev).sum(-1), -1.0, 1.0)
    theta = np.arccos(cos_full)
    corner_offset = half_gap / np.sin(0.5 * theta)  # joint to inset corner

    # joints: nodes shared by two or more triangles
    owners = np.bincount(tri.ravel(), minlength=net.n_nodes)
    is_joint = owners[tri] >= 2  # (M, 3)
    joints = np.flatnonzero(owners >= 2)
    if m > 1:
        _check_connected(tri, owners, net.n_nodes)

    # each plate corner at a joint is cut square to its bisector, at least hinge_length / 2 from
    # the joint and far enough that the plate is as wide as the hinge where the hinge meets it,
    # with half a nozzle width to spare on each side (sharp corners get longer arms; a hinge
    # flush with the plate's sides would leave edges that nearly coincide, which the float32
    # coordinates of an STL can merge)
    landing = s.hinge_width + s.nozzle_width
    c = np.where(is_joint, np.maximum(s.arm_length,
                                      corner_offset + 0.5 * landing / np.tan(0.5 * theta)),
                 0.0)
    along = np.where(is_joint, (c - corner_offset) / np.cos(0.5 * theta), 0.0)
    neck = np.where(is_joint, 2.0 * (c - corner_offset) * np.tan(0.5 * theta), np.inf)
    inset_next = np.roll(inset, -1, axis=1) - inset
    inset_len = np.linalg.norm(inset_next, axis=2)  # side k -> k+1
    remaining = inset_len - along - np.roll(along, -1, axis=1)
    if (remaining < s.nozzle_width).any():
        t, k = np.argwhere(remaining < s.nozzle_width)[0]
        raise FabricationError(
            f"triangle {_fmt_tri(tri[t])} is too small for {s.hinge_length:g} mm hinges: the cut "
            f"corners leave {max(remaining[t, k], 0.0):.3g} mm of its side ({tri[t, k]}, "
            f"{tri[t, (k + 1) % 3]}); shorten hinge_length or raise scale")
    u_next = _unit(np.roll(inset, -1, axis=1) - inset)
    u_prev = _unit(np.roll(inset, 1, axis=1) - inset)
    first = inset + along[..., None] * u_prev  # on the side coming in
    second = inset + along[..., None] * u_next  # on the side going out
    ring = np.stack([first, second], axis=2).reshape(m, 6, 2)  # duplicates where no cut
    keep = np.stack([is_joint, np.ones_like(is_joint)], axis=2).reshape(m, 6)
    plate_areas = _shoelace(ring)
    counts = keep.sum(1)
    plates = np.split(ring[keep], np.cumsum(counts)[:-1])

    # hinge arms: from the joint along the corner's bisector to inside the plate
    w = s.hinge_width
    overlap = 0.5 * w
    a_t, a_k = np.nonzero(is_joint)
    joint_xy = v[a_t, a_k]
    b = bisector[a_t, a_k]
    normal = np.stack([-b[:, 1], b[:, 0]], axis=1)
    arm_len = c[a_t, a_k]
    far = joint_xy + (arm_len + overlap)[:, None] * b
    arms = np.stack([joint_xy - 0.5 * w * normal, far - 0.5 * w * normal,
                     far + 0.5 * w * normal, joint_xy + 0.5 * w * normal], axis=1)
    arms = np.where((_shoelace(arms) < 0)[:, None, None], arms[:, ::-1], arms)
    # the arm's end must lie inside its plate (a plate too short along its bisector)
    depth = (arm_len + overlap) - corner_offset[a_t, a_k]
    reach = (_inside_convex(ring[a_t], far - 0.5 * w * normal)
             & _inside_convex(ring[a_t], far + 0.5 * w * normal))
    if not reach.all():
        i = np.flatnonzero(~reach)[0]
        raise FabricationError(
            f"the hinge at node {tri[a_t[i], a_k[i]]} does not fit inside triangle "
            f"{_fmt_tri(tri[a_t[i]])} ({depth[i]:.3g} mm deep); shorten hinge_length or raise "
            "scale")
    ang = (np.arange(_HUB_SIDES) + 0.5) * (2.0 * np.pi / _HUB_SIDES)
    r_hub = _HUB_RATIO * w / np.cos(np.pi / _HUB_SIDES)
    circle = r_hub * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    hubs = p[joints][:, None, :] + circle[None]
    hinge_area, plate_gap = _check_clearances(tri, plates, arms, a_t, tri[a_t, a_k], hubs, joints,
                                              s)
    min_feature = {
        "hinge_width": float(w),
        "plate_neck": float(neck[is_joint].min()) if is_joint.any() else None,
        "plate_edge": float(remaining.min()),
        "plate_gap": plate_gap,
    }
    return PrintGeometry(settings=s, triangles=tri, positions=p, plates=plates,
                         plate_areas=plate_areas, joints=joints, arms=arms, arm_plate=a_t,
                         arm_joint=tri[a_t, a_k], arm_length=arm_len, hubs=hubs,
                         hinge_area=hinge_area, min_feature=min_feature)


def _inside_convex(ring, pts) -> np.ndarray:
    """Points strictly inside counter-clockwise convex polygons given as (A, 6, 2) rings with
    repeated points (edges of zero length are ignored)."""
    nxt = np.roll(ring, -1, axis=1)
    edge = nxt - ring
    rel = pts[:, None, :] - ring
    cr = _cross(edge, rel)
    real = np.linalg.norm(edge, axis=2) > 0
    return np.where(real, cr > 0, True).all(1)


def _check_connected(tri, owners, n):
    """Refuse triangles that fall apart into separate pieces (they would be separate bodies)."""
    from scipy.sparse.csgraph import connected_components

    m = len(tri)
    rows = np.repeat(np.arange(m), 3)
    cols = tri.ravel()
    shared = owners[cols] >= 2
    g = sp.csr_matrix((np.ones(shared.sum()), (rows[shared], m + cols[shared])),
                      shape=(m + n, m + n))
    ncomp, labels = connected_components(g, directed=False)
    pieces = np.unique(labels[:m])
    if pieces.size > 1:
        lone = np.flatnonzero(labels[:m] != labels[0])[0]
        raise FabricationError(
            f"the triangles form {pieces.size} separate pieces (triangle {_fmt_tri(tri[lone])} "
            f"is not joined to triangle {_fmt_tri(tri[0])}); a print must be one body")


def _check_clearances(tri, plates, arms, arm_plate, arm_joint, hubs, joints, s):
    """Plates at least ``gap`` apart; hinge material clear of the plates and hinges it does not
    join. Returns (area of the hinge outline outside the plates, smallest plate gap)."""
    import shapely

    counts = np.array([len(q) for q in plates])
    rings = shapely.linearrings(np.concatenate(plates), indices=np.repeat(np.arange(len(plates)),
                                                                         counts))
    plate_geoms = shapely.polygons(rings)
    tree = shapely.STRtree(plate_geoms)
    pairs = tree.query(plate_geoms, predicate="dwithin", distance=s.gap * (1.0 - GAP_SLACK))
    pairs = pairs[:, pairs[0] < pairs[1]]
    if pairs.shape[1]:
        i, j = pairs[:, 0]
        d = shapely.distance(plate_geoms[i], plate_geoms[j])
        raise FabricationError(
            f"the plates of triangles {_fmt_tri(tri[i])} and {_fmt_tri(tri[j])} would be "
            f"{d:.3g} mm apart, less than the {s.gap:g} mm gap (the triangles overlap or touch "
            "in this configuration)")
    # smallest plate-to-plate distance among near neighbours (for the report)
    near = tree.query(plate_geoms, predicate="dwithin", distance=4.0 * s.gap + s.hinge_length)
    near = near[:, near[0] < near[1]]
    plate_gap = (float(shapely.distance(plate_geoms[near[0]], plate_geoms[near[1]]).min())
                 if near.shape[1] else None)
    arm_geoms = shapely.polygons(arms)
    hub_geoms = shapely.polygons(hubs)
    # hinge material of joint v must stay clear of every plate that has no corner at v
    piece_geoms = np.concatenate([arm_geoms, hub_geoms])
    piece_joint = np.concatenate([arm_joint, joints])
    hits = tree.query(piece_geoms, predicate="dwithin", distance=0.5 * s.gap)
    at_joint = (tri[hits[1]] == piece_joint[hits[0]][:, None]).any(1)
    bad = hits[:, ~at_joint]
    if bad.shape[1]:
        k, t = bad[:, 0]
        raise FabricationError(
            f"the hinge at node {piece_joint[k]} comes within {0.5 * s.gap:g} mm of the plate of "
            f"triangle {_fmt_tri(tri[t])}; shorten or narrow the hinges, or raise scale")
    # an arm must also keep clear of the other plates at its own joint (else it would fuse to
    # them, shortening the hinge or leaving faces that nearly touch)
    near_arm = tree.query(arm_geoms, predicate="dwithin", distance=0.5 * s.gap)
    other = (near_arm[1] != arm_plate[near_arm[0]]) & (
        tri[near_arm[1]] == arm_joint[near_arm[0]][:, None]).any(1)
    if other.any():
        k, t = near_arm[:, np.argmax(other)]
        raise FabricationError(
            f"the hinge arm at node {arm_joint[k]} comes within {0.5 * s.gap:g} mm of the plate "
            f"of triangle {_fmt_tri(tri[t])}, which meets the same joint; the angle between the "
            "triangles there is too small for this hinge: narrow it or raise the gap")
    htree = shapely.STRtree(piece_geoms)
    hh = htree.query(piece_geoms, predicate="dwithin", distance=s.gap * (1.0 - GAP_SLACK))
    clash = hh[:, piece_joint[hh[0]] != piece_joint[hh[1]]]
    if clash.shape[1]:
        a, b = piece_joint[clash[:, 0]]
        raise FabricationError(f"the hinges at nodes {a} and {b} come closer than the "
                               f"{s.gap:g} mm gap; shorten or narrow the hinges, or raise scale")
    hinge_outline = shapely.union_all(piece_geoms)
    exposed = shapely.difference(hinge_outline, shapely.union_all(plate_geoms))
    return float(shapely.area(exposed)), plate_gap


def manifold3d():
    """The manifold3d module, or a FabricationError saying that printing needs it (an optional
    dependency: only the STL format uses it)."""
    try:
        import manifold3d as mf
    except ImportError as exc:
        raise FabricationError(f"3D printing needs the manifold3d package: {exc}") from None
    return mf


def print_solid(geo: PrintGeometry):
    """The printable body as a manifold3d ``Manifold`` (mm, z from 0 up).

    Plates are extruded to ``plate_thickness``, the hinge outline (arms and hubs) to the hinge
    thickness, both from z = 0; one union joins them. manifold3d evaluates lazily: the work
    happens when the result is first used (``solid_mesh`` forces it).

    Raises
    ------
    FabricationError
        manifold3d is missing, or the union is not a valid manifold.
    """
    mf = manifold3d()
    s = geo.settings
    plates = mf.CrossSection([np.ascontiguousarray(q) for q in geo.plates],
                             mf.FillRule.Positive)
    pieces = [np.ascontiguousarray(q) for q in geo.arms] + [np.ascontiguousarray(q)
                                                             for q in geo.hubs]
    hinges = mf.CrossSection(pieces, mf.FillRule.Positive)
    body = (mf.Manifold.extrude(plates, s.plate_thickness)
            + mf.Manifold.extrude(hinges, s.hinge_thickness))
    status = body.status()
    if status != mf.Error.NoError:
        raise FabricationError(f"the solid could not be built (manifold3d: {status.name})")
    return body


def solid_mesh(body) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) float64 and triangles (F, 3) int64 of a manifold3d body."""
    mesh = body.to_mesh()
    verts = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    faces = np.asarray(mesh.tri_verts, dtype=np.int64)
    return verts, faces


def hinge_bending(geo: PrintGeometry, positions) -> tuple[np.ndarray, np.ndarray]:
    """Largest rotation of each hinge over a motion, and the bending strain it causes.

    A hinge joining two plates is modelled as a neck of width ``hinge_width`` and free length
    the sum of its two arms, bent uniformly: curvature = rotation / length, so the largest
    strain, at the neck's edges, is ``hinge_width * rotation / (2 * length)``.

    Parameters
    ----------
    geo : PrintGeometry
    positions : array_like, shape (S, N, 2)
        The network's configurations along its motion (design units); the first is the
        printed state.

    Returns
    -------
    rotation : numpy.ndarray, shape (A,)
        For each arm, the largest change (radians) along the motion of the angle between its
        plate and the next plate around the same joint (the joint's last arm is paired with
        its first).
    strain : numpy.ndarray, shape (A,)
    """
    x = np.asarray(positions, dtype=np.float64)
    tri = geo.triangles
    d = x[:, tri[:, 1]] - x[:, tri[:, 0]]
    ang = np.unwrap(np.arctan2(d[..., 1], d[..., 0]), axis=0)  # (S, M): each plate's heading
    rel = ang - ang[:1]
    order = np.argsort(geo.arm_joint, kind="stable")
    joint_sorted = geo.arm_joint[order]
    # partner: the next arm of the same joint, cyclically
    first = np.r_[True, joint_sorted[1:] != joint_sorted[:-1]]
    group_start = np.maximum.accumulate(np.where(first, np.arange(len(order)), 0))
    last = np.r_[joint_sorted[1:] != joint_sorted[:-1], True]
    partner_sorted = np.where(last, group_start, np.arange(len(order)) + 1)
    partner = np.empty_like(order)
    partner[order] = order[partner_sorted]
    turn = np.abs(rel[:, geo.arm_plate] - rel[:, geo.arm_plate[partner]]).max(0)
    free = geo.arm_length + geo.arm_length[partner]
    strain = geo.settings.hinge_width * turn / (2.0 * free)
    return turn, strain
