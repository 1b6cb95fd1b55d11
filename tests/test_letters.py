"""Inverse curvature design: the zigzag model against simulated chains, curve fits, glyphs and
the ``fabkit letters`` command."""

from __future__ import annotations

import json

import numpy as np
import pytest

import fabkit
from fabkit.design.assemble import chain
from fabkit.cli import main
from fabkit.errors import DesignError, FabkitError
from fabkit.design.letters import (GLYPHS, chain_centerline, curvature_modules, design_curve,
                            design_word, glyph, polyline_distance, strip_model)
from fabkit.model.rigidity import count_modes
from fabkit.templates import load_template

from conftest import TEMPLATES

D2 = 1.5 * np.sqrt(3.0)
NAMES = ("contract", "maintain", "expand")


@pytest.fixture(scope="module")
def nets():
    return {n: load_template(TEMPLATES / f"curvature_{n}.toml").network for n in NAMES}


@pytest.fixture(scope="module")
def modules(nets):
    return curvature_modules(nets, D2)


def test_module_final_shapes(modules):
    bottoms = {m.name: m.bottom for m in modules}
    assert bottoms["contract"] == pytest.approx(0.87549650, abs=1e-7)
    assert bottoms["maintain"] == pytest.approx(1.69170175, abs=1e-7)
    assert bottoms["expand"] == pytest.approx(D2, abs=1e-9)
    apex = {m.name: np.degrees(m.apex) for m in modules}
    assert apex["contract"] == pytest.approx(19.4, abs=1e-6)
    assert apex["maintain"] == pytest.approx(38.0, abs=1e-6)
    assert apex["expand"] == pytest.approx(60.0, abs=1e-9)


def test_strip_model_matches_simulated_chain(nets, modules):
    rng = np.random.default_rng(3)
    types = rng.integers(0, 3, size=40)
    net = chain([nets[NAMES[t]] for t in types], mirror="alternate")
    traj = fabkit.trace(net, "d1", to=D2, method="constructive", samples=3)
    assert str(traj.status) == "finished" and traj.max_edge_error < 1e-12
    sim = chain_centerline(net, traj.positions[-1], 40)
    model = strip_model(types, modules)
    model_c = 0.5 * (model[:-1] + model[1:])
    # same shape up to a proper rigid motion: compare all pairwise distances
    ds = np.linalg.norm(sim[:, None] - sim[None], axis=-1)
    dm = np.linalg.norm(model_c[:, None] - model_c[None], axis=-1)
    assert float(np.abs(ds - dm).max()) < 1e-9
    # and the same turning sense (no reflection)
    def cross(p):
        a, b = p[1:-1] - p[:-2], p[2:] - p[1:-1]
        return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]

    np.testing.assert_allclose(cross(sim), cross(model_c), atol=1e-9)


def test_turning_rate_of_alternating_modules(modules):
    for seq, turn in (([0, 2] * 10, -40.6), ([2, 0] * 10, 40.6), ([1, 1] * 10, 0.0)):
        q = strip_model(seq, modules)
        c = 0.5 * (q[:-1] + q[1:])
        v = np.diff(c[::2], axis=0)
        a = np.degrees(np.diff(np.unwrap(np.arctan2(v[:, 1], v[:, 0]))))
        np.testing.assert_allclose(a, turn, atol=1e-9)


def test_initial_state_is_straight(nets, modules):
    types = [0, 2, 1, 1, 2, 0, 0, 2]
    net = chain([nets[NAMES[t]] for t in types], mirror="alternate")
    c = chain_centerline(net, net.nodes, len(types))
    d = c - c[0]
    u = d[-1] / np.linalg.norm(d[-1])
    assert float(np.abs(d[:, 0] * u[1] - d[:, 1] * u[0]).max()) < 1e-12


def test_design_circle_arc(modules):
    t = np.linspace(0, np.pi, 60)
    arc = 15.0 * np.column_stack([np.cos(t), np.sin(t)])
    fit = design_curve(arc, modules, beam=48)
    assert fit.rms_error < 0.1 and fit.max_error < 0.4 and fit.end_error < 1.0
    assert len(fit.types) > 40
    np.testing.assert_allclose(polyline_distance(fit.centerline, arc).max(), fit.max_error)


def test_design_straight_line_uses_straight_modules(modules):
    fit = design_curve([[0.0, 0.0], [30.0, 0.0]], modules, beam=24)
    assert fit.max_error < 0.5
    # straight strips: neighbours equal (C-C, M-M, E-E) except where a slip is corrected
    same = np.mean(fit.types[1:] == fit.types[:-1])
    assert same > 0.8


@pytest.mark.parametrize("target, message", [
    ([[0.0, 0.0]], "at least 2 distinct points"),
    ([[0.0, 0.0], [0.0, 0.0]], "at least 2 distinct points"),
    ([1.0, 2.0, 3.0], "must have shape"),
])
def test_design_curve_errors(modules, target, message):
    with pytest.raises(DesignError, match=message):
        design_curve(target, modules)


def test_design_curve_too_long(modules):
    with pytest.raises(DesignError, match="needs more than 20 modules"):
        design_curve([[0.0, 0.0], [100.0, 0.0]], modules, max_modules=20)


def test_curvature_modules_rejects_non_fixed_point(module):
    with pytest.raises(DesignError, match="the final state must be a fixed point d1 = d2"):
        curvature_modules({"fp": module("fixed_point")}, 2.0)


def test_glyphs_and_errors():
    assert set(GLYPHS) == set("ABCDEFGHIJKLMNOPQRSTUVWXYZ")
    g = glyph("N", 40.0)
    assert np.ptp(g[:, 1]) == 40.0
    with pytest.raises(FabkitError, match="no glyph for 'n'"):
        glyph("n")
    with pytest.raises(FabkitError, match="cannot spell '1'"):
        design_word("A1", [])


def test_letters_command_spells_network(tmp_path, capsys):
    out = tmp_path / "letters"
    assert main(["letters", "NETWORK", "-o", str(out)]) == 0
    report = json.loads((out / "network_fit.json").read_text())
    rows = report["letters"]
    assert [r["letter"] for r in rows] == list("NETWORK")
    # fit error of the simulated final states to the target strokes (relative to the height)
    for r in rows:
        assert r["rms_error"] < 0.03 and r["max_error"] < 0.12 and r["end_error"] < 0.01
        assert r["max_edge_error"] < 1e-12
    png = (out / "network.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    printed = capsys.readouterr().out
    assert "worst rms fit error" in printed
    # each template loads next to the copied module templates and moves as designed
    for r in rows:
        design = load_template(out / r["template"])
        net = design.network
        assert net.n_edges == 6 * r["modules"]
        traj = design.trace(samples=3)
        assert str(traj.status) == "finished" and traj.max_edge_error < 1e-12
    m = count_modes(load_template(out / rows[2]["template"]).network)
    assert (m.conformational, m.self_stress) == (1, 0)


@pytest.mark.parametrize("args, message, code", [
    (["letters", "Net"], "WORD: must be capital letters, those with strokes: A", 2),
    (["letters", "AB", "--height", "-2"], "--height must be positive", 2),
    (["letters", "AB", "--modules", "/nonexistent"], "no curvature module template", 1),
])
def test_letters_command_errors(tmp_path, capsys, args, message, code):
    out = tmp_path / "o"
    assert main(args + ["-o", str(out)]) == code
    err = capsys.readouterr().err.strip()
    assert err.startswith("fabkit: error: ") and message in err and "\n" not in err
    assert not out.exists()
