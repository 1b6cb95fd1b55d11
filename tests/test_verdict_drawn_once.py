"""The laser guide and bill of materials carry the verdict: ``fabkit export`` draws them once,
judged, at the report stage; the writer alone still makes a whole kit headed "not judged"."""

from __future__ import annotations

import json

import pytest

import fabkit
import fabkit.writers.dxf as dxf
from fabkit.cli import main
from fabkit.fab.plans import make_plan, trace_needs
from fabkit.motion import trace_motion
from fabkit.settings.design import design_settings

NAME = "fourbar"


@pytest.fixture(scope="module")
def plan():
    design = fabkit.load_template(NAME)
    settings = design_settings(design)
    motion = trace_motion(design, **trace_needs({dxf.PROCESS}, design, settings))
    return make_plan(dxf.PROCESS, design, settings, motion)


def _counted(monkeypatch):
    calls = []
    drawn = dxf.guide_pages

    def guide_pages(*args, **kwargs):
        calls.append(kwargs.get("verdict"))
        return drawn(*args, **kwargs)

    monkeypatch.setattr(dxf, "guide_pages", guide_pages)
    return calls


def test_the_writer_alone_makes_a_whole_kit_not_judged(plan, monkeypatch):
    calls = _counted(monkeypatch)
    kit = dxf.write(plan)
    assert calls == [None]
    assert kit.files["laser_guide.pdf"].startswith(b"%PDF")
    assert kit.files["laser_guide_page1.png"].startswith(b"\x89PNG")
    bom = json.loads(kit.files["laser_bom.json"])
    assert bom["verdict"]["level"] == "not judged"
    assert kit.report["guide_pages"] >= 2


def test_a_kit_left_to_be_judged_draws_no_guide_and_differs_in_nothing_else(plan, monkeypatch):
    whole = dxf.write(plan)
    calls = _counted(monkeypatch)
    later = dxf.write(plan, verdict_pages=False)
    assert calls == []
    assert list(later.files) == list(whole.files)
    for name, data in later.files.items():
        assert data == (b"" if name in dxf.VERDICT_FILES else whole.files[name]), name
    assert "guide_pages" not in later.report
    assert list(later.report) == [k for k in whole.report if k != "guide_pages"]
    assert later.report == {k: v for k, v in whole.report.items() if k != "guide_pages"}


def test_an_export_holds_the_judged_guide_and_the_writers_other_files(plan, tmp_path):
    """The exported kit: every file the writer makes alone, byte for byte, except those that
    carry the verdict, which are what ``with_verdict`` makes with report.json's verdict (the
    files the export made before the guide was drawn once)."""
    assert main(["export", NAME, "--to", "dxf", "--no-previews", "--tolerance-samples", "0",
                 "-o", str(tmp_path), "-q"]) == 0
    folder = tmp_path / NAME
    report = json.loads((folder / "report.json").read_text(encoding="utf-8"))
    whole = dxf.write(plan)
    kit = [n for n in whole.files if n not in dxf.VERDICT_FILES]
    for name in kit:
        assert (folder / name).read_bytes() == whole.files[name], name
    files, fmt = dxf.with_verdict(plan, sorted(whole.files), report["verdict"])
    assert report["verdict"]["level"] != "not judged"
    for name in dxf.VERDICT_FILES:
        assert (folder / name).read_bytes() == files[name], name
    assert report["formats"]["dxf"]["report"]["guide_pages"] == fmt["guide_pages"]
    assert set(report["formats"]["dxf"]["files"]) == set(whole.files)


def test_the_report_stage_adds_the_guides_warnings_to_the_writers(plan, monkeypatch):
    """A guide whose text reaches past a page: the report stage's ``with_verdict`` says so in
    the laser format's warnings, after the writer's own (a picture's), which it keeps."""
    from types import SimpleNamespace

    from fabkit.pipeline.design import carry_verdict

    drawn = dxf.guide_pages

    def clipped(*args, **kwargs):
        guide = drawn(*args, **kwargs)
        guide.stats["clipped"] = [(2, "a stack line too long")]
        return guide

    monkeypatch.setattr(dxf, "guide_pages", clipped)
    result = SimpleNamespace(files={"laser_sheet1.dxf": b""},
                             status=SimpleNamespace(produced=True),
                             report={"warnings": ["laser_assembly.png: text cut off"]})
    art = SimpleNamespace(plans={dxf.PROCESS: plan}, formats={"dxf": result}, files={})
    written = {}
    stage = SimpleNamespace(write=lambda name, data: written.__setitem__(name, data))
    verdict = SimpleNamespace(as_dict=lambda: {"level": "ok", "headline": "ok", "text": "ok",
                                               "findings": []})
    again = carry_verdict(stage, SimpleNamespace(chosen=[("dxf", dxf)]), art, verdict)
    assert sorted(again) == sorted(dxf.VERDICT_FILES) == sorted(written)
    assert result.report["warnings"] == [
        "laser_assembly.png: text cut off",
        "laser_guide.pdf: text past the edge of page 2: a stack line too long"]
    assert result.report["guide_pages"] > 1
