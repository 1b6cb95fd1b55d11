"""``fabkit bench [-o DIR] [--quick]``: speed against accuracy of the tracing methods.

Writes ``DIR/bench/``: ``work_precision.png``, ``scaling.png`` (fitted exponents),
``stability.md`` (the stability table with its evidence), ``failure_cases.png``, ``bench.json``
(every measured point, the targets, machine information) and, with ``--profile``,
``profile.txt``. Nothing is written until every result exists. Each measurement, as it ends,
is a progress line on stderr (:mod:`fabkit.io.progress`); the summary goes to stdout.

Budgets, skips and targets are judged in CPU seconds (``time_s``), so that the verdicts do not
change with the load of a shared machine; the wall seconds of the same work (``wall_s``) are
shown and recorded beside them.

This module only reads the command line and prints; the study (its parts, budgets, targets and
files) is :func:`fabkit.bench.study.bench_study`.
"""

from __future__ import annotations

import signal
import sys

from ..bench import clock_text, levels as lv
from ..bench.study import bench_study, BenchStudy, MODES, PARTS
from ..errors import UsageError
from . import (add_out_dir, add_progress_options, check_count, check_number, Example,
               out_folder, progress_for)

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


def _parts(text):
    parts = [v.strip() for v in text.split(",") if v.strip()]
    bad = [v for v in parts if v not in PARTS]
    if bad or not parts:
        raise UsageError("--parts", f"must name some of {', '.join(PARTS)}, got {text!r}")
    return parts


def run(args) -> int:
    # a terminated bench stops its measuring child process too (cleanup runs on SystemExit)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    cfg = MODES["quick" if args.quick else "full"]
    # every option is checked before the first measurement
    sizes = _sizes(args.sizes) if args.sizes is not None else None
    budget = cfg["budget"] if args.budget is None else float(args.budget)
    check_number("--budget", budget)
    parts = _parts(args.parts)
    say = progress_for(args, NAME)
    result = bench_study(out_folder(args), quick=args.quick, parts=parts, sizes=sizes,
                         budget=budget, profile=args.profile, progress=say)
    say.close()
    print_summary(result)
    return 0


# --- the summary on stdout -------------------------------------------------------------------

def print_summary(result: BenchStudy) -> None:
    """What the run measured, in a few lines: the fitted exponents, the targets, the levels
    of model, the stability classes and the predictability horizon."""
    doc = result.doc
    print(f"fabkit bench ({result.mode}) -> {result.outdir}  ({doc['elapsed_cpu_s']:.0f} s of "
          f"CPU, {doc['elapsed_s']:.0f} s wall)")
    _print_scaling(result.scaling, result.comparison)
    _print_targets(doc.get("targets", {}))
    for p in result.levels or ():
        print("  levels  " + lv.levels_line(p).strip())
    if result.stability is not None:
        _print_stability(result.stability, result.horizon)


def _print_scaling(scal, comparison) -> None:
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


def _print_targets(targets) -> None:
    for name, g in targets.items():
        figures = {k: v for k, v in g.items() if k not in ("target", "met")}
        shown = ", ".join(f"{k}={_short(v)}" for k, v in figures.items())
        verdict = "met" if g["met"] else (
            "NOT met" if any(v is not None for v in figures.values()) else "not measured")
        print(f"  target    {name:<22} {verdict}: {g['target']} [{shown}]")


def _print_stability(study, horizon) -> None:
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


def _short(v):
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, list):
        return f"[{len(v)} items]" if len(v) > 3 else str(v)
    return str(v)
