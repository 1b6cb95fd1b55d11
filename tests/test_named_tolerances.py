"""Every numerical tolerance in fabkit's code has a name that says what it is and where its value
comes from: a float literal below 1e-3 may appear only in fabkit/numerics.py, as the value of an
UPPER_CASE module constant (with its ``#:`` comment), in a documented default (a function's
default argument, an ``options`` dict, a dataclass field) or as a keyword argument's value."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "fabkit"

#: Magnitudes below this are tolerances, floors or nudges; larger literals are ordinary numbers.
SMALL = 1e-3


def bare_literals(source: str) -> list[tuple[int, float]]:
    """(line, value) of every unnamed float literal with 0 < |value| < SMALL in ``source``."""
    tree = ast.parse(source)
    named: set[int] = set()

    def name_all(node):
        named.update(id(sub) for sub in ast.walk(node))

    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None:
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names = [t.id for t in targets if isinstance(t, ast.Name)]
            if names and all(n.isupper() or n == "options" for n in names):
                name_all(node.value)
        elif isinstance(node, ast.ClassDef):  # dataclass fields and class constants
            for stmt in node.body:
                if isinstance(stmt, (ast.Assign, ast.AnnAssign)) and stmt.value is not None:
                    name_all(stmt.value)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            for default in node.args.defaults + [d for d in node.args.kw_defaults if d]:
                name_all(default)
        elif isinstance(node, ast.Call):
            for kw in node.keywords:
                if kw.arg is not None and isinstance(kw.value, (ast.Constant, ast.UnaryOp)):
                    name_all(kw.value)
        elif isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values):
                if isinstance(key, ast.Constant) and isinstance(key.value, str) \
                        and isinstance(value, ast.Constant):
                    named.add(id(value))
    return sorted((node.lineno, node.value) for node in ast.walk(tree)
                  if isinstance(node, ast.Constant) and isinstance(node.value, float)
                  and 0 < abs(node.value) < SMALL and id(node) not in named)


FILES = sorted(p for p in ROOT.rglob("*.py") if p.name != "numerics.py")


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_bare_tolerance(path):
    rel = str(path.relative_to(ROOT))
    found = bare_literals(path.read_text())
    assert not found, f"fabkit/{rel}: bare tolerance literal(s) at " + ", ".join(
        f"line {n} ({v:g})" for n, v in found) + ": name them (numerics.py or an UPPER_CASE " \
        "module constant with a #: comment on where the value comes from)"


def test_the_scanner_finds_a_planted_literal_and_spares_named_ones():
    code = '''
TOL = 1e-9
class C:
    tol: float = 1e-8
def f(x, rtol=1e-7):
    y = g(x, atol=1e-6)
    opts = {"xatol": 1e-14}
    if abs(x) < 2e-10:
        return -5e-12 * y
    return 0.5 * x
'''
    assert bare_literals(code) == [(8, 2e-10), (9, 5e-12)]
