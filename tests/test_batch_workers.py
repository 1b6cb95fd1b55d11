"""Worker processes of the batch that die at any moment: the design they were handed fails with
the worker's exit status, nothing of it is written, the other designs are exported as usual.

The deaths are injected at fixed moments (``fabkit.pipeline.FAULT_ENV``): the worker ends itself as
it receives the design, as a stage starts, or after the export before it reports back, so every
case is reached deterministically, not by timing a kill from outside.
"""

from __future__ import annotations

import os
import signal
import textwrap
from pathlib import Path

import pytest

from fabkit.pipeline import FAULT_ENV, Stage, Status, exit_code, export_many
from fabkit.cli import main
from fabkit.templates import bundled_folder

from conftest import TEMPLATES

MODULE = "fabkit_test_worker_lengths"

# A small format of our own (one text file of edge lengths), so that these tests exercise the
# engine and not the real exporters.
SOURCE = textwrap.dedent('''
    FORMAT = "lengths"

    def applies(design):
        return design.network.dim == 2

    def export_design(design, settings):
        from fabkit.writers import ExportResult

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
    assert dead.status is Status.FAILED and dead.error_code == "worker"
    assert dead.worker_exit == status and dead.folder == "" and dead.files == 0
    how = f"exit code {status}" if status > 0 else \
        f"signal {-status}, {signal.Signals(-status).name}"
    assert dead.message == (f"{TEMPLATES / (VICTIM + '.toml')}: worker died ({how}) while "
                          f"exporting {VICTIM}; nothing of it was written")
    for name in DESIGNS:
        if name != VICTIM:
            assert by_name[name].status is Status.OK and by_name[name].worker_exit is None
    assert exit_code(results) == 1
    files = _files(out)
    # no folder, no staging folder, no lock, no temporary file of the victim
    assert not any(VICTIM in k for k in files), sorted(files)
    assert sorted(k for k in files if not k.startswith("index")) == sorted(
        f"{n}/{f}" for n in DESIGNS if n != VICTIM
        for f in (f"{n}_lengths.txt", "exports.json", "report.html", "report.json", "report.md"))
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []


@pytest.mark.parametrize("action", ["stop", "hang"])
def test_a_worker_that_stops_answering_fails_only_its_design(tmp_path, lengths, monkeypatch,
                                                             action):
    if action == "stop":
        # stopped (SIGSTOP): even its heartbeat is silent, so the silence limit finds it; the
        # heartbeat beats six times within the limit, and a worker's silence counts from its
        # first word, so the others, slow to start on a busy machine, are not taken for silent
        limits = {"silence": 3.0}
        words = "the worker stopped answering (no word for 3 s) while exporting super_stable"
    else:
        # stuck in the export while its heartbeat goes on: the design's time limit finds it.
        # The limit leaves the other designs four times what they take on this machine now,
        # measured by the same export without the fault.
        slowest = max(r.seconds for r in _export(tmp_path / "clean", lengths))
        limits = {"timeout": max(4.0, round(4 * slowest))}
        words = (f"exporting super_stable ran past the time limit of {limits['timeout']:g} s "
                 "(--timeout)")
    out = tmp_path / "out"
    monkeypatch.setenv(FAULT_ENV, f"{VICTIM}@{Stage.WRITE}:{action}")
    results = export_many([TEMPLATES / f"{n}.toml" for n in DESIGNS], None, out, jobs=2,
                          exporters=lengths, previews=False, tolerance_samples=0, **limits)
    by_name = {r.name: r for r in results}
    stuck = by_name[VICTIM]
    assert stuck.status is Status.FAILED and stuck.error_code == "timeout"
    assert stuck.message == (f"{TEMPLATES / (VICTIM + '.toml')}: {words}, and was stopped; "
                           f"nothing of {VICTIM} was written")
    assert stuck.worker_exit == -signal.SIGKILL
    assert all(by_name[n].status is Status.OK for n in DESIGNS if n != VICTIM)
    assert exit_code(results) == 1
    assert not any(VICTIM in k for k in _files(out))
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []


def test_a_dead_worker_leaves_the_previous_export_untouched(tmp_path, lengths, monkeypatch):
    out = tmp_path / "out"
    first = _export(out, lengths)
    assert [r.status for r in first] == [Status.OK] * 3
    before = _files(out / VICTIM)
    assert f"{VICTIM}_lengths.txt" in before
    # the second export of the victim is complete in its staging folder when its worker dies
    monkeypatch.setenv(FAULT_ENV, f"{VICTIM}@done")
    second = _export(out, lengths)
    assert [r.status for r in second] == [Status.OK, Status.FAILED, Status.OK]
    assert _files(out / VICTIM) == before
    assert sorted(p.name for p in out.iterdir()) == sorted(DESIGNS + ["index.html"])


def test_the_command_line_reports_the_death_and_exits_1(tmp_path, lengths, monkeypatch, capsys):
    import fabkit.writers

    monkeypatch.setattr(fabkit.writers, "EXPORTERS", dict(lengths))
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
    assert [r.status for r in _export(tmp_path / "a", lengths)] == [Status.OK] * 3
    monkeypatch.setenv(FAULT_ENV, f"{VICTIM}@no_such_moment")
    results = _export(tmp_path / "b", lengths)
    assert [r.status for r in results] == [Status.OK] * 3 and exit_code(results) == 0


def test_the_limits_judge_the_worker_not_the_machine():
    """The parent's judgement on a fake clock: a starting worker is not silent, silence counts
    from the last word, the design's time limit from the moment the worker took the design."""
    from fabkit.executor import overdue, heartbeat_interval
    from fabkit.pipeline.workers import _stuck_reason

    limits = {"silence": 3.0, "timeout": 4.0, "startup": 120.0}

    def why(now, heard=None, since=None, **other):
        stop = overdue(now, born=100.0, heard=heard, since=since, **{**limits, **other})
        return "" if stop is None else _stuck_reason(*stop, "a")

    # starting (an interpreter importing numpy and scipy): not a word yet, for a long time
    assert why(100.0 + 119.0) == ""
    assert why(100.0 + 121.0) == (
        "the worker did not start within 120 s (it was to export a), and was stopped")
    # its first word at 110: silent only 3 s after its last word, whatever came before
    assert why(112.9, heard=110.0) == ""
    assert why(113.1, heard=110.0).startswith(
        "the worker stopped answering (no word for 3 s) while exporting a")
    # it took the design at 111 and goes on beating: the time limit runs from 111
    assert why(114.9, heard=114.9, since=111.0) == ""
    assert why(115.2, heard=115.2, since=111.0) == (
        "exporting a ran past the time limit of 4 s (--timeout), and was stopped")
    assert why(115.2, heard=115.2, since=111.0, timeout=None) == ""
    # several beats fit in any silence limit
    assert heartbeat_interval(120.0) == 1.0 and heartbeat_interval(3.0) == 0.5


def test_export_many_takes_bare_names_like_the_command_line(tmp_path, monkeypatch):
    """``export_many(["fourbar", ...])`` exports the bundled template of that name; a template of
    the same name in the current folder wins; a misspelt name fails that design alone, with the
    fix suggested, and writes nothing for it."""
    monkeypatch.chdir(tmp_path)
    own = tmp_path / "mine.toml"
    own.write_text((TEMPLATES / "fourbar.toml").read_text().replace('name = "fourbar"',
                                                                    'name = "mine"'))
    results = export_many(["fourbar", "mine", "super_stabel"], ["dxf"], tmp_path / "out",
                          check=False, isolate=False)
    assert [r.name for r in results] == ["fourbar", "mine", "super_stabel"]
    assert [r.status for r in results[:2]] == [Status.OK, Status.OK]
    assert Path(results[0].path) == bundled_folder() / "fourbar.toml"
    assert Path(results[1].path).resolve() == own.resolve()
    assert "no such file, nor a bundled template" in results[2].message
    assert "did you mean 'super_stable'?" in results[2].message
    assert (tmp_path / "out" / "fourbar" / "laser_sheet1.dxf").is_file()
    assert (tmp_path / "out" / "mine" / "laser_sheet1.dxf").is_file()
    assert not (tmp_path / "out" / "super_stabel").exists()
