"""The command line: info, simulate; one-line errors, exit codes, no partial files."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main

from conftest import TEMPLATES


def run_cli(args, capsys):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_info_reports_modes_and_construction(capsys):
    code, out, err = run_cli(["info", TEMPLATES / "fourbar.toml"], capsys)
    assert code == 0 and err == ""
    assert "4 zero modes = 3 rigid + 1 conformational; 0 state(s) of self-stress" in out
    assert "constructive  yes" in out
    assert "nodes, edges  4, 4" in out


def test_simulate_writes_npz_and_png(tmp_path, capsys):
    code, out, err = run_cli(["simulate", TEMPLATES / "fourbar.toml", "--method", "projected",
                              "-o", tmp_path], capsys)
    assert code == 0, err
    assert "method        projected" in out and "max edge err" in out
    folder = tmp_path / "fourbar"
    data = np.load(folder / "trajectory.npz")
    d1 = np.linalg.norm(data["positions"][:, 0] - data["positions"][:, 1], axis=1)
    d2 = np.linalg.norm(data["positions"][:, 2] - data["positions"][:, 3], axis=1)
    assert np.abs(d1 * d2 - 4).max() < 1e-10
    assert str(data["status"]) == "finished"
    png = (folder / "motion.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(folder.glob("*.part"))


def test_simulate_to_override_reports_turning_point(tmp_path, capsys):
    code, out, err = run_cli(["simulate", TEMPLATES / "fourbar.toml", "--to", "0.5",
                              "--method", "constructive", "-o", tmp_path], capsys)
    assert code == 1  # the target is not reached: a failure, as in export
    assert "turning_point" in out and "0.8284271247" in out
    assert err.count("\n") == 1 and "motion.to: target d1 = 0.5 is not reached" in err
    assert (tmp_path / "fourbar" / "trajectory.npz").exists()  # the motion up to the stop


BAD = {
    "syntax.toml": ("[network\nnodes = [[0.0, 0.0]]", "not valid TOML"),
    "missing.toml": ("[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\n", "network.edges: missing required key"),
    "type.toml": ('[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\nedges = "0-1"\n', "network.edges: must be an array, got string"),
    "index.toml": ("[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\nedges = [[0, 3]]\n", "network.edges[0][1]: node index 3 is out of range"),
    "zero.toml": ("[network]\nnodes = [[0.0, 0.0], [0.0, 0.0], [1.0, 0.0]]\nedges = [[0, 1], [0, 2]]\n", "network.edges[0]: edge 0 [0, 1] has zero length"),
}


@pytest.mark.parametrize("name", sorted(BAD))
@pytest.mark.parametrize("command", ["info", "simulate"])
def test_malformed_templates_one_line_error_no_files(tmp_path, capsys, name, command):
    text, expected = BAD[name]
    path = tmp_path / name
    path.write_text(text)
    out_dir = tmp_path / "out"
    args = [command, path] + (["-o", out_dir] if command == "simulate" else [])
    code, out, err = run_cli(args, capsys)
    assert code != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("fabkit: error: ") and str(path) in lines[0] and expected in lines[0]
    assert "Traceback" not in err
    assert not out_dir.exists() or not any(out_dir.rglob("*"))


def test_console_script_exit_code(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("not toml at all ][")
    proc = subprocess.run([sys.executable, "-m", "fabkit.cli", "info", str(bad)],
                          capture_output=True, text=True)
    assert proc.returncode == 1
    assert proc.stderr.count("\n") == 1 and "not valid TOML" in proc.stderr


def test_usage_errors(capsys):
    assert main(["simulate"]) == 2
    assert main(["no-such-command"]) == 2
    assert main([]) == 2


def test_an_internal_error_is_one_line_with_its_own_exit_code(monkeypatch, capsys):
    import fabkit.commands.info as info

    def broken(args):
        return 1 // 0

    monkeypatch.setattr(info, "run", broken)
    code = main(["info", str(TEMPLATES / "fourbar.toml")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 70 and len(err) == 1
    assert err[0].startswith("fabkit: internal error at test_cli_core.py:")
    assert "ZeroDivisionError" in err[0] and "--debug" in err[0]
    with pytest.raises(ZeroDivisionError):
        main(["--debug", "info", str(TEMPLATES / "fourbar.toml")])


def test_errors_carry_fields_and_a_stable_code():
    from fabkit import errors

    codes = {cls.code for cls in (errors.FabkitError, errors.NetworkError, errors.TemplateError,
                                  errors.KinematicsError, errors.ConstructionError,
                                  errors.DesignError, errors.FabricationError,
                                  errors.UsageError, errors.BoundsError, errors.InputFileError,
                                  errors.OutputError, errors.LockedError, errors.MotionError,
                                  errors.SingularStartError, errors.UnavailableError)}
    assert len(codes) == 15  # every class has its own
    e = errors.MotionError("a.toml", "motion.to", "not reached", status="turning_point")
    assert (e.path, e.key, e.reason, e.status, e.code, e.exit_code) == (
        "a.toml", "motion.to", "not reached", "turning_point", "motion", 1)
    u = errors.UsageError("--jobs", "must be at least 1, got 0")
    assert (u.option, u.exit_code, str(u)) == ("--jobs", 2, "--jobs: must be at least 1, got 0")
    b = errors.BoundsError("--period", "for a cycle period", 1000, 24, "fabkit --allow-large",
                           option=True)
    assert (b.value, b.limit, b.exit_code) == (1000, 24, 2)
    assert errors.BoundsError("t.toml: chain.copies", "modules", 10**7, 20000).exit_code == 1
    assert errors.LockedError("out", 42).pid == 42


def test_no_decision_reads_message_text():
    """The engine, the command line and the commands decide on exception classes and typed
    results: none of them tests whether some words occur in an error's text."""
    import re

    root = Path(__file__).resolve().parents[1] / "fabkit"
    files = [*sorted((root / "pipeline").glob("*.py")), root / "cli.py",
             root / "report" / "text.py", root / "templates.py", root / "errors.py",
             *sorted((root / "commands").glob("*.py"))]
    pattern = re.compile(r"in str\(|in reason\b|in message\b|in msg\b|_is_singular_start"
                         r"|startswith\(str\(")
    hits = [f"{p.name}:{i}" for p in files
            for i, line in enumerate(p.read_text().splitlines(), 1) if pattern.search(line)]
    assert hits == []


@pytest.mark.parametrize("stem, cls, key, status", [
    ("too_few_steps", "MotionError", "motion", "failed"),
    ("unreachable_target", "MotionError", "motion.to", "turning_point"),
    ("singular_start", "SingularStartError", "network.nodes", "refused"),
    ("two_motions", "MotionError", "network", "refused"),
    ("rigid_network", "MotionError", "network", "refused"),
])
def test_motion_failures_are_typed(stem, cls, key, status):
    from fabkit import errors
    from fabkit.pipeline import traced_motion
    from fabkit.templates import load_template

    design = load_template(Path(__file__).resolve().parent / "bad_templates" / f"{stem}.toml")
    with pytest.raises(errors.MotionError) as info:
        traced_motion(design, allow_singular_start=True)
    assert type(info.value).__name__ == cls
    assert (info.value.key, info.value.status) == (key, status)


def test_minus_o_means_the_output_folder_in_every_command():
    # one meaning of -o/--out-dir across commands: the output folder, nothing else; --out, the
    # older spelling, is the same option, not shown
    import argparse

    from fabkit.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    seen = 0
    for name, p in sub.choices.items():
        for action in p._actions:
            flags = set(action.option_strings)
            if flags & {"-o", "--out-dir", "--out"}:
                assert action.dest == "out_dir", (name, flags)
                if action.help is argparse.SUPPRESS:
                    assert flags == {"--out"}, (name, flags)
                    continue
                assert flags == {"-o", "--out-dir"}, (name, flags)
                assert "folder" in (action.help or ""), (name, action.help)
                seen += 1
    assert seen >= 9
