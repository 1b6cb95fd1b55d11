"""The import graph of fabkit: data flows one way, no two modules import each other.

Every ``import`` counts, wherever it stands (a function-level import is still a dependency).
The top of the package stays small enough to read: a few modules beside the packages that show
the flow (model, design, io, kinematics, maps, fab, export, check, tolerance, pipeline, report).
"""

from __future__ import annotations

import ast
from pathlib import Path

import fabkit

ROOT = Path(fabkit.__file__).parent

#: Modules allowed directly under fabkit/ (``__init__.py`` and ``__main__.py`` included).
MAX_TOP_LEVEL = 10


def _modules() -> dict[str, Path]:
    out = {}
    for path in ROOT.rglob("*.py"):
        parts = path.relative_to(ROOT.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _graph(mods: dict[str, Path]) -> dict[str, set[str]]:
    edges = {m: set() for m in mods}
    for m, path in mods.items():
        package = m if path.name == "__init__.py" else m.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                for a in node.names:
                    full = f"{target}.{a.name}"
                    dst = full if full in mods else target
                    if dst in mods and dst != m:
                        edges[m].add(dst)
            elif isinstance(node, ast.Import):
                edges[m].update(a.name for a in node.names if a.name in mods and a.name != m)
    return edges


def _cycles(edges: dict[str, set[str]]) -> list[set[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]
    for root in edges:
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(edges[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = set()
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.add(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    found.append(comp)
    return found


def test_the_graph_is_read_with_function_level_imports():
    edges = _graph(_modules())
    # a function-level import: check/__init__ imports the workload bound inside check_file
    assert "fabkit.io.workload" in edges["fabkit.check"]
    assert "fabkit.model.construction" in edges["fabkit.kinematics.constructive"]


def test_a_planted_cycle_is_found():
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(edges) == [{"a", "b", "c"}]


def test_no_import_cycle():
    cycles = [sorted(c) for c in _cycles(_graph(_modules()))]
    assert cycles == [], "modules that import each other: " + "; ".join(" <-> ".join(c)
                                                                         for c in cycles)


def _unit(module: str) -> str:
    """The package-level unit of a module: its package directly under fabkit/, or the top-level
    module itself (``fabkit.templates``, ``fabkit.cli``); the root ``fabkit`` is its own unit."""
    parts = module.split(".")
    return ".".join(parts[:2])


def _package_graph(edges: dict[str, set[str]]) -> dict[str, set[str]]:
    """Edges between units (:func:`_unit`), the root's own ``__init__`` left out: it re-exports
    the public names of the packages below it and imports nothing back."""
    out: dict[str, set[str]] = {}
    for m, targets in edges.items():
        src = _unit(m)
        if src == "fabkit":
            continue
        out.setdefault(src, set()).update(_unit(t) for t in targets if _unit(t) not in (src,
                                                                                    "fabkit"))
    return out


def test_a_planted_package_cycle_is_found():
    edges = {"fabkit.a.x": {"fabkit.b.y"}, "fabkit.b.y": {"fabkit.b.z"},
             "fabkit.b.z": {"fabkit.a.w"}, "fabkit.a.w": set(), "fabkit.c": {"fabkit.a.x"}}
    assert _cycles(_package_graph(edges)) == [{"fabkit.a", "fabkit.b"}]


def test_no_package_imports_another_that_imports_it_back():
    graph = _package_graph(_graph(_modules()))
    # the walk sees packages and top-level modules as units
    assert {"fabkit.motion", "fabkit.tolerance", "fabkit.templates", "fabkit.cli"} <= set(graph)
    assert "fabkit.kinematics" in graph["fabkit.templates"]
    cycles = [sorted(c) for c in _cycles({k: graph.get(k, set()) | set()
                                          for k in set(graph).union(*graph.values())})]
    assert cycles == [], "packages that import each other: " + "; ".join(" <-> ".join(c)
                                                                          for c in cycles)


def test_few_modules_at_the_top():
    top = sorted(p.name for p in ROOT.glob("*.py"))
    assert "cli.py" in top and "errors.py" in top  # the walk sees the package's own top
    assert len(top) <= MAX_TOP_LEVEL, f"{len(top)} modules at the top of fabkit/: {top}"


#: Imports of another fabkit module's ``_private`` names (dunders excluded): none. A name another
#: module needs is public (no underscore) or lives in the module that uses it.
MAX_UNDERSCORE_IMPORTS = 0

#: Import statements of fabkit modules inside functions rather than at a module's top. This only
#: goes down: hoist one when it makes no cycle, pulls no heavy library into ``fabkit.cli`` and is
#: not a name tests replace on its module (they must be looked up at call time).
MAX_FUNCTION_LEVEL_IMPORTS = 150


def _imports(mods: dict[str, Path]):
    """Yield (module, path, line, target, name, at_top) for every ``from fabkit... import``."""
    for m, path in mods.items():
        package = m if path.name == "__init__.py" else m.rsplit(".", 1)[0]
        tree = ast.parse(path.read_text(), str(path))
        top = {id(n) for n in tree.body}
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "fabkit":
                continue
            for a in node.names:
                yield m, path, node.lineno, target, a.name, id(node) in top


def _underscore_imports(mods: dict[str, Path]) -> list[str]:
    found = []
    for m, path, line, target, name, _ in _imports(mods):
        private = name.startswith("_") and not name.startswith("__")
        if private and target != m and f"{target}.{name}" not in mods:
            found.append(f"{path.relative_to(ROOT.parent)}:{line} {name} from {target}")
    return found


def _function_level_imports(mods: dict[str, Path]) -> int:
    return len({(path, line) for _, path, line, _, _, at_top in _imports(mods) if not at_top})


def test_private_names_stay_in_their_module():
    found = _underscore_imports(_modules())
    assert len(found) <= MAX_UNDERSCORE_IMPORTS, (
        f"{len(found)} imports of another module's private names (at most "
        f"{MAX_UNDERSCORE_IMPORTS}):\n" + "\n".join(found))


def test_function_level_imports_only_go_down():
    count = _function_level_imports(_modules())
    assert count <= MAX_FUNCTION_LEVEL_IMPORTS, (
        f"{count} function-level fabkit imports, at most {MAX_FUNCTION_LEVEL_IMPORTS}")


_IMPORT_EACH = """
import importlib, sys
failed = []
for name in sys.argv[1:]:
    for loaded in [m for m in sys.modules if m == "fabkit" or m.startswith("fabkit.")]:
        del sys.modules[loaded]
    try:
        importlib.import_module(name)
    except Exception as exc:
        failed.append(f"{name}: {type(exc).__name__}: {exc}")
print("\\n".join(failed))
"""


def test_every_module_imports_first():
    # the graph above is of modules; importing a module also runs its packages' __init__, so a
    # package that imports (at its top) a module whose package imports it back fails only when
    # it is imported first: import each module first, in a fresh set of fabkit modules
    import subprocess
    import sys

    names = sorted(m for m in _modules() if not m.endswith("__main__"))
    run = subprocess.run([sys.executable, "-c", _IMPORT_EACH, *names], capture_output=True,
                         text=True, env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin",
                                         "PYTHONPATH": str(ROOT.parent)}, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip() == "", run.stdout
