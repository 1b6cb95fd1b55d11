"""``fabkit simulate TEMPLATE``: trace the template's motion, write .npz + PNG, print a summary."""

from __future__ import annotations

import io
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
    from ..export import write_atomic
    from ..viz import figure_png, motion_figure

    overrides = {}
    if method:
        overrides["method"] = method
    if to is not None:
        overrides["to"] = to
    traj = design.trace(**overrides)
    npz = trajectory_npz(traj)
    png = figure_png(motion_figure(traj, title=design.name))
    extra = {}
    if gif:
        from ..animate import motion_gif

        extra["motion.gif"] = motion_gif(traj)
    folder = outdir / design.name
    write_atomic(folder / "trajectory.npz", npz)
    write_atomic(folder / "motion.png", png)
    for name, data in extra.items():
        write_atomic(folder / name, data)
    return traj, folder


def run(args) -> int:
    from ..errors import UsageError
    from ..kinematics import METHODS, Status
    from ..templates import load_template
    from . import check_number, expand_templates

    if args.method is not None and args.method != "auto" and args.method not in METHODS:
        raise UsageError("--method", f"unknown method {args.method!r}; valid: auto, "
                                     f"{', '.join(METHODS)}")
    check_number("--to", args.to)
    failed = 0
    for path in expand_templates(args.templates):
        design = load_template(path)
        traj, folder = simulate_design(design, Path(args.out), args.method, args.to, args.gif)
        print(f"== {design.name} -> {folder}")
        print(traj.summary())
        failed += traj.status is Status.FAILED
    return 1 if failed else 0
