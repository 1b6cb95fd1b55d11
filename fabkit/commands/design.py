"""``fabkit design``: a module from its map wishes, or a chain from a drawn curve."""

from __future__ import annotations

import json
import re
from pathlib import Path

from ..errors import InputFileError, UsageError

NAME = "design"
HELP = "design a module from map wishes (--fixed-point, --cycle) or a chain from a curve (--curve)"
DESCRIPTION = (
    "Design a module whose map has the wished fixed points (D or D:SLOPE, up to two) and 2-cycle "
    "(A,B), built with the paper's construction; or a chain of curvature modules whose final "
    "state follows a drawn curve (an .svg path or a .csv polyline in mm). Writes the templates, "
    "a JSON report and a picture into -o DIR; the templates export like any other "
    "(fabkit export DIR/NAME.toml --to dxf). A wish that cannot be met exits 2 with one line "
    "naming it, why, and the nearest feasible wish.")

#: Largest curve file read (an SVG of a hand-drawn curve is a few kB).
MAX_CURVE_BYTES = 16 * 2**20
#: Output names: a plain file stem, so every file stays inside -o.


def add_arguments(p):
    p.add_argument("--fixed-point", action="append", default=[], metavar="D[:SLOPE]",
                   help="a fixed point D of the map, with its slope (repeatable, up to two)")
    p.add_argument("--cycle", default=None, metavar="A,B", help="a 2-cycle f(A) = B, f(B) = A")
    p.add_argument("--curve", default=None, metavar="FILE",
                   help="design a chain whose final state follows this curve (.svg or .csv, mm)")
    p.add_argument("--module-size", type=float, default=50.0, metavar="MM",
                   help="--curve: the chain's pitch along the curve in mm (default 50)")
    p.add_argument("--curve-scale", type=float, default=1.0, metavar="F",
                   help="--curve: draw the curve F times larger (default 1)")
    p.add_argument("--types", type=int, default=3,
                   help="--curve: number of module types, odd (default 3)")
    p.add_argument("--name", default=None,
                   help="stem of the files written (default: module, or the curve file's stem)")
    p.add_argument("-o", "--out", default="out/design", help="output folder (default out/design)")


def _name(args) -> str:
    if args.name is not None:
        from ..errors import UnsafeNameError, brief
        from ..outputs import check_name

        try:  # the one guard: a name never leaves -o
            return check_name(args.name, "--name")
        except UnsafeNameError as exc:
            raise UsageError("--name", f"{brief(args.name)} {exc.reason}") from None
    if args.curve:
        stem = re.sub(r"[^A-Za-z0-9_.-]", "_", Path(args.curve).stem).lstrip("._-")
        return (stem or "curve")[:80]
    return "module"


def write_files(out: Path, files: dict[str, bytes]) -> list[Path]:
    """Write every file inside the output folder ``out``, all or nothing, refusing any name
    that would leave it (the one place this command writes: :func:`fabkit.outputs.write_files`)."""
    from ..outputs import write_files as write_all

    return write_all(out, files)


def _read_curve_file(path: str):
    from ..designer import read_curve
    from ..errors import BoundsError
    from ..inputs import read_regular
    from ..workload import require

    p = Path(path)
    if not p.exists():
        raise InputFileError(p, "no such curve file (give an .svg or a .csv)")
    try:  # a FIFO or a device is refused, never waited on
        data = read_regular(p, MAX_CURVE_BYTES, what="bytes for a curve file")
    except BoundsError as exc:
        raise InputFileError(p, f"{exc.value:,} bytes is over the limit of {MAX_CURVE_BYTES:,} "
                                "for a curve file") from None
    if p.suffix.lower() == ".svg":
        from ..designer.curve_files import svg_work

        require(f"{p}", *svg_work(data), option=True)
    return read_curve(data, str(p))


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
    from ..viz import figure_png
    from . import check_number

    name = _name(args)
    out = Path(args.out)
    if args.curve is not None:
        if args.fixed_point or args.cycle:
            raise UsageError("--curve", "designs a chain from a curve; give it without "
                                        "--fixed-point and --cycle")
        check_number("--module-size", args.module_size)
        check_number("--curve-scale", args.curve_scale)
        return _run_curve(args, name, out, figure_png)
    if not args.fixed_point and args.cycle is None:
        raise UsageError("", "give --fixed-point D[:SLOPE] (up to two) and/or --cycle A,B, or "
                             "--curve FILE")
    return _run_module(args, name, out, figure_png)


def _run_module(args, name, out, figure_png) -> int:
    from ..designer import design_map, parse_cycle, parse_fixed_point
    from ..designplots import module_design_figure
    from ..maps import classify_slope

    wishes = [parse_fixed_point(v) for v in args.fixed_point]
    cycle = parse_cycle(args.cycle) if args.cycle is not None else None
    result = design_map(wishes, cycle, name=name)
    report = result.report
    files = {
        f"{name}.toml": result.template.encode(),
        f"{name}_design.json": (json.dumps(report, indent=1) + "\n").encode(),
        f"{name}_map.png": figure_png(module_design_figure(result), dpi=100),
    }
    write_files(out, files)
    print(f"{name}: module designed from {report['wish']} in {report['seconds']:.2f} s "
          f"-> {out / (name + '.toml')}")
    met = report["wishes_met"]
    for p in met["fixed_points"]:
        wished = "" if p["wished_slope"] is None else f"; wished {p['wished_slope']:g}"
        print(f"  fixed point {p['value']:.10g}: |f(D) - D| = {p['residual']:.1e}, slope "
              f"{p['slope']:.6g} ({classify_slope(p['slope'])}{wished})")
    if met["cycle"] is not None:
        c = met["cycle"]
        print(f"  2-cycle {c['values'][0]:.10g} <-> {c['values'][1]:.10g}: residual "
              f"{max(c['residuals']):.1e}, multiplier {c['multiplier']:.6g}")
    extra = report["extra_fixed_points"]
    print("  other fixed points on the branch: "
          + (", ".join(f"{v:.6g}" for v in extra) if extra else "none"))
    b = report["buildability"]
    print(f"  buildability: bar-length ratio {b['bar_length_ratio']:.2f}, joints at least "
          f"{b['joint_separation']:.3f} apart, rigidity margin {b['rigidity_margin']:.3f}")
    print(f"  export: fabkit export {out / (name + '.toml')} --to dxf")
    return 0


def _run_curve(args, name, out, figure_png) -> int:
    import numpy as np

    from ..designer import design_curve_chain
    from ..designplots import curve_design_figure

    from ..designer.curve import scaled

    curve = _read_curve_file(args.curve)
    if args.curve_scale != 1.0:
        with np.errstate(over="ignore", invalid="ignore"):
            curve = scaled(curve, args.curve_scale)
    _check_curve_size(curve, args.module_size)
    result = design_curve_chain(curve, module_size=args.module_size, types=args.types,
                                name=name)
    report = result.report
    rows = "\n".join(f"{x:.6f},{y:.6f}" for x, y in np.asarray(result.centerline))
    files = {f: t.encode() for f, t in result.templates.items()}
    files[f"{name}_fit.json"] = (json.dumps(report, indent=1) + "\n").encode()
    files[f"{name}_centerline.csv"] = ("# the traced final state's centre line, mm (x,y)\n"
                                       + rows + "\n").encode()
    files[f"{name}.png"] = figure_png(curve_design_figure(result), dpi=100)
    write_files(out, files)
    e, pr = result.errors, result.proportions
    print(f"{name}: {report['modules']} modules ({len(result.types)} types) following a "
          f"{curve.length:.1f} mm curve ({curve.source}), module size {args.module_size:g} mm, "
          f"scale {result.scale:.4g} mm/unit in {report['seconds']:.2f} s "
          f"-> {out / (name + '.toml')}")
    print(f"  fit error of the traced final state: rms {e['rms']:.3f} mm, max {e['max']:.3f} mm, "
          f"end {e['end']:.3f} mm")
    c, ch = pr["curve"], pr["chain"]
    print(f"  proportions (curve / chain): length {c['length']:.1f} / {ch['length']:.1f} mm, "
          f"fitted circle r {c['circle_radius']:.1f} / {ch['circle_radius']:.1f} mm over "
          f"{c['circle_sweep_deg']:.1f} / {ch['circle_sweep_deg']:.1f} deg")
    if curve.strokes > 1:
        print(f"  the file holds {curve.strokes} strokes; the longest was followed")
    print(f"  laser kit: fabkit export {out / (name + '.toml')} --to dxf")
    return 0
