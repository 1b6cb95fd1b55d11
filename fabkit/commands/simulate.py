"""``fabkit simulate TEMPLATE``: trace the template's motion, write .npz + PNG, print a summary."""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np

from ..errors import UsageError
from ..io.outputs import inside, write_files
from ..io.schema import refuse_unused
from ..io.suggest import did_you_mean
from ..kinematics import METHODS, Status
from ..motion import judge_ends
from ..report.viz import figure_png, motion_figure
from . import (add_out_dir, add_progress_options, add_settings, check_number, each_template,
               Example, progress_for)
from .settings import parse_settings

NAME = "simulate"
HELP = "trace a template's motion; writes trajectory.npz and motion.png"

EXAMPLES = [
    Example("fabkit simulate fourbar --method projected",
            "trace the 4-bar with the continuation method; out/fourbar/trajectory.npz, motion.png"),
    Example("fabkit simulate super_stable_chain8 --gif --set motion.to=1.5",
            "the chain driven part of the way (d1 = 1.5), with an animated motion.gif"),
    Example("fabkit simulate origami_sheet --method branch -o out/sim",
            "leave the flat sheet on a branch (the bifurcation method)"),
]


def add_arguments(p):
    p.add_argument("templates", nargs="+", metavar="TEMPLATE", help="template file(s)")
    p.add_argument("--method", default=None, metavar="METHOD",
                   help=f"{', '.join(['auto', *METHODS])} (default: the template's)")
    p.add_argument("--to", type=float, default=None, help="target value of the drive")
    add_out_dir(p, "out", "output folder (default: out); results go to DIR/<name>/")
    add_settings(p, "override a motion setting, e.g. --set motion.to=1.5 or "
                    "--set motion.method=projected (repeatable)")
    p.add_argument("--gif", action="store_true", help="also write an animated motion.gif")
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


def simulate_design(design, outdir: Path, method=None, to=None, gif=False, progress=None):
    say = progress.stage if progress is not None else (lambda text: None)

    overrides = {}
    if method:
        overrides["method"] = method
    if to is not None:
        overrides["to"] = to
    folder = inside(outdir, design.name)  # before the work
    say(f"{design.name}: tracing the motion")
    traj = design.trace(**overrides)
    say(f"{design.name}: drawing")
    files = {"trajectory.npz": trajectory_npz(traj),
             "motion.png": figure_png(motion_figure(traj, title=design.name))}
    if gif:
        from ..report.animate import motion_gif

        say(f"{design.name}: animating motion.gif")
        files["motion.gif"] = motion_gif(traj)
    write_files(folder, files)
    return traj, folder


def run(args) -> int:
    from ..io.templates import load_template, with_settings

    valid = ["auto", *METHODS]
    if args.method is not None and args.method not in valid:
        hint = did_you_mean(args.method, valid)
        raise UsageError("--method", f"unknown method {args.method!r}; "
                                     + (f"{hint} " if hint else "") + f"valid: {', '.join(valid)}")
    check_number("--to", args.to)
    settings = parse_settings(args.settings)
    refuse_unused(settings, {"motion"}, "simulate reads motion settings only")
    progress = progress_for(args, NAME)

    def one(path) -> bool:
        from dataclasses import replace

        design = with_settings(load_template(path), settings)
        traj, folder = simulate_design(design, Path(args.out_dir), args.method, args.to,
                                       args.gif, progress)
        print(f"== {design.name} -> {folder}")
        ends = None
        if traj.success:
            # reaching the target is not the design happening: every designed end, judged
            traced = replace(design, motion=replace(design.motion, to=float(traj.target)))
            ends = judge_ends(traced, traj)
        if ends is not None and not ends.reached:  # the trace finished, the design did not
            print(traj.summary(status="ends missed", message=(
                f"the drive reached {design.motion.drive} = {traj.target:.10g}, "
                "the designed ends were not")))
            print(f"fabkit: error: {path}: motion.ends: target {design.motion.drive} = "
                  f"{traj.target:.10g} is reached, but {ends.reason}", file=sys.stderr)
            return True
        print(traj.summary())
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
