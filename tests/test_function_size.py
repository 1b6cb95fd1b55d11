"""Functions a reader can hold: in the folders listed here, no function (methods and nested
functions too) is longer than :data:`MAX_LINES` lines, from its ``def`` line to its last line,
or has a McCabe complexity over :data:`MAX_COMPLEXITY`.

The complexity is counted on the syntax tree, the usual way: 1, plus one for each ``if`` and
``elif``, conditional expression, ``for`` and ``while`` loop, ``except`` handler, ``match``
case, ``if`` of a comprehension, and each operand of a boolean operator after the first. A
function nested in another is counted on its own, not in the one that holds it (its lines are
part of both).
"""

from __future__ import annotations

import ast
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "fabkit"

#: The folders whose functions are held to the limits (more can be added as they are split).
FOLDERS = ["commands", "report", "pipeline", "writers", "check"]

#: Longest function, in lines from its ``def`` line to its last line.
MAX_LINES = 100

#: Highest McCabe complexity of a function.
MAX_COMPLEXITY = 25

_FUNCTIONS = (ast.FunctionDef, ast.AsyncFunctionDef)
_BRANCHES = (ast.If, ast.IfExp, ast.For, ast.AsyncFor, ast.While, ast.ExceptHandler,
             ast.match_case)


def _own_nodes(func: ast.AST):
    """Every node of a function's body, not descending into the functions (and classes) it
    defines: those are measured on their own."""
    stack = list(ast.iter_child_nodes(func))
    while stack:
        node = stack.pop()
        yield node
        if not isinstance(node, (*_FUNCTIONS, ast.ClassDef)):
            stack.extend(ast.iter_child_nodes(node))


def complexity(func: ast.AST) -> int:
    """McCabe complexity of one function node (see the module's docstring)."""
    count = 1
    for node in _own_nodes(func):
        if isinstance(node, _BRANCHES):
            count += 1
        elif isinstance(node, ast.BoolOp):
            count += len(node.values) - 1
        elif isinstance(node, ast.comprehension):
            count += len(node.ifs)
    return count


def measure(source: str, filename: str = "<source>") -> list[tuple[str, int, int, int]]:
    """(qualified name, first line, lines, complexity) of every function in a source."""
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, _FUNCTIONS):
                name = f"{prefix}{child.name}"
                first = min([child.lineno] + [d.lineno for d in child.decorator_list])
                out.append((name, first, child.end_lineno - child.lineno + 1,
                            complexity(child)))
                visit(child, f"{name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(source, filename), "")
    return out


def _too_big(source: str, filename: str = "<source>") -> list[str]:
    return [f"{filename}:{line} {name}: {lines} lines, complexity {cc}"
            for name, line, lines, cc in measure(source, filename)
            if lines > MAX_LINES or cc > MAX_COMPLEXITY]


@pytest.mark.parametrize("folder", FOLDERS)
def test_functions_are_short_and_simple(folder):
    files = sorted((ROOT / folder).rglob("*.py"))
    assert files, f"fabkit/{folder} holds no Python file"
    found = [bad for path in files
             for bad in _too_big(path.read_text(encoding="utf-8"),
                                 str(path.relative_to(ROOT.parent)))]
    assert not found, "split these into named steps:\n" + "\n".join(found)


def test_the_measure_counts_lines_and_branches():
    source = textwrap.dedent('''
        def simple(x):
            return x

        def branchy(x, xs):
            if x and x > 1 or not xs:
                return [y for y in xs if y if y > 0]
            elif x:
                pass
            for y in xs:
                while y:
                    y = y - 1 if y > 2 else 0
            try:
                pass
            except ValueError:
                pass
            except KeyError:
                pass
            match x:
                case 1:
                    pass
                case _:
                    pass

        class Holder:
            def method(self):
                def inner():
                    if self:
                        return 1
                return inner
        ''')
    found = {name: (lines, cc) for name, _, lines, cc in measure(source)}
    # branchy: 1 + if, elif (2) + and/or (2) + comprehension ifs (2) + for, while (2)
    # + ternary (1) + handlers (2) + cases (2)
    assert found == {"simple": (2, 1), "branchy": (19, 14), "Holder.method": (5, 1),
                     "Holder.method.inner": (3, 2)}


def test_a_function_too_long_or_too_complex_is_named():
    long_body = "\n".join(f"    x{i} = {i}" for i in range(MAX_LINES))
    complex_body = "\n".join(f"    if x == {i}:\n        return {i}"
                             for i in range(MAX_COMPLEXITY))
    source = f"def long():\n{long_body}\n\ndef tangled(x):\n{complex_body}\n\ndef fine():\n" \
             "    pass\n"
    found = _too_big(source, "synthetic.py")
    assert found == [f"synthetic.py:1 long: {MAX_LINES + 1} lines, complexity 1",
                     f"synthetic.py:{MAX_LINES + 3} tangled: {2 * MAX_COMPLEXITY + 1} lines, "
                     f"complexity {MAX_COMPLEXITY + 1}"]
