"""The paper's origami sheet: mode counts, the bifurcation at the flat state, folding, angles."""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from fabkit.fab.creases import (CreasePattern, assignment_score, flat_foldability, fold_angles,
                                network_from_pattern, planar_faces)
from fabkit.kinematics import Status, place, plan_construction
from fabkit.kinematics.branching import (BranchSwitch, analyze_bifurcation, fold_through,
                                         step_off)
from fabkit.kinematics.rk4_nullspace import conformational_velocity
from conftest import TEMPLATES, module_network

D2_STAR = 2.0 - np.sqrt(2.0)  # the folded fixed point d1 = d2 (computed, see docs/origami.md)
PAPER_ASSIGNMENT = ["B", "B", "B", "B", "V", "V", "V", "M"]


@pytest.fixture(scope="module")
def sheet():
    return module_network("origami_sheet")


@pytest.fixture(scope="module")
def faces(sheet):
    return planar_faces(sheet.nodes[:, :2], sheet.edges)


def _score(sheet, faces):
    return lambda x: assignment_score(PAPER_ASSIGNMENT, fold_angles(sheet.edges, faces, x))


def test_flat_state_has_one_self_stress_and_two_motions(sheet):
    m = fabkit.count_modes(sheet)
    assert (m.self_stress, m.conformational, m.rigid) == (1, 2, 6)


def test_folded_state_has_one_motion_and_no_self_stress(sheet, faces):
    traj = fold_through(sheet, "d1", D2_STAR, score=_score(sheet, faces))
    m = fabkit.count_modes(sheet, traj.final)
    assert (m.self_stress, m.conformational) == (0, 1)
    assert m.gap > 1e6


def test_second_order_test_finds_exactly_two_branches(sheet):
    bif = analyze_bifurcation(sheet)
    assert bif.singular and len(bif.branches) == 2
    diag, fold = bif.branches
    assert max(b.residual for b in bif.branches) < 1e-12
    # branch 1: folding along the diagonal BD (nodes 1-3): d1 does not change, P stays on BD
    assert abs(diag.port_rates["d1"][1]) < 1e-9 and diag.port_rates["d2"][1] < -1.0
    x = step_off(sheet, bif, 1, 1.0, 1e-2)
    u = (x[3] - x[1]) / np.linalg.norm(x[3] - x[1])
    off = x[4] - x[1] - ((x[4] - x[1]) @ u) * u
    assert np.linalg.norm(off) < 1e-12
    # branch 2: the one-motion fold: P leaves the line BD, both distances shrink
    assert fold.port_rates["d1"][1] < -1.0 and fold.port_rates["d2"][1] < -0.1
    x = step_off(sheet, bif, 2, 1.0, 1e-2)
    u = (x[3] - x[1]) / np.linalg.norm(x[3] - x[1])
    off = x[4] - x[1] - ((x[4] - x[1]) @ u) * u
    assert np.linalg.norm(off) > 1e-3
    # slope of the map at the flat state: d2'' / d1'' = 1 / (5 + 4 sqrt 2)
    assert fold.port_rates["d2"][1] / fold.port_rates["d1"][1] == pytest.approx(
        1.0 / (5.0 + 4.0 * np.sqrt(2.0)), rel=1e-9)


def test_rk4_nullspace_is_not_trusted_at_the_flat_state(sheet):
    # the paper's method needs a unique null-space velocity: here there are two
    v, count = conformational_velocity(sheet, sheet.nodes.ravel())
    assert v is None and count == 2
    # the projected tracer refuses the singular start and says why
    traj = fabkit.trace(sheet, "d1", 1.0, method="projected")
    assert traj.status is Status.FAILED and "singular" in traj.message


def test_fold_through_follows_the_assignment_to_the_fixed_point(sheet, faces):
    traj = fold_through(sheet, "d1", D2_STAR, score=_score(sheet, faces))
    assert traj.status is Status.FINISHED
    assert traj.stats["branch"] == 2 and traj.events[0].kind == "bifurcation"
    assert np.allclose(traj.positions[0], sheet.nodes)
    assert traj.max_edge_error < 1e-12
    d1, d2 = traj.distance("d1"), traj.distance("d2")
    assert d1[-1] == pytest.approx(D2_STAR, abs=1e-12)
    assert d2[-1] == pytest.approx(D2_STAR, abs=1e-12)  # d1 = d2: the fixed point D2*
    assert np.all(d2[1:-1] > d1[1:-1])  # f(d) > d between the two fixed points
    angles = fold_angles(sheet.edges, faces, traj.final)
    signs = np.sign(angles[4:])
    assert signs.tolist() == [1.0, 1.0, 1.0, -1.0]  # valleys PA, PB, PC; mountain PD
    assert angles[4] == pytest.approx(angles[6], abs=1e-9)
    assert angles[5] == pytest.approx(-angles[7], abs=1e-9)
    assert assignment_score(PAPER_ASSIGNMENT, angles) == 4


def test_named_branch_folds_along_the_diagonal(sheet, faces):
    traj = fold_through(sheet, "d2", 1.0, branch=1, sign=1)
    assert traj.status is Status.FINISHED and traj.stats["branch"] == 1
    assert np.allclose(traj.distance("d1"), np.sqrt(2.0), atol=1e-12)
    angles = fold_angles(sheet.edges, faces, traj.final)
    assert abs(angles[4]) < 1e-9 and abs(angles[6]) < 1e-9  # PA, PC stay flat
    assert abs(angles[5]) > 10 and angles[5] == pytest.approx(angles[7], abs=1e-9)


def test_no_branch_moves_the_drive_the_wrong_way(sheet):
    with pytest.raises(fabkit.KinematicsError, match="towards the target"):
        fold_through(sheet, "d1", 1.6)


def test_branch_switch_method_class(sheet):
    traj = fabkit.trace(sheet, "d1", 1.0, method=BranchSwitch)
    assert traj.status is Status.FINISHED and traj.distance("d1")[-1] == pytest.approx(1.0)
    assert traj.max_edge_error < 1e-12


def test_map_slopes_at_the_two_fixed_points(sheet):
    bif = analyze_bifurcation(sheet)
    plan = plan_construction(sheet, sheet.port("d1"), step_off(sheet, bif, 2, 1.0, 1e-2))
    h = 1e-6
    x, _, _ = place(plan, [D2_STAR - h, D2_STAR + h])
    d2 = sheet.port_distance("d2", x)
    assert (d2[1] - d2[0]) / (2 * h) == pytest.approx(5.0 + 4.0 * np.sqrt(2.0), rel=1e-7)


def test_maekawa_kawasaki(sheet, faces):
    cp = CreasePattern(sheet.nodes[:, :2], sheet.edges, PAPER_ASSIGNMENT, faces)
    (vertex,) = flat_foldability(cp)
    assert vertex["vertex"] == 4 and vertex["maekawa"] and vertex["kawasaki"]
    assert abs(vertex["kawasaki_deg"]) < 1e-9
    wrong = CreasePattern(sheet.nodes[:, :2], sheet.edges, ["B"] * 4 + ["V", "M", "V", "M"], faces)
    (vertex,) = flat_foldability(wrong)
    assert not vertex["maekawa"] and vertex["kawasaki"]


def test_quad_panels_get_an_apex_and_no_spurious_motion():
    # a 2 x 1 rectangle creased down the middle: two square panels, one hinge
    v = [[0, 0], [1, 0], [2, 0], [2, 1], [1, 1], [0, 1]]
    e = [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 0], [1, 4]]
    cp = CreasePattern(v, e, ["B"] * 6 + ["V"], planar_faces(v, e))
    net, info = network_from_pattern(cp)
    assert len(info["apex"]) == 2 and len(info["diagonals"]) == 2
    m = fabkit.count_modes(net)
    assert (m.conformational, m.self_stress) == (1, 0)
    # without the apexes the panels bend along their diagonals: two spurious motions
    bare = fabkit.Network(net.nodes[:6], np.vstack([e, info["diagonals"]]))
    assert fabkit.count_modes(bare).conformational == 3


def test_sheet_template_loads(sheet):
    d = fabkit.load_template(TEMPLATES / "origami_sheet.toml")
    assert np.allclose(d.network.nodes, sheet.nodes) and d.motion.to == pytest.approx(D2_STAR)


def test_null_lines_of_several_stresses():
    from fabkit.kinematics.branching import _null_lines

    # c1² = c2² and c2² = c3²: the four lines (±1, ±1, 1) / sqrt 3
    forms = np.array([np.diag([1.0, -1.0, 0.0]), np.diag([0.0, 1.0, -1.0])])
    lines = _null_lines(forms)
    assert len(lines) == 4
    for c in lines:
        assert np.allclose(np.abs(c), 1 / np.sqrt(3), atol=1e-10)
    # a definite form has no real branch: rigid to second order
    assert _null_lines(np.array([np.eye(2)])) == []


def test_projected_continuation_after_the_step_agrees_with_constructive(sheet):
    a = fold_through(sheet, "d1", 0.6, sign=-1, method="projected")
    b = fold_through(sheet, "d1", 0.6, sign=-1)
    assert (a.method, b.method) == ("branch/projected", "branch/constructive")
    assert a.max_edge_error < 1e-12 and a.status is Status.FINISHED
    assert a.distance("d2")[-1] == pytest.approx(b.distance("d2")[-1], abs=1e-10)
