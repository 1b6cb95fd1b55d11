"""Property tests (hypothesis): rigid motions and reflections change nothing a design depends on
(mode counts, edge lengths, port distances, the module map, traced motions), and kerf
compensation round-trips without touching the bar lengths."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import fabkit
from fabkit.model.rigidity import count_modes

from conftest import module_network

DATA = json.loads((Path(__file__).resolve().parent / "data" / "paper_modules.json").read_text())
# the planar modules of the paper (their networks come from the bundled templates)
MODULES = sorted(k for k, v in DATA["modules"].items() if len(v["nodes"][0]) == 2
                 and k not in ("printed_planar",))
PROPS = settings(max_examples=25, deadline=None,
                 suppress_health_check=[HealthCheck.function_scoped_fixture])


def network(name: str) -> fabkit.Network:
    return module_network(name)


def rigid_2d(angle, shift, mirror):
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    if mirror:
        rot = rot @ np.diag([1.0, -1.0])
    return lambda x: x @ rot.T + np.asarray(shift)


def rigid_3d(quat, shift, mirror):
    q = np.asarray(quat, dtype=float)
    q = q / np.linalg.norm(q)
    w, x, y, z = q
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    if mirror:
        rot = rot @ np.diag([1.0, 1.0, -1.0])
    return lambda p: p @ rot.T + np.asarray(shift)


angles = st.floats(-np.pi, np.pi, allow_nan=False)
shifts2 = st.tuples(*[st.floats(-50, 50, allow_nan=False)] * 2)
shifts3 = st.tuples(*[st.floats(-50, 50, allow_nan=False)] * 3)
quats = st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 4).filter(
    lambda q: np.linalg.norm(q) > 0.1)
module_names = st.sampled_from(sorted(MODULES))


@PROPS
@given(name=module_names, angle=angles, shift=shifts2, mirror=st.booleans())
def test_rigid_motions_keep_mode_counts_lengths_and_ports(name, angle, shift, mirror):
    net = network(name)
    moved = net.with_nodes(rigid_2d(angle, shift, mirror)(net.nodes))
    a, b = count_modes(net), count_modes(moved)
    assert (a.total, a.rigid, a.conformational, a.self_stress) == \
        (b.total, b.rigid, b.conformational, b.self_stress)
    assert a.conformational == 1
    np.testing.assert_allclose(moved.edge_lengths, net.edge_lengths, rtol=1e-12)
    for port in net.ports:
        assert float(moved.port_distance(port)) == pytest.approx(float(net.port_distance(port)),
                                                                 rel=1e-12)
    assert moved.edge_error(moved.nodes) < 1e-12
    assert np.array_equal(moved.edges, net.edges) and moved.ports == net.ports


@functools.lru_cache(maxsize=None)
def module_map_of(name: str):
    """The module's map, or None when its reference is a flat state (no branch to follow)."""
    try:
        return fabkit.module_map(network(name))
    except fabkit.ConstructionError:
        return None


@PROPS
@given(name=module_names, angle=angles, shift=shifts2, mirror=st.booleans(),
       t=st.floats(0.05, 0.95))
def test_rigid_motions_keep_the_module_map(name, angle, shift, mirror, t):
    net = network(name)
    f = module_map_of(name)
    assume(f is not None)
    moved = net.with_nodes(rigid_2d(angle, shift, mirror)(net.nodes))
    g = fabkit.module_map(moved)
    lo, hi = f.domain
    assert g.domain == pytest.approx(f.domain, rel=1e-9, abs=1e-12)
    d = lo + t * (hi - lo)
    assert g(d) == pytest.approx(f(d), rel=1e-9, abs=1e-12)
    assert g.derivative(d) == pytest.approx(f.derivative(d), rel=1e-6, abs=1e-9)


@PROPS
@given(angle=angles, shift=shifts2, mirror=st.booleans(), to=st.floats(1.2, 3.5))
def test_traced_motion_does_not_depend_on_placement(angle, shift, mirror, to):
    # the antiparallelogram keeps d1 * d2 = 4 wherever it is drawn
    net = network("fourbar")
    moved = net.with_nodes(rigid_2d(angle, shift, mirror)(net.nodes))
    a = fabkit.trace(net, drive="d1", to=to)
    b = fabkit.trace(moved, drive="d1", to=to)
    assert str(a.status) == str(b.status) == "finished"
    np.testing.assert_allclose(b.distance("d2"), a.distance("d2"), rtol=1e-12)
    np.testing.assert_allclose(b.distance("d1") * b.distance("d2"), 4.0, rtol=1e-12)
    assert b.max_edge_error < 1e-12


@PROPS
@given(quat=quats, shift=shifts3, mirror=st.booleans())
def test_rigid_motions_keep_3d_mode_counts(quat, shift, mirror):
    net = module_network("origami_sheet")
    # lift the flat sheet off its bifurcation so the count is generic
    x = net.nodes.copy()
    x[4, 2] = 0.3
    net = fabkit.Network(x, net.edges, net.ports)
    moved = net.with_nodes(rigid_3d(quat, shift, mirror)(net.nodes))
    a, b = count_modes(net), count_modes(moved)
    assert (a.total, a.rigid, a.conformational, a.self_stress) == \
        (b.total, b.rigid, b.conformational, b.self_stress)
    assert a.rigid == 6
    np.testing.assert_allclose(moved.edge_lengths, net.edge_lengths, rtol=1e-12)


@PROPS
@given(n=st.integers(4, 9), seed=st.integers(0, 10_000), angle=angles, shift=shifts2)
def test_random_networks_count_the_same_anywhere(n, seed, angle, shift):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 2))
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)])
    edges = pairs[rng.choice(len(pairs), size=min(len(pairs), 2 * n - 3), replace=False)]
    net = fabkit.Network(x, edges)
    moved = net.with_nodes(rigid_2d(angle, shift, False)(x))
    a, b = count_modes(net), count_modes(moved)
    assert (a.total, a.conformational, a.self_stress) == (b.total, b.conformational, b.self_stress)
    # Maxwell: dN - E + S = zero modes
    assert a.total == 2 * n - len(edges) + a.self_stress


@PROPS
@given(scale=st.floats(0.01, 100.0), name=module_names)
def test_scaling_keeps_mode_counts_and_scales_lengths(scale, name):
    net = network(name)
    big = net.with_nodes(net.nodes * scale)
    a, b = count_modes(net), count_modes(big)
    assert (a.total, a.conformational, a.self_stress) == (b.total, b.conformational, b.self_stress)
    np.testing.assert_allclose(big.edge_lengths, scale * net.edge_lengths, rtol=1e-12)


# --- kerf -------------------------------------------------------------------------------------

@settings(max_examples=200, deadline=None)
@given(width=st.floats(5.0, 40.0), hole=st.floats(1.0, 4.9), kerf=st.floats(0.0, 0.5),
       length=st.floats(10.0, 300.0))
def test_kerf_compensation_round_trips_and_keeps_bar_lengths(width, hole, kerf, length):
    from fabkit.fab.bars import bar_outline, hole_radius, outline_radius, undo_kerf

    drawn = bar_outline(length, width, kerf)
    r_out = float(drawn[3, 1])
    assert r_out == pytest.approx(outline_radius(width, kerf), rel=1e-15)
    got_width, got_hole = undo_kerf(r_out, hole_radius(hole, kerf), kerf)
    assert float(got_width) == pytest.approx(width, rel=1e-12)
    assert float(got_hole) == pytest.approx(hole, rel=1e-12)
    # compensation moves edges, never hole centres: the bar's length is the design's
    assert float(drawn[1, 0] - drawn[0, 0]) == length
    assert np.array_equal(bar_outline(length, width, 0.0)[:, 0], drawn[:, 0])


@settings(max_examples=100, deadline=None)
@given(sigma=st.floats(0.0, 0.2), seed=st.integers(0, 1000))
def test_tolerance_samples_are_reproducible_and_centred(sigma, seed):
    from fabkit.tolerance import ToleranceSpec, perturbed_lengths

    spec = ToleranceSpec(samples=64, seed=seed, length_sigma=sigma, kerf_sigma=0.0,
                         hole_clearance=0.0, thickness_sigma=0.0)
    a, _ = perturbed_lengths([1.0, 2.0, 3.0], spec, np.random.default_rng(seed))
    b, _ = perturbed_lengths([1.0, 2.0, 3.0], spec, np.random.default_rng(seed))
    assert np.array_equal(a, b)
    # with no joint play the errors are pure length errors: |error| < 6 sigma always
    assert np.abs(a - [1.0, 2.0, 3.0]).max() * spec.scale <= 6 * sigma + 1e-15
