"""A build driven with elastic bars (fabkit.builds.quasistatic, fabkit.tolerance.elastic and
``fabkit simulate --model elastic``): stress and energy against σ = E ε and ½ k δ², where the
stress reaches the allowable against the closed form, a mechanism unstrained all along, a kit
pushed past its lock, and bad input named."""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from fabkit.builds.materials import MATERIALS
from fabkit.builds.quasistatic import drive_elastically
from fabkit.cli import main
from fabkit.tolerance.elastic import elastic_motion

ACRYLIC = MATERIALS["acrylic"]
#: A 14.5 mm bar of 3 mm acrylic.
SECTION = 14.5 * 3.0


def _triangle(side: float) -> np.ndarray:
    return np.array([[0.0, 0.0], [side, 0.0], [side / 2, side * np.sqrt(3) / 2]])


def test_a_pulled_bar_carries_e_times_its_strain():
    # 200 mm bars, the base pulled 1 mm: the apex follows, the base takes it all
    x = _triangle(200.0)
    m = drive_elastically([[0, 1], [1, 2], [2, 0]], [200.0] * 3, 0.0, x, (0, 1),
                          [200.0, 200.5, 201.0], ACRYLIC, SECTION)
    eps = np.array([0.0, 0.5, 1.0]) / 200.0
    assert m.peak_stress == pytest.approx(ACRYLIC.youngs_mpa * eps, abs=1e-9)
    k = ACRYLIC.youngs_mpa * SECTION / 200.0
    assert m.energy == pytest.approx(0.5 * k * (eps * 200.0) ** 2, rel=1e-9, abs=1e-12)
    assert m.stress[:, 1:] == pytest.approx(0.0, abs=1e-9)  # the other two bars are free
    assert m.closes.tolist() == [True, False, False]


def test_play_takes_the_pull_before_the_bar_does():
    # 0.2 mm of play in the pulled bar: the first 0.2 mm cost nothing
    x = _triangle(100.0)
    m = drive_elastically([[0, 1], [1, 2], [2, 0]], [100.0] * 3, 0.2, x, (0, 1),
                          [100.0, 100.1, 100.2, 100.5], ACRYLIC, SECTION)
    assert m.peak_stress[:3] == pytest.approx(0.0, abs=1e-6)
    assert m.peak_stress[3] == pytest.approx(ACRYLIC.youngs_mpa * 0.3 / 100.0, rel=1e-6)


def test_the_stress_reaches_the_allowable_where_the_closed_form_says():
    # σ = E (v - 100) / 100 reaches 15 MPa at v = 100 + 1500 / 3200 = 100.46875 mm
    m = drive_elastically([[0, 1], [1, 2], [2, 0]], [100.0] * 3, 0.0, _triangle(100.0), (0, 1),
                          [100.0, 100.4, 100.8], ACRYLIC, SECTION)
    assert m.first_over() == 2
    assert m.crossing == pytest.approx(100.0 + 100.0 * 15.0 / 3200.0, abs=1e-5)


def test_a_mechanism_moves_unstrained():
    run = elastic_motion(fabkit.load_template("fourbar"), steps=11)
    assert run.process == "laser" and run.room_mm == pytest.approx(0.2)
    assert run.section_mm2 == pytest.approx(SECTION)
    assert run.motion.closes.all() and run.motion.peak_stress.max() < 1e-6
    # the drive runs from the start (2 units) to the target (3), 100 mm a unit
    assert run.motion.drive[[0, -1]] == pytest.approx([200.0, 300.0])
    assert run.over() is None


def test_a_kit_pushed_past_its_lock_is_strained(tmp_path):
    # the super-stable chain locks at d1 = 1.00995; pushed on to 0.99 its acrylic passes 15 MPa
    out = tmp_path / "sim"
    code = main(["simulate", "super_stable_chain8", "--model", "elastic", "--to", "0.99",
                 "--steps", "21", "-o", str(out), "-q"])
    assert code == 1
    data = np.load(out / "super_stable_chain8" / "elastic.npz")
    assert data["drive_mm"].shape == (21,) and data["stress_mpa"].shape[0] == 21
    peak = np.abs(data["stress_mpa"]).max(axis=1)
    assert peak[0] < 1e-6 and peak[-1] > float(data["allowable_mpa"])
    assert data["energy_mj"][-1] > data["energy_mj"][0]
    assert (out / "super_stable_chain8" / "elastic.png").stat().st_size > 0


def test_the_cli_names_what_is_wrong(tmp_path, capsys):
    out = str(tmp_path / "o")
    assert main(["simulate", "super_stable_chain8", "--model", "elastic", "--to", "0.99",
                 "-o", out]) == 1
    err = capsys.readouterr().err
    assert "reaches the 15 MPa acrylic (PMMA) allows at d1 = " in err
    assert main(["simulate", "fourbar", "--model", "elastc", "-o", out]) == 2
    assert "did you mean 'elastic'" in capsys.readouterr().err
    assert main(["simulate", "fourbar", "--steps", "5", "-o", out]) == 2
    assert "--steps" in capsys.readouterr().err
    assert main(["simulate", "fourbar", "--model", "elastic", "--steps", "1", "-o", out]) == 2
    assert main(["simulate", "origami_sheet", "--model", "elastic", "-o", out]) == 1
    assert "creases" in capsys.readouterr().err
    assert not (tmp_path / "o" / "origami_sheet").exists()
    # the laser's settings reach the elastic model (and only it)
    assert main(["simulate", "fourbar", "--model", "elastic", "--set", "laser.bar_width=20",
                 "-o", out]) == 0
    assert main(["simulate", "fourbar", "--set", "laser.bar_width=20", "-o", out]) == 2


def test_bad_values_are_refused():
    with pytest.raises(ValueError, match="values_mm"):
        drive_elastically([[0, 1]], [1.0], 0.0, [[0, 0], [1, 0]], (0, 1), [np.nan], ACRYLIC, 1.0)
    with pytest.raises(ValueError, match="steps"):
        elastic_motion(fabkit.load_template("fourbar"), steps=1)


def test_the_section_follows_the_laser_settings():
    run = elastic_motion(fabkit.load_template("fourbar"), steps=2,
                         settings={"laser": {"bar_width": 20.0}})
    assert run.section_mm2 == pytest.approx(20.0 * 3.0)


def test_a_pin_jointed_print_is_its_material_with_its_pins_play():
    # PLA, 7 x 2.4 mm bars, 0.3 mm radial pin clearance at each end that turns on a pin: the
    # plan puts bar (0, 3) lowest, carrying the pins of joints 0 and 3 (no play there), bar
    # (1, 2) turns on both its pins, the others on one: plays 0.3, 0, 0.6, 0.3 mm, median 0.3
    d = fabkit.load_template("fourbar")
    run = elastic_motion(d, steps=3, settings={"tolerance": {"process": "print"},
                                               "print": {"linkage": "pins"}})
    assert run.process == "print" and run.material.name == "PLA"
    assert run.section_mm2 == pytest.approx(7.0 * 2.4)
    assert run.room_mm == pytest.approx(0.3)
    with pytest.raises(fabkit.errors.TemplateError, match="flexure hinges"):
        elastic_motion(d, steps=3, settings={"tolerance": {"process": "print"},
                                             "print": {"linkage": "hinges"}})
