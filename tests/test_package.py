"""Package contracts: public names, typing marker, lint."""

from __future__ import annotations

import importlib.resources
import shutil
import subprocess
import sys
from pathlib import Path
import fabkit

ROOT = Path(__file__).resolve().parents[1]


def test_all_lists_every_public_name_and_each_resolves():
    assert len(set(fabkit.__all__)) == len(fabkit.__all__)
    for name in fabkit.__all__:
        assert getattr(fabkit, name) is not None, name
    # the lazily imported names are public too, and dir() shows them before first use
    assert set(fabkit._LAZY) <= set(fabkit.__all__)
    assert set(fabkit.__all__) <= set(dir(fabkit))


def test_star_import_gives_the_public_names():
    ns: dict = {}
    exec("from fabkit import *", ns)
    assert {"Network", "trace", "chain", "module_map", "design_word"} <= set(ns)


def test_py_typed_ships():
    assert importlib.resources.files("fabkit").joinpath("py.typed").is_file()


def test_ruff_passes_with_the_pinned_config():
    ruff = shutil.which("ruff") or str(Path(sys.executable).with_name("ruff"))
    proc = subprocess.run([ruff, "check", "--no-cache", "fabkit", "tests"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
