"""Shared fixtures: the paper's modules as networks, paths to bundled templates."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import fabkit

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"


def _find_modules_json() -> Path:
    for cand in (ROOT / "tests" / "data" / "paper_modules.json",):
        if cand.exists():
            return cand
    raise FileNotFoundError("paper_modules.json")


@pytest.fixture(scope="session")
def paper_modules() -> dict:
    """The paper's module geometry (tests/data copy, so tests run from a clean clone)."""
    return json.loads(_find_modules_json().read_text())["modules"]


def module_network(modules: dict, name: str) -> fabkit.Network:
    m = modules[name]
    return fabkit.Network(np.array(m["nodes"], dtype=float), m["edges"],
                          ports={"d1": tuple(m["d1"]), "d2": tuple(m["d2"])})


@pytest.fixture(scope="session")
def fourbar(paper_modules) -> fabkit.Network:
    return module_network(paper_modules, "fourbar")


@pytest.fixture(scope="session")
def module(paper_modules):
    """Factory: module("super_stable") -> Network with ports d1, d2."""
    return lambda name: module_network(paper_modules, name)
