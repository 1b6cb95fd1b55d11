"""ORIPA ``.cp`` crease patterns: one line per segment, ``type x1 y1 x2 y2``.

Types: 1 cut/boundary, 2 mountain, 3 valley (ORIPA's; flat and unassigned segments are left
out, ORIPA has no type for them). Mountains and valleys are those of the simulated folding. Coordinates in mm, y up, centred on the sheet (ORIPA's
convention). Single sheets only.
"""

from __future__ import annotations


from ..errors import FabricationError
from . import ExportResult

FORMAT = "cp"

#: The process whose plan (:func:`fabkit.fab.creases.plan.origami_plan`) this format is written from.
PROCESS = "origami"
#: The sections of ``--set`` this format reads (any other has no effect on it).
READS = ("origami",)

#: ORIPA line type of each assignment.
TYPES = {"B": 1, "C": 1, "M": 2, "V": 3}


#: Why the format does not apply, when :func:`applies` says so (reported by ``--to cp``).
NOT_APPLICABLE = ("an ORIPA .cp crease pattern needs a single sheet with a [fabrication.origami] "
                  "table; chains of sheets are written as svg and fold")


def applies(design) -> bool:
    """True for a single-sheet design with a ``[fabrication.origami]`` table."""
    fab = getattr(design, "fabrication", None)
    return (isinstance(fab, dict) and isinstance(fab.get("origami"), dict)
            and "sheets" not in fab["origami"])


def render(pattern, scale: float) -> bytes:
    """The .cp text of a crease pattern at ``scale`` mm per design unit."""
    v = pattern.vertices
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    p = (v - centre) * scale
    lines = []
    for k, (a, b) in enumerate(pattern.edges.tolist()):
        t = TYPES.get(pattern.assignment[k])
        if t is None:
            continue
        lines.append(f"{t} {p[a, 0]:.6f} {p[a, 1]:.6f} {p[b, 0]:.6f} {p[b, 1]:.6f}")
    return ("\n".join(lines) + "\n").encode("ascii")


def export_design(design, settings=None, *, motion=None) -> ExportResult:
    """``<name>.cp`` of a design: its origami plan, written (see :func:`write`)."""
    from ..fab.plans import make_plan

    return write(make_plan(PROCESS, design, settings, motion))


def write(plan) -> ExportResult:
    """``<name>.cp`` of an origami plan (:class:`fabkit.fab.creases.plan.OrigamiPlan`) of a
    single sheet.

    Raises
    ------
    FabricationError
        The plan has several sheets (the SVG writer lays them out).
    """
    design, model = plan.design, plan.model
    if len(model.sheets) != 1:
        raise FabricationError(f"{design.name}: ORIPA .cp holds one sheet; this design has "
                               f"{len(model.sheets)} (export svg for the layout)")
    # mountain and valley as the simulator folds the sheet (they equal the template's when the
    # branch is chosen by its assignment): the plan's realised pattern
    pattern = plan.layout.realised.pattern()
    labs = pattern.assignment
    data = render(pattern, model.scale)
    n = int(sum(a in TYPES for a in labs))
    return ExportResult(files={f"{design.name}.cp": data},
                        report={"format": FORMAT, "segments": n, "scale_mm_per_unit": model.scale})
