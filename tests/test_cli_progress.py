"""Progress of the long commands, seen from the command line: one stream (stderr) for all, a line
from the start before any work, counts and stages, nothing on a pipe unless --progress, nothing
with -q, and the results on stdout untouched."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import fabkit.pipeline
import fabkit.bench.workprecision
import fabkit.sweep
from fabkit.cli import main
from fabkit.errors import FabkitError

#: A cheap run of every command that can take more than two seconds.
RUNS = {
    "export": ["export", "fourbar", "--to", "dxf", "--no-previews", "--tolerance-samples", "0",
               "-o", "{tmp}/out"],
    "sweep": ["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:3", "--measure",
              "fixed_points,slopes", "--no-plots", "-j", "1", "-o", "{tmp}/sweep"],
    "bench": ["bench", "--quick", "--parts", "workprecision", "--sizes", "3", "--budget", "5",
              "-o", "{tmp}/out"],
    "tolerance": ["tolerance", "fourbar", "--samples", "30", "--no-files"],
    "design": ["design", "--fixed-point", "1.6:0", "--fixed-point", "1.1", "-o", "{tmp}/design"],
    "map": ["map", "fourbar", "-o", "{tmp}/out"],
    "simulate": ["simulate", "fourbar", "-o", "{tmp}/out"],
    "letters": ["letters", "NO", "-o", "{tmp}/letters"],
    "fold": ["fold", "origami_sheet"],
    "info": ["info", "fourbar", "super_stable"],
    "check": ["check", "{tmp}/out/fourbar/laser_sheet1.dxf", "--design", "fourbar"],
}
#: The count each command ends on (units of its progress line), when it counts its work.
FINAL_COUNT = {"export": "1/1 designs", "sweep": "3/3 points", "bench": "7/7 runs",
               "tolerance": "1/1 templates", "map": "1/1 templates",
               "simulate": "1/1 templates", "letters": "5/5 steps", "fold": "1/1 templates",
               "check": "1/1 files", "info": "2/2 templates"}
LINE = re.compile(r"^fabkit (\w+) \[((\d+/\d+ \w+, )*)([\d.]+ s|\d+ min( \d+ s)?)"
                  r"(, about [^\]]+ left( in this one)?)?\] \S")


def _argv(name, tmp_path):
    return [word.replace("{tmp}", str(tmp_path)) for word in RUNS[name]]


def _run(argv, capsys):
    rc = main(argv)
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    return captured


@pytest.fixture(scope="module")
def kit(tmp_path_factory):
    """A laser kit of the 4-bar, for ``fabkit check`` to read."""
    tmp = tmp_path_factory.mktemp("kit")
    assert main(_argv("export", tmp) + ["-q"]) == 0
    return tmp


@pytest.mark.parametrize("name", sorted(RUNS))
def test_progress_goes_to_stderr_from_the_start_and_q_silences_it(name, kit, tmp_path, capsys):
    tmp = kit if name == "check" else tmp_path
    shown = _run(_argv(name, tmp) + ["--progress"], capsys)
    lines = shown.err.splitlines()
    assert len(lines) >= 2, shown.err
    for line in lines:
        assert LINE.match(line) and line.split(" ")[1] == name, line
    assert re.search(r"\[(0/\d+ \w+, )?0\.\d s\] ", lines[0]), lines[0]  # said at the start
    if name in FINAL_COUNT:
        assert lines[0].startswith(f"fabkit {name} [0/")
        assert f"[{FINAL_COUNT[name]}, " in lines[-1] or f"[{FINAL_COUNT[name]}, " in lines[-2]
    assert f"fabkit {name} [" not in shown.out  # stdout keeps the results only
    assert shown.out.strip()
    quiet = _run(_argv(name, tmp) + ["-q"], capsys)
    assert quiet.err == ""
    assert quiet.out.strip() and len(quiet.out.splitlines()) == len(shown.out.splitlines())


def test_a_single_design_export_counts_its_stages(tmp_path, capsys):
    """One design: each stage says its place among the design's stages, after the first line
    that comes before any work (the time left is the Progress tests' business: it depends on
    the clock)."""
    shown = _run(_argv("export", tmp_path) + ["--progress"], capsys)
    lines = shown.err.splitlines()
    assert lines[0].startswith("fabkit export [0/1 designs, ") and all(map(LINE.match, lines))
    stages = [re.search(r"\[0/1 designs, (\d)/7 stages, .*\] fourbar: (\w+)$", x)
              for x in lines[1:-1]]
    assert all(stages), lines
    # --no-previews and --tolerance-samples 0: those stages do not run, and are not counted
    assert [(int(m[1]), m[2]) for m in stages] == [(0, "load"), (1, "motion"), (2, "export"),
                                                   (5, "write"), (6, "check")]
    assert lines[-1].startswith("fabkit export [1/1 designs, ") and "fourbar: ok in " in lines[-1]


class _Stop(FabkitError):
    """Raised in place of a command's work, once the test has seen what was said before it."""


@pytest.mark.parametrize("name, module, work", [
    ("export", fabkit.pipeline, "export_many"),
    ("sweep", fabkit.sweep, "sweep"),
    ("bench", fabkit.bench.workprecision, "work_precision"),
    ("tolerance", fabkit.pipeline, "traced_motion"),
])
def test_the_first_line_comes_before_any_work(name, module, work, tmp_path, monkeypatch,
                                              capsys):
    seen = []

    def instead(*args, **kwargs):
        seen.append(capsys.readouterr().err)
        raise _Stop("stopped before the work")

    monkeypatch.setattr(module, work, instead)
    assert main(_argv(name, tmp_path) + ["--progress"]) == 1
    err = capsys.readouterr().err
    assert len(seen) == 1 and seen[0].startswith(f"fabkit {name} [0/"), seen
    assert LINE.match(seen[0].splitlines()[0])
    assert "stopped before the work" in err.splitlines()[-1]


def _on_a_terminal(argv, tmp_path):
    """Run ``fabkit ARGV`` with stderr on a pseudo-terminal and stdout on a pipe; returns
    (exit code, what the terminal showed, stdout)."""
    master, slave = os.openpty()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "fabkit", *argv], stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=slave, cwd=tmp_path, env=env)
    os.close(slave)
    shown = b""
    try:
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:  # the last end of the terminal closed: the command is done
                break
            if not chunk:
                break
            shown += chunk
    finally:
        os.close(master)
    out, _ = proc.communicate(timeout=300)
    return proc.returncode, shown.decode().replace("\r\n", "\n"), out.decode()


def test_on_a_terminal_progress_shows_unasked_and_q_silences_it(tmp_path):
    rc, shown, out = _on_a_terminal(["map", "fourbar", "-o", "out"], tmp_path)
    assert rc == 0
    lines = shown.splitlines()
    assert lines[0].startswith("fabkit map [0/1 templates, ") and all(map(LINE.match, lines))
    assert lines[-1].startswith("fabkit map [1/1 templates, ") and "fourbar.toml: done" in shown
    assert "fixed point" in out and "fabkit map [" not in out
    rc, shown, out = _on_a_terminal(["map", "fourbar", "-o", "out", "-q"], tmp_path)
    assert rc == 0 and shown == "" and "fixed point" in out


# --- make demo -------------------------------------------------------------------------------

MAKEFILE = Path(__file__).resolve().parents[1] / "Makefile"


@pytest.mark.parametrize("status", [0, 1])
def test_make_demo_ends_by_naming_the_page_to_open_and_keeps_the_exit_code(status, tmp_path):
    """The demo recipe, run with a stand-in for ``fabkit`` (the real export is the suite's
    business elsewhere): it asks for progress lines even off a terminal, says how long it took,
    and its last line names out/index.html, after the export's own last words, whether the
    export succeeded or not; the export's exit code is make's."""
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (tmp_path / "pyproject.toml").write_text("")
    os.utime(tmp_path / "pyproject.toml", (0, 0))  # older than the stamp: no install
    (venv / ".installed").write_text("")
    fake = venv / "bin" / "fabkit"
    fake.write_text("#!/bin/sh\n"
                    "echo \"fabkit $*\" > called.txt\n"
                    "mkdir -p out && echo '<html></html>' > out/index.html\n"
                    "echo '1 exported, 0 failed'\n"
                    f"[ {status} = 0 ] || echo 'fabkit: error: a design failed' >&2\n"
                    f"exit {status}\n")
    fake.chmod(0o755)
    proc = subprocess.run(["make", "--no-print-directory", "-f", str(MAKEFILE), "-C",
                           str(tmp_path), "demo", f"VENV={venv}"], capture_output=True,
                          text=True, timeout=60)
    assert (tmp_path / "called.txt").read_text() == \
        "fabkit export templates -o out --jobs 2 --progress\n"
    said = proc.stdout.splitlines()
    assert said[0] == "1 exported, 0 failed" and len(said) == 3
    assert re.fullmatch(r"The demo took 0 min \d+ s\.", said[1]), said
    assert said[2] == "Open out/index.html in a browser: every design's report, files and checks."
    if status:
        assert proc.returncode == 2  # make's own code for a recipe that failed
        assert proc.stderr.splitlines()[0] == "fabkit: error: a design failed"
    else:
        assert proc.returncode == 0 and proc.stderr == ""
    (tmp_path / "out" / "index.html").unlink()
    fake.write_text("#!/bin/sh\necho 'fabkit: error: -o: out is a file' >&2\nexit 2\n")
    proc = subprocess.run(["make", "-s", "-f", str(MAKEFILE), "-C", str(tmp_path), "demo",
                           f"VENV={venv}"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2  # no page to open: none is named
    assert re.fullmatch(r"The demo took 0 min \d+ s\.\n", proc.stdout), proc.stdout
