"""``fabkit tolerance TEMPLATE... [-o DIR] [--samples N] [--seed S] [--set tolerance.key=value]``.

Monte Carlo over the manufacturing errors of the design's process (laser: bar length, kerf,
hole play, sheet thickness; print: xy accuracy, shrinkage, line width, hinge flexure; origami:
crease position, cut, paper thickness, crease compliance; see :mod:`fabkit.tolerance`), in mm at
the process's own scale,: prints the spread of the final port distances and of the far-end
positions, the verdict, and for chains the Lyapunov exponent and predictability horizon; writes
``tolerance.png`` and ``tolerance.json`` into ``DIR/<name>/``. Exits 1 when a design is flagged
(its intended final state is not reached within tolerance), so scripts can gate on it.
"""

from __future__ import annotations

from pathlib import Path

NAME = "tolerance"
HELP = "Monte Carlo of manufacturing errors: final distances, end positions, horizon"


def add_arguments(p):
    p.add_argument("templates", nargs="+", metavar="TEMPLATE", help="template file(s)")
    p.add_argument("-o", "--out", default="out", help="output folder (default: out)")
    p.add_argument("--samples", type=int, default=None,
                   help="simulated builds (default: the template's, else 200)")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: 0)")
    p.add_argument("--set", dest="settings", action="append", default=[],
                   metavar="SECTION.KEY=VALUE",
                   help="override a setting, e.g. --set tolerance.length_sigma=0.1, "
                        "--set tolerance.process=print or --set laser.scale=40")
    p.add_argument("--no-files", action="store_true", help="print only; write no files")


def describe(result) -> str:
    """Terminal lines for a :class:`~fabkit.tolerance.ToleranceResult`."""
    d = result.as_dict()
    lines = [f"  builds        {d['samples']} ({result.method}); {d['model']}",
             f"  effective     bar-length error {d['length_rms_mm']:.3g} mm RMS",
             f"  reached       {100 * d['reached_fraction']:.1f}% of builds reach the target"]
    for name, v in (d.get("sources") or {}).items():
        err = v["p95_error_mm"]
        lines.append(f"  alone         {name}: {100 * v['reached_fraction']:.0f}% reach, 95% "
                     "port error " + ("n/a" if err is None else f"{err:.3g} mm"))
    for p in d["ports"]:
        if p["mean"] is None:
            continue
        lines.append(f"  {p['port']:<13} designed {p['nominal']:.6g}, built {p['mean']:.6g} ± "
                     f"{p['std']:.2g}; 95% |error| {p['p95_abs_error_mm']:.3g} mm "
                     f"(limit {p['limit_mm']:.3g} mm)")
    if "end_position_p95_mm" in d:
        lines.append(f"  far end       nodes {', '.join(map(str, result.end_nodes))}: 95% within "
                     f"{d['end_position_p95_mm']:.3g} mm, worst {d['end_position_max_mm']:.3g} mm")
    hz = d.get("horizon")
    if hz:
        lines.append(f"  lyapunov      λ = {hz['lyapunov']:.4g} per module ({hz['source']})")
        lines.append(f"  horizon       {hz['detail']}")
    lines.append(f"  verdict       {d['verdict']}")
    return "\n".join(lines)


def run(args) -> int:
    from ..errors import FabkitError
    from ..report import report_json
    from ..templates import load_template, with_settings
    from ..tolerance import analyse_tolerance, tolerance_figure, tolerance_spec
    from ..viz import figure_png
    from ..outputs import inside, write_files
    from . import each_template
    from ..batch import traced_motion
    from .export import parse_settings

    from ..batch import MAX_SAMPLES
    from ..errors import UsageError
    from . import check_count

    if args.samples is not None and args.samples < 1:
        raise UsageError("--samples", f"must be at least 1, got {args.samples}")
    check_count("--samples", args.samples, 1, MAX_SAMPLES, "Monte Carlo samples")
    if args.seed is not None and not 0 <= args.seed < 2**63:
        raise UsageError("--seed", f"must be a whole number from 0 to 2**63 - 1, got {args.seed}")
    settings = parse_settings(args.settings)
    overrides = {k: v for k, v in (("samples", args.samples), ("seed", args.seed)) if v is not None}

    def one(path) -> bool:
        design = with_settings(load_template(path), settings)
        folder = inside(Path(args.out), design.name)  # before the work
        traj = traced_motion(design)
        if traj is None:
            raise FabkitError(f"{path}: motion.to: the tolerance analysis needs a target value "
                              "of the drive")
        spec = tolerance_spec(design, settings, **overrides)
        result = analyse_tolerance(design, spec, trajectory=traj)
        # compute every byte before writing any
        files = {} if args.no_files else {
            "tolerance.json": report_json(result.as_dict()),
            "tolerance.png": figure_png(tolerance_figure(result, title=design.name)),
        }
        if files:
            write_files(folder, files)
        print(f"== {design.name}" + (f" -> {folder}" if files else ""))
        print(describe(result))
        return bool(result.flagged)

    return each_template(args.templates, one, debug=args.debug)
