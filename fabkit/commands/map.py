"""``fabkit map TEMPLATE``: a module's map d2 = f(d1), its cobweb diagram and a JSON summary."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import FabkitError, UsageError
from ..io.outputs import inside, write_files
from ..io.workload import require
from ..numerics import DOMAIN_RTOL
from ..plots.viz import figure_png
from . import (out_folder, add_out_dir, add_progress_options, add_settings, check_count, each_template,
               Example, progress_for)
from ..io.progress import Progress
from .settings import read_settings

#: Bounds on the options (``fabkit --allow-large`` lifts them): a cycle of period m is searched
#: on f composed m times, whose roots grow with m; orbits and iterations cost one map evaluation
#: each.
MAX_PERIOD = 24
MAX_STEPS = 100_000
MAX_ORBITS = 100_000
MAX_ITERATIONS = 10_000_000
MAX_D1 = 1_000  #: cobweb orbits drawn in one picture

#: Defaults of the Lyapunov protocol (the paper's supplement): orbits, discarded, averaged.
LYAPUNOV_DEFAULTS = {"orbits": 1000, "discard": 5000, "average": 20000}

NAME = "map"
HELP = "a module's iterated map: map.png, cobweb.png and map.json (fixed points, cycles, λ)"
DESCRIPTION = (
    "Compute the map d2 = f(d1) of a module template on the branch through its start "
    "configuration: fixed points with slopes and stability, cycles, optionally the Lyapunov "
    "exponent. Writes DIR/<name>/map.png, cobweb.png, map.json (and lyapunov.png, design.png).")

EXAMPLES = [
    Example("fabkit map fourbar", "f(d) = 4/d: its fixed point 2, the cobweb; out/fourbar/"),
    Example("fabkit map chaotic --lyapunov --orbits 50 --discard 500 --average 2000",
            "the chaotic module's exponent, with a shorter protocol"),
    Example("fabkit map chaotic --lyapunov -o out/maps",
            "the paper's protocol: 1000 orbits, 5000 discarded, 20000 averaged", cheap=False),
]


def add_arguments(p):
    p.add_argument("templates", nargs="+", metavar="TEMPLATE", help="module template file(s)")
    p.add_argument("--d1", default=None, metavar="VALUES",
                   help="comma-separated initial d1 values for the cobweb (default: the fixed "
                        "points and a value between them)")
    p.add_argument("--steps", type=int, default=16, help="iterations in the cobweb (default 16)")
    p.add_argument("--period", type=int, action="append", default=None, metavar="M",
                   help="look for cycles of this period (repeatable; default 2)")
    p.add_argument("--d-in", dest="d_in", default="d1", metavar="PORT",
                   help="input port (default d1)")
    p.add_argument("--d-out", dest="d_out", default="d2", metavar="PORT",
                   help="output port (default d2)")
    p.add_argument("--lyapunov", action="store_true",
                   help="compute Lyapunov exponents (1000 orbits, 5000 discarded, 20000 averaged)")
    p.add_argument("--orbits", type=int, default=None,
                   help="orbits for --lyapunov (default 1000)")
    p.add_argument("--discard", type=int, default=None,
                   help="discarded iterations for --lyapunov (default 5000)")
    p.add_argument("--average", type=int, default=None,
                   help="averaged iterations for --lyapunov (default 20000)")
    add_out_dir(p, "out", "output folder (default: out); results go to DIR/<name>/",
                ambiguous="could mean two things here: the output folder is -o/--out-dir DIR, "
                          "the map's output port --d-out PORT")
    add_settings(p, "override a motion setting, e.g. --set motion.to=2.9 (repeatable)")
    add_progress_options(p)


def parse_values(text: str) -> list[float]:
    """``"1.8, 2.0"`` -> [1.8, 2.0], with a one-line error naming the bad entry."""
    out = []
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        try:
            v = float(item)
        except ValueError:
            raise UsageError("--d1", f"{item!r} is not a number (give comma-separated values, "
                                     "e.g. --d1 1.8,2.0)") from None
        if not np.isfinite(v):
            raise UsageError("--d1", f"{item!r} is not a finite number")
        out.append(v)
    if not out:
        raise UsageError("--d1", "no values given (e.g. --d1 1.8,2.0)")
    return out


def map_design(design, outdir: Path, *, d1=None, steps=16, periods=(2,), lyapunov=False,
               orbits=1000, discard=5000, average=20000, d_in="d1", d_out="d2",
               progress=None) -> dict:
    """Compute everything for one template and write its files; returns the summary.
    ``progress``: a :class:`~fabkit.io.progress.Progress` told each stage."""
    from ..plots.mapplots import cobweb_figure, lyapunov_figure, map_figure, solution_space_figure
    from ..maps.of_design import cobweb_starts, map_of  # scipy: not for every --help

    progress = progress or Progress("", show=False)
    inside(outdir, design.name)  # before the work: a name that would leave it is refused
    progress.stage(f"{design.name}: the map")
    fmap = map_of(design, d_in, d_out)
    progress.stage(f"{design.name}: fixed points and cycles")
    fixed = fmap.fixed_points()
    cycles = [c for m in periods for c in fmap.cycles(m)]
    values = cobweb_starts(fmap, fixed) if d1 is None else list(d1)
    lo, hi = fmap.domain
    for v in values:
        slack = DOMAIN_RTOL * max(abs(lo), abs(hi), 1.0)
        if not lo - slack <= v <= hi + slack:
            raise FabkitError(f"--d1 {v:g} is outside the map's domain [{lo:.6g}, {hi:.6g}] "
                              f"for {design.name}: no configuration there")
    lyap = None
    if lyapunov:
        progress.stage(f"{design.name}: Lyapunov exponent, {orbits} orbits")
        lyap = fmap.lyapunov(initial=orbits, discard=discard, average=average,
                             progress=lambda done, total: progress.within(done, total,
                                                                          "iterations"))
    summary = fmap.summary(periods=periods, lyapunov=lyap)
    summary["template"] = str(design.path)
    summary["cobweb"] = [{"d1": v, "orbit": fmap.orbit(v, steps).tolist()} for v in values]
    claims = []
    powers = summary["identity_powers"]
    for m in ([1] if 1 in powers else powers):  # f = id makes every power the identity too
        claims.append("f(d) = d on the whole branch: every d1 is a neutral fixed point" if m == 1
                      else f"f^{m}(d) = d on the whole branch: every d1 lies on a {m}-cycle")
    for p in summary["fixed_points"]:
        claims.append(f"fixed point {p['value']:.10g}: slope {p['slope']:.6g} ({p['kind']})")
    for c in summary["cycles"]:
        vals = ", ".join(f"{x:.10g}" for x in c["values"])
        claims.append(f"{c['period']}-cycle ({vals}): multiplier {c['multiplier']:.6g} "
                      f"({c['kind']})")
    if lyap is not None:
        claims.append(f"Lyapunov exponent {lyap.mean:.4f} ± {lyap.std:.4f} "
                      f"({'chaotic' if lyap.mean > 0 else 'not chaotic'})")
    summary["claims"] = claims
    if "design" in design.meta:
        summary["design"] = design.meta["design"]
    progress.stage(f"{design.name}: drawing")
    files = {
        "map.png": figure_png(map_figure(fmap, fixed=fixed, cycles=cycles, title=design.name)),
        "cobweb.png": figure_png(cobweb_figure(fmap, values, steps, title=f"{design.name}: cobweb")),
    }
    if lyap is not None:
        files["lyapunov.png"] = figure_png(lyapunov_figure(lyap))
    section = design.raw.get("design")
    if isinstance(section, dict) and design.network.dim == 2:
        from ..design.solution_space import displacement_space, velocity_space

        spaces = []
        if "velocities" in section:
            spaces.append(velocity_space(section["designed"], section["velocities"]))
        if "final" in section:
            spaces.append(displacement_space(section["designed"], section["final"]))
        if spaces:
            var = design.network.nodes[len(section["designed"]):]
            files["design.png"] = figure_png(solution_space_figure(spaces, variable=var,
                                                                   title=design.name))
    text = json.dumps(summary, indent=2, default=_json_default) + "\n"
    files["map.json"] = text.encode()
    # everything computed first: all or nothing, through the output folder's handle
    write_files(outdir, {f"{design.name}/{n}": data for n, data in files.items()})
    return summary


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def run(args) -> int:
    from ..templates import load_template, with_settings

    if args.steps < 1:
        raise UsageError("--steps", f"must be at least 1, got {args.steps}")
    check_count("--steps", args.steps, 1, MAX_STEPS, "iterations")
    periods = tuple(args.period or (2,))
    if any(m < 2 for m in periods):
        raise UsageError("--period", "must be at least 2 (fixed points are always reported)")
    for m in periods:
        check_count("--period", m, 2, MAX_PERIOD, "for a cycle period")
    given = [f"--{k}" for k in LYAPUNOV_DEFAULTS if getattr(args, k) is not None]
    if given and not args.lyapunov:  # an option that would do nothing is a mistake to say
        raise UsageError(given[0], "applies only with --lyapunov")
    for key, default in LYAPUNOV_DEFAULTS.items():
        if getattr(args, key) is None:
            setattr(args, key, default)
    check_count("--orbits", args.orbits, 1, MAX_ORBITS, "orbits")
    check_count("--discard", args.discard, 0, MAX_ITERATIONS, "iterations")
    check_count("--average", args.average, 1, MAX_ITERATIONS, "iterations")
    d1 = parse_values(args.d1) if args.d1 is not None else None
    if d1 is not None:
        check_count("--d1", len(d1), 1, MAX_D1, "values")
    # the options multiply: one estimate of the whole work, before any of it

    lyap = ("map evaluation", args.orbits * (args.discard + args.average) if args.lyapunov
            else 0)
    require("map --lyapunov" if args.lyapunov else "map", lyap,
            ("orbit step", args.steps * (len(d1) if d1 else 3)), option=True)

    settings = read_settings(args, {"motion": None}, "map reads motion settings only")
    progress = progress_for(args, NAME)

    def one(path) -> bool:
        design = with_settings(load_template(path), settings)
        summary = map_design(design, out_folder(args), d1=d1, steps=args.steps,
                             periods=periods, lyapunov=args.lyapunov, orbits=args.orbits,
                             discard=args.discard, average=args.average, d_in=args.d_in,
                             d_out=args.d_out, progress=progress)
        lo, hi = summary["domain"]
        print(f"== {design.name} -> {Path(args.out_dir) / design.name}")
        print(f"map {summary['name']} ({summary['source']}), domain [{lo:.10g}, {hi:.10g}], "
              f"{len(summary['branches'])} branch(es) in the whole motion")
        for line in summary["claims"]:
            print("  " + line)
        return False

    return each_template(args.templates, one, debug=args.debug, progress=progress)
