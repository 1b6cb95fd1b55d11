"""``fabkit simulate TEMPLATE``: trace the template's motion, write .npz + PNG, print a summary."""

from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np

NAME = "simulate"
HELP = "trace a template's motion; writes trajectory.npz and motion.png"


def add_arguments(p):
    p.add_argument("templates", nargs="+", metavar="TEMPLATE", help="template file(s)")
    p.add_argument("--method", default=None,
                   help="auto, constructive, projected or rk4-nullspace (default: the template's)")
    p.add_argument("--to", type=float, default=None, help="target value of the drive")
    p.add_argument("-o", "--out", default="out", help="output folder (default: out)")
    p.add_argument("--gif", action="store_true", help="also write an animated motion.gif")


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


def simulate_design(design, outdir: Path, method=None, to=None, gif=False):
    from ..outputs import inside, write_files
    from ..viz import figure_png, motion_figure

    overrides = {}
    if method:
        overrides["method"] = method
    if to is not None:
        overrides["to"] = to
    folder = inside(outdir, design.name)  # before the work
    traj = design.trace(**overrides)
    files = {"trajectory.npz": trajectory_npz(traj),
             "motion.png": figure_png(motion_figure(traj, title=design.name))}
    if gif:
        from ..animate import motion_gif

        files["motion.gif"] = motion_gif(traj)
    write_files(folder, files)
    return traj, folder


def run(args) -> int:
    from ..errors import UsageError
    from ..kinematics import METHODS, Status
    from ..templates import load_template
    from . import check_number, each_template

    if args.method is not None and args.method != "auto" and args.method not in METHODS:
        raise UsageError("--method", f"unknown method {args.method!r}; valid: auto, "
                                     f"{', '.join(METHODS)}")
    check_number("--to", args.to)

    def one(path) -> bool:
        from dataclasses import replace

        from ..motion import judge_ends

        design = load_template(path)
        traj, folder = simulate_design(design, Path(args.out), args.method, args.to, args.gif)
        print(f"== {design.name} -> {folder}")
        print(traj.summary())
        if traj.success:
            # reaching the target is not the design happening: every designed end, judged
            traced = replace(design, motion=replace(design.motion, to=float(traj.target)))
            ends = judge_ends(traced, traj)
            if ends is None:
                return False
            if ends.reached:
                print(f"designed ends: every one reached ({ends.basis})")
                return False
            print(f"fabkit: error: {path}: motion.ends: target {design.motion.drive} = "
                  f"{traj.target:.10g} is reached, but {ends.reason}", file=sys.stderr)
            return True
        # the files show the motion up to where it stopped; the target was not reached
        target = traj.target
        key = "motion.to" if traj.status in (Status.TURNING_POINT, Status.BRANCH_POINT) \
            else "motion"
        print(f"fabkit: error: {path}: {key}: target {design.motion.drive} = {target:.10g} is "
              f"not reached: {traj.message}", file=sys.stderr)
        return True

    return each_template(args.templates, one, debug=args.debug)
