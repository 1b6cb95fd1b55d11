"""Chains built as arrays: the same network as the module-by-module build, a port table that
behaves as a dict, and counts that need no object per module.

The reference is fabkit's own module-by-module build (kept for chains whose modules are not at
their reference: it places each one at its input), forced here by switching the array build
off; the two must agree exactly, node for node, bar for bar, port for port.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import fabkit
from fabkit.design import assemble
from fabkit.model.matrix import rigid_body_basis, rigid_body_count
from fabkit.model.network import Assembly, ChainPorts, Network
from fabkit.model.rigidity import count_modes


def _module_by_module(monkeypatch, *args, **kwargs):
    with monkeypatch.context() as m:
        m.setattr(assemble, "_chain_at_reference", lambda *a, **k: None)
        return fabkit.chain(*args, **kwargs)


@pytest.mark.parametrize("name, kwargs", [
    ("super_stable", {"mirror": "alternate"}),   # output (1, 2) shares node 1 with input (0, 1)
    ("super_stable", {"mirror": [True, False, False, True, True, False, True, False, True]}),
    ("fourbar", {}),
    ("slope_one", {"mirror": "alternate"}),
])
def test_the_array_build_is_the_module_by_module_build(monkeypatch, name, kwargs):
    m = fabkit.load_template(name).network
    fast = fabkit.chain(m, 9, **kwargs)
    slow = _module_by_module(monkeypatch, m, 9, **kwargs)
    assert isinstance(fast.ports, ChainPorts) and not isinstance(slow.ports, ChainPorts)
    assert np.array_equal(fast.edges, slow.edges)
    assert np.abs(fast.nodes - slow.nodes).max() <= 1e-15 * fast.size
    assert dict(fast.ports) == slow.ports and list(fast.ports) == list(slow.ports)
    assert fast.assembly.count == slow.assembly.count == 9
    for (ma, ia, fa), (mb, ib, fb) in zip(fast.assembly.copies, slow.assembly.copies):
        assert ma is mb and np.array_equal(ia, ib) and fa == fb


def test_two_kinds_of_module_interleave(monkeypatch):
    # a chain of two distinct (equal) module objects, alternating: each kind's copies are one
    # array, the chain order is kept
    a = fabkit.load_template("fourbar").network
    b = Network(a.nodes, a.edges, a.ports)
    fast = fabkit.chain([a, b], copies=3)
    slow = _module_by_module(monkeypatch, [a, b], copies=3)
    assert len(fast.assembly.modules) == 2 and fast.assembly.kind.tolist() == [0, 1] * 3
    assert np.array_equal(fast.edges, slow.edges) and dict(fast.ports) == slow.ports


def test_a_chain_off_its_reference_is_built_module_by_module():
    # the 4-bar chain started at d1 = 2.5 (not its fixed point 2): each module is placed at
    # the distance the one before gives it, d2 = 4/2.5 = 1.6, d3 = 2.5, ...
    m = fabkit.load_template("fourbar").network
    x = fabkit.trace(m, drive="d1", to=2.5).final
    net = fabkit.chain(m.with_nodes(x), 4)
    assert not isinstance(net.ports, ChainPorts)
    assert [round(net.port_distance(f"d{k}"), 12) for k in range(1, 6)] == [2.5, 1.6, 2.5, 1.6,
                                                                            2.5]


def test_chain_ports_behave_as_a_dict():
    p = ChainPorts([[0, 1], [1, 2], [2, 5]])
    assert p["d3"] == (2, 5) and len(p) == 3 and list(p) == ["d1", "d2", "d3"]
    assert "d3" in p and "d4" not in p and "d0" not in p and "d01" not in p and 3 not in p
    with pytest.raises(KeyError):
        p["d4"]
    assert {**p, "x": (0, 2)}["x"] == (0, 2)
    assert pickle.loads(pickle.dumps(p)) == p
    net = Network(np.arange(12.0).reshape(6, 2) ** 1.5, [[0, 1], [1, 2], [2, 5]], p)
    assert net.port("d2") == (1, 2)
    with pytest.raises(fabkit.errors.NetworkError, match="port 'd3' names node 5"):
        Network(np.arange(10.0).reshape(5, 2) ** 1.5, [[0, 1], [1, 2]], p)


@pytest.mark.parametrize("k", [10**5, pytest.param(10**6, marks=pytest.mark.slow)])
def test_a_long_chain_is_a_few_arrays(k):
    m = fabkit.load_template("super_stable").network
    net = fabkit.chain(m, copies=k, mirror="alternate")
    layout = net.assembly
    assert layout.count == k and len(layout.modules) == 1
    assert layout.index[0].shape == (k, m.n_nodes)
    assert len(net.ports) == k + 1 and f"d{k + 1}" in net.ports and f"d{k + 2}" not in net.ports
    counts = count_modes(net)
    # dN - E + S = 2·(3k + 2) - 6k + 0: three rigid motions and the one motion
    assert (counts.total, counts.rigid, counts.conformational, counts.self_stress) == (4, 3, 1, 0)


@pytest.mark.parametrize("x", [
    np.random.default_rng(0).random((5, 2)), np.random.default_rng(1).random((5, 3)),
    [[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 0], [0, 0]], [[1, 2, 3]],
    np.outer(np.arange(6), [1, 2, 3]) + 1e-14 * np.random.default_rng(2).random((6, 3)),
    np.random.default_rng(3).random((4, 3)) * [1, 1, 0],
])
def test_rigid_motions_are_counted_as_the_basis_has_them(x):
    assert rigid_body_count(x) == rigid_body_basis(x).shape[1]


def test_an_assembly_from_copies_keeps_them():
    m = fabkit.load_template("fourbar").network
    net = fabkit.chain(m, 3)
    again = Assembly.from_copies(net.assembly.copies, "d1")
    assert again.kind.tolist() == [0, 0, 0]
    assert np.array_equal(again.index[0], net.assembly.index[0])
