"""``fabkit simulate TEMPLATE``: trace the template's motion, write .npz + PNG, print a summary."""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np

from ..errors import FabkitError, UsageError
from ..io.outputs import inside, write_files
from ..io.suggest import did_you_mean
from ..kinematics import METHODS, Status
from ..motion import judge_ends
from ..motion.spread import module_spread, shape_missed
from ..plots.viz import elastic_figure, figure_png, motion_figure
from . import (out_folder, add_out_dir, add_progress_options, add_settings, check_count, check_number,
               each_template, Example, progress_for)
from .settings import read_settings

#: Most quasi-static steps of ``--model elastic`` (each one a least-energy assembly).
MAX_STEPS = 10_000

NAME = "simulate"
HELP = "trace a template's motion; writes trajectory.npz and motion.png"

EXAMPLES = [
    Example("fabkit simulate super_stable_chain8 --gif --set motion.to=1.5",
            "the chain driven part of the way (d1 = 1.5), with an animated motion.gif"),
    Example("fabkit simulate physical_fourbar --set motion.drive=d1 --to 1.9 --branch 2",
            "drive d1 from the flat start on the mirror branch (node 2 on the side of node 3)"),
    Example("fabkit simulate super_stable_chain8 --model elastic --to 1.0",
            "push the laser kit 1 mm past where it locks: energy and the largest bar stress "
            "(MPa) along the drive; out/<name>/elastic.npz, elastic.png"),
]

#: Quasi-static steps of ``--model elastic`` without ``--steps``: the elastic model's own default
#: (:data:`fabkit.tolerance.elastic.DEFAULT_STEPS`; tests/test_cli_startup.py holds them equal),
#: stated here so that the help does not import the elastic model.
DEFAULT_STEPS = 51

#: Values of ``--model``: the rigid kinematic model, or bars as springs with the joints' play.
MODELS = ("rigid", "elastic")


def add_arguments(p):
    p.add_argument("templates", nargs="+", metavar="TEMPLATE", help="template file(s)")
    p.add_argument("--method", default=None, metavar="METHOD",
                   help=f"{', '.join(['auto', *METHODS])} (default: the template's)")
    p.add_argument("--to", type=float, default=None, help="target value of the drive")
    add_out_dir(p, "out", "output folder (default: out); results go to DIR/<name>/")
    add_settings(p, "override a motion setting, e.g. --set motion.to=1.5 or "
                    "--set motion.method=projected (repeatable)")
    p.add_argument("--branch", type=int, default=None, metavar="N",
                   help="at a singular start or one where the drive turns (a flat state), "
                        "leave on branch N (the branches and the one taken are named in the "
                        "output; default: the first that moves the drive towards the target)")
    p.add_argument("--gif", action="store_true", help="also write an animated motion.gif")
    p.add_argument("--model", default="rigid", metavar="MODEL",
                   help="rigid (default: bars keep their lengths) or elastic (the build's bars "
                        "as springs with its joints' play, driven in quasi-static steps to the "
                        "target: energy and the largest stress; writes elastic.npz, elastic.png)")
    p.add_argument("--steps", type=int, default=None,
                   help=f"quasi-static steps of --model elastic (default: {DEFAULT_STEPS})")
    add_progress_options(p)


def trajectory_npz(traj) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(
        buf,
        positions=traj.positions,
        drive=traj.drive,
        arclength=traj.arclength,
        edge_error=traj.edge_error,
        edges=traj.network.edges,
        method=np.array(traj.method),
        status=np.array(str(traj.status)),
        message=np.array(traj.message),
        **{f"port_{k}": np.array(v) for k, v in traj.network.ports.items()},
    )
    return buf.getvalue()


def simulate_design(design, outdir: Path, method=None, to=None, gif=False, progress=None,
                    elastic=None, branch=None):
    """Trace a design's motion and write its files; with ``elastic`` (``{"steps": K,
    "settings": {...}}``) also drive its build with elastic bars; with ``branch``, leave a
    singular or turning start on that branch. A start where the drive turns (a flat state)
    that the method asked for cannot leave is left on its first branch, and the trace says
    which. Returns (trajectory, folder, elastic run or None)."""
    say = progress.stage if progress is not None else (lambda text: None)

    overrides = {}
    if method:
        overrides["method"] = method
    if to is not None:
        overrides["to"] = to
    if branch is not None:
        overrides.update(method="branch", branch=branch)
    folder = inside(outdir, design.name)  # before the work
    say(f"{design.name}: tracing the motion")
    traj = design.trace(**overrides)
    if branch is None and not traj.success and traj.n_steps <= 1 and \
            traj.status in (Status.TURNING_POINT, Status.BRANCH_POINT):
        # stuck at its start: a turning point of the drive or a bifurcation has branches
        # that leave it; take the first that moves the drive towards the target, and say so
        try:
            traj = design.trace(**{**overrides, "method": "branch"})
        except FabkitError:
            pass
    say(f"{design.name}: drawing")
    files = {"trajectory.npz": trajectory_npz(traj),
             "motion.png": figure_png(motion_figure(traj, title=design.name))}
    if gif:
        from ..plots.animate import motion_gif

        say(f"{design.name}: animating motion.gif")
        files["motion.gif"] = motion_gif(traj)
    run = None
    if elastic is not None:
        # the elastic model is imported here, not at the top: it brings the fabrication
        # geometry and scipy, which `fabkit simulate --help` and the rigid model do without
        from ..tolerance.elastic import elastic_motion

        say(f"{design.name}: driving the build with elastic bars")
        run = elastic_motion(design, to=to, steps=elastic["steps"],
                             settings=elastic.get("settings"))
        buf = io.BytesIO()
        np.savez_compressed(buf, **run.arrays())
        files["elastic.npz"] = buf.getvalue()
        files["elastic.png"] = figure_png(elastic_figure(run, title=f"{design.name}, elastic"))
    # through the output folder's handle, never by its name again
    write_files(outdir, {f"{design.name}/{n}": data for n, data in files.items()})
    return traj, folder, run


def run(args) -> int:
    from ..templates import load_template, with_settings

    valid = ["auto", *METHODS]
    if args.method is not None and args.method not in valid:
        hint = did_you_mean(args.method, valid)
        raise UsageError("--method", f"unknown method {args.method!r}; "
                                     + (f"{hint} " if hint else "") + f"valid: {', '.join(valid)}")
    check_number("--to", args.to)
    if args.model not in MODELS:
        hint = did_you_mean(args.model, MODELS)
        raise UsageError("--model", f"unknown model {args.model!r}; "
                                    + (f"{hint} " if hint else "") + f"valid: {', '.join(MODELS)}")
    elastic = args.model == "elastic"
    if args.steps is not None and not elastic:
        raise UsageError("--steps", "counts the quasi-static steps of --model elastic")
    if args.branch is not None:
        if args.branch < 1:
            raise UsageError("--branch", f"numbers branches from 1, got {args.branch}")
        if args.method is not None and args.method != "branch":
            raise UsageError("--branch", f"leaves a singular start by the branch method; "
                                         f"--method {args.method} does not take it")
    steps = DEFAULT_STEPS if args.steps is None else args.steps
    check_count("--steps", steps, 2, MAX_STEPS, "quasi-static steps")
    if elastic:
        settings = read_settings(args, dict.fromkeys(("motion", "laser", "print", "tolerance")),
                                 "simulate --model elastic reads motion, laser, print and "
                                 "tolerance settings only")
    else:
        settings = read_settings(args, {"motion": None}, "simulate reads motion settings only")
    progress = progress_for(args, NAME)

    def one(path) -> bool:
        from dataclasses import replace

        design = with_settings(load_template(path), settings)
        traj, folder, run = simulate_design(
            design, out_folder(args), args.method, args.to, args.gif, progress,
            {"steps": steps, "settings": settings} if elastic else None, args.branch)
        print(f"== {design.name} -> {folder}")
        if run is not None:
            # the elastic model answers: the rigid trace is shown, its stop is no failure
            print(traj.summary())
            print("\n".join(run.summary()))
            over = run.over()
            if over is not None:
                print(f"fabkit: error: {path}: motion: {over}", file=sys.stderr)
            return over is not None
        ends = spread = None
        if traj.success:
            # reaching the target is not the design happening: every designed end, judged,
            # and how far each module of a chain went
            traced = replace(design, motion=replace(design.motion, to=float(traj.target)))
            ends = judge_ends(traced, traj)
            spread = module_spread(traced, traj)
        where = "" if spread is None else \
            f"\nmodules       {spread.strip()}  {spread.sentence()} (each module's output: how " \
            "far it went, of the drive's travel)"
        if ends is not None and not ends.reached:  # the trace finished, the design did not
            print(traj.summary(status="ends missed", message=(
                f"the drive reached {design.motion.drive} = {traj.target:.10g}, "
                "the designed ends were not")) + where)
            print(f"fabkit: error: {path}: motion.ends: target {design.motion.drive} = "
                  f"{traj.target:.10g} is reached, but {ends.reason}", file=sys.stderr)
            return True
        missed = shape_missed(design, spread) if traj.success else ""
        if missed:
            print(traj.summary(status="shape missed", message=(
                f"the drive reached {design.motion.drive} = {traj.target:.10g}; "
                f"{spread.sentence()}")) + where)
            print(f"fabkit: error: {path}: motion: target {design.motion.drive} = "
                  f"{traj.target:.10g} is reached, but {missed}", file=sys.stderr)
            return True
        local = f"; {spread.sentence()}" if spread is not None and spread.localised else ""
        print(traj.summary(message=f"{traj.message}{local}" if local else None) + where)
        if traj.success:
            if ends is not None:
                print(f"designed ends: every one reached ({ends.basis})")
            return False
        # the files show the motion up to where it stopped; the target was not reached
        target = traj.target
        key = "motion.to" if traj.status in (Status.TURNING_POINT, Status.BRANCH_POINT) \
            else "motion"
        print(f"fabkit: error: {path}: {key}: target {design.motion.drive} = {target:.10g} is "
              f"not reached: {traj.message}", file=sys.stderr)
        return True

    return each_template(args.templates, one, debug=args.debug, progress=progress)
