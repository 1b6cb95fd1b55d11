"""Laser settings, screw catalogue and bar checks: bad input is one clear line and no file."""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from fabkit.errors import FabkitError, FabricationError, SettingsError
from fabkit.writers import export
from fabkit.fab.bars import bar_set
from fabkit.settings.fasteners import CATALOGUE, choose_length, screw_spec
from fabkit.settings.laser import laser_settings
from fabkit.templates import parse_template

from conftest import TEMPLATES


def test_defaults_follow_the_fabrication_facts():
    s = laser_settings()
    assert s.screw.name == "M4-chicago"
    assert (s.screw.barrel_diameter, s.screw.hole_diameter, s.screw.head_diameter) == (5.0, 5.2, 10.0)
    assert s.bar_width == 14.5  # the 5.2 mm hole and 4.5 mm of web each side, to the 0.5 mm
    assert s.min_web == pytest.approx(1.5 * s.thickness)
    assert s.kerf == 0.15 and s.sample_step == pytest.approx(0.5 * s.clearance)
    # measured thickness drives the default web
    assert laser_settings({"thickness": 3.4, "bar_width": 16}).min_web == pytest.approx(5.1)
    assert laser_settings({"thickness": 3.4}).bar_width == 15.5   # follows the web
    with pytest.raises(FabricationError, match="use bar_width >= 15.4 mm"):
        laser_settings({"thickness": 3.4, "bar_width": 15})


def test_overrides_win_and_size_sets_the_scale():
    s = laser_settings({"kerf": 0.2, "scale": 60}, {"kerf": 0.1})
    assert s.kerf == 0.1 and s.scale == 60
    s = laser_settings({"size": 200}, network_size=2.0)
    assert s.scale == 100.0


def test_screw_catalogue_entries_and_overrides():
    assert screw_spec("M4-chicago").hole_diameter == 5.2
    custom = screw_spec({"hole_diameter": 5.3, "lengths": [10, 6, 8]})
    assert custom.hole_diameter == 5.3 and custom.lengths == (6.0, 8.0, 10.0)
    assert choose_length(CATALOGUE["M3-chicago"], 6.0) == 7.0    # 6.0 + 0.1 play
    assert choose_length(CATALOGUE["M3-chicago"], 17.0) == 18.0
    with pytest.raises(FabricationError, match="longer than the longest"):
        choose_length(CATALOGUE["M3-chicago"], 30.0)
    with pytest.raises(FabricationError, match="unknown screw 'M9'"):
        screw_spec("M9")
    with pytest.raises(FabricationError, match="smaller than the barrel"):
        screw_spec({"hole_diameter": 4.9})


@pytest.mark.parametrize("table, message", [
    ({"kerf": -0.1}, "fabrication.laser.kerf: must be >= 0, got -0.1 (width the laser burns"),
    ({"bar_width": 12.0}, "hole-to-edge web 3.40 mm is below the minimum 4.50 mm"),
    ({"bar_width": 4.0}, "the 5.2 mm screw hole is bigger than the 4 mm bar"),
    ({"scale": 0}, "scale: must be > 0, got 0"),
    ({"flavour": "spline"}, "flavour: must be one of 'lwpolyline' or 'line-arc', got 'spline'"),
    ({"kerff": 0.1}, "fabrication.laser.kerff: unknown key; known: bar_width, clearance"),
    ({"min_web": -5}, "min_web: must be >= 0, got -5"),
    ({"screw": {"name": "M5-chicgo"}}, "unknown screw 'M5-chicgo'; catalogue entries: "
                                       "M4-chicago, M3-chicago, M5-chicago, inch-chicago; a screw "
                                       "of your own "
                                       "needs every size"),
    ({"sheet_width": 90}, "cannot hold the 100 mm reference square"),
    ({"scale": 10, "size": 100}, "either laser scale"),
])
def test_bad_settings_are_one_line(table, message):
    with pytest.raises(FabkitError) as info:
        laser_settings(table, network_size=1.0)
    text = str(info.value)
    assert message in text and "\n" not in text


def test_bar_too_short_and_overlapping_holes():
    s = laser_settings()
    with pytest.raises(FabricationError) as info:
        bar_set([100.0, 7.0], [[0, 1], [1, 2]], s, scale=10.0)
    text = str(info.value)
    assert "bar 1 (joints 1-2) is too short" in text and ">= 9.70 mm" in text
    assert "raise scale to >= 13.86 mm per design unit" in text and "\n" not in text
    with pytest.raises(FabricationError, match="holes of bar 0 .* overlap"):
        bar_set([3.0], [[0, 1]], s)
    bars = bar_set([9.7, 50.0], [[0, 1], [1, 2]], s)   # exactly the minimum is allowed
    assert np.array_equal(bars.lengths, [9.7, 50.0])


def _fourbar_with(laser_lines: str):
    base = (TEMPLATES / "fourbar.toml").read_text().split("[fabrication.laser]")[0]
    text = base + "\n[fabrication.laser]\n" + laser_lines
    return parse_template(text, TEMPLATES / "fourbar_laser_test.toml")


@pytest.mark.parametrize("lines, overrides, message", [
    ("bar_width = 10.0\n", {}, "hole-to-edge web"),
    ("scale = 4.0\n", {}, "is too short"),
    ("", {"laser": {"kerf": -0.2}}, "kerf: must be >= 0, got -0.2"),
    ("bar_width = 14.5\n", {"laser": {"screw": {"hole_diameter": 16.0, "head_diameter": 20.0}}},
     "screw hole is bigger than the 14.5 mm bar"),
])
def test_bad_settings_write_nothing(tmp_path, lines, overrides, message):
    design = _fourbar_with(lines)
    out = tmp_path / "out"
    with pytest.raises(FabkitError) as info:
        export(design, "dxf", out, **overrides)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert not out.exists() or not any(out.iterdir())


def test_unknown_or_misspelt_section_is_refused(tmp_path):
    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    with pytest.raises(SettingsError, match="kerf_mm: unknown section; known: laser, motion"):
        export(design, "dxf", tmp_path, kerf_mm=0.1)
    with pytest.raises(ValueError, match="lazer: unknown section"):  # a ValueError too
        export(design, "dxf", tmp_path, lazer={"kerf": 0.1})
    assert not any(tmp_path.iterdir())
