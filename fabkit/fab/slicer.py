"""What a printed network's 3MF tells the slicer: the settings the design needs, and no more.

PrusaSlicer reads two kinds of settings from a 3MF (2.5, ``src/libslic3r/Format/3mf.cpp``):

* **per object** (``Metadata/Slic3r_PE_model.config``): settings of the object alone, kept
  whichever way the file is opened, "Import geometry only" included. Layer height, perimeters,
  thin walls and supports are object settings;
* **project** (``Metadata/Slic3r_PE.config``): read by the command line (its own options win)
  and by "Open as project" in the window, which fills every setting the file leaves out with
  PrusaSlicer's defaults. Material and first layer height exist only there.

So the design's needs go per object wherever PrusaSlicer allows, and into the project part as
well: PrusaSlicer's G-code header lists the project's settings only, so a setting that lives
per object alone is applied while the header says the default (``perimeters = 3``,
``support_material = 0``); written in both, the header shows what was applied. The project
part also carries the material, the first layer (so that the printed heights fall on whole
layers) and a skirt (one loop, 3 mm out, no brim).

What the slicer prints around the parts — the support's first layer spread out, the brim, the
skirt's distance and loops — reaches :func:`slicer_reach` mm beyond them, as the written
settings ask; the bed layout keeps the parts that much further from the bed's edges than the
printer's margin (:func:`placement_margin`), so that the margin stays free of everything
printed.
Printer, bed shape and nozzle are never written: they stay the user's (the report says so, and
how to keep them when opening the file in the window).

:func:`slicer_settings` gives both parts with the reason for every key; the 3MF writer
(:func:`fabkit.writers.stl.threemf_package`) writes them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..settings.filaments import FILAMENTS

__all__ = ["SlicerSettings", "slicer_settings", "slicer_reach", "placement_margin",
           "LEFT_TO_USER", "SKIRT_DISTANCE", "SUPPORT_FIRST_LAYER_EXPANSION",
           "LINE_WIDTH_FACTOR"]

#: Distance of the skirt from the parts (mm).
SKIRT_DISTANCE = 3.0
#: How far PrusaSlicer spreads the first layer of support beyond the support itself
#: (``raft_first_layer_expansion``, mm; its default, written so that the file fixes it: the
#: support of a print-in-place linkage reached 3.8 mm past the parts in PrusaSlicer 2.5).
SUPPORT_FIRST_LAYER_EXPANSION = 3.0
#: A line the slicer lays around the parts (a skirt loop, the support's outer line) is at most
#: this many nozzle widths wide: PrusaSlicer 2.5's first layer is 0.42 mm for a 0.4 mm nozzle,
#: and the file leaves extrusion widths to the user.
LINE_WIDTH_FACTOR = 2.0

#: What the file never sets.
LEFT_TO_USER = ("printer and its profile", "bed shape and size", "nozzle diameter",
                "extrusion widths", "speeds (but the TPU volumetric limit)", "cooling",
                "retraction")

_WHY_MATERIAL = {
    ("hinges", "TPU"): "the hinges turn far: TPU takes the bending strain (limit {limit:g}) "
                       "where PLA (0.02) and PETG (0.03) hinges break",
    ("hinges", "PLA"): "the template asks for PLA: keep the hinge strain below {limit:g} (see "
                       "the hinge report)",
    ("hinges", "PETG"): "the template asks for PETG: keep the hinge strain below {limit:g} (see "
                        "the hinge report)",
    ("pins", "PLA"): "bars and pins are rigid and nothing bends: PLA is stiff, prints accurate "
                     "holes and pins, and is the easiest to print in place",
    ("pins", "PETG"): "the template asks for PETG: tougher pins than PLA, but it strings more, "
                      "which can bridge the clearances",
    ("pins", "TPU"): "the template asks for TPU: the bars will flex; PLA is the usual choice",
}


@dataclass(frozen=True)
class SlicerSettings:
    """Settings written into a 3MF, each with its reason.

    Attributes
    ----------
    material : str
    material_reason : str
    project : dict
        Key -> value for ``Metadata/Slic3r_PE.config``.
    per_object : dict
        Key -> value for every object in ``Metadata/Slic3r_PE_model.config``.
    reasons : dict
        Key -> why the design needs it.
    notes : tuple of str
        What was looked at and left alone.
    """

    material: str
    material_reason: str
    project: dict = field(default_factory=dict)
    per_object: dict = field(default_factory=dict)
    reasons: dict = field(default_factory=dict)
    notes: tuple = ()

    def as_dict(self) -> dict:
        return {"slicer": "PrusaSlicer (its 3MF metadata; tested with 2.5)",
                "material": self.material, "material_reason": self.material_reason,
                "per_object": dict(self.per_object), "project": dict(self.project),
                "reasons": dict(self.reasons), "notes": list(self.notes),
                "left_to_user": list(LEFT_TO_USER),
                "how_to_open": "PrusaSlicer's command line slices with both parts (its own "
                               "options win). In the window, 'Import geometry only' (Ctrl+I) "
                               "keeps your printer and filament and applies the per-object "
                               "settings; choose the material named here yourself. 'Open as "
                               "project' also loads the material, and fills every setting the "
                               "file leaves out (printer, bed, nozzle) with PrusaSlicer's "
                               "defaults: choose your printer again after opening."}


def slicer_settings(s) -> SlicerSettings:
    """The settings a print needs from the slicer (see the module docstring).

    Parameters
    ----------
    s : PrintSettings

    Returns
    -------
    SlicerSettings

    Examples
    --------
    >>> from fabkit.settings.printing import print_settings
    >>> ss = slicer_settings(print_settings({"material": "TPU"}))
    >>> ss.project["filament_type"], ss.per_object["layer_height"]
    ('FLEX', 0.2)
    """
    layer = float(s.layer_height)
    material = FILAMENTS[s.material]
    reasons = {
        "layer_height": f"every height of the print is a whole number of {layer:g} mm layers",
        "first_layer_height": "the first layer as tall as the others, so that the layer "
                              "boundaries fall where the design's heights change",
    }
    margin = s.printer_profile().margin
    project = {"layer_height": layer, "first_layer_height": layer, **material,
               "skirts": 1, "skirt_distance": SKIRT_DISTANCE, "skirt_height": 1,
               "brim_width": 0}
    reach = _reach({**project, "raft_first_layer_expansion": SUPPORT_FIRST_LAYER_EXPANSION},
                   s.nozzle_width, s.linkage == "pins")
    for key in material:
        reasons[key] = f"the material, {s.material}"
    reasons.update(
        skirts=f"one skirt loop, {SKIRT_DISTANCE:g} mm from the parts (and their support): the "
               f"parts stand {margin:g} mm plus what the slicer lays around them ({reach:g} mm"
               + (", the support's spread first layer included" if s.linkage == "pins" else "")
               + f") from the bed's edges, so that nothing is printed in the {margin:g} mm kept "
               "free along them",
        skirt_distance="see skirts", skirt_height="see skirts",
        brim_width="no brim: the parts are flat and wide on the bed, and a brim would take "
                   "the bed's margin")
    per_object = {"layer_height": layer, "brim_width": 0}
    notes = []
    if s.linkage == "pins":
        per_object.update(perimeters=4, support_material=1, support_material_buildplate_only=1,
                          raft_first_layer_expansion=SUPPORT_FIRST_LAYER_EXPANSION)
        reasons.update(
            perimeters=f"the {s.pin_diameter:g} mm pins print solid from perimeters alone (four "
                       "0.45 mm lines reach their centre), and the webs around the holes are "
                       "walls, not infill",
            support_material="bars of upper layers overhang the empty bed",
            support_material_buildplate_only="support only from the bed: support standing on a "
                                             "lower bar would fill the gap between the layers "
                                             "and fuse them; over a lower bar the upper bar "
                                             "bridges the layer gap",
            raft_first_layer_expansion=f"the support's first layer spreads "
                                       f"{SUPPORT_FIRST_LAYER_EXPANSION:g} mm (PrusaSlicer's "
                                       "default, for its grip on the bed), written so that the "
                                       "room the layout leaves for it is the room it takes")
    elif s.hinge_style == "neck" and s.hinge_width < 2.0 * s.nozzle_width:
        # measured in PrusaSlicer 2.5's G-code (0.4 mm nozzle): each 0.6 mm neck of the printed
        # chain is one 0.6 mm line along the hinge, with or without thin walls, and however
        # many perimeters; the filament then runs the length of the hinge, the strong way to
        # bend it. No setting is needed, so none is written.
        notes.append(f"each {s.hinge_width:g} mm hinge neck prints as one extrusion line along "
                     "the hinge (PrusaSlicer 2.5, 0.4 mm nozzle): the filament runs the length of "
                     "the hinge, the way it bends best; no perimeter setting changes that, so "
                     "none is written")
    # the G-code header lists the project's settings: what an object needs is written there too
    project.update(per_object)
    why = _WHY_MATERIAL[(s.linkage, s.material)].format(limit=s.strain_limit)
    return SlicerSettings(material=s.material, material_reason=why, project=project,
                          per_object=per_object, reasons=reasons, notes=tuple(notes))


def _reach(project: dict, nozzle: float, support: bool) -> float:
    """See :func:`slicer_reach`; ``project``: the slicer's own keys as the 3MF writes them (not
    fabkit's settings); ``support``: whether the print has support from the bed."""
    line = LINE_WIDTH_FACTOR * nozzle
    spread = float(project.get("raft_first_layer_expansion", 0.0)) + line if support else 0.0
    skirts = int(project.get("skirts", 0))
    skirt = (float(project.get("skirt_distance", 0.0)) + skirts * line) if skirts else 0.0
    return round(spread + float(project.get("brim_width", 0.0)) + skirt, 6)


def slicer_reach(settings: SlicerSettings, nozzle: float) -> float:
    """How far beyond the parts (mm) the slicer prints, as the written settings ask.

    The support's first layer (when there is support) spreads ``raft_first_layer_expansion``
    and one line past the parts; a brim adds ``brim_width`` around that; the skirt lies
    ``skirt_distance`` further out, ``skirts`` loops of one line each. A line is
    :data:`LINE_WIDTH_FACTOR` nozzle widths at most.

    Parameters
    ----------
    settings : SlicerSettings
        What the 3MF files tell the slicer (their project part, which the G-code applies).
    nozzle : float
        The nozzle's width (mm).

    Returns
    -------
    float

    Examples
    --------
    >>> from fabkit.settings.printing import print_settings
    >>> s = print_settings({"material": "TPU"})
    >>> slicer_reach(slicer_settings(s), s.nozzle_width)
    3.8
    """
    project = settings.project
    return _reach(project, nozzle, bool(int(project.get("support_material", 0))))


def placement_margin(s) -> float:
    """Distance (mm) the bed layout keeps the parts from the bed's edges: the printer's margin
    (:attr:`~fabkit.settings.printers.Printer.margin`) plus :func:`slicer_reach`, so that what
    the slicer prints around the parts stays out of the margin too.

    Parameters
    ----------
    s : PrintSettings
    """
    return s.printer_profile().margin + slicer_reach(slicer_settings(s), s.nozzle_width)
