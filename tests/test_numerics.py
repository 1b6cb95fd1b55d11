"""The shared numerics core: rigid fits and projection onto edge lengths."""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from fabkit.numerics import EDGE_RTOL, apply_fit, project_to_lengths, rigid_fit


def _orthogonal(rng, d, det):
    q, _ = np.linalg.qr(rng.standard_normal((d, d)))
    if np.sign(np.linalg.det(q)) != det:
        q[:, 0] *= -1
    return q


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("det", [1, -1])
def test_rigid_fit_recovers_the_motion_with_the_asked_handedness(d, det):
    rng = np.random.default_rng(3 + d)
    p = rng.standard_normal((6, d))
    rot = _orthogonal(rng, d, det)
    shift = rng.standard_normal(d)
    q = p @ rot.T + shift
    exact = {1: "proper", -1: "improper"}[det]
    for handedness in ("proper", "improper", "any"):
        fit = rigid_fit(p, q, handedness=handedness)
        want = det if handedness == "any" else (1 if handedness == "proper" else -1)
        assert np.linalg.det(fit.rotation) == pytest.approx(want, abs=1e-12)
        if handedness in (exact, "any"):
            assert fit.rms < 1e-13
            np.testing.assert_allclose(fit.rotation, rot, atol=1e-12)
            np.testing.assert_allclose(fit.shift, shift, atol=1e-12)
            np.testing.assert_allclose(apply_fit(fit, p), q, atol=1e-12)
        else:
            assert fit.rms > 1e-2  # a mirror image cannot be reached by the other handedness


def test_rigid_fit_is_batched_and_broadcasts():
    rng = np.random.default_rng(7)
    p = rng.standard_normal((4, 5, 3))
    rots = np.stack([_orthogonal(rng, 3, 1) for _ in range(4)])
    q = np.einsum("bij,bkj->bki", rots, p) + 1.5
    fit = rigid_fit(p, q)
    assert fit.rotation.shape == (4, 3, 3) and fit.shift.shape == (4, 3)
    assert np.max(fit.rms) < 1e-13
    np.testing.assert_allclose(apply_fit(fit, p), q, atol=1e-12)
    # one destination for every source configuration
    fit = rigid_fit(q, q[0])
    assert fit.rms.shape == (4,) and fit.rms[0] < 1e-13 and np.all(fit.rms[1:] > 1e-3)


def test_rigid_fit_rejects_bad_input():
    with pytest.raises(ValueError, match="handedness"):
        rigid_fit(np.zeros((3, 2)), np.zeros((3, 2)), handedness="left")
    with pytest.raises(ValueError, match=r"\(\.\.\., K, d\)"):
        rigid_fit(np.zeros((3, 2)), np.zeros((4, 2)))


def _fourbar():
    nodes = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]])
    edges = np.array([[0, 2], [0, 3], [1, 2], [1, 3]])
    return fabkit.Network(nodes, edges, ports={"d1": (0, 1), "d2": (2, 3)})


def test_projection_lands_on_the_lengths_and_the_drive():
    net = _fourbar()
    rng = np.random.default_rng(1)
    x0 = net.nodes + 1e-3 * rng.standard_normal((5, 4, 2))
    targets = np.linspace(1.9, 2.1, 5)
    proj = project_to_lengths(net.edges, net.edge_lengths, x0, pairs=[(0, 1)],
                              targets=targets[:, None])
    assert proj.converged and proj.residual < 1e-14
    x = proj.positions
    lengths = np.linalg.norm(x[:, net.edges[:, 0]] - x[:, net.edges[:, 1]], axis=-1)
    np.testing.assert_allclose(lengths, np.broadcast_to(net.edge_lengths, lengths.shape), rtol=1e-14)
    d1 = np.linalg.norm(x[:, 0] - x[:, 1], axis=-1)
    d2 = np.linalg.norm(x[:, 2] - x[:, 3], axis=-1)
    np.testing.assert_allclose(d1, targets, rtol=1e-14)
    np.testing.assert_allclose(d1 * d2, 4.0, rtol=1e-12)  # the antiparallelogram's map d2 = 4/d1
    # minimum-norm steps: the correction is small, of the size of the perturbation
    assert np.max(np.abs(x - x0)) < 0.2


def test_projection_of_a_large_chain_uses_sparse_steps_and_keeps_rigid_position():
    chain = fabkit.chain(_fourbar(), copies=200)  # 402 nodes: above the dense limit
    rng = np.random.default_rng(5)
    x0 = chain.nodes + 1e-4 * rng.standard_normal(chain.nodes.shape)
    proj = project_to_lengths(chain.edges, chain.edge_lengths, x0)
    assert proj.converged and proj.residual <= EDGE_RTOL
    assert float(chain.edge_error(proj.positions)) < 1e-12
    # a minimum-norm correction adds no rigid motion: the centroid barely moves
    assert np.linalg.norm(proj.positions.mean(axis=0) - x0.mean(axis=0)) < 1e-5


def test_projection_reports_an_impossible_target_instead_of_raising():
    net = _fourbar()
    # d1 = 5 is beyond the fully stretched linkage (at most 2 * sqrt(2) * ... < 5)
    proj = project_to_lengths(net.edges, net.edge_lengths, net.nodes, pairs=[(0, 1)],
                              targets=[5.0], max_iter=25)
    assert not proj.converged and proj.residual > 1e-3
    with pytest.raises(ValueError, match="targets"):
        project_to_lengths(net.edges, net.edge_lengths, net.nodes, pairs=[(0, 1)])
    with pytest.raises(ValueError, match="positive"):
        project_to_lengths(net.edges, np.zeros(4), net.nodes)


def test_projection_stops_early_on_lengths_no_configuration_has():
    # K4 in the plane has a state of self-stress: lengths off its Cayley-Menger surface cannot
    # be realised, and Gauss-Newton stalls above the tolerance; it must say so, not spin
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.9, 1.1]])
    e = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    lengths = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1) * (1 + 1e-3 * np.arange(6))
    proj = project_to_lengths(e, lengths, x, max_iter=40)
    assert not proj.converged and proj.residual > 1e-7 and proj.iterations < 10


@pytest.mark.parametrize("copies", [40, 120])  # 82 and 242 nodes: the QR and the sparse solver
def test_mid_size_and_large_projections_agree_with_each_other(copies, monkeypatch):
    import fabkit.numerics as numerics

    chain = fabkit.chain(_fourbar(), copies=copies)
    rng = np.random.default_rng(7)
    x0 = chain.nodes + 1e-4 * rng.standard_normal(chain.nodes.shape)
    first = project_to_lengths(chain.edges, chain.edge_lengths, x0)
    # the same projection with the other solver: minimum-norm steps are unique, so they agree
    other = 10 ** 6 if chain.nodes.size > numerics._QR_MAX_UNKNOWNS else 0
    monkeypatch.setattr(numerics, "_QR_MAX_UNKNOWNS", other)
    second = project_to_lengths(chain.edges, chain.edge_lengths, x0)
    assert first.converged and second.converged
    np.testing.assert_allclose(first.positions, second.positions, atol=1e-12)


def test_the_qr_steps_are_minimum_norm_where_the_jacobian_is_rank_deficient():
    # a chain of K4s carries one self-stress per K4: the rows are dependent, and the step is the
    # least-squares solution of least norm (LSQR's answer from a zero start)
    from fabkit.numerics import _qr_steps, _sparse_steps

    k4 = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.9, 1.1]])
    nodes = np.concatenate([k4 + [2.0 * c, 0.0] for c in range(20)])
    e = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    edges = np.concatenate([e + 4 * c for c in range(20)])
    rng = np.random.default_rng(3)
    x = nodes + 1e-3 * rng.standard_normal(nodes.shape)
    d = x[edges[:, 0]] - x[edges[:, 1]]
    ell = np.linalg.norm(d, axis=1)
    res = ell - np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)
    u = (d / ell[:, None])[None]
    qr = _qr_steps(u, edges, res[None], 80, 2)
    ls = _sparse_steps(u, edges, res[None], 80, 2)
    np.testing.assert_allclose(qr, ls, atol=1e-10)


@pytest.mark.parametrize("shape", [(1001, 2), (300, 2, 2), (257, 3), (4, 3, 3), (0, 2), (5, 4)])
@pytest.mark.parametrize("scale", [1e-200, 1e-3, 1.0, 1e150])
def test_row_norms_are_numpys_norms_bit_for_bit(shape, scale):
    """Plans, sines and edge lengths computed with it must keep their bits: a chain driven next
    to an unstable state amplifies one ulp into a visible change."""
    from fabkit.numerics import row_norms

    rng = np.random.default_rng(sum(shape))
    v = rng.standard_normal(shape) * scale
    v.reshape(-1, shape[-1])[::7] = 0.0  # rows of zeros among them
    assert row_norms(v).tobytes() == np.linalg.norm(v, axis=-1).tobytes()


def test_edge_lengths_are_the_norms_of_the_differences_bit_for_bit():
    from fabkit.model.network import Network

    rng = np.random.default_rng(5)
    for d in (2, 3):
        x = rng.standard_normal((60, d)) * 37.0
        e = np.array([[i, j] for i in range(60) for j in range(i + 1, 60) if (i * j) % 11 == 1])
        want = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=-1)
        assert Network(x, e).edge_lengths.tobytes() == want.tobytes()
