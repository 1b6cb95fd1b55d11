"""The same-layer clearance check measures only the pairs that come near at some samples; its
answer (smallest gap, which parts, which sample) is that of measuring every pair at every
sample, found here by brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fabkit
from fabkit.check.clearance import point_gap, same_layer_gaps, segment_gap


def _first_least(gaps: dict) -> tuple:
    """Smallest gap over {(first, second): gaps per sample}: ties to the earliest sample, then
    the lowest pair."""
    best = (math.inf, -1, (-1, -1))
    for pair in sorted(gaps):
        g = gaps[pair]
        s = int(np.flatnonzero(g == g.min())[0])
        best = min(best, (float(g[s]), s, pair))
    return best


def _brute(edges, layer, x, widths, columns):
    """Every pair of parts sharing a layer measured at every sample."""
    edges = np.asarray(edges)
    half = 0.5 * np.broadcast_to(np.asarray(widths, dtype=float), (len(edges),))
    bars, joint, screws, cols = {}, [], {}, {}
    for i in range(len(edges)):
        for j in range(i + 1, len(edges)):
            if layer[i] != layer[j]:
                continue
            if set(edges[i]) & set(edges[j]):
                joint.append((-(half[i] + half[j]), i, j))
                continue
            bars[(i, j)] = segment_gap(x[:, edges[i, 0]], x[:, edges[i, 1]], x[:, edges[j, 0]],
                                       x[:, edges[j, 1]]) - half[i] - half[j]
    jid = columns["joints"]
    r, r_in = columns["radius"], columns["inner_radius"]
    for i in range(len(edges)):
        for k, jo in enumerate(jid):
            z = layer[i]
            if not columns["low"][k] <= z <= columns["high"][k] or jo in edges[i]:
                continue
            inner = columns["inner_low"][k] <= z <= columns["inner_high"][k]
            screws[(i, k)] = point_gap(x[:, jo], x[:, edges[i, 0]], x[:, edges[i, 1]]) \
                - half[i] - (max(r, r_in) if inner else r)
    for k in range(len(jid)):
        for m in range(k + 1, len(jid)):
            if columns["low"][k] <= columns["high"][m] and columns["low"][m] <= columns["high"][k]:
                cols[(k, m)] = np.linalg.norm(x[:, jid[k]] - x[:, jid[m]], axis=-1) - 2 * r
    return bars, min(joint, default=None), screws, cols


def _assert_same(edges, layer, x, widths, columns):
    got = same_layer_gaps(edges, layer, x, widths, columns=columns)
    bars, joint, screws, cols = _brute(edges, layer, x, widths, columns)
    gap, sample, pair = _first_least(bars)
    assert got["bar_gap"] == gap and got["sample"] == (sample if bars else None)
    assert got["bar_pair"] == (list(pair) if bars else None)
    assert got["joint_gap"] == (joint[0] if joint else math.inf)
    gap, _, (i, k) = _first_least(screws)
    assert got["screw_gap"] == gap
    assert got["screw_at"] == ([i, int(columns["joints"][k])] if screws else None)
    gap, _, (k, m) = _first_least(cols)
    assert got["column_gap"] == gap
    assert got["column_pair"] == ([int(columns["joints"][k]), int(columns["joints"][m])]
                                  if cols else None)
    return got


def _columns(rng, n_joints, n_layers):
    low = rng.integers(-1, n_layers, n_joints)
    high = np.minimum(low + rng.integers(0, 4, n_joints), n_layers)
    return {"joints": np.arange(n_joints), "low": low, "high": high,
            "inner_low": low + 1, "inner_high": high - 1, "radius": 1.5, "inner_radius": 2.5}


@pytest.mark.parametrize("name", ["fourbar_chain", "super_stable", "slope_one_chain"])
def test_bundled_motions_give_the_gaps_of_every_pair_at_every_sample(name):
    design = fabkit.load_template(name)
    net = design.network
    x = np.asarray(design.trace().positions, dtype=float)[..., :2]
    edges = np.asarray(net.edges)
    scale = 50.0 / float(np.median(np.linalg.norm(x[0, edges[:, 0]] - x[0, edges[:, 1]],
                                                  axis=1)))
    x = np.repeat(x * scale, 3, axis=0)[: 3 * x.shape[0] - 2]  # repeated samples: ties
    rng = np.random.default_rng(7)
    layer = rng.integers(0, 3, len(edges))
    got = _assert_same(edges, layer, x, 6.0, _columns(rng, x.shape[1], 3))
    assert got["bar_pair"] is not None and got["screw_at"] is not None


@pytest.mark.parametrize("seed", range(6))
def test_random_bars_give_the_gaps_of_every_pair_at_every_sample(seed):
    rng = np.random.default_rng(seed)
    n, s = int(rng.integers(8, 40)), int(rng.integers(1, 120))
    # joints wander from random starts: some bars cross (negative gaps), some stay far apart
    x = rng.uniform(0, 300, (1, n, 2)) + np.cumsum(rng.normal(0, 2.0, (s, n, 2)), axis=0)
    edges = np.array([rng.choice(n, 2, replace=False) for _ in range(int(rng.integers(5, 60)))])
    layer = rng.integers(0, 4, len(edges))
    widths = rng.uniform(2.0, 12.0, len(edges))
    _assert_same(edges, layer, x, widths, _columns(rng, n, 4))


def test_far_parts_are_still_measured():
    """Two bars a metre apart on a layer: the reach grows until it holds their gap."""
    x = np.array([[[0.0, 0.0], [10.0, 0.0], [1000.0, 0.0], [1010.0, 5.0]]] * 40)
    x[:, 2:, 0] += np.linspace(0, -3, 40)[:, None]
    cols = {"joints": np.array([0, 3]), "low": np.array([0, 0]), "high": np.array([0, 0]),
            "inner_low": np.array([1, 1]), "inner_high": np.array([0, 0]), "radius": 2.0,
            "inner_radius": 2.0}
    got = _assert_same([[0, 1], [2, 3]], [0, 0], x, 4.0, cols)
    assert got["bar_gap"] == pytest.approx(990.0 - 3.0 - 4.0)
    assert got["sample"] == 39


def test_small_blocks_split_and_give_the_same_gaps(monkeypatch):
    """Blocks of samples split when they would hold too many candidates; measurements in
    small pieces: the same answer."""
    import fabkit.check.clearance as clearance

    monkeypatch.setattr(clearance, "BLOCK_ELEMENTS", 2**12)
    monkeypatch.setattr(clearance, "MEASURE_ELEMENTS", 7)
    monkeypatch.setattr(clearance, "WINDOW_SAMPLES", 4)
    near, splits = clearance._near, []

    def counted(*args):
        out = near(*args)
        splits.append(out is None)
        return out

    monkeypatch.setattr(clearance, "_near", counted)
    rng = np.random.default_rng(11)
    n, s = 30, 200
    x = rng.uniform(0, 200, (1, n, 2)) + np.cumsum(rng.normal(0, 1.0, (s, n, 2)), axis=0)
    edges = np.array([rng.choice(n, 2, replace=False) for _ in range(40)])
    _assert_same(edges, rng.integers(0, 3, 40), x, 5.0, _columns(rng, n, 3))
    assert any(splits)


def _point_gap_pairs(x, p, q):
    """Distance from points to segments written on (..., 2) arrays summed over their last axis."""
    d = q - p
    dd = (d * d).sum(-1)
    t = np.clip(((x - p) * d).sum(-1) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    e = p + t[..., None] * d - x
    return np.sqrt((e * e).sum(-1))


def test_distances_on_components_are_those_of_point_pairs_to_the_bit():
    """The gaps are measured on x and y apart: the very values of the (..., 2) formulas, with
    segments of no length, shared ends and crossings among them."""
    rng = np.random.default_rng(5)
    p1, q1, p2, q2 = (rng.uniform(-50, 50, (4000, 2)) for _ in range(4))
    q1[:300] = p1[:300]          # segments of no length
    p2[300:600] = q1[300:600]    # touching at an end
    p2[600:900] = np.round(p2[600:900])
    q2[600:900] = np.round(q2[600:900])
    got = point_gap(p1, p2, q2)
    assert np.array_equal(got, _point_gap_pairs(p1, p2, q2))
    seg = segment_gap(p1, q1, p2, q2)
    ref = np.minimum(np.minimum(_point_gap_pairs(p1, p2, q2), _point_gap_pairs(q1, p2, q2)),
                     np.minimum(_point_gap_pairs(p2, p1, q1), _point_gap_pairs(q2, p1, q1)))
    crossing = seg == 0.0
    assert np.array_equal(seg[~crossing], ref[~crossing])
    assert 0 < crossing.sum() < len(seg)
    # by hand: crossing diagonals, parallel bars 3 apart, a point 5 from a segment of no length
    a, b, c, d = (np.array(v, dtype=float) for v in ([[0, 0], [0, 0]], [[2, 2], [1, 0]],
                                                     [[0, 2], [0, 3]], [[2, 0], [1, 3]]))
    assert segment_gap(a, b, c, d).tolist() == [0.0, 3.0]
    assert point_gap(np.array([1.0, 1.0]), np.array([4.0, 5.0]), np.array([4.0, 5.0])) == 5.0


@pytest.mark.parametrize("seed", range(3))
def test_bars_on_a_whole_millimetre_grid_give_the_gaps_of_every_pair(seed):
    """Joints on whole millimetres: boxes that start and end where others do (ties in the sort
    and sweep) are all measured."""
    rng = np.random.default_rng(100 + seed)
    n, s = 24, 90
    x = np.round(rng.uniform(0, 60, (1, n, 2)) + np.cumsum(rng.integers(-1, 2, (s, n, 2)),
                                                          axis=0)).astype(float)
    edges = np.array([rng.choice(n, 2, replace=False) for _ in range(40)])
    layer = rng.integers(0, 3, len(edges))
    got = _assert_same(edges, layer, x, 4.0, _columns(rng, n, 3))
    assert got["bar_pair"] is not None
