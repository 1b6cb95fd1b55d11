"""Independent edges of a network with states of self-stress: the windowed selection keeps exactly
the certified rank, its rows are independent, and `projected` traces with it what it traced with
the dense column-pivoted QR, beyond the size the dense QR could take."""

import functools

import numpy as np
import pytest

import fabkit
from fabkit import Network, count_modes
from fabkit.model import rigidity
from fabkit.bench import large
from fabkit.errors import KinematicsError, NetworkError
from fabkit.model import independent_edges as selection
from fabkit.model.independent_edges import independent_edges
from fabkit.model.rigidity import rigidity_matrix

from conftest import TEMPLATES


def k4():
    """A square with both diagonals: one state of self-stress."""
    return Network([[0, 0], [1, 0], [1, 1], [0, 1]],
                   [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3]])


def random_overbraced(seed=3, n=30, e=90):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(0, 10, (n, 2))
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    pick = rng.choice(len(pairs), e, replace=False)
    return Network(pts, [pairs[p] for p in pick])


def collinear_rails(cells=6):
    """A braced ladder whose two rails also carry one long bar each, collinear with the rail: two
    states of self-stress that exist only because the rails are straight (non-generic)."""
    top = [[i, 1.0] for i in range(cells + 1)]
    bottom = [[i, 0.0] for i in range(cells + 1)]
    b = cells + 1
    edges = [[i, i + 1] for i in range(cells)] + [[b + i, b + i + 1] for i in range(cells)]
    edges += [[i, b + i] for i in range(cells + 1)] + [[i, b + i + 1] for i in range(cells)]
    edges += [[0, cells], [b, b + cells]]
    return Network(top + bottom, edges)


def parallel_bars():
    """Three parallel, equal bars joining two triangles (a rigid-body translation pair): the third
    bar is redundant only because the three are parallel."""
    nodes = [[0, 0], [2, 0], [1, 1], [0, 3], [2, 3], [1, 4]]
    edges = [[0, 1], [1, 2], [2, 0], [3, 4], [4, 5], [5, 3], [0, 3], [1, 4], [2, 5]]
    return Network(nodes, edges)


def k5_3d():
    """Five nodes in space joined by all 10 bars: one state of self-stress."""
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.7, 0.6, 0.8]]
    return Network(pts, [[i, j] for i in range(5) for j in range(i + 1, 5)])


NETWORKS = {
    "k4": k4,
    "random_overbraced": random_overbraced,
    "collinear_rails": collinear_rails,
    "parallel_bars": parallel_bars,
    "k5_3d": k5_3d,
    "and_gate": lambda: fabkit.load_template(TEMPLATES / "and_gate.toml").network,
    **{f"lattice_{k}": functools.partial(large.lattice, k) for k in range(3, 9)},
}


def svd_rank(r):
    s = np.linalg.svd(r, compute_uv=False)
    return int((s > 1e-9 * max(s[0], 1.0)).sum()), s


@pytest.mark.parametrize("block", [3, 64])
@pytest.mark.parametrize("name", sorted(NETWORKS))
def test_windowed_selection_keeps_the_certified_rank(name, block):
    net = NETWORKS[name]()
    m = count_modes(net)
    assert not m.ambiguous
    rank = net.n_edges - m.self_stress
    assert m.self_stress > 0  # every network here has redundant edges
    keep = independent_edges(net, method="windowed", block=block)
    dense = independent_edges(net, method="dense")
    r = rigidity_matrix(net, normalized=True).toarray()
    assert svd_rank(r)[0] == rank
    assert keep.size == dense.size == rank
    assert np.all(np.diff(keep) > 0) and keep[0] >= 0 and keep[-1] < net.n_edges
    kept_rank, s = svd_rank(r[keep])
    assert kept_rank == rank
    assert s[-1] > 1e-4  # independent with room to spare, not just above the threshold


def test_special_positions_drop_a_redundant_bar():
    # the collinear long bars and the third parallel bar are each in a self-stress: whatever is
    # dropped, the kept rows span every row of R
    for net in (collinear_rails(), parallel_bars()):
        r = rigidity_matrix(net, normalized=True).toarray()
        keep = independent_edges(net, method="windowed", block=2)
        dropped = np.setdiff1d(np.arange(net.n_edges), keep)
        coef, *_ = np.linalg.lstsq(r[keep].T, r[dropped].T, rcond=None)
        assert np.abs(r[keep].T @ coef - r[dropped].T).max() < 1e-12


def test_every_bundled_template_keeps_its_rank():
    for path in sorted(TEMPLATES.glob("*.toml")):
        net = fabkit.load_template(path).network
        if net.n_nodes * net.dim > 600:
            continue  # the long chains: the dense reference would dominate the suite
        m = count_modes(net)
        keep = independent_edges(net, method="windowed", block=5)
        assert keep.size == net.n_edges - m.self_stress, path.name
        if m.self_stress == 0:
            assert keep.tolist() == list(range(net.n_edges)), path.name


def test_rank_given_or_counted_agree():
    net = large.lattice(5)
    m = count_modes(net)
    counted = independent_edges(net)
    given = independent_edges(net, rank=net.n_edges - m.self_stress)
    assert counted.tolist() == given.tolist()
    assert counted.size == 2 * net.n_nodes - 4  # 3 rigid motions and 1 conformational


def test_failed_check_falls_back_to_the_dense_qr_or_raises():
    # a threshold of 0.5 throws away rows the rank needs: the count check fails
    net = large.lattice(4)
    rank = net.n_edges - count_modes(net).self_stress
    with pytest.raises(KinematicsError, match=f"no independent set of {rank} edges"):
        independent_edges(net, rank=rank, rtol=0.5, method="windowed")
    auto = independent_edges(net, rank=rank, rtol=0.5)
    assert auto.tolist() == independent_edges(net, rank=rank, method="dense").tolist()
    # a rank the rows cannot have: neither more kept rows nor a fallback invents it
    with pytest.raises(KinematicsError, match=f"where the rank is {rank + 1}"):
        independent_edges(net, rank=rank + 1, method="windowed")


def test_bad_input():
    with pytest.raises(ValueError, match="unknown method 'qr'"):
        independent_edges(k4(), method="qr")
    with pytest.raises(NetworkError, match="edge 4 .* zero or undefined length") as exc:
        independent_edges(k4(), positions=[[0, 0], [1, 0], [0, 0], [0, 1]])
    assert exc.value.key == "edges[4]"
    none = Network([[0, 0], [1, 0]], np.zeros((0, 2), dtype=int))
    assert independent_edges(none).tolist() == []
    # a triangle 1e-9 from collinear: the rank is ambiguous, so nothing is picked
    flat = Network([[0.0, 0.0], [2.0, 0.0], [1.0, 1e-9]], [[0, 1], [1, 2], [0, 2]])
    with pytest.raises(KinematicsError, match="rank of the rigidity matrix is ambiguous"):
        independent_edges(flat)


# -- projected on lattices ------------------------------------------------------------------------

def dense_selection(monkeypatch):
    """Make `projected` pick its edges by the dense column-pivoted QR (its former rule)."""
    monkeypatch.setattr(selection, "independent_edges",
                        functools.partial(selection.independent_edges, method="dense"))


def all_edge_error(net, positions):
    x = np.asarray(positions)
    e = net.edges
    lengths = np.linalg.norm(x[:, e[:, 0]] - x[:, e[:, 1]], axis=2)
    return float(np.abs(lengths / net.edge_lengths - 1).max())


def test_lattice_traces_the_configurations_of_the_dense_selection(monkeypatch):
    net = large.lattice(8)
    traj = fabkit.trace(net, drive="d1_0_0", to=2.5, method="projected")
    assert str(traj.status) == "finished" and len(traj.positions) >= 4
    # every edge keeps its length, the dropped (redundant) ones included
    assert independent_edges(net).size < net.n_edges
    assert all_edge_error(net, traj.positions) < 1e-13
    dense_selection(monkeypatch)
    for i in (1, len(traj.positions) // 2, len(traj.positions) - 1):
        value = float(np.linalg.norm(traj.positions[i][0] - traj.positions[i][1]))
        ref = fabkit.trace(net, drive="d1_0_0", to=value, method="projected")
        assert str(ref.status) == "finished"
        assert np.abs(ref.positions[-1] - traj.positions[i]).max() < 1e-10


def test_lattice_beyond_the_dense_limit_is_traced():
    # 2116 nodes, 4232 coordinates: refused before (dense QR only up to 4000 coordinates)
    net = large.lattice(45)
    assert 2 * net.n_nodes > rigidity.DENSE_LIMIT
    traj = fabkit.trace(net, drive="d1_0_0", to=2.5, method="projected")
    assert str(traj.status) == "finished"
    d1 = np.linalg.norm(traj.positions[-1][0] - traj.positions[-1][1])
    assert d1 == pytest.approx(2.5, abs=1e-12)
    assert all_edge_error(net, traj.positions) < 1e-12


def test_two_motions_with_self_stress_are_refused():
    # two braced squares sharing a side (2 self-stresses) with a 5-bar loop hanging off: 2 motions
    nodes = [[0, 0], [1, 0], [1, 1], [0, 1], [1.2, 2], [0.5, 2.6], [-0.2, 2], [2, 0.2],
             [2.1, 1.1]]
    edges = [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3], [2, 4], [4, 5], [5, 6], [6, 3],
             [1, 7], [7, 8], [8, 2], [1, 8], [7, 2]]
    net = Network(nodes, edges)
    with pytest.raises(KinematicsError, match="2 conformational motions"):
        fabkit.trace(net, drive=(2, 5), to=1.5, method="projected")
    # holding one distance leaves one motion, traced with a redundant edge dropped
    traj = fabkit.trace(net, drive=(2, 5), to=1.5, method="projected", hold=[(4, 6)])
    assert str(traj.status) == "finished"
    assert all_edge_error(net, traj.positions) < 1e-12


def delaunay_overbraced(seed, n=200):
    """A Delaunay triangulation of random points with n/3 random extra bars."""
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed)
    pts = rng.uniform(0, 10, (n, 2))
    edges = {tuple(sorted((int(t[a]), int(t[(a + 1) % 3]))))
             for t in Delaunay(pts).simplices for a in range(3)}
    for i, j in rng.choice(n, (n // 3, 2)):
        if i != j:
            edges.add((int(min(i, j)), int(max(i, j))))
    return Network(pts, sorted(edges))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_nearly_dependent_rows_wait_for_better_ones(seed):
    # kept as they come, the rows of a random over-braced network ended 100-1000 times worse
    # conditioned than the dense QR's choice (or with a dependent row among them)
    net = delaunay_overbraced(seed)
    r = rigidity_matrix(net, normalized=True).toarray()
    keep = independent_edges(net, method="windowed")
    dense = independent_edges(net, method="dense")
    assert keep.size == dense.size == net.n_edges - count_modes(net).self_stress
    s_keep = np.linalg.svd(r[keep], compute_uv=False)[-1]
    s_dense = np.linalg.svd(r[dense], compute_uv=False)[-1]
    assert s_keep > s_dense / 10
