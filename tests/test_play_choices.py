"""Which bars take up a loop's play: ties made explicit, and a build judged by the worst choice."""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
import fabkit.tolerance.analysis as analysis
from fabkit.builds.closure import self_stress_basis
from fabkit.model.network import Network
from fabkit.tolerance import analyse_tolerance, tolerance_spec
from fabkit.tolerance.play_choices import PLAY_CHOICES_MAX, redundant_choices


def test_a_flat_quadrilaterals_four_bars_tie_by_hand():
    # nodes 1 and 3 on the segment 0-2: a flat quadrilateral with one state of self-stress.
    # In tensions (the basis is of the normalised rigidity matrix), every force lies on one
    # line: node 1 gives t01 = t12, node 3 t30 = t23, node 0 t01 = -t30, so |t| is equal in
    # all four bars whatever their lengths, and each bar is a choice
    nodes = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.5, 0.0]])
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    net = Network(nodes, edges, {"d": (0, 2)})
    stresses = self_stress_basis(net, net.nodes)
    assert stresses.shape[1] == 1
    np.testing.assert_allclose(stresses[:, 0] / stresses[3, 0], [-1, -1, 1, 1], atol=1e-12)
    assert [c.tolist() for c in redundant_choices(stresses)] == [[0], [1], [2], [3]]
    # off the line the quadrilateral has no state of self-stress left to choose from
    bent = Network(nodes + [[0, 0], [0, 0.3], [0, 0], [0, -0.2]], edges, {"d": (0, 2)})
    assert self_stress_basis(bent, bent.nodes).shape[1] == 0


def test_hand_stresses_give_every_tied_bar_once_and_a_generic_one_a_single_bar():
    assert [c.tolist() for c in redundant_choices(np.array([[1.0], [-1.0], [1.0], [-1.0]]))] \
        == [[0], [1], [2], [3]]
    assert [c.tolist() for c in redundant_choices(np.array([[0.3], [-0.9], [0.5]]))] == [[1]]
    # two states of self-stress on separate loops, each tied in two bars: 2 x 2 sets
    two = np.array([[1.0, 0], [1.0, 0], [0, 2.0], [0, -2.0], [0, 0.1]])
    assert [c.tolist() for c in redundant_choices(two)] == [[0, 2], [0, 3], [1, 2], [1, 3]]
    # many tied loops stop at the cap, in index order
    many = np.kron(np.eye(6), np.ones((2, 1)))
    got = redundant_choices(many)
    assert len(got) == PLAY_CHOICES_MAX and got[0].tolist() == [0, 2, 4, 6, 8, 10]
    # every set removes every state of self-stress: the rest of the basis has full rank
    for c in got:
        assert np.linalg.matrix_rank(many[c]) == many.shape[1]


@pytest.fixture(scope="module")
def and_gate():
    return fabkit.load_template("and_gate")


def test_the_and_gates_junction_ties_its_four_bars(and_gate):
    net = and_gate.network
    choices = redundant_choices(self_stress_basis(net, net.nodes))
    # the junction: the trunk's module and the branch's last one share the port (20, 23), both
    # flat, so the four bars to nodes 25 and 97 carry the stress equally
    assert sorted(tuple(sorted(net.edges[c[0]].tolist())) for c in choices) == \
        [(20, 25), (20, 97), (23, 25), (23, 97)]


def test_a_build_is_judged_by_the_bar_that_disturbs_its_still_ports_least(and_gate, monkeypatch):
    spec = tolerance_spec(and_gate, samples=10)
    both = analyse_tolerance(and_gate, spec, attribute=False).judged["still ports"].value_mm
    one_by_one = []
    for c in redundant_choices(self_stress_basis(and_gate.network, and_gate.network.nodes)):
        monkeypatch.setattr(analysis, "redundant_choices", lambda s, c=c: [c])
        res = analyse_tolerance(and_gate, spec, attribute=False)
        one_by_one.append(np.asarray(res.judged["still ports"].value_mm))
    # the least over the choices, the search ending at the first choice that leaves the still
    # ports still to round-off (no later one can be judged stiller)
    runs = np.array(one_by_one)
    still_mm = analysis.UNDISTURBED_RTOL * float(and_gate.network.size) * spec.scale
    first_still = np.argmax(runs <= still_mm, axis=0)
    expected = np.where((runs <= still_mm).any(axis=0),
                        runs[first_still, np.arange(runs.shape[1])], runs.min(axis=0))
    np.testing.assert_array_equal(np.asarray(both), expected)
    np.testing.assert_allclose(np.asarray(both), runs.min(axis=0), rtol=0, atol=still_mm)
    # without one of the trunk's junction bars (the first two choices) some locked builds swing
    # the trunk by tenths of a millimetre; without one of the branch's, none moves it
    assert np.max(one_by_one[:2]) > 0.1 and np.max(one_by_one[2:]) < 1e-9
