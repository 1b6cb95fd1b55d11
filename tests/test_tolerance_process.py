"""Tolerance per process: each process's error model, its units and scale, the batch placement
of many builds, and verdicts that name the error source that stops a design."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fabkit.errors import TemplateError
from fabkit.kinematics import make_problem, place
from fabkit.templates import load_template
from fabkit.tolerance import ToleranceSpec, analyse_tolerance, design_process, tolerance_spec
from fabkit.motion.modules import find_plan
from fabkit.tolerance.placement import _place_builds
from fabkit.tolerance.processes import ProcessGeometry, sample_lengths

TEMPLATES = Path(__file__).resolve().parents[1] / "templates"


@pytest.fixture(scope="module")
def chain10():
    return load_template(TEMPLATES / "printed_planar_chain10.toml")


@pytest.fixture(scope="module")
def sheet():
    return load_template(TEMPLATES / "origami_sheet.toml")


def test_each_design_speaks_in_its_own_process_and_scale(chain10, sheet):
    fourbar = load_template(TEMPLATES / "fourbar.toml")
    assert design_process(fourbar) == "laser"
    p = tolerance_spec(chain10)
    assert (p.process, p.scale, p.hinge_length) == ("print", 4.0, 4.0)
    assert (p.shrinkage, p.shrinkage_sigma) == (0.006, 0.002)  # TPU
    o = tolerance_spec(sheet)
    assert o.process == "origami"
    assert o.scale == pytest.approx(150.0 / math.sqrt(2.0))  # sheet_size over the diagonal BD


def test_a_key_of_another_process_is_refused_with_its_name(chain10):
    with pytest.raises(TemplateError) as err:
        tolerance_spec(chain10, {"tolerance": {"kerf_sigma": 0.1}})
    assert "--set tolerance.kerf_sigma: is a laser error; this design is analysed as print" \
        in str(err.value)
    assert tolerance_spec(chain10, {"tolerance": {"process": "laser",
                                                  "kerf_sigma": 0.1}}).kerf_sigma == 0.1


def test_shrinkage_alone_scales_every_bar_by_one_factor_per_build():
    nodes = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    edges = np.array([[0, 1], [1, 2], [0, 2]])
    L = np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)
    spec = ToleranceSpec(process="print", scale=10.0, samples=20000, shrinkage=0.004,
                         shrinkage_sigma=0.001)
    built = sample_lengths(ProcessGeometry(nodes, edges, L), spec, np.random.default_rng(0),
                           sources=["shrinkage"])
    ratio = built / L
    np.testing.assert_allclose(ratio, ratio[:, :1] * np.ones((1, 3)), rtol=1e-12)
    none = sample_lengths(ProcessGeometry(nodes, edges, L), spec, np.random.default_rng(0),
                          sources=())
    np.testing.assert_array_equal(none, np.broadcast_to(L, (20000, 3)))  # one row per build
    assert 1 - ratio[:, 0].mean() == pytest.approx(0.004, abs=3e-5)
    assert ratio[:, 0].std() == pytest.approx(0.001, rel=0.03)


def test_hinge_flexure_shortens_bars_by_the_arc_chord_at_each_joint():
    nodes = np.array([[0.0, 0.0], [3.0, 0.0]])
    edges = np.array([[0, 1]])
    turn = np.array([np.pi / 2, 0.0])  # only joint 0 turns, by 90 degrees
    spec = ToleranceSpec(process="print", scale=10.0, samples=3, hinge_length=4.0)
    built = sample_lengths(ProcessGeometry(nodes, edges, np.array([3.0]), turn), spec,
                           np.random.default_rng(0), sources=["hinge flexure"])
    half = np.pi / 4
    loss_mm = 0.5 * 4.0 * (1 - math.sin(half) / half)
    np.testing.assert_allclose(built[:, 0], 3.0 - loss_mm / 10.0, rtol=1e-12)


def test_crease_position_error_grows_linearly_in_the_origami_sheet(sheet):
    quiet = dict(cut_sigma=0.0, paper_thickness=0.0, compliance_sigma=0.0)
    errs = []
    for sigma in (0.05, 0.1):
        res = analyse_tolerance(sheet, tolerance_spec(sheet, samples=100, crease_sigma=sigma,
                                                      **quiet), attribute=False)
        assert res.method == "constructive" and res.reached.all()
        errs.append(res.port_errors_mm()[:, res.ports.index("d2")].std())
    assert errs[1] / errs[0] == pytest.approx(2.0, rel=0.05)
    exact = analyse_tolerance(sheet, tolerance_spec(sheet, samples=10, crease_sigma=0.0,
                                                    **quiet))
    assert np.abs(exact.port_errors_mm()).max() < 1e-9


@pytest.mark.parametrize("name", ["fourbar_chain", "origami_chain12"])
def test_builds_are_placed_by_the_one_placement_with_radii_per_column(name):
    d = load_template(TEMPLATES / f"{name}.toml")
    m = d.motion
    problem = make_problem(d.network, m.drive, m.to, hold=m.hold)
    plan = find_plan(problem, d.trace())
    eidx = plan.edge_index(problem.work)
    values = np.linspace(problem.start_drive, m.to, 7)
    # the plan's own radii given per column: the same bits as the plain placement
    X0, m0, w0 = place(plan, values)
    X1, m1, w1 = place(plan, values, radii=np.broadcast_to(plan.radii, (7,) + plan.radii.shape))
    assert np.array_equal(X0, X1) and np.array_equal(m0, m1) and np.array_equal(w0, w1)
    # four builds with their own bar lengths, placed together = one plan per build
    rng = np.random.default_rng(5)
    noise = rng.standard_normal((4, problem.work.n_edges))
    lengths = problem.work.edge_lengths * (1 + 1e-3 * noise)
    radii = np.where(eidx >= 0, lengths[:, np.maximum(eidx, 0)], 0.0)
    X, margin = _place_builds(plan, np.broadcast_to(values, (4, 7)), radii)
    for s in range(4):
        Xs, ms, _ = place(replace(plan, radii=radii[s]), values)
        np.testing.assert_allclose(X[s], Xs, atol=1e-12)
        np.testing.assert_allclose(margin[s], ms, atol=1e-12)
        # where the build assembles, its bars have its own lengths, to round-off
        ok = margin[s] >= 0
        assert ok[0]
        used = np.unique(eidx[eidx >= 0])
        e = problem.work.edges[used]
        got = np.linalg.norm(X[s][ok][:, e[:, 0]] - X[s][ok][:, e[:, 1]], axis=-1)
        assert np.abs(got - lengths[s, used]).max() < 1e-12 * lengths.max()
    with pytest.raises(ValueError, match=r"radii must have shape"):
        place(plan, values, radii=radii[0])


def test_each_process_speaks_its_own_units_and_error_model(chain10):
    printed = analyse_tolerance(chain10, tolerance_spec(chain10, samples=40), attribute=False)
    d = printed.as_dict()
    assert d["process"] == "print" and d["scale_mm"] == 4.0
    assert d["model"].startswith("print: xy accuracy σ 0.1 mm")
    # 2 % of the module size, at 4 mm per unit: the mean of the first module's two port
    # distances (d1, d2) at the target (every module of the chain is a copy of it)
    at_target = chain10.trace().final
    pairs = np.array([chain10.network.port(p) for p in ("d1", "d2")])
    mean = np.linalg.norm(at_target[pairs[:, 0]] - at_target[pairs[:, 1]], axis=-1).mean()
    assert d["ports"][0]["limit_mm"] == pytest.approx(0.02 * mean * 4.0)
    assert set(d["errors"]) == {"xy_sigma", "shrinkage", "shrinkage_sigma", "line_width_sigma",
                                "hinge_length"}


def test_verdicts_name_the_source_that_stops_the_design():
    d = load_template(TEMPLATES / "super_stable_chain8.toml")
    # bar lengths a hundred times less precise than a laser cuts them: only they stop it
    res = analyse_tolerance(d, tolerance_spec(d, samples=60, length_sigma=5.0))
    alone = res.margin["sources"]
    assert res.flagged and res.margin["value"] < 1
    assert alone["bar length"]["value"] < 1
    assert set(alone) == {"bar length", "kerf"}  # hole play is a freedom, not an error
    assert alone["kerf"]["value"] >= 1
    # each source's curve falls where its margin says (fraction of builds kept at scale 1)
    curves = res.margin["curves"]
    one = curves["scales"].index(1.0) if 1.0 in curves["scales"] else \
        int(np.argmin(np.abs(np.asarray(curves["scales"]) - 1.0)))
    assert curves["bar length"][one] < 0.95 <= curves["kerf"][one]
