"""Bundled templates by name: resolution, a user's own file winning, every command, --copy.

The installed package (a wheel outside the repo) is tested in tests/test_installed.py; here the
same rules are checked in the repo's own environment, quickly.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import fabkit
from fabkit import TemplateError, load_template
from fabkit.cli import main
from fabkit.commands.templates import template_files
from fabkit.templates import (bundled_folder, bundled_names, bundled_template, is_template_name,
                              resolve_template)

from conftest import TEMPLATES

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: The 4-bar at twice the size of the bundled one: d1 = 4 at the start instead of 2.
BIG_FOURBAR = """name = "fourbar"
description = "my own 4-bar, twice the size"
[network]
nodes = [[-2.0, -2.0], [-2.0, 2.0], [2.0, -2.0], [2.0, 2.0]]
edges = [[0, 2], [0, 3], [1, 2], [1, 3]]
ports = { d1 = [0, 1], d2 = [2, 3] }
[motion]
drive = "d1"
to = 5.0
"""


@pytest.fixture
def elsewhere(tmp_path, monkeypatch):
    """A current folder outside the repo, without templates."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_bundled_folder_is_the_repos_templates_folder():
    # one copy of the designs: the package data of the editable install is templates/ itself
    assert bundled_folder().resolve() == TEMPLATES.resolve()
    assert bundled_names() == sorted(p.stem for p in TEMPLATES.glob("*.toml"))
    assert len(bundled_names()) == 30


@pytest.mark.parametrize("name", ["fourbar", "fourbar.toml"])
def test_a_bare_name_is_the_bundled_template(elsewhere, name):
    path = resolve_template(name)
    assert path == bundled_folder() / "fourbar.toml"
    design = load_template(name)
    assert design.path == path and design.network.n_nodes == 4
    assert float(design.network.port_distance("d1")) == 2.0
    assert fabkit.load_template("super_stable_chain").network.n_nodes == 74


@pytest.mark.parametrize("text", ["./fourbar", "../fourbar", "sub/fourbar.toml",
                                  "templates/../fourbar", "..", ".fourbar", "fourbar.toml.bak",
                                  "fourbar\\x", "/fourbar", "-fourbar", ""])
def test_a_name_with_a_folder_part_is_a_path(elsewhere, text):
    assert not is_template_name(text)
    assert resolve_template(text) == Path(text)
    with pytest.raises(KeyError, match="no bundled template"):
        bundled_template(text)


def test_a_path_object_is_always_a_path(elsewhere):
    assert not is_template_name(Path("fourbar"))
    assert resolve_template(Path("fourbar")) == Path("fourbar")
    with pytest.raises(TemplateError) as info:
        load_template(Path("fourbar"))
    assert str(info.value) == "fourbar: no such file"


def test_an_unknown_name_says_there_is_no_file_nor_bundled_template(elsewhere, capsys):
    assert main(["info", "fourbars"]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        "fabkit: error: fourbars: no such file, nor a bundled template of that name "
        "(fabkit templates lists them); did you mean 'fourbar'?"]
    assert main(["info", "qwertyuiop"]) == 1  # nothing alike: no suggestion
    assert capsys.readouterr().err.strip().splitlines() == [
        "fabkit: error: qwertyuiop: no such file, nor a bundled template of that name "
        "(fabkit templates lists them)"]
    assert main(["info", "./fourbar"]) == 1
    assert capsys.readouterr().err.strip() == "fabkit: error: fourbar: no such file"


@pytest.mark.parametrize("own", ["fourbar.toml", "fourbar"])
def test_a_users_own_file_in_the_current_folder_wins(elsewhere, capsys, own):
    (elsewhere / own).write_text(BIG_FOURBAR)
    for name in ("fourbar", "fourbar.toml") if own == "fourbar.toml" else ("fourbar",):
        assert resolve_template(name) == Path(own)
        design = load_template(name)
        assert design.description == "my own 4-bar, twice the size"
        assert float(design.network.port_distance("d1")) == 4.0
    assert main(["info", "fourbar"]) == 0
    assert capsys.readouterr().out.startswith("fourbar: my own 4-bar, twice the size\n")
    assert main(["templates"]) == 0
    lines = capsys.readouterr().out.splitlines()
    marked = [ln for ln in lines if ln.endswith("in this folder is used instead]")]
    assert marked == [next(ln for ln in lines if ln.startswith("fourbar "))]
    assert marked[0].endswith(f"along the motion  [{own} in this folder is used instead]")


def test_every_command_takes_a_bundled_name(elsewhere, capsys):
    assert main(["info", "fourbar"]) == 0
    assert "nodes, edges  4, 4" in capsys.readouterr().out
    assert main(["simulate", "fourbar", "-o", "sim"]) == 0
    traj = np.load(elsewhere / "sim" / "fourbar" / "trajectory.npz")
    x = traj["positions"]
    d1, d2 = (np.linalg.norm(x[:, i] - x[:, j], axis=-1) for i, j in ((0, 1), (2, 3)))
    np.testing.assert_allclose(d1 * d2, 4.0, rtol=0, atol=1e-10)
    assert d1[-1] == pytest.approx(3.0, abs=1e-12)
    assert main(["map", "super_stable", "--steps", "5", "-o", "map"]) == 0
    assert (elsewhere / "map" / "super_stable").is_dir()
    assert main(["tolerance", "fourbar", "--samples", "20", "-o", "tol"]) == 0
    assert (elsewhere / "tol" / "fourbar").is_dir()
    assert main(["fold", "origami_sheet", "-o", "fold"]) == 0
    assert (elsewhere / "fold" / "origami_sheet").is_dir()
    assert main(["export", "physical_fourbar", "--to", "dxf", "-o", "kit", "--quiet"]) == 0
    sheet = elsewhere / "kit" / "physical_fourbar" / "laser_sheet1.dxf"
    capsys.readouterr()
    assert main(["check", str(sheet), "--design", "physical_fourbar", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert [v["ok"] for v in report.values()] == [True]
    # a sweep spec of the user's own naming a bundled template
    (elsewhere / "spec.toml").write_text('[sweep]\ntemplate = "chaotic"\n'
                                         'vary = ["nodes[4].x=-0.33:-0.32:2"]\n'
                                         'measure = ["fixed_points"]\n')
    assert main(["sweep", "spec.toml", "-o", "sweep", "--no-plots", "--jobs", "1"]) == 0
    points = json.loads((elsewhere / "sweep" / "sweep.json").read_text())["points"]
    assert [p["fixed_value"] for p in points] == [pytest.approx(1.5, abs=1e-12)] * 2


def test_a_chain_of_the_users_may_name_a_bundled_module(elsewhere):
    (elsewhere / "mine.toml").write_text('[chain]\nmodule = "fourbar"\ncopies = 2\n')
    mine = load_template("mine.toml")
    assert mine.references["chain.module"].path == bundled_folder() / "fourbar.toml"
    np.testing.assert_array_equal(mine.network.nodes,
                                  load_template("fourbar_chain2").network.nodes)
    (elsewhere / "fourbar.toml").write_text(BIG_FOURBAR)  # now the module next to it wins
    assert load_template("mine.toml").references["chain.module"].path.resolve() == \
        (elsewhere / "fourbar.toml").resolve()
    (elsewhere / "bad.toml").write_text('[chain]\nmodule = "nope"\ncopies = 2\n')
    with pytest.raises(TemplateError) as info:
        load_template("bad.toml")
    assert str(info.value) == ("bad.toml: chain.module: no template file 'nope' next to this "
                               "one, nor a bundled template of that name")


def _toml_names(value) -> set[str]:
    """Every string ending in .toml anywhere in a parsed template."""
    if isinstance(value, str):
        return {value} if value.endswith(".toml") else set()
    items = value.values() if isinstance(value, dict) else value if isinstance(value, list) else []
    return set().union(*(_toml_names(v) for v in items)) if items else set()


@pytest.mark.parametrize("name", bundled_names())
def test_a_copy_carries_every_template_it_refers_to(tmp_path, name):
    files = template_files(name)
    raw = tomllib.loads((TEMPLATES / f"{name}.toml").read_text())
    assert set(files) == {f"{name}.toml"} | _toml_names(raw)
    assert main(["templates", "--copy", name, str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(files)
    for rel in files:
        assert (tmp_path / rel).read_bytes() == (TEMPLATES / rel).read_bytes()
    copy = load_template(tmp_path / f"{name}.toml")
    for ref in copy.references.values():  # the references resolve to the copies
        assert ref.path.resolve().parent == tmp_path.resolve()


def test_copy_then_edit(elsewhere, capsys):
    assert main(["templates", "--copy", "super_stable_chain"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == ["wrote super_stable_chain.toml", "wrote super_stable.toml",
                   "edit it, then e.g.: fabkit info super_stable_chain.toml"]
    # the user's copies now win by name, and the chain reads the edited module
    module = elsewhere / "super_stable.toml"
    module.write_text(module.read_text().replace('description = "', 'description = "EDITED '))
    chain = load_template("super_stable_chain")
    assert chain.path == Path("super_stable_chain.toml")
    assert chain.references["chain.module"].description.startswith("EDITED ")


def test_copy_refuses_to_overwrite_without_force(tmp_path, capsys):
    dest = tmp_path / "mine"
    dest.mkdir()
    (dest / "fourbar.toml").write_text("# my notes\n")
    assert main(["templates", "--copy", "fourbar_chain2", str(dest)]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        f"fabkit: error: {dest / 'fourbar.toml'}: exists; give --force to overwrite it, or "
        "choose another folder"]
    # nothing written: not the chain either, and the user's file is untouched
    assert sorted(p.name for p in dest.iterdir()) == ["fourbar.toml"]
    assert (dest / "fourbar.toml").read_text() == "# my notes\n"
    assert main(["templates", "--copy", "fourbar_chain2", str(dest), "--force"]) == 0
    assert (dest / "fourbar.toml").read_bytes() == (TEMPLATES / "fourbar.toml").read_bytes()
    assert main(["templates", "--force"]) == 2
    assert "--force: only goes with --copy NAME" in capsys.readouterr().err


def test_copy_never_writes_outside_its_folder(tmp_path, capsys):
    outside = tmp_path / "outside.toml"
    outside.write_text("# not to be touched\n")
    dest = tmp_path / "dest"
    dest.mkdir()
    (dest / "fourbar.toml").symlink_to(outside)  # a link out of the folder is replaced, not followed
    assert main(["templates", "--copy", "fourbar", str(dest), "--force"]) == 0
    assert outside.read_text() == "# not to be touched\n"
    assert not (dest / "fourbar.toml").is_symlink()
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == [
        "dest", "dest/fourbar.toml", "outside.toml"]
    for bad in ("../fourbar", "sweeps/period_doubling", "/etc/passwd", "nope"):
        assert main(["templates", "--copy", bad, str(dest)]) == 2
        assert capsys.readouterr().err.strip().splitlines() == [
            f"fabkit: error: --copy: no bundled template {bad!r}; `fabkit templates` lists them"]
    (dest / "sub").mkdir()
    (dest / "sub" / "x").write_text("")
    assert main(["templates", "--copy", "fourbar", str(dest / "sub" / "x")]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        f"fabkit: error: {dest / 'sub' / 'x'}: FOLDER: exists and is not a folder; choose "
        "another output folder"]
    assert sorted(p.name for p in (dest / "sub").iterdir()) == ["x"]
