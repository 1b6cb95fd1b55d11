"""Maps of modules: branches, exact values and slopes, fixed points, cycles, Lyapunov exponents."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fabkit
from fabkit.errors import BoundsError, DesignError, KinematicsError
from fabkit.kinematics import place, plan_construction
from fabkit.maps import Map1D, classify_slope, map_from_trajectory, module_map, slope_at

SQRT3 = math.sqrt(3.0)
PLANAR_MODULES = ["fourbar", "fixed_point", "period_two", "chaotic", "slope_one",
                  "slope_one_and_a_half", "super_stable", "curvature_contract",
                  "curvature_maintain", "curvature_expand", "velocity_design_example",
                  "displacement_design_example"]


# -- closed-form checks --------------------------------------------------------------------------
def test_fourbar_map_is_4_over_d_on_the_whole_branch(fourbar):
    f = module_map(fourbar)
    lo, hi = f.domain
    # the antiparallelogram with sides 2 and 2√2 turns at d1 = 2√2 ∓ 2
    assert lo == pytest.approx(2 * math.sqrt(2) - 2, abs=1e-12)
    assert hi == pytest.approx(2 * math.sqrt(2) + 2, abs=1e-12)
    d = np.linspace(lo, hi, 2001)
    assert np.max(np.abs(f(d) - 4 / d)) < 1e-10
    di = d[1:-1]  # at the two ends the triangles are flat: the slope formula is 0 * inf there
    assert np.max(np.abs(f.derivative(di) + 4 / di ** 2)) < 1e-10


def test_fourbar_fixed_point_and_continuum_of_two_cycles(fourbar):
    f = module_map(fourbar)
    (p,) = f.fixed_points()
    assert p.value == pytest.approx(2.0, abs=1e-13)
    assert p.slope == pytest.approx(-1.0, abs=1e-12)
    assert p.kind == "neutral"
    assert f.is_identity(2) and not f.is_identity(1)  # f(f(d)) = 16/(4d)·... = d
    assert f.cycles(2) == []


def test_constructive_slope_matches_implicit_differentiation(module):
    for name in PLANAR_MODULES:
        net = module(name)
        f = module_map(net)
        lo, hi = f.domain
        d = np.linspace(lo, hi, 41)[1:-1]
        # configurations on the branch, from the kinematics' own placement
        X, margin, _ = place(plan_construction(net, net.ports["d1"]), d)
        assert np.all(margin >= 0)
        implicit = slope_at(net, X)
        scale = max(1.0, np.max(np.abs(implicit)))
        assert np.max(np.abs(f.derivative(d) - implicit)) < 1e-9 * scale, name
        i, j = net.ports["d2"]
        assert np.max(np.abs(f(d) - np.linalg.norm(X[:, i] - X[:, j], axis=1))) < 1e-12, name


def test_slope_at_turning_point_raises(fourbar):
    f = module_map(fourbar)
    X, _, _ = place(plan_construction(fourbar, (0, 1)), [f.domain[1]])
    with pytest.raises(KinematicsError, match="turning point"):
        slope_at(fourbar, X)


# -- the paper's modules -------------------------------------------------------------------------
def test_fixed_point_module_has_its_two_designed_fixed_points(module):
    f = module_map(module("fixed_point"))
    fps = f.fixed_points()
    assert [round(p.value, 9) for p in fps] == [round(SQRT3, 9), round(1.7 * SQRT3, 9)]
    assert abs(fps[0].slope) < 1e-6 and fps[0].kind == "super-stable"
    assert fps[1].kind == "unstable" and fps[1].slope == pytest.approx(40.0376, rel=1e-4)


def test_super_stable_module(module):
    f = module_map(module("super_stable"))
    fps = f.fixed_points()
    kinds = {round(p.value, 6): p.kind for p in fps}
    assert kinds[round(SQRT3, 6)] == "super-stable"
    assert abs(f.derivative(SQRT3)) < 1e-12
    low = [p for p in fps if p.value < 1.5]
    assert len(low) == 1 and low[0].value == pytest.approx(1.00995049, abs=1e-7)
    assert low[0].kind == "unstable"


def test_period_two_module_unstable_fixed_point_and_stable_cycle(module):
    f = module_map(module("period_two"))
    (p,) = f.fixed_points()
    assert p.value == pytest.approx(SQRT3, abs=1e-12) and p.kind == "unstable"
    (c,) = f.cycles(2)
    assert c.kind == "stable" and abs(c.multiplier) < 1
    a, b = c.values
    assert f(a) == pytest.approx(b, abs=1e-12) and f(b) == pytest.approx(a, abs=1e-12)
    assert c.multiplier == pytest.approx(f.derivative(a) * f.derivative(b), rel=1e-12)
    # orbits from near the fixed point settle on the cycle
    orbit = f.orbit(SQRT3 + 1e-3, 200)
    assert orbit.size == 201
    assert min(abs(orbit[-1] - a), abs(orbit[-1] - b)) < 1e-9


def test_chaotic_module_branches_range_and_cycle(module):
    f = module_map(module("chaotic"))
    assert len(f.branches) == 4
    # consecutive branches meet at a turning point: the walk covers one closed motion
    assert all(br.hi > br.lo for br in f.branches)
    (p,) = f.fixed_points()
    assert p.value == pytest.approx(1.5, abs=1e-12) and p.kind == "unstable"
    (c,) = f.cycles(2)
    assert c.kind == "unstable"
    lo, hi = f.invariant_range()
    peak = f.image(*f.domain)[1]
    assert hi == pytest.approx(peak, abs=1e-12)           # range r = [f(f(c)), f(c)]
    assert lo == pytest.approx(f(hi), abs=1e-12)
    assert f.domain[0] < lo < hi < f.domain[1]


def test_chaotic_lyapunov_exponent_short_protocol(module):
    f = module_map(module("chaotic"))
    lam = f.lyapunov(initial=100, discard=500, average=3000)
    assert lam.escaped == 0
    assert 0.29 < lam.mean < 0.33
    assert lam.std < 0.02


def test_chaotic_lyapunov_exponent_full_protocol(module):
    # the supplement's protocol: 1000 orbits, 5000 discarded, 20 000 averaged (~2 s)
    lam = module_map(module("chaotic")).lyapunov()
    assert lam.values.size == 1000 and lam.escaped == 0
    assert lam.mean == pytest.approx(0.3117, abs=0.002)


def test_curvature_modules_keep_d1_equal_d2_between_their_fixed_points(module):
    for name in ("curvature_contract", "curvature_maintain", "curvature_expand"):
        f = module_map(module(name), toward=1.5 * SQRT3)
        d = np.linspace(SQRT3, 1.5 * SQRT3, 201)
        # their variable nodes were found numerically: d1 = d2 to ~1e-7 along the whole motion
        assert np.max(np.abs(f(d) - d)) < 1e-6, name
        assert f.derivative(SQRT3) == pytest.approx(1.0, abs=1e-4)


def test_slope_one_module_is_the_identity(module):
    f = module_map(module("slope_one"))
    assert f.is_identity()
    (p,) = f.fixed_points()
    assert p.kind == "neutral" and p.slope == pytest.approx(1.0, abs=1e-12)


# -- agreement with a map read off a projected trace --------------------------------------------
@pytest.mark.parametrize("name,to", [("fixed_point", 2.9), ("period_two", 2.2),
                                     ("chaotic", 0.8)])
def test_projected_trace_map_agrees_with_constructive(module, name, to):
    net = module(name)
    exact = module_map(net)
    traj = fabkit.trace(net, drive="d1", to=to, method="projected")
    assert str(traj.status) == "finished"
    read = map_from_trajectory(traj)
    lo, hi = read.domain
    d = np.linspace(lo, hi, 9)
    assert np.max(np.abs(read(d) - exact(d))) < 1e-8
    assert np.max(np.abs(read.derivative(d) - exact.derivative(d))) < 1e-8
    fa = exact.fixed_points()
    fb = read.fixed_points(samples=201)
    inside = [p for p in fa if lo <= p.value <= hi]
    assert len(fb) == len(inside)
    for p, q in zip(inside, fb):
        assert abs(p.value - q.value) < 1e-8 and abs(p.slope - q.slope) < 1e-8


# -- closed-form maps ----------------------------------------------------------------------------
def _tent():
    return Map1D.from_function(lambda x: 1 - np.abs(2 * x - 1),
                               lambda x: np.where(x < 0.5, 2.0, -2.0), (0.0, 1.0), name="tent")


def _logistic(r):
    return Map1D.from_function(lambda x: r * x * (1 - x), lambda x: r * (1 - 2 * x), (0.0, 1.0),
                               name=f"logistic {r}")


def test_lyapunov_tent_map_is_ln2():
    lam = _tent().lyapunov(initial=50, discard=100, average=1000)
    assert lam.mean == pytest.approx(math.log(2), abs=1e-12)  # |f'| = 2 everywhere


def test_lyapunov_skew_tent_map_closed_form():
    p = 0.3  # exponent -p ln p - (1-p) ln(1-p) (uniform invariant density)
    f = Map1D.from_function(lambda x: np.where(x < p, x / p, (1 - x) / (1 - p)),
                            lambda x: np.where(x < p, 1 / p, -1 / (1 - p)), (0.0, 1.0))
    lam = f.lyapunov(initial=200, discard=200, average=5000)
    assert lam.mean == pytest.approx(-p * math.log(p) - (1 - p) * math.log(1 - p), abs=5e-3)


def test_lyapunov_logistic_r4_is_ln2():
    lam = _logistic(4.0).lyapunov(initial=200, discard=200, average=5000, lo=0.01, hi=0.99)
    assert lam.mean == pytest.approx(math.log(2), abs=5e-3)


def test_lyapunov_of_stable_two_cycle_is_log_multiplier_over_two():
    f = _logistic(3.2)
    (c,) = f.cycles(2)
    lam = f.lyapunov(initial=20, discard=500, average=2000, lo=0.1, hi=0.9)
    assert lam.mean == pytest.approx(0.5 * math.log(abs(c.multiplier)), abs=1e-3)


def test_logistic_two_cycle_closed_form():
    r = 3.2
    f = _logistic(r)
    (c,) = f.cycles(2)
    s = math.sqrt((r - 3) * (r + 1))
    assert c.values[0] == pytest.approx((r + 1 - s) / (2 * r), abs=1e-13)
    assert c.values[1] == pytest.approx((r + 1 + s) / (2 * r), abs=1e-13)
    assert c.multiplier == pytest.approx(4 + 2 * r - r * r, abs=1e-12)
    assert c.kind == "stable"
    fps = f.fixed_points()
    assert [round(p.value, 12) for p in fps] == [0.0, round(1 - 1 / r, 12)]
    assert [p.kind for p in fps] == ["unstable", "unstable"]


def test_period_three_cycles_of_logistic_r4():
    # r = 4: 2 three-cycles (8 points of f^3 minus the 2 fixed points)
    cycles = _logistic(4.0).cycles(3, samples=20001)
    assert len(cycles) == 2
    for c in cycles:
        assert c.period == 3 and c.residual < 1e-12 and c.kind == "unstable"


def test_classify_slope():
    assert [classify_slope(s) for s in (0.0, 1e-9, 0.5, -1.0, 1.5, 1e9, float("inf"))] == [
        "super-stable", "super-stable", "stable", "neutral", "unstable", "super-unstable",
        "super-unstable"]


# -- errors --------------------------------------------------------------------------------------
def test_outside_domain_is_a_clear_error(fourbar):
    f = module_map(fourbar)
    with pytest.raises(DesignError, match=r"outside the domain \[0.828"):
        f(10.0)
    with pytest.raises(DesignError, match="outside"):
        f.derivative([1.0, 6.0])


def test_unknown_port(fourbar):
    with pytest.raises(KinematicsError, match="unknown port 'd9'"):
        module_map(fourbar, d_out="d9")


def test_orbit_stops_where_it_leaves_the_domain(module):
    f = module_map(module("fixed_point"))
    orbit = f.orbit(2.9446, 30)  # just above the unstable D2*: moves away upwards, then leaves
    assert 2 <= orbit.size < 31
    # every d_k but the last is an input of a module; the last is only an output
    assert np.all((orbit[:-1] >= f.domain[0]) & (orbit[:-1] <= f.domain[1]))
    assert orbit[-1] > f.domain[1]


def test_top_level_lazy_names(fourbar):
    assert fabkit.module_map is module_map and fabkit.Map1D is Map1D


def test_lyapunov_table_matches_the_exact_map(module):
    from fabkit.maps.map1d import _hermite_table

    f = module_map(module("chaotic"))
    lo, hi = f.invariant_range()
    step, err = _hermite_table(f, lo, hi)
    assert step is not None and err["f"] < 1e-11 and err["derivative"] < 1e-8
    x = np.random.default_rng(1).uniform(lo, hi, 5000)
    fx, dfx = step(x, True)
    assert np.max(np.abs(fx - f(x))) < 1e-11
    assert np.max(np.abs(dfx - f.derivative(x))) < 1e-8
    # the ends of the range evaluate too (d = hi is the end of the last interval)
    assert step(np.array([hi]), False)[0][0] == pytest.approx(f(hi), abs=1e-12)
    short = dict(initial=100, discard=500, average=3000)
    assert f.lyapunov(method="table", **short).method == "table"
    assert f.lyapunov(method="exact", **short).method == "exact"
    with pytest.raises(ValueError, match="method must be one of 'auto', 'exact', 'table', got "
                                         "'fast'"):
        f.lyapunov(method="fast")
    with pytest.raises(BoundsError, match=r"Map1D.lyapunov: about .* over the limit"):
        f.lyapunov(initial=100_000, discard=0, average=10**7)
    with pytest.raises(BoundsError, match=r"Map1D.iterate: about .* over the limit"):
        f.iterate(2.0, 10**10)
    with pytest.raises(TypeError, match="steps must be a whole number, got 2.5"):
        f.iterate(2.0, 2.5)


def test_general_evaluator_agrees_with_the_planar_one(module):
    # the any-dimension path (kinematics.place + implicit slopes) on a planar module
    from fabkit.maps.evaluate import Constructive2D, ConstructiveGeneral

    net = module("period_two")
    plan = plan_construction(net, (0, 1))
    d = np.linspace(1.3, 2.2, 31)
    f2, df2, m2, _ = Constructive2D(plan, (1, 2))(d, tuple(plan.signs))
    fg, dfg, mg, _ = ConstructiveGeneral(plan, net, (0, 1), (1, 2))(d, tuple(plan.signs))
    assert np.max(np.abs(f2 - fg)) < 1e-12 and np.max(np.abs(df2 - dfg)) < 1e-9
    assert np.allclose(m2, mg, atol=1e-12)


def test_3d_module_map_follows_the_traced_motion():
    nodes = [[0, 0, 0], [1.6, 0, 0], [0.7, 1.0, 0.1], [0.9, 0.4, 1.1], [1.5, 1.2, 0.9]]
    edges = [[0, 2], [1, 2], [0, 3], [1, 3], [2, 3], [1, 4], [2, 4], [3, 4]]
    net = fabkit.Network(nodes, edges, ports={"d1": (0, 1), "d2": (0, 4)})
    assert fabkit.count_modes(net).conformational == 1
    f = module_map(net)
    lo, hi = f.domain
    assert lo < 1.6 < hi
    traj = fabkit.trace(net, drive="d1", to=0.5 * (1.6 + hi), method="projected")
    read = map_from_trajectory(traj)
    d = np.linspace(*read.domain, 7)
    assert np.max(np.abs(f(d) - read(d))) < 1e-9
    assert np.max(np.abs(f.derivative(d) - read.derivative(d))) < 1e-8


def test_flat_start_physical_fourbar_is_super_unstable(module):
    net = module("physical_fourbar")
    f = module_map(net)
    assert f.domain[0] == pytest.approx(1.0, abs=1e-12)  # starts collapsed: a turning point
    (p,) = f.fixed_points()
    assert p.value == pytest.approx(1.0, abs=1e-12) and p.kind == "super-unstable"
    # the mirror branch leaving the same flat state holds the stable D2* of the paper's Fig S4a
    other = [module_map(net, branch=b.index) for b in f.branches]
    d2 = [q for g in other for q in g.fixed_points() if q.value > 1.5]
    assert d2 and d2[0].value == pytest.approx(1.907212261, abs=1e-9) and d2[0].kind == "stable"
    # the branch chosen at a flat start does not depend on where the module is drawn
    c, s = math.cos(2.0), math.sin(2.0)
    moved = net.with_nodes(net.nodes @ np.array([[c, -s], [s, c]]).T * np.array([-1.0, 1.0]))
    g = module_map(moved)
    assert g.domain == pytest.approx(f.domain, abs=1e-12)
    assert g(1.7) == pytest.approx(f(1.7), abs=1e-12)
    with pytest.raises(DesignError, match="branch must be in 0..3"):
        module_map(net, branch=7)


def test_slope_is_nan_for_configurations_beyond_the_motion(fourbar):
    # an orbit that left the map's domain carries NaN positions: no slope, and no LinAlgError
    x = np.stack([fourbar.nodes, np.full_like(fourbar.nodes, np.nan)])
    s = slope_at(fourbar, x)
    assert s[0] == pytest.approx(-1.0, abs=1e-12) and np.isnan(s[1])


# -- configurations and the walk between branches ----------------------------------------------
def test_configuration_on_each_branch_has_the_maps_values(fourbar):
    f = module_map(fourbar)
    for br in f.branches:
        g = f.on_branch(br.index)
        d = np.linspace(br.lo, br.hi, 9)[1:-1]
        x = g.configuration(d)
        assert x.shape == (7, 4, 2)
        assert np.allclose(fourbar.port_distance("d1", x), d, atol=1e-12)
        assert np.allclose(fourbar.port_distance("d2", x), g(d), atol=1e-12)
        assert np.abs(fourbar.lengths_at(x) / fourbar.edge_lengths - 1).max() < 1e-12
    assert f.configuration(2.5).shape == (4, 2)
    with pytest.raises(DesignError, match="outside the domain"):
        f.configuration(f.domain[1] + 1.0)
    closed = Map1D.from_function(lambda x: 4 / x, lambda x: -4 / x ** 2, (1, 3))
    with pytest.raises(DesignError, match="has no configurations"):
        closed.configuration(2.0)


def test_branches_record_where_the_walk_entered_them():
    net = fabkit.load_template("templates/printed_planar.toml").network
    f = module_map(net)
    first = f.branches[0]
    assert first.previous is None and first.entered_at is None
    assert len(f.branches) >= 3
    for br in f.branches[1:]:
        came = f.branches[br.previous]
        # entered at a turning point: an end of both the branch and the one walked from
        assert br.entered_at in (came.lo, came.hi)
        assert min(abs(br.lo - br.entered_at), abs(br.hi - br.entered_at)) < 1e-9
        # and both say so as a flag, not only in words
        assert came.turning[(came.lo, came.hi).index(br.entered_at)] is True
        side = 0 if abs(br.lo - br.entered_at) < abs(br.hi - br.entered_at) else 1
        assert br.turning[side] is True and br.ends[side].startswith("turning point")
        # at that turning point the two branches meet in one configuration
        a = f.on_branch(came.index).configuration(br.entered_at)
        b = f.on_branch(br.index).configuration(min(max(br.entered_at, br.lo), br.hi))
        assert np.abs(a - b).max() < 1e-6
