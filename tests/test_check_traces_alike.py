"""A check traces the rebuilt network as the Motion stage traced the design.

The AND gate starts at a branch point (two infinitesimal motions and a state of self-stress). The
Motion stage traces it at the node step its laser kit's stacking needs
(:func:`fabkit.fab.plans.trace_needs`); traced again at the default step, the same network leaves
its start on another branch (port d3_b 0.72 design units away). An as-built check that traced the
rebuilt network with the template's options only failed every and_gate export ("module_map").
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fabkit.check.motion import compare_motion, design_window
from fabkit.fab.plans import trace_needs
from fabkit.motion import trace_motion
from fabkit.templates import load_template

TEMPLATES = Path(__file__).resolve().parents[1] / "templates"
#: the DXF check's own bound on a port-distance difference, relative to the network's size
MAP_RTOL = 1e-6
#: how far the other branch takes port d3_b (design units): the failure this test guards
OTHER_BRANCH = 0.5


@pytest.fixture(scope="module")
def and_gate():
    design = load_template(TEMPLATES / "and_gate.toml")
    needs = trace_needs({"laser"}, design)
    assert "max_node_step" in needs  # the kit needs a finer trace than the template's
    return design, needs, trace_motion(design, **needs)


def test_the_motion_stage_keeps_the_options_it_traced_with(and_gate):
    design, needs, motion = and_gate
    assert motion.traced
    assert motion.options == needs


def test_the_same_network_retraced_as_the_design_matches(and_gate):
    from fabkit.model.network import Network

    design, _, motion = and_gate
    kit, reference = design_window(design, None, None, motion)
    assert kit.motion.options["max_node_step"] == motion.options["max_node_step"]
    net = design.network
    copy = Network(net.nodes.copy(), net.edges.copy(), net.ports, net.labels)
    cmp = compare_motion(kit, copy, MAP_RTOL, reference)
    assert cmp["trajectory"] is not reference  # traced again: another network object
    assert cmp["ok"], cmp
    assert cmp["worst"] == 0.0  # the same network, the same options: the same numbers
    assert cmp["same_end"]
    assert cmp["trajectory"].n_steps == reference.n_steps == 2196
    assert np.array_equal(cmp["trajectory"].positions, reference.positions)


def test_the_design_s_own_network_is_not_traced_again(and_gate, monkeypatch):
    """A kit whose files give back the design's joints to the bit and its bars in order is the
    network the Motion stage traced: the check takes that trace (the retrace above gives it
    bit for bit); one ulp off, or the bars in another order, and it traces again."""
    from fabkit.check import motion as check_motion
    from fabkit.check.motion import as_traced
    from fabkit.model.network import Network

    design, _, motion = and_gate
    kit, reference = design_window(design, None, None, motion)
    net = design.network
    assert reference.network is net
    assert reference.request["options"] == kit.motion.options
    copy = Network(net.nodes.copy(), net.edges.copy(), dict(net.ports), net.labels)
    assert as_traced(copy, reference) is net
    nudged = net.nodes.copy()
    nudged[5, 1] = np.nextafter(nudged[5, 1], np.inf)
    assert as_traced(Network(nudged, net.edges, net.ports, net.labels), reference) is not net
    turned = net.edges.copy()
    turned[[0, 1]] = turned[[1, 0]]
    assert as_traced(Network(net.nodes, turned, net.ports, net.labels), reference) is not net
    other_ports = {**net.ports, "extra": (0, 2)}
    assert as_traced(Network(net.nodes, net.edges, other_ports, net.labels),
                     reference) is not net

    def refused(*args, **kwargs):
        raise AssertionError("traced again")

    monkeypatch.setattr(check_motion, "trace", refused)
    cmp = compare_motion(kit, as_traced(copy, reference), MAP_RTOL, reference)
    assert cmp["trajectory"] is reference and cmp["ok"] and cmp["worst"] == 0.0
    # the template's own options are not those the reference was traced with: traced again
    with pytest.raises(AssertionError, match="traced again"):
        compare_motion(design, net, MAP_RTOL, reference)


def test_retraced_with_the_template_options_only_it_takes_another_branch(and_gate):
    # what the check did before: the design's own [motion] options, not the Motion stage's
    design, _, motion = and_gate
    _, reference = design_window(design, None, None, motion)
    cmp = compare_motion(design, design.network, MAP_RTOL, reference)
    assert not cmp["ok"]
    assert cmp["worst"] > OTHER_BRANCH


@pytest.mark.parametrize("name", ["super_stable_chain", "and_gate", "fourbar_chain"])
def test_the_clearance_sampling_starts_from_the_compared_trace(name, monkeypatch):
    """The clearance check samples the rebuilt network's motion from the trace the comparison
    made (not a second trace of the same network): the same samples, bit for bit, as tracing
    again; a trace of another method is not taken for it."""
    import dataclasses

    import numpy as np

    from fabkit.check import clearance
    from fabkit.check.clearance import fine_motion
    from fabkit.model.network import Network

    design = load_template(TEMPLATES / f"{name}.toml")
    needs = trace_needs({"laser"}, design)
    kit, reference = design_window(design, None, None, trace_motion(design, **needs))
    net = design.network
    built = Network(net.nodes.copy(), net.edges, net.ports)  # as a check rebuilds it
    cmp = compare_motion(kit, built, MAP_RTOL, reference)
    assert cmp["ok"] and cmp["trajectory"].network is built
    traces, trace = {}, clearance.trace

    def counted(*args, **kwargs):
        traces[key] = traces.get(key, 0) + 1
        return trace(*args, **kwargs)

    monkeypatch.setattr(clearance, "trace", counted)
    key = "again"
    again = fine_motion(built, kit.motion, 10.0, 0.5, floor=2.0)
    key = "reused"
    reused = fine_motion(built, kit.motion, 10.0, 0.5, floor=2.0, traced=cmp["trajectory"])
    traces.setdefault("reused", 0)
    assert np.array_equal(again.positions, reused.positions)
    assert (again.max_step, again.status) == (reused.max_step, reused.status)
    assert traces["reused"] == traces["again"] - 1  # held ports too (the AND gate holds d1)
    other = "projected" if cmp["trajectory"].method == "constructive" else "constructive"
    asked = dataclasses.replace(kit.motion, method=other)
    if other == "constructive":
        return  # a network without a construction order has no constructive trace to compare
    mine = fine_motion(built, asked, 10.0, 0.5, floor=2.0, traced=cmp["trajectory"])
    fresh = fine_motion(built, asked, 10.0, 0.5, floor=2.0)
    assert np.array_equal(mine.positions, fresh.positions)


def test_the_bisection_measures_the_steps_it_makes():
    """The clearance samples are bisected until no joint moves more than the limit between two
    of them; the bisection measures only the steps next to new samples, and what it returns
    keeps the limit everywhere, as measured on the whole sampling afterwards."""
    from fabkit.check.clearance import fine_motion, joint_steps

    design = load_template(TEMPLATES / "super_stable_chain.toml")
    fine = fine_motion(design.network, design.motion, 30.0, 0.02, floor=1.0)
    steps = joint_steps(fine.positions)
    assert fine.n_samples > 10_000
    assert steps.max() <= 0.02 and fine.max_step == steps.max()
    # halving any step would not have been needed: every pair of neighbouring steps of one
    # bisected interval together exceed the limit
    assert (steps[:-1] + steps[1:] > 0.02).mean() > 0.5
