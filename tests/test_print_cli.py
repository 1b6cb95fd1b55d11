"""`fabkit export TEMPLATE --to stl` and `fabkit check` on printed networks, through cli.main."""

from __future__ import annotations

import json

import pytest
import trimesh

from fabkit.cli import main

from conftest import TEMPLATES


def test_export_stl_writes_checked_files(tmp_path, capsys):
    code = main(["export", str(TEMPLATES / "printed_planar.toml"), "--to", "stl", "-o",
                 str(tmp_path), "--tolerance-samples", "0"])
    assert code == 0, capsys.readouterr()
    folder = tmp_path / "printed_planar"
    mesh = trimesh.load(folder / "printed_planar.stl")
    assert mesh.is_watertight and mesh.body_count == 1
    report = json.loads((folder / "report.json").read_text())
    stl = report["formats"]["stl"]
    assert stl["status"] == "exported"
    checks = stl["checks"][0]
    assert checks["ok"]
    assert checks["transition"]["sequential"]


def test_settings_from_the_command_line(tmp_path, capsys):
    code = main(["export", str(TEMPLATES / "printed_planar.toml"), "--to", "stl", "-o",
                 str(tmp_path), "--tolerance-samples", "0", "--set", "print.gap=0.5",
                 "--set", "print.hinge_style=\"bridge\""])
    assert code == 0, capsys.readouterr()
    report = json.loads((tmp_path / "printed_planar" / "report.json").read_text())
    settings = report["formats"]["stl"]["report"]["settings"]
    assert settings["gap"] == 0.5 and settings["hinge_style"] == "bridge"
    assert settings["hinge_thickness"] == pytest.approx(0.6)  # TPU: 3 layers of 0.2 mm
    assert report["formats"]["stl"]["checks"][0]["ok"]


def test_gap_zero_is_one_line_and_writes_nothing(tmp_path, capsys):
    code = main(["export", str(TEMPLATES / "printed_planar.toml"), "--to", "stl", "-o",
                 str(tmp_path / "out"), "--tolerance-samples", "0", "--set", "print.gap=0"])
    err = capsys.readouterr().err
    assert code == 2  # a --set value out of range is a usage error
    lines = [line for line in err.splitlines() if "gap" in line]
    assert len(lines) == 1 and "--set: print.gap: must be > 0, got 0" in lines[0]
    assert "Traceback" not in err
    assert not list((tmp_path / "out").rglob("*.stl"))
