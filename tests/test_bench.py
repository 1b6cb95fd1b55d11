"""`fabkit bench`: the work-precision study at tiny sizes, the budget, the classification of
outcomes on cases whose truth is known, and the predictability horizon. No timing assertions:
budgets, skips and targets are judged in CPU time, which the tests check by the figures each
measured item carries and by a CPU clock made to run fast, never by how long anything took."""

from __future__ import annotations

import json
import math
import os
import time

import numpy as np
import pytest

from fabkit.bench import ModuleMap, finite, paper_module
from fabkit.bench import stability as stab
from fabkit.bench.workprecision import (SKIPPED, STOPPED, Setting, fit_exponent, run_budgeted,
                                        scaling, targets, work_precision)
from fabkit.cli import main


# -- shared inputs ----------------------------------------------------------------------------
def test_module_map_is_the_fourbar_hyperbola():
    f = ModuleMap(paper_module("fourbar"))
    d1 = np.array([1.0, 1.5, 2.0, 3.0, 4.0])
    assert np.allclose(d1 * f(d1), 4.0, rtol=0, atol=1e-13)
    # outside the motion (below the flat state 2√2 - 2) there is no configuration
    assert np.isnan(f(np.array([0.5]))[0])
    # two copies give back d1
    assert np.allclose(f.iterate(d1, 2)[-1], d1, atol=1e-13)


def test_module_map_matches_the_chain_it_references():
    from fabkit.design.assemble import chain

    ss = paper_module("super_stable")
    net = chain(ss, 5)
    ref = ModuleMap(ss).iterate([float(net.port_distance("d1"))], 5)[:, 0]
    got = [float(net.port_distance(f"d{c + 1}")) for c in range(6)]
    assert np.allclose(got, ref, atol=1e-13)


def test_fit_exponent_recovers_a_power_law():
    n = np.array([10, 100, 1000, 10000])
    p, c = fit_exponent(n, 3e-6 * n ** 1.1)
    assert p == pytest.approx(1.1, abs=1e-12) and c == pytest.approx(3e-6, rel=1e-10)
    assert fit_exponent([10], [1.0]) is None


# -- work-precision at tiny sizes ---------------------------------------------------------------
SETTINGS = (
    Setting("map", {"samples": 21}),
    Setting("constructive", {"samples": 21}),
    Setting("projected", {}),
    Setting("rk4-nullspace", {"step": 0.1}),
)
POINT_KEYS = {"method", "options", "label", "modules", "nodes", "coordinates", "outcome", "status",
              "time_s", "times", "wall_s", "wall_times", "repeats", "configurations",
              "time_per_configuration_s", "max_edge_error", "d_last_error", "d_last_final_error",
              "budget_s"}


def _both_clocks(item, cpu="time_s", wall="wall_s"):
    """A measured item carries its CPU seconds and its wall seconds, both real numbers."""
    assert isinstance(item[cpu], float) and item[cpu] >= 0, item
    assert isinstance(item[wall], float) and item[wall] >= 0, item


@pytest.fixture(scope="module")
def points():
    return work_precision([2, 4], SETTINGS, budget=40.0, repeats=2)


def test_points_have_every_field_and_real_errors(points):
    assert len(points) == 2 * len(SETTINGS)
    for p in points:
        assert POINT_KEYS <= set(p), p["label"]
        assert p["outcome"] == "ok" and p["status"] == "finished", (p["label"], p.get("message"))
        assert 1 <= p["repeats"] <= 2 and p["time_s"] == pytest.approx(np.median(p["times"]))
        # CPU seconds judged, wall seconds beside them: one of each per repeat
        _both_clocks(p)
        assert len(p["wall_times"]) == len(p["times"])
        assert p["wall_s"] == pytest.approx(np.median(p["wall_times"]))
    by = {(p["method"], p["modules"]): p for p in points}
    for k in (2, 4):
        # exact methods keep edges and d_{k+1} to round-off ...
        assert by["constructive", k]["max_edge_error"] < 1e-13
        assert by["constructive", k]["d_last_error"] < 1e-12
        assert by["projected", k]["max_edge_error"] < 1e-12
        assert by["projected", k]["d_last_error"] < 1e-11
        # ... the uncorrected dense RK4 at a coarse step drifts
        assert 1e-9 < by["rk4-nullspace", k]["max_edge_error"] < 1e-3
        # the library's map iteration against the bench's own placement map
        assert by["map", k]["d_last_error"] < 1e-12 and by["map", k]["max_edge_error"] is None
        assert by["constructive", k]["configurations"] == 21
        assert by["constructive", k]["nodes"] == 3 * k + 2
    # the whole study serialises as strict JSON
    json.dumps(points, allow_nan=False)


def test_scaling_uses_the_first_setting_of_each_method(points):
    s = scaling(points)
    assert set(s) == {"map", "constructive", "projected", "rk4-nullspace"}
    assert s["constructive"]["nodes"] == [8, 14]
    assert s["constructive"]["exponent"] is not None


def test_over_budget_runs_are_skipped_with_the_estimate():
    pts = work_precision([2, 40], [Setting("rk4-nullspace", {"step": 0.1})], budget=1e-4,
                         repeats=1)
    # the first run cannot be estimated, so it runs (and exceeds the tiny budget: killed or,
    # if it returns in time, recorded); the next size is never run
    assert pts[1]["outcome"] == SKIPPED
    assert pts[1]["time_s"] is None
    if pts[0]["outcome"] == STOPPED:
        assert "smaller chain" in pts[1]["message"]
    else:
        assert pts[1]["estimated_time_s"] > 1e-4


def test_a_run_over_its_cpu_budget_is_killed_and_marked(tmp_path):
    pid_file = tmp_path / "pid"

    def endless():
        pid_file.write_text(str(os.getpid()))
        while True:
            pass

    # a wall limit no busy machine reaches here: only the CPU budget can stop the run
    outcome, times, info = run_budgeted(endless, lambda r: {}, budget=0.3, grace=0.2, wall=600)
    assert outcome == STOPPED and times == [] and "CPU budget" in info, info
    # not waited on: the run never ends by itself, and it is gone when run_budgeted returns
    pid = int(pid_file.read_text())
    assert pid != os.getpid()
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)


def test_a_run_that_waits_is_stopped_by_the_wall_clock(tmp_path):
    # asleep, a run uses no CPU time: the wall limit is what ends it
    pid_file = tmp_path / "pid"

    def asleep():
        pid_file.write_text(str(os.getpid()))
        time.sleep(3600)

    outcome, times, info = run_budgeted(asleep, lambda r: {}, budget=600, wall=0.5)
    assert outcome == STOPPED and times == [] and "wall time" in info, info
    with pytest.raises(ProcessLookupError):
        os.kill(int(pid_file.read_text()), 0)


class _FastCPUClock:
    """The bench's CPU clock running ``per_call`` seconds ahead at every reading: a machine on
    which the same work costs thousands of times more CPU, while the wall clock runs as usual."""

    def __init__(self, real, per_call):
        self.real, self.per_call, self.calls = real, per_call, 0

    def __call__(self):
        self.calls += 1
        return self.real() + self.per_call * self.calls


def test_budgets_and_skips_follow_the_cpu_clock_not_the_wall_clock(monkeypatch):
    settings = [Setting("constructive", {"samples": 5})]
    quiet = work_precision([2, 3], settings, budget=20, repeats=3)
    assert [p["outcome"] for p in quiet] == ["ok", "ok"]
    # the same work with a CPU clock that says each run took 50 s: one repeat (a second would
    # pass half the budget), and the larger chain is skipped by its estimate from the smaller
    # one; the wall clock (small) decides nothing. The measuring child is forked: it has the
    # same clock.
    from fabkit.bench import own_cpu_seconds, workprecision

    monkeypatch.setattr(workprecision, "own_cpu_seconds", _FastCPUClock(own_cpu_seconds, 50.0))
    costly = work_precision([2, 3], settings, budget=20, repeats=3)
    first, second = costly
    assert first["outcome"] == "ok" and first["repeats"] == 1
    assert first["time_s"] >= 50  # judged: the CPU seconds; the wall seconds stand beside them
    _both_clocks(first)
    assert second["outcome"] == SKIPPED and second["estimated_time_s"] > 20
    assert "estimated" in second["message"]


def test_targets_judge_the_cpu_seconds_not_the_wall_seconds():
    slow_cpu = {**_pt("constructive", 10000, 5.0, 1e-15), "wall_s": 0.5}
    slow_wall = {**_pt("constructive", 10000, 0.5, 1e-15), "wall_s": 5.0}
    goal = targets([slow_cpu], {})["largest_chain"]
    assert not goal["met"] and (goal["time_s"], goal["wall_s"]) == (5.0, 0.5)
    goal = targets([slow_wall], {})["largest_chain"]
    assert goal["met"] and (goal["time_s"], goal["wall_s"]) == (0.5, 5.0)


def test_an_error_in_a_run_is_reported_not_raised():
    outcome, _, info = run_budgeted(lambda: 1 / 0, lambda r: {}, budget=5)
    assert outcome == "error" and "ZeroDivisionError" in info


# -- classification -----------------------------------------------------------------------------
@pytest.mark.parametrize("args, kwargs, expected", [
    (("finish", "finished"), {"edge_error": 1e-15, "ref_error": 1e-14}, stab.FINISHED),
    (("finish", "finished"), {"edge_error": 3e-7, "ref_error": 1e-10}, stab.INACCURATE),
    (("finish", "finished"), {"edge_error": 1e-12, "ref_error": 0.04}, stab.WRONG_BRANCH),
    (("finish", "finished"), {"edge_error": 0.2, "ref_error": 0.04}, stab.DIVERGED),
    (("finish", "finished"), {"edge_error": math.nan}, stab.DIVERGED),
    (("finish", "turning_point"), {"edge_error": 1e-15}, stab.NO_CAUSE),
    (("stop", "turning_point"), {"edge_error": 1e-15, "stop_error": 1e-12}, stab.STOPPED_OK),
    (("stop", "turning_point"), {"edge_error": 1e-15, "stop_error": 0.1}, stab.MISPLACED),
    (("stop", "raised"), {}, stab.STOPPED_OK),
    (("stop", "finished"), {"edge_error": 1e-14}, stab.WRONG_BRANCH),
    (("stop", "finished"), {"edge_error": 0.25}, stab.DIVERGED),
    (("stop", "crashed"), {}, stab.CRASHED),
])
def test_classify(args, kwargs, expected):
    assert stab.classify(*args, **kwargs) == expected


@pytest.fixture(scope="module")
def cases():
    return {c.name: c for c in stab.stability_cases(chaotic_modules=10, super_stable_modules=4)}


def test_cases_have_the_truth_they_claim(cases):
    assert cases["fourbar_flat"].stop_drive == pytest.approx(2 * math.sqrt(2) - 2, abs=1e-14)
    tp = cases["turning_point"]
    assert 0 < tp.facts["start_d1"] - tp.stop_drive < 2e-5  # the turning point hugs the start
    from fabkit.model.rigidity import count_modes

    gate = count_modes(cases["self_stress"].network)
    assert (gate.conformational, gate.self_stress) == (2, 1)
    sheet = count_modes(cases["origami_flat"].network)
    assert sheet.self_stress >= 1 and sheet.conformational >= 2


@pytest.mark.parametrize("name, method, expected", [
    ("fourbar_flat", "constructive", stab.STOPPED_OK),
    ("fourbar_flat", "projected", stab.STOPPED_OK),
    ("turning_point", "constructive", stab.STOPPED_OK),
    ("turning_point_away", "constructive", stab.FINISHED),
    ("origami_flat", "constructive", stab.STOPPED_OK),
    ("super_stable", "constructive", stab.FINISHED),
    ("super_stable", "rk4-nullspace", stab.INACCURATE),
])
def test_known_outcomes(cases, name, method, expected):
    opts = {"step": 0.1} if method == "rk4-nullspace" else None
    row = stab.run_case(cases[name], method, opts, budget=600)  # a guard, not a speed limit
    assert row["class"] == expected, row["message"]
    if expected == stab.STOPPED_OK and row["status"] != "raised":
        assert row["stop_error"] <= cases[name].tol_stop
        if method == "constructive":  # exact placement stops at the end of the motion itself
            assert row["stop_error"] < 1e-9
    if expected == stab.INACCURATE:
        assert 1e-9 < row["edge_error"] < 1e-3  # RK4 without correction drifts off the edges


def test_stability_table_lists_every_row(cases):
    study = stab.stability_study(["constructive"], cases=[cases["fourbar_flat"]], budget=600)
    text = stab.stability_table(study)
    assert "| fourbar_flat | constructive | **stopped with a correct report** |" in text
    (row,) = study["rows"]
    _both_clocks(row)
    assert "| CPU s (wall s) |" in text
    json.dumps(finite(study), allow_nan=False)


# -- chaos ----------------------------------------------------------------------------------------
def test_decimal_map_agrees_with_float_map_before_the_horizon():
    f = ModuleMap(paper_module("chaotic"))
    exact = stab.decimal_map(f, 0.9, 40)
    approx = f.iterate([0.9], 40)[:, 0]
    err = np.abs(exact - approx)
    assert err[:5].max() < 1e-14
    assert 1e-13 < err[30:].max() < 1e-6  # round-off has grown by orders of magnitude


def test_predictability_horizon_small():
    h = stab.predictability_horizon(80, projected_modules=20, threshold=1e-8)
    assert 0.2 < h["lyapunov_orbit"] < 0.45
    assert set(h["methods"]) == {"map", "constructive", "projected"}
    m = h["methods"]["map"]
    assert m["horizon"] is not None and 30 < m["horizon"] < 90
    assert m["growth_rate"] == pytest.approx(h["lyapunov_orbit"], abs=0.15)


# -- command line -------------------------------------------------------------------------------
def test_cli_rejects_bad_options(capsys):
    assert main(["bench", "--sizes", "ten"]) == 2  # usage errors, before any measurement
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--sizes: must be comma-separated integers" in err[0]
    assert main(["bench", "--parts", "charts"]) == 2
    assert main(["bench", "--budget", "0"]) == 2


def test_cli_workprecision_part_writes_charts_and_json(tmp_path):
    rc = main(["bench", "--quick", "--sizes", "2,3", "--budget", "30", "--parts",
               "workprecision", "-o", str(tmp_path)])
    assert rc == 0
    out = tmp_path / "bench"
    assert sorted(p.name for p in out.iterdir()) == ["bench.json", "scaling.png",
                                                    "work_precision.png"]
    for png in ("scaling.png", "work_precision.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    doc = json.loads((out / "bench.json").read_text())
    assert {"machine", "points", "scaling", "targets", "sizes", "budget_s"} <= set(doc)
    assert doc["sizes"] == [2, 3]
    assert {p["modules"] for p in doc["points"]} == {2, 3}
    assert doc["machine"]["cpu_count"] >= 1
    # every measured point: its CPU seconds (judged) and its wall seconds (information)
    measured = [p for p in doc["points"] if p["outcome"] == "ok"]
    assert measured
    for p in measured:
        _both_clocks(p)
    assert {"time_s", "wall_s"} <= set(doc["targets"]["largest_chain"])
    assert set(doc["clock"]) >= {"time_s", "wall_s"} and "CPU" in doc["clock"]["time_s"]
    _both_clocks(doc, "elapsed_cpu_s", "elapsed_s")


def test_the_quick_bench_states_one_time_everywhere(capsys):
    import re
    from pathlib import Path

    from fabkit.commands import bench

    figure = re.search(r"--quick finishes in about (\d+ s) ", bench.DESCRIPTION).group(1)
    try:
        main(["bench", "--help"])
    except SystemExit:
        pass
    helped = " ".join(capsys.readouterr().out.split())
    assert f"(about {figure} on a quiet 2-core machine)" in helped
    root = Path(__file__).resolve().parents[1]
    assert f"`--quick` about {figure})" in (root / "README.md").read_text()
    assert re.search(rf"fabkit bench --quick +# .*\(about {figure}\)",
                     (root / "docs" / "bench.md").read_text())


# -- targets -------------------------------------------------------------------------------------
def _pt(method, k, t, edge, dlast=0.0, status="finished"):
    return {"method": method, "label": f"{method} (x)", "modules": k, "nodes": 3 * k + 2,
            "outcome": "ok", "status": status, "time_s": t, "time_per_configuration_s": t / 10,
            "configurations": 10, "max_edge_error": edge, "d_last_error": dlast, "options": {}}


def test_targets_judge_the_measured_figures():
    from fabkit.bench.workprecision import targets

    pts = [_pt("constructive", 100, 0.1, 1e-15), _pt("constructive", 10000, 0.8, 1e-15),
           _pt("projected", 10000, 5.0, 1e-14), _pt("rk4-nullspace", 100, 0.05, 1e-6),
           _pt("rk4-nullspace", 100, 3.0, 1e-9)]
    goals = targets(pts, scaling(pts))
    assert goals["largest_chain"]["met"] and goals["largest_chain"]["time_s"] == 0.8
    # the cheap rk4 run (0.05 s) has no rival as fast: reported as an exception
    assert not goals["dominates_rk4"]["met"]
    assert goals["dominates_rk4"]["exceptions"] == ["rk4-nullspace (x) at 100 modules"]
    goals = targets([_pt("constructive", 10000, 1.5, 1e-15)], {})
    assert not goals["largest_chain"]["met"]


def test_library_lyapunov_is_timed():
    from fabkit.bench.workprecision import maps_lyapunov

    res = maps_lyapunov(200, 100, 400, budget=60)
    assert res is not None  # fabkit.maps is part of the package: the bench must time it
    assert res["outcome"] == "ok" and res["time_s"] > 0
    _both_clocks(res)
    assert res["exponent"] == pytest.approx(0.312, abs=0.02)  # the paper's λ ≈ 0.312


def test_cli_levels_part_compares_the_levels_of_a_build(tmp_path, capsys):
    # the first-order test (basis and sparse LP) against the nonlinear assembly on the AND gate
    # and 3x3, 10x10, 30x30 lattices: the same verdict on every build; the elastic level forces
    # every build together and names its stress
    rc = main(["bench", "--quick", "--parts", "levels", "-o", str(tmp_path)])
    assert rc == 0
    out = tmp_path / "bench"
    assert sorted(p.name for p in out.iterdir()) == ["bench.json", "levels.png"]
    doc = json.loads((out / "bench.json").read_text())
    points = doc["levels"]["points"]
    assert {p["case"] for p in points} == {"AND gate", "lattice 3x3", "lattice 10x10",
                                          "lattice 30x30"}
    first = [p for p in points if p["level"].startswith("first order") and p["builds"]]
    assert first and all(p["agrees"] == 1.0 for p in first)
    # the dense basis is left out where its SVD alone would pass the budget (30x30: 2730 bars)
    skipped = [p for p in points if p["seconds_per_build"] is None]
    assert [(p["case"], p["level"]) for p in skipped] == [("lattice 30x30", "first order (basis)")]
    for p in points:
        if p not in skipped:
            _both_clocks(p, "seconds_per_build", "wall_seconds_per_build")
    gate = {p["level"]: p for p in points if p["case"] == "AND gate"}
    assert gate["first order (basis)"]["self_stresses"] == 1
    assert 0 < gate["elastic, no play"]["max_stress_mpa"] < 15
    assert "levels  AND gate" in capsys.readouterr().out
