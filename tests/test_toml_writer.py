"""The one TOML writer: every value through tomli_w, hostile text reads back equal, the
designer's, the letters' and the bench's templates built with it and nothing else."""

import ast
try:  # Python 3.11+
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from pathlib import Path

import numpy as np
import pytest

from fabkit.design.curvature import design_curvature_type
from fabkit.design.toml_text import curvature_template
from fabkit.errors import FabkitError
from fabkit.templates import load_template
from fabkit.io.toml_writer import TomlDocument, toml_key, toml_value

HOSTILE = ['two\nlines', 'say "hi"', "back\\slash", "tab\there", "ünïcødé ✓ 曲率", "#not a comment",
           "]", "' single", "trailing space "]


@pytest.mark.parametrize("text", HOSTILE)
def test_hostile_strings_read_back_equal(text):
    doc = TomlDocument()
    doc.comment(text)
    doc.value("name", text, note=text)
    doc.value(text, [text, {"k": text}], per_line=1)
    doc.table(f"section.{text}")
    doc.value("value", text)
    data = tomllib.loads(doc.text())
    assert data["name"] == text
    assert data[text] == [text, {"k": text}]
    assert data["section"][text]["value"] == text


def test_numbers_round_trip_exactly_and_numpy_is_plain():
    pts = np.array([[0.1, 1 / 3], [2.0**-40, -1e300]])
    doc = TomlDocument()
    doc.value("points", pts, per_line=1)
    doc.value("count", np.int64(7))
    doc.value("flag", np.bool_(True))
    text = doc.text()
    data = tomllib.loads(text)
    assert data["points"] == pts.tolist()
    assert data["count"] == 7 and data["flag"] is True
    # one point a line, as a person reads a template
    assert text.splitlines()[:3] == ["points = [", f"    [0.1, {1 / 3!r}],",
                                     f"    [{2.0**-40!r}, -1e+300],"]


@pytest.mark.parametrize("bad", [float("inf"), float("nan")])
def test_non_finite_numbers_are_refused_by_name(bad):
    with pytest.raises(FabkitError, match="cannot write .* into a template"):
        toml_value(bad)


def test_keys_and_inline_tables():
    assert toml_key("d1") == "d1"
    assert toml_key("two words") == '"two words"'
    assert toml_value({"d1": [0, 1], "d2": [1, 2]}) == "{ d1 = [0, 1], d2 = [1, 2] }"
    assert toml_value({}) == "{}"


@pytest.mark.parametrize("name", ['module "A"', "back\\slash", "ünïcødé ✓", "two\nlines"])
def test_a_designed_template_with_a_hostile_name_is_valid_toml_refused_by_name(tmp_path, name):
    """The writer writes any name as valid TOML; the template reader then refuses a name that is
    no safe file stem, naming the field, never as broken TOML."""
    text = curvature_template(name, design_curvature_type(60.0))
    assert tomllib.loads(text)["name"] == name
    path = tmp_path / "module.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(FabkitError, match=r"module.toml: name: .*(use letters, digits|control character)"):
        load_template(path)


def test_a_designed_template_loads_back(tmp_path):
    path = tmp_path / "curve_m1.toml"
    path.write_text(curvature_template("curve_m1-2.0+b", design_curvature_type(60.0)),
                    encoding="utf-8")
    design = load_template(path)
    assert design.name == "curve_m1-2.0+b"


WRITERS = ["fabkit/design/toml_text.py", "fabkit/design/letters.py", "fabkit/bench/large.py"]


@pytest.mark.parametrize("rel", WRITERS)
def test_template_writers_build_no_toml_by_hand(rel):
    """No string literal in a template writer holds a TOML table header or a quoted value."""
    root = Path(__file__).resolve().parents[1]
    tree = ast.parse((root / rel).read_text(encoding="utf-8"))
    docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                  if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef)) and n.body
                  and isinstance(n.body[0], ast.Expr)}
    for node in ast.walk(tree):
        if (isinstance(node, ast.Constant) and isinstance(node.value, str)
                and id(node) not in docstrings):
            s = node.value
            assert not any(h in s for h in ("[chain]", "[motion]", "[design]", '= "')), (rel, s)
