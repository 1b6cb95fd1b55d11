"""``fabkit sweep TEMPLATE --vary KEY=START:STOP:N [--set motion.to=VALUE]``: a module family on
a grid of parameters."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from ..errors import FabkitError, Interrupted, UsageError
from ..io.outputs import inside
from . import (out_folder, add_jobs, add_out_dir, add_progress_options, add_settings, check_jobs, check_number,
               Example, progress_for)
from .settings import read_settings

NAME = "sweep"
HELP = "sweep template keys on a grid: fixed points, cycles, λ per point; bifurcation diagram"
DESCRIPTION = (
    "Evaluate a module template on a grid of values of numeric keys (node coordinates or any "
    "number in the template) through its map d2 = f(d1): fixed points, slopes, 2-cycles, "
    "attractor, Lyapunov exponent, mode count. Writes DIR/sweep.csv, DIR/sweep.json and a "
    "bifurcation diagram (one key) or heat maps (two keys). Runs on local processes, or on a "
    "dask.distributed cluster with --scheduler (or DASK_SCHEDULER_ADDRESS). Finished chunks "
    "are kept in DIR/chunks: running the same command again after an interruption resumes. "
    "TEMPLATE may also be a sweep spec (a TOML file with a [sweep] table, e.g. "
    "templates/sweeps/period_doubling.toml).")

EXAMPLES = [
    Example("fabkit sweep chaotic --vary nodes[4].x=-0.3:-0.2:3 --measure fixed_points,slopes "
            "--no-plots -j 1 -o out/sweep-small",
            "three members of a module family: their fixed points and slopes"),
    Example("fabkit sweep templates/sweeps/period_doubling.toml -o out/sweep",
            "the bifurcation diagram of a module family (a sweep spec file)", cheap=False),
    Example("fabkit sweep chaotic --vary nodes[4].x=-0.3:0.3:41 --scheduler tcp://10.0.0.5:8786",
            "the same on a dask cluster", cheap=False),
]


#: Rates are points per second over at least this long (a run that finished at once).
MIN_SECONDS = 1e-9
#: Longest wait for a scheduler (an hour: a longer one is a typo, or a wait for nothing).
MAX_CONNECT_TIMEOUT = 3600.0
#: Most points a task (and a chunk file) holds: a chunk is rewritten whole when it ends.
MAX_CHUNK_SIZE = 100_000


def add_arguments(p):
    p.add_argument("template", metavar="TEMPLATE", help="module template, or a sweep spec file")
    p.add_argument("--vary", action="append", default=None, metavar="KEY=START:STOP:N",
                   help="vary a key over N evenly spaced values (repeatable: a grid); keys like "
                        "nodes[4].x, network.nodes[4][1], motion.to")
    p.add_argument("--measure", default=None, metavar="LIST",
                   help="comma-separated: fixed_points,slopes,cycles,lyapunov,modes,attractor "
                        "(default: all)")
    add_settings(p, "override the template's motion target at every point, e.g. "
                    "--set motion.to=2.9: the branch measured, and the motion traced where "
                    "the module has no construction (the sweep reads motion.to only)")
    add_out_dir(p, None, "output folder (default: out/sweep-<template name>)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="dask.distributed scheduler, e.g. tcp://10.0.0.5:8786 (default: "
                        "$DASK_SCHEDULER_ADDRESS, else this machine)")
    p.add_argument("--connect-timeout", type=float, default=10.0, metavar="SECONDS",
                   help="how long to wait for the scheduler (default 10)")
    add_jobs(p, None, "local processes without a scheduler (default: one per core)")
    p.add_argument("--chunk-size", type=int, default=None, metavar="N",
                   help="points per task (default: about four tasks per worker, at most 32)")
    p.add_argument("--lyapunov-protocol", default=None, metavar="ORBITS:DISCARD:AVERAGE",
                   help="Lyapunov protocol per point (default 32:1000:4000; the paper's "
                        "1000:5000:20000)")
    p.add_argument("--no-plots", action="store_true", help="write the table and sweep.json only")
    p.add_argument("--point-timeout", type=float, default=None, metavar="SECONDS",
                   help="seconds a point may take on a worker process before it counts as "
                        "stopped answering and is recorded as failed (default 600)")
    add_progress_options(p)


def _usage(message: str):
    """A bad request of the command line: one line, exit status 2."""
    raise UsageError("", message)


class _Points:
    """The sweep's ``progress(done, total)``, said through a
    :class:`~fabkit.io.progress.Progress` (points done of all, the time left at the rate of
    this run)."""

    def __init__(self, progress, name: str):
        self.progress = progress
        self.name = name
        self.start = None

    @property
    def started(self) -> bool:
        """True once the sweep has begun computing (its chunk folder exists)."""
        return self.start is not None

    def __call__(self, done, total):
        if self.start is None:  # the first call: the points read back from an earlier run
            self.start = done
            resumed = f", {done} read back from an earlier run" if done else ""
            self.progress.stage(f"{self.name}: computing{resumed}", total=total, unit="points",
                                done=done)
            return
        if done >= total:
            self.progress.update(done, total, f"{self.name}: writing the table and plots")
        else:
            self.progress.update(done, total)


def _with_target(design, settings, axes):
    """The design with ``--set motion.to`` in its template's ``[motion]`` (the sweep rebuilds
    every point from the template's table, so the value goes there); refused when a ``--vary``
    axis varies that same key (one of them would be ignored)."""
    import copy
    from dataclasses import replace

    from ..sweep.model import key_path, path_text

    target = settings.get("motion", {}).get("to")
    if target is None:
        return design
    raw = copy.deepcopy(design.raw)
    for axis in axes:
        if path_text(key_path(axis.key, raw)) == "motion.to":
            raise UsageError("--set", f"motion.to: --vary {axis.key} varies it already; give "
                                      "one of the two")
    if not isinstance(raw.get("motion"), dict):
        raw["motion"] = {}
    raw["motion"]["to"] = float(target)
    return replace(design, raw=raw, motion=replace(design.motion, to=float(target)))


def _checked_options(args, protocol):
    """The protocol with ``--lyapunov-protocol`` applied, and every numeric option checked
    against its range, before any work (one line, exit status 2)."""
    from dataclasses import replace

    from ..sweep import SweepError

    if args.lyapunov_protocol is not None:
        parts = args.lyapunov_protocol.split(":")
        try:
            k, dis, avg = (int(v) for v in parts)
        except ValueError:
            _usage(f"--lyapunov-protocol {args.lyapunov_protocol!r}: expected three "
                   "integers ORBITS:DISCARD:AVERAGE, e.g. 32:1000:4000")
        try:
            protocol = replace(protocol, lyapunov_orbits=k, lyapunov_discard=dis,
                               lyapunov_average=avg)
        except SweepError as exc:
            _usage(f"--lyapunov-protocol {args.lyapunov_protocol}: {exc}")
    check_number("--point-timeout", args.point_timeout)
    if not 0 < args.connect_timeout <= MAX_CONNECT_TIMEOUT:
        _usage(f"--connect-timeout must be a number of seconds above 0 and at most "
               f"{MAX_CONNECT_TIMEOUT:g}, got {args.connect_timeout}")
    if args.chunk_size is not None and args.chunk_size > MAX_CHUNK_SIZE:
        _usage(f"--chunk-size must be at most {MAX_CHUNK_SIZE}, got {args.chunk_size}")
    check_jobs("--jobs", args.jobs)
    if args.chunk_size is not None and args.chunk_size < 1:
        _usage(f"--chunk-size must be at least 1, got {args.chunk_size}")
    return protocol


def _say_where_to_resume(exc: BaseException, outdir) -> None:
    """Ctrl-C, a signal, or a crash mid-run: say where the finished work is; the command line
    reports the interruption itself (a signal: with this in its one line)."""
    hint = (f"finished chunks are in {Path(outdir) / 'chunks'}: run the same command again to "
            "resume")
    if isinstance(exc, Interrupted):
        exc.hint = hint
    else:
        print(f"fabkit: {hint}", file=sys.stderr)


def run(args) -> int:
    from ..sweep import Protocol, SweepError, parse_vary, read_sweep_file, sweep
    from ..templates import load_template

    settings = read_settings(args, {"motion": {"to"}}, "sweep reads motion.to only (the branch "
                                                       "measured, the target of a traced motion)")
    try:
        spec_file = read_sweep_file(args.template)
        if spec_file is not None:
            template = spec_file.template
            axes = spec_file.axes
            measures = spec_file.measures
            protocol = spec_file.protocol
        else:
            template, axes, measures, protocol = args.template, (), None, Protocol()
        if args.vary:  # the command line wins over the spec file
            axes = tuple(parse_vary(v) for v in args.vary)
        if not axes:
            _usage("nothing to vary: give --vary KEY=START:STOP:N (or a sweep spec file "
                          "with vary = [...])")
        if args.measure is not None:
            measures = args.measure
        protocol = _checked_options(args, protocol)
        progress = progress_for(args, NAME)
        size = 1
        for axis in axes:
            size *= len(axis.values)
        progress.stage(f"{template}: {size} points", total=size, unit="points")
        design = _with_target(load_template(template), settings, axes)
        outdir = (out_folder(args) if args.out_dir  # the folder held since the start
                  else inside(Path("out"), f"sweep-{design.name}"))
        scheduler = args.scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
        where = f"the scheduler {scheduler}" if scheduler else (
            f"{args.jobs} process{'es' * (args.jobs != 1)}" if args.jobs else "this machine's cores")
        progress.stage(f"{design.name}: starting on {where}")
        bar = _Points(progress, design.name)
        try:
            result = sweep(design, axes, measures, outdir=outdir, scheduler=scheduler,
                           jobs=args.jobs, chunk_size=args.chunk_size, protocol=protocol,
                           plots=not args.no_plots, progress=bar,
                           connect_timeout=args.connect_timeout,
                           **({} if args.point_timeout is None
                              else {"point_timeout": args.point_timeout}))
        except FabkitError:
            raise
        except BaseException as exc:
            if bar.started:
                _say_where_to_resume(exc, outdir)
            raise
    except SweepError as exc:
        _usage(str(exc))
    progress.close()
    counts = ", ".join(f"{n} {s}" for s, n in sorted(result.counts().items()))
    print(f"sweep {design.name}: {result.spec.size} points ({counts}) -> {outdir}")
    resumed = result.spec.size - result.computed
    if result.computed:
        rate = result.computed / max(result.seconds, MIN_SECONDS)
        per_cpu = result.computed / max(result.cpu_seconds, MIN_SECONDS)
        print(f"  computed {result.computed} points in {result.seconds:.1f} s on "
              f"{result.workers} worker(s) ({result.where}): {rate:.2f} points/s, "
              f"{per_cpu:.2f} points per CPU second"
              + (f"; {resumed} read back from an earlier run" if resumed else ""))
    else:
        print(f"  all {resumed} points read back from an earlier run")
    for name, why in result.damaged:
        print(f"  damaged chunk {name} set aside as {name}.damaged ({why}); its points were "
              "computed again")
    for f in result.files:
        print(f"  wrote {f}")
    return 0
