"""Help that helps: every subcommand's --help ends with examples that run, options are spelt the
same in every command, and a misspelt command, template, option or letter gets "did you mean"."""

from __future__ import annotations

import argparse
import shlex

import pytest

from fabkit.cli import build_parser, main

#: Options that mean the same in every command, and their one spelling.
SHARED = {"out_dir": {"-o", "--out-dir"}, "jobs": {"-j", "--jobs"}, "settings": {"--set"},
          "quiet": {"-q", "--quiet"}, "progress": {"--progress"}}
#: Commands that can run for more than two seconds: they show progress (and take -q).
LONG = {"export", "sweep", "bench", "tolerance", "design", "map", "simulate", "letters", "check",
        "fold", "info"}
#: Commands whose work runs in parallel processes.
PARALLEL = {"export", "sweep"}
#: Commands that read templates and apply settings to them.
SETTINGS = {"export", "tolerance", "check", "simulate", "map", "fold", "design", "sweep", "letters",
            "info"}


def _commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, sub.choices


def _modules():
    from fabkit.cli import _commands as found

    return {mod.NAME: mod for mod in found()}


def _examples():
    return [(name, e) for name, mod in sorted(_modules().items()) for e in mod.EXAMPLES]


# --- examples ---------------------------------------------------------------------------------

def test_every_subcommand_help_ends_with_two_or_three_examples(capsys):
    _, commands = _commands()
    modules = _modules()
    assert set(commands) == set(modules) and len(commands) >= 12
    for name in commands:
        assert main([name, "--help"]) == 0
        text = capsys.readouterr().out
        head, _, tail = text.rpartition("\nExamples:\n")
        assert head, f"fabkit {name} --help has no Examples section"
        lines = tail.rstrip("\n").splitlines()
        shown = [line.strip() for line in lines if line.startswith("  fabkit ")]
        assert 2 <= len(shown) <= 3, (name, shown)
        assert all(cmd.startswith(f"fabkit {name} ") or cmd == f"fabkit {name}"
                   for cmd in shown), shown
        # the section is the end of the help: each example with its line of explanation
        assert len(lines) == 2 * len(shown), lines
        assert shown == [e.command for e in modules[name].EXAMPLES]


def test_top_level_help_names_the_progress_stream_and_has_examples(capsys):
    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    assert "\nExamples:\n  fabkit templates\n" in text
    assert "Progress of long commands goes to stderr" in text


@pytest.mark.parametrize("name, example", _examples(),
                         ids=[e.command[:60] for _, e in _examples()])
def test_every_example_parses(name, example):
    parser, _ = _commands()
    for line in (*example.needs, example.command):
        words = shlex.split(line)
        assert words[0] == "fabkit"
        args = parser.parse_args(words[1:])  # a usage error would exit 2 here
        assert args.command == line.split()[1]


@pytest.mark.parametrize("name, example", [(n, e) for n, e in _examples() if e.cheap],
                         ids=[e.command[:60] for _, e in _examples() if e.cheap])
def test_every_cheap_example_runs(name, example, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # the examples write into out/ of the current folder
    for line in (*example.needs, example.command):
        rc = main(shlex.split(line)[1:])
        captured = capsys.readouterr()
        assert rc == 0, (line, captured.err)
        assert captured.err == ""  # not a terminal: no progress, and no error
    assert captured.out.strip()


def test_simulate_method_lists_every_registered_method(capsys):
    from fabkit.kinematics import METHODS

    _, commands = _commands()
    action = next(a for a in commands["simulate"]._actions if a.dest == "method")
    listed = [w.strip(" ,") for w in action.help.split("(")[0].split()]
    assert listed == ["auto", *METHODS] and "branch" in listed


# --- options spelt the same -------------------------------------------------------------------

def test_options_are_named_the_same_in_every_command():
    _, commands = _commands()
    spellings = set().union(*SHARED.values()) | {"--out", "--outdir", "--output"}
    having = {dest: set() for dest in SHARED}
    for name, p in commands.items():
        for action in p._actions:
            flags = set(action.option_strings)
            if action.dest in SHARED:
                having[action.dest].add(name)
                if action.help is argparse.SUPPRESS:  # the older spelling, still accepted
                    assert (action.dest, flags) == ("out_dir", {"--out"}), (name, flags)
                    continue
                assert flags == SHARED[action.dest], (name, action.dest, flags)
                if action.dest == "out_dir":
                    assert action.metavar == "DIR" and "folder" in action.help, name
                if action.dest == "settings":
                    assert action.metavar == "SECTION.KEY=VALUE", name
            else:  # a shared spelling never means something else
                assert not flags & spellings, (name, action.dest, flags)
    assert having["quiet"] == having["progress"] == LONG
    assert having["jobs"] == PARALLEL
    assert having["settings"] == SETTINGS
    assert having["out_dir"] >= LONG - {"check", "info"} and "templates" in having["out_dir"]


def test_quiet_and_progress_exclude_each_other(capsys):
    assert main(["map", "fourbar", "-q", "--progress"]) == 2
    line = capsys.readouterr().err.strip()
    assert line.startswith("fabkit: error: argument --progress: not allowed with argument -q")


def test_the_older_out_spelling_still_works(tmp_path, capsys):
    assert main(["simulate", "fourbar", "--out", str(tmp_path / "old")]) == 0
    assert (tmp_path / "old" / "fourbar" / "trajectory.npz").is_file()
    assert main(["simulate", "fourbar", "--out-dir", str(tmp_path / "new")]) == 0
    assert (tmp_path / "new" / "fourbar" / "trajectory.npz").is_file()
    capsys.readouterr()


def test_templates_copy_takes_minus_o_and_refuses_it_alone(tmp_path, capsys):
    assert main(["templates", "--copy", "fourbar_chain2", "-o", str(tmp_path / "mine")]) == 0
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["fourbar.toml",
                                                                    "fourbar_chain2.toml"]
    capsys.readouterr()
    assert main(["templates", "-o", str(tmp_path / "x")]) == 2
    assert capsys.readouterr().err.strip() == (
        "fabkit: error: -o: is the folder --copy copies into; give it with --copy NAME")
    assert main(["templates", "--copy", "fourbar", str(tmp_path / "a"), "-o",
                 str(tmp_path / "b")]) == 2
    assert "both name the folder to copy into" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists() and not (
        tmp_path / "x").exists()


def test_settings_a_command_does_not_read_are_refused(tmp_path, capsys):
    assert main(["simulate", "fourbar", "--set", "laser.kerf=0.2", "-o", str(tmp_path)]) == 2
    assert capsys.readouterr().err.strip() == (
        "fabkit: error: --set: laser.kerf: laser settings have no effect here: simulate reads "
        "motion settings only; remove them")
    assert main(["simulate", "fourbar", "--set", "motion.to=2.5", "-o", str(tmp_path)]) == 0
    import numpy as np

    drive = np.load(tmp_path / "fourbar" / "trajectory.npz")["drive"]
    assert drive[-1] == pytest.approx(2.5, abs=1e-12)
    capsys.readouterr()
    assert list(tmp_path.iterdir()) == [tmp_path / "fourbar"]


# --- did you mean -----------------------------------------------------------------------------

def _error(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    return lines[0]


def test_a_misspelt_command_gets_did_you_mean(capsys):
    assert main(["exprot"]) == 2
    assert _error(capsys) == (
        "fabkit: error: argument COMMAND: invalid choice: 'exprot'; did you mean 'export'? "
        "(choose from 'bench', 'check', 'design', 'export', 'fold', 'info', 'letters', 'map', "
        "'simulate', 'sweep', 'templates', 'tolerance') (see fabkit --help)")


def test_a_misspelt_template_gets_did_you_mean(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["export", "super_stabel"]) == 1
    captured = capsys.readouterr()
    assert captured.err.strip() == (
        "fabkit: error: super_stabel: no such file, nor a bundled template of that name "
        "(fabkit templates lists them); did you mean 'super_stable'?")
    assert list(tmp_path.iterdir()) == []
    # a file of one's own is offered too, and a path is answered with the path beside it
    (tmp_path / "my_design.toml").write_text("")
    assert main(["info", "my_desing"]) == 1
    assert _error(capsys).endswith("did you mean 'my_design'?")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "chain.toml").write_text("")
    assert main(["info", "sub/chian.toml"]) == 1
    assert _error(capsys) == "fabkit: error: sub/chian.toml: no such file; did you mean " \
                             "'sub/chain.toml'?"


def test_a_misspelt_file_to_check_gets_the_file_beside_it(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "kit").mkdir()
    (tmp_path / "kit" / "laser_sheet1.dxf").write_text("0\nEOF\n")
    (tmp_path / "kit" / "laser_bom.md").write_text("")
    assert main(["check", "kit/laser_sheet.dxf"]) == 1
    assert _error(capsys) == ("fabkit: error: kit/laser_sheet.dxf: no such file; did you mean "
                              "'kit/laser_sheet1.dxf'?")
    assert main(["check", "kit/part.stl"]) == 1  # nothing alike: no guess
    assert _error(capsys) == "fabkit: error: kit/part.stl: no such file"
    assert main(["check", "nowhere/part.stl"]) == 1  # no such folder either
    assert _error(capsys) == "fabkit: error: nowhere/part.stl: no such file"


def test_letters_in_lower_case_get_the_word_in_capitals(tmp_path, capsys):
    assert main(["letters", "network", "-o", str(tmp_path / "out")]) == 2
    assert _error(capsys) == (
        "fabkit: error: WORD: must be capital letters, those with strokes: "
        "ABCDEFGHIJKLMNOPQRSTUVWXYZ; got 'network': did you mean NETWORK?")
    assert main(["letters", "NET-WORK", "-o", str(tmp_path / "out")]) == 2
    assert _error(capsys).endswith("got 'NET-WORK': '-' is none of them")
    assert main(["letters", "", "-o", str(tmp_path / "out")]) == 2
    assert _error(capsys) == "fabkit: error: WORD: is empty; give capital letters, e.g. NETWORK"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv, line", [
    (["export", "fourbar", "--jbos", "2"],
     "fabkit: error: unrecognized arguments: --jbos 2; did you mean '--jobs'? "
     "(see fabkit export --help)"),
    (["sweep", "chaotic", "--mesure=slopes"],
     "fabkit: error: unrecognized arguments: --mesure=slopes; did you mean '--measure'? "
     "(see fabkit sweep --help)"),
    (["export", "fourbar", "--no-such-option"],
     "fabkit: error: unrecognized arguments: --no-such-option (see fabkit export --help)"),
    (["info", "fourbar", "--rank-method", "dnese"],
     "fabkit: error: argument --rank-method: invalid choice: 'dnese'; did you mean 'dense'? "
     "(choose from 'auto', 'structure', 'dense', 'sparse') (see fabkit info --help)"),
    (["simulate", "fourbar", "--method", "brnch"],
     "fabkit: error: --method: unknown method 'brnch'; did you mean 'branch'? valid: auto, "
     "constructive, projected, rk4-nullspace, branch"),
    (["export", "fourbar", "--to", "dfx"],
     "fabkit: error: --to: unknown format 'dfx'; did you mean 'dxf'? valid: dxf, svg, fold, "
     "stl, cp"),
    (["map", "chaotic", "--in", "d2"],
     "fabkit: error: unrecognized arguments: --in d2; did you mean '--d-in'? "
     "(see fabkit map --help)"),
    (["map", "chaotic", "--out", "d2"],  # a port or a folder? (it used to write into d2/)
     "fabkit: error: argument --out: could mean two things here: the output folder is "
     "-o/--out-dir DIR, the map's output port --d-out PORT (see fabkit map --help)"),
    (["templates", "--copy", "fourbr"],
     "fabkit: error: --copy: no bundled template 'fourbr'; did you mean 'fourbar'? "
     "`fabkit templates` lists them"),
])
def test_misspelt_options_and_values_get_did_you_mean(argv, line, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert _error(capsys) == line
    assert list(tmp_path.iterdir()) == []


def test_a_misspelt_setting_gets_did_you_mean(tmp_path, capsys):
    assert main(["export", "fourbar", "--set", "laser.kref=0.2", "-o", str(tmp_path)]) == 2
    assert _error(capsys).endswith("; did you mean 'kerf'?")
    assert main(["export", "fourbar", "--set", "lazer.kerf=0.2", "-o", str(tmp_path)]) == 2
    assert _error(capsys) == ("fabkit: error: --set: lazer: unknown section; known: laser, "
                              "motion, origami, print, tolerance; did you mean 'laser'?")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, option", [
    (["map", "chaotic", "--orbit", "10"], "--orbit"),        # not --orbits
    (["export", "fourbar", "--tolerance", "0"], "--tolerance"),  # not --tolerance-samples
    (["--allow", "templates"], "--allow"),                  # not --allow-large
])
def test_no_option_is_taken_from_its_abbreviation(argv, option, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"unrecognized arguments: {option}" in err


def test_every_parser_refuses_abbreviations():
    parser, commands = _commands()
    assert parser.allow_abbrev is False
    assert {name for name, p in commands.items() if p.allow_abbrev is not False} == set()


def test_export_help_lists_every_format_with_its_process(capsys, monkeypatch):
    import importlib
    import sys

    import fabkit.writers
    from fabkit.tolerance import PROCESS_FORMATS
    from fabkit.writers import EXPORTERS, format_process

    for name in EXPORTERS.values():  # read from the source, as a fresh `fabkit export --help`
        monkeypatch.delitem(sys.modules, name, raising=False)
    read = {fmt: format_process(fmt) for fmt in EXPORTERS}
    monkeypatch.undo()
    assert read == {fmt: importlib.import_module(name).PROCESS for fmt, name in EXPORTERS.items()}
    assert read == {f: p for p, fs in PROCESS_FORMATS.items() for f in fs}
    assert main(["export", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "dxf (a laser-cut acrylic kit, its guide and BOM); svg, fold, cp (origami crease " \
           "patterns and cut sheets); stl (a 3D print, STL and 3MF)" in text
    # a format of one's own, registered, is listed too: the help is the registry's
    monkeypatch.setattr(fabkit.writers, "EXPORTERS", {**EXPORTERS, "lengths": "no_such_module"})
    assert main(["export", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "stl (a 3D print, STL and 3MF); lengths (a format of one's own)" in text


@pytest.mark.parametrize("command", ["export", "map", "simulate", "info", "tolerance", "fold"])
def test_a_misspelt_template_is_one_line_in_every_command(command, tmp_path, monkeypatch,
                                                            capsys):
    monkeypatch.chdir(tmp_path)
    assert main([command, "super_stabel"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and captured.err.startswith(
        "fabkit: error: super_stabel: no such file, nor a bundled template of that name")
    assert list(tmp_path.iterdir()) == []


def test_an_export_says_each_error_once_beside_the_designs_that_worked(tmp_path, capsys):
    rc = main(["export", "fourbar", "super_stabel", "--to", "dxf", "--no-previews",
               "--tolerance-samples", "0", "-o", str(tmp_path)])
    out, err = capsys.readouterr()
    assert rc == 1
    assert err.count("\n") == 1 and err.startswith("fabkit: error: super_stabel: no such file")
    assert (out + err).count("nor a bundled template") == 1
    rows = {line.split()[0]: line for line in out.splitlines()}
    assert rows["super_stabel"].split()[1] == "failed"
    assert rows["super_stabel"].endswith("(error below)")
    assert rows["fourbar"].endswith(str(tmp_path / "fourbar"))
    assert "1 exported, 1 failed" in out
