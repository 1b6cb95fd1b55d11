"""Errors carry their kind as a type or a code; no code decides by reading an error's text.

A reworded message must never change behaviour: a ``SettingsError`` says what is wrong in
``kind`` ("unknown", "missing", "type", "value"), and the code that must tell the cases apart
(a tracing method's options: an undeclared option is the method's own, a value of the wrong
type is a TypeError, a number out of range a ValueError) reads that, not ``reason``.
"""

from __future__ import annotations

import ast
import os
from pathlib import Path

import pytest

import fabkit
from fabkit.errors import ArgumentTypeError, ArgumentValueError, SettingsError
from fabkit.io.schema import check_method_options
from fabkit.kinematics.base import check_option

ROOT = Path(fabkit.__file__).parent

#: Attributes that hold an error's words.
TEXT = {"reason", "message", "args", "msg"}


def _is_error_text(node) -> bool:
    """``x.reason`` / ``x.message`` / ``x.args`` / ``x.msg`` (or one of its items), or
    ``str(exc)``."""
    if isinstance(node, ast.Subscript):
        node = node.value
    if isinstance(node, ast.Attribute) and node.attr in TEXT:
        return True
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            and node.func.id == "str" and bool(node.args) and isinstance(node.args[0], ast.Name)
            and node.args[0].id in ("exc", "e", "err", "error"))


def _reads_error_text(tree) -> list[int]:
    """Lines that decide on an error's words: ``"..." in exc.reason``, ``exc.reason == "..."``,
    ``str(exc).startswith("...")``, ``re.search(..., exc.message)``."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            words = any(isinstance(s, ast.Constant) and isinstance(s.value, str) for s in sides)
            if words and any(_is_error_text(s) for s in sides):
                found.append(node.lineno)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            f = node.func
            if f.attr in ("startswith", "endswith", "find", "count") and _is_error_text(f.value):
                found.append(node.lineno)
            elif (isinstance(f.value, ast.Name) and f.value.id == "re"
                  and any(_is_error_text(a) for a in node.args)):
                found.append(node.lineno)
    return found


def test_the_walk_finds_a_decision_on_text():
    tree = ast.parse('try:\n    f()\nexcept E as exc:\n    if "unknown option" in exc.reason:'
                     '\n        pass\n    if "x" in str(exc):\n        pass\n')
    assert _reads_error_text(tree) == [4, 6]
    more = ast.parse('if exc.reason == "no such file":\n    pass\n'
                     'if str(exc).startswith("turning"):\n    pass\n'
                     'if re.search("kerf", exc.args[0]):\n    pass\n'
                     'if exc.kind == "missing":\n    pass\n')
    assert _reads_error_text(more) == [1, 3, 5]


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


def test_an_input_file_error_says_its_kind(tmp_path):
    from fabkit.errors import InputFileError
    from fabkit.io.inputs import read_regular

    with pytest.raises(InputFileError) as missing:
        read_regular(tmp_path / "nothing.toml", 100)
    os.mkfifo(tmp_path / "pipe")
    with pytest.raises(InputFileError) as fifo:
        read_regular(tmp_path / "pipe", 100)
    assert (missing.value.kind, fifo.value.kind) == ("missing", "not_regular")
    with pytest.raises(ValueError):
        InputFileError("a.toml", "gone", kind="vanished")



def test_a_folder_given_as_a_file_is_refused_with_its_kind(tmp_path):
    """A folder where a file is read: a typed refusal with kind "not_regular", from the
    bounded reader and from the as-built check alike (the reader raised a bare
    IsADirectoryError when it made a file object of the folder before looking at it)."""
    from fabkit.check import check_file
    from fabkit.errors import InputFileError
    from fabkit.io.inputs import read_regular

    folder = tmp_path / "kit.dxf"
    folder.mkdir()
    for read in (lambda: read_regular(folder, 100), lambda: check_file(folder)):
        with pytest.raises(InputFileError) as err:
            read()
        assert err.value.kind == "not_regular"
    with pytest.raises(InputFileError) as err:
        check_file(tmp_path / "absent.dxf")
    assert err.value.kind == "missing"


#: A DXF that ezdxf cannot parse, even in its recover mode.
BROKEN_DXF = "0\nSECTION\n2\nHEADER\n0\nBOGUS\nxx\n"


def test_a_dxf_given_that_ezdxf_cannot_parse_is_a_damaged_input(tmp_path, capsys):
    """A user's DXF ezdxf cannot parse: InputFileError kind "damaged", exit 2, one line naming
    the file (it was a failed "readable" check, exit 1, with a report of checks)."""
    from fabkit.check import check_file
    from fabkit.cli import main
    from fabkit.errors import InputFileError

    given = tmp_path / "laser_sheet1.dxf"
    given.write_text(BROKEN_DXF)
    with pytest.raises(InputFileError) as err:
        check_file(given)
    assert err.value.kind == "damaged" and err.value.path == str(given)
    capsys.readouterr()
    assert main(["check", str(given)]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"fabkit: error: {given}: not a DXF file"), \
        cap.err
    assert "FAIL" not in cap.out


def test_a_dxf_of_fabkits_own_that_ezdxf_cannot_parse_is_a_failed_check(tmp_path):
    """The same bytes staged by an export (read through its folder): a failed check."""
    from fabkit.check import check_file
    from fabkit.io.folder import OutputFolder

    held = OutputFolder.open(tmp_path / "stage")
    held.write("laser_sheet1.dxf", BROKEN_DXF.encode())
    report = check_file(held.path / "laser_sheet1.dxf", folder=held)
    assert not report["ok"]
    readable = [c for c in report["checks"] if c["name"] == "readable"]
    assert len(readable) == 1 and not readable[0]["ok"]
    assert readable[0]["value"] == "laser_sheet1.dxf"
