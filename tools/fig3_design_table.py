"""The table of docs/design.md: paper modules redesigned from their map wishes.

For each module, the map of the paper's own geometry (``fabkit.module_map`` of
``tests/data/paper_modules.json``) beside the module ``fabkit design`` builds from the wish
(:func:`fabkit.design.design_map` with the command's simulated laser builds), its wished fixed
points recomputed from the template it writes: residual |f(D) − D| and slope.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

from paper_modules_table import number  # a sibling file: run from tools/, or by docs_tables

ROOT = Path(__file__).resolve().parents[1]
PAPER_MODULES = ROOT / "tests" / "data" / "paper_modules.json"

#: module, figure, the wish as given on the command line.
WISHES = (
    ("slope_one", "Fig 3a", "--fixed-point 1.7320508075688772:1"),
    ("slope_one_and_a_half", "Fig 3c", "--fixed-point 1.7320508075688772:1.5"),
    ("super_stable", "Fig 3e", "--fixed-point 1.7320508075688772:0 --fixed-point 1.009950494"),
    ("fixed_point", "Fig 1j–l",
     "--fixed-point 1.7320508075688772:0 --fixed-point 2.9444863728670914"),
)


def _paper(module: dict) -> str:
    """The fixed points of the paper's geometry on its start's branch."""
    import fabkit

    net = fabkit.Network(module["nodes"], module["edges"],
                         ports={"d1": tuple(module["d1"]), "d2": tuple(module["d2"])})
    f = fabkit.module_map(net)
    if f.is_identity():
        return "s = 1 (f = identity on the branch)"
    return "; ".join(f"s = {number(p.slope)} at {p.value:.10g}" for p in f.fixed_points())


def _designed(wish: str) -> str:
    """The wished fixed points of the module ``fabkit design`` builds, from its template."""
    import fabkit
    from fabkit.tolerance.builds import laser_builds
    from fabkit.design import design_map

    points = wish.replace("--fixed-point", "").split()
    result = design_map(points, name="fig", sample_builds=laser_builds)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fig.toml"
        path.write_text(result.template)
        design = fabkit.load_template(path)
    f = fabkit.module_map(design.network, toward=design.motion.to)
    parts = []
    for text in points:
        d = float(text.split(":")[0])
        parts.append(f"s = {number(float(f.derivative(d)))} at {d:.10g} (residual "
                     f"{number(abs(float(f(d)) - d), 2)})")
    others = [p for p in f.fixed_points()
              if all(abs(p.value - float(t.split(":")[0])) > 1e-6 for t in points)]
    parts.append("no other fixed point" if not others else
                 "also " + ", ".join(f"{p.value:.10g} (s = {number(p.slope)})" for p in others))
    return "; ".join(parts)


def fig3_design_table() -> str:
    """Markdown rows: each module's wish, its paper geometry's map and the designed module's."""
    modules = json.loads(PAPER_MODULES.read_text())["modules"]
    rows = ["| module (figure) | wish | as built from the paper's coordinates | `fabkit design` |",
            "|---|---|---|---|"]
    for name, figure, wish in WISHES:
        rows.append(f"| {name} ({figure}) | `{wish}` | {_paper(modules[name])} | "
                    f"{_designed(wish)} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(fig3_design_table())
