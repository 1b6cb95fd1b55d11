"""``fabkit check FILE [FILE ...] [--design TEMPLATE]``: the as-built check of exported files alone.

Reads an exported DXF, FOLD or STL file back (through :func:`fabkit.check.check_file`), rebuilds
the network from it and, given the design's template, compares mode count and motion with the
design. Prints one line per check; exits 1 when any check fails.
"""

from __future__ import annotations

from ..check import check_file
from ..errors import FabkitError
from ..report.text import jsonable
from . import add_progress_options, add_settings, Example, progress_for
from .settings import parse_settings

NAME = "check"
HELP = "as-built check of exported DXF / FOLD / STL files (optionally against their template)"

_KIT = "fabkit export fourbar --to dxf --no-previews --tolerance-samples 0"
EXAMPLES = [
    Example("fabkit check out/fourbar/laser_sheet1.dxf --design fourbar",
            f"a kit exported before ({_KIT}) read back, rebuilt and moved like the design",
            needs=(_KIT,)),
    Example("fabkit check out/fourbar/laser_sheet1.dxf --json",
            "the file alone (no template), the report as JSON on stdout", needs=(_KIT,)),
    Example("fabkit check out/super_stable/*.stl --design super_stable --set print.clearance=0.4",
            "printed parts, checked with the settings they were exported with", cheap=False),
]


def add_arguments(p):
    p.add_argument("files", nargs="+", metavar="FILE", help="exported file(s)")
    p.add_argument("--design", default=None, metavar="TEMPLATE",
                   help="the template the files were exported from")
    add_settings(p, "fabrication settings used for the export (as for fabkit export; "
                    "repeatable)")
    p.add_argument("--json", action="store_true", help="print the check reports as JSON")
    add_progress_options(p)


def _value(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return "-" if v is None else str(v)


def format_report(path, report: dict) -> str:
    """A check report as lines: ``ok|FAIL name value (limit) detail``, then a verdict."""
    lines = []
    for c in report.get("checks", []):
        lim = f" (limit {_value(c.get('limit'))})" if c.get("limit") is not None else ""
        detail = f"  {c['detail']}" if c.get("detail") else ""
        lines.append(f"  {'ok  ' if c.get('ok') else 'FAIL'}  {c.get('name')}: "
                     f"{_value(c.get('value'))}{lim}{detail}")
    if report.get("not_checked"):
        lines.append(f"  not checked: {report['not_checked']}")
    lines.append(f"{path}: {'ok' if report.get('ok') else 'FAILED'}")
    return "\n".join(lines)


def run(args) -> int:
    import json
    from pathlib import Path

    from ..stoppable import run_stoppable
    from ..templates import load_template, with_settings

    settings = parse_settings(args.settings)
    if settings:  # a section no check of these files reads would be accepted without effect
        from ..check import checker_for
        from ..io.schema import refuse_unused

        reads = {"motion"}.union(*(getattr(checker_for(f), "READS", ()) for f in args.files))
        refuse_unused(settings, reads, f"the checks of these files read "
                                       f"{', '.join(sorted(reads - {'motion'}))} settings only")
    progress = progress_for(args, NAME)
    progress.stage(f"{len(args.files)} file{'s' * (len(args.files) != 1)}",
                   total=len(args.files), unit="files")
    design = with_settings(load_template(args.design), settings) if args.design else None
    failed = 0
    out = {}
    for name in args.files:
        path = Path(name)
        if not path.is_file():
            from ..io.suggest import nearest_file

            hint = nearest_file(path)
            raise FabkitError(f"{path}: no such file" + (f"; {hint}" if hint else ""))
        progress.stage(f"{path}: reading back, rebuilding, moving")
        if args.debug:  # in this process, for the traceback
            report = check_file(path, design=design, settings=settings)
        else:  # where SIGINT/SIGTERM stop it at once, held to its work estimate
            report = run_stoppable(check_file, path, design=design, settings=settings,
                                   what=str(path))
        failed += not report.get("ok")
        progress.advance(text=f"{path}: {'ok' if report.get('ok') else 'FAILED'}")
        if args.json:
            out[str(path)] = report
        else:
            print(format_report(path, report))
    progress.close()
    if args.json:
        print(json.dumps(jsonable(out), indent=2, sort_keys=True))
    return 1 if failed else 0
