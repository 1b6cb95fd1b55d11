"""What a trace keeps (keep="all" | "ports" | k): the same drive, arclength, edge errors and port
distances as the full trace, the positions of the configurations asked for only; and projected on
the long mirrored super-stable chain, in a gauge that keeps the far end still."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fabkit
from fabkit.bench import paper_module
from fabkit.bench.workprecision import collapsed_fixed_point
from fabkit.errors import KinematicsError
from fabkit.kinematics import Status

ROOT = Path(__file__).resolve().parents[1]


def soliton_target():
    return collapsed_fixed_point() + 1e-12


def chain(k):
    """The super-stable module chained k times, every second one mirrored (Fig. 3f scaled up)."""
    return fabkit.chain(paper_module("super_stable"), copies=k, mirror="alternate")


@pytest.mark.parametrize("method", ["constructive", "projected"])
def test_ports_keep_every_scalar_and_two_configurations(method):
    net = chain(40)
    full = fabkit.trace(net, "d1", to=1.2, method=method)
    thin = fabkit.trace(net, "d1", to=1.2, method=method, keep="ports")
    s = full.n_steps
    assert thin.n_steps == s and str(thin.status) == str(full.status) == "finished"
    assert thin.kept.tolist() == [0, s - 1] and thin.positions.shape == (2, net.n_nodes, 2)
    np.testing.assert_allclose(thin.positions, full.positions[[0, -1]], atol=1e-12)
    np.testing.assert_allclose(thin.final, full.final, atol=1e-12)
    np.testing.assert_allclose(thin.drive, full.drive, atol=1e-13)
    np.testing.assert_allclose(thin.arclength, full.arclength, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(thin.edge_error, full.edge_error, atol=1e-14)
    assert set(thin.port_values) == set(net.ports)
    for name in ("d1", "d2", "d20", "d41"):
        np.testing.assert_allclose(thin.distance(name), full.distance(name), atol=1e-12)
    assert full.kept is None and full.port_values is None


def test_every_kth_configuration_and_the_last():
    net = chain(30)
    full = fabkit.trace(net, "d1", to=1.1, method="constructive", samples=23)
    thin = fabkit.trace(net, "d1", to=1.1, method="constructive", samples=23, keep=10)
    assert thin.kept.tolist() == [0, 10, 20, 22]
    np.testing.assert_allclose(thin.positions, full.positions[[0, 10, 20, 22]], atol=1e-12)


def test_events_keep_their_drive_and_arclength_when_thinned(fourbar):
    full = fabkit.trace(fourbar, "d1", to=0.5, method="projected")
    thin = fabkit.trace(fourbar, "d1", to=0.5, method="projected", keep="ports")
    assert full.status == thin.status == Status.BRANCH_POINT
    (ev,), (et,) = full.events, thin.events
    assert (et.kind, et.index) == (ev.kind, ev.index) == (ev.kind, full.n_steps - 1)
    assert et.drive == pytest.approx(ev.drive, abs=1e-13)
    assert et.arclength == pytest.approx(ev.arclength, rel=1e-12)


def test_branch_method_thins_too():
    sheet = paper_module("origami_sheet")
    thin = fabkit.trace(sheet, "d1", to=1.2, method="branch", keep="ports")
    full = fabkit.trace(sheet, "d1", to=1.2, method="branch")
    assert thin.n_steps == full.n_steps and thin.positions.shape[0] == 2
    np.testing.assert_allclose(thin.distance("d2"), full.distance("d2"), atol=1e-12)


def test_node_pairs_need_all_positions_and_bad_keeps_are_refused():
    net = chain(5)
    thin = fabkit.trace(net, "d1", to=1.2, keep="ports")
    with pytest.raises(KinematicsError, match=r"kept the positions of 2 of its 101 "):
        thin.distance((0, 5))
    with pytest.raises(KeyError, match="unknown port 'd99'"):
        thin.distance("d99")
    for bad in ("some", 0, -3, 2.5, True):
        with pytest.raises(KinematicsError, match="`keep` must be 'all', 'ports' or a positive"):
            fabkit.trace(net, "d1", to=1.2, keep=bad)


def test_a_hundred_thousand_module_trace_keeps_the_ports():
    net = chain(100_000)
    traj = fabkit.trace(net, "d1", to=soliton_target(), method="constructive", keep="ports")
    assert traj.status == Status.FINISHED and traj.n_steps == 101
    assert traj.positions.shape == (2, 300_002, 2)
    assert traj.max_edge_error < 1e-10
    d = traj.port_values
    # the soliton: the collapse front is 20 modules in; far modules keep D1* = √3 (to the
    # round-off of coordinates 1.7e5 from the origin, 4e-11)
    assert d["d1"][-1] == pytest.approx(soliton_target(), abs=1e-13)
    assert d["d100001"][-1] == pytest.approx(np.sqrt(3), abs=1e-10)
    assert d["d40"][-1] == pytest.approx(np.sqrt(3), abs=1e-9)
    assert d["d10"][-1] < 1.1  # collapsed


@pytest.mark.parametrize("name, block", [("super_stable_chain", 8), ("origami_chain12", 4),
                                         ("fourbar_chain", 2), ("printed_planar_chain10", 16)])
def test_the_streamed_sweep_matches_the_placement(monkeypatch, name, block):
    """Blocks of a few placements and a ring of rows give the configurations that one placement
    of everything gives, moved to the gauge frame."""
    from fabkit.kinematics import align_to_gauge, constructive, make_problem, place

    design = fabkit.load_template(ROOT / "templates" / f"{name}.toml")
    net, m = design.network, design.motion
    monkeypatch.setattr(constructive, "BLOCK", block)
    traj = fabkit.trace(net, m.drive, to=m.to, method="constructive", samples=17)
    problem = make_problem(net, m.drive, m.to)
    plan = constructive.cached_plan(net, problem.drive)
    x, margin, _ = place(plan, np.linspace(problem.start_drive, m.to, 17))
    assert np.all(margin[1:] >= 0) and traj.n_steps == 17
    want = align_to_gauge(x, problem.start, problem.gauge)
    np.testing.assert_allclose(traj.positions, want, atol=1e-12)
    steps = np.linalg.norm((want[1:] - want[:-1]).reshape(16, -1), axis=1)
    np.testing.assert_allclose(traj.arclength[1:], np.cumsum(steps), rtol=1e-12)
    np.testing.assert_allclose(traj.edge_error, net.edge_error(want), atol=1e-14)


def test_projected_holds_the_still_far_end_of_a_long_chain():
    """The near-drive gauge swung the whole far chain about the collapse front: steps grew with
    the chain and a third of them were rejected. Holding the stillest part keeps the step count
    of a short chain; the output is still in the caller's gauge frame."""
    to = soliton_target()
    steps = {}
    for k in (100, 2000):
        net = chain(k)
        traj = fabkit.trace(net, "d1", to=to, method="projected")
        ref = fabkit.trace(net, "d1", to=to, method="constructive", samples=2)
        assert traj.status == ref.status == Status.FINISHED and not traj.events
        assert traj.stats["gauge_changes"] >= 1 and traj.stats["rejected"] <= 10
        steps[k] = traj.stats["steps"]
        # the configuration reached is the constructive one, in the same gauge frame, where d1
        # determines it in float64: the distance to D2* grows by 4 per module, so round-off in
        # d1 (1e-16) moves the collapse front 20 modules in by 1e-5; the first 10 modules are
        # fixed to 1e-10
        np.testing.assert_allclose(traj.final[:32], ref.final[:32], atol=1e-9)
        ports = [f"d{i}" for i in range(1, 11)] + [f"d{i}" for i in range(40, k + 2)]
        np.testing.assert_allclose([traj.distance(p)[-1] for p in ports],
                                   [ref.distance(p)[-1] for p in ports], atol=1e-9)
        g = traj.positions[:, [0, 4]]  # the gauge edge near the drive: held still
        np.testing.assert_allclose(g, np.broadcast_to(net.nodes[[0, 4]], g.shape), atol=1e-12)
    assert steps[2000] <= steps[100] + 10


@pytest.mark.parametrize("method", ["constructive", "projected"])
def test_ports_chooses_the_distances_kept_bit_for_bit(method):
    """A trace that keeps some ports' distances reports, for them, what one that keeps every
    port, or every configuration's positions (keep=1), reports: the same numbers, bit for bit."""
    net = chain(40)
    every = fabkit.trace(net, "d1", to=1.2, method=method, keep="ports")
    some = fabkit.trace(net, "d1", to=1.2, method=method, keep="ports", ports=["d41", "d1", "d7"])
    frames = fabkit.trace(net, "d1", to=1.2, method=method, keep=1)
    assert str(some.status) == str(every.status) == str(frames.status) == "finished"
    assert some.message == every.message and some.events == every.events
    for other in (every, frames):
        for field in ("drive", "arclength", "edge_error"):
            assert np.array_equal(getattr(some, field), getattr(other, field))
        assert np.array_equal(some.positions, other.positions[other.kept.searchsorted(some.kept)])
    assert list(some.port_values) == ["d41", "d1", "d7"] and len(every.port_values) == 41
    for name in ("d1", "d7", "d41"):
        assert np.array_equal(some.distance(name), every.distance(name))
        assert np.array_equal(some.distance(name), frames.distance(name))
    with pytest.raises(KinematicsError, match="kept the distances of 3 ports"):
        some.distance("d2")


def test_ports_are_checked():
    net = chain(5)
    with pytest.raises(KinematicsError, match="'d9', which is not a port"):
        fabkit.trace(net, "d1", to=1.2, keep="ports", ports=["d1", "d9"])
    with pytest.raises(KinematicsError, match="keep='all' keeps every configuration"):
        fabkit.trace(net, "d1", to=1.2, ports=["d1"])
    with pytest.raises(TypeError, match="list of port names"):
        fabkit.trace(net, "d1", to=1.2, keep="ports", ports="d1")


def test_a_chain_keeps_its_ports_as_one_array():
    """Every port of a chain kept: one array with a row per port, looked up by the chain's own
    port table (no dict of a name and an array per module)."""
    from fabkit.kinematics.record import PortValues

    net = chain(300)
    traj = fabkit.trace(net, "d1", to=1.2, keep="ports", samples=11)
    values = traj.port_values
    assert isinstance(values, PortValues) and values.values.shape == (301, 11)
    assert values.names is net.ports and "d301" in values and "d302" not in values
    i, j = net.ports["d150"]
    assert np.array_equal(values["d150"], traj.distance("d150"))
    np.testing.assert_allclose(values["d150"][[0, -1]],
                               np.linalg.norm(traj.positions[:, i] - traj.positions[:, j],
                                              axis=-1), rtol=1e-13)
