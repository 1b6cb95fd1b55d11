"""Joining networks: chains, sequences, mirroring, general joins (2D and 3D), branches,
tessellations and the template builders."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import fabkit
from fabkit.design.assemble import (branch, build_tessellation, chain, join, join_transform,
                                    tessellate)
from fabkit.errors import BoundsError, FabkitError, TemplateError
from fabkit.model.rigidity import count_modes
from fabkit.templates import TemplateContext, load_template, parse_template

from conftest import TEMPLATES


@pytest.fixture(scope="module")
def super_stable():
    return load_template(TEMPLATES / "super_stable.toml").network


@pytest.fixture(scope="module")
def fourbar_ports():
    return fabkit.Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]],
                          ports={"d1": (0, 1), "d2": (2, 3), "b": (0, 2), "t": (1, 3)})


def signed_area(x, tri):
    a, b, c = x[list(tri)]
    return 0.5 * ((b - a)[0] * (c - a)[1] - (b - a)[1] * (c - a)[0])


def module_blocks(net, module, k):
    """Edge lengths of the chain, module by module (each module's edges in its own order)."""
    return net.edge_lengths.reshape(k, module.n_edges)


# -- chain -------------------------------------------------------------------------------------

def test_chain_ports_and_sizes(fourbar):
    net = chain(fourbar, copies=5)
    assert net.n_nodes == 4 + 4 * 2 and net.n_edges == 20
    assert sorted(net.ports, key=lambda p: int(p[1:])) == [f"d{i}" for i in range(1, 7)]
    assert net.port("d1") == (0, 1) and net.port("d2") == (2, 3)
    np.testing.assert_allclose(net.port_distance("d4"), 2.0, atol=1e-12)


@pytest.mark.parametrize("mirror", [None, "alternate", [True, False, False, True, True, False]])
def test_chain_keeps_every_module_edge_length(super_stable, mirror):
    net = chain(super_stable, 6, mirror=mirror)
    np.testing.assert_allclose(module_blocks(net, super_stable, 6),
                               np.tile(super_stable.edge_lengths, (6, 1)), rtol=1e-14)
    assert count_modes(net).conformational == 1


def _coincident_pairs(net) -> int:
    """Pairs of distinct nodes at one place, by brute force over every pair."""
    x = net.nodes
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    return int((d[np.triu_indices(len(x), 1)] < 1e-9 * net.size).sum())


def test_a_chain_picks_the_mirroring_its_module_needs(super_stable, fourbar):
    # the paper's 5-node module folds back onto the module before it when chained as it is:
    # of four copies joined as they are, five pairs of nodes stand on one another
    straight = chain(super_stable, 4, mirror="none")
    assert _coincident_pairs(straight) == 5
    picked = chain(super_stable, 6)  # "auto"
    assert picked.assembly.mirrored.tolist() == [False, True] * 3  # it says what it used
    assert _coincident_pairs(picked) == 0
    np.testing.assert_array_equal(picked.nodes, chain(super_stable, 6, mirror="alternate").nodes)
    # a module that chains as it is keeps its handedness
    plain = chain(fourbar, 4)
    assert not plain.assembly.mirrored.any()
    np.testing.assert_array_equal(plain.nodes, chain(fourbar, 4, mirror="none").nodes)


def test_stacked_nodes_counts_what_brute_force_counts():
    # every pair measured (numpy, all N^2) against the count of the sorted sweep, on clouds
    # with many exact and near repeats, a column of equal x (a straight chain) and 1-3 dims;
    # a tiny chunk makes the sweep measure its candidates in many pieces
    import fabkit.design.assemble as assemble

    rng = np.random.default_rng(7)
    for trial in range(60):
        n, d = int(rng.integers(0, 120)), int(rng.integers(1, 4))
        x = rng.integers(0, 5, (n, d)) * rng.choice([1e-10, 0.25, 1.0])
        x = x + rng.normal(0.0, 1e-11, (n, d)) * (trial % 2)
        if trial % 5 == 0:
            x[:, 0] = 0.0
        tol = float(rng.choice([1e-9, 0.3]))
        gaps = np.linalg.norm(x[:, None] - x[None], axis=-1)[np.triu_indices(n, 1)]
        want = int((gaps <= tol).sum())
        assert assemble.stacked_nodes(x, tol) == want
        old = assemble.STACKED_CHUNK
        try:
            assemble.STACKED_CHUNK = 3
            assert assemble.stacked_nodes(x, tol) == want
        finally:
            assemble.STACKED_CHUNK = old


def test_modules_that_stand_on_one_another_either_way_are_refused(super_stable, monkeypatch):
    import fabkit.design.assemble as assemble

    monkeypatch.setattr(assemble, "_stacked_nodes", lambda net: 2)
    with pytest.raises(FabkitError, match="however they are chained.*list of booleans"):
        chain(super_stable, 5)
    assert chain(super_stable, 5, mirror="alternate").n_nodes  # a rule given is not second-guessed


def test_a_template_chain_without_mirror_picks_it(tmp_path):
    (tmp_path / "c.toml").write_text(
        f'name = "c"\n[chain]\nmodule = "{(TEMPLATES / "super_stable.toml").as_posix()}"\n'
        'copies = 4\n')
    net = load_template(tmp_path / "c.toml").network
    assert net.assembly.mirrored.tolist() == [False, True, False, True]
    with pytest.raises(TemplateError, match="mirror"):
        (tmp_path / "d.toml").write_text((tmp_path / "c.toml").read_text()
                                         + 'mirror = "sometimes"\n')
        load_template(tmp_path / "d.toml")


def test_mirror_flags_flip_handedness(super_stable):
    net = chain(super_stable, 4, mirror=[False, True, True, False])
    # module k's designed triangle (nodes 0, 1, 2) in the chain: d_k pair + the d_{k+1} far node
    areas = []
    for k in range(1, 5):
        a, b = net.port(f"d{k}")
        _, c = net.port(f"d{k + 1}")
        areas.append(signed_area(net.nodes, (a, b, c)))
    ref = signed_area(super_stable.nodes, (0, 1, 2))
    np.testing.assert_allclose(np.sign(areas), np.sign(ref) * np.array([1, -1, -1, 1]))


def test_alternate_mirror_makes_a_straight_strip(super_stable):
    net = chain(super_stable, 10, mirror="alternate")
    mids = np.array([net.nodes[list(net.port(f"d{k}"))].mean(axis=0) for k in range(1, 12)])
    # every pair midpoint on one line: the strip is straight at the D1* crystal
    d = mids - mids[0]
    u = d[-1] / np.linalg.norm(d[-1])
    assert float(np.abs(d[:, 0] * u[1] - d[:, 1] * u[0]).max()) < 1e-12


def test_sequence_of_different_modules(paper_modules, module):
    a, c = module("curvature_contract"), module("curvature_expand")
    net = chain([a, c, a, c], mirror="alternate")
    assert net.n_nodes == 5 + 3 * 3
    lengths = module_blocks(net, a, 4)
    np.testing.assert_allclose(lengths[0], a.edge_lengths, rtol=1e-14)
    np.testing.assert_allclose(lengths[1], c.edge_lengths, rtol=1e-14)
    assert count_modes(net).conformational == 1


def test_sequence_repeated_by_copies(module):
    a, c = module("curvature_contract"), module("curvature_expand")
    net = chain([a, c], copies=3, mirror="alternate")
    assert len([p for p in net.ports if p.startswith("d")]) == 7


def test_chain_places_each_module_at_the_previous_output(fourbar):
    x = fourbar.nodes.copy()
    x[[2, 3]] = [[1.0, -1.0], [1.2, 1.0]]  # a 4-bar whose d2 differs from d1 at its reference
    lengths = np.linalg.norm(x[fourbar.edges[:, 0]] - x[fourbar.edges[:, 1]], axis=1)
    m = fabkit.Network(x, fourbar.edges, fourbar.ports)
    net = chain(m, 3)
    np.testing.assert_allclose(net.edge_lengths, np.tile(lengths, 3), rtol=1e-13)
    assert net.port_distance("d2") != pytest.approx(net.port_distance("d1"))


def test_other_ports_get_module_suffix(module):
    net = chain(module("curvature_maintain").with_ports(
        {"d1": (0, 1), "d2": (1, 2), "bottom": (0, 2)}), 3, mirror="alternate")
    assert {"bottom_1", "bottom_2", "bottom_3"} <= set(net.ports)


def test_chain_inverse_map_direction(module):
    m = module("physical_fourbar")
    net = chain(m, 4, d_in="d2", d_out="d1")  # joins d1 of module k to d2 of module k + 1
    assert net.port("d1") == (2, 3)
    np.testing.assert_allclose([net.port_distance(f"d{k}") for k in range(1, 6)], 1.0, atol=1e-12)
    assert count_modes(net).conformational == 1


@pytest.mark.parametrize("kwargs, message, kind", [
    ({"copies": 0}, "copies must be at least 1, got 0", ValueError),
    ({"copies": 2.5}, "copies must be a whole number, got 2.5", TypeError),
    ({"copies": True}, "copies must be a whole number, got True", TypeError),
    ({}, "copies is needed with one module", TypeError),
    ({"copies": 3, "mirror": "sometimes"}, "mirror must be one of 'auto', 'alternate', 'none'",
     ValueError),
    ({"copies": 3, "mirror": [True]}, "mirror has 1 entries for 3 modules", ValueError),
    ({"copies": 3, "mirror": [1, 0, 1]}, "mirror must be 'auto', 'alternate', 'none' or a list "
                                         "of booleans", TypeError),
    ({"copies": 2, "d_in": "dx"}, "d_in 'dx' is not a port of the network", ValueError),
    ({"copies": 2, "d_out": ["d2"]}, "d_out must be a port name", TypeError),
])
def test_chain_errors(fourbar, kwargs, message, kind):
    with pytest.raises(FabkitError, match=message) as info:
        chain(fourbar, **kwargs)
    assert isinstance(info.value, kind)  # what Python users expect, and fabkit's own class


def test_chain_size_is_bounded_before_building(fourbar):
    with pytest.raises(BoundsError, match=r"chain: about .* GB .*is over the limit of 2 GB of "
                                          r"memory; fabkit --allow-large"):
        chain(fourbar, copies=10**7)


def test_chain_error_out_of_range(fourbar, super_stable):
    small = super_stable.with_nodes(super_stable.nodes * 0.1)
    with pytest.raises(FabkitError, match=r"module 2 of the chain: the module has no configuration "
                                          r"with d1 = 2"):
        chain([fourbar, small])


def test_chain_error_mixed_dimensions(fourbar):
    tri3 = fabkit.Network([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1], [1, 2], [0, 2]],
                          ports={"d1": (0, 1), "d2": (1, 2)})
    with pytest.raises(FabkitError, match="module 2 is 3D but module 1 is 2D"):
        chain([fourbar, tri3])


def test_chain_3d(module):
    m = module("origami_sheet")
    net = chain(m, 3)
    assert net.dim == 3 and net.n_nodes == 5 + 2 * 3
    np.testing.assert_allclose(net.edge_lengths, np.tile(m.edge_lengths, 3), rtol=1e-13)


def test_join_transform_maps_pairs():
    src = np.array([[0.0, 0.0], [1.0, 0.0]])
    dst = np.array([[2.0, 3.0], [2.0, 4.0]])
    for mirror in (False, True):
        rot, shift = join_transform(src, dst, mirror=mirror)
        np.testing.assert_allclose(src @ rot.T + shift, dst, atol=1e-15)
        assert np.sign(np.linalg.det(rot)) == (-1 if mirror else 1)


# -- join ----------------------------------------------------------------------------------

def test_join_2d_by_ports(fourbar_ports):
    res = join(fourbar_ports, fourbar_ports, ("d2", "d1"))
    net = res.network
    assert net.n_nodes == 6 and res.second_index.tolist() == [2, 3, 4, 5]
    assert set(net.ports) == {"d1", "d2", "b", "t", "d1_b", "d2_b", "b_b", "t_b"}
    assert net.port("d1_b") == net.port("d2")
    np.testing.assert_allclose(net.edge_lengths, np.tile(fourbar_ports.edge_lengths, 2))


def test_join_3d_three_nodes_is_rigid_two_nodes_hinge():
    tet = fabkit.Network([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, 0.8]],
                         [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    res = join(tet, tet, [(0, 0), (1, 1), (2, 2)], mirror=True)
    net = res.network
    assert (net.n_nodes, net.n_edges) == (5, 9)        # the shared face's 3 bars appear once
    np.testing.assert_allclose(net.nodes[4], [0.3, 0.3, -0.8], atol=1e-15)
    m = count_modes(net)
    assert (m.rigid, m.conformational) == (6, 0)
    # two shared nodes only: the parts keep a hinge rotation about the shared axis
    hinge = join(tet, tet, [(0, 0), (1, 1)], mirror=True).network
    assert count_modes(hinge).conformational == 1


def test_join_rejects_mismatch_and_wrong_handedness():
    tet = fabkit.Network([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, 0.8]],
                         [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    with pytest.raises(FabkitError, match="nodes 1 and 3 are 1.104536102 apart in the first "
                                          "network but nodes 1 and 2 are 1.414213562 apart"):
        join(tet, tet, [(0, 0), (1, 1), (3, 2)])
    flat = fabkit.Network([[0, 0], [2, 0], [0, 1]], [[0, 1], [0, 2]])
    flip = fabkit.Network([[0, 0], [2, 0], [0, -1]], [[0, 1], [0, 2]])
    with pytest.raises(FabkitError, match="try mirror=True"):
        join(flat, flip, [(0, 0), (1, 1), (2, 2)])
    assert join(flat, flip, [(0, 0), (1, 1), (2, 2)], mirror=True).network.n_nodes == 3


@pytest.mark.parametrize("at, message", [
    (("zz", "d1"), "the first network has no port 'zz'"),
    ([(0, 0)], "a join merges at least 2 node pairs"),
    ([(0, 0), (9, 1)], "node 9 is not in the first network"),
    ([(0, 0), (1, 0)], "each node may be merged only once"),
    ("nonsense", "`at` must be two port names or a list"),
])
def test_join_errors(fourbar_ports, at, message):
    with pytest.raises(FabkitError, match=message):
        join(fourbar_ports, fourbar_ports, at)


def test_join_port_collision(fourbar_ports):
    with pytest.raises(FabkitError, match="port 'd1' exists in both networks"):
        join(fourbar_ports, fourbar_ports, ("d2", "d1"), ports="{name}")


# -- branch (the AND gate) ------------------------------------------------------------------------

def test_branch_and_gate_structure(super_stable):
    trunk = chain(super_stable, 8, mirror="alternate")
    net = branch(trunk, trunk, at="d5", end="d9", mirror=True, swap=True)
    assert net.n_nodes == 2 * trunk.n_nodes - 2 and net.n_edges == 2 * trunk.n_edges
    assert set(net.port("d9_b")) == set(net.port("d5"))
    m = count_modes(net)
    assert (m.conformational, m.self_stress) == (2, 1)
    # the branch's free end points up and to the left of the junction
    j = net.nodes[list(net.port("d5"))].mean(axis=0)
    tip = net.nodes[list(net.port("d1_b"))].mean(axis=0)
    assert tip[1] - j[1] > 5.0 and tip[0] < j[0]


def test_branch_errors(super_stable):
    trunk = chain(super_stable, 4, mirror="alternate")
    with pytest.raises(FabkitError, match="the trunk has no port 'd9'"):
        branch(trunk, trunk, at="d9", end="d5")
    with pytest.raises(FabkitError, match="the limb has no port 'x'"):
        branch(trunk, trunk, at="d3", end="x")


# -- tessellation ---------------------------------------------------------------------------------

def test_tessellate_fourbar_lattice(fourbar_ports):
    net = tessellate(fourbar_ports, (2, 2), y_join=("t", "b"))
    assert (net.n_nodes, net.n_edges) == (9, 14)  # shared horizontal bars appear once
    m = count_modes(net)
    assert (m.rigid, m.conformational, m.self_stress) == (3, 1, 0)
    big = tessellate(fourbar_ports, (3, 3), y_join=("t", "b"))
    m = count_modes(big)
    assert (big.n_nodes, big.n_edges) == (16, 30)
    assert (m.conformational, m.self_stress) == (1, 2)
    assert set(big.port("d1_1_1")) == set(big.port("d2_1_0"))
    # the lattice moves: trace one column distance, every cell keeps its bars
    traj = fabkit.trace(net, "d1_0_0", to=2.5, method="projected")
    assert str(traj.status) == "finished" and traj.max_edge_error < 1e-10


def test_tessellate_errors(fourbar_ports, super_stable):
    with pytest.raises(FabkitError, match="the lattice does not close: node 1 of copy"):
        tessellate(fourbar_ports, (2, 2), x_join=("d2", "b"), y_join=("t", "b"))
    with pytest.raises(FabkitError, match=r"y_join\[0\] 'q' is not a port of the network"):
        tessellate(fourbar_ports, (2, 2), y_join=("q", "b"))
    with pytest.raises(ValueError, match=r"shape\[0\] must be at least 1, got 0"):
        tessellate(fourbar_ports, (0, 2), y_join=("t", "b"))
    with pytest.raises(TypeError, match=r"shape must be \(rows, columns\), got '2x2'"):
        tessellate(fourbar_ports, "2x2", y_join=("t", "b"))
    with pytest.raises(FabkitError, match="`y_join` joins ports of lengths 2 and 2.828427125"):
        tessellate(fourbar_ports.with_ports({**fourbar_ports.ports, "x": (0, 3)}), (2, 2),
                   y_join=("t", "x"))


# -- template builders ------------------------------------------------------------------------------

AND_GATE_SMALL = f"""
[chain]
module = "{TEMPLATES / 'super_stable.toml'}"
copies = 4
mirror = "alternate"
[chain.branch]
module = "{TEMPLATES / 'super_stable.toml'}"
copies = 4
mirror = "alternate"
end = "d5"
at = "d3"
join_mirror = true
swap = true
"""


def test_chain_template_with_branch(tmp_path):
    design = parse_template(AND_GATE_SMALL, tmp_path / "gate.toml")
    net = design.network
    assert {"d1", "d5", "d1_b", "d5_b"} <= set(net.ports)
    assert count_modes(net).self_stress == 1


@pytest.mark.parametrize("edit, key, reason", [
    (('at = "d3"', 'at = "d7"'), "chain.branch.at", "the chain has no port 'd7'"),
    (('end = "d5"', 'end = "q"'), "chain.branch.end", "the branch has no port 'q'"),
    (("swap = true", "swap = 1"), "chain.branch.swap", "must be true or false"),
    (("swap = true", "tilt = 3"), "chain.branch.tilt", "unknown key"),
])
def test_chain_template_branch_errors(tmp_path, edit, key, reason):
    text = AND_GATE_SMALL.replace(*edit)
    with pytest.raises(TemplateError) as info:
        parse_template(text, tmp_path / "gate.toml")
    assert info.value.key == key and reason in info.value.reason


def test_chain_template_errors(tmp_path):
    base = f'[chain]\nmodule = "{TEMPLATES / "fourbar.toml"}"\n'
    with pytest.raises(TemplateError, match="chain.copies: must be at least 1"):
        parse_template(base + "copies = 0\n", tmp_path / "a.toml")
    with pytest.raises(TemplateError, match="chain.mirror: must be"):
        parse_template(base + "copies = 2\nmirror = 3\n", tmp_path / "a.toml")
    with pytest.raises(TemplateError, match="give either `module`"):
        parse_template("[chain]\ncopies = 2\n", tmp_path / "a.toml")


def test_tessellation_builder(tmp_path):
    (tmp_path / "cell.toml").write_text(
        "[network]\nnodes = [[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]\n"
        "edges = [[0, 2], [0, 3], [1, 2], [1, 3]]\n"
        "ports = { d1 = [0, 1], d2 = [2, 3], b = [0, 2], t = [1, 3] }\n")
    ctx = TemplateContext(tmp_path / "lattice.toml", {})
    net = build_tessellation({"module": "cell.toml", "shape": [2, 3], "y_join": ["t", "b"]}, ctx)
    assert net.n_nodes == 12
    with pytest.raises(TemplateError, match="tessellation.shape: must be two positive integers"):
        build_tessellation({"module": "cell.toml", "shape": [2], "y_join": ["t", "b"]}, ctx)


def test_core_does_not_import_fabrication_layers():
    code = ("import sys, fabkit.design.assemble, fabkit.design.letters, fabkit.plots.animate\n"
            "bad = [m for m in sys.modules if m.startswith(('fabkit.fab', 'fabkit.writers', "
            "'fabkit.check', 'fabkit.cli', 'fabkit.commands'))]\n"
            "assert not bad, bad\n")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_chains_load_without_the_designer():
    # fabkit.design's names are imported on first use: chaining modules (fabkit.chain) does not
    # load the map and curve designers, and every name the package lists is still there
    code = ("import sys, fabkit.design.assemble, fabkit.design as d; "
            "print(sorted(m for m in sys.modules if m.startswith('fabkit.design.'))); "
            "print(all(callable(getattr(d, n)) for n in d.__all__)); "
            "print(d.design_map.__module__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.splitlines()
    assert out[0] == "['fabkit.design.assemble']"
    assert out[1:] == ["True", "fabkit.design.module"]


def test_a_chain_that_closes_a_ring_late_is_mirrored(tmp_path):
    # a designed module whose copies, joined as they are, turn round and close a ring: its
    # nodes stand on the first copy's only after a few modules, past a short prefix
    import fabkit

    module = fabkit.design_map([(1.0, 0.0), 2.0]).network
    straight = chain(module, 20, mirror="none")
    assert _coincident_pairs(chain(module, 3, mirror="none")) == 0
    assert _coincident_pairs(straight) > 0
    picked = chain(module, 20)  # "auto"
    assert picked.assembly.mirrored.tolist() == [False, True] * 10
    assert _coincident_pairs(picked) == 0
