"""Every shell and Python block of README.md and docs/*.md runs as written, in a fresh folder.

The blocks, their languages and the marks that say how a block is run (``slow``, ``continues``,
``exits N``, ``checkout``, ``cluster``, ``not run: REASON``) are described in tests/docs_blocks.py.
A block without a language, or a shell or Python block that is neither run nor marked as not run
with a reason, fails ``test_every_block_is_run_or_marked``: a new example cannot be left untried.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from pathlib import Path

import pytest

from docs_blocks import (DATA_LANGUAGES, PAGES, ROOT, RUN_LANGUAGES, all_blocks, blocks,
                         comparable_lines, runnable_chains)

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
    printed = comparable_lines(proc.stdout + "\n" + proc.stderr)
    at = 0
    for line in block.quoted_lines:
        assert line in printed[at:], (f"{block.name}: the docs quote a line that "
                                      f"`{block.output_of}` does not print (after its line {at}):"
                                      f"\n  {line}\nit printed:\n" + "\n".join(printed))
        at = printed.index(line, at) + 1


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


def test_tables_are_what_the_code_computes():
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "docs_tables.py"), "--check"],
                          env=_environment(), capture_output=True, text=True, timeout=TIMEOUT)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_every_block_is_run_or_marked():
    problems = []
    for b in all_blocks():
        if b.language not in RUN_LANGUAGES | DATA_LANGUAGES:
            problems.append(f"{b.name}: fence without a known language ({b.language!r}); "
                            f"use one of {sorted(RUN_LANGUAGES | DATA_LANGUAGES)}")
        elif b.language in RUN_LANGUAGES and not b.runs:
            if not any(m == "cluster" or (m.startswith("not run:") and m[8:].strip())
                       for m in b.marks):
                problems.append(f"{b.name}: not run and no reason given")
        if b.exit_status and b.language != "sh" and not b.output_of:
            problems.append(f"{b.name}: 'exits N' is for shell blocks and quoted output")
        if b.output_of and b.language != "text":
            problems.append(f"{b.name}: 'output of' is for text blocks")
        shown = [re.sub(r"\s+#.*$", "", line[2:]).strip() for line in b.code.splitlines()
                 if line.startswith("$ ")]
        if b.output_of and shown and shown != [b.output_of]:
            problems.append(f"{b.name}: shows `$ {shown}`, runs `{b.output_of}`")
        if b.has("continues") and b.runs:
            before = [x for x in blocks(b.page) if x.line < b.line]
            if not before:
                problems.append(f"{b.name}: 'continues' on the first block of the page")
    assert not problems, "\n".join(problems)


def test_toml_blocks_parse():
    for b in all_blocks():
        if b.language == "toml":
            tomllib.loads(b.code)


def test_marks_are_known_words():
    bad = [f"{b.name}: {m!r}" for b in all_blocks() for m in b.marks
           if m not in ("slow", "continues", "checkout", "cluster")
           and not m.startswith(("exits ", "not run:", "output of:"))]
    assert not bad, "unknown marks (see tests/docs_blocks.py):\n" + "\n".join(bad)


def test_pages_are_found():
    names = {p.name for p in PAGES}
    assert {"README.md", "laser.md", "batch.md", "maps.md"} <= names
    assert sum(1 for _ in runnable_chains()) > 10
