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


def test_a_second_system_of_the_same_bars_shares_the_orderings_and_solves_alike(fourbar):
    """The orderings are kept for the next system of the same network (the tolerance analysis
    traces a hundred builds of one design); its factors and solves are those of a fresh one."""
    net = fabkit.chain(fourbar, copies=6)
    first, x0 = _system(net)
    second, _ = _system(net)
    assert second._colperm is first._colperm and second._base_order is first._base_order
    assert not second._colpos.flags.writeable  # shared, so read-only
    xf = x0.ravel() + 1e-3 * np.random.default_rng(5).standard_normal(x0.size)
    rhs = np.random.default_rng(6).standard_normal(first.n_rows)
    for j in (3, 3, 17):  # the last row's placement is kept per column, too
        a, b = first.factorize(xf, np.array([j]), np.array([1.0])), \
            second.factorize(xf, np.array([j]), np.array([1.0]))
        assert np.array_equal(a.solve(rhs), b.solve(rhs)) and a.det_sign() == b.det_sign()
        want = np.linalg.solve(_dense(first, xf, j), rhs)
        assert np.allclose(a.solve(rhs), want, rtol=1e-9, atol=1e-9)
    # another gauge: its own row order, the same as a system made with it from the start
    gcols = gauge_rows(x0, (4, 5))
    first.regauge(gcols, x0.ravel()[gcols])
    fresh = BorderedSystem(net.edges, net.edge_lengths ** 2, *x0.shape, gcols, x0.ravel()[gcols],
                           None)
    assert np.array_equal(first._base_order, fresh._base_order)
    j = next(c for c in range(20, 40) if c not in gcols)  # a column the gauge leaves free
    lu_a, lu_b = (s.factorize(xf, np.array([j]), np.array([1.0])) for s in (first, fresh))
    assert np.array_equal(lu_a.solve(rhs), lu_b.solve(rhs))


def test_until_ends_a_trace_where_the_caller_says_and_keeps_its_steps(fourbar):
    """``until`` cuts a projected trace after the first configuration it holds for; the
    configurations up to there are those of the trace without it."""
    net = fabkit.chain(fourbar, copies=4)
    full = fabkit.trace(net, drive="d1", to=2.5, method="projected")
    a, b = net.port("d1")
    middle = 0.5 * (float(full.drive[0]) + 2.5)
    cut = fabkit.trace(net, drive="d1", to=2.5, method="projected",
                       until=lambda x: float(np.linalg.norm(x[a] - x[b])) > middle)
    k = len(cut.positions)
    assert str(full.status) == "finished" and str(cut.status) == "failed"
    assert "until" in cut.message and 2 < k < len(full.positions)
    assert np.array_equal(cut.positions, full.positions[:k])
    assert cut.drive[-1] > middle >= cut.drive[-2]
