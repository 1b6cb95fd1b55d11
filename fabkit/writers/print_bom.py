"""The print's bill of materials: ``print_bom.json`` and ``print_bom.md`` beside every print.

What a maker needs at the printer and at the bench, in one place (as ``laser_bom.md`` is for a
laser kit): the printer, bed and material; every bed with its files and the parts on it (stacks
of bars on printed pins, bars laid flat, hinged pieces); the filament each bed takes; and every
part that is not printed — bolts with their lengths (``M3 x 16``), washers, lock nuts — in all
and joint by joint.

The filament estimate is the parts' solid volume (the exact volume of the bodies written) as
1.75 mm filament of the material's density: the parts are a few millimetres thick and print
almost solid with the 3MF's perimeters; the slicer's support, skirt and infill pattern are not
counted (a slicer's own estimate is the one to trust for a spool that is nearly empty).

Pure: :func:`print_bom_files` returns bytes.
"""

from __future__ import annotations

import json
import math

__all__ = ["FILAMENT_DIAMETER_MM", "DENSITY_G_CM3", "filament", "print_bom_document",
           "print_bom_markdown", "print_bom_files", "BOM_FILES"]

#: The files this module writes.
BOM_FILES = ("print_bom.json", "print_bom.md")
#: Filament diameter the estimate is given for (mm): the common one.
FILAMENT_DIAMETER_MM = 1.75
#: Density of each material (g/cm^3), as filament makers state it.
DENSITY_G_CM3 = {"PLA": 1.24, "PETG": 1.27, "TPU": 1.21}


def filament(volume_mm3: float, material: str) -> dict:
    """The filament a solid volume takes: grams and metres of 1.75 mm filament.

    Examples
    --------
    >>> filament(1000.0, "PLA")["grams"]
    1.24
    """
    area = math.pi * (0.5 * FILAMENT_DIAMETER_MM) ** 2
    return {"volume_mm3": round(float(volume_mm3), 3),
            "grams": round(float(volume_mm3) * 1e-3 * DENSITY_G_CM3[material], 2),
            "metres": round(float(volume_mm3) / area * 1e-3, 3)}


def print_bom_document(design: str, kind: str, settings, printer: dict, beds: list[dict],
                       buy: list[dict], joints: list[dict], notes: list[str]) -> dict:
    """The print's bill of materials as data (``print_bom.json``).

    Parameters
    ----------
    design : str
        The design's name.
    kind : str
        What is printed (``"print-in-place bar linkage"``, ``"triangle-hinge solid"``).
    settings : PrintSettings
    printer : dict
        ``name``, ``bed_mm``, ``margin_mm``, ``parts_margin_mm``.
    beds : list of dict
        Per bed: ``bed`` (from 1), ``files``, ``parts`` (list of dict with a ``text``),
        ``volume_mm3``.
    buy : list of dict
        Parts not printed: ``part``, ``standard``, ``size``, ``count``.
    joints : list of dict
        Per bolted joint: ``joint``, ``bars`` (bottom first), ``parts`` (as in ``buy``).
    notes : list of str

    Returns
    -------
    dict
    """
    material = settings.material
    out_beds = [{**b, "filament": filament(b["volume_mm3"], material)} for b in beds]
    total = sum(b["volume_mm3"] for b in beds)
    bolts = [b for b in buy if b["standard"] == "ISO 4762"]
    return {
        "design": design, "kind": kind, "material": material,
        "layer_height_mm": float(settings.layer_height), "printer": printer,
        "beds": out_beds, "bed_count": len(out_beds),
        "filament": {**filament(total, material), "diameter_mm": FILAMENT_DIAMETER_MM,
                     "density_g_cm3": DENSITY_G_CM3[material],
                     "note": "solid volume of the parts; support, skirt and infill pattern not "
                             "counted (the slicer's estimate is the one to trust)"},
        "buy": buy, "bolts": sum(b["count"] for b in bolts),
        "bolt_sizes": sorted({b["size"] for b in bolts}),
        "joints": joints, "notes": notes,
        "files": list(BOM_FILES)}


def _table(header, rows) -> str:
    return "\n".join(["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
                     + ["| " + " | ".join(str(c) for c in r) + " |" for r in rows])


def print_bom_markdown(doc: dict) -> str:
    """The bill of materials as Markdown for a person at the printer and the bench."""
    p, f = doc["printer"], doc["filament"]
    bolts = ", ".join(f"{b['count']} x {b['size'].replace(' mm', '')}" for b in doc["buy"]
                      if b["standard"] == "ISO 4762")
    out = [f"# Print bill of materials: {doc['design']}",
           f"**{doc['kind']}: {doc['bed_count']} bed(s) of {p['bed_mm'][0]:g} x "
           f"{p['bed_mm'][1]:g} mm ({p['name']}), {doc['material']}, "
           f"{doc['layer_height_mm']:g} mm layers; about {f['grams']:g} g "
           f"({f['metres']:g} m of {f['diameter_mm']:g} mm filament)"
           + (f"; to buy: bolts {bolts}" if bolts else "; nothing to buy") + ".**",
           f"Print the 3MF files (they carry the slicer settings); every part stands at least "
           f"{p['parts_margin_mm']:g} mm from the bed's edges, so that the skirt and support "
           f"stay out of the {p['margin_mm']:g} mm kept free along them.",
           "## Beds",
           _table(["bed", "files", "parts", "filament"],
                  [[b["bed"], ", ".join(b["files"]), len(b["parts"]),
                    f"{b['filament']['grams']:g} g, {b['filament']['metres']:g} m"]
                   for b in doc["beds"]]),
           "## Parts per bed"]
    for b in doc["beds"]:
        out.append(f"**Bed {b['bed']}** ({', '.join(b['files'])})")
        out.append("\n".join(f"- {part['text']}" for part in b["parts"]))
    out.append("## To buy (not printed)")
    if doc["buy"]:
        out.append(_table(["part", "standard", "size", "count"],
                          [[b["part"], b["standard"], b["size"], b["count"]]
                           for b in doc["buy"]]))
    else:
        out.append("Nothing: every joint is printed.")
    if doc["joints"]:
        out.append("## Bolted joints")
        out.append(_table(["joint", "bars, bottom first", "their layers",
                           "layers without a bar (washers)", "bolt", "washers in all", "nut"],
                          [[j["joint"], ", ".join(str(b) for b in j["bars"]),
                            ", ".join(str(v) for v in j["layers"]),
                            ", ".join(str(v) for v in j["empty_layers"]) or "none",
                            _named(j, "ISO 4762"), _count(j, "ISO 7089"),
                            _count(j, "ISO 10511")] for j in doc["joints"]]))
    out.append("## Filament")
    out.append(f"{f['volume_mm3']:g} mm³ of {doc['material']} ({f['density_g_cm3']:g} g/cm³): "
               f"{f['grams']:g} g, {f['metres']:g} m of {f['diameter_mm']:g} mm filament; "
               f"{f['note']}.")
    if doc["notes"]:
        out.append("## Notes")
        out.append("\n".join(f"- {n}" for n in doc["notes"]))
    return "\n\n".join(out) + "\n"


def _named(joint: dict, standard: str) -> str:
    return ", ".join(p["size"] for p in joint["parts"] if p["standard"] == standard)


def _count(joint: dict, standard: str) -> int:
    return sum(p["count"] for p in joint["parts"] if p["standard"] == standard)


def print_bom_files(doc: dict) -> dict[str, bytes]:
    """``print_bom.json`` and ``print_bom.md`` of a bill of materials
    (:func:`print_bom_document`)."""
    return {"print_bom.json": (json.dumps(doc, indent=2, sort_keys=True) + "\n").encode("utf-8"),
            "print_bom.md": print_bom_markdown(doc).encode("utf-8")}
