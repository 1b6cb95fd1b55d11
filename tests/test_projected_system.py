"""projected's bordered system: banded solves (one and several right-hand sides, transposed),
the sign of det A, the residual, against dense linear algebra; the packaging helpers it uses."""

import numpy as np
import pytest

import fabkit
from fabkit.kinematics.base import align_to_gauge
from fabkit.kinematics.bordered import _BandLU, BorderedSystem, gauge_rows
from fabkit.kinematics.record import edge_errors
from fabkit.numerics import rigid_fit


def _system(net):
    x0 = np.asarray(net.nodes, dtype=np.float64)
    gcols = gauge_rows(x0, (0, 1))
    n, d = x0.shape
    sys_ = BorderedSystem(net.edges, net.edge_lengths ** 2, n, d, gcols, x0.ravel()[gcols], None)
    return sys_, x0


def _dense(sys_, xf, j):
    """A = [J; gauge rows; e_j] written out."""
    n, d = sys_.n, sys_.d
    x = xf.reshape(n, d)
    e = sys_.edges.shape[0]
    a = np.zeros((sys_.n_rows, sys_.n_rows))
    for r, (p, q) in enumerate(sys_.edges):
        a[r, d * p:d * p + d] = x[p] - x[q]
        a[r, d * q:d * q + d] = x[q] - x[p]
    a[e + np.arange(sys_.gcols.size), sys_.gcols] = 1.0
    a[-1, j] = 1.0
    return a


@pytest.fixture
def chain_system(fourbar):
    net = fabkit.chain(fourbar, copies=12)
    sys_, x0 = _system(net)
    rng = np.random.default_rng(3)
    xf = x0.ravel() + 1e-3 * rng.standard_normal(x0.size)  # off the constraint set
    return sys_, xf


def test_band_solves_match_dense(chain_system):
    sys_, xf = chain_system
    j = sys_.n_rows - 5
    lu = sys_.factorize(xf, np.array([j]), np.array([1.0]))
    assert isinstance(lu, _BandLU)
    a = _dense(sys_, xf, j)
    rng = np.random.default_rng(4)
    b = rng.standard_normal((2, sys_.n_rows))
    np.testing.assert_allclose(lu.solve(b[0]), np.linalg.solve(a, b[0]), atol=1e-9)
    np.testing.assert_allclose(lu.solve(b[0], trans="T"), np.linalg.solve(a.T, b[0]), atol=1e-9)
    # two right-hand sides in one pass give what two separate solves give
    both = lu.solve(b)
    assert both.shape == b.shape
    np.testing.assert_allclose(both[0], lu.solve(b[0]), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(both[1], lu.solve(b[1]), rtol=1e-13, atol=1e-13)
    assert lu.det_sign() == int(np.sign(np.linalg.det(a)))


def test_det_sign_follows_the_last_row(chain_system):
    sys_, xf = chain_system
    for j in (0, 7, sys_.n_rows // 2, sys_.n_rows - 1):
        if j in set(sys_.gcols.tolist()):
            continue
        lu = sys_.factorize(xf, np.array([j]), np.array([1.0]))
        assert lu.det_sign() == int(np.sign(np.linalg.det(_dense(sys_, xf, j))))


def test_residual_written_into_a_right_hand_side(chain_system):
    sys_, xf = chain_system
    x = xf.reshape(sys_.n, sys_.d)
    diff = x[sys_.edges[:, 0]] - x[sys_.edges[:, 1]]
    want = np.concatenate([0.5 * ((diff ** 2).sum(axis=1) - sys_.rest2),
                           xf[sys_.gcols] - sys_.gvals])
    np.testing.assert_allclose(sys_.residual(xf), want, rtol=1e-13, atol=1e-16)
    out = np.full(sys_.n_rows, 7.0)
    r = sys_.residual(xf, out=out)
    np.testing.assert_array_equal(out[:-1], r)
    assert out[-1] == 7.0  # the last entry is the caller's


def test_edge_errors_planar_and_spatial_match_the_network(monkeypatch):
    from fabkit.kinematics import record

    monkeypatch.setattr(record, "BLOCK_LENGTHS", 50)  # blocks of 2 configurations
    rng = np.random.default_rng(5)
    for d in (2, 3):
        x = rng.standard_normal((9, d))
        edges = [[i, (i + k) % 9] for i in range(9) for k in (1, 2)]
        net = fabkit.Network(x, edges)
        pos = x + 1e-4 * rng.standard_normal((41, 9, d))
        np.testing.assert_allclose(edge_errors(net, pos), net.edge_error(pos), rtol=1e-12)
        np.testing.assert_allclose(edge_errors(net, pos[::3]), net.edge_error(pos[::3]),
                                   rtol=1e-12)  # strided input


def test_align_to_gauge_over_several_blocks():
    rng = np.random.default_rng(6)
    pos = rng.standard_normal((3000, 6, 2))  # more configurations than one block holds
    ref = pos[0]
    out = align_to_gauge(pos, ref, (0, 1, 2))
    fit = rigid_fit(pos[:, [0, 1, 2]], ref[[0, 1, 2]])
    want = np.einsum("sab,snb->sna", fit.rotation, pos) + fit.shift[:, None, :]
    np.testing.assert_allclose(out, want, atol=1e-12)
