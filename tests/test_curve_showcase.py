"""The showcase curves of docs/design.md (bundled in templates/curves): a quadrifolium, an S of
two arcs, an L with a right-angled corner and a spiral of 1.5 turns. Each designs (or is refused
with a suggestion that then designs); the written chain is loaded, traced to its final state and
fitted onto its curve here, with this test's own fit (a rigid motion that minimises the mean
squared distance to the curve, found by scipy from a Kabsch start): its centre line must lie
within 1 % of the curve's size (bounding-box diagonal) on average, its ends within 2 %, its
length within one module of the curve's, turning the way the drawing turns."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.spatial import cKDTree

import fabkit
from fabkit.cli import main
from fabkit.design.letters import chain_centerline

#: The bundled curves of this source tree (an installed package may point at another copy).
CURVES = Path(__file__).resolve().parents[1] / "templates" / "curves"


def read_csv(path):
    rows = [ln.split(",") for ln in path.read_text().splitlines()
            if ln and not ln.startswith(("#", "x"))]
    return np.array(rows, dtype=float)


def dense(curve, step=0.25):
    """The curve resampled every ``step`` mm (for nearest-point distances)."""
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])
    t = np.arange(0, s[-1] + step, step).clip(max=s[-1])
    return np.column_stack([np.interp(t, s, curve[:, 0]), np.interp(t, s, curve[:, 1])])


def moved(points, p):
    c, s = math.cos(p[0]), math.sin(p[0])
    return points @ np.array([[c, -s], [s, c]]).T + p[1:]


def own_fit(points, curve):
    """The rigid motion (no mirror) that brings the points closest to the curve: Kabsch on the
    points at equal arclength, then Nelder-Mead on the mean squared distance, the chain's two
    ends counting as two more points whose target is the curve's ends (a chain covers its
    curve end to end, it does not slide along it)."""
    tree = cKDTree(dense(curve))
    s_c = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    s_k = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])
    ref = np.column_stack([np.interp(s_c * s_k[-1] / s_c[-1], s_k, curve[:, 0]),
                           np.interp(s_c * s_k[-1] / s_c[-1], s_k, curve[:, 1])])
    a, b = points - points.mean(0), ref - ref.mean(0)
    u, _, vt = np.linalg.svd(a.T @ b)
    rot = (u @ vt).T
    if np.linalg.det(rot) < 0:
        u[:, -1] *= -1
        rot = (u @ vt).T
    t0 = ref.mean(0) - points.mean(0) @ rot.T
    p0 = np.array([math.atan2(rot[1, 0], rot[0, 0]), *t0])

    def cost(p):
        m = moved(points, p)
        ends = np.sum((m[[0, -1]] - curve[[0, -1]]) ** 2)
        return float((np.sum(tree.query(m)[0] ** 2) + ends) / (len(m) + 2))

    p = minimize(cost, p0, method="Nelder-Mead",
                 options={"xatol": 1e-6, "fatol": 1e-9, "maxiter": 4000}).x
    return moved(points, p), tree


def turn(points):
    d = np.diff(points, axis=0)
    return float(np.sum(np.arctan2(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0],
                                   np.sum(d[:-1] * d[1:], axis=1))))


def design(tmp_path, name, *extra):
    """``fabkit design --curve CURVES/NAME.csv``. Returns the output folder and the exit
    status."""
    out = tmp_path / name
    args = ["design", "--curve", str(CURVES / f"{name}.csv"), *extra, "-o", str(out)]
    code = main(args)
    return out, code


def check_chain(out, name, curve):
    """Load the written chain, trace it to its final state, fit it here; the figures."""
    d = fabkit.load_template(out / f"{name}.toml")
    scale = d.fabrication["laser"]["scale"]
    traj = fabkit.trace(d.network, "d1", to=d.motion.to, method="constructive", samples=2)
    assert str(traj.status) == "finished" and traj.max_edge_error < 1e-9
    k = len(d.raw["chain"]["modules"])
    centre = chain_centerline(d.network, traj.positions[-1], k) * scale
    fitted, tree = own_fit(centre, curve)
    size = float(np.linalg.norm(np.ptp(curve, axis=0)))
    dist = tree.query(fitted)[0]
    report = json.loads((out / f"{name}_fit.json").read_text())
    return {"mean": dist.mean() / size, "start": np.linalg.norm(fitted[0] - curve[0]) / size,
            "end": np.linalg.norm(fitted[-1] - curve[-1]) / size, "centre": fitted,
            "length": float(np.linalg.norm(np.diff(centre, axis=0), axis=1).sum()),
            "modules": k, "report": report}


def assert_follows(fit, curve, module_size, corner_cut=0.0):
    assert fit["mean"] <= 0.01
    assert fit["start"] <= 0.02 and fit["end"] <= 0.02
    length = float(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum())
    # within one module of the curve (less what a corner's cut takes off)
    assert -module_size - corner_cut <= fit["length"] - length <= module_size
    # the program's own figures agree with this test's fit
    e = fit["report"]["fit_error_fraction_of_size"]
    assert e["mean"] <= 0.01 and abs(e["mean"] - fit["mean"]) <= 0.002


def test_s_curve_of_two_arcs_end_to_end(tmp_path, capsys):
    curve = read_csv(CURVES / "s_curve.csv")
    out, code = design(tmp_path, "s_curve")
    stdout = capsys.readouterr().out
    assert code == 0
    fit = check_chain(out, "s_curve", curve)
    assert_follows(fit, curve, 50.0)
    assert fit["end"] <= 0.005 and fit["mean"] <= 0.002
    assert abs(fit["modules"] - 785.4 / 50) <= 1
    # right first, then left, as drawn
    c = fit["centre"]
    half = len(c) // 2
    assert turn(c[:half + 1]) < -0.5 and turn(c[half:]) > 0.5
    # the headline carries the ends; no circle is fitted to an S
    head = [ln for ln in stdout.splitlines() if "traced final state on the curve" in ln][0]
    assert "ends" in head
    assert "fitted circle" not in stdout
    assert "circle_radius" not in fit["report"]["proportions"]["curve"]


def test_l_with_a_right_angle_is_cut_within_the_tolerance(tmp_path, capsys):
    # two 400 mm legs: 50 mm modules cut the corner 1.1 % off on average and are refused
    # (tests/test_curve_design.py); the refusal names 30 mm modules at the drawing's size
    curve = read_csv(CURVES / "l_corner.csv")
    out, code = design(tmp_path, "l_corner", "--module-size", "30")
    capsys.readouterr()
    assert code == 0
    fit = check_chain(out, "l_corner", curve)
    # the chain turns 90 deg at its fastest (no module size turns tighter than r ~ 122 mm): it
    # cuts the corner along a round of radius r ~ 150 mm at most, shorter than the legs by
    # (2 - pi / 2) r
    assert_follows(fit, curve, 30.0, corner_cut=(2 - math.pi / 2) * 150.0)
    assert 80.0 <= math.degrees(turn(fit["centre"])) <= 100.0  # south, then east: 90 deg left


def test_spiral_turns_the_way_it_is_drawn(tmp_path, capsys):
    # at 50 mm the spiral's inner turn (r = 100 mm: 57 deg per two modules) is too sharp; the
    # drawing 2.2 times larger follows it (the refusal names 30 mm modules at its own size:
    # test_spiral_refused_with_a_suggestion_that_builds)
    curve = read_csv(CURVES / "spiral.csv") * 2.2
    out, code = design(tmp_path, "spiral", "--curve-scale", "2.2")
    capsys.readouterr()
    assert code == 0
    fit = check_chain(out, "spiral", curve)
    assert_follows(fit, curve, 50.0)
    assert fit["mean"] <= 0.002
    # anticlockwise outward, 1.5 turns: the chain winds the same way
    drawn = math.degrees(turn(curve))
    chain = math.degrees(turn(fit["centre"]))
    assert drawn > 540 and abs(chain - drawn) <= 15.0


def test_quadrifolium_enlarged_until_its_cut_tips_fit(tmp_path, capsys):
    # r = 162 sin 2theta mm drawn; its tips (r = 32 mm) are tighter than any module turns
    # (r ~ 122 mm), so the drawing is enlarged until the cut tips fit: 2.9 times with 25 mm
    # modules (its nodes lie 1.6 % off the curve there: the refusal names a larger drawing,
    # test_quadrifolium_refused_with_a_scale_that_builds)
    fit = quadrifolium_follows(tmp_path, capsys, "2.9", "25")
    assert 1.5 <= fit["report"]["drawing_fit_percent_of_size"]["nodes_mean"] <= 1.7


def quadrifolium_follows(tmp_path, capsys, scale, module):
    """The quadrifolium designed at this scale and module size follows its drawing: the
    chain's fit (check_chain)."""
    curve = read_csv(CURVES / "quadrifolium.csv") * float(scale)
    out, code = design(tmp_path, "quadrifolium", "--curve-scale", scale, "--module-size",
                       module)
    stdout = capsys.readouterr().out
    assert code == 0
    fit = check_chain(out, "quadrifolium", curve)
    assert_follows(fit, curve, float(module))
    assert 1000 <= math.degrees(turn(fit["centre"])) <= 1100  # four petals: three turns
    proportions = fit["report"]["proportions"]["curve"]
    assert proportions["closed"] and "chord" not in proportions
    assert "closed" in stdout and "fitted circle" not in stdout
    return fit


@pytest.mark.slow
def test_quadrifolium_refused_with_a_scale_that_builds(tmp_path, capsys):
    out, code = design(tmp_path, "quadrifolium")
    err = capsys.readouterr().err
    assert code == 2
    (line,) = err.strip().splitlines()
    # the whole option set, pasteable: the file, the absolute scale, the module size
    assert "nearest feasible: --curve " in line and " --curve-scale " in line
    options = line.rsplit("nearest feasible: ", 1)[1].split()
    scale = options[options.index("--curve-scale") + 1]
    # 2.9 times (25 mm modules) fits the centre line, but its nodes lie 1.6 % off the curve;
    # 19.9 mm modules put them 13 mm off, within 1 % of the drawing 4 times larger
    assert float(scale) <= 4.5
    fit = quadrifolium_follows(tmp_path / "paste", capsys, scale,
                               options[options.index("--module-size") + 1])
    assert fit["report"]["drawing_fit_percent_of_size"]["nodes_mean"] <= 1.0


@pytest.mark.slow
def test_spiral_refused_with_a_suggestion_that_builds(tmp_path, capsys):
    out, code = design(tmp_path, "spiral")
    err = capsys.readouterr().err
    assert code == 2
    (line,) = err.strip().splitlines()
    # smaller modules cut the inner turn (tighter than any module turns along) closely enough:
    # 30 mm ones at the drawing's own size (test_spiral_at_its_own_size_with_30_mm_modules),
    # but their nodes lie 2.3 % of the size off the curve; the nodes of 19.9 mm modules lie
    # 13.6 mm off it, within 1 % of the drawing 1.6 times larger
    assert line.endswith(f"nearest feasible: --curve {CURVES / 'spiral.csv'} --curve-scale 1.6 "
                         "--module-size 19.9")
    assert not out.exists()
    out, code = design(tmp_path, "spiral", "--curve-scale", "1.6", "--module-size", "19.9")
    assert code == 0
    fit = check_chain(out, "spiral", 1.6 * read_csv(CURVES / "spiral.csv"))
    assert_follows(fit, 1.6 * read_csv(CURVES / "spiral.csv"), 19.9)
    assert fit["report"]["drawing_fit_percent_of_size"]["nodes_mean"] <= 1.0


def test_spiral_at_its_own_size_with_30_mm_modules(tmp_path, capsys):
    out, code = design(tmp_path, "spiral", "--module-size", "30")
    assert code == 0
    fit = check_chain(out, "spiral", read_csv(CURVES / "spiral.csv"))
    # within the tolerance; where the inner turn is cut the chain wavers (69 mm longer than the
    # 2378 mm curve), so the length is not held to a module here
    assert fit["mean"] <= 0.01 and fit["start"] <= 0.02 and fit["end"] <= 0.02
    assert abs(fit["length"] - 2378.1) <= 0.05 * 2378.1
    assert 2.2 <= fit["report"]["drawing_fit_percent_of_size"]["nodes_mean"] <= 2.4


def test_fit_summary_says_only_what_fits_the_curve(tmp_path, capsys):
    # a sine: no circle; an arc: its circle; a straight line: no circle
    x = np.linspace(0.0, 1600.0, 801)
    shapes = {"sine": np.column_stack([x, 150.0 * np.sin(2 * np.pi * x / 800.0)]),
              "line": np.column_stack([np.linspace(0, 600, 7), np.zeros(7)]),
              "arc": np.column_stack([400 * np.cos(np.linspace(0, 1, 300)),
                                      400 * np.sin(np.linspace(0, 1, 300))])}
    for name, pts in shapes.items():
        src = tmp_path / f"{name}.csv"
        src.write_text("x,y\n" + "\n".join(f"{a:.6f},{b:.6f}" for a, b in pts) + "\n")
        assert main(["design", "--curve", str(src), "-o", str(tmp_path / name)]) == 0, name
        stdout = capsys.readouterr().out
        report = json.loads((tmp_path / name / f"{name}_fit.json").read_text())
        curve = report["proportions"]["curve"]
        if name == "arc":
            assert abs(curve["circle_radius"] - 400.0) < 0.5
            assert abs(curve["circle_sweep_deg"] - math.degrees(1.0)) < 0.5
            assert "fitted circle: curve r = 400.00 mm" in stdout
        else:
            assert "circle_radius" not in curve and "fitted circle" not in stdout
        assert report["fit_error_fraction_of_size"]["mean"] <= 0.01
