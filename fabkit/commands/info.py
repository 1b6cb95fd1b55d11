"""``fabkit info TEMPLATE``: nodes, edges, modes, self-stress, and whether constructive applies."""

from __future__ import annotations

NAME = "info"
HELP = "describe a template: sizes, mode count, self-stress, applicable methods"


def add_arguments(p):
    p.add_argument("templates", nargs="+", metavar="TEMPLATE", help="template file(s)")
    p.add_argument("--rank-method", choices=("auto", "dense", "sparse"), default="auto",
                   help="how the modes are counted: dense SVD up to 1000 coordinates and the "
                        "certified sparse path beyond (auto), or either one; a dense SVD that "
                        "cannot fit in memory is refused before it starts")


def describe(design, rank_method: str = "auto") -> str:
    from ..errors import ConstructionError
    from ..kinematics import plan_construction
    from ..rigidity import count_modes

    net = design.network
    m = count_modes(net, method=rank_method)
    lines = [f"{design.name}: {design.description}".rstrip(": ")]
    lines.append(f"  dimension     {net.dim}D")
    lines.append(f"  nodes, edges  {net.n_nodes}, {net.n_edges}")
    lines.append(f"  modes         {m}")
    bound = "at least " if m.method == "sparse" else ""
    lines.append(f"  rank gap      {bound}{m.gap:.2e} (smallest kept singular value "
                 f"{m.smallest_nonzero:.2e}; {m.method})")
    ports = ", ".join(f"{k}={v}" for k, v in list(net.ports.items())[:12])
    more = f" ... ({len(net.ports)} ports)" if len(net.ports) > 12 else ""
    lines.append(f"  ports         {ports}{more}")
    drive = design.motion.drive
    if drive in net.ports:
        try:
            plan_construction(net, net.port(drive))
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
    from . import expand_templates

    for path in expand_templates(args.templates):
        print(describe(load_template(path), args.rank_method))
    return 0
