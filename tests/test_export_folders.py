"""A design's folder gathers formats: a later export adds its files to those an earlier one left
(while they are current: same design, settings and fabkit version), removes stale ones saying
why, and the folder's reports are one report over every format in it, with their origin."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import ezdxf
import pytest
import trimesh

from fabkit.cli import main
from fabkit.errors import OutputError
from fabkit.pipeline import export_many
from fabkit.pipeline.manifest import MANIFEST, SCHEMA, SCHEMA_VERSION, read_manifest

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"
FAST = ["--no-previews", "--tolerance-samples", "0"]


def _export(template, out, *args, capsys=None):
    rc = main(["export", str(template), "-o", str(out), *FAST, *args])
    captured = capsys.readouterr() if capsys is not None else None
    return rc, captured


def _report(folder: Path) -> dict:
    return json.loads((folder / "report.json").read_text())


@pytest.fixture
def fourbar(tmp_path):
    """A copy of the bundled 4-bar template that a test may edit."""
    path = tmp_path / "fourbar.toml"
    shutil.copy(TEMPLATES / "fourbar.toml", path)
    return path


def test_a_later_export_adds_its_formats_and_the_report_covers_both(fourbar, tmp_path,
                                                                    capsys):
    out = tmp_path / "out"
    folder = out / "fourbar"
    rc, _ = _export(fourbar, out, "--to", "dxf", capsys=capsys)
    assert rc == 0
    sheet = (folder / "laser_sheet1.dxf").read_bytes()
    rc, captured = _export(fourbar, out, "--to", "stl", capsys=capsys)
    assert rc == 0, captured.err
    # the laser kit is still there, byte for byte, beside the print
    assert (folder / "laser_sheet1.dxf").read_bytes() == sheet
    assert ezdxf.readfile(folder / "laser_sheet1.dxf").modelspace().query("CIRCLE")
    mesh = trimesh.load(folder / "fourbar.stl")
    assert len(mesh.faces) > 100
    assert "fourbar: dxf kept from export 1 (" in captured.out
    report = _report(folder)
    assert report["report_version"] == 4
    assert {f: report["formats"][f]["status"] for f in ("dxf", "stl")} == {
        "dxf": "exported", "stl": "exported"}
    assert (report["exports"]["dxf"]["export"], report["exports"]["dxf"]["kept"]) == (1, True)
    assert (report["exports"]["stl"]["export"], report["exports"]["stl"]["kept"]) == (2, False)
    assert report["removed"] == []
    # as-built checks of both kits, the kept one read back again by this export
    checked = {f: [c["file"] for c in report["formats"][f]["checks"]] for f in ("dxf", "stl")}
    assert "laser_sheet1.dxf" in checked["dxf"] and "fourbar.stl" in checked["stl"]
    assert all(c["ok"] for f in ("dxf", "stl") for c in report["formats"][f]["checks"])
    assert report["verdict"]["level"] == "ok"
    # every file of both formats is listed as the folder's, the record included
    on_disk = sorted(p.name for p in folder.iterdir())
    assert report["files"] == on_disk and MANIFEST in on_disk
    md = (folder / "report.md").read_text()
    assert "This folder holds the files of more than one export: export 1: dxf; " \
           "export 2: stl." in md
    assert "kept from that export (same design, settings and fabkit version) and checked " \
           "again as built" in md
    html = (folder / "report.html").read_text()
    assert "<h2>Exports in this folder</h2>" in html and "kept, checked again" in html
    index = (out / "index.html").read_text()
    assert "from more than one export: dxf: export 1 (" in index and "stl: export 2 (" in index
    # the record is typed and names where each format came from
    record = read_manifest(folder)
    assert record.formats["dxf"].export == 1 and record.formats["stl"].export == 2
    assert "laser_sheet1.dxf" in record.formats["dxf"].files


def test_stale_formats_are_removed_with_the_reason(fourbar, tmp_path, capsys):
    out = tmp_path / "out"
    folder = out / "fourbar"
    assert _export(fourbar, out, "--to", "dxf", capsys=capsys)[0] == 0
    # a setting of the laser kit changes in the template: the kit in the folder is stale
    text = fourbar.read_text()
    fourbar.write_text(text.replace("kerf = 0.15 ", "kerf = 0.2  "))
    assert fourbar.read_text() != text
    rc, captured = _export(fourbar, out, "--to", "stl", capsys=capsys)
    assert rc == 0, captured.err
    assert not any(p.name.startswith("laser_") for p in folder.iterdir())
    assert (folder / "fourbar.stl").is_file()
    line = next(x for x in captured.out.splitlines() if " removed: " in x)
    assert line.startswith("fourbar: dxf (laser_assembly.png, ") and \
        line.endswith("from export 1 removed: the design changed since")
    report = _report(folder)
    assert "dxf" not in report["formats"] and list(report["exports"]) == ["stl"]
    assert report["removed"] == [line.removeprefix("fourbar: ")]
    assert "Removed from the folder (stale): dxf (" in (folder / "report.md").read_text()
    assert report["process"] == "print"  # the folder now holds a print only


def test_a_changed_setting_removes_the_kits_that_read_it(tmp_path, capsys):
    out = tmp_path / "out"
    template = TEMPLATES / "fourbar.toml"
    assert _export(template, out, "--to", "dxf,stl", capsys=capsys)[0] == 0
    # motion.to is read by every format: the print made again now, the laser kit is stale
    rc, captured = _export(template, out, "--to", "stl", "--set", "motion.to=2.9",
                           capsys=capsys)
    assert rc == 0, captured.err
    report = _report(out / "fourbar")
    assert "dxf" not in report["formats"]
    assert report["removed"][0].endswith("removed: settings changed: motion.to default → 2.9")
    assert report["exports"]["stl"]["settings"] == {"motion": {"to": 2.9}}


def test_the_same_format_again_replaces_its_files(fourbar, tmp_path, capsys):
    out = tmp_path / "out"
    folder = out / "fourbar"
    assert _export(fourbar, out, "--to", "dxf", capsys=capsys)[0] == 0
    first = _report(folder)["exports"]["dxf"]
    # the same export again: the same files, the same record (identical input, identical bytes)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert _export(fourbar, out, "--to", "dxf", capsys=capsys)[0] == 0
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    # with another kerf: replaced, and a new export number
    rc, captured = _export(fourbar, out, "--to", "dxf", "--set", "laser.kerf=0.25",
                           capsys=capsys)
    assert rc == 0, captured.err
    report = _report(folder)
    assert report["exports"]["dxf"]["export"] == first["export"] + 1
    assert report["exports"]["dxf"]["settings"] == {"laser": {"kerf": 0.25}}
    assert report["removed"] == []
    assert json.loads((folder / "laser_bom.json").read_text())["kerf"]["kerf_mm"] == 0.25


def test_files_of_other_commands_stay_and_a_foreign_record_is_refused(fourbar, tmp_path,
                                                                      capsys):
    out = tmp_path / "out"
    folder = out / "fourbar"
    assert _export(fourbar, out, "--to", "dxf", capsys=capsys)[0] == 0
    (folder / "notes.txt").write_text("mine")
    assert _export(fourbar, out, "--to", "stl", capsys=capsys)[0] == 0
    assert (folder / "notes.txt").read_text() == "mine"
    for bad, why in [("{\"formats\": {}}", "no schema"),
                     (json.dumps({"schema": SCHEMA, "schema_version": 99, "design": "fourbar",
                                  "formats": {}}), "schema version 99"),
                     (json.dumps({"schema": SCHEMA, "schema_version": SCHEMA_VERSION,
                                  "design": "fourbar", "formats": {"dxf": {"files": ["../x"]}}}),
                      "formats.dxf.files: expected plain file names"),
                     ("not json", "not JSON")]:
        (folder / MANIFEST).write_text(bad)
        before = sorted(p.name for p in folder.iterdir())
        with pytest.raises(OutputError, match=why) as err:
            read_manifest(folder)
        assert str(folder / MANIFEST) in str(err.value)
        rc, captured = _export(fourbar, out, "--to", "stl", capsys=capsys)
        assert rc == 1
        assert captured.err.strip().splitlines()[-1] == f"fabkit: error: {err.value}"
        assert "remove it (or the folder) to export afresh" in captured.err
        assert sorted(p.name for p in folder.iterdir()) == before  # nothing touched


def test_the_library_batch_adds_formats_too(fourbar, tmp_path):
    out = tmp_path / "out"
    first = export_many([fourbar], ["dxf"], out, isolate=False, tolerance_samples=0,
                        previews=False)
    assert first[0].ok, first[0].message
    second = export_many([fourbar], ["stl"], out, isolate=False, tolerance_samples=0,
                         previews=False)
    assert second[0].ok and second[0].exported_formats == ["dxf", "stl"]
    assert second[0].notes[0].startswith("dxf kept from export 1 (")
    assert second[0].formats["dxf"].checks and all(c.ok for c in second[0].formats["dxf"].checks)


def test_export_many_takes_bundled_names_and_suggests_for_misspelt_ones(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no file of those names here: the bundled templates are meant
    rows = export_many(["fourbar", "super_stabel", "fourbar_chian"], ["dxf"], "out",
                       isolate=False, tolerance_samples=0, previews=False)
    assert rows[0].ok, rows[0].message
    assert Path(rows[0].path) == TEMPLATES / "fourbar.toml"
    assert (tmp_path / "out" / "fourbar" / "laser_sheet1.dxf").is_file()
    assert [r.status.value for r in rows[1:]] == ["failed", "failed"]
    assert rows[1].message == ("super_stabel: no such file, nor a bundled template of that name "
                               "(fabkit templates lists them); did you mean 'super_stable'?")
    assert rows[2].message.endswith("did you mean 'fourbar_chain'?")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["fourbar", "index.html"]
    # a file of that name in the current folder wins over the bundled one, as on the command line
    own = (TEMPLATES / "fourbar.toml").read_text().replace('name = "fourbar"',
                                                           'name = "my_fourbar"')
    (tmp_path / "fourbar.toml").write_text(own)
    rows = export_many(["fourbar"], ["dxf"], "out", isolate=False, tolerance_samples=0,
                       previews=False)
    assert rows[0].ok and rows[0].name == "my_fourbar"


# --- the library's export: the same lock, and no second truth in a design folder --------------

def test_a_library_export_into_a_locked_folder_fails_and_writes_nothing(tmp_path):
    import fabkit
    from fabkit.errors import LockedError
    from fabkit.writers import export
    from fabkit.io.outputs import OutputLock

    design = fabkit.load_template("fourbar")
    out = tmp_path / "out"
    out.mkdir()
    with OutputLock(out):  # an export into out/ is running (it would write out/<name>/)
        with pytest.raises(LockedError) as err:
            export(design, "dxf", out / "kit")
        assert err.value.path == str(out)
        assert str(err.value).startswith(f"{out}: process ")
        assert sorted(p.name for p in out.iterdir()) == [".fabkit.lock"]  # nothing written
    paths, report = export(design, "dxf", out / "kit")  # the lock released: it goes through
    assert (out / "kit" / "laser_sheet1.dxf") in paths and report["layers"]["count"] >= 1
    assert sorted(p.name for p in out.iterdir()) == ["kit"]  # the lock file is gone with it


def test_a_library_export_leaves_an_exported_design_folder_alone(tmp_path, capsys):
    import fabkit
    from fabkit.writers import export

    out = tmp_path / "out"
    assert _export(TEMPLATES / "fourbar.toml", out, "--to", "dxf", capsys=capsys)[0] == 0
    folder = out / "fourbar"
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with pytest.raises(OutputError, match=r"holds the kit and report of a `fabkit export`"):
        export(fabkit.load_template("fourbar"), "dxf", folder, laser={"kerf": 0.2})
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    # the way to add a kerf-0.2 kit beside it keeps one report: a folder of its own
    paths, _ = export(fabkit.load_template("fourbar"), "dxf", out / "kerf_0.2",
                      laser={"kerf": 0.2})
    assert json.loads((out / "kerf_0.2" / "laser_bom.json").read_text())["kerf"]["kerf_mm"] == 0.2
