"""``fabkit tolerance TEMPLATE [TEMPLATE ...] [-o DIR] [--samples N] [--seed S] [--set KEY=VALUE]``.

Monte Carlo over the manufacturing errors of the design's process (laser: bar length, kerf,
hole play, sheet thickness; print: xy accuracy, shrinkage, line width, hinge flexure; origami:
crease position, cut, paper thickness, crease compliance; see :mod:`fabkit.tolerance`), in mm at
the process's own scale: prints what the design is for (its crystals, order and end), what
fraction of builds keep each part of it, the verdict with its margin (the factor by which every
error may grow with the verdict unchanged), and for chains the Lyapunov exponent and
predictability horizon; writes ``tolerance.png`` and ``tolerance.json`` into ``DIR/<name>/``.
Exits 1 when a design is flagged (fewer than ``min_reached`` of the builds keep its behaviour),
so scripts can gate on it.
"""

from __future__ import annotations

import math

from ..errors import FabkitError, UsageError
from ..io.outputs import inside, write_files
from ..numerics import printed
from ..report.text import report_json
from ..plots.viz import figure_png
from . import (add_out_dir, add_progress_options, add_settings, check_count, each_template,
               Example, out_folder, progress_for, TOLERANCE_SAMPLES)
from .settings import parse_settings

NAME = "tolerance"
HELP = "Monte Carlo of manufacturing errors: the behaviour builds keep, the verdict's margin"

EXAMPLES = [
    Example("fabkit tolerance fourbar --samples 50 --no-files",
            "does a laser-cut 4-bar keep what it is for? the verdict and its margin"),
    Example("fabkit tolerance super_stable_chain8 --set tolerance.process=print",
            "the same chain judged as a 3D print; tolerance.json and .png into out/<name>/"),
    Example("fabkit tolerance templates/*.toml -o out/tolerance",
            "every template; exits 1 when any is flagged", cheap=False),
]


def add_arguments(p):
    p.add_argument("templates", nargs="+", metavar="TEMPLATE", help="template file(s)")
    add_out_dir(p, "out", "output folder (default: out); results go to DIR/<name>/")
    p.add_argument("--samples", type=int, default=None,
                   help=f"simulated builds (default: the template's, else {TOLERANCE_SAMPLES})")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: 0)")
    add_settings(p, "override a setting, e.g. --set tolerance.length_sigma=0.1, "
                    "--set tolerance.process=print or --set laser.scale=40 (repeatable)")
    p.add_argument("--no-files", action="store_true", help="print only; write no files")
    add_progress_options(p)


def describe(result) -> str:
    """Terminal lines for a :class:`~fabkit.tolerance.ToleranceResult`."""
    from ..tolerance.margin import margin_text

    d = result.as_dict()
    lines = [f"  builds        {d['samples']} ({result.method}); {d['model']}",
             f"  effective     bar-length error {d['length_rms_mm']:.3g} mm RMS"]
    if d.get("play_note"):
        lines.append(f"  pins          {d['play_note']}")
    if d.get("assembly"):
        lines.append(f"  assembly      {d['assembly']['sentence']}")
    if d.get("slop"):
        lines.append(f"  slop          {d['slop']['sentence']}")
    lines += _behaviour_lines(d.get("behaviour") or {})
    for c in d.get("criteria", []):
        lines.append(f"  {c['criterion']:<13} {_criterion_text(c, d)}")
        if (c["detail"] or {}).get("front"):
            lines.append(f"  front         {c['detail']['front']}")
    if d.get("ports_judged"):
        lines += _port_lines(d, result.end_nodes)
    if d.get("margin") is not None:
        alone = ", ".join(f"{n} {margin_text(v['value'], v['bound'])}"
                          for n, v in (d.get("source_margins") or {}).items())
        lines.append(f"  margin        {margin_text(d['margin'], d['margin_bound'])}: every error "
                     "may grow by this factor with the verdict unchanged"
                     + (f"; each source alone: {alone}" if alone else ""))
    hz = d.get("horizon")
    if hz:
        lines.append(f"  lyapunov      λ = {hz['lyapunov']:.4g} per module ({hz['source']})")
        lines.append(f"  horizon       {hz['detail']}")
    lines.append(f"  verdict       {d['verdict']}")
    return "\n".join(lines)


def _behaviour_lines(b: dict) -> list[str]:
    """The behaviour judged (its criteria, crystals, lock, order, notes), when there is one."""
    if not b:
        return []
    how = "stated in the template" if b["intent"] != "auto" else "inferred"
    lines = [f"  behaviour     {', '.join(b['criteria'])} ({how}; the end: "
             f"{b['end']} at the {b['end_at']}, drive {b['end_drive']:.6g})"]
    for c in b["crystals"]:
        lines.append(f"  crystal       {c['role']}: D* = {c['value']:.6g}, slope "
                     f"{c['slope']:.3g} ({c['kind']})"
                     + (", at a turning point" if c["at_turning_point"] else ""))
    if b.get("end_lock"):
        lines.append(f"  lock          the first module ends where it locks: d_in = "
                     f"{b['end_lock'][0]:.6g}, d_out = {b['end_lock'][1]:.6g}")
    if b.get("order"):
        lines.append(f"  order         the front runs {b['order']}")
    for note in b.get("notes", []):
        lines.append(f"  note          {note}")
    return lines


def _criterion_text(c: dict, d: dict) -> str:
    """One criterion's line: the builds that keep it, and how far the others are."""
    pct = 100 * c["kept_fraction"]
    if c["criterion"] == "order":
        side = c["detail"]
        text = (f"{pct:.1f}% of builds: every module on the designed side of the diagonal "
                f"over d_in {side['interval'][0]:.4g}..{side['interval'][1]:.4g}")
        obs = d.get("observed_order")
        if obs:
            text += (f"; observed along the motion: {100 * obs['monotone_fraction']:.1f}% "
                     f"monotone ({obs['samples']} instants)")
        return text
    u = " mm" if c.get("unit", "mm") == "mm" else c["unit"]  # 22 mm, 41.4°
    if c["p95_mm"] is None or not math.isfinite(c["p95_mm"]):
        return (f"{pct:.1f}% of builds; {c['missing']} with no such state within "
                f"{c['limit_mm']:.3g}{u}")
    text = (f"{pct:.1f}% of builds within {c['limit_mm']:.3g}{u} (95%: "
            f"{printed(c['p95_mm'], '.3g')}{u}, worst {printed(c['worst_mm'], '.3g')}{u})")
    if c.get("unit") == "°":
        text += " of a crease's designed fold angle"
    slopes = (c["detail"] or {}).get("slopes")
    if isinstance(slopes, list):
        text += f"; built slopes {slopes[0]:.3g}..{slopes[1]:.3g}"
    return text


def _port_lines(d: dict, end_nodes) -> list[str]:
    """Each judged port, designed against built, and the far end's nodes."""
    lines = []
    for p in d["ports"]:
        if p["mean"] is None:
            continue
        lines.append(f"  {p['port']:<13} designed {p['nominal']:.6g}, built {p['mean']:.6g} ± "
                     f"{p['std']:.2g}; 95% |error| {p['p95_abs_error_mm']:.3g} mm "
                     f"(limit {p['limit_mm']:.3g} mm)")
    if "end_position_p95_mm" in d:
        lines.append(f"  far end       nodes {', '.join(map(str, end_nodes))}: 95% "
                     f"within {d['end_position_p95_mm']:.3g} mm, worst "
                     f"{d['end_position_max_mm']:.3g} mm")
    return lines


def run(args) -> int:
    from ..templates import load_template, with_settings
    from ..tolerance import (analyse_tolerance, design_process, refuse_foreign,
                             tolerance_figure, tolerance_spec)
    from ..pipeline import traced_motion

    from ..pipeline import MAX_SAMPLES

    if args.samples is not None and args.samples < 1:
        raise UsageError("--samples", f"must be at least 1, got {args.samples}")
    check_count("--samples", args.samples, 1, MAX_SAMPLES, "Monte Carlo samples")
    if args.seed is not None and not 0 <= args.seed < 2**63:
        raise UsageError("--seed", f"must be a whole number from 0 to 2**63 - 1, got {args.seed}")
    settings = parse_settings(args.settings)
    overrides = {k: v for k, v in (("samples", args.samples), ("seed", args.seed)) if v is not None}

    progress = progress_for(args, NAME)

    def one(path) -> bool:
        progress.stage(f"{path.name}: loading")
        design = with_settings(load_template(path), settings)
        # --set of another process has no effect here: refused as a key of another process is
        refuse_foreign(settings, design_process(design), design.name)
        held = out_folder(args)
        folder = inside(held.path, design.name)  # before the work
        progress.stage(f"{design.name}: tracing the motion")
        traj = traced_motion(design)
        if traj is None:
            raise FabkitError(f"{path}: motion.to: the tolerance analysis needs a target value "
                              "of the drive")
        spec = tolerance_spec(design, settings, **overrides)
        result = analyse_tolerance(design, spec, trajectory=traj,
                                   progress=lambda done, total, what: progress.within(
                                       done, total, "steps", f"{design.name}: {what}"))
        # compute every byte before writing any
        if not args.no_files:
            progress.stage(f"{design.name}: drawing and writing")
        files = {} if args.no_files else {
            "tolerance.json": report_json(result.as_dict()),
            "tolerance.png": figure_png(tolerance_figure(result, title=design.name)),
        }
        if files:  # through the folder held since the start, never by its name
            write_files(held, {f"{design.name}/{n}": data for n, data in files.items()})
        print(f"== {design.name}" + (f" -> {folder}" if files else ""))
        print(describe(result))
        return bool(result.flagged)

    return each_template(args.templates, one, debug=args.debug, progress=progress)
