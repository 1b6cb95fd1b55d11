"""STL and 3MF of a print-in-place bar linkage (:mod:`fabkit.fab.pinned`): the ``stl`` format
for planar bar networks.

Files (``NAME`` is the design's name; ``_bed<k>`` when the print needs more than one bed):

* ``NAME.stl`` — binary STL of the bed as it prints (millimetres, turned and placed on the
  chosen printer's bed, every piece lowered onto it; centred on the bed's centre, as an STL
  carries no placement): one closed shell per bar;
* ``NAME.3mf`` — the same bed, one object per piece (its bars as named parts, in bed
  coordinates), with the print settings the design needs
  (:mod:`fabkit.fab.slicer`), unless ``threemf = false``;
* ``NAME_print.png`` — the beds seen from above, bars coloured by layer, unless
  ``preview = false``;
* ``print_bom.json``, ``print_bom.md`` — the print's bill of materials
  (:mod:`fabkit.writers.print_bom`): beds, parts per bed, filament, and the bolts (with their
  lengths), washers and lock nuts of the joints where the print is cut.

Pure: returns bytes. The as-built check (:mod:`fabkit.check.pinned`) reads the STL or 3MF
back, finds the bars, pins and holes, rebuilds the joints and re-simulates the motion.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import FabricationError
from ..numerics import MM_SLACK
from ..plots.viz import figure_kit
from . import ExportResult
from .print_bom import print_bom_document, print_bom_files
from .stl_file import binary_stl, stl_origin, stored_mesh_is_closed
from .threemf import threemf_package

__all__ = ["write_pinned", "bed_file_names", "body_meshes", "JOIN_PINNED", "print_bom",
           "BOLT_LENGTHS", "STL_NOTE"]

JOIN_PINNED = ("the pieces meet at the joints of the port named joined_at, where every bar has a "
               "plain hole: lay the later piece on the earlier one so that those holes line up, "
               "then close each such joint with the parts the print's bill of materials lists for "
               "it (bolt, washers, lock nut): the bars in the order of their layers, bottom "
               "first, {fill:g} mm of washers in each layer with no bar, the lock nut left loose "
               "enough for the bars to turn")
#: ISO 4762 M3 socket head cap screw lengths as sold (mm).
BOLT_LENGTHS = (6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0,
                55.0, 60.0, 65.0, 70.0, 80.0, 90.0, 100.0)
#: ISO 7089 M3 washer (mm): 3.2 mm hole, 7 mm outside, 0.5 mm thick.
_WASHER = (3.2, 7.0, 0.5)
#: ISO 10511 M3 lock nut (nylon insert) height (mm).
_NUT = 4.0
#: What a bare STL is: the 3MF carries the settings the print needs.
STL_NOTE = ("geometry only: use the 3MF, which carries the settings this print needs (layer "
            "height, perimeters, supports from the bed only, material, a skirt inside the bed's "
            "margin); an STL sliced with a slicer's defaults prints the upper bars into air")


def bed_file_names(name: str, beds: int, suffix: str) -> list[str]:
    """``NAME.suffix`` for one bed, else ``NAME_bed1.suffix``, ``NAME_bed2.suffix``, ..."""
    if beds == 1:
        return [f"{name}{suffix}"]
    return [f"{name}_bed{b + 1}{suffix}" for b in range(beds)]


def body_meshes(plan) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every bar's body as (vertices (V, 3) mm in the print frame, triangles (F, 3))."""
    from ..fab.hinges import solid_mesh
    from ..fab.pinned import bar_body

    return [solid_mesh(bar_body(plan, k)) for k in range(plan.n_bars)]


def _placed(vertices, matrix) -> np.ndarray:
    return vertices @ matrix[:3, :3].T + matrix[:3, 3]


#: Layout of the print preview (inches): each bed's panel, and the room around it for tick
#: labels (7 pt, up to four digits), the bed's title and the wrapped heading.
_BED_IN, _LEFT_IN, _RIGHT_IN, _BOTTOM_IN = 4.2, 0.5, 0.15, 0.35
_WSPACE_IN, _HSPACE_IN, _TITLE_IN, _LINE_IN = 0.5, 0.6, 0.35, 0.17


def preview_figure(plan, title: str):
    """The beds of a print-in-place plan seen from above: bars by layer, printed pins as
    white caps.

    The layout is fixed in inches (no tight layout: the panels are alike and their tick labels
    bounded) and the heading is wrapped to the figure's width.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import textwrap

    from matplotlib.collections import PatchCollection, PolyCollection

    s = plan.settings
    printer = s.printer_profile()
    beds = plan.beds
    cols = min(beds, 3)
    rows = -(-beds // cols)
    width = _BED_IN * cols
    heading = textwrap.wrap(
        f"{title}: {plan.n_bars} bars in {plan.stacking.n_layers} layers (colour = layer), "
        f"{len(plan.carrier)} printed pins (white caps), {printer.width:g} x {printer.depth:g} mm "
        f"bed, {printer.margin:g} mm kept free along its edges (dashed) and the parts "
        f"{plan.parts_margin:g} mm from them (dotted: room for the skirt and support)",
        int(width * 72 / (9 * 0.62)))
    top = 0.15 + _LINE_IN * len(heading) + _TITLE_IN
    height = _BED_IN * rows + top - _TITLE_IN + 0.25
    fig, axes = figure_kit.subplots(rows, cols, figsize=(width, height), squeeze=False)
    panel_w = (width - _LEFT_IN - _RIGHT_IN - _WSPACE_IN * (cols - 1)) / cols
    panel_h = (height - top - _BOTTOM_IN - _HSPACE_IN * (rows - 1)) / rows
    fig.subplots_adjust(left=_LEFT_IN / width, right=1 - _RIGHT_IN / width,
                        bottom=_BOTTOM_IN / height, top=1 - top / height,
                        wspace=_WSPACE_IN / panel_w, hspace=_HSPACE_IN / panel_h)
    cmap = figure_kit.get_cmap("viridis", max(int(plan.layer.max()) + 1, 2))
    piece_of = plan.piece_of_bar()
    order = np.argsort(plan.layer, kind="stable")  # upper layers drawn on top
    for b, ax in enumerate(axes.ravel()):
        if b >= beds:
            ax.axis("off")
            continue
        ax.add_patch(figure_kit.Rectangle((0, 0), printer.width, printer.depth, fill=False, lw=0.8,
                                   ec="0.5"))
        # the margin kept free for the slicer's skirt, brim and support
        m = printer.margin
        ax.add_patch(figure_kit.Rectangle((m, m), printer.width - 2 * m, printer.depth - 2 * m,
                                   fill=False, lw=0.6, ec="0.6", ls="--"))
        m = plan.parts_margin
        ax.add_patch(figure_kit.Rectangle((m, m), printer.width - 2 * m, printer.depth - 2 * m,
                                          fill=False, lw=0.6, ec="0.6", ls=":"))
        polys, colours = [], []
        for k in order:
            p = int(piece_of[k])
            if plan.layout[p].bed != b:
                continue
            m = plan.placement_matrix(p)
            polys.append(plan.bar_outline(k) @ m[:2, :2].T + m[:2, 3])
            colours.append(cmap(int(plan.layer[k])))
        ax.add_collection(PolyCollection(polys, facecolors=colours, edgecolors="k", lw=0.4,
                                         alpha=0.85))
        caps = []
        for j, k in plan.carrier.items():
            m = plan.placement_matrix(int(piece_of[k]))
            if plan.layout[int(piece_of[k])].bed == b:
                x, y = plan.positions[j] @ m[:2, :2].T + m[:2, 3]
                caps.append(figure_kit.Circle((x, y), 0.5 * s.cap_diameter))
        ax.add_collection(PatchCollection(caps, facecolor="w", edgecolor="k", lw=0.5))
        ax.set_xlim(-5, printer.width + 5)
        ax.set_ylim(-5, printer.depth + 5)
        ax.set_aspect("equal")
        ax.set_title(f"bed {b + 1} of {beds}", fontsize=9)
        ax.tick_params(labelsize=7)
    fig.suptitle("\n".join(heading), fontsize=9, y=1 - 0.1 / height, va="top")
    return fig


def print_bom(plan) -> dict:
    """Every part of a print-in-place linkage that is not printed, with its size and count:
    at each joint the print is cut at, an M3 bolt through the stack (bars and washers for
    the layers without a bar), a washer under its head and under its lock nut.

    Returns
    -------
    dict
        ``buy``: list of {"part", "standard", "size", "count"}; ``joints``: joint -> the
        parts it takes; ``printed``: what is printed (bars and pins), counted.
    """
    s = plan.settings
    per_joint, totals = {}, {}
    # bolted, the bars lie on one another: a layer with no bar takes a bar's thickness
    fill = _WASHER[2] * math.ceil(s.bar_thickness / _WASHER[2] - MM_SLACK)
    for st in plan.stacking.joints:
        j = int(st.joint)
        if j in plan.carrier:
            continue
        n_bars, empty = len(st.bars), len(st.spacers)
        stack = n_bars * s.bar_thickness + empty * fill + 2 * _WASHER[2]
        need = stack + _NUT + 1.0  # a thread's turn or two past the nut
        length = next((v for v in BOLT_LENGTHS if v >= need - MM_SLACK), None)
        if length is None:
            raise FabricationError(f"joint {j}: a stack of {stack:.1f} mm needs an M3 bolt longer "
                                   f"than {BOLT_LENGTHS[-1]:g} mm; print it whole (a larger "
                                   "printer) or with fewer layers")
        washers = 2 + int(round(empty * fill / _WASHER[2]))
        parts = [(f"socket head cap screw M3 x {length:g}", "ISO 4762", f"M3 x {length:g} mm", 1),
                 ("washer M3", "ISO 7089", f"{_WASHER[0]:g} x {_WASHER[1]:g} x {_WASHER[2]:g} mm",
                  washers),
                 ("lock nut M3 (nylon insert)", "ISO 10511", "M3", 1)]
        per_joint[j] = [{"part": p, "standard": std, "size": size, "count": n}
                        for p, std, size, n in parts]
        for p, std, size, n in parts:
            key = (p, std, size)
            totals[key] = totals.get(key, 0) + n
    buy = [{"part": p, "standard": std, "size": size, "count": n}
           for (p, std, size), n in sorted(totals.items(), key=lambda kv: (kv[0][1], kv[0][0]))]
    return {"buy": buy, "joints": per_joint, "washers_per_empty_layer": int(round(
        fill / _WASHER[2])) if per_joint else 0,
            "printed": {"bars": plan.n_bars, "pins": len(plan.carrier)},
            "note": ("nothing to buy: every joint is a printed pin" if not buy else
                     f"{len(per_joint)} joints where the print is cut are bolted: "
                     f"{sum(b['count'] for b in buy if b['standard'] == 'ISO 4762')} bolts")}


def _stacks(plan) -> list[dict]:
    out = []
    s = plan.settings
    for st in plan.stacking.joints:
        j = int(st.joint)
        pinned = j in plan.carrier
        out.append({"joint": j, "bars": list(st.bars), "layers": list(st.layers),
                    "collars": list(st.spacers) if pinned else [],
                    "spacers": [] if pinned else list(st.spacers),
                    "pin": "printed" if pinned else "M3 bolt (the print is cut here; see "
                                                    "print_bom)",
                    "carrier": plan.carrier.get(j),
                    "pin_length_mm": (round(plan.pin_stack(j)[-1][1]
                                            - plan.z(plan.carrier[j]) - s.bar_thickness, 6)
                                      if pinned else None)})
    return out


def _bed_bodies(plan, meshes, b: int, name: str, origin) -> tuple[list, list, list]:
    """The bodies on bed ``b``, placed: their vertices and faces (one mesh for the STL) and one
    object per piece (for the 3MF)."""
    verts, faces, offset = [], [], 0
    objects = []
    on_bed = [p for p in range(len(plan.pieces)) if plan.layout[p].bed == b]
    stacks = [[p] for p in on_bed if not plan.pieces[p].get("flat")]
    flat = [p for p in on_bed if plan.pieces[p].get("flat")]
    for group in stacks + ([flat] if flat else []):
        pv, pf, volumes = [], [], []
        first = poff = 0
        for p, k in ((p, k) for p in group for k in plan.pieces[p]["bars"]):
            m = plan.placement_matrix(p)
            v, f = meshes[k]
            placed = _placed(v, m)
            if not (stored_mesh_is_closed(placed, f)
                    and stored_mesh_is_closed(placed - origin, f)):
                raise FabricationError(
                    f"bar {k}'s body is not watertight once its coordinates are rounded to "
                    "float32 (features too close); change bar_width or scale slightly")
            verts.append(placed)
            faces.append(f + offset)
            offset += len(v)
            pv.append(placed)
            pf.append(f + poff)
            poff += len(v)
            i, j = plan.edges[k]
            where = (f"laid flat, layer {int(plan.layer[k]) + 1} when bolted" if group is flat
                     else f"layer {int(plan.layer[k]) + 1}")
            volumes.append((first, first + len(f) - 1, f"bar {k} (joints {i}-{j}), {where}"))
            first += len(f)
        # placed in the mesh itself: PrusaSlicer 2.5 applies a build item's transform to
        # the first part of an object only
        title = (f"{name}_flat_bars" if group is flat else
                 name if len(plan.pieces) == 1 else f"{name}_piece{group[0] + 1}")
        objects.append((np.concatenate(pv), np.concatenate(pf), title, None, volumes))
    return verts, faces, objects


def write_pinned(plan, s, name: str, design, slicer) -> ExportResult:
    """Files and report of a print-in-place linkage's plan (see the module docstring).

    Parameters
    ----------
    plan : PinnedPrint
        The linkage's layers, pins, pieces and beds (:func:`fabkit.fab.pinned.pinned_print`).
    s : PrintSettings
        ``linkage = "pins"``.
    name : str
        File name stem.
    design : Design
        The design the plan was made for (its name, for the files' titles).
    slicer : SlicerSettings
        What the 3MF files tell the slicer (the print plan's
        :attr:`~fabkit.fab.print_plan.PrintPlan.slicer`).

    Returns
    -------
    ExportResult

    Raises
    ------
    FabricationError
        A body that is not watertight once its coordinates are rounded to float32.
    """
    meshes = body_meshes(plan)
    beds = plan.beds
    files: dict[str, bytes] = {}
    stl_names = bed_file_names(name, beds, ".stl")
    mf_names = bed_file_names(name, beds, ".3mf")
    origin = stl_origin(s.printer_profile())
    triangles = 0
    for b in range(beds):
        verts, faces, objects = _bed_bodies(plan, meshes, b, name, origin)
        v_bed, f_bed = np.concatenate(verts) - origin, np.concatenate(faces)
        triangles += len(f_bed)
        files[stl_names[b]] = binary_stl(
            v_bed, f_bed, header=f"fabkit print-in-place linkage, units mm, bed {b + 1} of {beds}")
        if s.threemf:
            files[mf_names[b]] = _threemf(objects, slicer, design.name)
    if s.preview:
        from ..plots.viz import figure_png

        files[f"{name}_print.png"] = figure_png(preview_figure(plan, design.name))
    volumes = plan.volumes
    pieces = [{"piece": p + 1, "bed": plan.layout[p].bed + 1, "angle_deg": plan.layout[p].angle,
               "offset_mm": list(plan.layout[p].offset), "size_mm": list(plan.layout[p].size),
               "lowered_mm": plan.piece_floor(p), "bars": [int(k) for k in piece["bars"]],
               "joined_at": piece["joined_at"] or None, "flat": bool(piece.get("flat"))}
              for p, piece in enumerate(plan.pieces)]
    printer = s.printer_profile()
    split = len(plan.pieces) > 1
    bom = print_bom(plan)
    files.update(print_bom_files(_bom_document(plan, s, design.name, bom, stl_names, mf_names)))
    report = {
        "linkage": "pins",
        "settings": s.as_dict(),
        "bars": plan.n_bars,
        "bodies": plan.n_bars,
        "layers": int(plan.stacking.n_layers),
        "layers_proof": plan.stacking.proof_text(),
        "printed_pins": len(plan.carrier),
        "cut_joints": list(plan.cut_joints),
        "joints": _stacks(plan),
        "height_mm": float(plan.layer.max() * s.layer_pitch + 2 * s.bar_thickness
                           + s.layer_gap),
        "clearances_mm": {"pin_radial": s.pin_clearance, "layer_gap": s.layer_gap,
                          "same_layer_over_motion": s.clearance},
        "motion_samples": plan.stats["samples"],
        "volume_mm3": float(volumes.sum()),
        "body_volumes_mm3": [float(v) for v in volumes],
        "mesh": {"triangles": int(triangles), "bodies": plan.n_bars},
        "printer": {"printer": printer.as_dict(), "beds": beds, "pieces": pieces,
                    "parts_margin_mm": plan.parts_margin, "laid_flat": plan.flat,
                    "join": JOIN_PINNED.format(fill=bom["washers_per_empty_layer"] * 0.5)
                    if split else None,
                    "files": sorted(n for n in files if n.endswith((".stl", ".3mf"))),
                    "stl": STL_NOTE if s.threemf else None},
        "print_bom": bom,
        "slicer": slicer.as_dict() if s.threemf else None,
        "warnings": [],
        "files": sorted(files),
    }
    return ExportResult(files=files, report=report)


def _bed_parts(plan, b: int) -> list[dict]:
    """What bed ``b`` holds, as the print's bill of materials lists it."""
    s = plan.settings
    out = []
    for p, piece in enumerate(plan.pieces):
        if plan.layout[p].bed != b:
            continue
        bars = [int(k) for k in piece["bars"]]
        if piece.get("flat"):
            k = bars[0]
            i, j = (int(v) for v in plan.edges[k])
            length = float(np.linalg.norm(plan.positions[i] - plan.positions[j]))
            out.append({"piece": p + 1, "bars": bars, "flat": True,
                        "text": f"bar {k} (joints {i}-{j}), {length:.1f} mm between its holes, "
                                f"laid flat: no printed pin joins it; it is bolted in layer "
                                f"{int(plan.layer[k]) + 1} of its joints' stacks"})
            continue
        pins = sorted(j for j, k in plan.carrier.items() if k in bars)
        layers = sorted({int(plan.layer[k]) for k in bars})
        joined = f", joined to the next piece at {piece['joined_at']}" if piece["joined_at"] else ""
        out.append({"piece": p + 1, "bars": bars, "flat": False, "printed_pins": pins,
                    "text": f"piece {p + 1}: bars {', '.join(map(str, bars))} printed in place "
                            f"in {len(layers)} layers of {s.layer_pitch:g} mm on {len(pins)} "
                            f"printed pins (joints {', '.join(map(str, pins)) or 'none'})"
                            + joined})
    return out


def _bom_document(plan, s, name: str, bom: dict, stl_names, mf_names) -> dict:
    """The print's bill of materials (:mod:`fabkit.writers.print_bom`) of a pinned plan."""
    volumes = plan.volumes
    piece_of = plan.piece_of_bar()
    beds = []
    for b in range(plan.beds):
        on_bed = [k for k in range(plan.n_bars) if plan.layout[int(piece_of[k])].bed == b]
        beds.append({"bed": b + 1,
                     "files": [stl_names[b]] + ([mf_names[b]] if s.threemf else []),
                     "parts": _bed_parts(plan, b), "bars": len(on_bed),
                     "volume_mm3": float(volumes[on_bed].sum())})
    stacks = {int(st.joint): st for st in plan.stacking.joints}
    joints = []
    for j, parts in sorted(bom["joints"].items()):
        st = stacks[j]
        order = sorted(zip(st.layers, st.bars))
        joints.append({"joint": j, "bars": [int(k) for _, k in order],
                       "layers": [int(layer) + 1 for layer, _ in order],
                       "empty_layers": [int(v) + 1 for v in st.spacers], "parts": parts})
    printer = s.printer_profile()
    notes = [JOIN_PINNED.format(fill=bom["washers_per_empty_layer"] * 0.5)
             if len(plan.pieces) > 1 else "one piece: nothing to join",
             "after printing, turn each printed joint by hand to break the first layer of "
             "the gaps free"]
    if plan.flat:
        notes.append(f"{len(plan.flat)} bars no printed pin joins are printed lying flat "
                     f"(bars {', '.join(map(str, plan.flat))}): bolt each into its joints' "
                     "stacks in the layer the table gives")
    return print_bom_document(
        name, "print-in-place bar linkage", s,
        {"name": printer.name, "bed_mm": [printer.width, printer.depth],
         "margin_mm": printer.margin, "parts_margin_mm": plan.parts_margin},
        beds, bom["buy"], joints, notes)


def _threemf(objects, slicer, title: str) -> bytes:
    return threemf_package(None, None, objects=objects, project=slicer.project,
                           per_object=slicer.per_object,
                           title=f"fabkit print settings for {title}")
