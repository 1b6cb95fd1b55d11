"""What a design is for and whether builds keep it: crystals, order, end state, chaos; the margin
of every verdict and its chart; the paper's photographed builds and the real failures."""

from __future__ import annotations

import json
import math
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main
from fabkit.errors import TemplateError
from fabkit.maps import module_map
from fabkit.numerics import project_to_lengths
from fabkit.report.text import tolerance_markdown
from fabkit.report.html import keep_chart_svg
from fabkit.templates import load_template, parse_template
from fabkit.tolerance import ToleranceSpec, analyse_tolerance, tolerance_spec
from fabkit.tolerance.criteria import profile_order
from fabkit.tolerance.processes import (ProcessGeometry, joint_turns, sample_builds,
                                        state_profile)

TEMPLATES = Path(__file__).resolve().parents[1] / "templates"

#: The builds the paper photographs working (Fig. 5).
PHOTOGRAPHED = ["super_stable_chain", "origami_sheet", "origami_chain12", "printed_planar",
                "printed_planar_chain10"]


def _criteria(data: dict) -> dict:
    return {c["criterion"]: c for c in data["criteria"]}


# --- the paper's builds ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def photographed(tmp_path_factory):
    """``fabkit tolerance`` on the five photographed builds at the default settings."""
    out = tmp_path_factory.mktemp("five")
    rc = main(["tolerance", *[str(TEMPLATES / f"{n}.toml") for n in PHOTOGRAPHED],
               "-o", str(out)])
    data = {n: json.loads((out / n / "tolerance.json").read_text()) for n in PHOTOGRAPHED}
    return rc, data


def test_the_photographed_builds_pass_with_a_margin(photographed):
    rc, data = photographed
    assert rc == 0
    for name, d in data.items():
        assert not d["flagged"], name
        assert d["margin"] >= 1.0 and d["keep_fraction"] >= 0.95, name
        for c in d["criteria"]:
            assert c["kept_fraction"] >= 0.95, (name, c["criterion"])
            if c["criterion"] != "order":
                assert c["missing"] <= 0.05 * d["samples"], (name, c["criterion"])


def test_the_super_stable_chain_keeps_its_crystals_its_front_and_its_end(photographed):
    d = photographed[1]["super_stable_chain"]
    b = d["behaviour"]
    assert b["criteria"] == ["crystals", "order", "end state"] and b["order"] == "left to right"
    start, end = b["crystals"]
    assert start["value"] == pytest.approx(math.sqrt(3), abs=1e-12)
    assert end["value"] == pytest.approx(1.0099504938, abs=1e-9) and end["slope"] > 3.9
    # the target sits 1e-12 above D2*: the motion's end is the lock right past it
    assert b["end_at"] == "lock" and abs(b["end_drive"] - 1.009950493837208) < 1e-11
    c = _criteria(d)
    lo, hi = c["crystals"]["detail"]["slopes"]["1.73205"]
    assert -0.1 < lo <= hi < 0.1  # every built D1* attracts (|f'| < 1): still nearly super-stable
    lo, hi = c["end state"]["detail"]["slopes"]
    assert lo > 2.0  # every built D2* repels (|f'| > 1)
    for name in ("crystals", "end state"):  # within a fraction of a millimetre
        assert c[name]["p95_mm"] < 1.0 < c[name]["limit_mm"]
    assert d["observed_order"]["monotone_fraction"] == 1.0


def test_the_sheets_keep_the_flat_and_the_folded_crystal(photographed):
    data = photographed[1]
    sheet = data["origami_sheet"]["behaviour"]
    flat, folded = sheet["crystals"]
    assert flat["at_turning_point"] and flat["value"] == pytest.approx(math.sqrt(2))
    assert folded["value"] == pytest.approx(2 - math.sqrt(2)) and folded["slope"] > 10
    lo, _ = _criteria(data["origami_sheet"])["end state"]["detail"]["slopes"]
    assert lo > 1.0  # the folded crystal stays repelling in every build
    chain = data["origami_chain12"]["behaviour"]
    assert chain["order"] == "left to right" and chain["modules"] == 12
    assert [c["role"] for c in chain["crystals"]] == ["start", "end"]
    assert chain["crystals"][1]["at_turning_point"]  # every sheet ends flat: where it locks


def test_the_printed_modules_end_where_they_lock(photographed):
    data = photographed[1]
    for name in ("printed_planar", "printed_planar_chain10"):
        b = data[name]["behaviour"]
        assert b["crystals"][0]["value"] == pytest.approx(4.0)
        assert b["end_at"] == "lock" and b["end_lock"][0] == pytest.approx(1.1843716, abs=1e-6)
        c = _criteria(data[name])["end state"]
        assert c["p95_mm"] < c["limit_mm"] and c["missing"] <= 0.02 * data[name]["samples"]
    assert data["printed_planar_chain10"]["behaviour"]["order"] == "left to right"


# --- real failures --------------------------------------------------------------------------

def test_the_chaotic_chain_stays_flagged():
    d = load_template(TEMPLATES / "chaotic_chain.toml")
    res = analyse_tolerance(d, tolerance_spec(d, samples=100), attribute=False)
    b = res.behaviour
    assert b.end == "ports" and b.chaos["lyapunov"] == pytest.approx(0.312, abs=0.02)
    assert res.flagged and res.margin["value"] < 1.0
    hz = res.horizon
    # the bars' 0.05 mm length errors alone (the play is a freedom, not an error) outgrow the
    # limit after ln(limit / error) / λ modules: about the chain's length
    assert hz["limit_modules"] == pytest.approx(
        np.log(res.limits[0] / hz["error_mm"]) / b.chaos["lyapunov"], rel=1e-9)
    assert hz["limit_modules"] < 16
    p95 = np.asarray(res.judged["end ports"].detail["p95_by_port_mm"])
    assert p95[res.ports.index("d13")] > 10 * res.limits[0]
    # among the builds that get to the target, errors grow along the chain past the limit
    err = np.percentile(res.port_errors_mm(), 95, axis=0)
    chain = [res.ports.index(f"d{k}") for k in range(2, 14)]
    assert err[chain[0]] < res.limits[0] < err[chain[-1]]
    assert err[chain[6:]].mean() > 5 * err[chain[:6]].mean()


def test_a_super_stable_chain_with_20_mm_bar_errors_is_flagged(tmp_path):
    rc = main(["tolerance", str(TEMPLATES / "super_stable_chain.toml"), "--samples", "40",
               "--set", "tolerance.length_sigma=20", "-o", str(tmp_path)])
    d = json.loads((tmp_path / "super_stable_chain" / "tolerance.json").read_text())
    assert rc == 1 and d["flagged"] and d["margin"] < 1.0
    c = _criteria(d)
    # its modules lose their crystals: none of their kind within a quarter of the travel
    assert c["crystals"]["kept_fraction"] < 0.2 and c["crystals"]["missing"] > 30
    assert c["end state"]["kept_fraction"] < 0.2


def _touching_chain():
    text = (f'[chain]\nmodule = "{(TEMPLATES / "velocity_design_example.toml").as_posix()}"\n'
            "copies = 6\nmirror = \"alternate\"\n[motion]\nto = 1.45\n")
    return parse_template(text, Path("touching_chain.toml"))


def test_a_fixed_point_that_vanishes_under_small_errors_is_flagged():
    d = _touching_chain()
    # the module's map touches the diagonal at √3 with slope 1: f(d) - d >= 0 on both sides
    f = module_map(d.network.assembly.copies[0][0])
    q = math.sqrt(3) + np.linspace(-0.1, 0.1, 21)
    assert np.all(f(q) - q >= -1e-12) and f.derivative(math.sqrt(3)) == pytest.approx(1.0)
    exact = analyse_tolerance(d, tolerance_spec(d, samples=20, length_sigma=0.0,
                                                kerf_sigma=0.0, hole_clearance=0.0,
                                                thickness_sigma=0.0), attribute=False)
    assert exact.judged["crystals"].ok.all() and not exact.flagged
    for sigma in (0.05, 0.0005):  # the defaults, and a hundred times finer bars alone
        spec = tolerance_spec(d, samples=100, length_sigma=sigma, kerf_sigma=0.0,
                              hole_clearance=0.0, thickness_sigma=0.0)
        res = analyse_tolerance(d, spec, attribute=False)
        crystals = res.judged["crystals"]
        missing = np.mean(~np.isfinite(crystals.value_mm))
        assert missing > 0.8  # in most builds one of the six modules has lost it
        assert res.flagged and res.margin["bound"] == "below"


# --- the margin -----------------------------------------------------------------------------

ERRORS = ("length_sigma", "kerf_sigma", "hole_clearance", "thickness_sigma")


def test_the_margin_is_the_factor_by_which_every_error_may_grow():
    d = load_template(TEMPLATES / "fourbar.toml")
    spec = tolerance_spec(d, samples=100, limit=1.0)
    res = analyse_tolerance(d, spec, attribute=False)
    m = res.margin["value"]
    assert 1.0 <= m < 10.0 and not res.flagged
    # the fraction of builds kept at scale 1 is the verdict's own
    curves = res.margin["curves"]
    one = int(np.argmin(np.abs(np.asarray(curves["scales"]) - 1.0)))
    assert curves["all"][one] == pytest.approx(res.keep_fraction)
    # every error twice as large: the margin halves (to the bisection's resolution)
    double = analyse_tolerance(d, replace(spec, **{k: 2 * getattr(spec, k) for k in ERRORS}),
                               attribute=False)
    assert double.margin["value"] == pytest.approx(m / 2, rel=0.2)
    # the margin is where 95% of the builds' own critical scales lie above
    crit = np.sort(res.critical)[::-1]
    assert crit[94] == pytest.approx(m)
    # errors grown past the margin flag the design; below it, they do not
    past = analyse_tolerance(d, replace(spec, **{k: 1.3 * m * getattr(spec, k)
                                                 for k in ERRORS}), attribute=False)
    below = analyse_tolerance(d, replace(spec, **{k: 0.85 * m * getattr(spec, k)
                                                  for k in ERRORS}), attribute=False)
    assert past.flagged and past.margin["value"] < 1.0
    assert not below.flagged and below.margin["value"] >= 1.0


def test_every_source_has_its_own_curve_and_margin():
    d = load_template(TEMPLATES / "super_stable_chain8.toml")
    res = analyse_tolerance(d, tolerance_spec(d, samples=40))
    curves = res.margin["curves"]
    # the laser's error sources; its hole play is a freedom of the assembly, not an error
    assert set(curves) == {"scales", "all", "bar length", "kerf"}
    assert curves["scales"][0] == pytest.approx(0.1) and curves["scales"][-1] == pytest.approx(10)
    for name in ("all", "bar length", "kerf"):
        y = np.asarray(curves[name])
        assert np.all(np.diff(y) <= 0) and 0.0 <= y.min() <= y.max() <= 1.0
    svg = keep_chart_svg(res.as_dict())
    assert svg.count("<polyline") == 3 and svg.startswith("<svg")


# --- the pieces -----------------------------------------------------------------------------

def test_a_second_front_breaks_the_order():
    b = load_template(TEMPLATES / "super_stable_chain8.toml")
    res = analyse_tolerance(b, tolerance_spec(b, samples=10), attribute=False)
    beh = res.behaviour
    d0, d1 = beh.crystals[0].value, beh.crystals[1].value
    one = np.array([d1, d1, (d0 + d1) / 2, d0, d0, d0, d0, d0, d0])  # one front
    two = np.array([d1, d1, d0, d0, d1, d1, d0, d0, d0])  # a second front ahead of the first
    lead = profile_order(beh, np.stack([one, two])[:, None, :], list(range(9)))
    assert lead[0] == pytest.approx(0.0) and lead[1] == pytest.approx(1.0)


def test_intent_in_the_template_says_what_cannot_be_inferred():
    base = (f'[chain]\nmodule = "{(TEMPLATES / "super_stable.toml").as_posix()}"\ncopies = 4\n'
            "mirror = \"alternate\"\n[motion]\nto = 1.0099505\n")
    auto = parse_template(base, Path("c.toml"))
    stated = parse_template(base + 'intent = "target"\n', Path("c.toml"))
    a = analyse_tolerance(auto, tolerance_spec(auto, samples=10), attribute=False)
    s = analyse_tolerance(stated, tolerance_spec(stated, samples=10), attribute=False)
    assert a.behaviour.intent == "auto" and a.behaviour.end == "state"
    assert s.behaviour.intent == "target" and s.behaviour.end == "ports"
    assert s.behaviour.end_at == "target"
    bad = parse_template(base + 'intent = "sideways"\n', Path("c.toml"))
    with pytest.raises(TemplateError, match=r"motion\.intent: must be one of auto, target"):
        analyse_tolerance(bad, tolerance_spec(bad, samples=5), attribute=False)


def test_a_sheet_is_made_flat_and_a_print_straight():
    sheet = load_template(TEMPLATES / "origami_sheet.toml")
    res = analyse_tolerance(sheet, tolerance_spec(sheet, samples=5), attribute=False)
    from fabkit.tolerance.placement import process_geometry
    from fabkit.kinematics import make_problem

    m = sheet.motion
    geo = process_geometry(sheet, res.spec, make_problem(sheet.network, m.drive, m.to),
                            res.behaviour.end_config)
    assert geo.sheets is not None and geo.sheets[0].creases.shape == (4, 4)
    builds = sample_builds(geo, replace(res.spec, samples=20), np.random.default_rng(3))
    flat = geo.sheets[0].flat
    for b in range(20):  # every build's bars are those of a flat sheet: it can lie flat
        proj = project_to_lengths(sheet.network.edges, builds.base[b], flat, rtol=1e-13,
                                  max_iter=50)
        assert proj.converged
    # the fold fraction is zero flat, and that of the folded target is its largest crease angle
    x = np.stack([sheet.network.nodes, res.behaviour.end_config])
    w = state_profile(geo, "origami", x, np.arange(5), np.arange(8))
    assert np.all(w[0] == 0.0) and 0.4 < w[1].max() <= 1.0
    printed = load_template(TEMPLATES / "printed_planar.toml")
    net = printed.network
    pgeo = ProcessGeometry(net.nodes, net.edges, net.edge_lengths)
    turn = joint_turns(net.edges, net.nodes, net.nodes[None])
    assert np.all(turn == 0.0)
    assert np.all(state_profile(pgeo, "print", net.nodes[None], np.arange(net.n_nodes),
                                np.arange(net.n_edges)) == 0.0)


def test_report_md_states_the_process_s_own_error_model():
    sheet = load_template(TEMPLATES / "origami_sheet.toml")
    result = analyse_tolerance(sheet, tolerance_spec(sheet, samples=10), attribute=False)
    tol = result.as_dict()
    section = "\n".join(tolerance_markdown(result))
    assert section.startswith("## Tolerance")
    assert "origami: crease position σ 0.5 mm, cut σ 0.2 mm" in section
    assert "bar-length" not in section and "hole clearance" not in section
    assert f"Margin {tol['margin']:.2g}" in section


def test_a_state_fraction_is_a_setting():
    d = load_template(TEMPLATES / "super_stable_chain8.toml")
    assert "state_fraction" in {f.name for f in fields(ToleranceSpec)}
    tight = tolerance_spec(d, {"tolerance": {"state_fraction": 0.05}}, samples=20)
    res = analyse_tolerance(d, tight, attribute=False)
    travel = abs(math.sqrt(3) - res.behaviour.module_end)
    assert res.behaviour.state_tol == pytest.approx(max(0.05 * travel, res.limits[0] / 100.0))
    with pytest.raises(TemplateError, match="state_fraction: must be <= 1, got 2.0"):
        tolerance_spec(d, {"tolerance": {"state_fraction": 2.0}})
