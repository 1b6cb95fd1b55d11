"""The API reference's configuration (docs/conf.py), without building it: ``make docs`` builds
it with warnings as errors, and fails by itself when a public function or class, or a name of
``fabkit.__all__``, is left out. Here: the docstrings' plain-text bars stay text, and every name
of ``fabkit.__all__`` (those imported on first use too) is linked to the page that documents it.
Those that read the configuration skip without the documentation tools (``pip install -e
'.[docs]'``); CI's entry point builds the reference, and a failed build fails it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "docs" / "conf.py"


@pytest.fixture(scope="module")
def conf():
    for tool in ("sphinx", "numpydoc", "myst_parser"):
        pytest.importorskip(tool)
    spec = importlib.util.spec_from_file_location("fabkit_docs_conf", CONF)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("line, read", [
    ("the distance |x0 - x1| of the two", "the distance \\|x0 - x1\\| of the two"),
    ("[x_Si - x | (x_Si - x)·v_Si]", "[x_Si - x \\| (x_Si - x)·v_Si]"),
    ("``|x|`` and :math:`|x|` stay", "``|x|`` and :math:`|x|` stay"),
    ("no bar at all", "no bar at all"),
])
def test_bars_in_docstrings_are_text_outside_literals(conf, line, read):
    assert conf._escape_bars(line) == read


def test_every_name_of_the_package_is_linked_to_its_page(conf):
    import fabkit

    lines = conf._names_of_fabkit()
    entries = [line for line in lines if line and not line.startswith(" ")]
    assert len(entries) == len(fabkit.__all__)
    for name, entry in zip(fabkit.__all__, entries):
        assert entry.startswith(":") and f"`fabkit.{name} <fabkit." in entry, entry
    assert ":func:`fabkit.chain <fabkit.design.assemble.chain>`" in entries
    assert ":data:`fabkit.METHODS <fabkit.kinematics.tracer.METHODS>`" in entries


def test_the_guide_and_the_reference_are_found_not_listed():
    index = (CONF.parent / "index.rst").read_text()
    assert ":glob:" in index and "\n   *\n" in index  # every docs/*.md page, as it comes
    reference = (CONF.parent / "api" / "reference.rst").read_text()
    assert ":recursive:" in reference and "\n   fabkit\n" in reference  # every public module


def test_ci_builds_the_reference_with_warnings_as_errors():
    run = (ROOT / ".ci" / "run").read_text()
    assert "set -euo pipefail" in run  # any failed step fails the run
    assert [line.split("#")[0].strip() for line in run.splitlines()
            if line.startswith("make ")] == ["make test", "make docs"]
    recipe = (ROOT / "Makefile").read_text().split("\ndocs:", 1)[1].split("\n\n", 1)[0]
    build = [line for line in recipe.splitlines() if "-m sphinx" in line]
    assert len(build) == 1 and " -W " in build[0] and " -E " in build[0], recipe
