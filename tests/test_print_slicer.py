"""A real slicer reads fabkit's printed networks: PrusaSlicer's command line (Debian package):
triangle-hinge solids and print-in-place linkages, on its default profile, with the settings
their 3MF files carry.

PrusaSlicer exits with 0 for a mesh with holes (and slices it), so its output is parsed: ``--info``
must report a manifold mesh in one part with the analytic volume, and ``--export-gcode`` must end
with "Slicing result exported" and no error, leaving G-code with one layer per 0.2 mm.
Skips (with the reason) when prusa-slicer is not installed (.ci/install.d/prusa-slicer.sh).
"""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest

import fabkit
from fabkit.writers import export

from conftest import TEMPLATES

SLICER = shutil.which("prusa-slicer")
pytestmark = pytest.mark.skipif(
    SLICER is None,
    reason="prusa-slicer is not installed (.ci/install.d/prusa-slicer.sh installs it)")

# a 250 x 210 mm bed (the default 200 x 200 bed is too short for the 10-module chain)
BED = ["--bed-shape", "0x0,250x0,250x210,0x210"]


def _run(args, tmp_path):
    proc = subprocess.run([SLICER, *args], capture_output=True, text=True, timeout=120,
                          cwd=tmp_path)
    out = proc.stdout + proc.stderr
    return proc.returncode, "\n".join(line for line in out.splitlines()
                                      if not line.startswith("["))  # drop its trace lines


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    out = {}
    for name in ("printed_planar", "printed_planar_chain10"):
        design = fabkit.load_template(TEMPLATES / f"{name}.toml")
        folder = tmp_path_factory.mktemp(name)
        _, report = export(design, "stl", folder, print={"preview": False})
        out[name] = (folder, report)
    return out


@pytest.mark.parametrize("suffix", [".stl", ".3mf"])
@pytest.mark.parametrize("name", ["printed_planar", "printed_planar_chain10"])
def test_info_reads_one_manifold_part(files, name, suffix, tmp_path):
    folder, report = files[name]
    code, out = _run(["--info", str(folder / f"{name}{suffix}")], tmp_path)
    assert "No such file" not in out and "error" not in out.lower(), out
    fields = dict(re.findall(r"^(\w+) = +(.+)$", out, flags=re.M))
    assert fields["manifold"] == "yes"
    assert int(fields["number_of_parts"]) == 1
    assert int(fields["number_of_facets"]) == report["mesh"]["triangles"]
    assert float(fields["volume"]) == pytest.approx(report["volume_mm3"], rel=1e-5)
    assert float(fields["size_z"]) == pytest.approx(3.0, abs=1e-5)


@pytest.mark.parametrize("name", ["printed_planar", "printed_planar_chain10"])
def test_slices_to_gcode(files, name, tmp_path):
    folder, _ = files[name]
    gcode = tmp_path / f"{name}.gcode"
    code, out = _run(["--export-gcode", *BED, "--layer-height", "0.2", "--first-layer-height",
                      "0.2", "--output", str(gcode), str(folder / f"{name}.stl")], tmp_path)
    assert code == 0, out
    assert "Slicing result exported" in out, out
    assert not re.search(r"error|could not|terminate", out, flags=re.I), out
    text = gcode.read_text()
    assert text.count(";LAYER_CHANGE") == 15  # 3 mm of plates in 0.2 mm layers


def test_output_is_parsed_because_the_exit_code_says_nothing(files, tmp_path):
    import trimesh

    folder, _ = files["printed_planar"]
    mesh = trimesh.load(folder / "printed_planar.stl")
    broken = tmp_path / "open.stl"
    trimesh.Trimesh(mesh.vertices, mesh.faces[:-3], process=False).export(broken)
    code, out = _run(["--info", str(broken)], tmp_path)
    assert code == 0  # a mesh with holes is "fine" by the exit code ...
    assert re.search(r"^manifold = no$", out, flags=re.M)  # ... but not by the output
    assert int(re.search(r"^open_edges = (\d+)$", out, flags=re.M).group(1)) > 0


def _gcode_config(text: str) -> dict:
    """The settings PrusaSlicer lists at the end of its G-code (``; key = value``)."""
    return dict(re.findall(r"^; (\w+) = (.*)$", text, flags=re.M))


def test_the_chain_slices_on_the_default_profile_from_both_files(files, tmp_path):
    # no printer options: PrusaSlicer's own default profile and its 200 x 200 mm bed
    folder, report = files["printed_planar_chain10"]
    assert report["printer"]["printer"]["bed_mm"] == [200.0, 200.0]
    assert not report["printer"]["fits_as_designed"]  # 207 mm long as designed ...
    for suffix in (".stl", ".3mf"):  # ... turned by 38 degrees in both files, it fits
        gcode = tmp_path / f"chain{suffix}.gcode"
        code, out = _run(["--export-gcode", "--output", str(gcode),
                          str(folder / f"printed_planar_chain10{suffix}")], tmp_path)
        assert code == 0 and "Slicing result exported" in out, out
        assert not re.search(r"error|could not|terminate", out, flags=re.I), out
        assert "; bed_shape = 0x0,200x0,200x200,0x200" in gcode.read_text()


def test_the_chain_prints_in_its_own_material_and_layers(files, tmp_path):
    # the 3MF alone, sliced with no option, prints in TPU ("FLEX") at 0.2 mm layers; the bare
    # STL on the same default profile in PLA at 0.3 mm (what the 3MF's settings replace)
    folder, report = files["printed_planar_chain10"]
    found = {}
    for suffix in (".3mf", ".stl"):
        gcode = tmp_path / f"chain{suffix}.gcode"
        code, out = _run(["--export-gcode", "--output", str(gcode),
                          str(folder / f"printed_planar_chain10{suffix}")], tmp_path)
        assert code == 0, out
        text = gcode.read_text()
        found[suffix] = (_gcode_config(text), [float(z) for z in
                                               re.findall(r"^;Z:([\d.]+)$", text, flags=re.M)])
    cfg, z = found[".3mf"]
    assert cfg["filament_type"] == "FLEX"
    assert cfg["layer_height"] == "0.2" and cfg["first_layer_height"] == "0.2"
    assert (cfg["temperature"], cfg["bed_temperature"]) == ("230", "50")
    assert cfg["filament_max_volumetric_speed"] == "3"
    assert np.allclose(z, 0.2 * np.arange(1, 16))  # 3 mm of plates in fifteen 0.2 mm layers
    # the file leaves the printer alone: PrusaSlicer's own bed and nozzle
    assert cfg["bed_shape"] == "0x0,200x0,200x200,0x200" and cfg["nozzle_diameter"] == "0.4"
    cfg, z = found[".stl"]
    assert (cfg["filament_type"], cfg["layer_height"]) == ("PLA", "0.3")
    assert report["slicer"]["project"]["filament_type"] == "FLEX"


@pytest.fixture(scope="module")
def pinned(tmp_path_factory):
    out = {}
    for name in ("super_stable", "fourbar_chain"):
        design = fabkit.load_template(TEMPLATES / f"{name}.toml")
        folder = tmp_path_factory.mktemp(name)
        paths, report = export(design, "stl", folder, print={"preview": False})
        out[name] = (folder, sorted(paths), report)
    return out


@pytest.mark.parametrize("name", ["super_stable", "fourbar_chain"])
def test_print_in_place_linkages_slice_on_the_default_profile(pinned, name, tmp_path):
    folder, paths, report = pinned[name]
    for path in (p for p in paths if p.suffix in (".stl", ".3mf")):
        bars = sum(len(p["bars"]) for p in report["printer"]["pieces"]
                   if path.stem.endswith(f"bed{p['bed']}") or report["printer"]["beds"] == 1)
        code, out = _run(["--info", str(path)], tmp_path)
        # one block per object (a 3MF bed: each stacked piece, and its bars laid flat)
        assert set(re.findall(r"^manifold = +(.+)$", out, flags=re.M)) == {"yes"}, out
        parts = re.findall(r"^number_of_parts = +(\d+)$", out, flags=re.M)
        assert sum(map(int, parts)) == bars  # one body per bar, nothing fused
        gcode = tmp_path / f"{path.name}.gcode"
        code, out = _run(["--export-gcode", "--output", str(gcode), str(path)], tmp_path)
        assert code == 0 and "Slicing result exported" in out, out
        assert not re.search(r"error|could not|terminate", out, flags=re.I), out


def test_print_in_place_settings_reach_the_gcode(pinned, tmp_path):
    folder, _, report = pinned["super_stable"]
    gcode = tmp_path / "ss.gcode"
    code, out = _run(["--export-gcode", "--output", str(gcode), str(folder / "super_stable.3mf")],
                     tmp_path)
    assert code == 0, out
    text = gcode.read_text()
    cfg = _gcode_config(text)
    assert (cfg["filament_type"], cfg["layer_height"]) == ("PLA", "0.2")
    # per object: supports from the bed under the upper layers' bars
    assert ";TYPE:Support material" in text
    heights = report["height_mm"]
    z = [float(v) for v in re.findall(r"^;Z:([\d.]+)$", text, flags=re.M)]
    assert max(z) == pytest.approx(heights, abs=1e-6)


def test_split_pieces_slice_on_a_small_bed(tmp_path):
    design = fabkit.load_template(TEMPLATES / "printed_planar_chain10.toml")
    _, report = export(design, "stl", tmp_path,
                       print={"preview": False, "printer": "mini", "scale": 8.0})
    beds = report["printer"]["files"]
    assert len(report["printer"]["pieces"]) >= 2 and report["printer"]["join"]
    for name in beds:
        code, out = _run(["--export-gcode", "--bed-shape", "0x0,180x0,180x180,0x180",
                          "--output", str(tmp_path / f"{name}.gcode"), str(tmp_path / name)],
                         tmp_path)
        assert code == 0 and "Slicing result exported" in out, out


# -- every move on the bed ---------------------------------------------------------------------

def _moves_off_bed(text: str, width: float, depth: float) -> tuple:
    """(extent of every G0/G1 move in x and y, moves outside the bed): absolute moves (G90),
    the extruder's position followed through moves that give x or y alone."""
    x = y = None
    xs, ys, off = [], [], []
    for line in text.splitlines():
        if not line.startswith(("G0 ", "G1 ")):
            continue
        mx = re.search(r"\bX(-?[\d.]+)", line)
        my = re.search(r"\bY(-?[\d.]+)", line)
        if mx:
            x = float(mx.group(1))
        if my:
            y = float(my.group(1))
        if (mx or my) and x is not None and y is not None:
            xs.append(x)
            ys.append(y)
            if not (0.0 <= x <= width and 0.0 <= y <= depth):
                off.append(line)
    return (min(xs), max(xs), min(ys), max(ys)), off


def _slice_on_its_bed(path, report, tmp_path):
    bed = report["printer"]["printer"]["bed_mm"]
    w, d = bed
    gcode = tmp_path / f"{path.name}.gcode"
    code, out = _run(["--export-gcode", "--bed-shape", f"0x0,{w:g}x0,{w:g}x{d:g},0x{d:g}",
                      "--output", str(gcode), str(path)], tmp_path)
    assert code == 0 and "Slicing result exported" in out, out
    text = gcode.read_text()
    extent, off = _moves_off_bed(text, w, d)
    assert not off, (path.name, extent, off[:3])
    margin = report["printer"]["printer"]["margin_mm"]
    return text, extent, margin


@pytest.mark.parametrize("name", ["printed_planar_chain10", "fourbar_chain"])
def test_every_move_of_a_print_lies_on_the_bed(name, tmp_path_factory):
    """The skirt, the support and every part of both files stay on the bed: parts keep the
    printer's margin (10 mm) and the 3MF asks for a skirt 3 mm out, no brim; the bare STL's
    default skirt (6 mm out) stays inside the margin too. The G-code header shows the settings
    the 3MF applied (perimeters, support), not the defaults."""
    design = fabkit.load_template(TEMPLATES / f"{name}.toml")
    folder = tmp_path_factory.mktemp(name)
    paths, report = export(design, "stl", folder, print={"preview": False})
    tmp = tmp_path_factory.mktemp(f"{name}_gcode")
    assert report["printer"]["printer"]["margin_mm"] == 10.0
    for path in paths:
        if path.suffix not in (".stl", ".3mf"):
            continue
        text, (x0, x1, y0, y1), margin = _slice_on_its_bed(path, report, tmp)
        if path.suffix == ".3mf":
            cfg = _gcode_config(text)
            assert (cfg["skirts"], cfg["skirt_distance"], cfg["brim_width"]) == ("1", "3", "0")
            if report.get("linkage") == "pins":
                assert (cfg["perimeters"], cfg["support_material"]) == ("4", "1")
                assert cfg["support_material_buildplate_only"] == "1"
    if report.get("linkage") == "pins":
        assert "geometry only: use the 3MF" in report["printer"]["stl"]


@pytest.mark.slow
def test_every_bundled_print_slices_with_every_move_on_the_bed(tmp_path_factory):
    """Every bundled design that exports a print (STL and 3MF beds, on its printer's bed)."""
    from fabkit.errors import FabricationError
    from fabkit.templates import bundled_names

    sliced = 0
    for name in bundled_names():
        design = fabkit.load_template(name)
        if "stl" in (design.fabrication.get("skip") or {}):
            continue
        folder = tmp_path_factory.mktemp(name)
        try:
            paths, report = export(design, "stl", folder, print={"preview": False})
        except FabricationError:
            continue  # a design that is not printable says so elsewhere
        for path in paths:
            if path.suffix in (".stl", ".3mf"):
                _slice_on_its_bed(path, report, tmp_path_factory.mktemp(f"{name}_g"))
                sliced += 1
    assert sliced >= 10
