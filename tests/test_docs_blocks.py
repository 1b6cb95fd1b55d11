"""Every shell and Python block of README.md and docs/*.md runs as written, in a fresh folder.

The blocks, their languages and the marks that say how a block is run (``slow``, ``continues``,
``exits N``, ``checkout``, ``cluster``, ``not run: REASON``) are described in tests/docs_blocks.py.
A block without a language, or a shell or Python block that is neither run nor marked as not run
with a reason, fails ``test_every_block_is_run_or_marked``: a new example cannot be left untried.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from pathlib import Path

import pytest

from docs_blocks import PAGES, ROOT, all_blocks, blocks, missing_line, problems, runnable_chains

VENV_BIN = Path(sys.executable).parent
TIMEOUT = 1800


def _chain_id(run) -> str:
    return run[0].name


def _params():
    out = []
    for run in runnable_chains():
        marks = [pytest.mark.slow] if any(b.slow for b in run) else []
        out.append(pytest.param(run, id=_chain_id(run), marks=marks))
    return out


def _environment() -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{VENV_BIN}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    env.pop("PYTHONPATH", None)
    return env


def _copy_checkout(folder: Path) -> None:
    """What a block written for a clone reads: the checkout's templates and test data."""
    shutil.copytree(ROOT / "templates", folder / "templates",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "tests" / "data", folder / "tests" / "data")


def _steps(run):
    """The run as steps: ('sh', block), ('output', block) or ('python', [blocks, one process])."""
    steps = []
    for b in run:
        if b.language == "python" and steps and steps[-1][0] == "python":
            steps[-1][1].append(b)
        elif b.language == "python":
            steps.append(("python", [b]))
        else:
            steps.append(("output" if b.output_of else "sh", b))
    return steps


def _compare_output(block, proc) -> None:
    """Every quoted line of ``block`` is printed by its command, in order."""
    printed = proc.stdout + "\n" + proc.stderr
    line = missing_line(block, printed)
    assert line is None, (f"{block.name}: the docs quote a line that `{block.output_of}` does "
                          f"not print (or not in this order):\n  {line}\nit printed:\n{printed}")


def _fail_text(what: str, proc) -> str:
    return (f"{what} exited {proc.returncode}\n--- stdout (end)\n{proc.stdout[-3000:]}"
            f"\n--- stderr (end)\n{proc.stderr[-3000:]}")


@pytest.mark.parametrize("run", _params())
def test_block_runs_as_written(run, tmp_path):
    folder = tmp_path / "fresh"
    folder.mkdir()
    if any(b.has("checkout") for b in run):
        _copy_checkout(folder)
    env = _environment()
    for n, (kind, what) in enumerate(_steps(run)):
        if kind in ("sh", "output"):
            script = tmp_path / f"step{n}.sh"
            script.write_text(what.output_of + "\n" if kind == "output" else what.code)
            proc = subprocess.run(["bash", "-e", str(script)], cwd=folder, env=env,
                                  capture_output=True, text=True, timeout=TIMEOUT)
            assert proc.returncode == what.exit_status, _fail_text(what.name, proc)
            if kind == "output":
                _compare_output(what, proc)
        else:
            script = tmp_path / f"step{n}.py"
            script.write_text("".join(b.code for b in what))
            proc = subprocess.run([sys.executable, str(script)], cwd=folder, env=env,
                                  capture_output=True, text=True, timeout=TIMEOUT)
            assert proc.returncode == 0, _fail_text(", ".join(b.name for b in what), proc)


def _check_tables(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "tools" / "docs_tables.py"), "--check",
                           *args], env=_environment(), capture_output=True, text=True,
                          timeout=TIMEOUT)


def test_tables_are_what_the_code_computes():
    """The letters of docs/assembly.md and the paper modules of docs/maps.md."""
    proc = _check_tables("--fast")
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.slow
def test_tolerance_table_is_what_the_code_computes():
    """docs/batch.md's verdict of every bundled design (``fabkit tolerance templates/*.toml``,
    a minute or two)."""
    proc = _check_tables("tolerance")
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_a_table_that_drifted_is_named(tmp_path):
    """The check compares a page's table with the code's: a row changed by hand is caught and
    the table named, and the page is left as it was."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_tables", ROOT / "tools" / "docs_tables.py")
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    page = tmp_path / "docs" / "maps.md"
    page.parent.mkdir()
    real = (ROOT / "docs" / "maps.md").read_text(encoding="utf-8")
    drifted = real.replace("| slope_one_and_a_half | **0** | [1.62724, 2.36603] | "
                           "1.732050808: s = 1.812", "| slope_one_and_a_half | **0** | "
                           "[1.62724, 2.36603] | 1.732050808: s = 1.5")
    assert drifted != real
    page.write_text(drifted, encoding="utf-8")
    tables.ROOT = tmp_path
    assert tables.table_in_page("paper_modules") != tables.TABLES["paper_modules"][1]()
    assert tables.main(["--check", "paper_modules"]) == 1
    assert page.read_text(encoding="utf-8") == drifted
    assert tables.main(["paper_modules"]) == 0
    assert page.read_text(encoding="utf-8") == real


def test_every_block_is_run_or_marked():
    found = [p for page in PAGES for p in problems(blocks(page))]
    assert not found, "\n".join(found)


def test_an_unmarked_block_is_caught(tmp_path):
    page = tmp_path / "new.md"
    page.write_text("<!-- docs: continues -->\n```sh\nfabkit info fourbar\n```\n\n"
                    "```\nfabkit whatever\n```\n\n"
                    "<!-- docs: not run: -->\n```python\nimport fabkit\n```\n\n"
                    "<!-- docs: later -->\n```sh\ntrue\n```\n\n"
                    "<!-- docs: output of: fabkit map chaotic -->\n"
                    "```text\n$ fabkit map fourbar\nmap chaotic\n```\n")
    found = "\n".join(problems(blocks(page)))
    assert "new.md:2: 'continues' on the first block" in found
    assert "new.md:6: fence without a known language ('')" in found
    assert "new.md:11: not run and no reason given" in found
    assert "new.md:16: unknown mark 'later'" in found
    assert "new.md:21: shows `$ fabkit map fourbar`, runs `fabkit map chaotic`" in found
    assert len(found.splitlines()) == 5


def test_a_drifted_number_is_caught(tmp_path):
    page = tmp_path / "quoted.md"
    page.write_text("<!-- docs: output of: fabkit map chaotic -->\n```text\n"
                    "$ fabkit map chaotic\n  fixed point 1.5: slope -1.32864 (unstable)\n"
                    "design in 2.46 s\n```\n")
    block = blocks(page)[0]
    assert block.runs and block.output_of == "fabkit map chaotic"
    printed = "map chaotic\ndesign in 0.9 s\n  fixed point 1.5: slope -1.32864 (unstable)\n"
    assert missing_line(block, printed) == "design in <time>"          # out of order
    printed = "  fixed point 1.5: slope -1.32864 (unstable)\ndesign in 0.9 s\n"
    assert missing_line(block, printed) is None                         # times are the machine's
    printed = "  fixed point 1.5: slope -1.32865 (unstable)\ndesign in 0.9 s\n"
    assert missing_line(block, printed) == "  fixed point 1.5: slope -1.32864 (unstable)"


def test_toml_blocks_parse():
    for b in all_blocks():
        if b.language == "toml":
            tomllib.loads(b.code)


def test_pages_are_found():
    names = {p.name for p in PAGES}
    assert {"README.md", "laser.md", "batch.md", "maps.md"} <= names
    assert sum(1 for _ in runnable_chains()) > 10
