"""Laser-cut acrylic: DXF sheets, SVG previews, bill of materials and assembly pictures.

The pipeline (all pure, nothing is written here):

1. settings: the template's ``[fabrication.laser]`` table merged with the caller's overrides
   (:func:`fabkit.settings.laser.laser_settings`);
2. bars: design units to mm, outlines and holes, refusal of bars that cannot be cut
   (:mod:`fabkit.fab.bars`);
3. stacking layers over the sampled motion (:mod:`fabkit.fab.layers`);
4. parts nested on sheets (:mod:`fabkit.fab.nest`);
5. one DXF per sheet (R2010, ``$INSUNITS = 4`` mm, ``$EXTMIN``/``$EXTMAX`` set; layers CUT,
   CUT_INNER, ENGRAVE and REFERENCE; closed LWPOLYLINE with bulges or LINE + ARC; CIRCLE
   holes; labels as glyph outlines by default), identical bytes for identical input, and a
   laser-ready SVG of the same sheet (:mod:`fabkit.writers.laser_svg`);
6. the as-built check is not run here (an exporter never imports the checks): the batch engine
   behind ``fabkit export`` reads the written sheets back with :mod:`fabkit.check.dxf` and marks
   the design failed when they do not rebuild the designed network.

Files: ``laser_sheet<k>.dxf``, ``laser_sheet<k>.svg``, ``laser_bom.json``, ``laser_bom.md``,
``laser_assembly.png``, ``laser_layers_motion.png``, ``laser_guide.pdf`` (A4 assembly pages,
:mod:`fabkit.fab.guide`), ``laser_guide_page1.png``, the kerf and fit test coupon
``laser_coupon.dxf`` / ``.svg`` / ``.md`` (:mod:`fabkit.fab.coupon`) and, with
``uncompensated = true``, ``laser_sheet<k>_uncompensated.dxf`` / ``.svg`` drawn at true size.

The guide's first page and the head of the bill of materials carry the design's verdict. A
writer cannot know it (the checks come after the files are written): :func:`write` says "not
judged", and ``fabkit export``'s report stage, once it has judged the design, calls
:func:`with_verdict` to make those four files (:data:`VERDICT_FILES`) again from the same plan
and the verdict, and nothing else.
"""

from __future__ import annotations

import contextlib
import io
import json
from collections import OrderedDict

import numpy as np

from ..errors import FabricationError
from ..fab.bars import bulge_primitives
from ..fab.coupon import COUPON_NAME, coupon_sheet, COUPON_SPACING, coupon_text
from ..fab.guide import (assembly_picture, guide_pages, guide_plan, motion_picture, NOT_JUDGED,
                        verdict_rows)
from ..fab.hardware import part_family, part_lines, spares
from ..fab.laser import kerf_note
from ..fab.nest import label_outlines, utilisation
from ..fab.laser_plan import LaserPlan, uncompensated_plan
from ..settings.fasteners import MAX_AXIAL_PLAY
from . import ExportResult
from .laser_svg import sheet_svg

__all__ = ["FORMAT", "PROCESS", "applies", "write", "export_design", "sheet_dxf",
           "bill_of_materials", "bom_verdict", "bom_json", "verdict_files", "with_verdict", "VERDICT_FILES", "bom_markdown", "bom_blocks", "kerf_note", "LAYERS", "APPID",
           "SHEET_MATERIAL"]

FORMAT = "dxf"

#: The process whose plan (:func:`fabkit.fab.laser_plan.laser_plan`) this format is written from.
PROCESS = "laser"
#: The sections of ``--set`` this format reads (any other has no effect on it).
READS = ("laser",)

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


def coupon_files(plan: LaserPlan) -> dict:
    """The kerf and fit test coupon: ``laser_coupon.dxf`` and ``.svg`` (the kit's bar pair
    and spacer ring, drawn as on its sheets) and ``laser_coupon.md`` (what to check)."""
    s = plan.settings
    sheet = coupon_sheet(s)
    header = {"FABKIT_COUPON": COUPON_NAME, "FABKIT_DESIGN": plan.design.name,
              "FABKIT_KERF": _fmt(s.kerf), "FABKIT_KERF_NOTE": kerf_note(s),
              "FABKIT_BAR_WIDTH": _fmt(s.bar_width), "FABKIT_HOLE": _fmt(s.screw.hole_diameter),
              "FABKIT_SPACER": _fmt(s.spacer_diameter), "FABKIT_SPACING": _fmt(COUPON_SPACING),
              "FABKIT_THICKNESS": _fmt(s.thickness)}
    return {f"{COUPON_NAME}.dxf": sheet_dxf(sheet, plan, 1, header=header),
            f"{COUPON_NAME}.svg": sheet_svg(sheet, s),
            f"{COUPON_NAME}.md": coupon_text(s, plan.design.name).encode("utf-8")}


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


def _add_polyline(msp, points, layer: str):
    """A closed LWPOLYLINE of ``points`` (rows x, y or x, y, bulge) on ``layer``.

    Its vertex array is made by numpy at once: ezdxf's ``add_lwpolyline`` appends the
    vertices one at a time (an array concatenation each), the larger part of writing a
    sheet's engraved labels. The file is the same to the byte."""
    from ezdxf.entities.lwpolyline import LWPolylinePoints

    p = np.asarray(points, dtype=np.float64)
    if p.size == 0:
        p = np.zeros((0, 2))
    rows = np.zeros((p.shape[0], 5))
    rows[:, :2] = p[:, :2]
    if p.shape[1] > 2:
        rows[:, 4] = p[:, 2]
    e = msp.add_lwpolyline((), close=True, dxfattribs={"layer": layer})
    e.lwpoints = LWPolylinePoints(rows.tolist())
    return e


def _fmt(v: float) -> str:
    return repr(float(v))


def _header(sheet, plan: LaserPlan, n_sheets: int, header: dict | None) -> dict:
    """The FABKIT_* header variables of a sheet: the kit's, or ``header`` (the coupon's)."""
    if header is not None:
        return header
    s = plan.settings
    meta = {
        "FABKIT_DESIGN": plan.design.name,
        "FABKIT_SHEET": f"{sheet.index}/{n_sheets}",
        "FABKIT_SCALE": _fmt(s.scale),
        "FABKIT_KERF": _fmt(s.kerf),
        "FABKIT_KERF_NOTE": kerf_note(s),
        "FABKIT_BAR_WIDTH": _fmt(s.bar_width),
        "FABKIT_HOLE": _fmt(s.screw.hole_diameter),
        "FABKIT_THICKNESS": _fmt(s.thickness),
        "FABKIT_LAYERS": str(plan.stacking.n_layers),
        "FABKIT_BARS": str(plan.bars.n_bars),
        "FABKIT_TEMPLATE": plan.design.path.name if plan.design.path else "",
    }
    if plan.variant:
        meta["FABKIT_VARIANT"] = plan.variant
    return meta


def sheet_dxf(sheet, plan: LaserPlan, n_sheets: int, header: dict | None = None) -> bytes:
    """One sheet as DXF bytes (R2010, mm).

    Parameters
    ----------
    sheet : Sheet
    plan : LaserPlan
    n_sheets : int
    header : dict, optional
        FABKIT_* header variables in place of the kit's (the test coupon's).

    Returns
    -------
    bytes
        ASCII DXF; entities in cutting order: engraving, inner contours (holes), outer contours.
    """
    import ezdxf
    from ezdxf.enums import TextEntityAlignment

    s = plan.settings
    with _fixed_metadata():
        doc = ezdxf.new("R2010", units=4, setup=False)
        doc.header["$MEASUREMENT"] = 1
        doc.header["$LUNITS"] = 2
        for name, colour in LAYERS.items():
            doc.layers.add(name, color=colour)
        doc.appids.add(APPID)
        for key, value in _header(sheet, plan, n_sheets, header).items():
            doc.header.custom_vars.append(key, value)
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
                tag(_add_polyline(msp, vertices, layer), part)
                return
            for prim in bulge_primitives(vertices):
                if prim[0] == "line":
                    e = msp.add_line(prim[1], prim[2], dxfattribs={"layer": layer})
                else:
                    e = msp.add_arc(prim[1], prim[2], prim[3], prim[4], dxfattribs={"layer": layer})
                tag(e, part)

        for part in sheet.parts:  # engraving first: the parts are still held by the sheet
            if part.kind == "reference" and not part.meta.get("cut"):
                closed_outline(part.outline, "REFERENCE", part)
            for label in part.labels:
                if s.labels == "outlines":
                    for poly in label_outlines(label):
                        _add_polyline(msp, poly, "ENGRAVE")
                else:
                    t = msp.add_text(label.text, height=label.height, rotation=label.angle,
                                     dxfattribs={"layer": "ENGRAVE"})
                    t.set_placement(label.insert, align=TextEntityAlignment.MIDDLE_CENTER)
        for part in sheet.parts:  # inner contours before outer ones
            radii = part.meta.get("hole_radii") or [part.hole_radius] * len(part.holes)
            for c, radius in zip(part.holes, radii):
                e = msp.add_circle(tuple(map(float, c)), float(radius),
                                   dxfattribs={"layer": "CUT_INNER"})
                tag(e, part)
        for part in sheet.parts:
            if part.ring is not None:
                e = msp.add_circle(tuple(map(float, part.holes[0])), part.ring,
                                   dxfattribs={"layer": "CUT"})
                tag(e, part)
            elif part.kind != "reference" or part.meta.get("cut"):
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
        # set (order depends on the string hash seed): add them first, sort them, then write.
        doc.commit_pending_changes()
        doc.classes.add_required_classes(doc.dxfversion)
        doc.classes.classes = OrderedDict(sorted(doc.classes.classes.items()))
        stream = io.StringIO()
        doc.write(stream)
    return stream.getvalue().encode("ascii")


# -- bill of materials ----------------------------------------------------------------------

#: The sheet stock a kit is cut from, as it is sold.
SHEET_MATERIAL = "cast acrylic (PMMA) sheet"


def bom_verdict(plan: LaserPlan, verdict: dict | None) -> dict:
    """The head of the bill of materials: the design's verdict (``level``, ``text``,
    ``findings``, as ``fabkit export`` judges it; None when no export judged it), with what to
    expect, what to adjust and which joints to watch (:func:`fabkit.fab.guide.verdict_rows`),
    each sentence whole."""
    return {"level": str(verdict.get("level")) if verdict else NOT_JUDGED,
            "headline": str(verdict.get("headline", "")) if verdict else "",
            "words": verdict_rows(verdict, plan)}


def bill_of_materials(plan: LaserPlan, files, verdict: dict | None = None) -> dict:
    """The verdict (:func:`bom_verdict`), parts, sheets and hardware to buy, screws by length,
    spacer rings and the stack at every joint (JSON-able). Every piece of hardware is named as
    a shop lists it (:mod:`fabkit.fab.hardware`), with the count the kit uses and spares."""
    s, st, bars = plan.settings, plan.stacking, plan.bars
    sheet_of = {p.id: sh.index for sh in plan.sheets for p in sh.parts}
    fasteners = [js.fastener for js in st.joints]
    kinds: dict[tuple, int] = {}
    for f in fasteners:
        key = (f.kind, f.post, tuple(f.extensions))
        kinds[key] = kinds.get(key, 0) + 1
    n_spacers = sum(len(js.spacers) for js in st.joints)
    shim = s.screw.shim()
    shim_kinds = {w.name: w for w in s.screw.shim_set()}
    shim_counts: dict[str, int] = {}
    for f in fasteners:
        for name, _, n in f.shims:
            shim_counts[name] = shim_counts.get(name, 0) + int(n)
    lines = part_lines(fasteners)
    n_sheets = len(plan.sheets)
    motion = plan.design.motion
    nominal = [f.play_nominal for f in fasteners]
    return {
        "verdict": bom_verdict(plan, verdict),
        "design": plan.design.name,
        "scale_mm_per_unit": s.scale,
        "settings": s.as_dict(),
        "kerf": {"kerf_mm": s.kerf, "applied": s.kerf > 0, "note": kerf_note(s),
                 "uncompensated_files": sorted(n for n in files if "_uncompensated" in n)},
        "buy": {"sheets": {"material": SHEET_MATERIAL, "thickness_mm": s.thickness,
                           "size_mm": [s.sheet_width, s.sheet_height], "count": n_sheets,
                           "spares": 1,
                           "note": f"the kit fills {n_sheets} sheet(s); one more for the test "
                                   "coupon and a recut"},
                "hardware": [{"key": ln.key, "kind": ln.kind, "description": ln.description,
                              "family": part_family(ln, s.screw),
                              "count": ln.count, "spares": spares(ln.count),
                              "order": ln.count + spares(ln.count), **ln.size}
                             for ln in lines]},
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
                   "method": st.strategy, "head_slots": st.head_slots,
                   "depth_mm": round(st.n_layers * s.thickness, 6)},
        "screws": [{"name": s.screw.name, "kind": kind, "post_length_mm": post,
                    "extensions_mm": list(ext), "count": count,
                    "description": (s.screw.series() if kind != "clevis pin" else
                                    f"clevis pin ISO 2341 B {s.screw.barrel_diameter:g} mm"),
                    "family": s.screw.family if kind != "clevis pin" else "ISO 2341 B"}
                   for (kind, post, ext), count in sorted(kinds.items())],
        "axial_play": {"nominal_max_mm": round(max(nominal, default=0.0), 6),
                       "nominal_min_mm": round(min(nominal, default=0.0), 6),
                       "limit_mm": MAX_AXIAL_PLAY,
                       "note": f"with the shims listed, on {s.thickness:g} mm sheet"},
        "washers": {"count": sum(js.washers for js in st.joints), "name": shim.name,
                    "thickness_mm": shim.thickness, "inner_diameter_mm": shim.inner,
                    "outer_diameter_mm": shim.outer, "over_mm": s.screw.barrel_diameter,
                    "kinds": [{"name": name, "count": n, "thickness_mm": shim_kinds[name].thickness
                               if name in shim_kinds else None,
                               "description": shim_kinds[name].description()
                               if name in shim_kinds else name}
                              for name, n in shim_counts.items() if n],
                    "note": f"shims over the {s.screw.barrel_diameter:g} mm barrel, counted for "
                            f"{s.thickness:g} mm sheet (axial play at most "
                            f"{MAX_AXIAL_PLAY:g} mm); the posts close on sheets up to "
                            f"{s.thickness + s.thickness_tolerance:g} mm: measure the sheet, "
                            "take shims off where a stack is thicker, add spares where it is "
                            "thinner"},
        "spacer_rings": {"count": n_spacers, "outer_diameter_mm": s.spacer_diameter,
                         "hole_diameter_mm": s.screw.hole_diameter, "thickness_mm": s.thickness,
                         "note": "cut from the same sheet"},
        "joints": [{"joint": js.joint, "bottom_to_top": js.order(), "layers": list(js.layers),
                    "screw_length_mm": js.screw_length, "stack_mm": round(js.stack_height, 6),
                    "play_mm": round(js.play, 6), "spacers": len(js.spacers),
                    "washers": js.washers, "fastener": js.fastener.describe(),
                    "fastener_kind": js.fastener.kind,
                    "shims": [[name, t, n] for name, t, n in js.fastener.shims if n],
                    "play_nominal_mm": round(js.fastener.play_nominal, 6),
                    "play_with_washers_mm": [round(v, 6) for v in js.play_range]}
                   for js in st.joints],
        "motion": {"method": plan.sweep.method, "status": plan.sweep.status,
                   "drive": motion.drive,
                   "from": float(plan.design.network.port_distance(motion.drive)),
                   "to": float(motion.to) if motion.to is not None else None,
                   "samples": plan.sweep.stats.get("window_samples", plan.sweep.n_samples),
                   **({"windows": plan.sweep.stats} if plan.sweep.stats else {}),
                   "step_limit_mm": plan.sweep.step_limit,
                   "max_node_step_mm": round(plan.sweep.max_step, 6),
                   "guarantee": "no node moves more than step_limit_mm (= clearance / 2) between "
                                "samples; bars of one layer are >= clearance apart at every "
                                "sample and >= clearance / 2 between samples"},
        "files": sorted(files),
    }


def bom_blocks(bom: dict) -> list[tuple]:
    """The bill of materials as blocks, in order: ``("title", text)``, ``("heading", text)``,
    ``("text", text)``, ``("strong", text)``, ``("item", text)`` or ``("table", header, rows)``
    (cells as text). :func:`bom_markdown` writes them as Markdown; the HTML report renders the
    same blocks (it never reads the Markdown back)."""
    s = bom["settings"]
    buy = bom["buy"]
    sh = buy["sheets"]
    blocks: list[tuple] = [
        ("title", f"Laser-cut kit: {bom['design']}"),
        ("heading", f"Verdict: {bom['verdict']['level']}"),
        *(("item", text) for text in bom["verdict"]["words"]),
        ("text", f"Scale {bom['scale_mm_per_unit']:g} mm per design unit; {s['thickness']:g} mm "
                 f"acrylic; bars {s['bar_width']:g} mm wide; {bom['layers']['proof']}. The "
                 f"stack is {bom['layers']['depth_mm']:g} mm deep."),
        ("strong", f"Kerf: {bom['kerf']['note']}."),
        ("heading", "What to buy"),
        ("item", f"{sh['material']}, {sh['thickness_mm']:g} mm thick, "
                 f"{sh['size_mm'][0]:g} x {sh['size_mm'][1]:g} mm: {sh['count']} sheet(s) + "
                 f"{sh['spares']} spare ({sh['note']})."),
        ("table", ("part", "used", "spares", "order"),
         [(h["description"], f"{h['count']}", f"{h['spares']}", f"{h['order']}")
          for h in buy["hardware"]]),
        ("heading", "Sheets"),
        ("table", ("sheet", "file", "parts", "utilisation"),
         [(f"{sheet['index']}", sheet["file"], f"{len(sheet['parts'])}",
           f"{100 * sheet['utilisation']:.1f} %") for sheet in bom["sheets"]]),
        ("heading", "Screws"),
        ("table", ("fastener", "post length (mm)", "extensions (mm)", "count"),
         [(sc["description"], f"{sc['post_length_mm']:.4g}",
           " + ".join(f"{v:.4g}" for v in sc["extensions_mm"]) or "-", f"{sc['count']}")
          for sc in bom["screws"]]),
    ]
    if bom["screws"]:
        blocks.append(("text", f"Series: {bom['screws'][0]['family']}."))
    sp = bom["spacer_rings"]
    blocks += [
        ("text", f"Spacer rings: {sp['count']} (outer {sp['outer_diameter_mm']:g} mm, hole "
                 f"{sp['hole_diameter_mm']:g} mm, {sp['thickness_mm']:g} mm thick, "
                 f"{sp['note']})."),
        ("heading", "Bars"),
        ("table", ("bar", "joints", "layer", "hole spacing (mm)", "sheet"),
         [(f"{b['id']}", f"{b['joints'][0]}-{b['joints'][1]}", f"{b['layer']}",
           f"{b['length_mm']:.3f}", f"{b['sheet']}") for b in bom["bars"]]),
        ("heading", "Stack at each joint (bottom to top)"),
        ("table", ("joint", "stack", "fastener", "play nominal sheet (mm)",
                   "play thick-thin sheets (mm)"),
         [(f"{j['joint']}", ", ".join(j["bottom_to_top"]), j["fastener"],
           f"{j['play_nominal_mm']:.2f}",
           f"{j['play_with_washers_mm'][0]:.2f}-{j['play_with_washers_mm'][1]:.2f}")
          for j in bom["joints"]]),
    ]
    wa = bom["washers"]
    kinds = "; ".join(f"{k['count']} x {k['description']}" for k in wa.get("kinds", [])) or \
        f"{wa['count']} x {wa['name']}"
    mo = bom["motion"]
    blocks += [("text", f"Shims: {kinds}; {wa['note']}."),
               ("text", f"Motion: {mo['drive']} from {mo['from']:.6g} to {mo['to']:.6g} (design "
                        "units); " + mo["guarantee"] + ".")]
    return blocks


def bom_markdown(bom: dict) -> str:
    """The bill of materials as Markdown for a person at the bench (:func:`bom_blocks`)."""
    out = []
    for block in bom_blocks(bom):
        kind = block[0]
        if kind == "table":
            _, header, rows = block
            out.append("\n".join(["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
                                 + ["| " + " | ".join(r) + " |" for r in rows]))
        else:
            text = block[1]
            out.append({"title": f"# {text}", "heading": f"## {text}", "strong": f"**{text}**",
                        "item": f"- {text}"}.get(kind, text))
    return "\n\n".join(out) + "\n"


# -- entry ----------------------------------------------------------------------------------

def write(plan: LaserPlan, *, verdict_pages: bool = True) -> ExportResult:
    """Laser-cut files of a laser plan (pure: returns bytes, writes nothing).

    Parameters
    ----------
    plan : LaserPlan
        The laser process's plan (:func:`fabkit.fab.laser_plan.laser_plan`).
    verdict_pages : bool
        Draw the files that carry the verdict (:data:`VERDICT_FILES`: the guide and the bill
        of materials), headed "not judged". False: they stand empty in ``files`` and the report
        has no ``guide_pages``, for :func:`with_verdict` to make once the design is judged (the
        batch engine does this, so the guide is drawn once per export).

    Returns
    -------
    ExportResult
        ``files``: ``laser_sheet<k>.dxf`` and ``.svg`` per sheet, ``laser_bom.json``,
        ``laser_bom.md``, ``laser_assembly.png``, ``laser_layers_motion.png``,
        ``laser_guide.pdf``, ``laser_guide_page1.png``. ``report``: the bill of materials.
        The as-built check reads the files back (:func:`fabkit.check.dxf.check_documents`,
        run on every export by the batch engine); an exporter never checks its own output.
    """
    files: dict[str, bytes] = {}
    n = len(plan.sheets)
    for sheet in plan.sheets:
        files[f"laser_sheet{sheet.index}.dxf"] = sheet_dxf(sheet, plan, n)
        files[f"laser_sheet{sheet.index}.svg"] = sheet_svg(sheet, plan.settings)
    if plan.settings.uncompensated and plan.settings.kerf > 0:
        raw = uncompensated_plan(plan)
        for sheet in raw.sheets:
            files[f"laser_sheet{sheet.index}_uncompensated.dxf"] = sheet_dxf(sheet, raw, n)
            files[f"laser_sheet{sheet.index}_uncompensated.svg"] = sheet_svg(sheet, raw.settings)
    files.update(coupon_files(plan))

    if verdict_pages:
        bom, guide, carried = verdict_files(plan, sorted(files), None)
        gp, pages = guide.plan, {"guide_pages": int(guide.stats["pages"])}
    else:  # the pictures need the guide's plan, not its pages
        bom = bill_of_materials(plan, _listed(sorted(files)), None)
        gp, pages, carried = guide_plan(plan, bom, None), {}, dict.fromkeys(VERDICT_FILES, b"")
    files.update(carried)
    pictures = {"laser_assembly.png": assembly_picture(plan, gp),
                "laser_layers_motion.png": motion_picture(plan, gp)}
    files.update({name: png for name, (png, _) in pictures.items()})
    # a text a picture cuts off at its edge is said, not shipped unnoticed (the report's
    # warnings); the pictures measure it on the drawing their PNG is made of
    cut = [f"{name}: text cut off at the picture's edge: {', '.join(map(str, st['clipped']))}"
           for name, (_, st) in pictures.items() if st["clipped"]]
    if verdict_pages:
        cut += guide_cut(guide)
    # the guide's page count rides with the report (a report never counts a PDF's pages)
    return ExportResult(files=files, report={"format": FORMAT, **bom, **pages,
                                             **({"warnings": cut} if cut else {})})


#: The files that carry the verdict: made again once ``fabkit export`` has judged the design.
VERDICT_FILES = ("laser_guide.pdf", "laser_guide_page1.png", "laser_bom.json", "laser_bom.md")


def bom_json(bom: dict) -> bytes:
    """laser_bom.json with its verdict first (what a reader meets at its head), the rest in
    key order."""
    def ordered(v):
        if isinstance(v, dict):
            return {k: ordered(v[k]) for k in sorted(v)}
        return [ordered(x) for x in v] if isinstance(v, list) else v

    head = {"verdict": ordered(bom["verdict"])}
    head.update(ordered({k: v for k, v in bom.items() if k != "verdict"}))
    return (json.dumps(head, indent=2) + "\n").encode("utf-8")


def verdict_files(plan: LaserPlan, names, verdict: dict | None) -> tuple:
    """The bill of materials and the assembly guide of a laser plan, headed with a verdict.

    Parameters
    ----------
    plan : LaserPlan
    names : list of str
        The sheet, coupon and uncompensated files the kit is written as (the bill of materials
        lists them with its own files).
    verdict : dict or None
        ``level``, ``headline``, ``text``, ``findings`` (report.json's ``verdict``); None when
        the design has not been judged.

    Returns
    -------
    bom : dict
    guide : fabkit.fab.guide.Guide
    files : dict of str to bytes
        :data:`VERDICT_FILES`.
    """
    bom = bill_of_materials(plan, _listed(names), verdict)
    guide = guide_pages(plan, bom, verdict=verdict)  # hardware per page as the BOM names it
    files = {"laser_guide.pdf": guide.pdf, "laser_guide_page1.png": guide.images[0],
             "laser_bom.json": bom_json(bom), "laser_bom.md": bom_markdown(bom).encode("utf-8")}
    return bom, guide, files


def _listed(names) -> list:
    """The files a bill of materials lists: the kit's and its own."""
    return sorted({*names, "laser_assembly.png", "laser_layers_motion.png", *VERDICT_FILES})


def with_verdict(plan: LaserPlan, names, verdict: dict) -> tuple:
    """The files of a written laser kit that carry the verdict, made again with it (the batch
    engine's report stage calls this once the design is judged; nothing else is rewritten).

    Parameters
    ----------
    plan : LaserPlan
    names : list of str
        The files the format wrote.
    verdict : dict
        report.json's ``verdict``.

    Returns
    -------
    files : dict of str to bytes
        :data:`VERDICT_FILES`.
    report : dict
        What changes in the format's report: ``verdict``, ``guide_pages`` and, when a text of
        the guide reaches past its page, ``warnings`` to add (:func:`guide_cut`).
    """
    kit = [n for n in names if n not in VERDICT_FILES]
    bom, guide, files = verdict_files(plan, kit, verdict)
    report = {"verdict": bom["verdict"], "guide_pages": int(guide.stats["pages"])}
    cut = guide_cut(guide)
    if cut:
        report["warnings"] = cut  # added to the format's warnings (the pictures' own)
    return files, report


def guide_cut(guide) -> list[str]:
    """The format's warnings for the guide's texts that reach past their page (none).

    Parameters
    ----------
    guide : fabkit.fab.guide.Guide

    Returns
    -------
    list of str
        One line per page with such texts.
    """
    pages: dict[int, list] = {}
    for page, text in guide.stats["clipped"]:
        pages.setdefault(int(page), []).append(str(text))
    return [f"laser_guide.pdf: text past the edge of page {p}: {', '.join(t)}"
            for p, t in sorted(pages.items())]


def export_design(design, settings=None, *, motion=None) -> ExportResult:
    """Laser-cut files for a design: its laser plan, written (pure: returns bytes, writes
    nothing).

    Parameters
    ----------
    design : Design
    settings : DesignSettings or dict, optional
        The design's resolved settings, or overrides nested by section, e.g.
        ``{"laser": {"kerf": 0.2, "scale": 60}}`` (resolved once, here).
    motion : TracedMotion, optional
        The design's motion, traced once (see :func:`fabkit.fab.laser_plan.laser_plan`).

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
        Bad settings or geometry (see :func:`fabkit.fab.laser_plan.laser_plan`).

    Examples
    --------
    >>> import fabkit
    >>> from fabkit.writers.dxf import export_design
    >>> design = fabkit.load_template("templates/fourbar.toml")   # doctest: +SKIP
    >>> sorted(export_design(design).files)[:2]                   # doctest: +SKIP
    ['laser_assembly.png', 'laser_bom.json']
    """
    from ..fab.plans import make_plan

    return write(make_plan(PROCESS, design, settings, motion))
