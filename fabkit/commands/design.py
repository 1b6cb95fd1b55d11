"""``fabkit design``: a module from its map wishes, or a chain from a drawn curve."""

from __future__ import annotations

import argparse
import json
import re
import shlex
from pathlib import Path

from ..design import (design_curve_chain, design_map, parse_cycle, parse_decimal,
                      parse_fixed_point, read_curve, WishError)
from ..design.curve_files import MAX_CURVE_BYTES
from ..design.toml_text import builds_line, fit_lines, margin_lines
from ..errors import BoundsError, brief, InputFileError, UnsafeNameError, UsageError
from ..numerics import printed, printed_residual
from ..io.inputs import read_regular
from ..io.outputs import check_name, write_files as write_all
from ..templates import bundled_folder
from ..io.toml_writer import TomlDocument
from ..io.workload import require
from ..plots.designplots import curve_design_figure, module_design_figure
from ..plots.viz import figure_png
from . import add_out_dir, add_progress_options, add_settings, Example, out_folder, progress_for
from .settings import read_settings

NAME = "design"
HELP = "design a module from map wishes (--fixed-point, --cycle) or a chain from a curve (--curve)"
DESCRIPTION = (
    "Design a module whose map has the wished fixed points (D or D:SLOPE, up to two) and 2-cycle "
    "(A,B), built with the paper's construction; or a chain of curvature modules whose final "
    "state follows a drawn curve (an .svg path or a .csv polyline in mm). Writes the templates, "
    "a JSON report and a picture into -o DIR; the templates export like any other "
    "(fabkit export DIR/NAME.toml --to dxf). A wish that cannot be met exits 2 with one line "
    "naming it, why, and the nearest feasible wish.")

EXAMPLES = [
    Example("fabkit design --fixed-point 1.6:0 --fixed-point 1.1 -o out/design",
            "a module super-stable at 1.6 with a second fixed point at 1.1"),
    Example("fabkit design --cycle 1.4,1.8 --name two_cycle",
            "a module whose map has the 2-cycle 1.4 <-> 1.8; out/design/two_cycle.toml"),
    Example("fabkit design --curve quadrifolium.csv --curve-scale 4 --module-size 19.9 "
            "-o out/quad",
            "a chain whose final state follows a bundled curve, 4 times the drawing, in "
            "modules of 19.9 mm (its nodes within 1 % of the drawing's size)", cheap=False),
]

#: Output names: a plain file stem, so every file stays inside -o.


class _Once(argparse.Action):
    """An option that may be given once: a second one is refused (one line, exit status 2)
    rather than silently replacing the first."""

    def __call__(self, parser, namespace, values, option_string=None):
        seen = f"_given_{self.dest}"
        if getattr(namespace, seen, None) is not None:
            raise argparse.ArgumentError(
                self, f"given twice ({getattr(namespace, seen)} and {values}): give it once")
        setattr(namespace, seen, values)
        setattr(namespace, self.dest, values)


def _decimal(option: str, *, positive: bool = True):
    """argparse type: a decimal number as typed (see :func:`fabkit.design.parse_decimal`)."""
    def convert(text):
        try:
            value = parse_decimal(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        if positive and value <= 0:
            raise argparse.ArgumentTypeError(f"must be positive, got {text}")
        return value

    convert.__name__ = option
    return convert


def _whole(text):
    if not re.fullmatch(r"\d+", str(text)):
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number")
    return int(text)


#: The laser settings the simulated builds of a designed module read (its scale, the sheet
#: thickness, the screw's hole play): :func:`fabkit.tolerance.spec.tolerance_spec`.
LASER_KEYS = ("scale", "size", "thickness", "screw")
#: The tolerance settings they read: the laser errors and the scale (the number of builds and
#: their seed are fixed, :data:`fabkit.design.robustness.BUILDS`).
TOLERANCE_KEYS = ("scale", "length_sigma", "kerf_sigma", "hole_clearance", "thickness",
                  "thickness_sigma")

#: Options that only apply to a curve, and their defaults.
CURVE_OPTIONS = {"module_size": 50.0, "curve_scale": 1.0, "types": None}


def add_arguments(p):
    p.add_argument("--fixed-point", action="append", default=[], metavar="D[:SLOPE]",
                   help="a fixed point D of the map, with its slope (repeatable, up to two; "
                        "decimal numbers, D from 0.05 to 20 design units)")
    p.add_argument("--cycle", action=_Once, default=None, metavar="A,B",
                   help="a 2-cycle f(A) = B, f(B) = A")
    p.add_argument("--curve", action=_Once, default=None, metavar="FILE",
                   help="design a chain whose final state follows this curve (.svg or .csv, mm; "
                        "a bare name such as quadrifolium.csv is also looked up among the "
                        "bundled curves)")
    p.add_argument("--module-size", action=_Once, type=_decimal("--module-size"), default=None,
                   metavar="MM", help="--curve: mm per module along the curve (default 50)")
    p.add_argument("--curve-scale", action=_Once, type=_decimal("--curve-scale"), default=None,
                   metavar="F", help="--curve: draw the curve F times larger (default 1)")
    p.add_argument("--types", action=_Once, type=_whole, default=None,
                   help="--curve: number of module types, 1 to 15 (default: as few as keep "
                        "the fit)")
    p.add_argument("--name", action=_Once, default=None,
                   help="stem of the files written (default: module, or the curve file's stem)")

    add_settings(p, "a setting of the simulated laser builds a module's wishes are judged "
                    "against, written into its template so that its export is judged the "
                    "same way, e.g. --set tolerance.length_sigma=0.1 or --set laser.scale=50 "
                    f"(reads laser.{', laser.'.join(LASER_KEYS)} and the laser keys of "
                    "tolerance; a chain from --curve reads none)")
    add_out_dir(p, "out/design", "output folder (default: out/design)", action=_Once)
    add_progress_options(p)


def _name(args) -> str:
    if args.name is not None:
        try:  # the one guard: a name never leaves -o
            return check_name(args.name, "--name")
        except UnsafeNameError as exc:
            raise UsageError("--name", f"{brief(args.name)} {exc.reason}") from None
    if args.curve:
        stem = re.sub(r"[^A-Za-z0-9_.-]", "_", Path(args.curve).stem).lstrip("._-")
        return (stem or "curve")[:80]
    return "module"


def write_files(out, files: dict[str, bytes]) -> list[Path]:
    """Write every file inside the output folder ``out`` (its handle, held since the start),
    all or nothing, refusing any name that would leave it (the one place this command writes:
    :func:`fabkit.io.outputs.write_files`)."""
    return write_all(out, files)


def _curve_path(path: str) -> Path:
    """The curve file: a path, or a bare name of a bundled curve (``quadrifolium.csv``) when
    no file of that name is here."""
    p = Path(path)
    if p.exists() or p.name != str(path):
        return p

    bundled = bundled_folder() / "curves" / p.name
    return bundled if bundled.is_file() else p


def _read_curve_file(path: str):
    p = _curve_path(path)
    if not p.exists():
        raise InputFileError(p, "no such curve file (give an .svg or a .csv)", kind="missing")
    try:  # a FIFO or a device is refused, never waited on
        data = read_regular(p, MAX_CURVE_BYTES, what="bytes for a curve file")
    except BoundsError as exc:
        raise InputFileError(p, f"{exc.value:,} bytes is over the limit of {MAX_CURVE_BYTES:,} "
                                "for a curve file") from None
    if p.suffix.lower() == ".svg":
        from ..design.curve_files import svg_work

        require(f"{p}", *svg_work(data), option=True)
    return read_curve(data, str(path))


def _check_curve_size(curve, module_size: float) -> None:
    """The drawing, at its scale, is within reach of a chain: finite, and at most
    :data:`fabkit.templates.MAX_MODULES` modules long (before any design work)."""
    import numpy as np

    from ..templates import MAX_MODULES, allow_large

    if not np.isfinite(curve.points).all() or not np.isfinite(curve.length):
        raise UsageError("--curve-scale", "makes the curve's coordinates overflow; give a "
                                          "smaller factor")
    modules = curve.length / module_size
    if modules > MAX_MODULES and not allow_large():
        count = f"{modules:,.0f}" if modules < 1e9 else f"{modules:.3g}"
        raise UsageError("--module-size", f"the curve of {curve.length:.6g} mm makes {count} "
                                          f"modules of {module_size:g} mm, over the limit of "
                                          f"{MAX_MODULES:,} modules; give a larger module size "
                                          "or a smaller --curve-scale")


def run(args) -> int:
    name = _name(args)
    out = out_folder(args)
    if args.curve is not None and args.settings:
        read_settings(args, {}, "a chain designed from a curve reads no settings")
    args.settings = read_settings(
        args, {"laser": set(LASER_KEYS), "tolerance": set(TOLERANCE_KEYS)},
        "a designed module reads the settings of its simulated laser builds only: laser."
        + ", laser.".join(LASER_KEYS) + ", tolerance." + ", tolerance.".join(TOLERANCE_KEYS))
    if args.curve is not None:
        if args.fixed_point or args.cycle:
            raise UsageError("--curve", "designs a chain from a curve; give it without "
                                        "--fixed-point and --cycle")
        for key, default in CURVE_OPTIONS.items():
            if getattr(args, key) is None:
                setattr(args, key, default)
        return _run_curve(args, name, out, figure_png)
    given = [k for k in CURVE_OPTIONS if getattr(args, k) is not None]
    if given:
        option = "--" + given[0].replace("_", "-")
        raise UsageError(option, "applies to --curve only (a module from map wishes has no "
                                 "module size, curve scale or types)")
    if not args.fixed_point and args.cycle is None:
        raise UsageError("", "give --fixed-point D[:SLOPE] (up to two) and/or --cycle A,B, or "
                             "--curve FILE")
    return _run_module(args, name, out, figure_png)


def _run_module(args, name, out, figure_png) -> int:
    from ..maps import classify_slope

    wishes = [parse_fixed_point(v) for v in args.fixed_point]
    cycle = parse_cycle(args.cycle) if args.cycle is not None else None
    progress = progress_for(args, NAME)
    progress.stage(f"{name}: a module from its map wishes, judged against simulated laser "
                   "builds")
    settings = args.settings
    from ..tolerance.builds import laser_builds  # scipy: not for every --help

    result = design_map(wishes, cycle, name=name, progress=progress.stage,
                        sample_builds=lambda design: laser_builds(design, settings))
    progress.stage(f"{name}: drawing and writing")
    report = result.report
    files = {
        f"{name}.toml": (result.template + settings_toml(settings)).encode(),
        f"{name}_design.json": (json.dumps(report, indent=1) + "\n").encode(),
        f"{name}_map.png": figure_png(module_design_figure(result), dpi=100),
    }
    write_files(out, files)
    print(f"{name}: module designed from {report['wish']} in {report['seconds']:.2f} s "
          f"-> {out.path / (name + '.toml')}")
    met = report["wishes_met"]
    for p in met["fixed_points"]:
        wished = "" if p["wished_slope"] is None else f"; wished {p['wished_slope']:g}"
        print(f"  fixed point {p['value']:.10g}: |f(D) - D| {printed_residual(p['residual'])}, "
              f"slope {printed(p['slope'])} ({classify_slope(p['slope'])}{wished})")
    if met["cycle"] is not None:
        c = met["cycle"]
        print(f"  2-cycle {c['values'][0]:.10g} <-> {c['values'][1]:.10g}: residual "
              f"{max(c['residuals']):.1e}, multiplier {c['multiplier']:.6g}")
    b = report["buildability"]
    worst = min(b["branch_margins"], key=lambda m: m["fraction"])
    print(f"  buildability: bar-length ratio {b['bar_length_ratio']:.2f}, joints at least "
          f"{b['joint_separation']:.3f} apart, rigidity margin {b['rigidity_margin']:.3f}, "
          f"branch margin {worst['margin']:.4g} ({100 * worst['fraction']:.3g} % of "
          f"{worst['value']:.6g}) to the nearest fold")
    for line in margin_lines(b["branch_margins"], report["map"]):
        print(f"  {line}")
    if report["builds"] is not None:
        print(f"  {builds_line(report['builds'])}")
    print(f"  export: fabkit export {out.path / (name + '.toml')} --to dxf")
    return 0


def settings_toml(settings: dict) -> str:
    """The ``--set`` settings as ``[fabrication.SECTION]`` tables to end a template with
    (empty without settings)."""
    if not settings:
        return ""
    doc = TomlDocument()
    doc.blank()
    doc.comment("set by `fabkit design --set`: the simulated builds above used it, and so does "
                "the export")
    for section, table in settings.items():
        doc.table(f"fabrication.{section}")
        for key, value in table.items():
            doc.value(key, value)
    return doc.text()


def _pasteable(nearest: str | None, args) -> str | None:
    """A curve's suggestion as the whole option set that designs it: the file, the scale of
    the drawing (absolute, not a factor of the scale given) and the module size, so that pasted
    alone it works."""
    if not nearest:
        return nearest
    words = nearest.split()
    scale, size = args.curve_scale, args.module_size
    if words[:1] not in (["--curve-scale"], ["--module-size"]):
        return nearest
    # the options lead the suggestion (words in brackets may follow): each one a value
    for option, value in zip(words[::2], words[1::2]):
        if option == "--curve-scale":
            scale = float(f"{args.curve_scale * float(value):.6g}")
        elif option == "--module-size":
            size = float(value)
        else:
            break
    tail = f" --types {args.types}" if args.types is not None else ""
    return (f"--curve {shlex.quote(str(args.curve))} --curve-scale {scale:g} --module-size "
            f"{size:g}{tail}")


def _run_curve(args, name, out, figure_png) -> int:
    import numpy as np

    from ..design.curve import MAX_MODULES, scaled

    progress = progress_for(args, NAME)
    progress.stage(f"{name}: reading {args.curve}")
    curve = _read_curve_file(args.curve)
    if args.curve_scale != 1.0:
        lo = 2 * args.module_size / curve.length
        hi = MAX_MODULES * args.module_size / curve.length
        if not np.isfinite(curve.length * args.curve_scale):
            raise UsageError("--curve-scale", "makes the curve's coordinates overflow; give a "
                                              "smaller factor")
        if not lo <= args.curve_scale <= hi:
            raise UsageError("--curve-scale", f"{args.curve_scale:g} makes the curve "
                             f"{curve.length * args.curve_scale:.4g} mm long; with modules of "
                             f"{args.module_size:g} mm it must be from 2 to {MAX_MODULES} "
                             f"modules long: scales from {lo:.3g} to {hi:.3g}")
        with np.errstate(over="ignore", invalid="ignore"):
            curve = scaled(curve, args.curve_scale)
    _check_curve_size(curve, args.module_size)
    try:
        result = design_curve_chain(curve, module_size=args.module_size, types=args.types,
                                    name=name, progress=progress.stage)
    except WishError as exc:
        raise WishError(exc.wish, exc.reason, _pasteable(exc.nearest, args)) from None
    progress.stage(f"{name}: drawing and writing")
    report = result.report
    rows = "\n".join(f"{x:.6f},{y:.6f}" for x, y in np.asarray(result.centerline))
    files = {f: t.encode() for f, t in result.templates.items()}
    files[f"{name}_fit.json"] = (json.dumps(report, indent=1) + "\n").encode()
    files[f"{name}_centerline.csv"] = ("# the traced final state's centre line, mm (x,y)\n"
                                       + rows + "\n").encode()
    files[f"{name}.png"] = figure_png(curve_design_figure(result), dpi=100)
    write_files(out, files)
    e = result.errors
    print(f"{name}: {report['modules']} modules ({len(result.types)} types) following a "
          f"{curve.length:.1f} mm curve ({curve.source}), module size {args.module_size:g} mm, "
          f"scale {result.scale:.4g} mm/unit in {report['seconds']:.2f} s "
          f"-> {out.path / (name + '.toml')}")
    print(f"  traced final state on the curve: mean {100 * e['mean_fraction']:.2g} % of its "
          f"size, ends {100 * e['start_fraction']:.2g} % / {100 * e['end_fraction']:.2g} % "
          f"(accepted: {100 * report['tolerance']['mean_fraction']:g} %, ends "
          f"{100 * report['tolerance']['end_fraction']:g} %)")
    for line in fit_lines(e, result.proportions):
        print(f"  {line}")
    print("  types (final apex, count; rigidity margin, branch margin to the nearer fold): "
          + ", ".join(f"{t['final_apex_deg']:.1f} deg x{t['count']} "
                      f"({t['margins']['rigidity']:.3f}, "
                      f"{100 * t['margins']['branch_margin_fraction']:.3g} %)"
                      for t in report["types"]))
    if curve.strokes > 1:
        print(f"  the file holds {curve.strokes} strokes; the longest was followed")
    print(f"  laser kit: fabkit export {out.path / (name + '.toml')} --to dxf")
    return 0
