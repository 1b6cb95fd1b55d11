"""``fabkit demo [TEMPLATES...] -o out``: the main job on the bundled templates.

Simulates every template's motion and runs every export format that applies to it, writing
one folder per design; prints a summary table. Exits non-zero when any design failed.
"""

from __future__ import annotations

from pathlib import Path

NAME = "demo"
HELP = "simulate and export every bundled template into one folder per design"


def add_arguments(p):
    p.add_argument("templates", nargs="*", default=["templates"], metavar="PATH",
                   help="template files or folders (default: templates)")
    p.add_argument("-o", "--out", default="out", help="output folder (default: out)")


def run(args) -> int:
    from ..errors import FabkitError
    from ..templates import load_template
    from . import expand_templates
    from .simulate import simulate_design

    rows, failed = [], 0
    for path in expand_templates(args.templates):
        try:
            design = load_template(path)
            traj, folder = simulate_design(design, Path(args.out))
            rows.append((design.name, traj.method, str(traj.status), f"{traj.max_edge_error:.1e}",
                         str(folder)))
            failed += str(traj.status) == "failed"
        except FabkitError as exc:
            rows.append((Path(path).stem, "-", "error", "-", str(exc)))
            failed += 1
    widths = [max(len(r[i]) for r in rows + [("design", "method", "status", "edge err", "output")])
              for i in range(5)]
    header = ("design", "method", "status", "edge err", "output")
    for r in [header, *rows]:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths)))
    return 1 if failed else 0
