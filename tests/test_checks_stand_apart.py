"""The as-built checks stand apart from the writers they check.

A check that reused a writer's code would reproduce the writer's bug instead of catching it. So
``fabkit/check`` imports nothing from ``fabkit/writers`` nor from ``fabkit/fab``, the plans the
writers draw from (the laser kit, the pinned print, the layer stacking, the hinges, the crease
patterns): it reads the written file with its own reader, rebuilds the network from the file's
geometry and re-simulates it. What a design asks for (``fabkit/settings``) both sides read. Here
that is tested on the import graph (function-level imports included) and by planting writer
bugs: a hole moved by 0.5 mm in a written DXF, pins written 0.4 mm thicker in a 3MF, a mountain turned
into a valley in a FOLD file.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import ezdxf
import numpy as np
import pytest

import fabkit
from fabkit.check import check_file
from fabkit.writers import export

from conftest import ROOT, TEMPLATES

CHECK = Path(fabkit.__file__).parent / "check"


def _imports(path: Path, package: str = "fabkit.check"):
    """(module, name) of every import in a file of ``package``, wherever it stands."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, None
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module
            for a in node.names:
                yield module, a.name


def test_the_checks_import_nothing_from_the_writers():
    files = sorted(CHECK.glob("*.py"))
    assert len(files) >= 10  # the walk sees the package
    seen_settings = set()
    for path in files:
        for module, name in _imports(path):
            where = f"{path.name}: from {module} import {name}"
            for writer in ("fabkit.writers", "fabkit.fab"):
                assert module != writer and not module.startswith(writer + "."), where
            if module.startswith("fabkit.settings."):
                seen_settings.add(module)
    # the walk resolves relative imports: the checks read what was asked for from the settings
    # (the design's, resolved once: fabkit.settings.design)
    assert {"fabkit.settings.design", "fabkit.settings.filaments",
            "fabkit.settings.fasteners"} <= seen_settings


def test_the_settings_import_no_stage_that_plans_draws_or_checks():
    banned = ("fabkit.fab", "fabkit.writers", "fabkit.check", "fabkit.tolerance", "fabkit.motion",
              "fabkit.pipeline", "fabkit.report")
    files = sorted((CHECK.parent / "settings").glob("*.py"))
    assert len(files) >= 6
    for path in files:
        rel = path.relative_to(CHECK.parent.parent).with_suffix("")
        for module, name in _imports(path, ".".join(rel.parts[:-1])):
            assert not any(module == b or module.startswith(b + ".") for b in banned), \
                f"{path.name}: from {module} import {name}"


@pytest.fixture(scope="module")
def laser_kit(tmp_path_factory):
    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    out = tmp_path_factory.mktemp("laser")
    result, _ = export(design, "dxf", out)
    sheets = sorted(p for p in out.glob("*.dxf") if "coupon" not in p.name)
    assert sheets  # the kit's sheets (the coupon is a test piece, checked on its own)
    return design, sheets


def _by_name(report):
    return {c["name"]: c for c in report["checks"]}


def test_the_written_dxf_passes(laser_kit):
    design, sheets = laser_kit
    r = check_file(sheets[0], design=design)
    assert r["ok"], [c for c in r["checks"] if not c["ok"]]


def test_a_hole_moved_half_a_millimetre_in_the_dxf_is_caught(laser_kit, tmp_path):
    design, sheets = laser_kit
    for sheet in sheets:  # the whole kit, one hole moved
        doc = ezdxf.readfile(sheet)
        if sheet == sheets[0]:
            hole = next(e for e in doc.modelspace()
                        if e.dxftype() == "CIRCLE" and e.dxf.layer == "CUT_INNER")
            c = hole.dxf.center
            hole.dxf.center = (c.x + 0.5, c.y, 0.0)
        doc.saveas(tmp_path / sheet.name)
    r = check_file(tmp_path / sheets[0].name, design=design)
    assert not r["ok"]
    c = _by_name(r)
    assert not c["holes_centred"]["ok"]
    assert c["holes_centred"]["value"] == pytest.approx(0.5, abs=1e-6)
    assert not c["lengths"]["ok"] and c["lengths"]["value"] > 0.1


@pytest.fixture(scope="module")
def super_stable():
    return fabkit.load_template(TEMPLATES / "super_stable.toml")


def _pin_clearance(report):
    c = _by_name(report)["pin clearance"]
    return c["ok"], c["value"]


def test_pins_written_thicker_in_the_3mf_are_caught(super_stable, tmp_path, monkeypatch):
    import fabkit.fab.pinned as pinned

    export(super_stable, "stl", tmp_path / "good", print={"preview": False})
    good = check_file(tmp_path / "good" / "super_stable.3mf", design=super_stable)
    assert good["ok"] and _pin_clearance(good)[1] == pytest.approx(0.3, abs=1e-3)

    real = pinned.pin_profile

    def thicker(z_start, stack, s):  # the writer's bug: the shaft 0.2 mm wider in radius
        profile = real(z_start, stack, s).copy()
        shaft = np.isclose(profile[:, 0], 0.5 * s.pin_diameter)
        profile[shaft, 0] += 0.2
        return profile

    monkeypatch.setattr(pinned, "pin_profile", thicker)
    export(super_stable, "stl", tmp_path / "bad", print={"preview": False})
    monkeypatch.undo()
    bad = check_file(tmp_path / "bad" / "super_stable.3mf", design=super_stable)
    ok, value = _pin_clearance(bad)
    assert not bad["ok"] and not ok
    assert value == pytest.approx(0.1, abs=1e-3)  # 0.3 mm asked, 0.1 mm written


@pytest.fixture(scope="module")
def origami_fold(tmp_path_factory):
    design = fabkit.load_template(TEMPLATES / "origami_sheet.toml")
    out = tmp_path_factory.mktemp("fold")
    export(design, "fold", out)
    return design, out / "origami_sheet.fold"


def test_the_written_fold_file_passes_maekawa_and_kawasaki(origami_fold):
    design, path = origami_fold
    r = check_file(path, design=design)
    assert r["ok"] and r["flat_foldable"] is True, [c for c in r["checks"] if not c["ok"]]
    c = _by_name(r)
    # P, the one interior vertex: PD a mountain, PA, PB, PC valleys
    assert c["maekawa"]["value"] == [] and c["maekawa"]["limit"] == 2
    assert "vertex 4: 1 mountains, 3 valleys, |#M - #V| = 2" in c["maekawa"]["detail"]
    assert c["kawasaki"]["value"] < 1e-12


def _mountain_made_valley(path, tmp_path):
    """The file with PD (edge 7, the one mountain at P) a valley, its fold angles turned too so
    that assignment and angles agree."""
    doc = json.loads(path.read_text())
    assert doc["edges_assignment"][7] == "M" and doc["edges_vertices"][7] == [3, 4]
    doc["edges_assignment"][7] = "V"
    doc["edges_foldAngle"][7] = -doc["edges_foldAngle"][7]
    for frame in doc["file_frames"]:
        frame["edges_foldAngle"][7] = -frame["edges_foldAngle"][7]
    bad = tmp_path / "valley.fold"
    bad.write_text(json.dumps(doc))
    return bad


def test_a_mountain_turned_into_a_valley_fails_maekawa(origami_fold, tmp_path):
    design, path = origami_fold
    bad = _mountain_made_valley(path, tmp_path)
    r = check_file(bad, design=design)
    c = _by_name(r)
    assert c["structure"]["ok"]  # the file is consistent: only the crease pattern is wrong
    assert not r["ok"] and r["flat_foldable"] is False
    assert not c["maekawa"]["ok"] and c["maekawa"]["value"] == [4]
    assert "vertex 4: 0 mountains, 4 valleys, |#M - #V| = 4" in c["maekawa"]["detail"]
    assert c["kawasaki"]["ok"]  # the geometry is untouched


def test_a_mountain_turned_into_a_valley_fails_fabkit_check(origami_fold, tmp_path):
    _, path = origami_fold
    bad = _mountain_made_valley(path, tmp_path)
    run = subprocess.run([sys.executable, "-m", "fabkit", "check", str(bad), "--design",
                          "origami_sheet"], capture_output=True, text=True, cwd=ROOT)
    assert run.returncode == 1, run.stderr
    assert "FAIL  maekawa: [4] (limit 2)  vertex 4: 0 mountains, 4 valleys" in run.stdout
    assert run.stdout.strip().endswith("valley.fold: FAILED")
    good = subprocess.run([sys.executable, "-m", "fabkit", "check", str(path), "--design",
                           "origami_sheet"], capture_output=True, text=True, cwd=ROOT)
    assert good.returncode == 0, good.stdout + good.stderr
