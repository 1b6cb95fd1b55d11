"""The whole bench study behind ``fabkit bench``: the parts chosen, each run in turn, the
targets judged, and ``DIR/bench/`` written (``bench.json``, the charts, ``stability.md``,
``profile.txt``) once every result exists.

:func:`bench_study` returns a :class:`BenchStudy`, what the command prints its summary from.
Budgets, skips and targets are judged in CPU seconds (``time_s``), so that the verdicts do not
change with the load of a shared machine; the wall seconds of the same work (``wall_s``) are
recorded beside them.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.progress import Progress
from ..io.outputs import inside, OutputFolder
from ..plots.viz import figure_png
from . import (clock_text, cpu_seconds, finite, large, levels as lv, machine_info,
               stability as stab, workprecision as wp)
from .stability import stability_table

__all__ = ["MODES", "PARTS", "CLOCK", "BenchStudy", "bench_study", "comparison_at",
           "point_line", "large_line", "stability_markdown"]

#: Parameters of the two modes.
MODES = {
    "quick": {"sizes": (10, 100, 1000), "budget": 8.0, "repeats": 3, "compare_modules": 300,
              "lyapunov": (1000, 500, 2000),
              "stability": {"super_stable_modules": 8}, "rk4_step": 0.05,
              "horizon_modules": 200, "profile_modules": 1000,
              "large": {"modes": (10, 100, 1000, 10000), "chains": (10, 100, 1000),
                        "lattice": (3, 10, 20, 30),
                        # one repeat; the 10⁵-module traces and the projected comparison are
                        # the full bench's (about a minute on their own)
                        "certified": {"counts": (10000, 100000), "traces": (10000,),
                                      "projected": None, "bundled": 100, "repeats": 1}},
              "levels": {"sizes": (3, 10, 30), "builds": 10}},
    "full": {"sizes": (10, 100, 1000, 10000), "budget": 30.0, "repeats": 3,
             "compare_modules": 300,
             "lyapunov": (1000, 500, 2000), "stability": {}, "rk4_step": 0.02,
             "horizon_modules": 200, "profile_modules": 10000,
             "large": {"modes": (10, 100, 300, 1000, 3000, 10000),
                       "chains": (10, 100, 1000, 10000),
                       "lattice": (3, 10, 20, 30, 50, 70, 100),
                       "certified": {"counts": (10000, 100000, 1_000_000),
                                     "builds": (10000, 100000, 1_000_000),
                                     "info": (100000, 1_000_000),
                                     "traces": (10000, 100000),
                                     "projected": 10000, "bundled": 100000,
                                     "memory": 1_000_000}},
             # k = 100: the 10⁴-cell lattice (one sparse LP a build takes about a minute)
             "levels": {"sizes": (3, 10, 30, 100), "builds": 10}},
}

#: The parts of the study, in the order they run.
PARTS = ("workprecision", "targets", "stability", "large", "levels")

#: What the times of bench.json are (its ``clock``): budgets, skips and targets judge CPU time.
CLOCK = {"time_s": "CPU seconds (user + system, every thread) of the process that did the "
                   "work (getrusage RUSAGE_SELF, the figure of time.process_time; a child "
                   "process's by getrusage RUSAGE_CHILDREN): budgets, skips, fitted exponents "
                   "and targets use these",
         "wall_s": "wall-clock seconds of the same work, for information: they grow with the "
                   "machine's load",
         "elapsed_cpu_s": "CPU seconds of the whole run, this process and its children"}

#: The Lyapunov protocol as the paper states it (starts, transient, iterations): a smaller run
#: records the time the paper's would take, by the count of map evaluations.
PAPER_LYAPUNOV = (1000, 5000, 20000)


@dataclass
class BenchStudy:
    """What one run of the bench measured and wrote.

    Attributes
    ----------
    mode : str
        ``"quick"`` or ``"full"``.
    outdir : Path
        The folder written (``DIR/bench``).
    doc : dict
        The contents of ``bench.json``: every measured point, targets, machine information.
    files : tuple of str
        The names of the files written into ``outdir``.
    scaling : dict
        The fitted exponent of each method (empty without the work-precision part).
    comparison : dict or None
        The best method against ``rk4-nullspace`` (the targets part).
    stability : dict or None
        The stability study (its rows), with the predictability ``horizon``.
    horizon : dict or None
    levels : list or None
        The points of the levels-of-model part.
    """

    mode: str
    outdir: Path
    doc: dict
    files: tuple = ()
    scaling: dict = field(default_factory=dict)
    comparison: dict | None = None
    stability: dict | None = None
    horizon: dict | None = None
    levels: list | None = None


def point_line(p) -> str:
    """One measured point of the work-precision study, in one progress line."""
    t = clock_text(p)
    e = "-" if p["max_edge_error"] is None else f"{p['max_edge_error']:.1e}"
    return f"  {p['modules']:>6} modules  {p['label']:<34} {p['status']:<30} {t:>24}  edge {e}"


def large_line(p) -> str:
    """One measured point of the large-networks part, in one progress line."""
    t = clock_text(p)
    what = p.get("path") or p.get("method")
    extra = p.get("status") or p.get("method") or ""
    err = f"  edge {p['max_edge_error']:.1e} (floor {p['floor']:.1e})" \
        if p.get("max_edge_error") is not None else ""
    counts = f"  counts {p['counts']}" if p.get("counts") else ""
    return (f"  {p['nodes']:>6} nodes  {what:<13} {p['outcome']:<30} {extra:<13} {t:>24}"
            f"{counts}{err}")


def comparison_at(k, points, settings, budget, repeats, rk4_step):
    """Best method against ``rk4-nullspace`` at k modules.

    The dense method is timed per evaluation at 10, 30, 100 and k modules (its scaling, where
    whole runs are over budget; larger sizes are left out once one evaluation takes more than
    the budget of CPU time); its time at k modules is the evaluation measured there times
    the evaluations of its largest finished run with the same step (the count depends on the
    step and the arclength, which for the super-stable chain does not grow with k). Times are
    CPU seconds, with the wall seconds beside them.
    """
    problem = wp.chain_problem(k)
    best = None
    for s in settings:
        if s.method in ("map", "rk4-nullspace"):
            continue
        pt = wp.measure(problem, s, budget, repeats)
        if pt["outcome"] == "ok" and pt["status"] == "finished" and (
                best is None or pt["time_s"] < best["time_s"]):
            best = pt
    evals = []
    for kk in (10, 30, 100, k):
        est = wp.rk4_estimate(kk, rk4_step, 1, repeats=3 if kk < k else 1)
        evals.append({"modules": kk, "nodes": est["nodes"], "evaluation_s": est["evaluation_s"],
                      "evaluation_wall_s": est["evaluation_wall_s"]})
        if est["evaluation_s"] > budget:
            break
    fit = wp.fit_exponent([e["nodes"] for e in evals], [e["evaluation_s"] for e in evals])
    fit_last = wp.fit_exponent([e["nodes"] for e in evals[-2:]],
                               [e["evaluation_s"] for e in evals[-2:]])
    return {"modules": k, "best": best, "rk4": _rk4_estimate(k, points, rk4_step, evals),
            "rk4_evaluations": evals,
            "rk4_evaluation_exponent": fit[0] if fit else None,
            "rk4_evaluation_exponent_largest": fit_last[0] if fit_last else None}


def _rk4_estimate(k, points, rk4_step, evals):
    """The dense method's time at k modules: one evaluation there times the evaluations of its
    largest finished run with the same step (None without such a run, or when the evaluations
    stopped short of k)."""
    rk4_runs = [p for p in points if p["method"] == "rk4-nullspace" and p["outcome"] == "ok"
                and p["options"].get("step") == rk4_step and p["status"] == "finished"]
    if not rk4_runs or evals[-1]["modules"] != k:
        return None
    ref = max(rk4_runs, key=lambda p: p["modules"])
    n_evals = int(ref["stats"].get("evaluations", 0))
    return {"label": f"rk4-nullspace (step={rk4_step:g})", "estimated": True,
            "time_s": n_evals * evals[-1]["evaluation_s"],
            "wall_s": n_evals * evals[-1]["evaluation_wall_s"],
            "evaluation_s": evals[-1]["evaluation_s"],
            "evaluation_wall_s": evals[-1]["evaluation_wall_s"], "evaluations": n_evals,
            "max_edge_error": ref["max_edge_error"],
            "note": f"one dense evaluation measured at {k} modules x the {n_evals} "
                    f"evaluations of the {ref['modules']}-module run with the same step; "
                    "edge error of that run"}


def stability_markdown(study, horizon) -> str:
    """``stability.md``: the stability table and the predictability horizon."""
    lines = ["# Stability study", "", stability_table(study), "## Predictability horizon of the "
             "chaotic chain", "",
             f"{horizon['modules']} chaotic modules built at d1 = {horizon['d1']}, driven by "
             f"{horizon['delta']:g}; exact distances by placement in 60-digit decimal arithmetic. "
             f"Horizon = first module where the error exceeds {horizon['threshold']:g}. "
             f"Lyapunov exponent along the orbit λ = {horizon['lyapunov_orbit']:.4f}; "
             f"ε·e^(λk) reaches the threshold at k = {horizon['expected_horizon']:.1f}.", "",
             "| compared | horizon (modules) | fitted growth rate of the error |", "|---|---|---|"]
    for name, h in list(horizon["methods"].items()) + list(horizon["pairs"].items()):
        hz = "–" if h["horizon"] is None else f"{h['horizon']:.1f}"
        if h["extrapolated"]:
            hz += " (extrapolated)"
        rate = "–" if h["growth_rate"] is None else f"{h['growth_rate']:.3f}"
        label = name if " vs " in name else f"{name} vs exact"
        lines.append(f"| {label} | {hz} | {rate} |")
    return "\n".join(lines) + "\n"


def _jsonable(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return str(v)


class _Run:
    """One run of the study: its configuration, its progress, and what it has measured and
    rendered so far (``doc``, ``files``); each part is one method."""

    def __init__(self, mode, sizes, budget, parts, say):
        self.mode, self.cfg = mode, dict(MODES[mode])
        self.sizes, self.budget, self.parts, self.say = sizes, budget, parts, say
        self.settings = wp.QUICK_SETTINGS if mode == "quick" else wp.FULL_SETTINGS
        self.rk4_step = self.cfg["rk4_step"]
        if not any(s.method == "rk4-nullspace" and s.options.get("step") == self.rk4_step
                   for s in self.settings):
            self.rk4_step = next(s.options["step"] for s in self.settings
                                 if s.method == "rk4-nullspace")
        self.doc = {"command": "fabkit bench" + (" --quick" if mode == "quick" else ""),
                    "mode": mode, "parts": parts, "sizes": list(sizes), "budget_s": budget,
                    "clock": CLOCK, "machine": machine_info()}
        self.files: dict[str, bytes] = {}
        self.points: list = []
        self.scaling: dict = {}
        self.comparison = self.lyapunov = self.study = self.horizon = self.levels = None

    def work_precision(self) -> None:
        say, sizes, budget = self.say, self.sizes, self.budget
        say.stage(f"{self.mode}: work-precision on {', '.join(map(str, sizes))} modules, budget "
                  f"{budget:g} s of CPU per run", total=len(sizes) * len(self.settings),
                  unit="runs")
        self.points = wp.work_precision(sizes, self.settings, budget=budget,
                                        repeats=self.cfg["repeats"],
                                        progress=lambda p: say.advance(text=point_line(p)))
        self.scaling = wp.scaling(self.points)
        self.doc.update(points=self.points, scaling=self.scaling)
        self.files["work_precision.png"] = figure_png(wp.work_precision_figure(self.points))

    def targets(self, quick: bool) -> None:
        say, cfg, budget = self.say, self.cfg, self.budget
        say.stage(f"comparison with rk4-nullspace at {cfg['compare_modules']} modules",
                  total=3, unit="steps")
        self.comparison = comparison_at(cfg["compare_modules"], self.points, self.settings,
                                        budget, cfg["repeats"], self.rk4_step)
        starts, transient, iterations = cfg["lyapunov"]
        say.update(1, text=f"Lyapunov protocol ({starts} x {transient + iterations} map "
                           "iterations)")
        lyap = wp.lyapunov_protocol(starts, transient, iterations)
        if (starts, transient, iterations) != PAPER_LYAPUNOV:
            # the protocol's cost is linear in the number of map evaluations
            paper_starts, paper_transient, paper_iterations = PAPER_LYAPUNOV
            scale = paper_starts * (paper_transient + paper_iterations) / max(
                starts * (transient + iterations), 1)
            lyap["extrapolated_time_s"] = lyap["time_s"] * scale
            lyap["extrapolated_wall_s"] = lyap["wall_s"] * scale
        lib_cfg = (1000, 500, 2000) if quick else PAPER_LYAPUNOV
        say.update(2, text=f"Lyapunov protocol of fabkit.maps ({lib_cfg[0]} x "
                           f"{lib_cfg[1] + lib_cfg[2]})")
        lyap["library"] = wp.maps_lyapunov(*lib_cfg, budget=max(budget, 60.0))
        say.update(3, text="comparison and Lyapunov protocols done")
        self.lyapunov = lyap
        self.doc.update(comparison=self.comparison, lyapunov=lyap)

    def judge_targets(self) -> None:
        self.doc["targets"] = wp.targets(self.points, self.scaling, self.comparison,
                                         self.lyapunov)
        self.files["scaling.png"] = figure_png(wp.scaling_figure(
            self.scaling, self.points,
            self.comparison["rk4_evaluations"] if self.comparison else None))

    def stability(self) -> None:
        say, budget = self.say, self.budget
        say.stage("stability study: building the cases")
        cases = stab.stability_cases(**self.cfg["stability"])
        say.stage("stability study", total=len(cases) * len(stab.study_methods()), unit="runs")
        self.study = stab.stability_study(
            None, budget=max(budget, 30.0), cases=cases,
            progress=lambda r: say.advance(text=f"{r['case']:<20} {r['method']:<14} "
                                                f"{r['class']:<34} {clock_text(r)}"))
        say.stage("predictability horizon of the chaotic chain", total=None)
        self.horizon = stab.predictability_horizon(self.cfg["horizon_modules"],
                                                   budget=max(budget, 30.0))
        self.doc.update(stability=self.study, horizon=self.horizon)
        self.files["failure_cases.png"] = figure_png(stab.failure_figure(self.study,
                                                                         self.horizon))
        self.files["stability.md"] = stability_markdown(self.study, self.horizon).encode()

    def large(self) -> None:
        say, budget, repeats = self.say, self.budget, self.cfg["repeats"]
        lcfg = self.cfg["large"]

        def measured(p):
            say.advance(text=large_line(p))

        say.stage("large networks: count_modes on super-stable chains",
                  total=2 * len(lcfg["modes"]), unit="runs")
        modes = large.count_modes_scaling(lcfg["modes"], budget=budget, repeats=repeats,
                                          progress=measured)
        say.stage("large networks: 4-bar chains, d1 2 -> 2.6", total=2 * len(lcfg["chains"]))
        chains = large.fourbar_chain_points(lcfg["chains"], budget=budget, repeats=repeats,
                                            progress=measured)
        say.stage("large networks: projected on k x k 4-bar lattices",
                  total=len(lcfg["lattice"]))
        lattice = large.lattice_points(lcfg["lattice"], budget=budget, repeats=repeats,
                                       progress=measured)
        self.doc["large"] = {"count_modes": modes, "fourbar_chains": chains, "lattice": lattice}
        self.doc.setdefault("targets", {}).update(large.large_targets(modes, chains))
        if "certified" in lcfg:
            say.stage("large networks: exact counts and linear traces, mirrored super-stable "
                      "chain", total=None)
            cert = large.certified_points(**{"repeats": repeats, **lcfg["certified"]},
                                          budget=max(budget, 60.0),
                                          progress=lambda k, p: say.note(
                                              large.certified_line(k, p)))
            self.doc["large"]["certified"] = cert
            self.doc["targets"].update(large.certified_targets(cert))
        self.files["large_networks.png"] = figure_png(large.large_figure(modes, chains, lattice))

    def levels_of_model(self) -> None:
        vcfg = self.cfg["levels"]
        cases = lv.level_cases(vcfg["sizes"])
        self.say.stage("levels of model: first order, assembly with play, elastic",
                       total=len(cases) * len(lv.LEVELS), unit="runs")
        self.levels = lv.levels_points(cases, builds=vcfg["builds"], budget=self.budget,
                                       progress=lambda p: self.say.advance(
                                           text=lv.levels_line(p)))
        self.doc["levels"] = {"points": self.levels, "builds": vcfg["builds"]}
        self.files["levels.png"] = figure_png(lv.levels_figure(self.levels))

    def profile(self, k: int) -> None:
        self.say.stage(f"profiling projected on {k} modules")
        prof = wp.profile_method(k, "projected")
        self.files["profile.txt"] = prof.pop("text").encode()
        self.doc["profile"] = prof


def bench_study(out_dir, *, quick: bool = False, parts=PARTS, sizes=None,
                budget: float | None = None, profile: bool = False,
                progress: Progress | None = None) -> BenchStudy:
    """Run the bench study and write ``out_dir/bench/``; nothing is written until every result
    exists.

    Parameters
    ----------
    out_dir : path or OutputFolder
        The output folder; the results go to ``out_dir/bench/``. It is held from before the
        work (:class:`~fabkit.io.folder.OutputFolder`) and written through that handle: never
        through a link, never into a folder put in its place meanwhile.
    quick : bool
        The quick mode's sizes, budgets and cases (:data:`MODES`), else the full study's.
    parts : sequence of str
        Some of :data:`PARTS`, checked by the caller.
    sizes : tuple of int or None
        Numbers of modules of the work-precision study (None: the mode's); given, the largest
        is also the chain profiled.
    budget : float or None
        CPU seconds allowed per method, setting and size (None: the mode's).
    profile : bool
        Also profile ``projected`` on the largest chain (``profile.txt``).
    progress : Progress, optional
        Where each stage and measurement is said (default: nowhere).

    Returns
    -------
    BenchStudy
    """
    mode = "quick" if quick else "full"
    cfg = MODES[mode]
    parts = list(parts)
    say = progress if progress is not None else Progress("fabkit bench", show=False)
    held = OutputFolder.open(out_dir)  # one handle, opened before the work (created later)
    outdir = inside(held.path, "bench")
    t_start, cpu_start = time.perf_counter(), cpu_seconds()
    run = _Run(mode, cfg["sizes"] if sizes is None else sizes,
               cfg["budget"] if budget is None else float(budget), parts, say)
    if "workprecision" in parts or "targets" in parts:
        run.work_precision()
    if "targets" in parts:
        run.targets(quick)
    if run.points:
        run.judge_targets()
    if "stability" in parts:
        run.stability()
    if "large" in parts:
        run.large()
    if "levels" in parts:
        run.levels_of_model()
    if profile:
        run.profile(max(sizes) if sizes else cfg["profile_modules"])
    doc = run.doc
    doc["elapsed_s"] = time.perf_counter() - t_start
    doc["elapsed_cpu_s"] = cpu_seconds() - cpu_start
    # everything measured and rendered: only now write
    run.files["bench.json"] = json.dumps(finite(doc), indent=1, default=_jsonable,
                                         allow_nan=False).encode()
    say.stage(f"writing {len(run.files)} files into {outdir}")
    held.write_files({f"bench/{name}": data for name, data in run.files.items()})
    return BenchStudy(mode, Path(outdir), doc, tuple(run.files), run.scaling, run.comparison,
                      run.study, run.horizon, run.levels)
