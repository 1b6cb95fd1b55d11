"""Layers import one way: a walk over every import in fabkit/, including imports inside functions.

Data flows template → network → kinematics/maps → fab geometry → export → check, with the batch
engine, the studies and the CLI on top. A module may import its own layer or any layer below it,
never one above; and only the template reader and the layers that take template paths from a user
read template files.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "fabkit"

#: Rank of each top-level part of the package; an import must not go to a higher rank.
LAYERS = {
    "errors": 0,
    "executor": 0,
    "io": 0,
    "io.outputs": 0,
    "stoppable": 0,
    "status": 0,
    "io.inputs": 0,
    "io.workload": 0,
    "io.schema": 0,
    "io.progress": 0,
    "io.suggest": 0,
    "arguments": 1,
    "numerics": 1,
    "model": 1,
    "model.network": 1,
    "model.rigidity": 2,
    "model.construction": 2,
    "model.certificate": 2,
    "model.independent_edges": 2,
    "kinematics": 3,
    "builds": 3,
    "maps": 4,
    "design.solution_space": 4,
    "design.assemble": 5,
    "design.letters": 5,
    "templates": 6,
    "design": 6,
    "report": 7,
    "plots": 7,
    "plots.viz": 7,
    "plots.animate": 7,
    "plots.mapplots": 7,
    "plots.designplots": 7,
    "settings": 7,
    "fab": 9,
    "motion": 8,
    "tolerance": 10,
    "writers": 11,
    "check": 12,
    "report.text": 13,
    "report.html": 13,
    "pipeline": 14,
    "sweep": 14,
    "bench": 15,
    "commands": 16,
    "cli": 17,
    "__main__": 18,
}

#: Only these may read template files (call the template loader): the reader itself, and the
#: layers that take template paths from a user (the command line, the batch engine behind
#: ``fabkit export``, sweeps, and the studies, which load the paper's bundled modules). Every
#: other stage gets a loaded Design, with the templates it refers to in ``Design.references``.
TEMPLATE_READERS = {"templates", "commands", "cli", "pipeline", "sweep", "bench"}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path, source: str | None = None):
    """(line, absolute target module, imported names) for every import in the file."""
    mod = _module_name(path)
    package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
    text = path.read_text(encoding="utf-8") if source is None else source
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            yield node.lineno, target, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name, []


def _part(module: str) -> str | None:
    """The entry of LAYERS a module belongs to: its longest dotted prefix under ``fabkit``
    (``model.network``, ``design.assemble``), else its top-level part."""
    pieces = module.split(".")
    if len(pieces) < 2 or pieces[0] != "fabkit":
        return None
    for end in range(len(pieces), 1, -1):
        key = ".".join(pieces[1:end])
        if key in LAYERS:
            return key
    return pieces[1]


FILES = sorted(p for p in ROOT.rglob("*.py"))


def test_every_part_has_a_layer():
    parts = {_part(_module_name(p)) for p in FILES} - {None}
    assert parts <= set(LAYERS), f"add {sorted(parts - set(LAYERS))} to LAYERS"


def _upward(path: Path, source: str | None = None) -> list[tuple[int, str]]:
    here = _part(_module_name(path))
    if here is None:  # fabkit/__init__.py re-exports the public names
        return []
    upward = []
    for line, target, names in _imports(path, source):
        if not target.startswith("fabkit"):
            continue
        # `from fabkit.model import network` imports the module fabkit.model.network; a name
        # re-exported by the package root (`from fabkit import Network`) has no layer of its own
        for there in sorted({_part(f"{target}.{n}") for n in names} or {_part(target)}):
            if there in LAYERS and LAYERS[there] > LAYERS[here]:
                upward.append((line, f"fabkit.{there}"))
    return upward


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT.parent)))
def test_imports_go_down_only(path):
    here = _part(_module_name(path))
    upward = _upward(path)
    assert not upward, (f"{path.relative_to(ROOT.parent)} ({here}, layer {LAYERS[here]}) imports "
                        + ", ".join(f"{t} at line {n}" for n, t in upward))


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT.parent)))
def test_only_the_template_reader_reads_templates(path):
    here = _part(_module_name(path))
    if here in TEMPLATE_READERS or here is None:
        return
    readers = [line for line, target, names in _imports(path)
               if (target.endswith("templates") and "load_template" in names)
               or (target == "fabkit" and "load_template" in names)]
    assert not readers, (f"{path.relative_to(ROOT.parent)} imports load_template at lines "
                         f"{readers}: referenced templates are resolved by fabkit.templates")


def test_the_walk_sees_imports_inside_functions():
    # An upward import hidden in a function body is caught, with its line; a downward one is not.
    src = ("import numpy\n\ndef f():\n    from ..writers import stl\n"
           "    from .network import Network\n")
    assert _upward(ROOT / "model" / "rigidity.py", src) == [(4, "fabkit.writers")]
    assert _upward(ROOT / "fab" / "bars.py", "def g():\n    from ..check import dxf\n") == [
        (2, "fabkit.check")]
    assert _upward(ROOT / "fab" / "bars.py", "from fabkit import pipeline\n") == [
        (1, "fabkit.pipeline")]
