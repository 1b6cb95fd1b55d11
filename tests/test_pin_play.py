"""The play of a pin-jointed print (bars printed in place on pins) in the tolerance analysis.

Every bar end that turns on a printed pin has ``pin_clearance`` of radial play; the end whose body
carries its joint's pin has none. The references here are counted by hand from the print's plan
(which bar carries each pin), the slop of a single 4-bar is checked against a dense first-order
solve and against the nonlinear 4-bar placed at the corners of its play box, and an
over-constrained print goes together within its pins' play as the self-stress criterion says.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

import fabkit
from fabkit.builds.closure import self_stress_basis
from fabkit.fab.pinned import pinned_print
from fabkit.settings.printing import design_print_settings
from fabkit.tolerance import analyse_tolerance, tolerance_spec
from fabkit.tolerance.pins import pin_play
from fabkit.tolerance.placement import process_geometry
from fabkit.tolerance.processes import nominal_room_mm, sample_builds, spec_sources

PINS = {"tolerance": {"process": "print"}, "print": {"linkage": "pins"}}


def _hand_play_ends(design, settings):
    """Per bar, its ends at a joint of two or more bars that it does not carry the pin of."""
    net = design.network
    plan = pinned_print(design, design_print_settings(design, settings))
    degree = np.bincount(net.edges.ravel(), minlength=net.n_nodes)
    ends = []
    for bar, (i, j) in enumerate(net.edges.tolist()):
        ends.append(sum(1 for v in (i, j) if degree[v] >= 2
                        and (v in plan.cut_joints or plan.carrier.get(v) != bar)))
    return ends


def test_the_play_is_at_every_end_but_the_pins_carrier():
    d = fabkit.load_template("fourbar")
    spec = tolerance_spec(d, PINS)
    assert spec.linkage == "pins"
    play = pin_play(d, spec.print_settings)
    assert play.note == ""
    assert play.ends.tolist() == _hand_play_ends(d, PINS)
    # four joints of two bars, one of which carries the pin: four ends turn on a pin
    assert play.ends.sum() == 4
    assert nominal_room_mm(spec, 4, play.ends).tolist() == pytest.approx(0.3 * play.ends)


def test_a_chain_cut_to_fit_the_bed_is_bolted_through_plain_holes():
    # the chain's inner joints (2..7, four bars each) are where the print is cut: every end
    # there turns on the maker's bolt; its end joints carry their pins: 4·1 + 6·4 ends
    d = fabkit.load_template("fourbar_chain")
    spec = tolerance_spec(d, {"tolerance": {"process": "print"}})
    assert spec.linkage == "pins"
    ends = pin_play(d, spec.print_settings).ends
    assert ends.tolist() == _hand_play_ends(d, {})
    assert ends.sum() == 4 * 1 + 6 * 4


def test_no_plan_takes_the_first_bar_and_says_why():
    d = fabkit.load_template("fourbar")
    # a bed smaller than the 4-bar: the plan fails, the analysis goes on and says so
    settings = {**PINS, "print": {"linkage": "pins", "bed": [30.0, 30.0]}}
    spec = tolerance_spec(d, settings, samples=4)
    play = pin_play(d, spec.print_settings)
    assert "could not be made" in play.note and "bed" in play.note
    # joints 0 and 1 are carried by bar 0 (0-2) and bar 2 (1-2), the first bars there;
    # joints 2 and 3 by bars 0 (0-2) and 1 (0-3)
    assert play.ends.tolist() == [0, 1, 1, 2]
    res = analyse_tolerance(d, spec, attribute=False)
    assert res.as_dict()["play_note"] == play.note


def test_a_pin_print_has_no_flexure_and_its_line_width_eats_the_play():
    d = fabkit.load_template("fourbar")
    spec = tolerance_spec(d, PINS, samples=400)
    assert list(spec_sources(spec)) == ["xy accuracy", "shrinkage", "line width"]
    ends = pin_play(d, spec.print_settings).ends
    geo = replace(process_geometry(d, spec, None, None), play_ends=ends)
    exact = sample_builds(geo, spec, np.random.default_rng(0), sources=())
    assert np.array_equal(exact.base, np.broadcast_to(d.network.edge_lengths, (400, 4)))
    assert not exact.bend.any()
    assert np.allclose(exact.room * spec.scale, 0.3 * ends[None, :])
    width = sample_builds(geo, spec, np.random.default_rng(0), sources=["line width"])
    assert np.array_equal(width.base, exact.base)
    # each build's pins w thicker and holes w narrower: the same radial play at every end
    per_end = width.room[:, ends > 0] * spec.scale / ends[ends > 0]
    assert np.ptp(per_end, axis=1).max() < 1e-12
    assert per_end[:, 0].mean() == pytest.approx(0.3, abs=4 * 0.03 / np.sqrt(400))
    assert per_end[:, 0].std() == pytest.approx(0.03, rel=0.15)


def _lambda(x, edges, held, port):
    """∂d_port/∂L_e of a network isostatic with the held pair: one dense solve."""
    n, d = x.shape

    def rows(pairs):
        out = np.zeros((len(pairs), n * d))
        for k, (i, j) in enumerate(pairs):
            u = (x[i] - x[j]) / np.linalg.norm(x[i] - x[j])
            out[k, d * i:d * i + d], out[k, d * j:d * j + d] = u, -u
        return out

    a = np.vstack([rows(edges), rows([held])])
    rhs = np.vstack([np.eye(len(edges)), np.zeros((1, len(edges)))])
    u = np.linalg.lstsq(a, rhs, rcond=None)[0]  # up to a rigid motion, which d_port ignores
    assert np.allclose(a @ u, rhs, atol=1e-12)
    return rows([port])[0] @ u


def _corner_d2(x, lengths):
    """d2 of the 4-bar with nodes 0 and 1 held where they are and bars 0-2, 0-3, 1-2, 1-3 of
    the given lengths, each free node placed on its side of d1 (circle intersections)."""
    base = x[1] - x[0]
    dist = np.linalg.norm(base)
    unit, normal = base / dist, np.array([-base[1], base[0]]) / dist

    def place(k, r0, r1):
        side = np.sign(normal @ (x[k] - x[0]))
        along = (r0 ** 2 - r1 ** 2 + dist ** 2) / (2 * dist)
        return x[0] + along * unit + side * np.sqrt(r0 ** 2 - along ** 2) * normal

    return np.linalg.norm(place(2, lengths[0], lengths[2]) - place(3, lengths[1], lengths[3]))


def test_the_slop_of_a_pin_printed_fourbar_is_the_first_order_sum_and_the_brute_force():
    d = fabkit.load_template("fourbar")
    spec = tolerance_spec(d, PINS, samples=4)
    res = analyse_tolerance(d, spec, attribute=False)
    slop = res.as_dict()["slop"]
    room = 0.3 * pin_play(d, spec.print_settings).ends
    x = d.network.nodes * spec.scale
    lam = _lambda(x, d.network.edges.tolist(), (0, 1), (2, 3))
    assert slop["output"] == "d2"
    assert slop["output_start_mm"] == pytest.approx(float(np.abs(lam) @ room), rel=1e-9)
    assert "radial pin play" in slop["sentence"]
    # the nonlinear 4-bar at every corner of its play box: the largest change of d2 agrees
    # with the first order to second order in the play over the bars' length
    lengths = d.network.edge_lengths * spec.scale
    nominal = _corner_d2(x, lengths)
    moves = [abs(_corner_d2(x, lengths + np.array(s) * room) - nominal)
             for s in itertools.product([-1.0, 1.0], repeat=4)]
    assert max(moves) == pytest.approx(slop["output_start_mm"], rel=0.01)


def test_an_over_constrained_print_is_made_together():
    """A print-in-place linkage is printed assembled: a joint printed off moves every bar at it
    (δL = R δx), shrinkage scales the whole (δL = R (s x)), and a state of self-stress sees
    neither (wᵀR = 0). The AND gate's loop closes with no play to first order, so every
    build goes together and the misfit is of second order in the errors."""
    d = fabkit.load_template("and_gate")
    spec = tolerance_spec(d, {"tolerance": {"process": "print"}}, samples=12)
    res = analyse_tolerance(d, spec, attribute=False)
    a = res.as_dict()["assembly"]
    assert a["self_stresses"] == 1 and a["model"] == "play"
    assert a["assemble"] == 12 and a["first_order_agrees"] == 12
    assert a["material"] == "PLA" and a["not_buildable"] == 0
    # second order: (0.1 mm over ~50 mm bars)² of the loop's play, far below one
    assert a["play_ratio_p95"] < 1e-2
    assert not res.flagged
    # the loop's misfit w·δL against the misfit the same bar errors would make drawn each on
    # its own (Σ|w_e||δL_e|): the first order cancels, what is left is of the order of δL/L
    # (~1e-3) of it
    w = self_stress_basis(d.network)[:, 0]
    builds = sample_builds(process_geometry(d, spec, None, None), spec,
                           np.random.default_rng(spec.seed))
    gap = builds.base - d.network.edge_lengths[None, :]
    assert (np.abs(gap @ w) <= 1e-2 * (np.abs(gap) @ np.abs(w))).all()
