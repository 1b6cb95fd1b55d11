"""The sparse, certified mode count: same counts as the dense SVD, bounds that bracket the
threshold, and "ambiguous" instead of a guess near singular configurations."""

import math

import numpy as np
import pytest

import fabkit
from fabkit import Network, count_modes
from fabkit.model import rigidity
from fabkit.design.assemble import tessellate
from fabkit.bench import paper_module


def counts(m):
    return (m.total, m.rigid, m.conformational, m.self_stress)


def sparse_count(monkeypatch, net, positions=None):
    monkeypatch.setattr(rigidity, "DENSE_LIMIT", 0)
    return count_modes(net, positions)


def with_all_ports(name):
    m = paper_module(name)
    n = m.n_nodes
    return m.with_ports({**m.ports, **{f"p{a}{b}": (a, b) for a in range(n) for b in range(n)
                                        if a != b}})


def triangle(height):
    """Nodes 0, 1, 2 with node 2 at ``height`` above the midpoint of 0-1: collinear at 0."""
    return Network([[0.0, 0.0], [2.0, 0.0], [1.0, height]], [[0, 1], [1, 2], [0, 2]])


NETWORKS = {
    # joined as they are (a fan folding onto itself): chain() alone would mirror every second
    "super_stable_chain_40": lambda: fabkit.chain(paper_module("super_stable"), copies=40,
                                                  mirror="none"),
    "chaotic_chain_20": lambda: fabkit.chain(paper_module("chaotic"), copies=20),
    # mirrored as in templates/super_stable_chain.toml (a minimum-degree ordering of [[0, R],
    # [Rᵀ, 0]] filled its factors densely: 10 s at 1000 modules, 250 s at 3000)
    "super_stable_mirrored_60": lambda: fabkit.chain(paper_module("super_stable"), copies=60,
                                                     mirror="alternate"),
    "origami_sheet": lambda: paper_module("origami_sheet"),  # 3D, S = 1, two motions
    "and_gate": lambda: fabkit.load_template("templates/and_gate.toml").network,
    # an open lattice of squares: many mechanisms, so the block of the search has to grow
    "square_grid": lambda: tessellate(
        Network([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 1], [1, 2], [2, 3], [3, 0]],
                ports={"l": (0, 3), "r": (1, 2), "b": (0, 1), "t": (3, 2)}),
        (4, 4), x_join=("r", "l"), y_join=("t", "b")),
    # over-braced lattices with many self-stresses: the normal-equations path
    "fourbar_lattice": lambda: tessellate(with_all_ports("fourbar"), (12, 12),
                                          y_join=("p13", "p02")),
    "super_stable_lattice": lambda: tessellate(with_all_ports("super_stable"), (10, 10),
                                               y_join=("p20", "p01")),
}


@pytest.mark.parametrize("name", sorted(NETWORKS))
def test_sparse_count_matches_dense(monkeypatch, name):
    net = NETWORKS[name]()
    dense = count_modes(net, method="dense")
    sparse = sparse_count(monkeypatch, net)
    assert dense.method == "dense" and sparse.method == "sparse"
    assert not dense.ambiguous and not sparse.ambiguous, sparse.note
    assert counts(sparse) == counts(dense)
    # the certified gap is a lower bound of the dense one, and still a clear decision
    assert sparse.gap >= 1e6
    if math.isfinite(dense.gap):
        assert sparse.gap <= dense.gap * 1.01


def test_square_grid_has_many_mechanisms(monkeypatch):
    m = sparse_count(monkeypatch, NETWORKS["square_grid"]())
    # 25 nodes, 40 bars: 50 - 40 = 10 zero modes, 7 of them mechanisms (one shear per row and
    # column); more than the first block of 8 vectors
    assert counts(m) == (10, 3, 7, 0)


def test_lattice_self_stresses_come_from_maxwell(monkeypatch):
    net = NETWORKS["super_stable_lattice"]()
    m = sparse_count(monkeypatch, net)
    assert m.self_stress == m.total - (2 * net.n_nodes - net.n_edges) > rigidity.MAX_BLOCK


@pytest.mark.parametrize("path", ["dense", "sparse"])
def test_near_singular_triangle_is_ambiguous(monkeypatch, path):
    if path == "sparse":
        monkeypatch.setattr(rigidity, "DENSE_LIMIT", 0)
    clear = count_modes(triangle(0.5))
    assert counts(clear) == (3, 3, 0, 0) and not clear.ambiguous
    flat = count_modes(triangle(0.0))  # collinear: a mechanism and a state of self-stress
    assert counts(flat) == (4, 3, 1, 1) and not flat.ambiguous
    # height 1e-9: the smallest singular value sits at the threshold, where no count is safe
    near = count_modes(triangle(1e-9))
    assert near.ambiguous and near.note
    assert str(near).startswith("ambiguous rank (")


def test_long_network_with_a_near_singular_part_is_ambiguous(monkeypatch):
    """A 400-module chain plus a triangle 1e-9 from collinear: no count is guessed; the same
    network with a clearly flat or clearly open triangle is counted."""
    chain = fabkit.chain(paper_module("fourbar"), copies=400)

    def with_triangle(height):
        tri = triangle(height)
        n = chain.n_nodes
        return Network(np.vstack([chain.nodes, tri.nodes + [0.0, 5.0]]),
                       np.vstack([chain.edges, tri.edges + n]))

    assert 2 * with_triangle(0.0).n_nodes > 1000
    flat = sparse_count(monkeypatch, with_triangle(0.0))
    # the chain's 4 zero modes, the triangle's 3 rigid motions and its mechanism
    assert (flat.total, flat.self_stress, flat.ambiguous) == (8, 1, False)
    assert (sparse_count(monkeypatch, with_triangle(0.5)).total,
            sparse_count(monkeypatch, with_triangle(0.5)).ambiguous) == (7, False)
    near = sparse_count(monkeypatch, with_triangle(1e-9))
    assert near.ambiguous and near.note


def test_ten_thousand_module_chain_without_a_dense_matrix(dense_copies):
    net = fabkit.chain(paper_module("super_stable"), copies=10_000, mirror="none")
    m = count_modes(net)
    assert counts(m) == (4, 3, 1, 0) and m.method == "sparse" and not m.ambiguous
    assert m.gap > 1e6 and 1e-4 < m.smallest_nonzero < 1e-3
    # about 0.5 s (fabkit bench times it): no dense copy of the 60000 × 60004 matrix was made
    assert not [s for s in dense_copies if max(s) > 1000], dense_copies
