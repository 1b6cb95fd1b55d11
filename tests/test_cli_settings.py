"""``--set SECTION.KEY=VALUE`` on design, sweep, letters and info: parsed and checked as on
export (types, ranges, did-you-mean), a key the command does not read refused in one line with
exit status 2 and nothing written, and a good value used by the work."""

from __future__ import annotations

import json
import math

import pytest

from fabkit.cli import main

SWEEP = ["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:2", "--measure", "fixed_points",
         "--no-plots", "-j", "1", "-q"]
DESIGN = ["design", "--fixed-point", "1.6:0", "--fixed-point", "1.1", "-q"]
D2_CURVATURE = 1.5 * math.sqrt(3.0)  # the curvature modules' final state D2*


def _error(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    return lines[0]


@pytest.mark.parametrize("argv, line", [
    # design: the settings of its simulated laser builds only
    (DESIGN + ["--set", "laser.scale=-3"],
     "fabkit: error: --set: laser.scale: must be > 0, got -3 (mm per design unit)"),
    (DESIGN + ["--set", "tolerance.length_sigam=0.1"],
     "fabkit: error: --set: tolerance.length_sigam: unknown key; known: bar_width, "
     "compliance_sigma, crease_sigma, cut_sigma, hinge_length, hole_clearance, kerf_sigma, length_sigma, limit, "
     "limit_fraction, line_width_sigma, min_reached, paper_thickness, process, samples, scale, "
     "seed, shrinkage, shrinkage_sigma, state_fraction, thickness, thickness_sigma, xy_sigma; "
     "did you mean 'length_sigma'?"),
    (DESIGN + ["--set", "laser.kerf=0.2"],
     "fabkit: error: --set: laser.kerf: has no effect here: a designed module reads the "
     "settings of its simulated laser builds only: laser.scale, laser.size, laser.thickness, "
     "laser.screw, tolerance.scale, tolerance.length_sigma, tolerance.kerf_sigma, "
     "tolerance.hole_clearance, tolerance.thickness, tolerance.thickness_sigma; remove it"),
    (DESIGN + ["--set", "tolerance.xy_sigma=0.1"],
     "fabkit: error: --set: tolerance.xy_sigma: has no effect here: a designed module reads the "
     "settings of its simulated laser builds only: laser.scale, laser.size, laser.thickness, "
     "laser.screw, tolerance.scale, tolerance.length_sigma, tolerance.kerf_sigma, "
     "tolerance.hole_clearance, tolerance.thickness, tolerance.thickness_sigma; remove it"),
    (["design", "--curve", "quadrifolium.csv", "--set", "laser.scale=50"],
     "fabkit: error: --set: laser.scale: laser settings have no effect here: a chain designed "
     "from a curve reads no settings; remove them"),
    # sweep: motion.to only
    (SWEEP + ["--set", "motion.to=abc"],
     "fabkit: error: --set: motion.to: must be a number, got 'abc' (target value of the drive)"),
    (SWEEP + ["--set", "motion.tto=1.2"],
     "fabkit: error: --set: motion.tto: unknown key; known: drive, method, to; did you mean "
     "'to'?"),
    (SWEEP + ["--set", "motion.drive=d2"],
     "fabkit: error: --set: motion.drive: has no effect here: sweep reads motion.to only (the "
     "branch measured, the target of a traced motion); remove it"),
    (SWEEP + ["--set", "laser.kerf=0.2"],
     "fabkit: error: --set: laser.kerf: laser settings have no effect here: sweep reads "
     "motion.to only (the branch measured, the target of a traced motion); remove them"),
    (SWEEP[:3] + ["motion.to=0.8:1.2:2"] + SWEEP[4:] + ["--set", "motion.to=1.2"],
     "fabkit: error: --set: motion.to: --vary motion.to varies it already; give one of the two"),
    (["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:2", "--set", "motion.to"],
     "fabkit: error: --set: 'motion.to': expected SECTION.KEY=VALUE, e.g. laser.kerf=0.2"),
    # letters: motion.to (D2*) only, and only a value that is the modules' fixed point
    (["letters", "NO", "-q", "--set", "motion.to=0"],
     "fabkit: error: --set: motion.to: must be > 0, got 0 (target value of the drive)"),
    (["letters", "NO", "-q", "--set", "motion.method=projected"],
     "fabkit: error: --set: motion.method: has no effect here: letters reads motion.to only "
     "(D2*, the final state of the chains); remove it"),
    (["letters", "NO", "-q", "--set", "moton.to=2.6"],
     "fabkit: error: --set: moton: unknown section; known: laser, motion, origami, print, "
     "tolerance; did you mean 'motion'?"),
    (["letters", "NO", "-q", "--set", "motion.to=2.55"],
     "fabkit: error: --set: motion.to: curvature module 'expand': d2 = 2.550000015 at "
     "d1 = 2.55; the final state must be a fixed point d1 = d2"),
    # info: every motion setting
    (["info", "fourbar", "--set", "motion.method=warp"],
     "fabkit: error: --set: motion.method: must be one of 'auto', 'constructive', 'projected', "
     "'rk4-nullspace' or 'branch', got 'warp' (tracing method)"),
    (["info", "fourbar", "--set", "print.gap=0.3"],
     "fabkit: error: --set: print.gap: print settings have no effect here: info reads motion "
     "settings only; remove them"),
])
def test_a_bad_setting_is_one_line_and_exit_2(argv, line, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert _error(capsys) == line
    assert list(tmp_path.iterdir()) == []  # refused before any work: no folder, no file


def test_design_builds_and_template_take_the_settings(tmp_path, capsys):
    from fabkit.templates import load_template
    from fabkit.tolerance import tolerance_spec

    out = tmp_path / "d"
    assert main(DESIGN + ["--set", "tolerance.length_sigma=0.2", "--set", "laser.scale=50",
                          "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "simulated at 50 mm per unit" in printed  # the builds judged are at that scale
    report = json.loads((out / "module_design.json").read_text())
    assert "50 mm per unit" in json.dumps(report["builds"])
    design = load_template(out / "module.toml")  # the export of it reads the same settings
    assert design.fabrication["laser"] == {"scale": 50}
    spec = tolerance_spec(design)
    assert (spec.scale, spec.length_sigma, spec.process) == (50.0, 0.2, "laser")

    plain = tmp_path / "plain"
    assert main(DESIGN + ["-o", str(plain)]) == 0
    assert "simulated at 100 mm per unit" in capsys.readouterr().out
    assert "[fabrication" not in (plain / "module.toml").read_text()


def test_sweep_sets_the_target_of_every_point(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(SWEEP + ["--set", "motion.to=1.2", "-o", str(out)]) == 0
    capsys.readouterr()
    spec = json.loads((out / "chunks" / "spec.json").read_text())["spec"]
    assert spec["raw"]["motion"]["to"] == 1.2  # the template of every point
    table = json.loads((out / "sweep.json").read_text())
    assert [p["fixed_value"] for p in table["points"]] == pytest.approx([1.5, 1.5])


def test_letters_design_for_the_final_state_given(tmp_path, capsys):
    out = tmp_path / "l"
    given = round(D2_CURVATURE, 7)  # the modules' D2* to 7 digits, not the template's 16
    assert main(["letters", "NO", "-q", "--set", f"motion.to={given}", "-o", str(out)]) == 0
    capsys.readouterr()
    fit = json.loads((out / "no_fit.json").read_text())
    assert fit["D2"] == given != D2_CURVATURE
    assert f"to = {given!r}" in (out / "no_1_N.toml").read_text()


def test_info_describes_the_motion_as_set(capsys):
    assert main(["info", "fourbar", "--set", "motion.drive=d2", "--set", "motion.to=3"]) == 0
    text = capsys.readouterr().out
    assert "constructive  yes (nodes placed by intersections from d2)" in text
    assert "motion        d2 = 2 to 3 (method auto)" in text
    assert main(["info", "fourbar", "--set", "motion.drive=d9"]) == 1
    assert _error(capsys).endswith("--set motion.drive: unknown port 'd9'; the network has "
                                   "ports: d1, d2")
