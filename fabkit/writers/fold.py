"""FOLD (spec 1.2) JSON of an origami design, with the simulated folding path as frames.

Root frame: for a single sheet, the flat crease pattern (``frame_classes = ["creasePattern"]``,
2D vertices in mm); for a chain of sheets, the start configuration in 3D (``foldedForm``).
Edges carry ``edges_assignment`` (B/M/V/F/U/C) and ``edges_foldAngle`` in degrees (positive
valley, negative mountain; the target angles: where each crease is folded most along the motion,
the end of a folding from flat, the start of an unfolding); ``faces_vertices`` are
counter-clockwise in the flat pattern. ``file_frames`` holds every configuration of the
simulated motion (3D, mm, ``frame_parent = 0``, ``frame_inherit = true``) with its own
``edges_foldAngle``.

fabkit's own fields (FOLD allows namespaced extensions): ``fabkit:ports`` (named vertex pairs),
``fabkit:motion`` (drive, target, branch taken out of the flat state), ``fabkit:map`` (every
port distance at every frame, design units), ``fabkit:scale`` (mm per design unit) and
``fabkit:frame_drive``. :mod:`fabkit.check.fold` reads them back to re-fold and compare.
"""

from __future__ import annotations

import json

import numpy as np

from .. import __version__
from . import ExportResult

FORMAT = "fold"

#: The process whose plan (:func:`fabkit.fab.creases.plan.origami_plan`) this format is written from.
PROCESS = "origami"
#: The sections of ``--set`` this format reads (any other has no effect on it).
READS = ("origami",)


#: Why the format does not apply, when :func:`applies` says so (reported by ``--to fold``).
NOT_APPLICABLE = ("a FOLD file needs a [fabrication.origami] table (mountain/valley assignment); "
                  "this design has none: cut it (dxf) or print it (stl)")


def applies(design) -> bool:
    """True when the template has a ``[fabrication.origami]`` table."""
    fab = getattr(design, "fabrication", None)
    return isinstance(fab, dict) and isinstance(fab.get("origami"), dict)


def _round(a, digits=12):
    return np.round(np.asarray(a, dtype=np.float64), digits).tolist()


def fold_document(plan) -> dict:
    """The FOLD dictionary of an origami plan's folded model (see the module docstring).

    ``edges_assignment`` is the assignment the simulated folding realises (the plan's
    ``layout.assignment``, :func:`~fabkit.fab.creases.folded_assignment`): its M/V always agree
    with the signs of ``edges_foldAngle``.
    """
    model, fold = plan.model, plan.fold
    drive, to = plan.design.motion.drive, plan.design.motion.to
    scale = model.scale
    nv = model.n_vertices
    if model.flat_start:
        pat = model.pattern()
        root = pat.vertices * scale
        classes, attrs = ["creasePattern"], ["2D"]
    else:
        root = model.network.nodes[:nv] * scale
        classes, attrs = ["foldedForm"], ["3D"]
    final = fold.target_angles
    frames = []
    for k in range(fold.positions.shape[0]):
        frames.append({
            "frame_classes": ["foldedForm"],
            "frame_attributes": ["3D"],
            "frame_parent": 0,
            "frame_inherit": True,
            "frame_title": f"{drive} = {fold.drive[k]:.12g}",
            "vertices_coords": _round(fold.positions[k, :nv] * scale, 9),
            "edges_foldAngle": _round(fold.angles[k], 9),
            "fabkit:frame_drive": float(fold.drive[k]),
        })
    return {
        "file_spec": 1.2,
        "file_creator": f"fabkit {__version__}",
        "file_title": model.name,
        "file_classes": ["singleModel"],
        "frame_title": model.name,
        "frame_classes": classes,
        "frame_attributes": attrs,
        "frame_unit": "mm",
        "vertices_coords": _round(root, 12),
        "edges_vertices": model.edges.tolist(),
        "edges_assignment": list(plan.layout.assignment),
        "edges_foldAngle": _round(final, 9),
        "faces_vertices": [list(f) for f in model.faces],
        "file_frames": frames,
        "fabkit:scale": scale,
        "fabkit:ports": {k: list(v) for k, v in model.network.ports.items()},
        "fabkit:motion": {"drive": drive, "to": float(to), "method": fold.method,
                          "branch": fold.branch, "sign": fold.sign,
                          "branches": fold.branches, "samples": int(fold.positions.shape[0]),
                          "spacing": model.settings.spacing,
                          "step_off": model.settings.step_off},
        "fabkit:map": {k: [float(x) for x in v] for k, v in fold.ports.items()},
        "fabkit:sheets": sheet_ports(model),
    }


def sheet_ports(model) -> list[dict]:
    """Per sheet: its vertices and the ports it maps (input, output), for the as-built check."""
    out = []
    names = sorted(model.network.ports, key=lambda k: (len(k), k))
    for sh in model.sheets:
        nodes = set(int(i) for i in sh.nodes.tolist())
        inside = [k for k in names if set(model.network.ports[k]) <= nodes]
        out.append({"vertices": [int(i) for i in sh.nodes.tolist()],
                    "map": [inside[0], inside[-1]] if len(inside) >= 2 else []})
    return out


def export_design(design, settings=None, *, motion=None) -> ExportResult:
    """``<name>.fold`` of a design: its origami plan, written (see :func:`write`).

    Raises
    ------
    FabricationError
        No [fabrication.origami] table, bad settings, or a folding the simulator cannot do.
    """
    from ..fab.plans import make_plan

    return write(make_plan(PROCESS, design, settings, motion))


def write(plan) -> ExportResult:
    """``<name>.fold`` of an origami plan (:class:`fabkit.fab.creases.plan.OrigamiPlan`)."""
    design, model, fold = plan.design, plan.model, plan.fold
    doc = fold_document(plan)
    data = (json.dumps(doc, indent=1) + "\n").encode("utf-8")
    changed = [k for k, (a, b) in enumerate(zip(model.assignment, doc["edges_assignment"]))
               if a != b]
    report = {"format": FORMAT, "frames": len(doc["file_frames"]), "method": fold.method,
              "assignment_changed": changed,
              "branch": fold.branch, "sign": fold.sign, "branches": fold.branches,
              "max_edge_error": fold.max_edge_error,
              "final_fold_angles": doc["edges_foldAngle"]}
    return ExportResult(files={f"{design.name}.fold": data}, report=report)
