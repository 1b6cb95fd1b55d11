"""Module design: solution spaces, their intersections, designed modules and the [design] builder."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import fabkit
from fabkit.design.solution_space import (SolutionSpace, design_module, displacement_space,
                                          velocity_space)
from fabkit.errors import DesignError, TemplateError
from fabkit.maps import module_map
from fabkit.templates import load_template, parse_template

SQRT3 = math.sqrt(3.0)
TEMPLATES = Path(__file__).resolve().parents[1] / "templates"


def _spec(paper_modules, name):
    m = paper_modules[name]
    d = m["design"]
    return m, np.array(d.get("initial_positions", m["nodes"][:3])), d


# -- solution spaces -----------------------------------------------------------------------------
def test_fixed_point_spaces_meet_in_four_points_including_the_papers(paper_modules):
    m, x0, d = _spec(paper_modules, "fixed_point")
    vs = velocity_space(x0, d["velocities"])
    ds = displacement_space(x0, d["final_positions"])
    pts = vs.intersect(ds)
    assert pts.shape == (4, 2)
    assert np.max(vs.residual(pts)) < 1e-12 and np.max(ds.residual(pts)) < 1e-12
    assert np.max(np.abs(vs.condition(pts))) < 1e-12
    paper = np.array(m["nodes"][3:])
    for p in paper:
        assert np.min(np.linalg.norm(pts - p, axis=1)) < 1e-12


def test_papers_variable_nodes_lie_on_their_spaces(paper_modules):
    for name in ("velocity_design_example", "super_stable", "slope_one", "displacement_design_example",
                 "curvature_contract", "curvature_maintain", "curvature_expand"):
        m, x0, d = _spec(paper_modules, name)
        var = np.array(m["nodes"][3:])
        if "velocities" in d:
            assert np.max(velocity_space(x0, d["velocities"]).residual(var)) < 1e-12, name
        if "final_positions" in d:
            # the displacement example's node 3 is given to 8 digits only
            assert np.max(displacement_space(x0, d["final_positions"]).residual(var)) < 1e-9, name


def test_slope_one_and_a_half_node_4_is_off_its_velocity_space(paper_modules):
    m, x0, d = _spec(paper_modules, "slope_one_and_a_half")
    res = velocity_space(x0, d["velocities"]).residual(np.array(m["nodes"][3:]))
    assert res[0] < 1e-12 and res[1] == pytest.approx(0.0647, abs=1e-4)


def test_sample_nearest_and_line_points_are_on_the_space(paper_modules):
    _, x0, d = _spec(paper_modules, "velocity_design_example")
    s = velocity_space(x0, d["velocities"])
    pts = s.sample(200)
    assert pts.shape[0] > 100
    assert np.max(s.residual(pts)) < 1e-10
    p = s.nearest([0.3, -1.4])
    assert s.residual(p) < 1e-12
    # Q agrees with the exact condition (same zero set): evaluate at the sampled points
    assert np.max(np.abs(s.evaluate(pts))) < 1e-12


def test_partner_gives_the_final_configuration_with_the_same_edge_lengths(paper_modules):
    _, x0, d = _spec(paper_modules, "displacement_design_example")
    s = displacement_space(x0, d["final_positions"])
    v = s.nearest([-1.0, 1.6])
    v1 = s.partner(v)
    l0 = np.linalg.norm(x0 - v, axis=1)
    l1 = np.linalg.norm(np.array(d["final_positions"]) - v1, axis=1)
    assert np.max(np.abs(l0 - l1)) < 1e-12


def test_3d_spaces_are_quadrics_and_intersect_in_a_curve():
    x0 = np.array([[1.0, 0, 0], [-0.5, 0.8, 0], [-0.5, -0.8, 0], [0, 0, 1.2]])
    vel = np.array([[0.2, 0, 0.1], [0, 0, 0], [0, 0.1, 0], [0, 0, -0.3]])
    fin = 1.3 * x0 + np.array([0.0, 0.1, 0.0])
    vs, ds = velocity_space(x0, vel), displacement_space(x0, fin)
    assert vs.Q.shape == (4, 4)
    pts = vs.sample(300)
    assert pts.shape[0] > 50 and np.max(vs.residual(pts)) < 1e-9
    curve = vs.intersect(ds, slices=20)
    assert curve.shape[0] >= 4 and curve.shape[1] == 3
    assert np.max(vs.residual(curve)) < 1e-9 and np.max(ds.residual(curve)) < 1e-9


def test_rigid_motion_specification_is_rejected():
    x0 = [[0, 0], [1, 0], [0, 1]]
    with pytest.raises(DesignError, match="rigid"):
        velocity_space(x0, [[1, 0], [1, 0], [1, 0]])  # a translation changes no distance


@pytest.mark.parametrize("kwargs,match", [
    ({"designed": [[0, 0], [1, 0]], "velocities": [[0, 0], [1, 0]]}, "exactly 3 designed"),
    ({"designed": [[0, 0], [1, 0], [0, 1]], "velocities": [[0, 0], [1, 0]]}, "must have 3 points"),
    ({"designed": [[0, 0, 0, 0]]}, r"shape \(n, 2\) or \(n, 3\)"),
    ({"designed": [[0, 0], [1, 0], [0, 1]]}, "give `velocities`, `final` or both"),
    ({"designed": [[0, 0], [1, 0], [0, 1]], "velocities": [[0, 0], [1, 0], [0, 0]]},
     "say where the variable nodes go"),
])
def test_bad_design_input(kwargs, match):
    designed = kwargs.pop("designed")
    with pytest.raises(DesignError, match=match):
        design_module(designed, **kwargs)


def test_one_variable_node_leaves_two_motions(paper_modules):
    _, x0, d = _spec(paper_modules, "velocity_design_example")
    with pytest.raises(DesignError, match="2 conformational motions"):
        design_module(x0, velocities=d["velocities"], near=[[-0.9, 0.5]])


# -- designed modules ----------------------------------------------------------------------------
def test_fixed_point_module_designed_from_its_specification(paper_modules):
    m, x0, d = _spec(paper_modules, "fixed_point")
    r = design_module(x0, velocities=d["velocities"], final=d["final_positions"],
                      near=[[-0.9, -1.5], [-0.9, 1.5]])
    assert r.meets == {"velocity": True, "displacement": True}
    assert max(r.residuals.values()) < 1e-10
    assert r.modes.conformational == 1 and r.modes.self_stress == 0
    assert np.max(np.abs(r.network.nodes - np.array(m["nodes"]))) < 1e-9
    f = module_map(r.network)
    fps = f.fixed_points()
    assert fps[0].value == pytest.approx(SQRT3, abs=1e-12) and abs(fps[0].slope) < 1e-6
    assert fps[1].value == pytest.approx(1.7 * SQRT3, abs=1e-9)
    # the designed final configuration keeps every edge and lies on the same branch
    fin = r.final_positions
    assert np.max(np.abs(r.network.lengths_at(fin) - r.network.edge_lengths)) < 1e-12
    assert f(r.network.port_distance("d1", fin)) == pytest.approx(
        r.network.port_distance("d2", fin), abs=1e-12)


def test_automatic_choice_gives_one_motion(paper_modules):
    _, x0, d = _spec(paper_modules, "fixed_point")
    r = design_module(x0, velocities=d["velocities"], final=d["final_positions"])
    assert r.modes.conformational == 1 and all(r.meets.values())


@pytest.mark.parametrize("name,slope", [("super_stable", 0.0), ("slope_one", 1.0),
                                        ("slope_one_and_a_half", 1.5)])
def test_velocity_design_fixes_the_slope(paper_modules, name, slope):
    m, x0, d = _spec(paper_modules, name)
    r = design_module(x0, velocities=d["velocities"], near=m["nodes"][3:])
    assert r.meets == {"velocity": True}
    f = module_map(r.network)
    assert f.derivative(SQRT3) == pytest.approx(slope, abs=1e-9)


# -- templates -----------------------------------------------------------------------------------
def test_design_templates_build_the_papers_modules(paper_modules):
    for name in ("fixed_point", "velocity_design_example", "displacement_design_example"):
        design = load_template(TEMPLATES / f"{name}.toml")
        meta = design.meta["design"]
        assert all(meta["meets"].values()) and meta["conformational_motions"] == 1
        tol = 1e-8 if name == "displacement_design_example" else 1e-9  # 8-digit paper values
        assert np.max(np.abs(design.network.nodes - np.array(paper_modules[name]["nodes"]))) < tol
        traj = design.trace()
        assert str(traj.status) == "finished" and np.max(traj.edge_error) < 1e-12


def test_design_template_errors_name_the_key():
    base = '[design]\ndesigned = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]\n'
    with pytest.raises(TemplateError, match=r"design\.velocities.*shape \(3, 2\)"):
        parse_template(base + "velocities = [[0.0, 0.0]]\nnear = [[1.0, 1.0]]\n", "t.toml")
    with pytest.raises(TemplateError, match=r"design\.colour.*unknown key"):
        parse_template(base + "colour = 1\n", "t.toml")
    with pytest.raises(TemplateError, match=r"design.*give `velocities`"):
        parse_template(base, "t.toml")
    with pytest.raises(TemplateError, match=r"design.*do not meet the velocity"):
        parse_template(base + "velocities = [[0.1, 0.0], [0.0, 0.0], [0.0, 0.2]]\n"
                              "variable = [[1.0, 1.0], [-1.0, 0.7]]\n", "t.toml")


def test_top_level_lazy_names():
    assert fabkit.SolutionSpace is SolutionSpace and fabkit.design_module is design_module


def test_3d_velocity_design_has_one_motion_with_the_designed_slope():
    from fabkit.maps import slope_at

    x0 = np.array([[1.0, 0, 0], [-0.5, 0.8, 0], [-0.5, -0.8, 0], [0, 0, 1.2]])
    vel = np.array([[0.2, 0, 0.1], [0, 0, 0], [0, 0.1, 0], [0, 0, -0.3]])
    hints = [[1.2, 1.0, 0.8], [-1.0, 0.9, 1.1], [0.3, -1.2, 0.9], [0.8, 0.7, -0.9],
             [-0.9, -0.8, -0.7]]
    r = design_module(x0, velocities=vel, near=hints)
    assert r.meets == {"velocity": True} and r.residuals["velocity"] < 1e-12
    assert r.modes.conformational == 1 and r.modes.rigid == 6  # 3·9 − 20 = 7 zero modes

    def rate(i, j):
        e = x0[i] - x0[j]
        return e @ (vel[i] - vel[j]) / np.linalg.norm(e)

    assert float(slope_at(r.network, r.network.nodes)) == pytest.approx(rate(1, 2) / rate(0, 1),
                                                                       rel=1e-10)
