"""``fabkit info TEMPLATE``: nodes, edges, modes, self-stress, and whether constructive applies."""

from __future__ import annotations

from itertools import islice

from ..errors import ConstructionError
from ..templates import with_settings
from ..kinematics.constructive import cached_plan
from ..model.rigidity import count_modes
from . import (add_progress_options, add_settings, Example, expand_templates, progress_for,
               short_list)
from .settings import read_settings

NAME = "info"
HELP = "describe a template: sizes, mode count, self-stress, applicable methods"

EXAMPLES = [
    Example("fabkit info fourbar", "4 nodes, 4 edges, one motion, constructive applies"),
    Example("fabkit info super_stable_chain --rank-method dense",
            "the 24-module chain, its modes counted by a dense SVD too"),
    Example("fabkit info fourbar super_stable origami_sheet", "several templates, a block each"),
]


def add_arguments(p):
    p.add_argument("templates", nargs="+", metavar="TEMPLATE", help="template file(s)")
    p.add_argument("--rank-method", choices=("auto", "structure", "dense", "sparse"),
                   default="auto",
                   help="how the modes are counted: proved from the network's construction "
                        "where it has one, cross-checked by the numeric rank up to 100 000 "
                        "coordinates, the numeric rank alone otherwise (auto); the structural "
                        "proof only (structure); or the numeric rank by a dense SVD or the "
                        "certified sparse path; a dense SVD that cannot fit in memory is refused "
                        "before it starts")

    add_settings(p, "describe the motion as changed, e.g. --set motion.drive=d2 or "
                    "--set motion.to=2.9 (info reads motion settings only)")
    add_progress_options(p)  # many templates, or one large network, take a while


def describe(design, rank_method: str = "auto") -> str:
    net = design.network
    m = count_modes(net, method=rank_method)
    lines = [f"{design.name}: {design.description}".rstrip(": ")]
    lines.append(f"  dimension     {net.dim}D")
    lines.append(f"  nodes, edges  {net.n_nodes}, {net.n_edges}")
    lines.append(f"  modes         {m}")
    if m.certificate == "numeric":
        why = f" ({m.detail})" if m.detail else ""
        lines.append(f"  certificate   numeric rank{why}")
    else:
        lines.append(f"  certificate   {m.certificate}: {m.detail}; margin (smallest "
                     f"intersection sine) {m.margin:.3g}")
    if m.method == "structure":
        lines.append(f"  rank gap      not measured (numeric cross-check {m.cross_check})")
    else:
        bound = "at least " if m.method == "sparse" else ""
        lines.append(f"  rank gap      {bound}{m.gap:.2e} (smallest kept singular value "
                     f"{m.smallest_nonzero:.2e}; {m.method})")
        if m.certificate != "numeric":
            lines.append(f"  cross-check   numeric rank {m.cross_check}")
    # the first twelve read one by one: a chain's million ports are not listed to show twelve
    ports = ", ".join(f"{k}={net.ports[k]}" for k in islice(net.ports, 12))
    more = f" ... ({len(net.ports)} ports)" if len(net.ports) > 12 else ""
    lines.append(f"  ports         {ports}{more}")
    drive = design.motion.drive
    if drive in net.ports:
        try:
            cached_plan(net, net.port(drive))
            cons = f"yes (nodes placed by intersections from {drive})"
        except ConstructionError as exc:
            cons = f"no: {exc}"
        lines.append(f"  constructive  {cons}")
        target = design.motion.to
        tail = f" to {target:.10g}" if target is not None else ""
        lines.append(f"  motion        {drive} = {float(net.port_distance(drive)):.10g}{tail} "
                     f"(method {design.motion.method})")
    return "\n".join(lines)


def run(args) -> int:
    from ..templates import load_template

    settings = read_settings(args, {"motion": None}, "info reads motion settings only")
    found = expand_templates(args.templates)
    progress = progress_for(args, NAME)
    progress.stage(short_list(found), total=len(found), unit="templates")
    for path in found:
        text = describe(with_settings(load_template(path), settings), args.rank_method)
        progress.advance(text=f"{path.name}: described")
        print(text)
    progress.close()
    return 0
