"""``fabkit fold TEMPLATE``: fold an origami template in the simulator and report it.

Prints the bifurcation at the flat state (self-stress, first-order motions, the branches the
second-order test finds), the branch taken (the one matching the mountain/valley assignment, or
``--branch``), the drive and ports at the start and end, and the fold angle of every crease at
the end. With ``-o`` it also writes the SVG, FOLD (and ORIPA .cp for a single sheet) and checks
the FOLD file by re-folding it.
"""

from __future__ import annotations


from ..errors import FabkitError, UsageError
from ..io.outputs import inside, write_files
from ..templates import with_settings
from . import (out_folder, add_out_dir, add_progress_options, add_settings, check_number, each_template,
               Example, progress_for)
from .settings import read_settings

NAME = "fold"
HELP = "fold an origami template: bifurcation, branches, fold angles; -o writes SVG/FOLD/CP"

EXAMPLES = [
    Example("fabkit fold origami_sheet",
            "the bifurcation at the flat sheet, the branch taken, every crease's fold angle"),
    Example("fabkit fold origami_sheet --branch 2 --sign -1 -o out/fold",
            "the branch's mirror image; writes the SVG, FOLD and .cp and re-folds the FOLD"),
    Example("fabkit fold origami_sheet --set origami.samples=40 --to 1.0",
            "fewer frames, folded only as far as d1 = 1.0"),
]


def add_arguments(p):
    p.add_argument("templates", nargs="+", metavar="TEMPLATE", help="origami template file(s)")
    p.add_argument("--branch", type=int, default=None,
                   help="branch number to leave the flat state on (default: by assignment)")
    p.add_argument("--sign", type=int, choices=(1, -1), default=None,
                   help="direction along the branch (the two are mirror images)")
    p.add_argument("--drive", default=None, help="port to drive (default: the template's)")
    p.add_argument("--to", type=float, default=None, help="target value of the drive")
    add_out_dir(p, None, "output folder: also write svg/fold/cp files into DIR/<name>/ and "
                         "check the FOLD file")
    add_settings(p, "override an origami or motion setting, e.g. --set origami.samples=40 "
                    "(repeatable)")
    add_progress_options(p)


def describe(design, model, fold) -> str:
    """The report printed for one template."""
    lines = [f"== {design.name}: {design.description}".rstrip(": ")]
    if fold.bifurcation:
        lines.append("flat state   " + fold.bifurcation.replace("\n", "\n             "))
        lines.append(f"taken        branch {fold.branch}, direction "
                     f"{'+' if (fold.sign or 1) > 0 else '-'}")
    else:
        lines.append("start        regular configuration (no branch choice)")
    lines.append(f"method       {fold.method}: {fold.message}")
    for name, d in sorted(fold.ports.items(), key=lambda kv: (len(kv[0]), kv[0]))[:14]:
        lines.append(f"{name:<12} {d[0]:.10g} -> {d[-1]:.10g}")
    lines.append(f"edge error   {fold.max_edge_error:.1e} (relative, largest over "
                 f"{fold.positions.shape[0]} frames)")
    labels = model.network.labels
    final = fold.angles[-1]
    shown = 0
    for k, (a, b) in enumerate(model.edges.tolist()):
        lab = model.assignment[k]
        if lab not in ("M", "V", "F", "U"):
            continue
        if shown == 24:
            lines.append("...")
            break
        na = labels[a] if labels else str(a)
        nb = labels[b] if labels else str(b)
        lines.append(f"crease {na}-{nb:<6} {lab}  fold angle {final[k]:+9.4f} deg")
        shown += 1
    return "\n".join(lines)


def run(args) -> int:
    from dataclasses import replace

    # the origami model is imported here, not at the top: it brings the settings schema
    # (pydantic), which `fabkit fold --help` does without
    from ..fab.creases.plan import origami_plan
    from ..templates import load_template

    if args.branch is not None and args.branch < 0:
        raise UsageError("--branch", f"must be 0 or more, got {args.branch}")
    check_number("--to", args.to)
    settings = read_settings(args, {"motion": None, "origami": None},
                             "fold reads origami and motion settings only")
    progress = progress_for(args, NAME)

    def one(path) -> bool:
        progress.stage(f"{path.name}: the crease pattern")
        design = with_settings(load_template(path), settings)
        out = out_folder(args) if args.out_dir else None
        folder = inside(out.path, design.name) if out else None  # before the work
        overrides = {**settings.get("origami", {}),
                     **{k: v for k, v in (("branch", args.branch), ("sign", args.sign))
                        if v is not None}}
        chosen = {"origami": overrides} if overrides else {}
        drive = args.drive or design.motion.drive
        if drive not in design.network.ports:
            known = ", ".join(sorted(design.network.ports))
            raise UsageError("--drive", f"{drive!r} is not a port of {path}; ports: {known}")
        # the command-line motion replaces the template's, for the report and the files alike
        motion = replace(design.motion, drive=drive,
                         to=args.to if args.to is not None else design.motion.to)
        design = replace(design, motion=motion)
        progress.stage(f"{design.name}: folding")
        # folded once: the summary and every file are drawn from the one origami plan
        plan = origami_plan(design, chosen)
        print(describe(design, plan.model, plan.fold))
        if out:
            from ..check import check_file
            from ..writers import get_exporter

            files: dict[str, bytes] = {}
            for fmt in ("svg", "fold", "cp"):
                module = get_exporter(fmt)
                if module.applies(design):
                    files.update(module.write(plan).files)
            # every format computed first: all or nothing, through the output folder's handle
            paths = write_files(out, {f"{design.name}/{n}": d for n, d in files.items()})
            print("wrote        " + ", ".join(str(p) for p in paths))
            progress.stage(f"{design.name}: checking {design.name}.fold by folding it again")
            try:
                # read back through the folder held, never by a path looked up again
                report = check_file(folder / f"{design.name}.fold", design=design,
                                    settings=chosen, folder=out)
            except FabkitError as exc:
                print(f"check        failed: {exc}")
                return True
            for c in report["checks"]:
                print(f"check        {c['name']}: {'ok' if c['ok'] else 'FAILED'} ({c['detail']})")
            return not report["ok"]
        return False

    return each_template(args.templates, one, debug=args.debug, progress=progress)
