"""Mode counts proved from the construction (fabkit.model.certificate): the same counts as the
numeric rank on every bundled template and on random chains, exact where the numeric rank of a
long straight chain is ambiguous, and the numeric rule where no construction decides."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import fabkit
from fabkit import Network, count_modes
from fabkit.bench import large, paper_module
from fabkit.model.construction import EdgeLookup, cached_plan
from fabkit.errors import ConstructionError
from fabkit.model.rigidity import rigidity_matrix
from fabkit.model.certificate import (MIN_SINE, Uncertified, certify, construction_velocity,
                                       intersection_sines)

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = sorted((ROOT / "templates").glob("*.toml"))


def counts(m):
    return (m.total, m.rigid, m.conformational, m.self_stress)


def mirrored_chain(k):
    """The paper's Fig. 3f design scaled up: the super-stable module, every second mirrored."""
    return fabkit.chain(paper_module("super_stable"), copies=k, mirror="alternate")


@pytest.mark.parametrize("path", TEMPLATES, ids=lambda p: p.stem)
def test_every_bundled_template_is_certified_and_agrees_with_the_numeric_rank(path):
    net = fabkit.load_template(path).network
    m = count_modes(net)
    numeric = count_modes(net, method="dense")
    assert counts(m) == counts(numeric)
    assert not m.ambiguous and not numeric.ambiguous
    # every bundled design is proved from its construction, or from parts that have one
    assert m.certificate in ("structure", "substructure")
    assert m.cross_check == "agrees"
    assert MIN_SINE <= m.margin <= 1.0
    proved = count_modes(net, method="structure")
    assert counts(proved) == counts(m) and proved.method == "structure"
    assert math.isnan(proved.gap) and math.isnan(proved.smallest_nonzero)


def test_the_and_gate_is_cut_into_parts():
    m = count_modes(fabkit.load_template(ROOT / "templates" / "and_gate.toml").network)
    assert m.certificate == "substructure" and counts(m) == (5, 3, 2, 1)
    assert m.detail.startswith("4 parts with construction orders (51, 48, 2, 2 nodes)")


def test_margin_is_the_flattest_intersection(fourbar):
    m = count_modes(fourbar)
    # node 2 (1, -1) sees its parents 0 (-1, -1) and 1 (-1, 1) along (-2, 0) and (-2, 2)
    assert m.margin == pytest.approx(1 / math.sqrt(2), abs=1e-15)
    plan = cached_plan(fourbar, (0, 1))
    sines = intersection_sines(fourbar.nodes, plan.order, plan.parents)
    assert sines.tolist() == pytest.approx([1 / math.sqrt(2)] * 2, abs=1e-15)


def _random_module(rng):
    """The super-stable module's topology (nodes 3 and 4 on 0, 1 and 2; ports d1 = (0, 1),
    d2 = (1, 2)) with random positions, mapping d1 to d2 near its own input distance."""
    while True:
        x = np.array([[-0.87, -0.5], [0.0, 1.0], [0.87, -0.5], [-0.3, -0.5], [0.28, 0.51]])
        x = x + 0.15 * rng.standard_normal(x.shape)
        d1, d2 = np.linalg.norm(x[0] - x[1]), np.linalg.norm(x[1] - x[2])
        x[2] = x[1] + (x[2] - x[1]) * d1 / d2  # d2 = d1 in the reference: a chain can start
        try:
            return Network(x, [[0, 3], [1, 3], [2, 3], [0, 4], [1, 4], [2, 4]],
                           ports={"d1": (0, 1), "d2": (1, 2)})
        except fabkit.errors.NetworkError:
            continue


@pytest.mark.parametrize("seed", range(12))
def test_random_chains_count_the_same_as_the_numeric_rank(seed):
    rng = np.random.default_rng(seed)
    module = _random_module(rng)
    k = int(rng.integers(2, 60))
    mirror = [bool(v) for v in rng.integers(0, 2, k)]
    net = fabkit.chain(module, copies=k, mirror=mirror)
    m = count_modes(net)
    numeric = count_modes(net, method="dense")
    assert m.certificate == "structure" and not numeric.ambiguous
    assert counts(m) == counts(numeric) == (4, 3, 1, 0)
    # one extra bar between nodes of two modules changes a distance along the motion: the chain
    # is rigid, and the bar is no self-stress
    i, j = int(net.port("d1")[0]), int(net.port(f"d{k + 1}")[1])
    braced = Network(net.nodes, np.vstack([net.edges, [[i, j]]]), net.ports)
    mb, nb = count_modes(braced), count_modes(braced, method="dense")
    assert mb.certificate == "structure" and "locks the motion" in mb.detail
    assert counts(mb) == counts(nb) == (3, 3, 0, 0)


@pytest.mark.parametrize("k", [3, 4, 6])
def test_lattice_extra_bars_are_self_stresses(k):
    net = large.lattice(k)
    m = count_modes(net)
    numeric = count_modes(net, method="dense")
    assert m.certificate == "structure" and "keep their length" in m.detail
    assert counts(m) == counts(numeric)
    assert (m.conformational, m.self_stress) == (1, (k - 1) * (k - 2))


def test_a_redundant_bar_inside_a_rigid_part_is_a_self_stress(fourbar):
    # 4-bar plus two nodes on the rigid triangle 0-2-4: the bar 4-5 keeps its length
    x = np.vstack([fourbar.nodes, [[0.0, -2.0], [0.5, -1.8]]])
    edges = np.vstack([fourbar.edges, [[0, 4], [2, 4], [0, 5], [2, 5], [4, 5]]])
    net = Network(x, edges, ports={"d1": (0, 1)})
    m = count_modes(net)
    assert m.certificate == "structure" and counts(m) == (4, 3, 1, 1)
    assert counts(count_modes(net, method="dense")) == (4, 3, 1, 1)
    # the same bar to node 3 (which moves relative to 4): the motion is locked
    locked = Network(x, np.vstack([edges[:-1], [[3, 4]]]), ports={"d1": (0, 1)})
    assert counts(count_modes(locked)) == counts(count_modes(locked, method="dense")) == (
        3, 3, 0, 0)


def test_construction_velocity_keeps_the_used_bars():
    net = fabkit.chain(paper_module("chaotic"), copies=30, mirror="alternate")
    plan = cached_plan(net, net.port("d1"))
    v = construction_velocity(net.nodes, plan.seed, plan.order, plan.parents)
    a, b = plan.seed
    assert np.all(v[a] == 0) and np.linalg.norm(v[b]) == pytest.approx(1.0, abs=1e-15)
    # every bar keeps its length to first order (R v = 0, to round-off of the velocities, which
    # the chaotic chain amplifies to 4e4), and the motion is not rigid
    r = rigidity_matrix(net, normalized=True)
    assert np.abs(r @ v.ravel()).max() < 1e-15 * np.abs(v).max()
    assert float(np.linalg.norm(v[net.port("d2")[1]] - v[net.port("d2")[0]])) > 1e-3


def test_three_dimensional_chains_are_certified():
    design = fabkit.load_template(ROOT / "templates" / "origami_chain12.toml")
    m = count_modes(design.network)
    assert m.certificate == "structure" and counts(m) == (7, 6, 1, 0)
    sheet = count_modes(paper_module("origami_sheet"))  # flat: no order, three parts and bars
    assert sheet.certificate == "substructure" and counts(sheet) == (8, 6, 2, 1)


def test_long_straight_chain_is_exact_where_the_numeric_rank_is_ambiguous():
    net = mirrored_chain(10_000)
    m = count_modes(net)
    assert counts(m) == (4, 3, 1, 0) and not m.ambiguous
    assert m.certificate == "structure" and m.margin == pytest.approx(math.sqrt(3) / 2, abs=1e-12)
    # the straight chain bends like a beam: its smallest singular value falls below the
    # numeric rule's resolution, which the cross-check reports
    assert m.cross_check.startswith("undecided: the bounds ")
    assert count_modes(net, method="sparse").ambiguous


def test_hundred_thousand_modules_are_counted_by_structure_alone():
    net = mirrored_chain(100_000)
    m = count_modes(net)
    assert counts(m) == (4, 3, 1, 0) and not m.ambiguous
    assert (m.certificate, m.method) == ("structure", "structure")
    assert math.isnan(m.gap) and m.cross_check.startswith("not run: 600004 coordinates")


def test_a_chain_built_backwards_is_certified_from_its_last_port():
    # the physical 4-bar at its flat D1*: every module is flat from d1, constructible from d2
    net = fabkit.chain(paper_module("physical_fourbar"), copies=200)
    m = count_modes(net)
    assert m.certificate == "structure" and "from d201" in m.detail
    assert counts(m) == counts(count_modes(net, method="sparse")) == (4, 3, 1, 0)


def _triangle(height):
    return Network([[0.0, 0.0], [2.0, 0.0], [1.0, height]], [[0, 1], [1, 2], [0, 2]])


def test_near_flat_constructions_are_left_to_the_numeric_rule():
    assert certify(_triangle(0.5)).kind == "structure"
    with pytest.raises(Uncertified, match="near singular"):
        certify(_triangle(1e-9))  # sine 2e-9, below MIN_SINE: the interface decides, ambiguous
    m = count_modes(_triangle(1e-9))
    assert m.certificate == "numeric" and m.ambiguous
    assert m.detail.startswith("no structural certificate: ")
    with pytest.raises(ConstructionError, match="^no structural count: "):
        count_modes(_triangle(1e-9), method="structure")


def test_edge_lookup_finds_edges_in_either_order():
    edges = np.array([[3, 1], [0, 2], [2, 3]])
    find = EdgeLookup(edges, 4)
    assert find([1, 2, 3, 0], [3, 0, 2, 1]).tolist() == [0, 1, 2, -1]
    assert find(3, 2).tolist() == 2 and find([[0], [2]], [[2], [0]]).tolist() == [[1], [1]]
    assert EdgeLookup(np.zeros((0, 2)), 4)([0, 1], [1, 2]).tolist() == [-1, -1]


def test_edge_lookup_agrees_with_a_dictionary():
    """Random graphs (repeated edges: the first one is found), queried with every pair of
    nodes in both orders, against a dictionary built edge by edge."""
    rng = np.random.default_rng(3)
    for n in (2, 7, 40):
        edges = rng.integers(0, n, size=(3 * n, 2))
        edges = edges[edges[:, 0] != edges[:, 1]]
        first = {}
        for k, (a, b) in enumerate(edges.tolist()):
            first.setdefault(frozenset((a, b)), k)
        i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        got = EdgeLookup(edges, n)(i.ravel(), j.ravel())
        want = [first.get(frozenset((a, b)), -1) if a != b else -1
                for a, b in zip(i.ravel().tolist(), j.ravel().tolist())]
        assert got.tolist() == want



@pytest.mark.parametrize("name, kinds", [("super_stable_chain", 1), ("curvature_chain", 3),
                                         ("fourbar", None)])
def test_a_tiled_plan_knows_its_edges_and_a_wrong_hint_is_refused(name, kinds):
    """A chain's plan tiled from its modules' plans carries the edge of every (node, parent)
    pair, equal to a dictionary lookup pair by pair; a hint that names one wrong edge is
    refused whole, and the certificate with no hint (looked up) is the same, field by field."""
    from dataclasses import replace

    net = fabkit.load_template(ROOT / "templates" / f"{name}.toml").network
    plan = cached_plan(net, net.port("d1"))
    if kinds is None:  # not a chain: planned by the search, with no hint
        assert plan.parent_edges is None and plan.hinted_edges(net.edges) is None
        return
    assert len(net.assembly.modules) == kinds
    by_pair = {frozenset(e): k for k, e in enumerate(net.edges.tolist())}
    want = [[by_pair[frozenset((v, p))] for p in ps]
            for v, ps in zip(plan.order.tolist(), plan.parents.tolist())]
    assert plan.parent_edges.tolist() == want
    assert plan.edge_index(net).tolist() == want  # from the checked hint
    assert replace(plan, parent_edges=None).edge_index(net).tolist() == want  # by dictionary
    assert plan.hinted_edges(net.edges).tolist() == np.ravel(want).tolist()
    for k in (0, len(want) // 2, -1):
        wrong = plan.parent_edges.copy()
        wrong[k] = wrong[k][::-1]  # the node's two bars swapped between its parents
        assert replace(plan, parent_edges=wrong).hinted_edges(net.edges) is None
    past = plan.parent_edges.copy()
    past[0, 0] = net.n_edges
    assert replace(plan, parent_edges=past).hinted_edges(net.edges) is None
    hinted = certify(net)
    net._cache[("construction_plan", tuple(net.port("d1")))] = replace(plan, parent_edges=None)
    assert certify(net) == hinted and hinted.kind == "structure"

@pytest.mark.parametrize("d", [2, 3])
def test_intersection_sines_keep_the_bits_of_the_unit_vectors_formula(d):
    """The sines are the determinant (2D: cross product) of the unit bar directions, each
    direction divided by numpy's norm of it: computed column by column, the same bits."""
    from fabkit.model.certificate import intersection_sines

    rng = np.random.default_rng(d)
    x = rng.standard_normal((400, d)) * 50.0
    order = rng.permutation(400)[:300]
    parents = np.stack([rng.integers(0, 400, 300) for _ in range(d)], axis=1)
    parents[parents == order[:, None]] = 0
    parents[5, 1] = parents[5, 0]  # two bars along one line: a sine of 0
    x[order[7]] = x[parents[7, 0]]  # a bar of no length: a zero direction, not a NaN
    vec = x[parents] - x[order][:, None, :]
    norm = np.linalg.norm(vec, axis=2)
    unit = vec / np.where(norm > 0, norm, 1.0)[..., None]
    want = (np.abs(unit[:, 0, 0] * unit[:, 1, 1] - unit[:, 0, 1] * unit[:, 1, 0]) if d == 2
            else np.abs(np.linalg.det(unit)))
    got = intersection_sines(x, order, parents)
    assert got.tobytes() == want.tobytes()
    assert got[5] == pytest.approx(0.0, abs=1e-12) and np.isfinite(got).all()
