"""`fabkit export --to FORMAT` for a format that cannot be produced: exit 1, the format
``refused`` with its reason in report.json, no file of it written, never "ok"."""

from __future__ import annotations

import json

import pytest

from fabkit.pipeline import Status, export_many
from fabkit.cli import main

from conftest import TEMPLATES

#: A bundled design each format cannot be made of, and words its reason must contain.
CASES = {
    "dxf": ("origami_sheet", "planar (2D) network"),
    "svg": ("fourbar", "[fabrication.origami]"),
    "fold": ("fourbar", "[fabrication.origami]"),
    "stl": ("origami_sheet", "does not apply"),
    "cp": ("fourbar", "single sheet"),
}
SUFFIX = {"dxf": ".dxf", "svg": ".svg", "fold": ".fold", "stl": ".stl", "cp": ".cp"}


def _export(argv, capsys):
    code = main(["export", *argv, "--tolerance-samples", "0", "--no-previews", "-q"])
    return code, capsys.readouterr()


@pytest.mark.parametrize("fmt", sorted(CASES))
def test_a_format_asked_for_that_cannot_be_made_fails_with_its_reason(fmt, tmp_path, capsys):
    name, words = CASES[fmt]
    code, out = _export([name, "--to", fmt, "-o", str(tmp_path)], capsys)
    assert code == 1
    report = json.loads((tmp_path / name / "report.json").read_text())
    entry = report["formats"][fmt]
    assert entry["status"] == "refused" and entry["files"] == []
    assert words in entry["detail"]
    assert report["ok"] is False and report["outcome"] == "refused"
    assert report["errors"] == [f"{fmt}: {entry['detail']} (format refused)"]
    # one line on stderr naming the format and the reason; the summary does not say ok
    err = [line for line in out.err.splitlines() if line.startswith("fabkit: error:")]
    assert len(err) == 1 and f"cannot produce {fmt}: " in err[0] and words in err[0]
    assert f"{name}  ok" not in out.out and "0 exported, 1 failed" in out.out
    assert not [p for p in (tmp_path / name).iterdir() if p.suffix == SUFFIX[fmt]]
    assert "REFUSED" in (tmp_path / name / "report.md").read_text()


def test_a_template_that_opts_out_is_refused_when_asked(tmp_path, capsys):
    text = (TEMPLATES / "fourbar.toml").read_text()
    design = tmp_path / "bars.toml"
    design.write_text(text.replace('name = "fourbar"', 'name = "bars"') +
                      '\n[fabrication.skip]\ndxf = "cut by hand from the drawing"\n')
    code, out = _export([str(design), "--to", "dxf", "-o", str(tmp_path / "out")], capsys)
    assert code == 1
    entry = json.loads((tmp_path / "out" / "bars" / "report.json").read_text())["formats"]["dxf"]
    assert entry == {"status": "refused", "files": [],
                     "detail": "the template opts out: cut by hand from the drawing"}
    # without --to the same template exports what applies and lists the opt-out
    code, out = _export([str(design), "-o", str(tmp_path / "all")], capsys)
    assert code == 0
    formats = json.loads((tmp_path / "all" / "bars" / "report.json").read_text())["formats"]
    assert formats["dxf"]["status"] == "skipped by the template"
    assert {formats[f]["status"] for f in ("svg", "fold", "cp")} == {"does not apply"}
    assert formats["stl"]["status"] == "exported"  # the print-in-place linkage of the bars


def test_a_format_not_installed_is_refused_when_asked(tmp_path):
    registry = {"dxf": "fabkit.writers.dxf", "gcode": "fabkit.writers.no_such_module"}
    [res] = export_many([TEMPLATES / "fourbar.toml"], ["gcode"], tmp_path, jobs=1,
                        isolate=False, tolerance_samples=0, previews=False, exporters=registry)
    assert res.status is Status.REFUSED and not res.ok and res.error_code == "refused"
    assert res.formats["gcode"].status is Status.REFUSED
    assert "no_such_module" in res.formats["gcode"].message
    [res] = export_many([TEMPLATES / "fourbar.toml"], None, tmp_path / "all", jobs=1,
                        isolate=False, tolerance_samples=0, previews=False, exporters=registry)
    assert res.ok and res.formats["gcode"].status is Status.NOT_AVAILABLE
    assert res.formats["dxf"].status is Status.EXPORTED


def test_one_format_refused_among_several_still_writes_the_others(tmp_path, capsys):
    code, out = _export(["fourbar", "--to", "dxf,svg", "-o", str(tmp_path)], capsys)
    assert code == 1
    report = json.loads((tmp_path / "fourbar" / "report.json").read_text())
    assert report["formats"]["dxf"]["status"] == "exported"
    assert report["formats"]["svg"]["status"] == "refused"
    assert (tmp_path / "fourbar" / "laser_sheet1.dxf").is_file()
