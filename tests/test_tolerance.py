"""Tolerance analysis: the error model's statistics, exact placement of perturbed builds,
flags, Lyapunov exponents and the predictability horizon, and ``fabkit tolerance``."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main
from fabkit.errors import TemplateError
from fabkit.templates import load_template, parse_template
from fabkit.tolerance.processes import ProcessGeometry, sample_builds
from fabkit.tolerance import (
    ToleranceSpec,
    analyse_tolerance,
    lyapunov_estimate,
    perturbed_lengths,
    tolerance_spec,
)

TEMPLATES = Path(__file__).resolve().parents[1] / "templates"
EXACT = dict(length_sigma=0.0, kerf_sigma=0.0, hole_clearance=0.0, thickness_sigma=0.0)


@pytest.fixture(scope="module")
def fourbar():
    return load_template(TEMPLATES / "fourbar.toml")


def chaotic_chain(copies: int, extra: str = ""):
    text = (f'[chain]\nmodule = "{(TEMPLATES / "chaotic.toml").as_posix()}"\ncopies = {copies}\n'
            "[motion]\nto = 0.75\n" + extra)
    return parse_template(text, Path("chaotic_chain.toml"))


# --- the error model --------------------------------------------------------------------------

def test_length_error_alone_has_the_given_sigma():
    spec = ToleranceSpec(scale=50.0, samples=20000, length_sigma=0.05, kerf_sigma=0.0,
                         hole_clearance=0.0, thickness_sigma=0.0)
    built, _ = perturbed_lengths([2.0, 1.0], spec, np.random.default_rng(1))
    err_mm = (built - [2.0, 1.0]) * spec.scale
    assert err_mm.std(axis=0) == pytest.approx([0.05, 0.05], rel=0.03)
    assert abs(err_mm.mean()) < 0.002


def test_joint_play_is_room_not_a_length_error():
    """A barrel sits where the assembly pushes it: hole play adds no length error, it gives each
    bar the sum of its two holes' radial clearances as room (c/2 + c/2 = c), widened or
    tightened by uneven kerf (σ of the room: kerf σ / √2, never below zero)."""
    c = 0.2
    spec = ToleranceSpec(scale=50.0, samples=20000, length_sigma=0.0, kerf_sigma=0.0,
                         hole_clearance=c, thickness_sigma=0.3)
    geo = ProcessGeometry(np.zeros((2, 2)), np.array([[0, 1]]), np.array([2.0]))
    builds = sample_builds(geo, spec, np.random.default_rng(2))
    assert np.all(builds.base == 2.0)  # neither the play nor the sheet's thickness moves a pin
    assert np.allclose(builds.room * spec.scale, c)
    kerf = sample_builds(geo, replace(spec, kerf_sigma=0.03), np.random.default_rng(2))
    room_mm = kerf.room[:, 0] * spec.scale
    assert room_mm.mean() == pytest.approx(c, abs=0.002)
    assert room_mm.std() == pytest.approx(0.03 / math.sqrt(2), rel=0.03)
    tight = sample_builds(geo, replace(spec, hole_clearance=0.0, kerf_sigma=0.03),
                          np.random.default_rng(2))
    assert tight.room.min() >= 0.0 and (tight.room == 0).mean() > 0.2


# --- exact builds -----------------------------------------------------------------------------

def test_without_errors_every_build_is_the_design(fourbar):
    res = analyse_tolerance(fourbar, tolerance_spec(fourbar, samples=20, **EXACT))
    assert res.method == "constructive"
    assert res.reached.all() and not res.flagged
    np.testing.assert_allclose(res.distances, np.broadcast_to(res.nominal, res.distances.shape),
                               atol=1e-12)
    assert res.nominal[res.ports.index("d2")] == pytest.approx(4.0 / 3.0, abs=1e-12)
    assert res.length_rms == 0.0
    assert np.abs(res.end_offsets).max() < 1e-12


def _quad_d2(lengths, d1):
    """d2 of a 4-bar with nodes 0, 1 (the d1 pair) and 2, 3 (the d2 pair) on one side of 0-1,
    by the law of cosines (independent of fabkit's placement)."""
    l02, l03, l12, l13 = lengths.T
    pts = []
    for a, b in ((l02, l12), (l03, l13)):
        x = (a ** 2 - b ** 2 + d1 ** 2) / (2 * d1)
        pts.append(np.stack([x, -np.sqrt(a ** 2 - x ** 2)], axis=-1))
    return np.linalg.norm(pts[0] - pts[1], axis=-1)


def test_built_distances_match_the_law_of_cosines(fourbar):
    spec = tolerance_spec(fourbar, samples=300, seed=7)
    res = analyse_tolerance(fourbar, spec)
    built, _ = perturbed_lengths(fourbar.network.edge_lengths, spec, np.random.default_rng(7))
    expected = _quad_d2(built, 3.0)  # edges are [0,2], [0,3], [1,2], [1,3]
    assert res.reached.all()
    np.testing.assert_allclose(res.distances[:, res.ports.index("d2")], expected, rtol=1e-12)


def test_spread_grows_linearly_with_the_length_error(fourbar):
    stds = []
    for sigma in (0.05, 0.1):
        spec = tolerance_spec(fourbar, samples=200, **{**EXACT, "length_sigma": sigma})
        res = analyse_tolerance(fourbar, spec)
        stds.append(res.distances[:, res.ports.index("d2")].std())
    assert stds[1] / stds[0] == pytest.approx(2.0, rel=0.01)


def test_networks_without_a_construction_order_use_projected_builds():
    # two rigid triangles joined by two bars: no node has two placed neighbours from the drive
    text = """
[network]
nodes = [[0, 0], [1, 0], [0.5, 0.8], [3, 0.2], [4, 0], [3.5, 1.0]]
edges = [[0, 1], [1, 2], [0, 2], [3, 4], [4, 5], [3, 5], [0, 3], [1, 4]]
ports = { d1 = [2, 5], d2 = [0, 4] }
[motion]
to = 3.2
"""
    design = parse_template(text, Path("triangles.toml"))
    exact = analyse_tolerance(design, tolerance_spec(design, samples=5, **EXACT))
    assert exact.method == "projected" and exact.reached.all()
    np.testing.assert_allclose(exact.distances, np.broadcast_to(exact.nominal, (5, 2)), atol=1e-8)
    res = analyse_tolerance(design, tolerance_spec(design, samples=500))
    assert res.distances.shape == (40, 2)  # capped: each build is traced on its own
    assert res.reached.all()
    assert 0 < np.nanstd(res.distances[:, 1]) < 0.01


# --- flags ------------------------------------------------------------------------------------

def test_a_knife_edge_target_is_judged_by_the_state_its_modules_end_in():
    # eight super-stable modules driven to 1.0105, 0.055 mm above D2* = 1.00995: the first
    # modules have collapsed, and which module is mid-collapse there depends on any error
    text = (f'[chain]\nmodule = "{(TEMPLATES / "super_stable.toml").as_posix()}"\ncopies = 8\n'
            "[motion]\nto = 1.0105\n")
    design = parse_template(text, Path("super_stable_chain8.toml"))
    res = analyse_tolerance(design, tolerance_spec(design, samples=100), attribute=False)
    b = res.behaviour
    assert b.end == "state" and b.order == 1
    assert [c.role for c in b.crystals] == ["start", "end"]
    assert b.crystals[1].value == pytest.approx(1.0099504938, abs=1e-9)
    end = res.judged["end state"]
    assert end.ok.all() and np.percentile(end.value_mm, 95) < 0.1 * end.limit_mm
    assert not res.flagged and res.margin["value"] >= 1
    # asked for the port distances at that instant instead, the far end is tens of mm off
    asked = parse_template(text + 'intent = "target"\n', Path("super_stable_chain8.toml"))
    ports = analyse_tolerance(asked, tolerance_spec(asked, samples=100), attribute=False)
    assert ports.behaviour.end == "ports" and ports.flagged
    far = np.asarray(ports.judged["end ports"].detail["p95_by_port_mm"])
    assert far[ports.ports.index("d9")] > 10 * ports.limits[0]
    assert far[ports.ports.index("d2")] < ports.limits[0]


def test_the_limit_decides_the_verdict(fourbar):
    loose = analyse_tolerance(fourbar, tolerance_spec(fourbar, samples=100, limit=5.0),
                              attribute=False)
    tight = analyse_tolerance(fourbar, tolerance_spec(fourbar, samples=100, limit=0.01),
                              attribute=False)
    assert loose.behaviour.end == "ports" and not loose.flagged
    assert loose.judged["end ports"].limit_mm == 5.0 and loose.judged["end ports"].ok.all()
    assert tight.flagged and tight.margin["value"] < 1
    j = tight.judged["end ports"]
    assert j.limit_mm == 0.01 and np.percentile(j.value_mm, 95) > 0.01
    d = loose.as_dict()
    assert d["samples"] == 100 and d["keep_fraction"] == 1.0
    assert [p["port"] for p in d["ports"]] == ["d1", "d2"]
    assert d["ports"][0]["p95_abs_error_mm"] == 0.0  # the drive is set exactly


# --- chaos and the predictability horizon -----------------------------------------------------

def test_lyapunov_exponent_of_the_chaotic_module_matches_the_paper():
    lam = lyapunov_estimate(load_template(TEMPLATES / "chaotic.toml"))
    assert lam["source"] == "iterated module map"
    assert lam["lyapunov"] == pytest.approx(0.312, abs=0.01)  # paper: "≈ 0.312"


def test_lyapunov_exponent_agrees_with_the_map_toolkit():
    import fabkit

    design = load_template(TEMPLATES / "chaotic.toml")
    ours = lyapunov_estimate(design)["lyapunov"]
    theirs = fabkit.module_map(design.network).lyapunov(initial=200, discard=200, average=1000)
    assert ours == pytest.approx(theirs.mean, abs=0.01)


def test_lyapunov_exponent_is_zero_for_the_four_bar_and_negative_when_super_stable():
    # f(d) = 4/d: f'(d) f'(f(d)) = 1, so errors neither grow nor shrink
    assert abs(lyapunov_estimate(load_template(TEMPLATES / "fourbar.toml"))["lyapunov"]) < 1e-8
    assert abs(lyapunov_estimate(load_template(TEMPLATES / "fourbar_chain2.toml"))["lyapunov"]) \
        < 1e-6
    assert lyapunov_estimate(load_template(TEMPLATES / "super_stable.toml"))["lyapunov"] < -10


def test_errors_grow_along_a_chaotic_chain_as_predicted():
    design = chaotic_chain(8, 'intent = "target"\n')
    res = analyse_tolerance(design, tolerance_spec(design, samples=200, min_reached=0.0),
                            attribute=False)
    hz = res.horizon
    assert hz["source"] == "chain gains" and hz["lyapunov"] > 0.2
    assert hz["modules"] == pytest.approx(
        math.log(hz["module_size_mm"] / hz["error_mm"]) / hz["lyapunov"], rel=1e-12)
    err = np.percentile(res.port_errors_mm(), 95, axis=0)
    chain = [res.ports.index(f"d{k}") for k in range(2, 10)]
    growth = np.polyfit(np.arange(8), np.log(err[chain]), 1)[0]
    assert 0.15 < growth < 0.5  # ≈ the module's λ = 0.31 per module
    assert err[chain[-1]] > 4 * err[chain[0]]


def test_no_horizon_where_errors_do_not_grow(fourbar):
    res = analyse_tolerance(fourbar, tolerance_spec(fourbar, samples=20))
    assert res.horizon["modules"] is None
    assert "neutral" in res.horizon["detail"]


# --- settings ---------------------------------------------------------------------------------

def test_settings_come_from_laser_template_and_command_line(fourbar):
    design = replace(fourbar, fabrication={"laser": {"scale": 40, "thickness": 2.0},
                                           "tolerance": {"length_sigma": 0.08, "samples": 30}})
    spec = tolerance_spec(design, {"tolerance": {"samples": 12}})
    assert (spec.scale, spec.thickness, spec.length_sigma, spec.samples) == (40.0, 2.0, 0.08, 12)
    assert spec.hole_clearance == pytest.approx(0.2)  # M3 Chicago screw: 4.2 mm hole, 4.0 barrel
    assert tolerance_spec(design, seed=3).seed == 3


@pytest.mark.parametrize("table, key, words", [
    ({"samples": 0}, "samples", "must be >= 1, got 0"),
    ({"samples": 2.5}, "samples", "must be a whole number, got 2.5"),
    ({"thickness": -3}, "thickness", "must be > 0, got -3"),
    ({"kerf_sigma": -0.1}, "kerf_sigma", "must be >= 0, got -0.1"),
    ({"min_reached": 1.5}, "min_reached", "must be <= 1, got 1.5"),
    ({"hole_clearance": "0.2 mm"}, "hole_clearance", "must be a number, got '0.2 mm'"),
])
def test_bad_settings_name_the_key(fourbar, table, key, words):
    with pytest.raises(TemplateError) as err:
        tolerance_spec(fourbar, {"tolerance": table})
    assert f"--set tolerance.{key}: " in str(err.value) and words in str(err.value)


def test_a_design_that_does_not_reach_its_target_is_refused(fourbar):
    far = replace(fourbar, motion=replace(fourbar.motion, to=10.0))
    with pytest.raises(TemplateError, match="motion.to: the designed motion does not reach"):
        analyse_tolerance(far, ToleranceSpec(samples=5))


# --- the command ------------------------------------------------------------------------------

def test_tolerance_command_writes_json_and_plot_and_flags(tmp_path, capsys):
    rc = main(["tolerance", str(TEMPLATES / "chaotic_chain.toml"), "-o", str(tmp_path),
               "--samples", "60"])
    out = capsys.readouterr().out
    assert rc == 1  # flagged: the chaotic chain's far end is unpredictable
    data = json.loads((tmp_path / "chaotic_chain" / "tolerance.json").read_text())
    assert data["samples"] == 60 and data["flagged"] is True
    assert data["margin"] < 1 and data["keep_fraction"] < 0.95
    assert data["horizon"]["map_lyapunov"] == pytest.approx(0.312, abs=0.01)
    verdict = [line for line in out.splitlines() if line.strip().startswith("verdict")]
    assert len(verdict) == 1 and "margin" in verdict[0]
    assert (tmp_path / "chaotic_chain" / "tolerance.png").read_bytes()[:4] == b"\x89PNG"

    rc = main(["tolerance", str(TEMPLATES / "fourbar.toml"), "-o", str(tmp_path / "q"),
               "--samples", "30", "--no-files"])
    assert rc == 0 and "ok, margin" in capsys.readouterr().out
    assert not (tmp_path / "q").exists()


def test_tolerance_command_rejects_bad_values(tmp_path, capsys):
    assert main(["tolerance", str(TEMPLATES / "fourbar.toml"), "--samples", "0",
                 "-o", str(tmp_path)]) == 2
    assert "--samples: must be at least 1" in capsys.readouterr().err
    assert main(["tolerance", str(TEMPLATES / "fourbar.toml"), "--set",
                 "tolerance.scale=-1", "-o", str(tmp_path)]) == 2  # refused before any template
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--set: tolerance.scale: must be > 0, got -1" in err[0]
    assert list(tmp_path.iterdir()) == []
