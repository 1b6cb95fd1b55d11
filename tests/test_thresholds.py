"""Decisions near a threshold, each by a stated rule that gives the same answer for any result
within rounding of the true one (fabkit.numerics names the tolerances and where they come from).
"""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from design_variants import moved, perturbed, renumbered
from fabkit.kinematics import place, plan_construction
from fabkit.maps import module_map
from fabkit.numerics import (COLLINEAR_PARENTS_RTOL, FLAT_SHEET_RTOL, TARGET_AT_TURN_RTOL,
                             canonical_frame, canonical_order)

ROOT2 = np.sqrt(2.0)


# --- a node whose parents lie on one line has no place ---------------------------------------

def _tetra(offset: float):
    """Node 3 placed from nodes 0, 1, 2, node 2 ``offset`` off the line through 0 and 1."""
    x = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, offset, 0.0], [1.0, 0.3, 0.8]])
    edges = [[0, 1], [0, 2], [1, 2], [0, 3], [1, 3], [2, 3]]
    return fabkit.Network(x, edges, ports={"d1": (0, 1)})


def test_parents_on_one_line_give_no_place_instead_of_round_off():
    net = _tetra(0.5)
    plan = plan_construction(net, (0, 1))
    # the same plan placed with node 2 moved onto the line 0-1: its lengths say so
    radii = np.array(plan.radii, dtype=np.float64)
    row = list(plan.order).index(2)
    radii[row, :2] = 1.0  # |x2 - x0| = |x2 - x1| = 1 with |x0 - x1| = 2: node 2 on the line
    x, margin, worst = place(plan, [2.0], radii=radii[None])
    assert margin[0] == -np.inf
    assert np.isnan(x[0, 3]).all()
    # just off the line (1e3 times the tolerance) node 3 has a place, to round-off
    net = _tetra(1e3 * COLLINEAR_PARENTS_RTOL * 2.0)
    plan = plan_construction(net, (0, 1))
    x, margin, _ = place(plan, [2.0])
    assert margin[0] > 0
    assert np.abs(net.edge_error(x[0])).max() < 1e-9


# --- the flat sheet's crystal: at the end of its branch, the same on every machine -----------

def test_the_flat_sheets_map_ends_at_its_flat_crystal_with_the_limit_slope():
    net = fabkit.load_template("origami_sheet").network
    fmap = module_map(net, "d1", "d2")
    lo, hi = fmap.domain
    assert hi == pytest.approx(ROOT2, abs=1e-12) and hi <= ROOT2
    flat = [p for p in fmap.fixed_points() if p.at_end]
    assert len(flat) == 1
    # the slope at the flat state is the limit from inside: 0.0938363 (d2 and d1 both fall
    # quadratically in the fold angle); evaluated at the end itself it was round-off (0.0056
    # or 0.0855, by BLAS kernel)
    assert flat[0].value == pytest.approx(ROOT2, abs=1e-12)
    assert flat[0].slope == pytest.approx(0.0938363, rel=1e-5)
    assert flat[0].kind == "stable"
    inside = fmap.derivative(hi - 1e-6)
    assert inside == pytest.approx(flat[0].slope, rel=1e-5)


@pytest.mark.parametrize("make", [renumbered, moved, perturbed])
def test_the_chain_of_sheets_ends_flat_on_every_copy(make):
    """A 1e-12 change of the chain's coordinates moves its map's flat end off the diagonal by
    3e-12: still the crystal at the end of the branch, with the same slope."""
    from fabkit.motion.modules import chain_modules
    from fabkit.kinematics import make_problem

    for d in (fabkit.load_template("origami_chain12"),
              make(fabkit.load_template("origami_chain12"))):
        p = make_problem(d.network, d.motion.drive, d.motion.to)
        mods = chain_modules(d, [p.start, d.trace().final])
        fmap = module_map(mods[0].network, "in", "out")
        ends = [f for f in fmap.fixed_points() if f.at_end]
        assert len(ends) == 1
        assert ends[0].value == pytest.approx(ROOT2, abs=1e-9)
        # the inverse of the sheet's own slope at flat: 1 / 0.0938363
        assert ends[0].slope == pytest.approx(1 / 0.0938363, rel=1e-5)
        assert ends[0].kind == "unstable"


# --- a touching fixed point (slope 1) ---------------------------------------------------------

def test_a_touching_fixed_point_stays_one_neutral_point_when_the_design_moves_by_1e12():
    d = fabkit.load_template("velocity_design_example")
    for design in (d, perturbed(d, seed=3), perturbed(d, seed=4), perturbed(d, seed=5)):
        fps = module_map(design.network, "d1", "d2").fixed_points()
        assert [p.kind for p in fps] == ["neutral"]
        assert fps[0].value == pytest.approx(np.sqrt(3), rel=1e-5)


# --- a target within rounding past a turning point ---------------------------------------------

def test_a_target_within_rounding_past_the_fold_is_reached_there_and_said():
    d = fabkit.load_template("super_stable_chain")   # to = D2* + 1e-12, at the collapse
    for design in (d, perturbed(d)):
        t = design.trace()
        assert t.success
        assert abs(t.drive[-1] - d.motion.to) <= TARGET_AT_TURN_RTOL * d.motion.to
    t = perturbed(d).trace()   # its turning point moved 7.6e-11 above the target
    assert "within rounding of the target" in t.message
    assert t.events[-1].kind.value == "turning_point"
    # a target visibly past the turning point is not reached
    far = d.trace(to=d.motion.to - 1e-6)
    assert not far.success and str(far.status) == "turning_point"


# --- a flat sheet, however drawn ----------------------------------------------------------------

def test_a_sheet_flat_to_typed_digits_is_flat_and_its_pattern_does_not_turn_with_svd():
    from fabkit.model.flat import flat_coords as _flat_coords

    d = fabkit.load_template("origami_sheet")
    x = d.network.nodes
    assert _flat_coords(x + 1e-12 * np.random.default_rng(0).standard_normal(x.shape),
                        d.network.edges) is not None
    bent = x.copy()
    bent[4, 2] = 10 * FLAT_SHEET_RTOL * 2.0
    assert _flat_coords(bent, d.network.edges) is None
    # turned out of the xy plane: the pattern in the frame of its own bars (congruent)
    t = moved(d).network.nodes
    flat = _flat_coords(t, d.network.edges)
    first = flat[1] - flat[0]
    assert first[1] == pytest.approx(0.0, abs=1e-12) and first[0] > 0  # first bar along x
    def dists(p):
        return np.linalg.norm(p[:, None] - p[None], axis=-1)
    assert np.allclose(dists(flat), dists(x[:, :2]), atol=1e-12)


def test_the_sheet_is_sized_corner_to_corner_whatever_its_drawing():
    from fabkit.fab.creases import origami_model

    d = fabkit.load_template("origami_sheet")
    a, b = origami_model(d), origami_model(moved(d))
    assert a.scale == pytest.approx(150.0 / ROOT2, rel=1e-12)
    assert b.scale == pytest.approx(a.scale, rel=1e-12)


# --- where random errors are attached ---------------------------------------------------------

def test_the_canonical_order_follows_the_bar_list_and_the_frame_turns_with_the_design():
    edges = np.array([[3, 1], [1, 0], [0, 3], [2, 0]])
    assert canonical_order(edges, 5).tolist() == [3, 1, 0, 2, 4]
    rng = np.random.default_rng(1)
    x = rng.standard_normal((4, 3))
    f = canonical_frame(x, edges)
    assert np.allclose(f @ f.T, np.eye(3), atol=1e-14) and np.linalg.det(f) > 0
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q *= np.sign(np.linalg.det(q))
    g = canonical_frame(x @ q.T + 5.0, edges)
    assert np.allclose(g, f @ q.T, atol=1e-12)
    # 2D: x along the first bar (3 -> 1), y the part of the next bar (1 -> 0) across it, so a
    # mirrored drawing gets the mirrored frame
    y = x[:, :2]
    f2 = canonical_frame(y, edges)
    assert np.allclose(f2[0], (y[1] - y[3]) / np.linalg.norm(y[1] - y[3]))
    v = y[0] - y[1]
    r = v - (v @ f2[0]) * f2[0]
    assert np.linalg.norm(r) / np.linalg.norm(v) > 0.1
    assert np.allclose(f2[1], r / np.linalg.norm(r))


# --- a start is singular relative to the network's size --------------------------------------

def test_the_singular_start_threshold_falls_with_the_size():
    from fabkit.kinematics.projected import (SINGULAR_START, SINGULAR_START_FLOOR,
                                             singular_start_threshold)

    assert singular_start_threshold(500) == SINGULAR_START
    # a chain of k 4-bars has about 4k rows and σ_min ≈ 3.5/k² at its start (3.5e-10 at 10⁵):
    # 35 times above the threshold at 10⁵ modules and at 10⁶
    for k in (10**4, 10**5, 10**6):
        assert 3.5 / k**2 > 30 * singular_start_threshold(4 * k)
    assert singular_start_threshold(10**9) == SINGULAR_START_FLOOR > 100 * 2.2e-16


def test_a_flat_sheet_is_still_singular_for_the_projected_method():
    d = fabkit.load_template("origami_sheet")
    tr = fabkit.trace(d.network, drive=d.motion.drive, to=d.motion.to, method="projected")
    assert not tr.success and "singular" in tr.message


@pytest.mark.slow
def test_projected_traces_a_chain_of_a_hundred_thousand_fourbars():
    # σ_min of its start is 3.5e-10, once below a fixed 1e-9 and refused as singular
    net = fabkit.chain(fabkit.load_template("fourbar").network, copies=10**5)
    proj = fabkit.trace(net, drive="d1", to=2.6, method="projected")
    cons = fabkit.trace(net, drive="d1", to=2.6, method="constructive")
    assert proj.success and cons.success
    end = f"d{10**5 + 1}"
    assert proj.distance(end)[-1] == pytest.approx(cons.distance(end)[-1], abs=1e-10)


# --- the exact searches stop at a count of work, the same on every machine ------------------

def test_the_exact_searches_are_held_to_named_counts_of_work_not_to_seconds(monkeypatch):
    """The layer program and the sheet rows' program stop at branch-and-bound node counts; the
    wall clock is only a far safety net (an error when reached), so a busy machine cannot change
    a stacking or a sheet."""
    import scipy.optimize
    from scipy.optimize._milp import milp as real

    import fabkit.fab.shelves as shelves
    from fabkit.fab.laser_plan import laser_plan
    from fabkit.fab.layers import constants

    # the limits, named: about what 20 s, 5 s and 5 s bought on a quiet 2-core machine
    assert (constants.MILP_NODES, constants.MILP_STEP_NODES, shelves.MILP_NODES) == \
        (10_000, 2_000, 500)
    assert constants.MILP_SAFETY_SECONDS == shelves.MILP_SAFETY_SECONDS == 900.0
    asked = []

    def milp(c, **kw):
        asked.append(dict(kw["options"]))
        res = real(c, **kw)
        asked[-1]["nodes used"] = res.mip_node_count
        return res

    monkeypatch.setattr(scipy.optimize, "milp", milp)
    # curvature_contract's kit asks both programs: its colouring stops a layer above the clique
    plan = laser_plan(fabkit.load_template("curvature_contract"))
    assert (plan.stacking.n_layers, plan.stacking.lower_bound, len(plan.sheets)) == (5, 5, 1)
    assert [{k: v for k, v in a.items() if k != "nodes used"} for a in asked] == [
        {"node_limit": constants.MILP_NODES, "time_limit": constants.MILP_SAFETY_SECONDS,
         "disp": False},
        {"node_limit": shelves.MILP_NODES, "time_limit": shelves.MILP_SAFETY_SECONDS}]
    # both settled far inside their counts (presolve; one node)
    assert all((a["nodes used"] or 0) <= 1 for a in asked)
