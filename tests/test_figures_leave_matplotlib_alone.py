"""Library code builds matplotlib Figure objects and never switches a user's backend.

A notebook or an application that uses fabkit keeps the matplotlib it set up: fabkit never
calls ``matplotlib.use`` nor imports pyplot (whose import picks a backend and keeps a list of
open figures); each picture gets its own Agg canvas (:data:`fabkit.plots.viz.figure_kit`).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import fabkit

from conftest import TEMPLATES

ROOT = Path(fabkit.__file__).parent


def test_no_library_module_switches_the_backend_or_imports_pyplot():
    offenders = []
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and (
                    node.func.attr == "use" and isinstance(node.func.value, ast.Name)
                    and node.func.value.id == "matplotlib"):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} matplotlib.use")
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [f"{node.module}.{a.name}" for a in node.names]
                     if isinstance(node, ast.ImportFrom) and node.module else [])
            offenders += [f"{path.relative_to(ROOT)}:{node.lineno} imports {n}" for n in names
                          if n.startswith("matplotlib.pyplot")]
    assert offenders == []


def test_an_export_leaves_the_users_backend_and_figures_as_they_were(tmp_path):
    # a user who chose the PDF backend and has a figure open exports a design with pictures
    script = f"""
import matplotlib
matplotlib.use("pdf")
import sys
import fabkit
from fabkit.writers import export
d = fabkit.load_template({str(TEMPLATES / "super_stable.toml")!r})
export(d, "dxf", {str(tmp_path)!r})
print(matplotlib.get_backend(), "matplotlib.pyplot" in sys.modules)
"""
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["pdf", "False"]
    assert any(p.suffix == ".png" for p in tmp_path.iterdir())  # pictures were drawn
