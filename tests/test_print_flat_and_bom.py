"""fourbar_chain's print, read back with trimesh (the STL directly, the 3MF's meshes parsed with
the standard library): bars that no printed pin joins lie flat on z = 0 side by side, every part
keeps the bed's margin plus the room the written slicer settings ask for (support's first
layer, brim, skirt), and a print bill of materials names the bolts with their lengths.
"""

from __future__ import annotations

import io
import json
import re
import shutil
import subprocess
import zipfile
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import shapely
import trimesh

import fabkit
from fabkit.check import check_file
from fabkit.writers import export

from conftest import TEMPLATES

NS = {"m": "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"}
#: float32 coordinates of a bed (mm).
FLOAT32_MM = 1e-4
SLICER = shutil.which("prusa-slicer")


@pytest.fixture(scope="module")
def fourbar(tmp_path_factory):
    design = fabkit.load_template(TEMPLATES / "fourbar_chain.toml")
    folder = tmp_path_factory.mktemp("fourbar_chain")
    paths, report = export(design, "stl", folder, print={"preview": False})
    return design, folder, sorted(paths), report


def _threemf_bodies(path) -> list:
    """The bodies of a 3MF bed (bed coordinates, mm): every object's mesh, placed by its build
    item, split into its shells by trimesh."""
    with zipfile.ZipFile(path) as z:
        root = ET.fromstring(z.read("3D/3dmodel.model"))
    assert root.get("unit") == "millimeter"
    meshes = {}
    for obj in root.iterfind(".//m:resources/m:object", NS):
        v = np.array([[float(p.get(k)) for k in "xyz"]
                      for p in obj.iterfind(".//m:vertex", NS)])
        f = np.array([[int(t.get(k)) for k in ("v1", "v2", "v3")]
                      for t in obj.iterfind(".//m:triangle", NS)])
        meshes[obj.get("id")] = (v, f)
    bodies = []
    for item in root.iterfind(".//m:build/m:item", NS):
        v, f = meshes[item.get("objectid")]
        if item.get("transform"):
            m = np.array([float(x) for x in item.get("transform").split()]).reshape(4, 3)
            v = v @ m[:3] + m[3]
        bodies += trimesh.Trimesh(v, f, process=True).split(only_watertight=False)
    return bodies


def _stl_bodies(path, report) -> list:
    """The bodies of an STL bed, moved from the bed's centre (where an STL is written) to the
    bed's corner."""
    w, d = report["printer"]["printer"]["bed_mm"]
    mesh = trimesh.load(path)
    mesh.apply_translation([0.5 * w, 0.5 * d, 0.0])
    return mesh.split(only_watertight=False)


def _beds(folder, report, suffix):
    names = [n for n in report["printer"]["files"] if n.endswith(suffix)]
    read = _stl_bodies if suffix == ".stl" else (lambda p, r: _threemf_bodies(p))
    return {int(re.search(r"bed(\d+)", n).group(1)): read(folder / n, report) for n in names}


@pytest.mark.parametrize("suffix", [".stl", ".3mf"])
def test_every_body_of_a_bed_without_printed_pins_lies_on_the_bed(fourbar, suffix):
    design, folder, _, report = fourbar
    s = report["settings"]
    pieces = report["printer"]["pieces"]
    no_pins = {b for b in range(1, report["printer"]["beds"] + 1)
               if all(p["flat"] for p in pieces if p["bed"] == b)}
    assert no_pins, "fourbar_chain has a bed of bars laid flat only"
    flat = set(report["printer"]["laid_flat"])
    assert flat == {4, 5, 6, 7, 8, 9, 10, 11}  # modules 2 and 3: every joint cut for a bolt
    beds = _beds(folder, report, suffix)
    on_floor = 0
    for bed, bodies in beds.items():
        for body in bodies:
            lo, hi = body.bounds[:, 2]
            alone = abs(lo) <= FLOAT32_MM and abs(hi - s["bar_thickness"]) <= FLOAT32_MM
            on_floor += alone
            if bed in no_pins:  # a bar alone: on z = 0, one bar thick
                assert alone, (suffix, bed, body.bounds)
    # every flat bar (and any stacked bar of a piece's lowest layer without a pin) on z = 0
    assert on_floor >= len(flat)
    # the whole print is still one body per bar
    assert sum(len(b) for b in beds.values()) == report["bars"]


def test_the_flat_bars_lie_side_by_side_and_the_stl_and_3mf_agree(fourbar):
    _, folder, _, report = fourbar
    stl, mf = _beds(folder, report, ".stl"), _beds(folder, report, ".3mf")
    assert sorted(stl) == sorted(mf)
    for bed in stl:
        a = sorted(np.round(b.bounds, 3).ravel().tolist() for b in stl[bed])
        b = sorted(np.round(b.bounds, 3).ravel().tolist() for b in mf[bed])
        assert np.allclose(a, b, atol=1e-3), bed
        # footprints on the bed (round-ended bars, with caps no wider than a bar: convex)
        feet = [shapely.MultiPoint(np.asarray(body.vertices)[:, :2]).convex_hull
                for body in mf[bed]]
        for i in range(len(feet)):
            for j in range(i + 1, len(feet)):
                # bodies of one stack overlap in plan (their pins pass through each other's
                # holes) only where they lie at different heights
                if mf[bed][i].bounds[0, 2] == mf[bed][j].bounds[0, 2] == 0.0:
                    assert feet[i].distance(feet[j]) > 1.0, (bed, i, j)


def _reach(project: dict, nozzle: float) -> float:
    """How far beyond the parts the slicer prints, read from a 3MF's project settings: the
    support's first layer spread (``raft_first_layer_expansion``, when there is support) and
    its outer line, the brim, the skirt's distance and its loops (a line at most two nozzle
    widths wide: PrusaSlicer's first layer is 0.42 mm for a 0.4 mm nozzle)."""
    line = 2.0 * nozzle
    support = int(project.get("support_material", "0")) == 1
    spread = float(project.get("raft_first_layer_expansion", "3")) + line if support else 0.0
    skirts = int(project.get("skirts", "1"))
    return (spread + float(project.get("brim_width", "0"))
            + (float(project.get("skirt_distance", "6")) + skirts * line if skirts else 0.0))


def _project(path) -> dict:
    with zipfile.ZipFile(path) as z:
        text = z.read("Metadata/Slic3r_PE.config").decode()
    return dict(re.findall(r"^; (\w+) = (.*)$", text, flags=re.M))


@pytest.mark.parametrize("name", ["fourbar_chain", "printed_planar"])
def test_parts_leave_room_for_what_the_written_slicer_settings_add(fourbar, name,
                                                                     tmp_path_factory):
    """Every part stands the bed's margin plus the slicer's reach (from the 3MF's own settings)
    from every edge of the bed, in the STL and in the 3MF."""
    if name == "fourbar_chain":
        _, folder, _, report = fourbar
    else:
        design = fabkit.load_template(TEMPLATES / f"{name}.toml")
        folder = tmp_path_factory.mktemp(name)
        _, report = export(design, "stl", folder, print={"preview": False})
    printer = report["printer"]["printer"]
    w, d = printer["bed_mm"]
    margin = printer["margin_mm"]
    assert margin == 10.0
    nozzle = report["settings"]["nozzle_width"]
    for suffix in (".stl", ".3mf"):
        names = [n for n in report["printer"]["files"] if n.endswith(suffix)]
        assert names
        for n in names:
            mf = folder / (n[:-4] + ".3mf")
            need = margin + _reach(_project(mf), nozzle)
            if report.get("linkage") == "pins":  # support, spread 3 mm, and the skirt around
                assert need >= margin + 7.0
            bodies = (_stl_bodies(folder / n, report) if suffix == ".stl"
                      else _threemf_bodies(folder / n))
            lo = np.min([b.bounds[0, :2] for b in bodies], axis=0)
            hi = np.max([b.bounds[1, :2] for b in bodies], axis=0)
            assert (lo >= need - FLOAT32_MM).all(), (n, lo, need)
            assert (hi <= np.array([w, d]) - need + FLOAT32_MM).all(), (n, hi, need)


def _extrusion_extent(text: str):
    """Smallest and largest x and y of the moves that extrude (E grows), absolute (G90, M83
    relative E as PrusaSlicer writes it)."""
    x = y = None
    xs, ys = [], []
    for line in text.splitlines():
        if not line.startswith("G1 "):
            continue
        mx = re.search(r"\bX(-?[\d.]+)", line)
        my = re.search(r"\bY(-?[\d.]+)", line)
        me = re.search(r"\bE(-?[\d.]+)", line)
        if mx:
            x = float(mx.group(1))
        if my:
            y = float(my.group(1))
        if (mx or my) and me and float(me.group(1)) > 0 and x is not None and y is not None:
            xs.append(x)
            ys.append(y)
    return min(xs), max(xs), min(ys), max(ys)


@pytest.mark.skipif(SLICER is None, reason="prusa-slicer is not installed (.ci/install.d/"
                                           "prusa-slicer.sh installs it)")
def test_the_slicer_prints_nothing_in_the_bed_margin(fourbar, tmp_path):
    """PrusaSlicer slices every 3MF bed (support, skirt and all) on its bed: every extruding
    move stays out of the 10 mm margin."""
    _, folder, _, report = fourbar
    w, d = report["printer"]["printer"]["bed_mm"]
    margin = report["printer"]["printer"]["margin_mm"]
    for n in (n for n in report["printer"]["files"] if n.endswith(".3mf")):
        gcode = tmp_path / f"{n}.gcode"
        proc = subprocess.run([SLICER, "--export-gcode", "--bed-shape",
                               f"0x0,{w:g}x0,{w:g}x{d:g},0x{d:g}", "--output", str(gcode),
                               str(folder / n)], capture_output=True, text=True, timeout=120,
                              cwd=tmp_path)
        out = proc.stdout + proc.stderr
        assert "Slicing result exported" in out, out
        text = gcode.read_text()
        assert ";TYPE:Skirt" in text
        bed = int(re.search(r"bed(\d+)", n).group(1))
        if all(p["flat"] for p in report["printer"]["pieces"] if p["bed"] == bed):
            # bars lying flat: nothing overhangs, no layer is empty
            assert ";TYPE:Support material" not in text and "empty layer" not in out.lower()
        else:
            assert ";TYPE:Support material" in text
        x0, x1, y0, y1 = _extrusion_extent(text)
        assert min(x0, y0) >= margin and x1 <= w - margin and y1 <= d - margin, \
            (n, x0, x1, y0, y1)


def test_the_print_has_a_bill_of_materials_naming_its_bolts(fourbar):
    _, folder, paths, report = fourbar
    assert {"print_bom.json", "print_bom.md"} <= {p.name for p in paths}
    bom = json.loads((folder / "print_bom.json").read_text())
    assert bom["bed_count"] == report["printer"]["beds"] == len(bom["beds"])
    assert bom["bolts"] == 6 and bom["bolt_sizes"] == ["M3 x 16 mm"]
    buy = {b["standard"]: b for b in bom["buy"]}
    assert (buy["ISO 4762"]["count"], buy["ISO 7089"]["count"], buy["ISO 10511"]["count"]) == \
        (6, 12, 6)
    # every bar on exactly one bed; the flat ones said to be flat
    bars = [k for b in bom["beds"] for part in b["parts"] for k in part["bars"]]
    assert sorted(bars) == list(range(report["bars"]))
    assert sorted(k for b in bom["beds"] for part in b["parts"] if part["flat"]
                  for k in part["bars"]) == report["printer"]["laid_flat"]
    # the filament: the parts' solid volume in PLA
    assert bom["filament"]["volume_mm3"] == pytest.approx(report["volume_mm3"], abs=1e-2)
    assert bom["filament"]["grams"] == pytest.approx(report["volume_mm3"] * 1.24e-3, abs=0.01)
    md = (folder / "print_bom.md").read_text()
    assert "M3 x 16" in md and "ISO 4762" in md and "bolt" in md.lower()
    for b in bom["beds"]:
        assert all(f in md for f in b["files"])
    assert {j["joint"] for j in bom["joints"]} == set(report["cut_joints"])


def test_the_command_writes_the_print_bom_beside_the_print(tmp_path):
    from fabkit.cli import main

    code = main(["export", "fourbar_chain", "--to", "stl", "-o", str(tmp_path),
                 "--tolerance-samples", "0"])
    assert code == 0
    folder = tmp_path / "fourbar_chain"
    md = (folder / "print_bom.md").read_text()
    assert re.search(r"6 x M3 x 16\b", md)
    assert "print_bom.md" in (folder / "report.md").read_text()
    assert "print_bom.json" in json.loads((folder / "exports.json").read_text())[
        "formats"]["stl"]["files"]


def test_a_hinge_print_has_a_bill_of_materials_with_nothing_to_buy(tmp_path):
    design = fabkit.load_template(TEMPLATES / "printed_planar.toml")
    _, report = export(design, "stl", tmp_path, print={"preview": False})
    bom = json.loads((tmp_path / "print_bom.json").read_text())
    assert bom["buy"] == [] and bom["bolts"] == 0 and bom["bed_count"] == 1
    assert bom["filament"]["volume_mm3"] == pytest.approx(report["volume_mm3"], abs=1e-2)
    assert "Nothing: every joint is printed." in (tmp_path / "print_bom.md").read_text()


@pytest.mark.parametrize("suffix", [".stl", ".3mf"])
def test_a_flat_bar_lifted_or_stretched_fails_the_check(fourbar, tmp_path, suffix):
    """The as-built check reads the flat bars as bars on layer 0: one lifted half a layer off
    the bed is off every layer, one stretched by 0.5 mm is no bar of the design."""
    design, folder, _, report = fourbar
    assert check_file(folder / f"fourbar_chain_bed3{suffix}", design=design)["ok"]
    for damage, failing in (("lift", {"bars read back"}),
                            ("stretch", {"rebuilt joints match the design", "lengths"})):
        out = tmp_path / damage
        out.mkdir()
        for p in folder.iterdir():
            if p.suffix == suffix:
                shutil.copy(p, out / p.name)
        _damage_bed3(out / f"fourbar_chain_bed3{suffix}", damage, report)
        r = check_file(out / f"fourbar_chain_bed3{suffix}", design=design)
        failed = [c["name"] for c in r["checks"] if not c["ok"]]
        # the stacked pieces still found in the design: the flat bar is what fails
        assert not r["ok"] and failed[0] in failing, (damage, failed)


def _damage_bed3(path, damage: str, report) -> None:
    """Lift bed 3's lower flat bar by half a layer pitch, or move its +x end 0.5 mm further
    out (the bed's two bars lie along x, one above the other)."""
    def change(v):
        v = v.copy()
        lower = v[:, 1] < v[:, 1].min() + report["settings"]["bar_width"] + 1.0
        if damage == "lift":
            v[lower, 2] += 1.4
        else:
            xs = v[lower, 0]
            v[lower & (v[:, 0] > xs.min() + 0.5 * np.ptp(xs)), 0] += 0.5
        return v

    if path.suffix == ".stl":  # the records rewritten, the header (a print-in-place's) kept
        data = bytearray(path.read_bytes())
        rec = np.dtype([("n", "<f4", (3,)), ("v", "<f4", (3, 3)), ("a", "<u2")])
        tri = np.frombuffer(bytes(data[84:]), dtype=rec).copy()
        tri["v"] = change(tri["v"].reshape(-1, 3).astype(np.float64)).reshape(-1, 3, 3)
        path.write_bytes(bytes(data[:84]) + tri.tobytes())
        return
    buf = io.BytesIO()
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "3D/3dmodel.model":
                data = _damage_model(data, change)
            z.writestr(info, data)
    path.write_bytes(buf.getvalue())


def _damage_model(data: bytes, change) -> bytes:
    ET.register_namespace("", NS["m"])
    root = ET.fromstring(data)
    vs = list(root.iterfind(".//m:vertex", NS))
    v = np.array([[float(p.get(k)) for k in "xyz"] for p in vs])
    v2 = change(v)
    for p, row in zip(vs, v2):
        for k, val in zip("xyz", row):
            p.set(k, f"{val:.9g}")
    return ET.tostring(root, xml_declaration=True, encoding="utf-8")
