"""``fabkit export PATH [PATH ...] [--to FORMATS] [-o DIR] [-j N] [--set KEY=VALUE ...]``.

Exports templates (files, folders of ``*.toml``, glob patterns) into one folder per design:
the files of every format that applies (or of the formats asked for), ``report.json``,
``report.md`` and preview PNGs (motion, map, tolerance, and any preview an exporter makes).

This module only reads the command line and prints; the work is done by :mod:`fabkit.pipeline`
(atomic folders, as-built checks, worker processes, signals, the lock on the output folder).
Progress (each design's stages as they start, each design as it ends, the time left) goes to
stderr through :mod:`fabkit.io.progress`; the summary table and the page to open go to stdout.
A design that fails is reported and the others still export; the exit code is 1 when any failed,
2 for a bad option. Identical input gives identical bytes.
"""

from __future__ import annotations

import sys

from ..errors import UsageError
from ..status import Status
from . import (add_jobs, add_out_dir, add_progress_options, add_settings, check_jobs, Example,
               expand_templates, out_folder, progress_for, TOLERANCE_SAMPLES)
from .settings import parse_settings

NAME = "export"
HELP = "export templates (files, folders, globs) for fabrication, with reports and checks"

EXAMPLES = [
    Example("fabkit export fourbar --to dxf --no-previews --tolerance-samples 0",
            "a laser-cut kit of a bundled design into out/fourbar/, quickly"),
    Example("fabkit export super_stable --to dxf,stl -o out",
            "the laser kit and the printed-in-place parts, checked as built", cheap=False),
    Example("fabkit export templates -o out -j 2",
            "every template of a folder, two at a time; then open out/index.html", cheap=False),
]


#: What each process makes, in the help's words (the formats of each come from the registry,
#: :data:`fabkit.writers.EXPORTERS`, and each format's ``PROCESS``).
PROCESS_WORDS = {"laser": "a laser-cut acrylic kit, its guide and BOM",
                 "origami": "origami crease patterns and cut sheets",
                 "print": "a 3D print, STL and 3MF"}


def formats_help() -> str:
    """The formats of :data:`fabkit.writers.EXPORTERS` grouped by the process that makes each
    (``dxf (a laser-cut acrylic kit, its guide and BOM); svg, fold, cp (origami ...)``), read
    without importing the writers."""
    from ..writers import EXPORTERS, format_process

    by_process: dict = {}
    for fmt in EXPORTERS:
        by_process.setdefault(format_process(fmt), []).append(fmt)
    return "; ".join(", ".join(fmts) + (f" ({PROCESS_WORDS.get(proc, f'the {proc} process')})"
                                        if proc else " (a format of one's own)")
                     for proc, fmts in by_process.items())


def add_arguments(p):
    p.add_argument("paths", nargs="+", metavar="PATH",
                   help="template files, folders of *.toml templates, or glob patterns")
    p.add_argument("--to", default=None, metavar="FORMATS",
                   help="comma-separated formats, each made by its process: "
                        + formats_help() + " (default: every format that applies to a design)")
    add_out_dir(p, "out", "output folder (default: out); each design goes to DIR/<name>/")
    add_jobs(p, 1, "designs exported in parallel processes (default: 1)")
    add_settings(p, "override a fabrication setting, e.g. --set laser.kerf=0.2 (repeatable; "
                    "values are read as TOML: 0.2, true, \"text\", [1, 2])")
    p.add_argument("--no-check", action="store_true",
                   help="skip the as-built check of the written files")
    p.add_argument("--no-previews", action="store_true",
                   help="skip the preview pictures (motion, map, tolerance): faster batches")
    p.add_argument("--tolerance-samples", type=int, default=None, metavar="N",
                   help="Monte Carlo builds in the tolerance analysis (0: skip; default: the "
                        f"template's [fabrication.tolerance] samples, else "
                        f"{TOLERANCE_SAMPLES})")
    p.add_argument("--wait", action="store_true",
                   help="wait for another export into the same output folder to finish "
                        "(default: refuse at once)")
    add_progress_options(p)
    p.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help="seconds one design may take before it is stopped and failed "
                        "(default 3600; 0: no limit)")


# --- command-line values ---------------------------------------------------------------------

def parse_formats(text: str | None) -> list[str] | None:
    """``"dxf,stl"`` → ``["dxf", "stl"]``; None stays None (every format that applies)."""
    from ..writers import EXPORTERS

    if text is None:
        return None
    names = [t.strip().lower() for t in text.split(",") if t.strip()]
    if not names:
        raise UsageError("--to", "give at least one format, e.g. --to dxf,stl")
    for n in names:
        if n not in EXPORTERS:
            from ..io.suggest import did_you_mean

            hint = did_you_mean(n, EXPORTERS)
            raise UsageError("--to", f"unknown format {n!r}; " + (f"{hint} " if hint else "")
                             + f"valid: {', '.join(EXPORTERS)}")
    return list(dict.fromkeys(names))


def run(args) -> int:
    from pathlib import Path

    from ..pipeline import exit_code, export_many, summary_table

    check_jobs("--jobs", args.jobs)
    if args.timeout is not None and not (args.timeout >= 0 and args.timeout < float("inf")):
        raise UsageError("--timeout", f"must be 0 (no limit) or a number of seconds, got "
                                      f"{args.timeout}")
    timeout = {} if args.timeout is None else {"timeout": args.timeout or None}
    if args.tolerance_samples is not None and args.tolerance_samples < 0:
        raise UsageError("--tolerance-samples", f"must be 0 or more, got {args.tolerance_samples}")
    formats = parse_formats(args.to)
    settings = parse_settings(args.settings)
    paths = expand_templates(args.paths)
    progress = progress_for(args, NAME)
    jobs = min(args.jobs, len(paths)) or 1
    progress.stage(f"{len(paths)} design{'s' * (len(paths) != 1)} into {args.out_dir}, "
                   f"{jobs} at a time", total=len(paths), unit="designs")
    results = export_many(paths, formats, out_folder(args), settings, jobs=args.jobs,
                          check=not args.no_check, tolerance_samples=args.tolerance_samples,
                          progress=DesignProgress(progress), previews=not args.no_previews,
                          debug=getattr(args, "debug", False), wait=args.wait,
                          allow_large=getattr(args, "allow_large", False), **timeout)
    progress.close()
    if any(r.folder for r in results):  # else the error lines below are all there is to say
        print(summary_table(results, messages=False))  # each error once: on stderr, below
    for r in results:  # the verdict of a design that is not plainly ok, in one line each
        if r.ok and r.level not in ("", Status.OK.value):
            print(f"{r.name}: {r.headline}")
        for note in r.notes:  # formats of earlier exports kept in the folder, or removed
            print(f"{r.name}: {note}")
    index = Path(args.out_dir) / "index.html"
    if any(r.folder for r in results) and index.is_file():
        print(f"open {index} (every design's report)")
    for r in results:
        if not r.ok:
            print(f"fabkit: error: {r.message}", file=sys.stderr)
    return exit_code(results)


class DesignProgress:
    """What :func:`fabkit.pipeline.export_many` reports (``stage(name, stage)`` as a design starts
    a stage, ``finished(result)`` as it ends), said through one
    :class:`~fabkit.io.progress.Progress` whose count is the designs.

    While one design is in hand (a single design, or one at a time), its stages are counted
    too (``[0/1 designs, 3/7 stages, 41 s, about 1 min left]``), with the time left at the rate
    of the stages done so far; designs exported side by side say each stage as it starts.

    Examples
    --------
    >>> import io
    >>> from fabkit.io.progress import Progress
    >>> from fabkit.pipeline import DesignResult, Stage, Status
    >>> out = io.StringIO()
    >>> p = Progress("fabkit export", show=True, stream=out,
    ...              clock=iter([0, 0, 1, 3, 9, 9]).__next__)
    >>> p.stage("1 design", total=1, unit="designs")
    >>> said = DesignProgress(p)
    >>> said.stage("chain", Stage.LOAD)
    >>> said.stage("chain", Stage.MOTION)
    >>> said.stage("chain", Stage.EXPORT)
    >>> said.finished(DesignResult("chain.toml", "chain", Status.OK, seconds=9.0))
    >>> print(out.getvalue(), end="")
    fabkit export [0/1 designs, 0.0 s] 1 design
    fabkit export [0/1 designs, 0/7 stages, 1.0 s] chain: load
    fabkit export [0/1 designs, 1/7 stages, 3.0 s, about 12 s left] chain: motion
    fabkit export [0/1 designs, 2/7 stages, 9.0 s, about 20 s left] chain: export
    fabkit export [1/1 designs, 9.0 s] chain: ok in 9.0 s
    """

    #: The stages of one design, in order: the count of its stages.
    STAGES = ("load", "motion", "export", "previews", "tolerance", "write", "check")

    def __init__(self, progress):
        self.progress = progress
        self.in_hand: set = set()

    def stage(self, name: str, stage) -> None:
        text = f"{name}: {stage}"
        if str(stage) == self.STAGES[0]:
            self.in_hand.add(name)
        if len(self.in_hand) <= 1 and str(stage) in self.STAGES:
            self.progress.within(self.STAGES.index(str(stage)), len(self.STAGES), "stages",
                                 text=text)
        else:
            self.progress.stage(text)

    def finished(self, result) -> None:
        from pathlib import Path

        # a design is named after its file until its template is read
        self.in_hand.difference_update({result.name, Path(result.path).stem})
        self.progress.advance(text=f"{result.name}: {result.word} in {result.seconds:.1f} s")

    def close(self) -> None:
        self.progress.close()
