"""Builds with joint play and elastic bars (fabkit.builds), against hand formulas and against
each other: the first-order self-stress test against the nonlinear assembly on random draws, the
elastic stress of a forced bar against σ = E ε, and the AND gate's kit as it goes together."""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from fabkit.builds.assembly import assemble, bar_stress, SETTLE_RTOL
from fabkit.builds.closure import play_ratio, self_stress_basis
from fabkit.builds.materials import MATERIALS, bar_stiffness, process_material
from fabkit.model.network import Network
from fabkit.tolerance import analyse_tolerance, tolerance_spec
from fabkit.tolerance.assembled import assemble_builds
from fabkit.tolerance.placement import process_geometry
from fabkit.tolerance.processes import sample_builds

#: A braced square, 100 mm a side: one state of self-stress through all six bars.
SQUARE = np.array([[0, 0], [100, 0], [100, 100], [0, 100]], float)
BRACED = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3]])


def _lengths(x, edges):
    return np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)


def test_one_self_stress_closes_exactly_when_the_hand_criterion_holds():
    """|w·δL| <= Σ|w_e| c_e decides, checked against the nonlinear assembly on random draws."""
    net = Network(SQUARE, BRACED)
    w = self_stress_basis(net)
    assert w.shape == (6, 1)
    wv = w[:, 0]
    # the hand formula: sides and diagonals of a braced square carry tensions 1 : -√2
    assert np.allclose(np.abs(wv / wv[0]), [1, 1, 1, 1, np.sqrt(2), np.sqrt(2)])
    rng = np.random.default_rng(7)
    L = _lengths(SQUARE, BRACED)
    checked = agree = 0
    for _ in range(300):
        dl = 0.05 * rng.standard_normal(6)
        room = rng.uniform(0.0, 0.03, 6)
        hand = abs(wv @ dl) / (np.abs(wv) @ room)
        if abs(hand - 1.0) < 0.05:  # within second-order terms of the edge: either answer holds
            continue
        assert play_ratio(w, dl, room) == pytest.approx(hand, rel=1e-9)
        a = assemble(BRACED, L + dl, room, SQUARE)
        checked += 1
        agree += a.closes == (hand <= 1.0)
        if a.closes:  # every bar within its own room of its own length
            assert np.all(np.abs(a.lengths - (L + dl)) <= room + 1e-7 * L)
    assert checked > 200 and agree == checked


def test_several_self_stresses_need_a_linear_program():
    """Two braced squares side by side (two states of self-stress): the ratio from the linear
    program closes the build exactly at τ = 1 on the nonlinear network (scaled room)."""
    x = np.vstack([SQUARE, SQUARE[[1, 2]] + [100, 0]])
    edges = np.vstack([BRACED, [[1, 4], [4, 5], [5, 2], [1, 5], [2, 4]]])
    net = Network(x, edges)
    w = self_stress_basis(net)
    assert w.shape[1] == 2
    L = _lengths(x, edges)
    rng = np.random.default_rng(3)
    for _ in range(20):
        dl = 0.05 * rng.standard_normal(edges.shape[0])
        room = np.full(edges.shape[0], 0.01)
        tau = float(play_ratio(w, dl, room))
        assert 0 < tau < np.inf
        assert assemble(edges, L + dl, room * tau * 1.05, x).closes
        assert not assemble(edges, L + dl, room * tau * 0.95, x).closes


def test_a_forced_bar_carries_e_times_its_strain():
    """A bar 0.1 mm too long forced between two corners of a rigid frame (the other five bars a
    million times stiffer): σ = E ε = E · 0.1 / L, compressive."""
    L = _lengths(SQUARE, BRACED)
    rest = L.copy()
    rest[0] += 0.1
    acrylic = MATERIALS["acrylic"]
    k = bar_stiffness(acrylic, 14.5 * 3.0, rest)
    k[1:] *= 1e6
    a = assemble(BRACED, rest, 0.0, SQUARE, stiffness=k)
    assert not a.closes
    sigma = bar_stress(a, rest, acrylic.youngs_mpa)
    hand = -acrylic.youngs_mpa * 0.1 / rest[0]
    assert sigma[0] == pytest.approx(hand, rel=1e-4)
    assert np.all(np.abs(sigma[1:]) < 1e-4 * abs(hand))  # the stiff frame carries it unstrained
    # the force is the same on both sides: the frame's bars carry k ε with their tiny strain
    assert a.energy == pytest.approx(0.5 * k[0] * (0.1 * rest[0] / rest[0]) ** 2, rel=1e-3)


def test_forced_stresses_match_the_first_order_self_stress():
    """With equal play of zero and bars of equal section, the least-energy assembly's tensions
    are t = τ w with τ = -(w·δL) / Σ(w_e² / k_e) (first order)."""
    L = _lengths(SQUARE, BRACED)
    w = self_stress_basis(Network(SQUARE, BRACED))[:, 0]
    dl = np.array([0.02, -0.01, 0.005, 0.0, 0.01, -0.02])
    k = bar_stiffness(MATERIALS["acrylic"], 14.5 * 3.0, L + dl)
    a = assemble(BRACED, L + dl, 0.0, SQUARE, stiffness=k)
    tension = k * a.excess
    tau = -(w @ dl) / np.sum(w ** 2 / k)
    assert np.allclose(tension, tau * w, rtol=2e-3, atol=1e-6 * np.abs(tau * w).max())


def test_a_network_without_self_stress_takes_its_own_lengths():
    """No loop to close: every build goes together with each bar at its own length (the play is
    not used to pull the build back to the design)."""
    net = fabkit.load_template("fourbar").network
    x = net.nodes * 100.0
    L = net.edge_lengths * 100.0
    assert self_stress_basis(net).shape[1] == 0
    dl = np.array([0.05, -0.08, 0.02, 0.1])
    a = assemble(net.edges, L + dl, 0.2, x)
    assert a.closes
    assert np.allclose(a.lengths, L + dl, atol=1e-6)


@pytest.fixture(scope="module")
def and_gate():
    return fabkit.load_template("and_gate")


def _builds(design, **overrides):
    spec = tolerance_spec(design, samples=40, **overrides)
    geo = process_geometry(design, spec, None, None)
    return spec, sample_builds(geo, spec, np.random.default_rng(spec.seed))


def test_the_and_gate_kit_goes_together_with_its_play(and_gate):
    spec, builds = _builds(and_gate)
    asm = assemble_builds(and_gate.network, builds, spec, and_gate.network.nodes)
    assert asm.self_stresses == 1
    assert asm.closes.mean() >= 0.95
    assert asm.model == "play"
    assert asm.sentence().startswith(f"{int(asm.closes.sum())} of 40 builds assemble")
    assert asm.loop_nodes == [20, 23, 25, 97]


def test_small_play_agrees_with_the_first_order_criterion(and_gate):
    """Bar-length errors only, 0.02 mm of play: the nonlinear assembly closes the builds the
    self-stress criterion closes (the fraction within the Monte Carlo's noise, build by build
    here); with no play none closes and the stress it takes is named in MPa."""
    spec, builds = _builds(and_gate, kerf_sigma=0.0, hole_clearance=0.02)
    asm = assemble_builds(and_gate.network, builds, spec, and_gate.network.nodes)
    first = asm.ratio <= 1.0
    assert 0.2 < first.mean() < 0.9
    assert abs(asm.closes.mean() - first.mean()) <= 2 * np.sqrt(0.25 / 40)
    assert np.mean(asm.closes == first) >= 0.95
    spec0, builds0 = _builds(and_gate, kerf_sigma=0.0, hole_clearance=0.0)
    none = assemble_builds(and_gate.network, builds0, spec0, and_gate.network.nodes)
    assert not none.closes.any()
    assert none.model == "elastic"
    assert (none.stress_mpa > 0).all() and (none.stress_mpa < 15.0).all()
    assert "MPa" in none.sentence() and "0 of 40 builds assemble" in none.sentence()


def test_the_tolerance_analysis_reports_assembly_and_slop(and_gate, monkeypatch):
    import fabkit.tolerance.analysis as analysis

    settles = []

    def recording(*args, settle=None, **kwargs):
        settles.append(settle)
        return assemble_builds(*args, settle=settle, **kwargs)

    monkeypatch.setattr(analysis, "assemble_builds", recording)
    res = analyse_tolerance(and_gate, tolerance_spec(and_gate, samples=20), attribute=False)
    # the main run's builds are reported where they sit: polished; the margin's runs only say
    # which builds keep the behaviour: settled once they close
    assert settles[0] is None and len(settles) >= 2
    assert all(s == SETTLE_RTOL for s in settles[1:])
    d = res.as_dict()
    assert d["assembly"]["assemble"] >= 19 and d["assembly"]["self_stresses"] == 1
    assert "builds assemble within their play" in d["verdict"]
    assert d["model_level"] == "play"
    # put together, every build collapses its branch (to the target, or until its loop runs
    # out of play: a lock) while the trunk stays still: the gate is judged by that switch
    assert d["behaviour"]["criteria"] == ["driven state", "still ports"]
    assert not res.flagged and res.keep_fraction == 1.0
    state = res.judged["driven state"]
    assert state.detail["designed"] == 13
    assert 0 < min(state.detail["switched"]) <= max(state.detail["switched"]) <= 13
    assert "the driven chain's front ends" in d["verdict"]
    # the trunk stays still (round-off): of the junction's four tied bars, the branch's give
    # way (tests/test_play_choices.py), the same with any number of BLAS threads
    assert float(np.max(res.judged["still ports"].value_mm)) < 1e-9


def test_an_and_gate_cut_twenty_times_worse_is_flagged_for_the_builds_it_cannot_force(and_gate):
    # bar lengths to σ 1 mm: the loop's misfit outgrows 0.2 mm of play, and some builds need
    # more than acrylic's 15 MPa to be forced together
    spec = tolerance_spec(and_gate, {"tolerance": {"length_sigma": 1.0}}, samples=10)
    res = analyse_tolerance(and_gate, spec, attribute=False)
    a = res.as_dict()["assembly"]
    assert res.flagged and a["not_buildable"] > 0 and a["model"] == "elastic"
    assert f"{a['not_buildable']} cannot be put together" in res.verdict
    assert res.keep_fraction <= 1 - a["not_buildable"] / 10


def test_a_settled_build_closes_where_a_polished_one_does_within_its_own_room(and_gate):
    """At ten times a laser kit's errors the AND gate's builds close, then trade bars at the
    edges of their play for many steps; settled once closed (the margin's runs), each closes
    exactly when the polished assembly closes it, every bar within its own room of its own
    length (measured here from the pins), in fewer steps; a build that never closes is
    untouched."""
    spec, builds = _builds(and_gate)
    builds = sample_builds(process_geometry(and_gate, spec, None, None), spec,
                           np.random.default_rng(spec.seed), gain=np.full(40, 10.0)).select(
        np.arange(12))
    net = and_gate.network
    s = spec.scale
    material = process_material(spec.process, spec.material)
    x0 = net.nodes * s
    steps = {None: 0, SETTLE_RTOL: 0}
    for b in range(12):
        rest, room = builds.base[b] * s, builds.room[b] * s
        k = bar_stiffness(material, spec.section_mm2, rest)
        polished = assemble(net.edges, rest, room, x0, stiffness=k)
        settled = assemble(net.edges, rest, room, x0, stiffness=k, settle=SETTLE_RTOL)
        steps[None] += polished.iterations
        steps[SETTLE_RTOL] += settled.iterations
        assert settled.closes == polished.closes
        if settled.closes:
            misfit = np.abs(_lengths(settled.positions, net.edges) - rest)
            assert np.all(misfit <= room + 1e-7 * rest)
        else:
            assert np.array_equal(settled.positions, polished.positions)
    assert steps[SETTLE_RTOL] < 0.8 * steps[None]


def test_a_settled_build_still_reaches_its_held_distance():
    """Settling waits for the held pairs too: a four-bar whose first bar is 0.3 mm long, with
    0.2 mm of play per bar, held at a diagonal of 130 mm, closes at that diagonal either way."""
    rest = np.array([100.3, 100.0, 100.0, 100.0])
    four = BRACED[:4]
    for settle in (None, SETTLE_RTOL):
        a = assemble(four, rest, 0.2, SQUARE, held=[(0, 2)], targets=[130.0], settle=settle)
        assert a.closes
        assert abs(float(np.linalg.norm(a.positions[0] - a.positions[2])) - 130.0) <= 1e-7 * 130
        assert np.all(np.abs(_lengths(a.positions, four) - rest) <= 0.2 + 1e-7 * rest)


def test_port_states_are_judged_from_hand_numbers():
    from fabkit.tolerance.criteria import judge_port_states

    # ports: driven d1_b (1.7 -> 1.0), d2_b of the driven chain (free), trunk d1 (kept still);
    # 10 mm per unit, limit 1 mm, state tolerance 2 mm
    start = np.array([1.7, 1.7, 1.2])
    end = np.array([1.0, 1.5, 1.2])
    starts = np.array([[1.7, 1.7, 1.2], [1.7, 1.7, 1.2], [1.7, 1.7, 1.2], [np.nan] * 3])
    finals = np.array([[1.05, 1.0, 1.25],   # 0.5 mm off its end state; trunk moved 0.5 mm
                       [1.3, 1.75, 1.2],    # stopped 3 mm short
                       [1.0, 1.0, 1.35],    # trunk moved 1.5 mm
                       [np.nan] * 3])       # never got there
    state, still = judge_port_states(starts, finals, start, end, 0, [True, True, False], 10.0,
                                     1.0, 2.0)
    assert state.value_mm[:3] == pytest.approx([0.5, 3.0, 0.0])
    assert state.ok.tolist() == [True, False, True, False]
    assert still.value_mm[:3] == pytest.approx([0.5, 0.0, 1.5])
    assert still.ok.tolist() == [True, True, False, False]
    assert still.detail["still_columns"] == [2]
    # ports that move in the design (travel > limit): d1_b and d2_b; each build's count at
    # their end state (within 2 mm): d2_b ends at 1.0, 5 mm from its designed 1.5
    assert state.detail["designed"] == 2
    assert state.detail["switched"] == [1, 0, 1, -1]


def test_fourbar_chain_reports_its_slop_at_the_far_end():
    """Four crossed 4-bars, 0.2 mm of play per bar, drive held at the start: each module adds
    0.2·(2 + 2√2) mm at its far port (the closed form of tests/test_slop.py), 3.86 mm at d5."""
    d = fabkit.load_template("fourbar_chain")
    res = analyse_tolerance(d, tolerance_spec(d, samples=10), attribute=False)
    slop = res.as_dict()["slop"]
    assert slop["output"] == "d5"
    assert slop["output_start_mm"] == pytest.approx(4 * 0.2 * (2 + 2 * np.sqrt(2)), rel=1e-9)
    assert slop["growth_mm_per_module"] == pytest.approx(0.2 * (2 + 2 * np.sqrt(2)), rel=1e-6)
    assert res.as_dict()["assembly"]["model"] == "rigid"


def test_a_super_stable_chain_keeps_each_modules_slop_its_own():
    # slope 0 at the start crystal: a module's play does not reach the next module's port
    d = fabkit.load_template("super_stable_chain")
    res = analyse_tolerance(d, tolerance_spec(d, samples=4), attribute=False)
    slop = res.as_dict()["slop"]
    assert "it does not grow along the chain" in slop["sentence"]
    assert abs(slop["growth_mm_per_module"]) * slop["modules"] < 0.01 * slop["chain_slop_mm"]


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="room"):
        assemble(BRACED, _lengths(SQUARE, BRACED), -0.1, SQUARE)
    with pytest.raises(ValueError, match="x0"):
        assemble(BRACED, _lengths(SQUARE, BRACED), 0.1, SQUARE[:, :1])
    for settle in (0.0, -1e-2, np.nan, np.inf):
        with pytest.raises(ValueError, match="settle"):
            assemble(BRACED, _lengths(SQUARE, BRACED), 0.1, SQUARE, settle=settle)
    with pytest.raises(ValueError, match="room"):
        play_ratio(np.ones((6, 1)), np.zeros(6), np.full(6, np.nan))
    with pytest.raises(ValueError, match="no bar material"):
        process_material("origami")


def test_the_sparse_first_order_test_is_the_basis_test():
    # the LP in (u, s, t) without the basis gives the same play ratio as |w·δL| / Σ|w_e| c_e
    # (one state, the AND gate) and as the LP over 72 states (a 10 x 10 4-bar lattice)
    from fabkit.bench.large import lattice
    from fabkit.builds.closure import play_ratio_sparse

    rng = np.random.default_rng(3)
    for net in (fabkit.load_template("and_gate").network, lattice(10)):
        L = net.edge_lengths
        gap = rng.normal(0.0, 5e-4, (4, L.size)) * L
        room = 1e-3 * L
        basis = play_ratio(self_stress_basis(net), gap, room)
        assert play_ratio_sparse(net, gap, room) == pytest.approx(basis, rel=1e-6)
    # no room where the misfit is: no play closes it
    sq = Network(SQUARE, BRACED)
    assert play_ratio_sparse(sq, [1.0, 0, 0, 0, 0, 0], 0.0) == np.inf
    assert play_ratio_sparse(sq, [0.0] * 6, 0.0) == 0.0
    with pytest.raises(ValueError, match="gap"):
        play_ratio_sparse(sq, [0.0] * 5, 0.1)
