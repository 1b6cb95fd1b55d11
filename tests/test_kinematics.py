"""trace(): the method registry, accuracy, events at turning and branch points, errors."""

import numpy as np
import pytest

import fabkit
from fabkit import KinematicsError, Network, trace
from fabkit.kinematics import METHODS, Status, plan_construction, place
from fabkit.errors import ConstructionError

ALL = sorted(METHODS)


@pytest.mark.parametrize("method", ALL)
def test_contract_fourbar_to_target(fourbar, method):
    traj = trace(fourbar, drive="d1", to=2.6, method=method)
    assert traj.method == method or traj.method.startswith(method + "/")
    assert traj.status is Status.FINISHED and traj.success
    assert traj.positions.shape[1:] == (4, 2) and traj.n_steps >= 2
    assert traj.drive[0] == pytest.approx(2.0, abs=1e-15)
    assert traj.drive[-1] == pytest.approx(2.6, abs=1e-12)  # lands on the target
    np.testing.assert_allclose(traj.drive, traj.distance("d1"))
    assert np.all(np.diff(traj.arclength) > 0)
    assert traj.edge_error.shape == (traj.n_steps,)
    bound = 1e-8 if method == "rk4-nullspace" else 1e-12
    assert traj.max_edge_error <= bound
    d1, d2 = traj.distance("d1"), traj.distance("d2")
    assert np.abs(d1 * d2 - 4.0).max() <= (1e-7 if method == "rk4-nullspace" else 1e-10)


@pytest.mark.parametrize("method", ["constructive", "projected"])
@pytest.mark.parametrize("to", [0.9, 4.7])
def test_fourbar_d1_d2_equals_4_over_whole_motion(fourbar, method, to):
    traj = trace(fourbar, drive="d1", to=to, method=method, **({"max_step": 0.05} if method == "projected" else {}))
    assert traj.success
    d1, d2 = traj.distance("d1"), traj.distance("d2")
    assert np.abs(d1 * d2 - 4.0).max() <= 1e-10
    assert traj.max_edge_error <= 1e-12
    assert traj.n_steps > 10


@pytest.mark.parametrize("method", ALL)
def test_fourbar_driven_into_flat_state_stops_and_names_the_value(fourbar, method):
    flat = 2 * np.sqrt(2) - 2  # the antiparallelogram's smallest d1: all four nodes collinear
    traj = trace(fourbar, drive="d1", to=0.5, method=method)
    assert traj.status in (Status.TURNING_POINT, Status.BRANCH_POINT)
    assert not traj.success
    # no wrong branch: every configuration still satisfies d1 * d2 = 4
    d1, d2 = traj.distance("d1"), traj.distance("d2")
    tol = 1e-7 if method == "rk4-nullspace" else 1e-9
    assert np.abs(d1 * d2 - 4).max() < tol
    assert traj.drive.min() >= flat - 1e-9
    reached = traj.drive[-1]
    assert reached == pytest.approx(flat, abs=5e-5 if method == "rk4-nullspace" else 1e-7)
    assert f"{reached:.6f}"[:7] in traj.message  # the message names the drive value
    assert traj.events and traj.events[-1].kind in ("turning_point", "branch_point")


def test_projected_reports_branch_point_at_flat_fourbar(fourbar):
    traj = trace(fourbar, drive="d1", to=0.5, method="projected")
    assert traj.status is Status.BRANCH_POINT
    assert "self-stress" in traj.message
    # at the located point the rigidity matrix is nearly singular (a state of self-stress there):
    # its smallest singular value has dropped by more than three orders from the start's 0.77
    from fabkit.model.rigidity import rigidity_matrix

    sv = np.linalg.svd(rigidity_matrix(fourbar, traj.final, normalized=True).toarray(), compute_uv=False)
    assert sv[-1] < 1e-3 and sv[-2] > 1.0


def test_constructive_turning_point_names_collinear_node(fourbar):
    traj = trace(fourbar, drive="d1", to=0.5, method="constructive")
    assert traj.status is Status.TURNING_POINT
    assert "collinear" in traj.message and "0.8284271247" in traj.message


def test_projected_turning_point_without_branching(module):
    # the curvature_contract module starts 1.5e-5 above its smallest d1 (NUMERICS.md): driving
    # d1 down meets a plain turning point almost at once, driving it up is regular
    net = module("curvature_contract")
    down = trace(net, drive="d1", to=1.0, method="projected")
    assert down.status is Status.TURNING_POINT
    assert down.drive[-1] < down.drive[0]
    assert down.drive[0] - down.drive[-1] < 1e-4
    up = trace(net, drive="d1", to=2.5, method="projected")
    assert up.success and up.max_edge_error < 1e-12
    ref = trace(net, drive="d1", to=2.5, method="constructive")
    assert up.distance("d2")[-1] == pytest.approx(ref.distance("d2")[-1], abs=1e-10)


def test_projected_matches_constructive_on_paper_modules(module):
    for name in ["fixed_point", "super_stable", "chaotic", "period_two"]:
        net = module(name)
        d0 = float(net.port_distance("d1"))
        to = d0 * 1.05
        a = trace(net, drive="d1", to=to, method="constructive")
        b = trace(net, drive="d1", to=to, method="projected")
        assert a.success and b.success, (name, a.message, b.message)
        assert b.distance("d2")[-1] == pytest.approx(a.distance("d2")[-1], abs=1e-10), name


def test_chain_of_1000_fourbars_projected(fourbar):
    net = fabkit.chain(fourbar, copies=1000)
    traj = trace(net, drive="d1", to=2.7, method="projected")
    assert traj.success, traj.message
    assert traj.max_edge_error <= 1e-10
    d = np.array([traj.distance(f"d{k}")[-1] for k in range(1, 1002)])
    np.testing.assert_allclose(d[1:], 4.0 / d[:-1], atol=1e-9)
    # along the whole path, not only at the end
    mid = traj.n_steps // 2
    dm = np.array([traj.distance(f"d{k}")[mid] for k in range(1, 1002)])
    np.testing.assert_allclose(dm[1:] * dm[:-1], 4.0, atol=1e-9)


def test_3d_tetrahedron_minus_one_edge():
    x = [[0, 0, 0], [1, 0, 0], [0.1, 0.9, 0], [0.2, 0.3, 0.9]]
    net = Network(x, [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3]], ports={"d": (2, 3)})
    d0 = float(net.port_distance("d"))
    results = {}
    for method in ALL:
        traj = trace(net, drive="d", to=d0 * 1.2, method=method)
        assert traj.success, (method, traj.message)
        assert traj.positions.shape[-1] == 3
        results[method] = traj.final
        bound = 1e-8 if method == "rk4-nullspace" else 1e-12
        assert traj.max_edge_error <= bound
    # gauge-independent comparison: all pairwise distances agree
    def dists(y):
        return np.linalg.norm(y[:, None] - y[None], axis=-1)
    np.testing.assert_allclose(dists(results["projected"]), dists(results["constructive"]), atol=1e-10)


def test_hold_fixes_a_port(module):
    # a two-copy chain of the super-stable module driven at d1 while d3 is held: d3 stays put
    net = fabkit.chain(module("fixed_point"), copies=3)
    m = fabkit.count_modes(net)
    assert m.conformational == 1
    with pytest.raises(KinematicsError, match="cannot both drive and hold"):
        trace(net, drive="d1", to=1.8, hold=["d1"])


def test_auto_picks_constructive_where_possible(fourbar, module):
    assert fabkit.kinematics.select_method(fourbar, "d1") == "constructive"
    traj = trace(fourbar, to=2.2)
    assert traj.method == "constructive"
    # the flat origami sheet has no construction (a flat state): auto falls back to projected
    sheet = module("origami_sheet")
    assert fabkit.kinematics.select_method(sheet, "d1") == "projected"


def test_projected_refuses_singular_start(module):
    sheet = module("origami_sheet")
    traj = trace(sheet, drive="d1", to=1.3, method="projected")
    assert traj.status is Status.FAILED and "singular" in traj.message
    assert traj.n_steps == 1  # returns what it has, never NaN


def test_constructive_refuses_flat_start_and_missing_order(module):
    net = module("physical_fourbar")
    with pytest.raises(ConstructionError, match="collinear"):
        trace(net, drive="d1", to=1.5, method="constructive")
    # a triangular prism missing one rung has one motion, but from the pair (2, 5) no node has
    # two placed neighbours: no construction order; auto falls back to projected
    prism = Network([[0, 0], [2, 0], [1, 1.5], [0.3, 3], [1.7, 3.1], [1.0, 4.4]],
                    [[0, 1], [1, 2], [2, 0], [3, 4], [4, 5], [5, 3], [0, 3], [1, 4]],
                    ports={"a": (2, 5)})
    assert fabkit.count_modes(prism).conformational == 1
    with pytest.raises(ConstructionError, match="no construction order"):
        plan_construction(prism, (2, 5))
    with pytest.raises(ConstructionError, match="no construction order"):
        trace(prism, drive="a", to=3.0, method="constructive")
    traj = trace(prism, drive="a", to=2.7)
    assert traj.method == "projected" and traj.success and traj.max_edge_error < 1e-12


def test_bad_arguments(fourbar):
    with pytest.raises(ValueError, match="valid methods: auto, constructive"):
        trace(fourbar, to=2.5, method="euler")
    with pytest.raises(TypeError, match="unknown option"):
        trace(fourbar, to=2.5, method="projected", stepp=0.1)
    with pytest.raises(KinematicsError, match="unknown port 'd9'"):
        trace(fourbar, drive="d9", to=2.5)
    with pytest.raises(ValueError, match="to must be positive, got -1"):
        trace(fourbar, to=-1.0)
    with pytest.raises(TypeError, match="to must be a number, got '2.5'"):
        trace(fourbar, to="2.5")
    with pytest.raises(TypeError, match="net must be a fabkit.Network, got None"):
        trace(None, to=2.5)
    with pytest.raises(TypeError, match="hold must be a port name or a list of them"):
        trace(fourbar, to=2.5, hold=3)
    # a target farther than all bars together is traced toward that length and reported as
    # not reached where the motion turns back; no step ever sees 1e308
    far = trace(fourbar, to=1e308)
    assert str(far.status) == "turning_point" and far.target == 1e308
    assert abs(far.drive[-1] - (1 + 2 ** 0.5) * 2) < 1e-8
    with pytest.raises(KinematicsError, match="required"):
        trace(fourbar)
    with pytest.raises(KinematicsError, match="share an edge"):
        trace(fourbar, drive=(0, 2), to=2.5)
    with pytest.raises(KinematicsError, match="does not keep the edge lengths"):
        trace(fourbar, to=2.5, start=fourbar.nodes * 1.1)


def test_place_vectorised_matches_scalar(module):
    net = module("chaotic")
    plan = plan_construction(net, net.port("d1"))
    values = np.linspace(1.2, 1.8, 7)
    batch, margin, _ = place(plan, values)
    for k, v in enumerate(values):
        single, _, _ = place(plan, [v])
        np.testing.assert_array_equal(single[0], batch[k])
    assert np.all(margin > 0)
    np.testing.assert_allclose(np.linalg.norm(batch[:, 0] - batch[:, 1], axis=1), values, atol=1e-14)


def test_start_configuration(fourbar):
    first = trace(fourbar, to=2.5, method="constructive")
    again = trace(fourbar, to=3.0, start=first.final, method="projected")
    assert again.success and again.drive[0] == pytest.approx(2.5, abs=1e-12)
    assert np.abs(again.distance("d1") * again.distance("d2") - 4).max() < 1e-10


def test_auto_accepts_options_of_any_method(fourbar):
    traj = trace(fourbar, to=2.5, method="auto", max_step=0.1, samples=11)
    assert traj.method == "constructive" and traj.n_steps == 11
    with pytest.raises(TypeError, match="unknown option"):
        trace(fourbar, to=2.5, method="auto", nonsense=1)


def test_projected_reaches_a_target_next_to_a_flat_turning_point(module):
    # the physical 4-bar turns at its flat state d1 = 1 (slope ∞ there); a chain driven to
    # 1e-9 above it must finish on this side, where constructive placement finishes too
    flat = module("physical_fourbar")
    open_ = trace(flat, drive="d2", to=1.2, method="projected")  # d2 is regular at the flat start
    assert open_.success
    module = flat.with_nodes(open_.final)
    net = fabkit.chain(module, 8)
    a = trace(net, drive="d1", to=1 + 1e-9, method="constructive")
    b = trace(net, drive="d1", to=1 + 1e-9, method="projected")
    assert a.success and b.success, b.message
    for k in range(1, 10):
        assert b.distance(f"d{k}")[-1] == pytest.approx(a.distance(f"d{k}")[-1], abs=1e-6)


def test_projected_node_step_bound_refines_only_where_nodes_move_fast():
    # The and-gate (held port, the tracer changes gauge): a bound on the arclength of the whole
    # network lets single nodes jump 8x that far, while a bound on each node's move holds as
    # the caller sees the nodes (in the caller's gauge) with fewer samples.
    design = fabkit.load_template("and_gate")
    m, bound = design.motion, 0.005
    by_node = trace(design.network, drive=m.drive, to=m.to, method="projected", hold=m.hold,
                    max_node_step=bound)
    by_arc = trace(design.network, drive=m.drive, to=m.to, method="projected", hold=m.hold,
                   max_step=bound)
    assert by_node.success and by_arc.success

    def worst(traj):
        return float(np.linalg.norm(np.diff(traj.positions, axis=0), axis=-1).max())

    assert worst(by_node) <= 1.1 * bound  # first order: 1.06 measured
    assert worst(by_arc) > 5 * bound
    assert by_node.n_steps < by_arc.n_steps
    assert abs(by_node.distance(m.drive)[-1] - m.to) < 1e-12
    from fabkit.errors import SettingsError
    from fabkit.io.schema import check_method_options

    with pytest.raises(SettingsError, match="max_node_step"):
        check_method_options("projected", {"max_node_step": -1.0})
