"""``fabkit export PATH... [--to dxf,svg,fold,stl] [-o DIR] [--jobs N] [--set KEY=VALUE ...]``.

Exports templates (files, folders of ``*.toml``, glob patterns) into one folder per design:
the files of every format that applies (or of the formats asked for), ``report.json``,
``report.md`` and preview PNGs (motion, map, tolerance, and any preview an exporter makes).

This module only reads the command line and prints; the work is done by :mod:`fabkit.batch`
(atomic folders, as-built checks, worker processes, signals, the lock on the output folder).
A design that fails is reported and the others still export; the exit code is 1 when any failed,
2 for a bad option. Identical input gives identical bytes.
"""

from __future__ import annotations

import sys

NAME = "export"
HELP = "export templates (files, folders, globs) for fabrication, with reports and checks"

def add_arguments(p):
    p.add_argument("paths", nargs="+", metavar="PATH",
                   help="template files, folders of *.toml templates, or glob patterns")
    p.add_argument("--to", default=None, metavar="FORMATS",
                   help="comma-separated formats (default: every format that applies to a design)")
    p.add_argument("-o", "--out", default="out", help="output folder (default: out)")
    p.add_argument("--jobs", "-j", type=int, default=1,
                   help="designs exported in parallel processes (default: 1)")
    p.add_argument("--set", dest="settings", action="append", default=[],
                   metavar="SECTION.KEY=VALUE",
                   help="override a fabrication setting, e.g. --set laser.kerf=0.2 (repeatable; "
                        "values are read as TOML: 0.2, true, \"text\", [1, 2])")
    p.add_argument("--no-check", action="store_true",
                   help="skip the as-built check of the written files")
    p.add_argument("--no-previews", action="store_true",
                   help="skip the preview pictures (motion, map, tolerance): faster batches")
    p.add_argument("--tolerance-samples", type=int, default=None, metavar="N",
                   help="Monte Carlo builds in the tolerance analysis (0: skip; default: the "
                        "template's [fabrication.tolerance] samples, else 100)")
    p.add_argument("--wait", action="store_true",
                   help="wait for another export into the same output folder to finish "
                        "(default: refuse at once)")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress lines on stderr")
    p.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help="seconds one design may take before it is stopped and failed "
                        "(default 3600; 0: no limit)")


# --- command-line values ---------------------------------------------------------------------

def parse_settings(items) -> dict:
    """``["laser.kerf=0.2", "laser.scale=10"]`` → ``{"laser": {"kerf": 0.2, "scale": 10}}``.

    Values are parsed as TOML values (numbers, booleans, quoted strings, arrays); anything that
    is not valid TOML is kept as a plain string.

    Raises
    ------
    UsageError
        An item without ``=`` or without a dotted key, a key given twice, or settings that the
        schema (:mod:`fabkit.schema`) refuses: an unknown section or key, a wrong type, a value
        out of range.
    """
    from ..errors import UsageError
    from ..templates import tomllib

    out: dict = {}
    for item in items:
        key, eq, text = item.partition("=")
        key = key.strip()
        if not eq or not key:
            raise UsageError("--set", f"{item!r}: expected SECTION.KEY=VALUE, e.g. "
                                      "laser.kerf=0.2")
        parts = key.split(".")
        if len(parts) < 2 or not all(parts):
            raise UsageError("--set", f"{item!r}: the key must name a section and a key, "
                                      "e.g. laser.kerf")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except (tomllib.TOMLDecodeError, RecursionError):
            value = text.strip()
        node = out
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise UsageError("--set", f"{item!r}: {part!r} is already set to a value")
        if parts[-1] in node:
            raise UsageError("--set", f"{item!r}: {key} is given twice")
        node[parts[-1]] = value
    from ..errors import SettingsError
    from ..export import check_export_settings

    try:  # one declared schema: unknown sections and keys, types and ranges
        check_export_settings(out)
    except SettingsError as exc:
        raise UsageError("--set", str(exc)) from None
    return out


def parse_formats(text: str | None) -> list[str] | None:
    """``"dxf,stl"`` → ``["dxf", "stl"]``; None stays None (every format that applies)."""
    from ..errors import UsageError
    from ..export import EXPORTERS

    if text is None:
        return None
    names = [t.strip().lower() for t in text.split(",") if t.strip()]
    if not names:
        raise UsageError("--to", "give at least one format, e.g. --to dxf,stl")
    for n in names:
        if n not in EXPORTERS:
            raise UsageError("--to", f"unknown format {n!r}; valid: {', '.join(EXPORTERS)}")
    return list(dict.fromkeys(names))


def run(args) -> int:
    from ..batch import Progress, exit_code, export_many, summary_table
    from ..errors import UsageError
    from . import check_jobs, expand_templates

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
    progress = Progress(len(paths), quiet=args.quiet)
    results = export_many(paths, formats, args.out, settings, jobs=args.jobs,
                          check=not args.no_check, tolerance_samples=args.tolerance_samples,
                          progress=progress, previews=not args.no_previews,
                          debug=getattr(args, "debug", False), wait=args.wait,
                          allow_large=getattr(args, "allow_large", False), **timeout)
    print(summary_table(results))
    for r in results:  # the verdict of a design that is not plainly ok, in one line each
        if r.ok and r.level not in ("", "ok"):
            print(f"{r.name}: {r.headline}")
    for r in results:
        if not r.ok:
            print(f"fabkit: error: {r.error}", file=sys.stderr)
    return exit_code(results)
