"""``fabkit bench [-o DIR] [--quick]``: speed against accuracy of the tracing methods.

Writes ``DIR/bench/``: ``work_precision.png``, ``scaling.png`` (fitted exponents),
``stability.md`` (the stability table with its evidence), ``failure_cases.png``, ``bench.json``
(every measured point, the targets, machine information) and, with ``--profile``,
``profile.txt``. Nothing is written until every result exists. Each measurement, as it ends,
is a progress line on stderr (:mod:`fabkit.commands.progress`); the summary goes to stdout.

Budgets, skips and targets are judged in CPU seconds (``time_s``), so that the verdicts do not
change with the load of a shared machine; the wall seconds of the same work (``wall_s``) are
shown and recorded beside them.
"""

from __future__ import annotations

import json
import sys
import time

from ..bench import (clock_text, cpu_seconds, finite, levels as lv, machine_info,
                     stability as stab)
from ..bench.stability import stability_table
from ..bench.workprecision import chain_problem, fit_exponent, measure, rk4_estimate
from ..errors import UsageError
from ..io.outputs import inside, write_files
from ..plots.viz import figure_png
from . import add_out_dir, add_progress_options, check_count, check_number, Example, progress_for

NAME = "bench"
HELP = "speed against accuracy: work-precision and scaling charts, stability study"
DESCRIPTION = (
    "Time every tracing method against its accuracy on chains of 10 to 10 000 super-stable "
    "modules, fit how the time grows with size, and run the stability study where methods fail. "
    "--quick finishes in about 40 s on a quiet 2-core machine.")

EXAMPLES = [
    Example("fabkit bench --quick --parts workprecision --sizes 3 --budget 5 -o out/bench-tiny",
            "one tiny chain, every method timed: the charts and bench.json"),
    Example("fabkit bench --quick",
            "speed against accuracy and the stability study, small sizes", cheap=False),
    Example("fabkit bench -o out --profile",
            "the full study, and a profile of 'projected' on the largest chain", cheap=False),
]

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
                       "certified": {"counts": (10000, 100000), "traces": (10000, 100000),
                                     "projected": 10000, "bundled": 100000}},
             # k = 100: the 10⁴-cell lattice (one sparse LP a build takes about a minute)
             "levels": {"sizes": (3, 10, 30, 100), "builds": 10}},
}


def add_arguments(p):
    add_out_dir(p, "out", "output folder (default: out); results go to DIR/bench/")
    p.add_argument("--quick", action="store_true",
                   help="small sizes and budgets (about 40 s on a quiet 2-core machine)")
    p.add_argument("--budget", type=float, default=None,
                   help="CPU seconds allowed per method, setting and size (default 30; quick "
                        "8): CPU time, not wall time, so that a busy machine changes no verdict")
    p.add_argument("--sizes", default=None,
                   help="comma-separated numbers of modules (default 10,100,1000,10000)")
    p.add_argument("--parts", default="workprecision,targets,stability,large,levels",
                   help="comma-separated parts to run: workprecision (charts), targets (rk4 "
                        "comparison at 300 modules, Lyapunov protocol), stability (table, "
                        "failure cases, horizon), large (mode counting and projected on large "
                        "chains and a 2D lattice), levels (a build's levels of model: first "
                        "order, assembly with play, elastic; the AND gate and 4-bar lattices); "
                        "default all")
    p.add_argument("--profile", action="store_true",
                   help="also profile 'projected' on the largest chain (profile.txt)")
    add_progress_options(p)


#: What the times of bench.json are (its ``clock``): budgets, skips and targets judge CPU time.
CLOCK = {"time_s": "CPU seconds (user + system, every thread) of the process that did the "
                   "work (getrusage RUSAGE_SELF, the figure of time.process_time; a child "
                   "process's by getrusage RUSAGE_CHILDREN): budgets, skips, fitted exponents "
                   "and targets use these",
         "wall_s": "wall-clock seconds of the same work, for information: they grow with the "
                   "machine's load",
         "elapsed_cpu_s": "CPU seconds of the whole run, this process and its children"}

#: Largest chain in the work-precision study without ``--allow-large`` (the full bench's own).
MAX_BENCH_MODULES = 10_000


def _sizes(text):
    try:
        sizes = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise UsageError("--sizes", f"must be comma-separated integers, got {text!r}") from None
    if not sizes or min(sizes) < 1:
        raise UsageError("--sizes", f"must list positive numbers of modules, got {text!r}")
    check_count("--sizes", max(sizes), 1, MAX_BENCH_MODULES, "modules")
    return sizes


def _point_line(p):
    t = clock_text(p)
    e = "-" if p["max_edge_error"] is None else f"{p['max_edge_error']:.1e}"
    return f"  {p['modules']:>6} modules  {p['label']:<34} {p['status']:<30} {t:>24}  edge {e}"


def comparison_at(k, points, settings, budget, repeats, rk4_step):
    """Best method against ``rk4-nullspace`` at k modules.

    The dense method is timed per evaluation at 10, 30, 100 and k modules (its scaling, where
    whole runs are over budget; larger sizes are left out once one evaluation takes more than
    the budget of CPU time); its time at k modules is the evaluation measured there times
    the evaluations of its largest finished run with the same step (the count depends on the
    step and the arclength, which for the super-stable chain does not grow with k). Times are
    CPU seconds, with the wall seconds beside them.
    """
    problem = chain_problem(k)
    best = None
    for s in settings:
        if s.method in ("map", "rk4-nullspace"):
            continue
        pt = measure(problem, s, budget, repeats)
        if pt["outcome"] == "ok" and pt["status"] == "finished" and (
                best is None or pt["time_s"] < best["time_s"]):
            best = pt
    evals = []
    for kk in (10, 30, 100, k):
        est = rk4_estimate(kk, rk4_step, 1, repeats=3 if kk < k else 1)
        evals.append({"modules": kk, "nodes": est["nodes"], "evaluation_s": est["evaluation_s"],
                      "evaluation_wall_s": est["evaluation_wall_s"]})
        if est["evaluation_s"] > budget:
            break
    fit = fit_exponent([e["nodes"] for e in evals], [e["evaluation_s"] for e in evals])
    fit_last = fit_exponent([e["nodes"] for e in evals[-2:]],
                            [e["evaluation_s"] for e in evals[-2:]])
    rk4_runs = [p for p in points if p["method"] == "rk4-nullspace" and p["outcome"] == "ok"
                and p["options"].get("step") == rk4_step and p["status"] == "finished"]
    rk4 = None
    if rk4_runs and evals[-1]["modules"] == k:
        ref = max(rk4_runs, key=lambda p: p["modules"])
        n_evals = int(ref["stats"].get("evaluations", 0))
        rk4 = {"label": f"rk4-nullspace (step={rk4_step:g})", "estimated": True,
               "time_s": n_evals * evals[-1]["evaluation_s"],
               "wall_s": n_evals * evals[-1]["evaluation_wall_s"],
               "evaluation_s": evals[-1]["evaluation_s"],
               "evaluation_wall_s": evals[-1]["evaluation_wall_s"], "evaluations": n_evals,
               "max_edge_error": ref["max_edge_error"],
               "note": f"one dense evaluation measured at {k} modules x the {n_evals} "
                       f"evaluations of the {ref['modules']}-module run with the same step; "
                       "edge error of that run"}
    return {"modules": k, "best": best, "rk4": rk4, "rk4_evaluations": evals,
            "rk4_evaluation_exponent": fit[0] if fit else None,
            "rk4_evaluation_exponent_largest": fit_last[0] if fit_last else None}


PARTS = ("workprecision", "targets", "stability", "large", "levels")


def _parts(text):
    parts = [v.strip() for v in text.split(",") if v.strip()]
    bad = [v for v in parts if v not in PARTS]
    if bad or not parts:
        raise UsageError("--parts", f"must name some of {', '.join(PARTS)}, got {text!r}")
    return parts


def run(args) -> int:
    from ..bench.workprecision import (FULL_SETTINGS, QUICK_SETTINGS, lyapunov_protocol,
                                       maps_lyapunov, profile_method, scaling, scaling_figure,
                                       targets, work_precision, work_precision_figure)

    import signal

    # a terminated bench stops its measuring child process too (cleanup runs on SystemExit)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    mode = "quick" if args.quick else "full"
    cfg = dict(MODES[mode])
    # every option is checked before the first measurement
    sizes = _sizes(args.sizes) if args.sizes is not None else cfg["sizes"]
    budget = cfg["budget"] if args.budget is None else float(args.budget)
    check_number("--budget", budget)
    parts = _parts(args.parts)
    settings = QUICK_SETTINGS if args.quick else FULL_SETTINGS
    rk4_step = cfg["rk4_step"]
    if not any(s.method == "rk4-nullspace" and s.options.get("step") == rk4_step
               for s in settings):
        rk4_step = next(s.options["step"] for s in settings if s.method == "rk4-nullspace")
    # checked before the work and again when writing: never through a link out of -o
    outdir = inside(args.out_dir, "bench")
    say = progress_for(args, NAME)
    t_start, cpu_start = time.perf_counter(), cpu_seconds()
    doc = {"command": "fabkit bench" + (" --quick" if args.quick else ""), "mode": mode,
           "parts": parts, "sizes": list(sizes), "budget_s": budget, "clock": CLOCK,
           "machine": machine_info()}
    files = {}

    points, scal = [], {}
    if "workprecision" in parts or "targets" in parts:
        say.stage(f"{mode}: work-precision on {', '.join(map(str, sizes))} modules, budget "
                  f"{budget:g} s of CPU per run", total=len(sizes) * len(settings), unit="runs")
        points = work_precision(sizes, settings, budget=budget, repeats=cfg["repeats"],
                                progress=lambda p: say.advance(text=_point_line(p)))
        scal = scaling(points)
        doc.update(points=points, scaling=scal)
        files["work_precision.png"] = figure_png(work_precision_figure(points))

    comparison = lyap = None
    if "targets" in parts:
        say.stage(f"comparison with rk4-nullspace at {cfg['compare_modules']} modules",
                  total=3, unit="steps")
        comparison = comparison_at(cfg["compare_modules"], points, settings, budget,
                                   cfg["repeats"], rk4_step)
        starts, transient, iterations = cfg["lyapunov"]
        say.update(1, text=f"Lyapunov protocol ({starts} x {transient + iterations} map "
                           "iterations)")
        lyap = lyapunov_protocol(starts, transient, iterations)
        if (starts, transient, iterations) != (1000, 5000, 20000):
            # the protocol's cost is linear in the number of map evaluations
            scale = 1000 * (5000 + 20000) / max(starts * (transient + iterations), 1)
            lyap["extrapolated_time_s"] = lyap["time_s"] * scale
            lyap["extrapolated_wall_s"] = lyap["wall_s"] * scale
        lib_cfg = (1000, 500, 2000) if args.quick else (1000, 5000, 20000)
        say.update(2, text=f"Lyapunov protocol of fabkit.maps ({lib_cfg[0]} x "
                           f"{lib_cfg[1] + lib_cfg[2]})")
        lyap["library"] = maps_lyapunov(*lib_cfg, budget=max(budget, 60.0))
        say.update(3, text="comparison and Lyapunov protocols done")
        doc.update(comparison=comparison, lyapunov=lyap)
    if points:
        doc["targets"] = targets(points, scal, comparison, lyap)
        files["scaling.png"] = figure_png(scaling_figure(
            scal, points, comparison["rk4_evaluations"] if comparison else None))

    study = horizon = None
    if "stability" in parts:
        say.stage("stability study: building the cases")
        cases = stab.stability_cases(**cfg["stability"])
        say.stage("stability study", total=len(cases) * len(stab.study_methods()), unit="runs")
        study = stab.stability_study(
            None, budget=max(budget, 30.0), cases=cases,
            progress=lambda r: say.advance(text=f"{r['case']:<20} {r['method']:<14} "
                                                f"{r['class']:<34} {clock_text(r)}"))
        say.stage("predictability horizon of the chaotic chain", total=None)
        horizon = stab.predictability_horizon(cfg["horizon_modules"], budget=max(budget, 30.0))
        doc.update(stability=study, horizon=horizon)
        files["failure_cases.png"] = figure_png(stab.failure_figure(study, horizon))
        files["stability.md"] = _stability_markdown(study, horizon).encode()

    if "large" in parts:
        from ..bench import large

        lcfg = cfg["large"]
        def measured(p):
            say.advance(text=_large_line(p))

        say.stage("large networks: count_modes on super-stable chains",
                  total=2 * len(lcfg["modes"]), unit="runs")
        modes = large.count_modes_scaling(lcfg["modes"], budget=budget, repeats=cfg["repeats"],
                                          progress=measured)
        say.stage("large networks: 4-bar chains, d1 2 -> 2.6", total=2 * len(lcfg["chains"]))
        chains = large.fourbar_chain_points(lcfg["chains"], budget=budget,
                                            repeats=cfg["repeats"], progress=measured)
        say.stage("large networks: projected on k x k 4-bar lattices",
                  total=len(lcfg["lattice"]))
        lattice = large.lattice_points(lcfg["lattice"], budget=budget, repeats=cfg["repeats"],
                                       progress=measured)
        doc["large"] = {"count_modes": modes, "fourbar_chains": chains, "lattice": lattice}
        doc.setdefault("targets", {}).update(large.large_targets(modes, chains))
        if "certified" in lcfg:
            say.stage("large networks: exact counts and linear traces, mirrored super-stable "
                      "chain", total=None)
            cert = large.certified_points(**{"repeats": cfg["repeats"], **lcfg["certified"]},
                                          budget=max(budget, 60.0),
                                          progress=lambda k, p: say.note(
                                              large.certified_line(k, p)))
            doc["large"]["certified"] = cert
            doc["targets"].update(large.certified_targets(cert))
        files["large_networks.png"] = figure_png(large.large_figure(modes, chains, lattice))

    levels = None
    if "levels" in parts:
        vcfg = cfg["levels"]
        cases = lv.level_cases(vcfg["sizes"])
        say.stage("levels of model: first order, assembly with play, elastic",
                  total=len(cases) * len(lv.LEVELS), unit="runs")
        levels = lv.levels_points(cases, builds=vcfg["builds"], budget=budget,
                                  progress=lambda p: say.advance(text=lv.levels_line(p)))
        doc["levels"] = {"points": levels, "builds": vcfg["builds"]}
        files["levels.png"] = figure_png(lv.levels_figure(levels))

    if args.profile:
        k = max(sizes) if args.sizes else cfg["profile_modules"]
        say.stage(f"profiling projected on {k} modules")
        prof = profile_method(k, "projected")
        files["profile.txt"] = prof.pop("text").encode()
        doc["profile"] = prof

    doc["elapsed_s"] = time.perf_counter() - t_start
    doc["elapsed_cpu_s"] = cpu_seconds() - cpu_start
    # everything measured and rendered: only now write
    files["bench.json"] = json.dumps(finite(doc), indent=1, default=_jsonable,
                                     allow_nan=False).encode()
    say.stage(f"writing {len(files)} files into {outdir}")
    write_files(args.out_dir, {f"bench/{name}": data for name, data in files.items()})
    say.close()

    print(f"fabkit bench ({mode}) -> {outdir}  ({doc['elapsed_cpu_s']:.0f} s of CPU, "
          f"{doc['elapsed_s']:.0f} s wall)")
    for s in scal.values():
        e = "-" if s["exponent"] is None else f"{s['exponent']:.2f}"
        e2 = "-" if s.get("exponent_largest") is None else f"{s['exponent_largest']:.2f}"
        print(f"  scaling   {s['label']:<34} time per configuration ~ N^{e} "
              f"(between the two largest sizes N^{e2})")
    if comparison and comparison.get("rk4_evaluation_exponent") is not None:
        print(f"  scaling   rk4-nullspace, one dense evaluation        ~ "
              f"N^{comparison['rk4_evaluation_exponent']:.2f} (between the two largest sizes "
              f"N^{comparison['rk4_evaluation_exponent_largest']:.2f}; "
              + ", ".join(f"{e['nodes']} nodes "
                          + clock_text(e, "evaluation_s", "evaluation_wall_s")
                          for e in comparison["rk4_evaluations"]) + ")")
    for name, g in doc.get("targets", {}).items():
        figures = {k: v for k, v in g.items() if k not in ("target", "met")}
        shown = ", ".join(f"{k}={_short(v)}" for k, v in figures.items())
        verdict = "met" if g["met"] else (
            "NOT met" if any(v is not None for v in figures.values()) else "not measured")
        print(f"  target    {name:<22} {verdict}: {g['target']} [{shown}]")
    for p in levels or ():
        print("  levels  " + lv.levels_line(p).strip())
    if study is not None:
        counts = {}
        for r in study["rows"]:
            counts.setdefault(r["method"], {}).setdefault(r["class"], 0)
            counts[r["method"]][r["class"]] += 1
        for m, c in counts.items():
            print(f"  stability {m:<14} " + ", ".join(f"{v} {k}" for k, v in c.items()))
        print(f"  horizon   chaotic chain, λ = {horizon['lyapunov_orbit']:.3f}: " + ", ".join(
            f"{m} {('-' if h['horizon'] is None else format(h['horizon'], '.0f'))}"
            f"{' (extrapolated)' if h['extrapolated'] else ''}"
            for m, h in horizon["methods"].items()) + " modules")
    return 0


def _large_line(p):
    t = clock_text(p)
    what = p.get("path") or p.get("method")
    extra = p.get("status") or p.get("method") or ""
    err = f"  edge {p['max_edge_error']:.1e} (floor {p['floor']:.1e})" \
        if p.get("max_edge_error") is not None else ""
    counts = f"  counts {p['counts']}" if p.get("counts") else ""
    return (f"  {p['nodes']:>6} nodes  {what:<13} {p['outcome']:<30} {extra:<13} {t:>24}"
            f"{counts}{err}")


def _short(v):
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, list):
        return f"[{len(v)} items]" if len(v) > 3 else str(v)
    return str(v)


def _stability_markdown(study, horizon) -> str:
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
    import numpy as np

    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return str(v)
