"""STL (and 3MF) export of printed triangle-hinge networks: one watertight body in millimetres.

The network's rigid triangles become plates and its shared vertices hinges
(:mod:`fabkit.fab.hinges`), with the settings of the template's ``[fabrication.print]`` table and
the ``print`` overrides (:mod:`fabkit.fab.printing`). Files (``NAME`` is the design's name):

* ``NAME.stl`` — binary STL of the whole part as designed (centred on its bounding box),
  millimetres, outward normals: the file the as-built check reads;
* ``NAME.3mf`` — the bed-ready layout as a 3MF package (unit millimetre), unless ``threemf =
  false``: the part turned and placed to fit the chosen printer's bed
  (:mod:`fabkit.fab.printers`, default the 200 x 200 mm bed PrusaSlicer assumes); a chain too
  long for any orientation is split between modules into pieces arranged on as few beds as
  needed (``NAME_bed1.3mf``, ``NAME_bed2.3mf`` ... when more than one); a piece that fits no
  orientation is refused with the bed size it needs;
* ``NAME_print.png`` — a top view of plates and hinges, unless ``preview = false``.

Pure: returns bytes, never opens a file. The report gives the analytic volume the STL is checked
against, the narrowest features, the largest hinge rotation along the design's motion and the
bending strain it puts in the hinges.
"""

from __future__ import annotations

import io
import re
import zipfile

import numpy as np

from ..errors import FabkitError, FabricationError
from . import ExportResult
from ..numerics import MM_SLACK

__all__ = ["FORMAT", "applies", "export_design", "binary_stl", "threemf_package",
           "stored_mesh_is_closed"]

FORMAT = "stl"

_STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])


def applies(design) -> bool:
    """True for planar designs with a ``[fabrication.print]`` table or made of rigid triangles."""
    net = design.network
    if net.dim != 2:
        return False
    if isinstance(design.fabrication, dict) and "print" in design.fabrication:
        return True
    from ..fab.hinges import rigid_triangles

    try:
        rigid_triangles(net)
    except FabkitError:
        return False
    return True


def binary_stl(vertices, faces, header: str = "fabkit printed network, units mm") -> bytes:
    """Binary STL bytes of a triangle mesh.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        Millimetres.
    faces : array_like of int, shape (F, 3)
        Counter-clockwise seen from outside.
    header : str
        ASCII text for the 80-byte header (must not start with "solid").

    Returns
    -------
    bytes
        84 + 50 F bytes.

    Examples
    --------
    >>> data = binary_stl([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> len(data)
    134
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    rec = np.zeros(len(f), dtype=_STL_RECORD)
    rec["normal"] = n
    rec["vertices"] = tri
    head = header.encode("ascii")[:80].ljust(80, b" ")
    return head + np.uint32(len(f)).tobytes() + rec.tobytes()


def threemf_package(vertices, faces, name: str = "network", transform=None, *,
                    objects=None) -> bytes:
    """A minimal 3MF package (unit millimetre), byte-for-byte reproducible.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
    faces : array_like of int, shape (F, 3)
    name : str
    transform : array_like, shape (3, 4), optional
        Placement of the object on the build plate (``x' = R x + t``, mm).
    objects : list of (vertices, faces, name, transform), optional
        Several objects (pieces) instead of the one above; ``vertices`` and ``faces`` are then
        ignored.

    Returns
    -------
    bytes
        A ZIP archive with ``[Content_Types].xml``, ``_rels/.rels`` and ``3D/3dmodel.model``.
    """
    from xml.sax.saxutils import quoteattr

    if objects is None:
        objects = [(vertices, faces, name, transform)]
    resources, items = [], []
    for oid, (vv, ff, nm, tr) in enumerate(objects, start=1):
        v = np.asarray(vv, dtype=np.float32)
        f = np.asarray(ff, dtype=np.int64)
        vtxt = "".join(f'<vertex x="{a!r}" y="{b!r}" z="{c!r}"/>'
                       for a, b, c in v.astype(float).tolist())
        ftxt = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in f.tolist())
        resources.append(f'<object id="{oid}" type="model" name={quoteattr(nm)}>'
                         f'<mesh><vertices>{vtxt}</vertices><triangles>{ftxt}</triangles></mesh>'
                         '</object>')
        if tr is None:
            items.append(f'<item objectid="{oid}"/>')
        else:
            m = np.asarray(tr, dtype=np.float64)
            # 3MF matrices act on row vectors: m00 m01 m02 m10 m11 m12 m20 m21 m22 m30 m31 m32
            vals = list(m[:, :3].T.ravel()) + list(m[:, 3])
            items.append(f'<item objectid="{oid}" transform="'
                         + " ".join(f"{x:.9g}" for x in vals) + '"/>')
    model = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<model unit="millimeter" xml:lang="en-US" '
        'xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
        '<resources>' + "".join(resources) + '</resources><build>' + "".join(items)
        + '</build></model>')
    types = ('<?xml version="1.0" encoding="UTF-8"?>\n'
             '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
             '<Default Extension="rels" '
             'ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
             '<Default Extension="model" '
             'ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/></Types>')
    rels = ('<?xml version="1.0" encoding="UTF-8"?>\n'
            '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
            '<Relationship Target="/3D/3dmodel.model" Id="rel0" '
            'Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>'
            '</Relationships>')
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for arcname, text in (("[Content_Types].xml", types), ("_rels/.rels", rels),
                              ("3D/3dmodel.model", model)):
            info = zipfile.ZipInfo(arcname, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, text.encode("utf-8"))
    return buf.getvalue()


JOIN = ("each cut port's two hinge hubs are printed on both pieces: lay the later piece's hubs "
        "on the earlier piece's (the port named in the layout), push a 1.75 mm filament pin "
        "through each stacked pair or bond them with a drop of cyanoacrylate, and keep the "
        "plates of both pieces free to turn about the pin")


def _piece_mesh(net, nodes, s):
    """Plates and hinges of the sub-network on ``nodes`` (mm, its own print frame)."""
    from ..fab.hinges import print_geometry, print_solid, solid_mesh
    from ..network import Network

    keep = np.zeros(net.n_nodes, dtype=bool)
    keep[nodes] = True
    index = np.cumsum(keep) - 1
    e = net.edges[keep[net.edges].all(axis=1)]
    sub = Network(net.nodes[keep], index[e])
    verts, faces = solid_mesh(print_solid(print_geometry(sub, s)))
    if not stored_mesh_is_closed(verts, faces):
        raise FabricationError("a split piece's solid is not watertight in float32 coordinates; "
                               "change hinge_width or scale slightly")
    return verts, faces


def bed_files(design, s, verts, faces, name: str) -> tuple[dict, dict]:
    """The bed-ready 3MF file(s) and the layout report (see the module docstring).

    Returns
    -------
    files : dict of str to bytes
    report : dict
        ``printer``, ``fits_as_designed``, ``beds``, ``pieces`` (piece, bed, angle_deg,
        offset_mm, size_mm, nodes, joined_at), ``join`` (None when not split).

    Raises
    ------
    FabricationError
        A piece (or the whole part, if it is not a chain) fits the bed in no orientation.
    """
    from ..fab.printers import bed_layout, chain_pieces

    printer = s.printer_profile()
    xy = np.asarray(verts)[:, :2]
    w, h = np.ptp(xy, axis=0)
    margin = 5.0
    fits = bool(w <= printer.width - 2 * margin and h <= printer.depth - 2 * margin)
    pieces = [(np.arange(design.network.n_nodes), "")]
    meshes = [(verts, faces)]
    try:
        layout = bed_layout([xy], printer, margin=margin)
    except FabricationError as whole:
        chain = [p for p in design.network.ports if re.fullmatch(r"d\d+", p)]
        layout = None
        refusal = whole
        for n in range(2, len(chain)):
            try:
                pieces = chain_pieces(design.network, n)
            except FabricationError:
                break
            meshes = [_piece_mesh(design.network, nodes, s) for nodes, _ in pieces]
            try:
                layout = bed_layout([m[0][:, :2] for m in meshes], printer, margin=margin)
                break
            except FabricationError as exc:
                refusal = exc
        if layout is None:
            raise FabricationError(f"the print does not fit the {printer.name} bed "
                                   f"({printer.width:g} x {printer.depth:g} mm): {refusal}") \
                from None
    beds = 1 + max(p.bed for p in layout)
    files = {}
    if s.threemf:
        for b in range(beds):
            objs = [(meshes[p.piece][0], meshes[p.piece][1],
                     name if len(pieces) == 1 else f"{name}_piece{p.piece + 1}", p.matrix())
                    for p in layout if p.bed == b]
            fname = f"{name}.3mf" if beds == 1 else f"{name}_bed{b + 1}.3mf"
            files[fname] = threemf_package(None, None, objects=objs)
    report = {"printer": printer.as_dict(), "fits_as_designed": fits, "beds": beds,
              "pieces": [{"piece": p.piece + 1, "bed": p.bed + 1, "angle_deg": p.angle,
                          "offset_mm": list(p.offset), "size_mm": list(p.size),
                          "nodes": int(len(pieces[p.piece][0])),
                          "joined_at": pieces[p.piece][1] or None} for p in layout],
              "join": JOIN if len(pieces) > 1 else None, "files": sorted(files)}
    return files, report


def stored_mesh_is_closed(vertices, faces) -> bool:
    """True when the mesh is still closed and consistently wound after its vertices are rounded
    to float32 (as in an STL file) and merged by position (as readers do).

    Every directed edge must occur once and its reverse once; no triangle may collapse.
    """
    v = np.asarray(vertices, dtype=np.float32)
    _, inverse = np.unique(v, axis=0, return_inverse=True)
    f = inverse.reshape(-1)[np.asarray(faces, dtype=np.int64)]
    if np.any((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])):
        return False
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    n = int(f.max()) + 1
    key = directed[:, 0] * n + directed[:, 1]
    rev = directed[:, 1] * n + directed[:, 0]
    if np.unique(key).size != key.size:
        return False
    return bool(np.isin(rev, key).all())


def _preview_png(geo, title: str) -> bytes:
    from ..viz import _mpl, figure_png

    plt = _mpl()
    from matplotlib.collections import PolyCollection

    w, h, _ = geo.size
    width = min(12.0, max(6.0, 2.0 + w / 12.0))
    height = min(8.0, max(3.0, 1.0 + width * h / max(w, MM_SLACK)))
    fig, ax = plt.subplots(figsize=(width, height))
    ax.add_collection(PolyCollection(geo.plates, facecolor="0.75", edgecolor="0.25", lw=0.5))
    pieces = list(geo.arms) + list(geo.hubs)
    ax.add_collection(PolyCollection(pieces, facecolor="C1", edgecolor="none", alpha=0.9))
    ax.plot(*geo.positions[geo.joints].T, "k.", ms=2)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    s = geo.settings
    ax.set_title(f"{title}: {len(geo.plates)} plates, {len(geo.joints)} hinges ({s.hinge_style}, "
                 f"{s.material}), {w:.1f} x {h:.1f} x {s.plate_thickness:g} mm", fontsize=9)
    fig.tight_layout()
    png = figure_png(fig)
    plt.close(fig)
    return png


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.+-]", "_", name) or "network"


def _hinge_report(design, geo) -> dict:
    """Largest hinge rotation along the design's motion and the bending strain it means."""
    from ..fab.hinges import hinge_bending

    s = geo.settings
    if design.motion.to is None:
        return {"status": "no motion in the template"}
    try:
        traj = design.trace()
    except FabkitError as exc:
        return {"status": f"motion not traced: {exc}"}
    turn, strain = hinge_bending(geo, traj.positions)
    k = int(np.argmax(strain)) if strain.size else 0
    return {"status": str(traj.status),
            "max_rotation_deg": float(np.degrees(turn.max())) if turn.size else 0.0,
            "bending_strain": float(strain[k]) if strain.size else 0.0,
            "worst_joint": int(geo.arm_joint[k]) if strain.size else None,
            "strain_limit": s.strain_limit,
            "hinge_length_needed": float(strain[k] / s.strain_limit * 2.0 * geo.arm_length[k])
            if strain.size else 0.0}


def export_design(design, settings: dict | None = None) -> ExportResult:
    """Plates and hinges of a design as STL (+ 3MF, preview PNG).

    Parameters
    ----------
    design : fabkit.templates.Design
        A planar network of rigid triangles.
    settings : dict, optional
        Command-line overrides; ``settings["print"]`` holds print keys (``gap``, ``scale`` ...).

    Returns
    -------
    ExportResult

    Raises
    ------
    FabricationError
        Invalid print settings (a gap of 0 among them), a network that is not made of
        triangles, plates that would touch, hinges that do not fit; nothing is produced.
    """
    from ..fab.hinges import print_geometry, print_solid, solid_mesh
    from ..fab.printing import design_print_settings

    s = design_print_settings(design, settings)
    geo = print_geometry(design.network, s)
    body = print_solid(geo)
    verts, faces = solid_mesh(body)
    if not stored_mesh_is_closed(verts, faces):
        raise FabricationError(
            "the solid has features so close that they merge in the STL's float32 coordinates "
            "(the file would not be watertight); change hinge_width or scale slightly")
    name = _safe(design.name)
    files = {f"{name}.stl": binary_stl(verts, faces)}
    bed, layout = bed_files(design, s, verts, faces, name)
    files.update(bed)
    if s.preview:
        files[f"{name}_print.png"] = _preview_png(geo, design.name)
    hinges = _hinge_report(design, geo)
    warnings = []
    if hinges.get("bending_strain", 0.0) > s.strain_limit:
        warnings.append(
            f"hinges bend by up to {hinges['max_rotation_deg']:.0f} degrees: strain "
            f"{hinges['bending_strain']:.3f} exceeds {s.strain_limit:g} for {s.material}; use "
            f"hinge_length >= {hinges['hinge_length_needed']:.1f} mm, a narrower hinge or TPU")
    size = geo.size
    if not layout["fits_as_designed"]:
        how = (f"split into {len(layout['pieces'])} pieces (see printer.join)"
               if layout["join"] else "turned to fit")
        note = (f"the part is {size[0]:.0f} x {size[1]:.0f} mm: as designed it does not fit the "
                f"{layout['printer']['name']} bed")
        if layout["files"]:
            layout["note"] = f"{note}; {', '.join(layout['files'])} holds it {how}"
        else:  # nothing bed-ready is written: the maker must do it
            warnings.append(f"{note}; it must be {how}: set threemf = true for a bed-ready file")
    report = {
        "settings": s.as_dict(),
        "plates": len(geo.plates),
        "hinges": int(len(geo.joints)),
        "size_mm": list(size),
        "volume_mm3": geo.volume,
        "plate_volume_mm3": geo.plate_volume,
        "hinge_volume_mm3": geo.hinge_volume,
        "mesh": {"vertices": int(len(verts)), "triangles": int(len(faces)),
                 "genus": int(body.genus()), "volume_mm3": float(body.volume())},
        "min_feature_mm": geo.min_feature,
        "hinge_motion": hinges,
        "printer": layout,
        "warnings": warnings,
        "files": sorted(files),
    }
    return ExportResult(files=files, report=report)
