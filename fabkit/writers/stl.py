"""STL (and 3MF) export of printed networks, in millimetres, laid out on the printer's bed.

Two kinds of print (``linkage`` in ``[fabrication.print]``, :mod:`fabkit.settings.printing`):

* ``"hinges"`` (the default for a network made of rigid triangles): plates and hinges as one
  watertight body (:mod:`fabkit.fab.hinges`), described below;
* ``"pins"`` (the default for every other planar network): bars stacked in layers on printed
  pins, one body per bar, printed in place (:mod:`fabkit.writers.pinned`).

Files of a hinge print (``NAME`` is the design's name; ``_bed<k>`` when it needs more than one
bed):

* ``NAME.stl`` — binary STL of the bed as it prints, centred on the bed's centre (an STL carries
  no placement): the part turned and placed to fit the chosen printer's bed (:mod:`fabkit.fab.printers`, default the 200 x 200 mm bed PrusaSlicer
  assumes), outward normals; a chain too long for any orientation is split between modules into
  pieces arranged on as few beds as needed; a piece that fits no orientation is refused with
  the bed size it needs;
* ``NAME.3mf`` — the same bed as a 3MF package (each piece an object placed by its build item),
  with the print settings the design needs (:mod:`fabkit.fab.slicer`), unless ``threemf =
  false``;
* ``NAME_print.png`` — a top view of plates and hinges, unless ``preview = false``;
* ``print_bom.json``, ``print_bom.md`` — the print's bill of materials
  (:mod:`fabkit.writers.print_bom`): beds, files and parts per bed, filament.

Pure: returns bytes, never opens a file. The report gives the analytic volume the STL is checked
against, the narrowest features, the largest hinge rotation along the design's motion and the
bending strain it puts in the hinges, where each piece went on the bed, and what the 3MF tells
the slicer.
"""

from __future__ import annotations

import re

import numpy as np

from ..errors import FabricationError
from ..fab.printers import split_to_fit
from ..model.network import Network
from ..numerics import MM_SLACK
from ..plots.viz import figure_kit, figure_png
from . import ExportResult
from .pinned import bed_file_names
from .print_bom import print_bom_document, print_bom_files
from .stl_file import binary_stl, stl_origin, stored_mesh_is_closed
from .threemf import threemf_package

__all__ = ["FORMAT", "PROCESS", "applies", "write", "export_design", "binary_stl", "threemf_package",
           "preview_figure", "stored_mesh_is_closed", "hinge_layout", "piece_network",
           "stl_origin", "mesh_volume"]

FORMAT = "stl"

#: The process whose plan (:func:`fabkit.fab.print_plan.print_plan`) this format is written from.
PROCESS = "print"
#: The sections of ``--set`` this format reads (any other has no effect on it).
READS = ("print",)


def applies(design) -> bool:
    """True for planar designs: a network of rigid triangles prints as one hinged solid, any
    other planar network as a print-in-place linkage of bars on pins."""
    return design.network.dim == 2


JOIN = ("each cut port's two hinge hubs are printed on both pieces: lay the later piece's hubs "
        "on the earlier piece's (the port named in the layout), push a 1.75 mm filament pin "
        "through each stacked pair or bond them with a drop of cyanoacrylate, and keep the "
        "plates of both pieces free to turn about the pin")


def piece_network(net, nodes):
    """The sub-network on ``nodes`` (renumbered in their order) that a split piece prints."""
    keep = np.zeros(net.n_nodes, dtype=bool)
    keep[nodes] = True
    index = np.cumsum(keep) - 1
    e = net.edges[keep[net.edges].all(axis=1)]
    return Network(net.nodes[keep], index[e])


def _outline(geo) -> np.ndarray:
    """Every corner of a hinge print's plates, arms and hubs: the hull of the solid's top view."""
    return np.concatenate([np.concatenate(geo.plates), geo.arms.reshape(-1, 2),
                           geo.hubs.reshape(-1, 2)])


def hinge_layout(design, s, geo=None, *, margin: float):
    """Where a hinge print goes on the bed: its pieces, their geometries and placements.

    The whole network when it fits the bed in some orientation, else a chain cut into the
    fewest runs of modules that fit (:func:`fabkit.fab.printers.split_to_fit`). Pure: the
    as-built check calls it to put what it reads back into the design's frame.

    Parameters
    ----------
    design : Design
    s : PrintSettings
    geo : PrintGeometry, optional
        The whole network's geometry, when already built.
    margin : float
        How far (mm) the parts stand from the bed's edges (the plan's ``parts_margin``).

    Returns
    -------
    pieces : list of (nodes, cut)
    geos : list of PrintGeometry
        Each piece's geometry in its own frame (:func:`fabkit.fab.hinges.print_geometry` of
        :func:`piece_network`).
    layout : list of Placement

    Raises
    ------
    FabricationError
        A piece (or the whole part, if it is not a chain) fits the bed in no orientation.
    """
    from ..fab.hinges import print_geometry

    net = design.network
    whole = geo if geo is not None else print_geometry(net, s)
    geos = {}

    def outline(nodes):
        key = tuple(np.asarray(nodes).tolist())
        if len(nodes) == net.n_nodes:
            geos[key] = whole
        elif key not in geos:
            geos[key] = print_geometry(piece_network(net, nodes), s)
        return _outline(geos[key])

    pieces, layout = split_to_fit(net, outline, s.printer_profile(), margin=margin)
    return pieces, [geos[tuple(np.asarray(n).tolist())] for n, _ in pieces], layout


def _piece_solid(geo):
    from ..fab.hinges import print_solid, solid_mesh

    body = print_solid(geo)
    verts, faces = solid_mesh(body)
    if not stored_mesh_is_closed(verts, faces):
        raise FabricationError("a split piece's solid is not watertight in float32 coordinates; "
                               "change hinge_width or scale slightly")
    return verts, faces


def bed_files(design, s, verts, faces, name: str, geo=None, *, slicer, margin: float
              ) -> tuple[dict, dict]:
    """The bed-ready STL and 3MF file(s) and the layout report (see the module docstring);
    ``slicer`` is what the 3MF files tell the slicer and ``margin`` how far the parts stand
    from the bed's edges (the plan's, :class:`~fabkit.fab.print_plan.PrintPlan`).

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
    printer = s.printer_profile()
    xy = np.asarray(verts)[:, :2]
    w, h = np.ptp(xy, axis=0)
    fits = bool(w <= printer.width - 2 * margin and h <= printer.depth - 2 * margin)
    pieces, geos, layout = hinge_layout(design, s, geo, margin=margin)
    meshes = [(verts, faces)] if len(pieces) == 1 else [_piece_solid(g) for g in geos]
    beds = 1 + max(p.bed for p in layout)
    files = {}
    stls, mfs = bed_file_names(name, beds, ".stl"), bed_file_names(name, beds, ".3mf")
    for b in range(beds):
        on_bed = [p for p in layout if p.bed == b]
        placed = []
        for p in on_bed:
            v, f = meshes[p.piece]
            m = p.matrix()
            vb = v @ m[:, :3].T + m[:, 3]
            if not (stored_mesh_is_closed(vb, f)
                    and stored_mesh_is_closed(vb - stl_origin(printer), f)):
                raise FabricationError("the solid is not watertight once turned onto the bed "
                                       "and rounded to float32; change hinge_width or scale "
                                       "slightly")
            placed.append((vb, f))
        offsets = np.cumsum([0] + [len(v) for v, _ in placed[:-1]])
        files[stls[b]] = binary_stl(np.concatenate([v for v, _ in placed]) - stl_origin(printer),
                                    np.concatenate([f + o for (_, f), o in zip(placed, offsets)]),
                                    header=f"fabkit printed network, units mm, bed {b + 1} of "
                                           f"{beds}")
        if s.threemf:
            objs = [(meshes[p.piece][0], meshes[p.piece][1],
                     name if len(pieces) == 1 else f"{name}_piece{p.piece + 1}", p.matrix())
                    for p in on_bed]
            files[mfs[b]] = threemf_package(None, None, objects=objs, project=slicer.project,
                                            per_object=slicer.per_object,
                                            title=f"fabkit print settings for {design.name}")
    report = {"printer": printer.as_dict(), "fits_as_designed": fits, "beds": beds,
              "parts_margin_mm": margin,
              "pieces": [{"piece": p.piece + 1, "bed": p.bed + 1, "angle_deg": p.angle,
                          "offset_mm": list(p.offset), "size_mm": list(p.size),
                          "nodes": int(len(pieces[p.piece][0])),
                          "plates": len(geos[p.piece].plates),
                          "hinges": int(len(geos[p.piece].joints)),
                          "volume_mm3": mesh_volume(*meshes[p.piece]),
                          "joined_at": pieces[p.piece][1] or None} for p in layout],
              "join": JOIN if len(pieces) > 1 else None, "files": sorted(files)}
    return files, report


def mesh_volume(vertices, faces) -> float:
    """Volume (mm^3) of a closed, outward-wound triangle mesh (divergence theorem)."""
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


def _bom(design, s, layout: dict) -> dict:
    """The hinge print's bill of materials (:mod:`fabkit.writers.print_bom`)."""
    beds = []
    for b in range(layout["beds"]):
        on_bed = [p for p in layout["pieces"] if p["bed"] == b + 1]
        names = [n for n in layout["files"] if n.endswith(".stl") or n.endswith(".3mf")]
        mine = [n for n in names if layout["beds"] == 1 or f"_bed{b + 1}." in n]
        parts = [{"piece": p["piece"], "text": f"piece {p['piece']}: {p['plates']} plates "
                                               f"joined by {p['hinges']} printed hinges, one "
                                               "body, nothing to assemble"
                                               + (f" (joined to the next piece at "
                                                  f"{p['joined_at']})" if p["joined_at"] else "")}
                 for p in on_bed]
        beds.append({"bed": b + 1, "files": mine, "parts": parts,
                     "volume_mm3": sum(p["volume_mm3"] for p in on_bed)})
    printer = s.printer_profile()
    return print_bom_document(
        design.name, "triangle-hinge solid", s,
        {"name": printer.name, "bed_mm": [printer.width, printer.depth],
         "margin_mm": printer.margin, "parts_margin_mm": layout["parts_margin_mm"]},
        beds, [], [], [layout["join"] or "one piece per bed: nothing to join"])


def preview_figure(geo, title: str):
    """A hinged solid seen from above: plates grey, hinges orange, joints as dots.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.collections import PolyCollection

    w, h, _ = geo.size
    width = min(12.0, max(6.0, 2.0 + w / 12.0))
    height = min(8.0, max(3.0, 1.0 + width * h / max(w, MM_SLACK)))
    fig, ax = figure_kit.subplots(figsize=(width, height))
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
    return fig


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.+-]", "_", name) or "network"


def export_design(design, settings=None, *, motion=None) -> ExportResult:
    """A printed network as STL (+ 3MF, preview PNG): its print plan, written (:func:`write`).

    Parameters
    ----------
    design : fabkit.templates.Design
        A planar network: of rigid triangles (a hinged solid) or of bars (a print-in-place
        linkage), as ``linkage`` says.
    settings : DesignSettings or dict, optional
        The design's resolved settings, or overrides nested by section (``{"print": {"gap":
        0.3}}``, resolved once, here).
    motion : TracedMotion, optional
        The design's motion, traced once by the pipeline (:func:`fabkit.motion.trace_motion`):
        the hinges' bending and a linkage's stacking are measured along it. Traced here, once,
        when not given.

    Returns
    -------
    ExportResult

    Raises
    ------
    FabricationError
        Invalid print settings (a gap of 0 among them), a network that is not made of
        triangles, plates that would touch, hinges that do not fit; bars that cannot be stacked
        or pinned (:func:`fabkit.fab.pinned.pinned_print`); nothing is produced.
    """
    from ..fab.plans import make_plan

    return write(make_plan(PROCESS, design, settings, motion))


def write(plan) -> ExportResult:
    """A print plan (:class:`fabkit.fab.print_plan.PrintPlan`) as STL (+ 3MF, preview PNG), laid
    out on the printer's bed.

    Raises
    ------
    FabricationError
        Features so close that they merge in the STL's float32 coordinates (the file would
        not be watertight); nothing is produced.
    """
    design, s = plan.design, plan.settings
    name = _safe(design.name)
    if plan.pinned is not None:
        from .pinned import write_pinned

        return write_pinned(plan.pinned, s, name, design, plan.slicer)
    geo, body, verts, faces = plan.geo, plan.body, plan.verts, plan.faces
    if not stored_mesh_is_closed(verts, faces):
        raise FabricationError(
            "the solid has features so close that they merge in the STL's float32 coordinates "
            "(the file would not be watertight); change hinge_width or scale slightly")
    files, layout = bed_files(design, s, verts, faces, name, geo, slicer=plan.slicer,
                              margin=plan.parts_margin)
    if not s.threemf:
        layout["files"] = sorted(n for n in files if n.endswith(".stl"))
    if s.preview:
        files[f"{name}_print.png"] = figure_png(preview_figure(geo, design.name))
    files.update(print_bom_files(_bom(design, s, layout)))

    hinges = plan.hinges
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
        layout["note"] = (f"the part is {size[0]:.0f} x {size[1]:.0f} mm: as designed it does "
                          f"not fit the {layout['printer']['name']} bed; "
                          f"{', '.join(layout['files'])} holds it {how}")

    report = {
        "linkage": "hinges",
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
        "slicer": plan.slicer.as_dict() if s.threemf else None,
        "warnings": warnings,
        "files": sorted(files),
    }
    return ExportResult(files=files, report=report)
