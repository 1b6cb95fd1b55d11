"""Tables of results in the docs, made from what the code computes now.

A generated table sits between two marks in a page::

    <!-- docs-table: letters -->
    | letter | modules | ... |
    <!-- /docs-table -->

``python tools/docs_tables.py`` runs the commands behind every table and writes the tables into
the pages; ``python tools/docs_tables.py --check`` writes nothing and exits 1 naming every table
that differs from what the code gives (tests/test_docs_blocks.py runs the check: ``--fast`` in
the fast suite, the tables of :data:`SLOW` in the slow one).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FABKIT = [sys.executable, "-m", "fabkit"]


def _run_fabkit(args: list[str], cwd: Path) -> None:
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run(FABKIT + args, cwd=cwd, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"fabkit {' '.join(args)} exited {proc.returncode}: {proc.stderr[-2000:]}")


def letters_table() -> str:
    """The letters of ``fabkit letters NETWORK``: modules and errors of the simulated final states.

    Errors are relative to the letter height (40), as ``network_fit.json`` gives them.
    """
    with tempfile.TemporaryDirectory() as folder:
        _run_fabkit(["letters", "NETWORK", "-o", "letters"], Path(folder))
        fit = json.loads((Path(folder) / "letters" / "network_fit.json").read_text())
    rows = ["| letter | modules | rms | max | end |", "|---|---|---|---|---|"]
    for row in fit["letters"]:
        rows.append(f"| {row['letter']} | {row['modules']} | {row['rms_error']:.4f} | "
                    f"{row['max_error']:.4f} | {row['end_error']:.4f} |")
    return "\n".join(rows)


def curvature_modules_table() -> str:
    """The final shape of each bundled curvature module (``fabkit.design.letters.
    curvature_modules`` at the D2* of ``curvature_expand.toml``, as ``fabkit letters`` uses
    them): bottom distance and apex angle."""
    import math

    from fabkit.design.letters import curvature_modules
    from fabkit.templates import bundled_folder, load_template

    names = ("contract", "maintain", "expand")
    designs = {n: load_template(bundled_folder() / f"curvature_{n}.toml") for n in names}
    final = float(designs["expand"].motion.to)
    modules = curvature_modules({n: d.network for n, d in designs.items()}, final)
    rows = ["| module | final bottom | apex angle |", "|---|---|---|"]
    for m in modules:
        rows.append(f"| {m.name} | {m.bottom:.8f} | {math.degrees(m.apex):.1f}° |")
    return "\n".join(rows)


def _sibling(name: str):
    """The module ``tools/<name>.py`` (tools/ is no package: its folder joins the path)."""
    import importlib

    here = str(Path(__file__).resolve().parent)
    if here not in sys.path:
        sys.path.insert(0, here)
    return importlib.import_module(name)


def paper_modules_table() -> str:
    """The map of every paper module and its labels checked (tools/paper_modules_table.py)."""
    return _sibling("paper_modules_table").paper_modules_table()


def paper_notes_table() -> str:
    """The paper's labels against the computed maps (tools/paper_modules_table.py)."""
    return _sibling("paper_modules_table").paper_notes_table()


def fig3_design_table() -> str:
    """Paper modules redesigned from their map wishes (tools/fig3_design_table.py)."""
    return _sibling("fig3_design_table").fig3_design_table()


def tolerance_table() -> str:
    """The tolerance verdict of every bundled design (tools/tolerance_table.py)."""
    return _sibling("tolerance_table").tolerance_table()


#: table name -> (page, function making the table's markdown)
TABLES = {"letters": ("docs/assembly.md", letters_table),
          "paper_modules": ("docs/maps.md", paper_modules_table),
          "curvature_modules": ("docs/assembly.md", curvature_modules_table),
          "paper_notes": ("docs/paper_notes.md", paper_notes_table),
          "fig3_design": ("docs/design.md", fig3_design_table),
          "tolerance": ("docs/batch.md", tolerance_table)}

#: Tables that take minutes to make (the slow suite checks them): ``--fast`` leaves them out.
SLOW = {"tolerance"}

_SPAN = r"(<!-- docs-table: {name} -->\n)(.*?)(\n<!-- /docs-table -->)"


def table_in_page(name: str) -> str:
    """The table ``name`` as the page holds it now."""
    page, _ = TABLES[name]
    text = (ROOT / page).read_text(encoding="utf-8")
    m = re.search(_SPAN.format(name=re.escape(name)), text, re.S)
    if not m:
        raise LookupError(f"{page}: no '<!-- docs-table: {name} -->' ... '<!-- /docs-table -->'")
    return m.group(2)


def write_table(name: str, table: str) -> None:
    """Put ``table`` between the marks of ``name`` in its page."""
    page, _ = TABLES[name]
    path = ROOT / page
    text = path.read_text(encoding="utf-8")
    table_in_page(name)
    new = re.sub(_SPAN.format(name=re.escape(name)), lambda m: m.group(1) + table + m.group(3),
                 text, flags=re.S)
    path.write_text(new, encoding="utf-8")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 if a page's table differs from the code's")
    parser.add_argument("--fast", action="store_true",
                        help=f"leave out the tables that take minutes ({', '.join(sorted(SLOW))})")
    parser.add_argument("names", nargs="*", help=f"tables (default: all of {sorted(TABLES)})")
    args = parser.parse_args(argv)
    stale = []
    unknown = [n for n in args.names if n not in TABLES]
    if unknown:
        parser.error(f"unknown table {unknown[0]!r}; known: {', '.join(sorted(TABLES))}")
    for name in args.names or sorted(set(TABLES) - (SLOW if args.fast else set())):
        table = TABLES[name][1]()
        if table_in_page(name) == table:
            continue
        if args.check:
            stale.append(f"{TABLES[name][0]}: table '{name}' differs from the code's:\n{table}")
        else:
            write_table(name, table)
            print(f"{TABLES[name][0]}: table '{name}' rewritten")
    for line in stale:
        print(line)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
