"""As-built check of a printed network's 3MF beds: read back, placed, and checked as its STL is.

The package is read with the standard library (ZIP and XML, no DTDs): every object's mesh,
placed by its build item's transform (3MF matrices act on row vectors), in millimetres (the
model's unit is checked). The beds of one export (``NAME.3mf`` or ``NAME_bed<k>.3mf``) are then
checked exactly as the STL beds are (:func:`fabkit.check.stl.check_meshes`: a hinge print's
solid, rebuilt linkage and transition, or a print-in-place linkage's bodies, pins, clearances
and motion). With the design, the print settings the file carries for PrusaSlicer
(:mod:`fabkit.fab.slicer`) must be the ones the design needs: every key, with its value, in
the project part and in every object.
"""

from __future__ import annotations

import io
import zipfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..errors import FabricationError

__all__ = ["FORMAT", "SUFFIXES", "check_file", "read_package"]

FORMAT = "3mf"
SUFFIXES = (".3mf",)

_NS = {"m": "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"}
#: Units a 3MF may declare, in millimetres.
_UNITS = {"micron": 1e-3, "millimeter": 1.0, "centimeter": 10.0, "inch": 25.4, "foot": 304.8,
          "meter": 1000.0}


def _check(name, ok, value=None, limit=None, detail=""):
    return {"name": name, "ok": bool(ok), "value": value, "limit": limit, "detail": detail}


def _xml(data: bytes, what: str):
    if b"<!DOCTYPE" in data[:4096].upper() or b"<!ENTITY" in data.upper():
        raise FabricationError(f"{what}: declares a DTD or entities, which a 3MF never needs")
    try:
        return ET.fromstring(data)
    except ET.ParseError as exc:
        raise FabricationError(f"{what}: not well-formed XML ({exc})") from None


def _parse_config(text: str) -> dict:
    """``; key = value`` lines of PrusaSlicer's project settings."""
    out = {}
    for line in text.splitlines():
        if line.startswith("; ") and " = " in line:
            key, value = line[2:].split(" = ", 1)
            out[key.strip()] = value.strip()
    return out


def read_package(path) -> dict:
    """A 3MF's placed meshes and PrusaSlicer settings.

    Returns
    -------
    dict
        ``mesh`` (trimesh.Trimesh of every build item placed, mm), ``objects`` (name, number
        of parts), ``project`` (key -> value strings), ``per_object`` (list of key -> value
        dicts, one per object listed).

    Raises
    ------
    FabricationError
        Not a ZIP, no model part, malformed XML, an unknown unit, indices out of range.
    """
    import trimesh

    path = Path(path)
    try:
        z = zipfile.ZipFile(io.BytesIO(path.read_bytes()))
        names = z.namelist()
    except (OSError, zipfile.BadZipFile) as exc:
        raise FabricationError(f"{path}: not a 3MF package: {exc}") from None
    model_name = next((n for n in names if n.lower().startswith("3d/")
                       and n.lower().endswith(".model")), None)
    if model_name is None:
        raise FabricationError(f"{path}: holds no 3D model (3D/*.model)")
    root = _xml(z.read(model_name), f"{path}: {model_name}")
    unit = root.get("unit", "millimeter")
    if unit not in _UNITS:
        raise FabricationError(f"{path}: unknown unit {unit!r}")
    scale = _UNITS[unit]
    meshes = {}
    for obj in root.iterfind("m:resources/m:object", _NS):
        vs = [(float(v.get("x")), float(v.get("y")), float(v.get("z")))
              for v in obj.iterfind("m:mesh/m:vertices/m:vertex", _NS)]
        ts = [(int(t.get("v1")), int(t.get("v2")), int(t.get("v3")))
              for t in obj.iterfind("m:mesh/m:triangles/m:triangle", _NS)]
        v = np.asarray(vs, dtype=np.float64).reshape(-1, 3) * scale
        f = np.asarray(ts, dtype=np.int64).reshape(-1, 3)
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise FabricationError(f"{path}: object {obj.get('id')} has triangle indices out of "
                                   "range")
        if not np.isfinite(v).all():
            raise FabricationError(f"{path}: object {obj.get('id')} has vertices that are not "
                                   "finite")
        meshes[obj.get("id")] = (v, f, obj.get("name", ""))
    placed = []
    for item in root.iterfind("m:build/m:item", _NS):
        oid = item.get("objectid")
        if oid not in meshes:
            raise FabricationError(f"{path}: a build item names object {oid!r}, which is not there")
        v, f, _ = meshes[oid]
        t = item.get("transform")
        if t:
            vals = np.array([float(x) for x in t.split()])
            if vals.size != 12:
                raise FabricationError(f"{path}: build item transform of {vals.size} numbers, "
                                       "not 12")
            rot = vals[:9].reshape(3, 3)  # rows act on row vectors
            v = v @ rot + vals[9:] * scale
        placed.append(trimesh.Trimesh(v, f, process=True))
    if not placed:
        raise FabricationError(f"{path}: no build items")
    project, per_object = {}, []
    lower = {n.lower(): n for n in names}
    if "metadata/slic3r_pe.config" in lower:
        project = _parse_config(z.read(lower["metadata/slic3r_pe.config"]).decode("utf-8",
                                                                                 "replace"))
    parts = {}
    if "metadata/slic3r_pe_model.config" in lower:
        cfg = _xml(z.read(lower["metadata/slic3r_pe_model.config"]), f"{path}: model config")
        for obj in cfg.iterfind("object"):
            per_object.append({m.get("key"): m.get("value") for m in obj.iterfind("metadata")
                               if m.get("type") == "object" and m.get("key") != "name"})
            parts[obj.get("id")] = len(obj.findall("volume"))
    return {"mesh": trimesh.util.concatenate(placed),
            "objects": [{"name": nm, "parts": parts.get(oid, 1)}
                        for oid, (_, _, nm) in meshes.items()],
            "project": project, "per_object": per_object}


def _settings_check(packages, names, design, settings) -> dict:
    """The slicer settings in every bed file are those the design needs."""
    from ..fab.printing import design_print_settings
    from ..fab.slicer import slicer_settings
    from ..export.threemf import _value

    s = design_print_settings(design, settings)
    want = slicer_settings(s)
    wrong = []
    for name, pkg in zip(names, packages):
        for key, value in want.project.items():
            if pkg["project"].get(key) != _value(value):
                wrong.append(f"{name}: project {key} = {pkg['project'].get(key)!r}, not "
                             f"{_value(value)!r}")
        if not pkg["per_object"]:
            wrong.append(f"{name}: no per-object settings")
        for k, obj in enumerate(pkg["per_object"]):
            for key, value in want.per_object.items():
                if obj.get(key) != _value(value):
                    wrong.append(f"{name}: object {k + 1} {key} = {obj.get(key)!r}, not "
                                 f"{_value(value)!r}")
    extra = ", ".join(f"{k} = {_value(v)}" for k, v in want.per_object.items()
                      if k != "layer_height")
    return _check("slicer settings", not wrong, value=len(wrong), limit=0,
                  detail="; ".join(wrong[:3]) or
                  f"{want.material} ({want.project['filament_type']}) and "
                  f"{s.layer_height:g} mm layers for the project; {s.layer_height:g} mm layers"
                  f"{', ' + extra if extra else ''} for every object")


def check_file(path, design=None, settings=None) -> dict:
    """Read an exported 3MF back (with the other beds of its export) and check it.

    Parameters
    ----------
    path : str or pathlib.Path
    design : Design, optional
        Without it only the solid checks run.
    settings : dict, optional
        The command-line overrides used for the export.

    Returns
    -------
    dict
        As :func:`fabkit.check.stl.check_file`, with the ``slicer settings`` check.

    Raises
    ------
    FabricationError
        A file that is not a readable 3MF.
    """
    from .beds import bed_set
    from .stl import check_meshes

    paths = bed_set(path)
    packages = [read_package(p) for p in paths]
    names = [p.name for p in paths]
    pinned = all(any(o["parts"] > 1 for o in pkg["objects"]) for pkg in packages)
    report = check_meshes([pkg["mesh"] for pkg in packages], names, design, settings,
                          fmt=FORMAT, pinned=pinned)
    if design is not None:
        report["checks"].append(_settings_check(packages, names, design, settings))
        report["ok"] = all(c["ok"] for c in report["checks"])
    report["slicer_settings"] = {"project": packages[0]["project"],
                                 "per_object": packages[0]["per_object"][:1]}
    return report
