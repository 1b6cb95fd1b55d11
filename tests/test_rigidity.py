"""Rigidity matrix and generalised Maxwell counting."""

import numpy as np
import pytest

from fabkit import Network, count_modes, rigidity_matrix, rigid_body_basis
from fabkit.model.rigidity import self_stresses, zero_modes


def test_rigidity_matrix_annihilates_rigid_motions(module):
    net = module("chaotic")
    r = rigidity_matrix(net)
    assert r.shape == (6, 10)
    basis = rigid_body_basis(net.nodes)
    assert basis.shape == (10, 3)
    assert np.abs(r @ basis).max() < 1e-14


def test_rigidity_matrix_is_the_length_derivative():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((6, 3))
    net = Network(x, [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [0, 5], [1, 4]])
    v = rng.standard_normal(x.size)
    h = 1e-6
    # d/dt of l²/2 along v equals R v
    l2p = net.lengths_at(x + h * v.reshape(x.shape)) ** 2 / 2
    l2m = net.lengths_at(x - h * v.reshape(x.shape)) ** 2 / 2
    np.testing.assert_allclose(rigidity_matrix(net) @ v, (l2p - l2m) / (2 * h), rtol=1e-7, atol=1e-9)


def counts(m):
    return (m.total, m.rigid, m.conformational, m.self_stress)


def test_triangle_is_rigid():
    m = count_modes(Network([[0, 0], [1, 0], [0.3, 0.8]], [[0, 1], [1, 2], [2, 0]]))
    assert counts(m) == (3, 3, 0, 0)


def test_fourbar_has_one_motion(fourbar):
    m = count_modes(fourbar)
    assert counts(m) == (4, 3, 1, 0)
    assert m.maxwell == 4 and m.gap == np.inf


def test_tetrahedron_minus_one_edge():
    x = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.3, 0.9]]
    full = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    assert counts(count_modes(Network(x, full))) == (6, 6, 0, 0)
    assert counts(count_modes(Network(x, full[:-1]))) == (7, 6, 1, 0)


def test_collinear_bar_has_self_stress():
    # three collinear nodes with all three edges: one state of self-stress, one extra motion
    m = count_modes(Network([[0, 0], [1, 0], [2, 0]], [[0, 1], [1, 2], [0, 2]]))
    assert counts(m) == (4, 3, 1, 1)
    s = self_stresses(Network([[0, 0], [1, 0], [2, 0]], [[0, 1], [1, 2], [0, 2]]))
    assert s.shape == (3, 1)


def test_degenerate_node_sets_have_fewer_rigid_motions():
    assert rigid_body_basis([[0, 0, 0], [1, 0, 0], [3, 0, 0]]).shape[1] == 5
    assert rigid_body_basis([[0, 0], [1, 1]]).shape[1] == 3
    assert rigid_body_basis([[1.0, 2.0, 3.0]]).shape[1] == 3  # a single node only translates


def test_origami_sheet_flat_and_folded(module):
    from scipy.optimize import least_squares

    flat = module("origami_sheet")
    mc = count_modes(flat)
    assert mc.self_stress >= 1
    assert counts(mc) == (8, 6, 2, 1)
    # A folded state: corners 1 and 3 brought to distance 1.3, corner 0 lifted by 0.35 rad about
    # the line 1-3 (this fixes the rigid rotation about that line); corner 2 and the crease
    # vertex 4 solved from the edge lengths.
    h, alpha = 0.65, 0.35
    a = np.sqrt(1 - h * h)

    def build(z):
        return np.array([[-a * np.cos(alpha), 0, a * np.sin(alpha)], [0, h, 0],
                         [a * np.cos(z[3]), 0, a * np.sin(z[3])], [0, -h, 0], z[:3]])

    def resid(z):
        y = build(z)
        return np.linalg.norm(y[flat.edges[:, 0]] - y[flat.edges[:, 1]], axis=1) - flat.edge_lengths

    sol = least_squares(resid, [0, 0.207, 0.1, 0.3], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    folded = build(sol.x)
    assert flat.edge_error(folded) < 1e-12
    assert folded[4, 2] > 0.1  # the crease vertex has left the plane
    assert counts(count_modes(flat, folded)) == (7, 6, 1, 0)


def test_zero_modes_are_orthogonal_to_rigid_motions(fourbar):
    z = zero_modes(fourbar)
    assert z.shape == (8, 1)
    assert np.abs(rigid_body_basis(fourbar.nodes).T @ z).max() < 1e-12
    assert np.abs(rigidity_matrix(fourbar) @ z).max() < 1e-12


def test_sparse_rank_decision_matches_dense(monkeypatch, fourbar):
    import fabkit
    from fabkit.model import rigidity

    net = fabkit.chain(fourbar, copies=40)
    dense = count_modes(net)
    monkeypatch.setattr(rigidity, "DENSE_LIMIT", 10)
    sparse = count_modes(net)
    assert counts(dense) == counts(sparse) == (4, 3, 1, 0)


@pytest.mark.slow
def test_large_chain_counts_one_motion(fourbar):
    import fabkit

    net = fabkit.chain(fourbar, copies=1500)  # 6004 coordinates: the sparse path
    assert counts(count_modes(net)) == (4, 3, 1, 0)
