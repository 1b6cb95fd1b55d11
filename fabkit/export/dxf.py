"""Laser-cut acrylic: DXF sheets, SVG previews, bill of materials and assembly pictures.

The pipeline (all pure, nothing is written here):

1. settings: the template's ``[fabrication.laser]`` table merged with the caller's overrides
   (:func:`fabkit.fab.laser.laser_settings`);
2. bars: design units to mm, outlines and holes, refusal of bars that cannot be cut
   (:mod:`fabkit.fab.bars`);
3. stacking layers over the sampled motion (:mod:`fabkit.fab.layers`);
4. parts nested on sheets (:mod:`fabkit.fab.nest`);
5. one DXF per sheet (R2010, ``$INSUNITS = 4`` mm, ``$EXTMIN``/``$EXTMAX`` set; layers CUT,
   CUT_INNER, ENGRAVE and REFERENCE; closed LWPOLYLINE with bulges or LINE + ARC; CIRCLE
   holes; labels as glyph outlines by default), identical bytes for identical input, and a
   laser-ready SVG of the same sheet (:mod:`fabkit.export.laser_svg`);
6. the as-built check is not run here (an exporter never imports the checks): the batch engine
   behind ``fabkit export`` reads the written sheets back with :mod:`fabkit.check.dxf` and marks
   the design failed when they do not rebuild the designed network.

Files: ``laser_sheet<k>.dxf``, ``laser_sheet<k>.svg``, ``laser_bom.json``, ``laser_bom.md``,
``laser_assembly.png``, ``laser_layers_motion.png``, ``laser_guide.pdf`` (A4 assembly pages,
:mod:`fabkit.fab.guide`) and ``laser_guide_page1.png``.
"""

from __future__ import annotations

import contextlib
import io
import json
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from ..errors import FabricationError
from . import ExportResult

__all__ = ["FORMAT", "applies", "export_design", "LaserPlan", "laser_plan", "sheet_dxf",
           "bill_of_materials", "bom_markdown", "LAYERS", "APPID"]

FORMAT = "dxf"

#: DXF layers and their ACI colours (red outer cut, blue inner cut, black/white engrave, and
#: the 100 mm reference square on a layer of its own, green, to cut, engrave or leave off).
LAYERS = {"CUT": 1, "CUT_INNER": 5, "ENGRAVE": 7, "REFERENCE": 3}
#: Application id of the extended data that names each part (ignored by cutting programs).
APPID = "FABKIT"


#: Why the format does not apply, when :func:`applies` says so (reported by ``--to dxf``).
NOT_APPLICABLE = ("laser-cut bars need a planar (2D) network; this design is 3D: fold it (svg, "
                  "fold) or print it")

def applies(design) -> bool:
    """Laser-cut bars need a planar network."""
    return design.network.dim == 2


@dataclass(eq=False)
class LaserPlan:
    """Everything decided before files are written."""

    design: object
    settings: object
    bars: object
    sweep: object
    stacking: object
    parts: list
    sheets: list


def laser_plan(design, settings: dict | None = None) -> LaserPlan:
    """Decide bars, layers, parts and sheets for a design (no files).

    Parameters
    ----------
    design : Design
        A loaded template with a 2D network and a motion target.
    settings : dict, optional
        Overrides of ``[fabrication.laser]`` (``{"laser": {"kerf": 0.2}}`` or ``{"kerf": 0.2}``).

    Returns
    -------
    LaserPlan

    Raises
    ------
    FabricationError
        Bad settings, bars that cannot be cut, no collision-free stacking, parts larger than
        a sheet; one line each with a suggested fix.
    """
    from ..fab.bars import bar_set
    from ..fab.laser import laser_overrides, laser_settings
    from ..fab.layers import plan_layers, sample_chain, sample_motion
    from ..fab.nest import make_parts, nest_parts

    net = design.network
    if net.dim != 2:
        raise FabricationError(f"laser-cut bars need a 2D network; {design.name} is {net.dim}D")
    table = design.fabrication.get("laser", {}) if isinstance(design.fabrication, dict) else {}
    if not isinstance(table, dict):
        raise FabricationError("[fabrication.laser] must be a table")
    s = laser_settings(table, laser_overrides(settings), network_size=net.size)
    bars = bar_set(net.edge_lengths * s.scale, net.edges, s, scale=s.scale)
    sweep = sample_chain(net, design.motion, s.scale, s.sample_step, width=s.bar_width,
                         clearance=s.clearance,
                         column_radius=0.5 * s.screw.head_diameter,
                         spacer_radius=0.5 * s.spacer_diameter, floor_limit=s.clearance)
    if sweep is None:  # not a chain of modules: sample the whole motion
        sweep = sample_motion(net, design.motion, s.scale, s.sample_step,
                              floor_limit=s.clearance)
    stacking = plan_layers(net.edges, sweep, s)
    parts = make_parts(bars, stacking, s)
    sheets = nest_parts(parts, s)
    return LaserPlan(design, s, bars, sweep, stacking, parts, sheets)


# -- DXF ------------------------------------------------------------------------------------

@contextlib.contextmanager
def _fixed_metadata():
    """ezdxf stamps dates, GUIDs and its version time into every file; fix them so identical
    input gives identical bytes."""
    import ezdxf

    old = ezdxf.options.write_fixed_meta_data_for_testing
    ezdxf.options.write_fixed_meta_data_for_testing = True
    try:
        yield
    finally:
        ezdxf.options.write_fixed_meta_data_for_testing = old


def _fmt(v: float) -> str:
    return repr(float(v))


def sheet_dxf(sheet, plan: LaserPlan, n_sheets: int) -> bytes:
    """One sheet as DXF bytes (R2010, mm).

    Parameters
    ----------
    sheet : Sheet
    plan : LaserPlan
    n_sheets : int

    Returns
    -------
    bytes
        ASCII DXF; entities in cutting order: engraving, inner contours (holes), outer contours.
    """
    import ezdxf
    from ezdxf.enums import TextEntityAlignment

    from ..fab.bars import bulge_primitives
    from ..fab.nest import label_outlines

    s = plan.settings
    with _fixed_metadata():
        doc = ezdxf.new("R2010", units=4, setup=False)
        doc.header["$MEASUREMENT"] = 1
        doc.header["$LUNITS"] = 2
        for name, colour in LAYERS.items():
            doc.layers.add(name, color=colour)
        doc.appids.add(APPID)
        custom = doc.header.custom_vars
        meta = {
            "FABKIT_DESIGN": plan.design.name,
            "FABKIT_SHEET": f"{sheet.index}/{n_sheets}",
            "FABKIT_SCALE": _fmt(s.scale),
            "FABKIT_KERF": _fmt(s.kerf),
            "FABKIT_BAR_WIDTH": _fmt(s.bar_width),
            "FABKIT_HOLE": _fmt(s.screw.hole_diameter),
            "FABKIT_THICKNESS": _fmt(s.thickness),
            "FABKIT_LAYERS": str(plan.stacking.n_layers),
            "FABKIT_BARS": str(plan.bars.n_bars),
            "FABKIT_TEMPLATE": plan.design.path.name if plan.design.path else "",
        }
        for key, value in meta.items():
            custom.append(key, value)
        msp = doc.modelspace()

        def tag(entity, part):
            data = [(1000, part.id), (1000, part.kind)]
            if part.kind == "bar":
                data += [(1071, part.meta["bar"]), (1071, part.meta["joints"][0]),
                         (1071, part.meta["joints"][1]), (1071, part.meta["layer"])]
            elif part.kind == "spacer":
                data += [(1071, part.meta["joint"]), (1071, part.meta["layer"])]
            entity.set_xdata(APPID, data)

        def closed_outline(vertices, layer, part):
            if s.flavour == "lwpolyline":
                e = msp.add_lwpolyline([tuple(map(float, v)) for v in vertices], format="xyb",
                                       close=True, dxfattribs={"layer": layer})
                tag(e, part)
                return
            for prim in bulge_primitives(vertices):
                if prim[0] == "line":
                    e = msp.add_line(prim[1], prim[2], dxfattribs={"layer": layer})
                else:
                    e = msp.add_arc(prim[1], prim[2], prim[3], prim[4], dxfattribs={"layer": layer})
                tag(e, part)

        for part in sheet.parts:  # engraving first: the parts are still held by the sheet
            if part.kind == "reference":
                closed_outline(part.outline, "REFERENCE", part)
            for label in part.labels:
                if s.labels == "outlines":
                    for poly in label_outlines(label):
                        msp.add_lwpolyline([tuple(map(float, p)) for p in poly], format="xy",
                                           close=True, dxfattribs={"layer": "ENGRAVE"})
                else:
                    t = msp.add_text(label.text, height=label.height, rotation=label.angle,
                                     dxfattribs={"layer": "ENGRAVE"})
                    t.set_placement(label.insert, align=TextEntityAlignment.MIDDLE_CENTER)
        for part in sheet.parts:  # inner contours before outer ones
            for c in part.holes:
                e = msp.add_circle(tuple(map(float, c)), part.hole_radius,
                                   dxfattribs={"layer": "CUT_INNER"})
                tag(e, part)
        for part in sheet.parts:
            if part.ring is not None:
                e = msp.add_circle(tuple(map(float, part.holes[0])), part.ring,
                                   dxfattribs={"layer": "CUT"})
                tag(e, part)
            elif part.kind != "reference":
                closed_outline(part.outline, "CUT", part)
        boxes = np.array([p.bbox for p in sheet.parts]) if sheet.parts else np.zeros((1, 4))
        # ezdxf writes $EXTMIN/$EXTMAX from the model space layout's extents
        msp.dxf.extmin = (float(boxes[:, 0].min()), float(boxes[:, 1].min()), 0.0)
        msp.dxf.extmax = (float(boxes[:, 2].max()), float(boxes[:, 3].max()), 0.0)
        auditor = doc.audit()
        if auditor.has_errors:  # pragma: no cover - would be a fabkit bug
            raise FabricationError(f"ezdxf audit found {len(auditor.errors)} errors in sheet "
                                   f"{sheet.index}: {auditor.errors[0]}")
        # ezdxf adds the CLASS entries of the entity types in use while writing, iterating a
        # set (order depends on the string hash seed): write once, sort them, write again.
        doc.write(io.StringIO())
        doc.classes.classes = OrderedDict(sorted(doc.classes.classes.items()))
        stream = io.StringIO()
        doc.write(stream)
    return stream.getvalue().encode("ascii")


# -- bill of materials ----------------------------------------------------------------------

def bill_of_materials(plan: LaserPlan, files: dict) -> dict:
    """Parts, sheets, screws by length, spacer rings and the stack at every joint (JSON-able)."""
    from ..fab.hardware import WASHER_THICKNESS
    from ..fab.nest import utilisation

    s, st, bars = plan.settings, plan.stacking, plan.bars
    sheet_of = {p.id: sh.index for sh in plan.sheets for p in sh.parts}
    screws: dict[float, int] = {}
    for js in st.joints:
        screws[js.screw_length] = screws.get(js.screw_length, 0) + 1
    n_spacers = sum(len(js.spacers) for js in st.joints)
    return {
        "design": plan.design.name,
        "scale_mm_per_unit": s.scale,
        "settings": s.as_dict(),
        "sheets": [{"index": sh.index, "file": f"laser_sheet{sh.index}.dxf",
                    "size_mm": [sh.width, sh.height], "parts": [p.id for p in sh.parts],
                    "utilisation": round(utilisation(sh), 4)}
                   for sh in plan.sheets],
        "bars": [{"id": f"B{k}", "joints": [int(v) for v in bars.edges[k]],
                  "layer": int(st.layer[k]), "length_mm": round(float(bars.lengths[k]), 6),
                  "overall_length_mm": round(float(bars.lengths[k]) + s.bar_width, 6),
                  "sheet": sheet_of[f"B{k}"]} for k in range(bars.n_bars)],
        "layers": {"count": st.n_layers, "lower_bound": st.lower_bound,
                   "proven_minimal": st.proven_minimal, "proof": st.proof_text(),
                   "method": st.strategy, "head_slots": st.head_slots},
        "screws": [{"name": s.screw.name, "post_length_mm": length, "count": count}
                   for length, count in sorted(screws.items())],
        "washers": {"count": sum(js.washers for js in st.joints),
                    "thickness_mm": WASHER_THICKNESS, "inner_diameter_mm": s.screw.barrel_diameter,
                    "note": f"screws close on sheets up to {s.thickness + s.thickness_tolerance:g} "
                            "mm; measure the sheet and drop washers where the stack is thicker"},
        "spacer_rings": {"count": n_spacers, "outer_diameter_mm": s.spacer_diameter,
                         "hole_diameter_mm": s.screw.hole_diameter, "thickness_mm": s.thickness,
                         "note": "cut from the same sheet"},
        "joints": [{"joint": js.joint, "bottom_to_top": js.order(), "layers": list(js.layers),
                    "screw_length_mm": js.screw_length, "stack_mm": round(js.stack_height, 6),
                    "play_mm": round(js.play, 6), "spacers": len(js.spacers),
                    "washers": js.washers,
                    "play_with_washers_mm": [round(v, 6) for v in js.play_range]}
                   for js in st.joints],
        "motion": {"method": plan.sweep.method, "status": plan.sweep.status,
                   "samples": plan.sweep.stats.get("window_samples", plan.sweep.n_samples),
                   **({"windows": plan.sweep.stats} if plan.sweep.stats else {}),
                   "step_limit_mm": plan.sweep.step_limit,
                   "max_node_step_mm": round(plan.sweep.max_step, 6),
                   "guarantee": "no node moves more than step_limit_mm (= clearance / 2) between "
                                "samples; bars of one layer are >= clearance apart at every "
                                "sample and >= clearance / 2 between samples"},
        "files": sorted(files),
    }


def bom_markdown(bom: dict) -> str:
    """The bill of materials as Markdown for a person at the bench."""
    s = bom["settings"]
    lines = [f"# Laser-cut kit: {bom['design']}", "",
             f"Scale {bom['scale_mm_per_unit']:g} mm per design unit; {s['thickness']:g} mm "
             f"acrylic; bars {s['bar_width']:g} mm wide; kerf {s['kerf']:g} mm; "
             f"{bom['layers']['proof']}.", "",
             "## Sheets", "", "| sheet | file | parts | utilisation |", "|---|---|---|---|"]
    for sh in bom["sheets"]:
        lines.append(f"| {sh['index']} | {sh['file']} | {len(sh['parts'])} | "
                     f"{100 * sh['utilisation']:.1f} % |")
    lines += ["", "## Screws", "", "| screw | post length (mm) | count |", "|---|---|---|"]
    for sc in bom["screws"]:
        lines.append(f"| {sc['name']} | {sc['post_length_mm']:g} | {sc['count']} |")
    sp = bom["spacer_rings"]
    lines += ["", f"Spacer rings: {sp['count']} (outer {sp['outer_diameter_mm']:g} mm, hole "
              f"{sp['hole_diameter_mm']:g} mm, {sp['thickness_mm']:g} mm thick, {sp['note']}).",
              "", "## Bars", "", "| bar | joints | layer | hole spacing (mm) | sheet |",
              "|---|---|---|---|---|"]
    for b in bom["bars"]:
        lines.append(f"| {b['id']} | {b['joints'][0]}-{b['joints'][1]} | {b['layer']} | "
                     f"{b['length_mm']:.3f} | {b['sheet']} |")
    lines += ["", "## Stack at each joint (bottom to top)", "",
              "| joint | stack | screw (mm) | washers | play thick-thin sheets (mm) |",
              "|---|---|---|---|---|"]
    for j in bom["joints"]:
        p0, p1 = j["play_with_washers_mm"]
        lines.append(f"| {j['joint']} | {', '.join(j['bottom_to_top'])} | "
                     f"{j['screw_length_mm']:g} | {j['washers']} | {p0:.2f}-{p1:.2f} |")
    wa = bom["washers"]
    lines += ["", f"Washers: {wa['count']} x {wa['thickness_mm']:g} mm (M3); {wa['note']}."]
    lines += ["", "Motion: " + bom["motion"]["guarantee"] + ".", ""]
    return "\n".join(lines)


# -- pictures -------------------------------------------------------------------------------

def _draw_layers(ax, plan, x, *, joint_labels):
    from matplotlib.collections import PolyCollection

    from ..fab.bars import stadium_polygon
    from ..viz import _mpl

    plt = _mpl()
    cmap = plt.get_cmap("tab10")
    e = plan.bars.edges
    r = 0.5 * plan.settings.bar_width
    order = np.argsort(plan.stacking.layer, kind="stable")  # lower layers drawn first
    polys = [stadium_polygon(x[e[k, 0]], x[e[k, 1]], r) for k in order]
    colours = [cmap(int(plan.stacking.layer[k]) % 10) for k in order]
    ax.add_collection(PolyCollection(polys, facecolors=colours, edgecolors="k", linewidths=0.4,
                                     alpha=0.55))
    joints = [js.joint for js in plan.stacking.joints]
    ax.plot(x[joints, 0], x[joints, 1], "o", ms=3, color="k", zorder=50)
    if joint_labels:
        for js in plan.stacking.joints:
            ax.annotate(f"J{js.joint}\n{js.screw_length:g} mm", x[js.joint], fontsize=6,
                        zorder=51, ha="center", va="bottom", xytext=(0, 4),
                        textcoords="offset points")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("mm")


def assembly_png(plan: LaserPlan) -> bytes:
    """Bars in the reference configuration coloured by layer, joints labelled with screws."""
    from matplotlib.patches import Patch

    from ..viz import _mpl, figure_png

    plt = _mpl()
    fig, ax = plt.subplots(figsize=(8, 6))
    _draw_layers(ax, plan, plan.design.network.nodes * plan.settings.scale, joint_labels=True)
    cmap = plt.get_cmap("tab10")
    ax.legend(handles=[Patch(color=cmap(z % 10), alpha=0.55, label=f"layer {z}")
                       for z in range(plan.stacking.n_layers)], fontsize=7, loc="best")
    ax.set_title(f"{plan.design.name}: assembly ({plan.stacking.n_layers} layers, bottom = 0)")
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.08, top=0.93)
    return figure_png(fig, dpi=90)


def motion_png(plan: LaserPlan, frames: int = 4) -> bytes:
    """The motion with the layers: bars coloured by layer at a few configurations."""
    from ..viz import _mpl, figure_png

    plt = _mpl()
    x = plan.sweep.positions
    idx = np.unique(np.linspace(0, x.shape[0] - 1, frames).round().astype(int))
    fig, axes = plt.subplots(1, idx.size, figsize=(3.2 * idx.size, 3.4))
    for ax, i in zip(np.atleast_1d(axes), idx):
        _draw_layers(ax, plan, x[i], joint_labels=False)
        ax.set_title(f"drive {plan.sweep.drive[i]:.4g}", fontsize=8)
        ax.tick_params(labelsize=6)
    fig.suptitle(f"{plan.design.name}: motion with stacking layers "
                 f"({plan.sweep.n_samples} samples checked)", fontsize=9)
    fig.subplots_adjust(left=0.05, right=0.99, bottom=0.15, top=0.85, wspace=0.3)
    return figure_png(fig, dpi=90)


# -- entry ----------------------------------------------------------------------------------

def export_design(design, settings: dict | None = None) -> ExportResult:
    """Laser-cut files for a design (pure: returns bytes, writes nothing).

    Parameters
    ----------
    design : Design
    settings : dict, optional
        Overrides of ``[fabrication.laser]``, e.g. ``{"laser": {"kerf": 0.2, "scale": 60}}``.

    Returns
    -------
    ExportResult
        ``files``: ``laser_sheet<k>.dxf`` and ``.svg`` per sheet, ``laser_bom.json``,
        ``laser_bom.md``, ``laser_assembly.png``, ``laser_layers_motion.png``,
        ``laser_guide.pdf``, ``laser_guide_page1.png``. ``report``: the bill of materials.
        The as-built check reads the files back (:func:`fabkit.check.dxf.check_documents`,
        run on every export by the batch engine); an exporter never checks its own output.

    Raises
    ------
    FabricationError
        Bad settings or geometry (see :func:`laser_plan`).

    Examples
    --------
    >>> import fabkit
    >>> from fabkit.export.dxf import export_design
    >>> design = fabkit.load_template("templates/fourbar.toml")   # doctest: +SKIP
    >>> sorted(export_design(design).files)[:2]                   # doctest: +SKIP
    ['laser_assembly.png', 'laser_bom.json']
    """
    from .laser_svg import sheet_svg

    plan = laser_plan(design, settings)
    files: dict[str, bytes] = {}
    n = len(plan.sheets)
    for sheet in plan.sheets:
        files[f"laser_sheet{sheet.index}.dxf"] = sheet_dxf(sheet, plan, n)
        files[f"laser_sheet{sheet.index}.svg"] = sheet_svg(sheet, plan.settings)
    files["laser_assembly.png"] = assembly_png(plan)
    files["laser_layers_motion.png"] = motion_png(plan)
    from ..fab.guide import guide_pages

    guide, first_page, _ = guide_pages(plan)
    files["laser_guide.pdf"] = guide
    files["laser_guide_page1.png"] = first_page
    names = sorted([*files, "laser_bom.json", "laser_bom.md"])
    bom = bill_of_materials(plan, names)
    files["laser_bom.json"] = (json.dumps(bom, indent=2, sort_keys=True) + "\n").encode("utf-8")
    files["laser_bom.md"] = bom_markdown(bom).encode("utf-8")
    return ExportResult(files=files, report={"format": FORMAT, **bom})
