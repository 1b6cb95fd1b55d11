"""The summary row of ``fabkit export`` and its progress line say each design's verdict (the
level its reports head with), not only that its files were written; exit codes stay those of
the outcome. The results are built here, so no slow export runs."""

from __future__ import annotations

import io

import pytest

import fabkit.pipeline
from fabkit.cli import main
from fabkit.commands.export import DesignProgress
from fabkit.io.progress import Progress
from fabkit.pipeline import DesignResult, exit_code, Status, summary_table


def _result(name: str, outcome: Status = Status.OK, level: str = "", headline: str = ""):
    folder = f"out/{name}" if outcome is Status.OK else ""
    error = "" if outcome is Status.OK else f"{name}.toml: network: cannot be read"
    return DesignResult(f"{name}.toml", name, outcome, files=5 if folder else 0, folder=folder,
                        message=error, seconds=1.0, level=level, headline=headline)


def _rows(table: str) -> dict:
    """Design name → its status column."""
    return {line.split()[0]: line.split()[1] for line in table.splitlines()[1:-1]}


FLAGGED = _result("and_gate", level="FLAG",
                  headline="FLAG: tolerance as laser builds: margin 0.4")
PASSING = _result("fourbar", level="ok", headline="ok: every as-built check passed")


def test_a_flagged_design_shows_its_verdict_in_the_summary_row():
    table = summary_table([FLAGGED])
    assert _rows(table) == {"and_gate": "FLAG"}
    assert table.splitlines()[-1] == "1 exported, 0 failed"  # written: not a failure
    assert exit_code([FLAGGED]) == 0


def test_a_passing_design_shows_ok_and_a_failed_one_its_outcome():
    failed = _result("broken", Status.FAILED)
    by_design = _result("chaotic_chain", level="by design")
    rows = _rows(summary_table([PASSING, failed, by_design]))
    assert rows == {"fourbar": "ok", "broken": "failed", "chaotic_chain": "by"}
    assert "chaotic_chain  by design " in summary_table([by_design])
    # a result without a verdict (none was judged) says its outcome
    assert _rows(summary_table([_result("plain")])) == {"plain": "ok"}


def test_the_progress_line_of_a_flagged_design_says_flag():
    stream = io.StringIO()
    progress = Progress("fabkit export", show=True, stream=stream,
                        clock=iter([0.0, 0.0, 1.0]).__next__)
    progress.stage("1 design", total=1, unit="designs")
    DesignProgress(progress).finished(FLAGGED)
    assert stream.getvalue().splitlines()[-1].endswith("] and_gate: FLAG in 1.0 s")


@pytest.mark.parametrize("result, status", [(FLAGGED, "FLAG"), (PASSING, "ok")])
def test_the_cli_prints_the_verdict_in_the_row(monkeypatch, tmp_path, capsys, result, status):
    def export_many(paths, *args, **kwargs):
        return [result]

    monkeypatch.setattr(fabkit.pipeline, "export_many", export_many)
    rc = main(["export", "fourbar", "--to", "dxf", "-o", str(tmp_path), "-q"])
    out = capsys.readouterr().out
    assert rc == 0
    assert _rows(out.split("\n1 exported")[0] + "\n-") == {result.name: status}
    if status == "FLAG":  # and its headline in one line under the table
        assert f"{result.name}: {result.headline}" in out.splitlines()
