"""``fabkit design --curve``: chains whose final state follows a drawn curve. Each chain is
loaded back from the written templates, traced to its final state and compared with the curve
here, with the test's own circle fit; the laser kits are exported and checked as built."""

from __future__ import annotations

import json
import math
import shlex
from pathlib import Path

import numpy as np
import pytest

import fabkit
from fabkit.cli import main
from fabkit.design import design_curve_chain, read_curve
from fabkit.design.curve import chain_plan, curve_radius, tightest_radius
from fabkit.design.curvature import APEX_RANGE_DEG, LEG_RATIO, design_curvature_type
from fabkit.errors import FabkitError
from fabkit.design.drawing_fit import fit_onto_drawing, fold_onto_drawing
from fabkit.design.letters import chain_centerline
from fabkit.maps import module_map

R = 250.0
QUARTER = f"""<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="300mm"
 viewBox="0 0 300 300"><path d="M 275 275 A {R:g} {R:g} 0 0 0 25 25" fill="none"
 stroke="black"/></svg>"""
HALF = f"""<svg xmlns="http://www.w3.org/2000/svg" width="600mm" height="300mm"
 viewBox="0 0 600 300"><path d="M 50 280 A {R:g} {R:g} 0 0 1 550 280" fill="none"
 stroke="black"/></svg>"""


def run_cli(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def circle(points):
    """Algebraic (Kasa) circle fit: radius and the angle swept, first to last point."""
    p = np.asarray(points)
    A = np.column_stack([2 * p, np.ones(len(p))])
    sol = np.linalg.lstsq(A, np.sum(p * p, axis=1), rcond=None)[0]
    c = sol[:2]
    r = math.sqrt(sol[2] + c @ c)
    ang = np.unwrap(np.arctan2(p[:, 1] - c[1], p[:, 0] - c[0]))
    return r, math.degrees(abs(ang[-1] - ang[0]))


def traced(path):
    """The chain template as written: its initial and final centre lines in mm."""
    design = fabkit.load_template(path)
    scale = design.fabrication["laser"]["scale"]
    traj = fabkit.trace(design.network, "d1", to=design.motion.to, method="constructive",
                        samples=2)
    assert str(traj.status) == "finished" and traj.max_edge_error < 1e-12
    k = len(design.raw["chain"]["modules"])
    start = chain_centerline(design.network, traj.positions[0], k) * scale
    end = chain_centerline(design.network, traj.positions[-1], k) * scale
    return design, start, end


@pytest.fixture(scope="module")
def arcs(tmp_path_factory):
    out = {}
    for name, svg in (("quarter", QUARTER), ("half", HALF)):
        folder = tmp_path_factory.mktemp(name)
        src = folder / f"{name}.svg"
        src.write_text(svg)
        code = main(["design", "--curve", str(src), "-o", str(folder / "kit")])
        assert code == 0
        out[name] = folder / "kit"
    return out


@pytest.mark.parametrize("name, sweep", [("quarter", 90.0), ("half", 180.0)])
def test_arc_chains_have_the_arcs_proportions(arcs, name, sweep):
    design, start, end = traced(arcs[name] / f"{name}.toml")
    length = math.radians(sweep) * R
    k = len(design.raw["chain"]["modules"])
    # the module count follows from length / module size (the pitch depends on the types)
    assert abs(k - length / 50.0) <= 1.0
    # straight at the start
    u = (start[-1] - start[0]) / np.linalg.norm(start[-1] - start[0])
    off = (start - start[0]) @ np.array([-u[1], u[0]])
    assert np.abs(off).max() < 1e-9 * length
    # the final state is the arc: radius, angle swept, chord against length
    r, swept = circle(end)
    assert abs(r - R) / R < 0.03
    assert abs(swept - sweep) < 4.0
    seg = np.linalg.norm(np.diff(end, axis=0), axis=1).sum()
    assert abs(seg - length) / length < 0.02
    chord_ratio = np.linalg.norm(end[-1] - end[0]) / seg
    assert abs(chord_ratio - math.sin(math.radians(sweep) / 2) / (math.radians(sweep) / 2)) < 0.02
    report = json.loads((arcs[name] / f"{name}_fit.json").read_text())
    assert report["fit_error_mm"]["rms"] < 3.0 and report["fit_error_mm"]["max"] < 12.0
    assert report["modules"] == k


def test_fit_error_is_written_with_the_template(arcs):
    text = (arcs["quarter"] / "quarter.toml").read_text()
    report = json.loads((arcs["quarter"] / "quarter_fit.json").read_text())
    e = report["fit_error_mm"]
    assert f"fit error: rms {e['rms']:.3f} mm, max {e['max']:.3f} mm" in text
    design = fabkit.load_template(arcs["quarter"] / "quarter.toml")
    assert f"rms {e['rms']:.2f} mm" in design.description
    rows = (arcs["quarter"] / "quarter_centerline.csv").read_text().splitlines()[1:]
    assert len(rows) == report["modules"] + 1


@pytest.mark.parametrize("name", ["quarter", "half"])
def test_arc_chains_export_a_laser_kit_that_passes_its_check(arcs, tmp_path, name):
    from fabkit.check import check_file
    from fabkit.writers import export

    design = fabkit.load_template(arcs[name] / f"{name}.toml")
    paths, report = export(design, "dxf", tmp_path)
    bom = json.loads((tmp_path / "laser_bom.json").read_text())
    assert bom["layers"]["count"] <= 12
    sheet = [p for p in paths if p.name == "laser_sheet1.dxf"][0]
    assert check_file(sheet, design=design)["ok"]


def test_curvature_modules_are_designed_as_wished(arcs):
    for f in sorted(arcs["quarter"].glob("quarter_m*.toml")):
        design = fabkit.load_template(f)
        fmap = module_map(design.network)
        # symmetric module: the identity map from D1* = 1 to D2*, both ends on one branch
        d = np.linspace(1.0, LEG_RATIO, 11)
        assert np.abs(fmap(d) - d).max() < 1e-12
        final = fmap.configuration(LEG_RATIO)
        apex = math.degrees(2 * math.asin(np.linalg.norm(final[0] - final[2]) / (2 * LEG_RATIO)))
        assert APEX_RANGE_DEG[0] - 1e-9 <= apex <= APEX_RANGE_DEG[1] + 1e-9


def test_variable_nodes_stay_inside_their_triangle():
    from fabkit.design.geometry import inside_margin

    for apex in (50.0, 70.0, 90.0):
        t = design_curvature_type(apex)
        xs = module_map(t.network).configuration(np.linspace(1.0, LEG_RATIO, 21))
        assert inside_margin(xs[:, 3:], xs[:, :3]).min() >= 0.02
    with pytest.raises(FabkitError):
        design_curvature_type(120.0)


def test_csv_polyline(tmp_path, capsys):
    t = np.linspace(0, np.pi / 2, 60)
    rows = "\n".join(f"{R * math.cos(a):.6f},{R * math.sin(a):.6f}" for a in t)
    src = tmp_path / "arc.csv"
    src.write_text("x,y\n" + rows + "\n")
    code, out, err = run_cli(["design", "--curve", src, "-o", tmp_path / "o"], capsys)
    assert code == 0, err
    _, _, end = traced(tmp_path / "o" / "arc.toml")
    r, swept = circle(end)
    assert abs(r - R) / R < 0.03 and abs(swept - 90.0) < 4.0


def test_bezier_s_curve_turns_both_ways():
    svg = b"""<svg xmlns="http://www.w3.org/2000/svg" width="800mm" height="400mm"
     viewBox="0 0 800 400"><path d="M 0 200 C 250 -100 550 500 800 200" fill="none"
     stroke="black"/></svg>"""
    curve = read_curve(svg, "s.svg")
    result = design_curve_chain(curve, module_size=50.0)
    assert result.errors["rms"] < 0.01 * curve.length
    c = result.centerline
    d = np.diff(c, axis=0)
    turn = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]
    # smoothed over module pairs, the chain turns one way, then the other
    pair = turn[:-1] + turn[1:]
    assert pair.max() > 0 and pair.min() < 0


def test_svg_units_transforms_and_shapes():
    svg = b"""<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm"
     viewBox="0 0 50 50"><g transform="scale(2)"><path d="M 0 0 L 10 0"/></g>
     <polyline points="0,5 30,5 30,20"/></svg>"""
    curve = read_curve(svg, "u.svg")
    # user unit = 2 mm; the polyline (45 units) is the longest of the two strokes
    assert curve.strokes == 2
    assert curve.length == pytest.approx(90.0, rel=1e-6)  # svgelements: 3.779528 px per mm
    assert curve.points[0] == pytest.approx([0.0, -10.0], abs=1e-4)  # y up


def test_too_tight_a_curve_names_a_wish_that_builds(tmp_path, capsys):
    src = tmp_path / "tight.svg"
    src.write_text(QUARTER.replace(f"A {R:g} {R:g}", "A 100 100").replace("M 275 275",
                                                                          "M 125 125"))
    code, out, err = run_cli(["design", "--curve", src, "-o", tmp_path / "o"], capsys)
    assert code == 2
    (line,) = err.strip().splitlines()
    # r = 100 mm turns by 2 x 50 / 100 rad = 57.3 deg over two 50 mm modules; 32 is the most
    # (apex angles 54/86: the widest pair whose mean keeps the neighbour rule)
    assert "turns by 57.3 deg within two modules" in line and "at most 32 deg" in line
    assert not (tmp_path / "o").exists()
    # the suggestion is the whole option set: pasted alone, it designs the curve
    options = shlex.split(line.rsplit("nearest feasible: ", 1)[1])
    assert options[:2] == ["--curve", str(src)]
    assert {"--curve-scale", "--module-size"} <= set(options)
    code, out, err = run_cli(["design", *options, "-o", tmp_path / "o"], capsys)
    assert code == 0, err


def test_a_suggested_scale_is_absolute_not_a_factor_of_the_one_given(tmp_path, capsys):
    # the quarter circle of r = 100 mm given --curve-scale 1.1 is still too tight; the scale
    # suggested is the one to type (from the drawing as drawn), and pasted alone it designs
    src = tmp_path / "tight.svg"
    src.write_text(QUARTER.replace(f"A {R:g} {R:g}", "A 100 100").replace("M 275 275",
                                                                          "M 125 125"))
    code, out, err = run_cli(["design", "--curve", src, "--curve-scale", "1.1", "-o",
                              tmp_path / "o"], capsys)
    assert code == 2
    (line,) = err.strip().splitlines()
    options = shlex.split(line.rsplit("nearest feasible: ", 1)[1])
    assert options[:2] == ["--curve", str(src)]
    if "--curve-scale" in options:
        assert float(options[options.index("--curve-scale") + 1]) >= 1.1
    code, out, err = run_cli(["design", *options, "-o", tmp_path / "o"], capsys)
    assert code == 0, err


def test_bad_curve_input_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.svg"
    bad.write_text("<svg><path d=")
    code, _, err = run_cli(["design", "--curve", bad, "-o", tmp_path / "o"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "bad.svg" in err
    code, _, err = run_cli(["design", "--curve", tmp_path / "none.svg", "-o", tmp_path / "o"],
                           capsys)
    assert code == 1 and "no such curve file" in err
    empty = tmp_path / "empty.svg"
    empty.write_text('<svg xmlns="http://www.w3.org/2000/svg"/>')
    code, _, err = run_cli(["design", "--curve", empty, "-o", tmp_path / "o"], capsys)
    assert code == 1 and "no path or shape" in err
    code, _, err = run_cli(["design", "--curve", empty, "--fixed-point", "1.6", "-o",
                            tmp_path / "o"], capsys)
    assert code == 2
    assert not (tmp_path / "o").exists()


def test_a_hundred_module_curve():
    x = np.linspace(0.0, 4400.0, 2000)
    curve = np.column_stack([x, 300.0 * np.sin(2 * np.pi * x / 1600.0)])
    result = design_curve_chain(curve, module_size=50.0)
    length = float(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum())
    assert abs(result.report["modules"] - length / 50.0) <= 0.05 * length / 50.0
    assert result.report["modules"] >= 100
    assert result.errors["rms"] < 5.0 and result.errors["max"] < 20.0


def test_a_one_mm_curve_is_a_refusal_like_any_other(tmp_path, capsys):
    src = tmp_path / "one.csv"
    src.write_text("x,y\n0,0\n1,0\n")
    code, out, err = run_cli(["design", "--curve", src, "-o", tmp_path / "o"], capsys)
    assert code == 2
    (line,) = err.strip().splitlines()
    assert "the curve (1 mm) is shorter than two modules" in line
    assert "even the smallest modules (15.3 mm) need a curve of at least 30.6 mm" in line
    # a straight chain's nodes lie half a module's width (12.4 mm for 19.9 mm modules) off the
    # line: within 1 % of its size only when the line is 1.3 m long or more
    assert line.endswith(f"nearest feasible: --curve {src} --curve-scale 1500 --module-size "
                         "19.9")
    assert "its designed nodes within 1 %" in line
    assert not (tmp_path / "o").exists()
    code, out, err = run_cli(["design", *suggestion(line), "-o", tmp_path / "o"], capsys)
    assert code == 0, err
    fit = measured(tmp_path / "o", "one", src, 1500.0)
    assert fit.mean <= 0.01 and fit.start <= 0.02 and fit.end <= 0.02
    assert fit.nodes_mean <= 0.01


# --- sharp curves at their own size, measured on the drawing (issue 50) -------------------------

#: The bundled curves of this source tree (the installed package may point at another copy).
CURVES = Path(__file__).resolve().parents[1] / "templates" / "curves"


def suggestion(line):
    """The option set a refusal names, split as a shell would."""
    return shlex.split(line.rsplit("nearest feasible: ", 1)[1])


def measured(folder, name, src, scale):
    """The chain written to ``folder``, traced and laid on its drawing (``src`` times
    ``scale``) by fabkit.design.drawing_fit."""
    design = fabkit.load_template(folder / f"{name}.toml")
    curve = read_curve(src.read_bytes(), str(src)).points * scale
    k = len(design.raw["chain"]["modules"])
    return fold_onto_drawing(design.network, design.fabrication["laser"]["scale"], k, curve)


def test_the_drawing_fit_finds_the_motion_and_can_fail():
    t = np.linspace(0.0, np.pi / 2, 400)
    arc = 100.0 * np.column_stack([np.cos(t), np.sin(t)])
    turn = np.array([[math.cos(1.0), -math.sin(1.0)], [math.sin(1.0), math.cos(1.0)]])
    pts = arc[::21] @ turn.T + [300.0, -40.0]
    rot, shift = fit_onto_drawing(pts, arc)
    assert np.abs(pts @ rot.T + shift - arc[::21]).max() < 1e-3
    # the same points on an arc of 110 mm cannot lie on the 100 mm one: the fit says so
    wide = 1.1 * arc[::21] @ turn.T
    rot, shift = fit_onto_drawing(wide, arc)
    from scipy.spatial import cKDTree

    gap = cKDTree(arc).query(wide @ rot.T + shift)[0]
    assert 1.0 < gap.mean() < 10.0


def test_the_drawing_fit_of_a_written_chain_agrees_with_the_designer(arcs):
    src = arcs["quarter"].parent / "quarter.svg"
    fit = measured(arcs["quarter"], "quarter", src, 1.0)
    report = json.loads((arcs["quarter"] / "quarter_fit.json").read_text())
    own = report["fit_error_fraction_of_size"]
    assert fit.mean <= 0.001 and abs(fit.mean - own["mean"]) < 0.0005
    assert fit.start <= 0.002 and fit.end <= 0.002
    # the designed nodes lie half a module's width from the curve: 36 mm of a 354 mm drawing
    assert 0.08 < fit.nodes_mean < 0.12
    # the designer's model puts them as far from the curve, on average (what the suggestions'
    # search judges nodes by before it builds)
    assert report["model_fit_fraction_of_size"]["nodes_mean"] == pytest.approx(fit.nodes_mean,
                                                                              abs=1e-4)
    assert report["drawing_fit_percent_of_size"]["mean"] == pytest.approx(100 * fit.mean,
                                                                          abs=1e-6)


def test_tightest_radius_is_what_the_module_sizes_turn_along():
    r = tightest_radius()
    assert 110.0 < r < 130.0
    # 2 m / (sharpest turn per two modules) at every size is at least that
    for m in (16.0, 20.0, 25.0, 30.0, 50.0):
        turn = math.radians(chain_plan(m)["turn_deg"])
        assert 2 * m / turn >= r - 1e-9
    t = np.linspace(0.0, np.pi / 2, 2000)
    assert curve_radius(60.0 * np.column_stack([np.cos(t), np.sin(t)]), 85.0) \
        == pytest.approx(60.0, rel=0.01)


def test_l_corner_folds_onto_its_drawing_at_the_size_suggested(tmp_path, capsys):
    # two 400 mm legs at 90 deg: 50 mm modules cut the corner 1.1 % off on average; smaller
    # modules cut it closer (the round no module turns tighter than stays), and their nodes lie
    # closer to the line drawn. At the drawing's own size (566 mm across) no module is narrow
    # enough for its nodes to lie within 1 % (the smallest, 15.3 mm, put them 10 mm off the
    # centre line): the refusal names the least enlargement with 19.9 mm modules, and pasted
    # alone it designs the L with its midpoints and its nodes on the drawing
    src = CURVES / "l_corner.csv"
    code, out, err = run_cli(["design", "--curve", src, "-o", tmp_path / "o"], capsys)
    assert code == 2
    (line,) = err.strip().splitlines()
    assert "no module size turns a chain tighter than" in line
    assert "its designed nodes within 1 %" in line
    options = suggestion(line)
    assert options == ["--curve", str(src), "--curve-scale", "2.7", "--module-size", "19.9"]
    code, out, err = run_cli(["design", *options, "-o", tmp_path / "o"], capsys)
    assert code == 0, err
    fit = measured(tmp_path / "o", "l_corner", src, 2.7)
    assert fit.mean <= 0.01 and fit.start <= 0.02 and fit.end <= 0.02
    assert fit.nodes_mean <= 0.01


def _refused_then_pasted(src, name, tmp_path, capsys):
    """A curve with a tip of r = 32 mm refused at its own size, its suggestion pasted alone and
    designed: (the options suggested, their --curve-scale, the traced chain's fit)."""
    code, out, err = run_cli(["design", "--curve", src, "-o", tmp_path / "o"], capsys)
    assert code == 2
    (line,) = err.strip().splitlines()
    assert "its sharpest turn has a radius of about 32" in line
    assert "its designed nodes within 1 %" in line
    options = suggestion(line)
    scale = float(options[options.index("--curve-scale") + 1])
    code, out, err = run_cli(["design", *options, "-o", tmp_path / "o"], capsys)
    assert code == 0, err
    return options, scale, measured(tmp_path / "o", name, src, scale)


def test_a_petal_is_enlarged_until_its_nodes_lie_on_it(tmp_path, capsys):
    # one petal of the quadrifolium r = 162 sin 2theta mm (176 mm across): its tip (r = 32 mm)
    # is tighter than any module turns, so the drawing is enlarged. Cut tips fit from about 2.9
    # times on; the nodes of the smallest modules tried (19.9 mm) lie 12-13 mm off the centre
    # line, within 1 % of the size from 7.4 times on: the nodes set the enlargement
    t = np.linspace(0.0, np.pi / 2, 400)
    r = 162.0 * np.sin(2 * t)
    src = tmp_path / "petal.csv"
    src.write_text("x,y\n" + "\n".join(f"{a:.6f},{b:.6f}" for a, b in
                                       zip(r * np.cos(t), r * np.sin(t))) + "\n")
    options, scale, fit = _refused_then_pasted(src, "petal", tmp_path, capsys)
    assert options[2:] == ["--curve-scale", "8.2", "--module-size", "19.9"]
    assert fit.mean <= 0.01 and fit.start <= 0.02 and fit.end <= 0.02
    assert 0.009 <= fit.nodes_mean <= 0.0095  # held to 95 % of 1 %, and no more than needed


@pytest.mark.slow
def test_quadrifolium_at_its_own_size_is_refused_with_options_that_fold_onto_it(tmp_path,
                                                                               capsys):
    # r = 162 sin 2theta mm, the authors' chain at its own size (353 mm across the diagonal):
    # refused, and the option set named designs a chain whose traced port midpoints lie within
    # 1 % of the drawing's size on average (ends 2 %) and whose designed nodes lie within 1 %
    src = CURVES / "quadrifolium.csv"
    drawing = read_curve(src.read_bytes(), str(src)).points
    assert np.abs(drawing).max() == pytest.approx(124.7, abs=0.1)
    options, scale, fit = _refused_then_pasted(src, "quadrifolium", tmp_path, capsys)
    assert options[2:] == ["--curve-scale", "4", "--module-size", "19.9"]
    assert fit.mean <= 0.01 and fit.start <= 0.02 and fit.end <= 0.02
    assert fit.nodes_mean <= 0.01
