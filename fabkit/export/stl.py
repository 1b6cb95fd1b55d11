"""STL (and 3MF) export of printed triangle-hinge networks: one watertight body in millimetres.

The network's rigid triangles become plates and its shared vertices hinges
(:mod:`fabkit.fab.hinges`), with the settings of the template's ``[fabrication.print]`` table and
the ``print`` overrides (:mod:`fabkit.fab.printing`). Files (``NAME`` is the design's name):

* ``NAME.stl`` — binary STL, millimetres, outward normals;
* ``NAME.3mf`` — the same mesh as a 3MF package (unit millimetre), unless ``threemf = false``;
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

__all__ = ["FORMAT", "applies", "export_design", "binary_stl", "threemf_package",
           "settings_for", "stored_mesh_is_closed"]

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


def settings_for(design, settings: dict | None = None):
    """The design's :class:`~fabkit.fab.printing.PrintSettings` with ``settings["print"]``
    overrides (a template's table, then the command line)."""
    from ..fab.printing import print_settings

    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    table = fab.get("print", {})
    if not isinstance(table, dict):
        raise FabricationError("fabrication.print: must be a table")
    over = (settings or {}).get("print", {})
    if not isinstance(over, dict):
        raise FabricationError("print: overrides must be given as print.KEY=VALUE")
    return print_settings(table, over)


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


def threemf_package(vertices, faces, name: str = "network") -> bytes:
    """A minimal 3MF package (one mesh object, unit millimetre), byte-for-byte reproducible.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
    faces : array_like of int, shape (F, 3)
    name : str

    Returns
    -------
    bytes
        A ZIP archive with ``[Content_Types].xml``, ``_rels/.rels`` and ``3D/3dmodel.model``.
    """
    from xml.sax.saxutils import quoteattr

    v = np.asarray(vertices, dtype=np.float32)
    f = np.asarray(faces, dtype=np.int64)
    vtxt = "".join(f'<vertex x="{a!r}" y="{b!r}" z="{c!r}"/>'
                   for a, b, c in v.astype(float).tolist())
    ftxt = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in f.tolist())
    model = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<model unit="millimeter" xml:lang="en-US" '
        'xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
        '<resources><object id="1" type="model" name=' + quoteattr(name) + '>'
        f'<mesh><vertices>{vtxt}</vertices><triangles>{ftxt}</triangles></mesh>'
        '</object></resources><build><item objectid="1"/></build></model>')
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
    height = min(8.0, max(3.0, 1.0 + width * h / max(w, 1e-9)))
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

    s = settings_for(design, settings)
    geo = print_geometry(design.network, s)
    body = print_solid(geo)
    verts, faces = solid_mesh(body)
    if not stored_mesh_is_closed(verts, faces):
        raise FabricationError(
            "the solid has features so close that they merge in the STL's float32 coordinates "
            "(the file would not be watertight); change hinge_width or scale slightly")
    name = _safe(design.name)
    files = {f"{name}.stl": binary_stl(verts, faces)}
    if s.threemf:
        files[f"{name}.3mf"] = threemf_package(verts, faces, name)
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
    if max(size[:2]) > 250.0 or min(size[:2]) > 210.0:
        warnings.append(f"the print is {size[0]:.0f} x {size[1]:.0f} mm: larger than a "
                        "250 x 210 mm bed; lower scale")
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
        "warnings": warnings,
        "files": sorted(files),
    }
    return ExportResult(files=files, report=report)
