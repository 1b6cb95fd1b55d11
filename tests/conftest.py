"""Shared fixtures: the paper's modules as networks, paths to bundled templates.

Module networks come from the bundled templates (templates/<name>.toml), the one home of the
paper's geometry in fabkit. tests/data/paper_modules.json is the paper's own input data: it is read
only for the design specifications it alone holds and as the independent reference that the
templates are checked against (tests/test_templates.py).
"""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path

import pytest

import fabkit

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"

if os.environ.get("PYTEST_XDIST_WORKER"):
    # one BLAS thread per test worker: `make test` runs a worker per core, and each worker's
    # BLAS taking every core as well would only make them wait on one another
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


def _find_modules_json() -> Path:
    for cand in (ROOT / "tests" / "data" / "paper_modules.json",):
        if cand.exists():
            return cand
    raise FileNotFoundError("paper_modules.json")


@pytest.fixture(scope="session")
def paper_modules() -> dict:
    """The paper's input data (design specifications, and the reference for the templates)."""
    return json.loads(_find_modules_json().read_text())["modules"]


@functools.lru_cache(maxsize=None)
def module_network(name: str) -> fabkit.Network:
    """A module of the paper as its bundled template builds it (ports d1, d2)."""
    return fabkit.load_template(TEMPLATES / f"{name}.toml").network


@pytest.fixture(scope="session")
def fourbar() -> fabkit.Network:
    return module_network("fourbar")


@pytest.fixture(scope="session")
def module():
    """Factory: module("super_stable") -> Network with ports d1, d2."""
    return module_network


@pytest.fixture
def dense_copies(monkeypatch) -> list:
    """The shapes of the sparse matrices made dense during the test (any sparse format): work
    that grows as the square of a network's size, checked without timing it."""
    import scipy.sparse as sp

    shapes = []
    for cls in (sp.csr_matrix, sp.csc_matrix, sp.coo_matrix, sp.csr_array, sp.csc_array,
                sp.coo_array):
        def toarray(self, *a, _real=cls.toarray, **k):
            shapes.append(self.shape)
            return _real(self, *a, **k)

        monkeypatch.setattr(cls, "toarray", toarray)
    return shapes


#: A verdict as ``fabkit export`` hands it to the report stage (report.json's ``verdict``).
FLAG = {"level": "FLAG", "headline": "FLAG: tolerance as laser builds: none of the 40 builds "
        "assembles within its play", "text": "tolerance as laser builds: none of the 40 builds "
        "assembles within its play",
        "findings": [{"level": "FLAG", "about": "tolerance", "text": "none of the 40 builds"}]}


@pytest.fixture(scope="session")
def gate():
    """The AND gate's plan, bill of materials and guide, headed with a FLAG (as the report
    stage makes them again once the export has judged it); made once for every test file."""
    from fabkit.fab.guide import guide_pages
    from fabkit.fab.laser_plan import laser_plan
    from fabkit.writers.dxf import bill_of_materials

    design = fabkit.load_template(TEMPLATES / "and_gate.toml")
    plan = laser_plan(design)
    bom = bill_of_materials(plan, [], FLAG)
    return plan, bom, guide_pages(plan, bom, verdict=FLAG, check=True)
