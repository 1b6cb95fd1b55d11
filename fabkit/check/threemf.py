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

from pathlib import Path

import numpy as np

from ..errors import FabricationError
from ..io.formats import open_zip, parse_xml, read_zip_entry
from ..io.readback import ReadBack
from ..io.workload import MAX_BYTES
from ..settings.filaments import FILAMENTS
from . import read_set, require_checked, require_triangles
from .beds import bed_set
from .items import Check, check
from .stl import check_meshes, MAX_COORDINATE_MM

__all__ = ["FORMAT", "SUFFIXES", "check_file", "read_package"]

FORMAT = "3mf"
#: The sections of ``--set`` this check reads (any other has no effect on it).
READS = ("print",)
SUFFIXES = (".3mf",)

#: A layer height read back from the slicer settings within this of the template's is the
#: template's (mm): the writer prints them as short decimals, far coarser than this.
LAYER_MATCH_MM = 1e-9

_NS = {"m": "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"}
#: Most XML elements in a 3MF's model (or its slicer settings): the placed triangles its
#: check accepts (about 800 000 within the estimate) with their vertices come to about this.
MAX_3MF_ELEMENTS = 1_000_000
#: Units a 3MF may declare, in millimetres.
_UNITS = {"micron": 1e-3, "millimeter": 1.0, "centimeter": 10.0, "inch": 25.4, "foot": 304.8,
          "meter": 1000.0}


def _xml(data: bytes, path, part: str):
    """A part of the package parsed within the bounds of
    :func:`fabkit.io.formats.parse_xml` (no DTD or entity: a 3MF never needs one)."""
    return parse_xml(data, path, max_elements=MAX_3MF_ELEMENTS, what=f"a 3MF's {part}",
                     no_dtd=True)


def _parse_config(text: str) -> dict:
    """``; key = value`` lines of PrusaSlicer's project settings."""
    out = {}
    for line in text.splitlines():
        if line.startswith("; ") and " = " in line:
            key, value = line[2:].split(" = ", 1)
            out[key.strip()] = value.strip()
    return out


def _inflate(z, path, names) -> dict:
    """The XML parts ``names`` of the package, inflated, each held to the size the ZIP
    directory declares, which the caller has estimated
    (:func:`fabkit.io.formats.read_zip_entry`)."""
    return {n: read_zip_entry(z, n, path) for n in names}


def _numbers(values: list, path, where, *, integer: bool = False) -> np.ndarray:
    """Attribute texts as numbers: finite floats, or indices (whole numbers from 0 that fit
    an int64); FabricationError naming the first one that is not (``where(k)`` says where
    the k-th value is)."""
    def good(t) -> bool:
        if integer:
            # ASCII digits: "²" is a digit to str.isdigit, not to int
            return isinstance(t, str) and t.isascii() and t.isdigit() and len(t) < 19
        try:
            return bool(np.isfinite(float(t)))
        except (ValueError, TypeError, OverflowError):
            return False

    try:
        if integer:
            if all(map(good, values)):
                return np.array([int(t) for t in values], dtype=np.int64)
        else:
            arr = np.array(values, dtype=np.float64)
            if np.isfinite(arr).all():
                return arr
    except (ValueError, TypeError, OverflowError):
        pass
    k = next(k for k, t in enumerate(values) if not good(t))
    kind = "an index (a whole number from 0)" if integer else "a finite number"
    got = "is missing" if values[k] is None else f"got {values[k]!r}"
    raise FabricationError(f"{path}: {where(k)}: must be {kind}, {got}")


def _parse_package(path, data: bytes) -> dict:
    """The package's parts, parsed and checked, nothing placed yet: ``meshes`` (object id ->
    vertices mm, faces, name), ``items`` (object id, 12-number transform or None), ``xml``
    (the inflated parts by name), ``lower`` (lower-case name -> name), ``scale``."""
    z = open_zip(data, path, what="a 3MF package")
    infos = {i.filename: i for i in z.infolist()}
    model_name = next((n for n in infos if n.lower().startswith("3d/")
                       and n.lower().endswith(".model")), None)
    if model_name is None:
        raise FabricationError(f"{path}: holds no 3D model (3D/*.model)")
    lower = {n.lower(): n for n in infos}
    wanted = [model_name] + [lower[k] for k in ("metadata/slic3r_pe.config",
                                                "metadata/slic3r_pe_model.config") if k in lower]
    # a few kB of ZIP may inflate to gigabytes: the declared sizes are estimated first
    require_checked(f"{path}: inflated XML",
                    ("XML byte", sum(infos[n].file_size for n in wanted)))
    xml = _inflate(z, path, wanted)
    root = _xml(xml[model_name], path, model_name)
    unit = root.get("unit", "millimeter")
    if unit not in _UNITS:
        raise FabricationError(f"{path}: unknown unit {unit!r}")
    scale = _UNITS[unit]
    meshes = {}
    for obj in root.iterfind("m:resources/m:object", _NS):
        oid = obj.get("id")
        what = f"object {oid!r}"
        verts = obj.findall("m:mesh/m:vertices/m:vertex", _NS)
        tris = obj.findall("m:mesh/m:triangles/m:triangle", _NS)
        v = _numbers([e.get(a) for e in verts for a in "xyz"], path,
                     lambda k: f"{what} vertex {k // 3} {'xyz'[k % 3]}").reshape(-1, 3) * scale
        f = _numbers([e.get(a) for e in tris for a in ("v1", "v2", "v3")], path,
                     lambda k: f"{what} triangle {k // 3} v{k % 3 + 1}",
                     integer=True).reshape(-1, 3)
        if f.size and f.max() >= len(v):
            raise FabricationError(f"{path}: {what} has triangle indices out of range (up to "
                                   f"{int(f.max())}, {len(v)} vertices)")
        meshes[oid] = (v, f, obj.get("name", ""))
    items = []
    for k, item in enumerate(root.iterfind("m:build/m:item", _NS)):
        oid = item.get("objectid")
        if oid not in meshes:
            raise FabricationError(f"{path}: a build item names object {oid!r}, which is not there")
        t = item.get("transform")
        matrix = None
        if t is not None:
            words = t.split()
            if len(words) != 12:
                raise FabricationError(f"{path}: build item {k} transform of {len(words)} "
                                       "numbers, not 12")
            matrix = _numbers(words, path, lambda j: f"build item {k} transform[{j}]")
        items.append((oid, matrix))
    if not items:
        raise FabricationError(f"{path}: no build items")
    return {"meshes": meshes, "items": items, "xml": xml, "lower": lower, "scale": scale}


def _placed_triangles(parsed: dict) -> int:
    """Triangles once every build item has placed its object (one object, many items: many
    copies)."""
    return sum(len(parsed["meshes"][oid][1]) for oid, _ in parsed["items"])


def _place(path, parsed: dict) -> dict:
    """The parsed package as :func:`read_package` returns it: every build item placed."""
    import trimesh

    meshes, scale, lower, xml = parsed["meshes"], parsed["scale"], parsed["lower"], parsed["xml"]
    placed = []
    for k, (oid, matrix) in enumerate(parsed["items"]):
        v, f, _ = meshes[oid]
        if matrix is not None:
            with np.errstate(over="ignore", invalid="ignore"):
                v = v @ matrix[:9].reshape(3, 3) + matrix[9:] * scale  # rows act on rows
        if len(v) and not (np.isfinite(v).all() and np.abs(v).max() <= MAX_COORDINATE_MM):
            raise FabricationError(f"{path}: build item {k} places object {oid!r} beyond "
                                   f"{MAX_COORDINATE_MM:g} mm (a corrupt file)")
        # vertices merged, nothing mended (see fabkit.check.stl)
        placed.append(trimesh.Trimesh(v, f, process=True, validate=False))
    if not any(len(m.faces) for m in placed):
        raise FabricationError(f"{path}: holds no triangles")
    project, per_object = {}, []
    if "metadata/slic3r_pe.config" in lower:
        project = _parse_config(xml[lower["metadata/slic3r_pe.config"]].decode("utf-8",
                                                                                "replace"))
    parts = {}
    if "metadata/slic3r_pe_model.config" in lower:
        cfg = _xml(xml[lower["metadata/slic3r_pe_model.config"]], path, "model config")
        for obj in cfg.iterfind("object"):
            per_object.append({m.get("key"): m.get("value") for m in obj.iterfind("metadata")
                               if m.get("type") == "object" and m.get("key") != "name"})
            parts[obj.get("id")] = len(obj.findall("volume"))
    return {"mesh": trimesh.util.concatenate(placed),
            "objects": [{"name": nm, "parts": parts.get(oid, 1)}
                        for oid, (_, _, nm) in meshes.items()],
            "project": project, "per_object": per_object}


def read_package(path, data: bytes | None = None) -> dict:
    """A 3MF's placed meshes and PrusaSlicer settings.

    Sizes hidden in the package are estimated before the work they cause: the inflated XML
    before it is inflated, the placed triangles (each build item places its object's
    triangles once more) before any mesh is built.

    Parameters
    ----------
    path : path
    data : bytes, optional
        The file's bytes, when already read.

    Returns
    -------
    dict
        ``mesh`` (trimesh.Trimesh of every build item placed, mm), ``objects`` (name, number
        of parts), ``project`` (key -> value strings), ``per_object`` (list of key -> value
        dicts, one per object listed).

    Raises
    ------
    InputFileError
        ``kind="damaged"``: not a ZIP, an entry that cannot be inflated or lies about its
        size, malformed XML, a DTD; ``kind="bounds"``: too many ZIP entries, XML elements or
        too deep (:mod:`fabkit.io.formats`).
    FabricationError
        No model part, an unknown unit, a value that is not a number, indices out of range,
        vertices beyond any printer.
    BoundsError
        Inflated XML or placed triangles past the bounds.
    """
    path = Path(path)
    if data is None:  # a regular file, of bounded size, as every file a check reads
        data = ReadBack().read(path, MAX_BYTES)
    parsed = _parse_package(path, data)
    require_checked(f"{path}: {len(parsed['items'])} build items",
                    ("placed triangle", _placed_triangles(parsed)))
    return _place(path, parsed)


def _number(text):
    """A setting's value as a number, or None when it is not one."""
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def _settings_check(packages, names, design, settings) -> Check:
    """The slicer settings in every bed file give the print the design's template asks for:
    its layer height (the project's, its first layer's and every object's: every height of the
    print is a whole number of layers) and its material (PrusaSlicer's filament type for it).

    The values are compared as numbers with the template's print settings; what else the
    writer chose to tell the slicer (perimeters, supports, skirt) is its own business."""
    from ..settings.design import design_settings

    s = design_settings(design, settings).require("print")
    layer = float(s.layer_height)
    filament = FILAMENTS[s.material]["filament_type"]
    wrong = []

    def compare(where, got, key):
        value = _number(got)
        if value is None or abs(value - layer) > LAYER_MATCH_MM:
            wrong.append(f"{where} {key} = {got!r}, not the template's {layer:g} mm")

    for name, pkg in zip(names, packages):
        for key in ("layer_height", "first_layer_height"):
            compare(f"{name}: project", pkg["project"].get(key), key)
        if pkg["project"].get("filament_type") != filament:
            wrong.append(f"{name}: project filament_type = "
                         f"{pkg['project'].get('filament_type')!r}, not {filament!r} "
                         f"({s.material})")
        if not pkg["per_object"]:
            wrong.append(f"{name}: no per-object settings")
        for k, obj in enumerate(pkg["per_object"]):
            compare(f"{name}: object {k + 1}", obj.get("layer_height"), "layer_height")
    return check("slicer settings", not wrong, value=len(wrong), limit=0,
                 detail="; ".join(wrong[:3]) or
                 f"{s.material} ({filament}) and {layer:g} mm layers for the project and its "
                 f"first layer; {layer:g} mm layers for every object")


def check_file(path, design=None, settings=None, *, motion=None, folder=None) -> dict:
    """Read an exported 3MF back (with the other beds of its export) and check it.

    Parameters
    ----------
    path : str or pathlib.Path
    design : Design, optional
        Without it only the solid checks run.
    settings : dict, optional
        The command-line overrides used for the export.
    motion : TracedMotion, optional
        As for :func:`fabkit.check.stl.check_file`.
    folder : OutputFolder or ReadBack, optional
        As for :func:`fabkit.check.stl.check_file`.

    Returns
    -------
    dict
        As :func:`fabkit.check.stl.check_file`, with the ``slicer settings`` check.

    Raises
    ------
    InputFileError
        A file its readers refuse (see :func:`read_package`).
    FabricationError
        A file that is not a readable 3MF.
    """
    paths = bed_set(path, folder)
    parsed = {p: _parse_package(p, data) for p, data in read_set(paths, folder).items()}
    # every bed's build items place their objects: all of them counted before any is placed
    require_triangles(f"{path}: {sum(len(q['items']) for q in parsed.values())} build items",
                      sum(map(_placed_triangles, parsed.values())), design)
    packages = [_place(p, q) for p, q in parsed.items()]
    names = [p.name for p in paths]
    # a bed may hold only bars laid flat (one object, a part each): one multi-part object says it
    pinned = any(any(o["parts"] > 1 for o in pkg["objects"]) for pkg in packages)
    report = check_meshes([pkg["mesh"] for pkg in packages], names, design, settings,
                          fmt=FORMAT, pinned=pinned, motion=motion)
    if design is not None:
        report["checks"].append(_settings_check(packages, names, design, settings).as_dict())
        report["ok"] = bool(report["ok"] and report["checks"][-1]["ok"])
    report["slicer_settings"] = {"project": packages[0]["project"],
                                 "per_object": packages[0]["per_object"][:1]}
    return report
