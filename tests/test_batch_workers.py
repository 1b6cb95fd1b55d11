"""Worker processes of the batch that die at any moment: the design they were handed fails with
the worker's exit status, nothing of it is written, the other designs are exported as usual.

The deaths are injected at fixed moments (``fabkit.batch.FAULT_ENV``): the worker ends itself as
it receives the design, as a stage starts, or after the export before it reports back, so every
case is reached deterministically, not by timing a kill from outside.
"""

from __future__ import annotations

import os
import signal
import textwrap
import time
from pathlib import Path

import pytest

from fabkit.batch import FAULT_ENV, Outcome, Stage, exit_code, export_many
from fabkit.cli import main

from conftest import TEMPLATES

MODULE = "fabkit_test_worker_lengths"

# A small format of our own (one text file of edge lengths), so that these tests exercise the
# engine and not the real exporters.
SOURCE = textwrap.dedent('''
    FORMAT = "lengths"

    def applies(design):
        return design.network.dim == 2

    def export_design(design, settings):
        from fabkit.export import ExportResult

        text = "".join(f"{v:.12g}\\n" for v in design.network.edge_lengths)
        return ExportResult(files={design.name + "_lengths.txt": text.encode()},
                            report={"edges": design.network.n_edges})
''')

DESIGNS = ["fourbar", "super_stable", "slope_one"]
VICTIM = "super_stable"


@pytest.fixture
def lengths(tmp_path, monkeypatch):
    """Register the format in a module file that the spawned workers import too."""
    mods = tmp_path / "mods"
    mods.mkdir()
    (mods / f"{MODULE}.py").write_text(SOURCE)
    monkeypatch.syspath_prepend(str(mods))
    monkeypatch.setenv("PYTHONPATH", str(mods) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    monkeypatch.delenv(FAULT_ENV, raising=False)
    return {"lengths": MODULE}


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _export(out, exporters):
    return export_many([TEMPLATES / f"{n}.toml" for n in DESIGNS], None, out, jobs=2,
                       exporters=exporters, previews=False, tolerance_samples=0)


@pytest.mark.parametrize("moment, action, status", [
    ("taken", "kill", -signal.SIGKILL),              # before the worker did anything
    (str(Stage.LOAD), "kill", -signal.SIGKILL),      # before the design has a name
    (str(Stage.WRITE), "kill", -signal.SIGKILL),     # before its staging folder exists
    (str(Stage.CHECK), "kill", -signal.SIGKILL),     # staging folder written, not checked
    ("done", "kill", -signal.SIGKILL),               # complete and staged, not yet reported
    ("taken", "exit", 3),                            # an exit without any cleaning up
    (str(Stage.CHECK), "term", -signal.SIGTERM),     # a SIGTERM from outside: unwound, then dies
])
def test_a_worker_dying_at_any_moment_fails_only_its_design(tmp_path, lengths, monkeypatch,
                                                            moment, action, status):
    out = tmp_path / "out"
    monkeypatch.setenv(FAULT_ENV, f"{VICTIM}@{moment}:{action}")
    results = _export(out, lengths)
    by_name = {r.name: r for r in results}
    assert [r.name for r in results] == DESIGNS  # every design reported, in input order
    dead = by_name[VICTIM]
    assert dead.outcome is Outcome.FAILED and dead.error_code == "worker"
    assert dead.worker_exit == status and dead.folder == "" and dead.files == 0
    how = f"exit code {status}" if status > 0 else \
        f"signal {-status}, {signal.Signals(-status).name}"
    assert dead.error == (f"{TEMPLATES / (VICTIM + '.toml')}: worker died ({how}) while "
                          f"exporting {VICTIM}; nothing of it was written")
    for name in DESIGNS:
        if name != VICTIM:
            assert by_name[name].outcome is Outcome.OK and by_name[name].worker_exit is None
    assert exit_code(results) == 1
    files = _files(out)
    # no folder, no staging folder, no lock, no temporary file of the victim
    assert not any(VICTIM in k for k in files), sorted(files)
    assert sorted(k for k in files if not k.startswith("index")) == sorted(
        f"{n}/{f}" for n in DESIGNS if n != VICTIM
        for f in (f"{n}_lengths.txt", "report.html", "report.json", "report.md"))
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []


@pytest.mark.parametrize("action, limits, words", [
    # stopped (SIGSTOP): even its heartbeat is silent, so the silence limit finds it
    ("stop", {"silence": 3.0}, "the worker stopped answering (no word for 3 s) while "
                               "exporting super_stable, and was stopped"),
    # stuck in the export while its heartbeat goes on: the design's time limit finds it
    ("hang", {"timeout": 4.0}, "exporting super_stable ran past the time limit of 4 s "
                               "(--timeout), and was stopped"),
])
def test_a_worker_that_stops_answering_fails_only_its_design(tmp_path, lengths, monkeypatch,
                                                             action, limits, words):
    out = tmp_path / "out"
    monkeypatch.setenv(FAULT_ENV, f"{VICTIM}@{Stage.WRITE}:{action}")
    t0 = time.monotonic()
    results = export_many([TEMPLATES / f"{n}.toml" for n in DESIGNS], None, out, jobs=2,
                          exporters=lengths, previews=False, tolerance_samples=0, **limits)
    assert time.monotonic() - t0 < 60  # found within its limit, not waited on forever
    by_name = {r.name: r for r in results}
    stuck = by_name[VICTIM]
    assert stuck.outcome is Outcome.FAILED and stuck.error_code == "timeout"
    assert stuck.error == (f"{TEMPLATES / (VICTIM + '.toml')}: {words}; nothing of "
                           f"{VICTIM} was written")
    assert stuck.worker_exit == -signal.SIGKILL
    assert all(by_name[n].outcome is Outcome.OK for n in DESIGNS if n != VICTIM)
    assert exit_code(results) == 1
    assert not any(VICTIM in k for k in _files(out))
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []


def test_a_dead_worker_leaves_the_previous_export_untouched(tmp_path, lengths, monkeypatch):
    out = tmp_path / "out"
    first = _export(out, lengths)
    assert [r.outcome for r in first] == [Outcome.OK] * 3
    before = _files(out / VICTIM)
    assert f"{VICTIM}_lengths.txt" in before
    # the second export of the victim is complete in its staging folder when its worker dies
    monkeypatch.setenv(FAULT_ENV, f"{VICTIM}@done")
    second = _export(out, lengths)
    assert [r.outcome for r in second] == [Outcome.OK, Outcome.FAILED, Outcome.OK]
    assert _files(out / VICTIM) == before
    assert sorted(p.name for p in out.iterdir()) == sorted(DESIGNS + ["index.html"])


def test_the_command_line_reports_the_death_and_exits_1(tmp_path, lengths, monkeypatch, capsys):
    import fabkit.export

    monkeypatch.setattr(fabkit.export, "EXPORTERS", dict(lengths))
    monkeypatch.setenv(FAULT_ENV, f"{VICTIM}@taken")
    out = tmp_path / "out"
    rc = main(["export", *[str(TEMPLATES / f"{n}.toml") for n in DESIGNS], "-o", str(out),
               "--jobs", "2", "--no-previews", "--tolerance-samples", "0"])
    captured = capsys.readouterr()
    assert rc == 1
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith(
        f"worker died (signal 9, SIGKILL) while exporting {VICTIM}; nothing of it was written")
    table = [line for line in captured.out.splitlines() if line.startswith(VICTIM + " ")]
    assert len(table) == 1 and " failed " in table[0]
    assert "2 exported, 1 failed" in captured.out
    assert sorted(p.name for p in out.iterdir()) == ["fourbar", "index.html", "slope_one"]


def test_a_fault_for_another_design_or_moment_changes_nothing(tmp_path, lengths, monkeypatch):
    monkeypatch.setenv(FAULT_ENV, "no_such_design@taken")
    assert [r.outcome for r in _export(tmp_path / "a", lengths)] == [Outcome.OK] * 3
    monkeypatch.setenv(FAULT_ENV, f"{VICTIM}@no_such_moment")
    results = _export(tmp_path / "b", lengths)
    assert [r.outcome for r in results] == [Outcome.OK] * 3 and exit_code(results) == 0
