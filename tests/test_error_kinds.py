"""Errors carry their kind as a type or a code; no code decides by reading an error's text.

A reworded message must never change behaviour: a ``SettingsError`` says what is wrong in
``kind`` ("unknown", "missing", "type", "value"), and the code that must tell the cases apart
(a tracing method's options: an undeclared option is the method's own, a value of the wrong
type is a TypeError, a number out of range a ValueError) reads that, not ``reason``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import fabkit
from fabkit.errors import ArgumentTypeError, ArgumentValueError, SettingsError
from fabkit.io.schema import check_method_options
from fabkit.kinematics.base import check_option

ROOT = Path(fabkit.__file__).parent

#: Attributes that hold an error's words.
TEXT = {"reason", "message", "args", "msg"}


def _reads_error_text(tree) -> list[int]:
    """Lines of ``"..." in exc.reason`` / ``in str(exc)`` comparisons."""
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Compare) or not any(isinstance(o, (ast.In, ast.NotIn))
                                                          for o in node.ops):
            continue
        if not isinstance(node.left, ast.Constant) or not isinstance(node.left.value, str):
            continue
        for right in node.comparators:
            text_attr = isinstance(right, ast.Attribute) and right.attr in TEXT
            str_call = (isinstance(right, ast.Call) and isinstance(right.func, ast.Name)
                        and right.func.id == "str" and right.args
                        and isinstance(right.args[0], ast.Name)
                        and right.args[0].id in ("exc", "e", "err", "error"))
            if text_attr or str_call:
                found.append(node.lineno)
    return found


def test_the_walk_finds_a_decision_on_text():
    tree = ast.parse('try:\n    f()\nexcept E as exc:\n    if "unknown option" in exc.reason:'
                     '\n        pass\n    if "x" in str(exc):\n        pass\n')
    assert _reads_error_text(tree) == [4, 6]


def test_no_code_reads_an_errors_text():
    found = []
    for path in sorted(ROOT.rglob("*.py")):
        lines = _reads_error_text(ast.parse(path.read_text(encoding="utf-8")))
        found += [f"{path.relative_to(ROOT.parent)}:{n}" for n in lines]
    assert found == []


@pytest.mark.parametrize("options, kind", [
    ({"frobnicate": 1}, "unknown"),
    ({"max_steps": 2.5}, "type"),
    ({"max_steps": "many"}, "type"),
    ({"max_steps": 0}, "value"),
    ({"max_step": float("nan")}, "value"),
])
def test_a_settings_error_says_its_kind(options, kind):
    with pytest.raises(SettingsError) as info:
        check_method_options("projected", options)
    assert info.value.kind == kind


def test_a_kind_outside_the_vocabulary_is_refused():
    with pytest.raises(ValueError):
        SettingsError("laser.kerf", "must be >= 0", kind="bad")


@pytest.mark.parametrize("value, error", [
    (2.5, ArgumentTypeError), ("x", ArgumentTypeError), (True, ArgumentTypeError),
    (-1, ArgumentValueError), (float("nan"), ArgumentValueError),
])
def test_a_method_option_is_refused_by_its_kind(value, error, monkeypatch):
    with pytest.raises(error):
        check_option("projected", "max_steps", value)
    # reworded messages change nothing: the decision is made on the kind
    import fabkit.io.schema as schema

    real = schema._explain

    def reworded(exc, where, model):
        key, _ = real(exc, where, model)
        return key, "something else entirely"

    monkeypatch.setattr(schema, "_explain", reworded)
    with pytest.raises(error):
        check_option("projected", "max_steps", value)


def test_an_undeclared_option_is_the_methods_own():
    assert check_option("projected", "plan", object()) is None
