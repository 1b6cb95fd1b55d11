"""The paper's large designs as chain templates: mode counts, the iterated map along simulated
chains, fixed points and cycles, the soliton, the AND gate, curvature and the physical 4-bar."""

from __future__ import annotations

import gc
import time

import numpy as np
import pytest

import fabkit
from fabkit.design.assemble import chain
from fabkit.errors import ConstructionError
from fabkit.kinematics import place, plan_construction
from fabkit.model.rigidity import count_modes, self_stresses
from fabkit.templates import load_template

from conftest import TEMPLATES

SQRT3 = np.sqrt(3.0)
D2_PHYSICAL = 1.9072122610809965  # computed fixed point of the physical 4-bar (slope -0.537)
D2_SUPER_STABLE = 1.0099504938362078  # computed fixed point of the super-stable module (slope 4)

CHAIN_TEMPLATES = [
    "fourbar_chain", "fixed_point_chain8", "period_two_chain16", "chaotic_chain",
    "slope_one_chain", "slope_one_and_a_half_chain", "super_stable_chain", "curvature_chain",
    "physical_fourbar_chain",
]


def load(name):
    return load_template(TEMPLATES / f"{name}.toml")


def module_map(module, d_in="d1", d_out="d2"):
    """f(d) of a single module by constructive placement on the module alone."""
    plan = plan_construction(module, module.port(d_in))
    o0, o1 = module.port(d_out)

    def f(d):
        x, margin, _ = place(plan, np.atleast_1d(d))
        assert (margin >= 0).all(), "value outside the module's range"
        return np.linalg.norm(x[:, o0] - x[:, o1], axis=1)

    return f


def chain_distances(traj, k):
    return np.array([traj.distance(f"d{i}") for i in range(1, k + 2)])  # (k+1, S)


def module_sequence(design):
    """The module networks of a [chain] template, in chain order."""
    sec = design.raw["chain"]
    names = sec["modules"] if "modules" in sec else [sec["module"]] * sec["copies"]
    cache = {n: load_template(TEMPLATES / n).network for n in set(names)}
    return [cache[n] for n in names]


@pytest.mark.parametrize("name", CHAIN_TEMPLATES + ["physical_fourbar", "physical_fourbar_open"])
def test_one_conformational_motion(name):
    m = count_modes(load(name).network)
    assert (m.rigid, m.conformational, m.self_stress) == (3, 1, 0)
    assert m.gap > 1e3


@pytest.mark.parametrize("name", CHAIN_TEMPLATES)
def test_template_motion_finishes_with_exact_edges(name):
    traj = load(name).trace()
    assert str(traj.status) == "finished", traj.message
    assert traj.max_edge_error < 1e-12


@pytest.mark.parametrize("name", CHAIN_TEMPLATES)
def test_iterated_map_along_constructive_trace(name):
    """d_{k+1} = f_k(d_k) at every step, f_k from the k-th module alone, to 1e-8."""
    design = load(name)
    mods = module_sequence(design)
    traj = design.trace(method="constructive", samples=41)
    d = chain_distances(traj, len(mods))
    maps = {id(m): module_map(m) for m in mods}
    worst = max(float(np.abs(maps[id(m)](d[k]) - d[k + 1]).max()) for k, m in enumerate(mods))
    assert worst < 1e-8


@pytest.mark.parametrize("name", ["fixed_point_chain8", "super_stable_chain", "curvature_chain"])
def test_iterated_map_along_projected_trace(name):
    design = load(name)
    mods = module_sequence(design)
    to = {"super_stable_chain": 1.05, "fixed_point_chain8": 2.9}.get(name, design.motion.to)
    traj = design.trace(method="projected", to=to)
    assert str(traj.status) == "finished", traj.message
    d = chain_distances(traj, len(mods))
    maps = {id(m): module_map(m) for m in mods}
    worst = max(float(np.abs(maps[id(m)](d[k]) - d[k + 1]).max()) for k, m in enumerate(mods))
    assert worst < 1e-8


def test_fourbar_chain_alternates():
    traj = load("fourbar_chain").trace(method="constructive", samples=11)
    d = chain_distances(traj, 4)
    np.testing.assert_allclose(d[1] * d[0], 4.0, atol=1e-12)
    np.testing.assert_allclose(d[2], d[0], atol=1e-12)
    np.testing.assert_allclose(d[4], d[0], atol=1e-12)


def test_fixed_point_chain_between_crystals():
    traj = load("fixed_point_chain8").trace(method="constructive", samples=51)
    d = chain_distances(traj, 8)
    np.testing.assert_allclose(d[:, 0], SQRT3, atol=1e-12)          # D1* crystal
    final = d[:, -1] - 2.944486372867092  # D2* crystal, but D2* is unstable (slope 40.3):
    assert float(np.abs(final[:5]).max()) < 1e-7  # the round-off of d1 grows 40x per module
    ratio = final[6] / final[5]
    assert 30 < ratio < 50
    mid = d[:, 25]
    # in between: every module moves towards the stable D1* (slope 0 there)
    assert np.all(np.diff(mid[:6]) < 0) and abs(mid[-1] - SQRT3) < 1e-12
    # super-stable D1*: the distance to D1* squares (roughly) from one module to the next
    gap = mid[:5] - SQRT3
    assert np.all(gap[1:] < 2 * gap[:-1] ** 2)


def test_period_two_chain_reaches_two_cycle():
    traj = load("period_two_chain16").trace(method="constructive", samples=41)
    d = chain_distances(traj, 16)
    np.testing.assert_allclose(d[:, 0], SQRT3, atol=1e-12)
    final = d[:, -1]
    np.testing.assert_allclose(final[0::2], 1.2624993415744663, atol=1e-7)
    np.testing.assert_allclose(final[1::2], 2.054946121859751, atol=1e-7)
    # the transition: the far end approaches the stable 2-cycle, away from the unstable D*
    mid = d[:, 20]
    assert abs(mid[-1] - mid[-2]) > abs(mid[0] - mid[1])


def test_chaotic_chain_is_sensitive():
    design = load("chaotic_chain")
    net = design.network
    plan = plan_construction(net, net.port("d1"))
    base = 1.2
    x, margin, _ = place(plan, [base, base + 1e-9])
    assert (margin >= 0).all()
    d = np.array([np.linalg.norm(x[:, i] - x[:, j], axis=1) for i, j in
                  (net.port(f"d{k}") for k in range(1, 14))])
    sep = np.abs(d[:, 1] - d[:, 0])
    # the separation grows as the product of the module slopes along the way (chain rule),
    # by more than an order of magnitude over 12 modules (Lyapunov exponent about 0.31)
    f = module_map(load("chaotic").network)
    h = 1e-7
    slopes = np.abs((f(d[:-1, 0] + h) - f(d[:-1, 0] - h)) / (2 * h))
    np.testing.assert_allclose(sep[1:] / sep[0], np.cumprod(slopes), rtol=1e-3)
    assert sep[-1] > 10 * sep[0]


def test_slope_one_motion_uniform():
    traj = load("slope_one_chain").trace(method="constructive", samples=21)
    d = chain_distances(traj, 8)
    assert float(np.abs(d - d[0]).max()) < 1e-9


def test_slope_one_and_a_half_localises_at_far_end():
    design = load("slope_one_and_a_half_chain")
    traj = design.trace(method="constructive", samples=201)
    d = chain_distances(traj, 8)
    change = np.abs(d[:, 5] - SQRT3)  # early in the motion
    assert np.all(np.diff(change) > 0) and change[-1] > 20 * change[0]
    np.testing.assert_allclose(d[:, -1], 2.039225723083626, atol=1e-9)


def soliton_distances(k, n_values=600, closest=1e-12):
    net = chain(load("super_stable").network, k, mirror="alternate")
    plan = plan_construction(net, net.port("d1"))
    values = D2_SUPER_STABLE + np.geomspace(SQRT3 - D2_SUPER_STABLE, closest, n_values)
    x, margin, _ = place(plan, values)
    assert (margin >= 0).all()
    d = np.array([np.linalg.norm(x[:, i] - x[:, j], axis=1) for i, j in
                  (net.port(f"d{m}") for m in range(1, k + 2))])
    return values, d


def test_soliton_collapse_order():
    values, d = soliton_distances(24)
    collapsed = (SQRT3 - d) / (SQRT3 - D2_SUPER_STABLE) > 0.5  # (k+1, S)
    when = np.where(collapsed.any(axis=1), collapsed.argmax(axis=1), -1)
    done = when[when >= 0]
    assert done.size >= 18                      # about 20 of 24 collapse by D2* + 1e-12
    assert np.all(np.diff(done) > 0)            # module k collapses before module k + 1
    assert np.all(when[done.size:] == -1)       # and no later module has started
    # a module that collapsed stays collapsed; modules ahead of the front stay at D1*
    assert np.all(np.diff(collapsed.astype(int), axis=1) >= 0)
    front = collapsed.sum(axis=0)          # number of collapsed modules at each step
    ahead = np.arange(d.shape[0])[:, None] >= front[None, :] + 6
    assert float(np.abs(d - SQRT3)[ahead].max()) < 1e-12
    # each further module needs d1 - D2* about 4 times smaller (slope 4.0 at D2*)
    gaps = values[done] - D2_SUPER_STABLE
    ratio = np.exp(np.mean(np.log(gaps[3:-1] / gaps[4:])))
    assert 3.5 < ratio < 4.5


def test_super_stable_fixed_point_values():
    f = module_map(load("super_stable").network)
    assert abs(f(D2_SUPER_STABLE)[0] - D2_SUPER_STABLE) < 1e-13
    h = 1e-6
    slope_d2 = (f(D2_SUPER_STABLE + h)[0] - f(D2_SUPER_STABLE - h)[0]) / (2 * h)
    slope_d1 = (f(SQRT3 - h)[0] - f(SQRT3 - 2 * h)[0]) / h
    assert abs(slope_d2 - 4.003) < 0.01
    assert abs(slope_d1) < 1e-5


# -- AND gate --------------------------------------------------------------------------------

def test_and_gate_mode_count_and_self_stress():
    net = load("and_gate").network
    m = count_modes(net)
    assert (m.rigid, m.conformational, m.self_stress) == (3, 2, 1)
    assert m.total == 2 * net.n_nodes - net.n_edges + 1
    s = self_stresses(net)[:, 0]
    # the self-stress: the 4 bars from the two junction nodes to one node of each chain
    stressed = np.flatnonzero(np.abs(s) > 1e-6 * np.abs(s).max())
    assert stressed.size == 4
    junction = set(net.port("d9"))
    assert all(len(junction & set(e)) == 1 for e in net.edges[stressed].tolist())
    np.testing.assert_allclose(
        fabkit.rigidity_matrix(net, normalized=True).T @ s, 0.0, atol=1e-12)
    # holding the trunk's free end leaves one motion (infinitesimally)
    held = fabkit.Network(net.nodes, np.vstack([net.edges, [net.port("d1")]]), net.ports)
    assert count_modes(held).conformational == 1


def branch_collapse(values, trunk_junction="d9", k=16):
    """Distances of the branch chain (k modules) placed constructively at drive values."""
    net = chain(load("super_stable").network, k, mirror="alternate")
    plan = plan_construction(net, net.port("d1"))
    x, margin, _ = place(plan, values)
    assert (margin >= 0).all()
    return np.array([np.linalg.norm(x[:, i] - x[:, j], axis=1) for i, j in
                     (net.port(f"d{m}") for m in range(1, k + 2))])


def test_and_gate_junction_still_while_branch_collapses():
    """Collapse the branch with the trunk's free end held: the junction stays still below 1e-12
    until 3/4 of the branch has collapsed (the traced numbers of the paper's Fig 3h)."""
    design = load("and_gate")
    traj = design.trace()
    assert str(traj.status) == "finished", traj.message
    assert traj.max_edge_error < 1e-12
    junction = np.abs(traj.distance("d9") - SQRT3)
    assert float(junction.max()) < 1e-12
    branch = np.array([traj.distance(f"d{m}_b") for m in range(1, 17)])
    fraction = ((SQRT3 - branch) / (SQRT3 - D2_SUPER_STABLE) > 0.5).mean(axis=0)
    assert fraction[-1] >= 0.75
    # the other branch and the trunk's far half did not move
    for port in ("d1", "d5", "d13", "d17"):
        assert float(np.abs(traj.distance(port) - SQRT3).max()) < 1e-12


def test_and_gate_junction_moves_only_when_branch_almost_collapsed():
    values = D2_SUPER_STABLE + np.geomspace(SQRT3 - D2_SUPER_STABLE, 1e-13, 500)
    d = branch_collapse(values)
    end = np.abs(d[-1] - SQRT3)
    fraction = ((SQRT3 - d[:-1]) / (SQRT3 - D2_SUPER_STABLE) > 0.5).mean(axis=0)
    first = int(np.argmax(end > 1e-12))
    assert end[first] > 1e-12 and fraction[first] >= 0.74
    assert float(end[fraction <= 0.7].max()) < 1e-12
    # and then it must move: near full collapse the junction is pulled by more than 1e-3
    assert float(end[fraction >= 0.95].min()) > 1e-3


# -- curvature --------------------------------------------------------------------------------

def strip_bottom_points(net, x, k):
    """Designed nodes along the strip: the endpoints of every d_k pair."""
    return np.array([x[list(net.port(f"d{m}"))].mean(axis=0) for m in range(1, k + 2)])


def turning_angles(p):
    v = np.diff(p, axis=0)
    ang = np.arctan2(v[:, 1], v[:, 0])
    return np.angle(np.exp(1j * np.diff(ang)))


def test_curvature_chain_straight_then_curved():
    design = load("curvature_chain")
    traj = design.trace(method="constructive", samples=11)
    net = design.network
    d = chain_distances(traj, 16)
    np.testing.assert_allclose(d[:, -1], 2.598076211353316, atol=1e-8)
    start = strip_bottom_points(net, traj.positions[0], 16)
    end = strip_bottom_points(net, traj.positions[-1], 16)
    # start: the pair midpoints lie on one straight line
    assert float(np.abs(turning_angles(start[1:])).max()) < 1e-9
    turn = turning_angles(end[1:])
    assert float(np.abs(turn[:4]).max()) < 0.02            # maintain modules: still straight
    # contract / expand alternation: the final apex angles 19.4 and 60 degrees turn the strip by
    # (60 - 19.4) / 2 = 20.3 degrees per module, all one way (downwards)
    np.testing.assert_allclose(np.degrees(turn[6:]), -20.3, atol=1e-6)
    assert np.degrees(turn[4:].sum()) == pytest.approx(-192.0, abs=1e-6)


# -- physical 4-bar ---------------------------------------------------------------------------

def test_physical_fourbar_flat_start_refused_then_started_off_flat():
    design = load("physical_fourbar")
    net = design.network
    with pytest.raises(ConstructionError, match="node 2 is collinear with nodes 0 and 1"):
        fabkit.trace(net, "d1", to=1.5, method="constructive")
    # the template's regular drive d2 starts at the flat state itself
    traj = design.trace()
    assert str(traj.status) == "finished" and traj.max_edge_error < 1e-12
    # off the flat state on the branch with node 2 opposite node 3, d1 drives to D2*
    start = load("physical_fourbar_open").network.nodes
    np.testing.assert_allclose(net.lengths_at(start), net.edge_lengths, rtol=1e-15)
    traj = fabkit.trace(net, "d1", to=D2_PHYSICAL, method="constructive", start=start)
    assert str(traj.status) == "finished"
    d1, d2 = traj.distance("d1"), traj.distance("d2")
    assert abs(d2[-1] - d1[-1]) < 1e-8                      # D2* is a fixed point
    # slope infinity at D1*: d2 - 1 grows like sqrt(d1 - 1) just off the flat state
    assert (d2[0] - 1.0) / (d1[0] - 1.0) > 1e2


def test_physical_fourbar_chain_collapses_to_crystal():
    traj = load("physical_fourbar_chain").trace(method="constructive", samples=101)
    d = chain_distances(traj, 12)
    assert abs(d[0, 0] - 1.0) < 2e-6 and abs(d[1, 0] - 1.0) < 1e-2   # near the flat D1*
    np.testing.assert_allclose(d[:, -1], D2_PHYSICAL, atol=1e-7)     # all at D2*


# -- long chains --------------------------------------------------------------------------------

@pytest.mark.parametrize("method", ["constructive"])
def test_ten_thousand_modules_build_and_trace(method):
    module = load("super_stable").network

    def cpu_seconds(copies):
        # the collector off while timing: a full collection walks every object the suite's
        # earlier tests left alive, work that is not the build's
        gc.collect()
        gc.disable()
        try:
            t0 = time.thread_time()
            built = chain(module, copies, mirror="alternate")
            return time.thread_time() - t0, built
        finally:
            gc.enable()

    small = min(cpu_seconds(1000)[0] for _ in range(3))
    build, net = min((cpu_seconds(10_000) for _ in range(2)), key=lambda r: r[0])
    assert net.n_nodes == 30_002 and net.n_edges == 60_000 and "d10001" in net.ports
    opts = {"samples": 5} if method == "constructive" else {}
    traj = fabkit.trace(net, "d1", to=1.3, method=method, **opts)
    assert str(traj.status) == "finished", traj.message
    assert traj.max_edge_error < 1e-9
    f = module_map(module)
    d1, d2, d3 = (traj.distance(p)[-1] for p in ("d1", "d2", "d3"))
    assert abs(f(d1)[0] - d2) < 1e-8 and abs(f(d2)[0] - d3) < 1e-8
    assert abs(traj.distance("d10001")[-1] - SQRT3) < 1e-12
    # the build is O(k) (docs/assembly.md): ten times the modules, about ten times the work
    # (measured 10-12 on a quiet machine and beside four busy processes; O(k²) would give 100).
    # Processor time of this thread, which neither the other processes on the machine nor this
    # process's BLAS threads (still spinning after an earlier test's work) inflate.
    assert build < 30 * small, (build, small)


# -- pictures ---------------------------------------------------------------------------------

def test_motion_gif_frames_read_back():
    from PIL import Image
    import io

    from fabkit.plots.animate import motion_gif

    traj = load("fourbar_chain").trace(method="constructive", samples=30)
    data = motion_gif(traj, frames=12, fps=10)
    img = Image.open(io.BytesIO(data))
    assert img.format == "GIF" and img.n_frames == 12
    assert img.info["duration"] == 100 and img.info.get("loop") == 0
    with pytest.raises(fabkit.FabkitError, match="`frames` must be at least 2"):
        motion_gif(traj, frames=1)


def test_sequence_and_junction_figures():
    from fabkit.plots.animate import (collapse_order, collapse_profile, junction_figure,
                                       sequence_figure)
    from fabkit.plots.viz import figure_png

    values, d = soliton_distances(12, n_values=200, closest=1e-8)
    profile = collapse_profile(d, SQRT3, D2_SUPER_STABLE)
    when = collapse_order(profile)
    done = when[when >= 0]
    assert done.size >= 11 and np.all(np.diff(done) > 0)
    fig = sequence_figure(profile, -np.log10(values - D2_SUPER_STABLE), xlabel="-log10(d1 - D2*)")
    assert len(fig.axes) == 3  # heat map, its colour bar, order of collapse
    order_line = fig.axes[1].lines[0]
    np.testing.assert_array_equal(order_line.get_xdata(), np.flatnonzero(when >= 0))
    assert figure_png(fig)[:4] == b"\x89PNG"
    frac = profile[:-1].mean(axis=0)
    fig = junction_figure(frac, d[-1] - SQRT3)
    y = fig.axes[0].lines[0].get_ydata()
    assert y.min() >= 1e-17 and y.max() < 1.0
    assert figure_png(fig)[:4] == b"\x89PNG"
    with pytest.raises(fabkit.FabkitError, match="`start` and `end` must differ"):
        collapse_profile(d, 1.0, 1.0)


def test_and_gate_junction_moves_only_when_both_inputs_collapse():
    """Fig 3i-j: moving the junction (and so the trunk beyond it) needs both the branch (16
    modules) and the trunk's free arm (8 modules) almost fully collapsed."""
    from scipy.optimize import brentq

    def arm_drive_for(junction, k):
        net = chain(load("super_stable").network, k, mirror="alternate")
        plan = plan_construction(net, net.port("d1"))
        i, j = net.port(f"d{k + 1}")

        def end(d1):
            x, _, _ = place(plan, [d1])
            return float(np.linalg.norm(x[0, i] - x[0, j]))

        d1 = brentq(lambda v: end(v) - junction, D2_SUPER_STABLE + 1e-15, SQRT3, xtol=1e-16)
        ds = np.array([np.linalg.norm(a - b) for a, b in
                       (place(plan, [d1])[0][0][list(net.port(f"d{m}"))] for m in range(1, k + 1))])
        return ((SQRT3 - ds) / (SQRT3 - D2_SUPER_STABLE) > 0.5).mean()

    for shift, arm8, arm16 in ((1e-12, 0.5, 0.75), (1e-6, 0.625, 0.8125), (1e-2, 0.875, 0.9375)):
        junction = SQRT3 - shift
        assert arm_drive_for(junction, 8) >= arm8
        assert arm_drive_for(junction, 16) >= arm16


def test_chain_records_its_assembly_and_the_plan_is_tiled_from_it(module):
    from fabkit.model.construction import _tiled_chain_plan

    m = module("super_stable")
    net = chain(m, copies=50)
    assert net.assembly is not None and len(net.assembly.copies) == 50
    assert net.assembly.d_in == "d1"
    for mod, index, _mirrored in net.assembly.copies:
        # every module's nodes went to nodes of the chain with the module's edge lengths
        x = net.nodes[index]
        lengths = np.linalg.norm(x[mod.edges[:, 0]] - x[mod.edges[:, 1]], axis=1)
        np.testing.assert_allclose(lengths, mod.edge_lengths, rtol=1e-12)
    tiled = _tiled_chain_plan(net, net.port("d1"))
    searched = plan_construction(net, net.port("d1"))
    assert tiled is not None and tiled.order.size == net.n_nodes - 2
    values = np.linspace(float(net.port_distance("d1")), 1.2, 7)
    xt, mt, _ = place(tiled, values)
    xs, ms, _ = place(searched, values)
    np.testing.assert_allclose(xt, xs, atol=1e-12)
    # a network without the record (other geometry, same topology) is planned by the search
    plain = net.with_nodes(net.nodes)
    assert plain.assembly is None and _tiled_chain_plan(plain, plain.port("d1")) is None
    assert net.with_ports(dict(net.ports)).assembly is net.assembly
    # its radii and sides are the chain's own, bit for bit those of the pairwise formulas
    x, order, par = net.nodes, tiled.order, tiled.parents
    for k in (0, 1):
        assert np.array_equal(tiled.radii[:, k], np.linalg.norm(x[order] - x[par[:, k]], axis=1))
    dpv, dpq = x[order] - x[par[:, 0]], x[par[:, 1]] - x[par[:, 0]]
    cross = dpq[:, 0] * dpv[:, 1] - dpq[:, 1] * dpv[:, 0]
    assert np.array_equal(tiled.signs, np.where(cross > 0, 1.0, -1.0))
    # the record with geometry that does not fit it: one node moved by 1e-6 of a bar is
    # refused (the node-by-node search takes over), one moved by round-off is not
    for shift, planned in ((1e-6, False), (1e-13, True)):
        moved = net.nodes.copy()
        moved[order[len(order) // 2]] += shift * float(np.mean(net.edge_lengths))
        other = fabkit.Network(moved, net.edges, net.ports, net.labels, net.assembly)
        assert (_tiled_chain_plan(other, other.port("d1")) is not None) == planned
    with pytest.raises(fabkit.NetworkError, match="assembly"):
        fabkit.Network(m.nodes, m.edges, assembly={"copies": []})
