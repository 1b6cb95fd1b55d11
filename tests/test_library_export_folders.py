"""The library's ``export()`` keeps out of folders another export owns: it waits for no one,
refuses a folder a running ``fabkit export`` holds (the folder or the one above it), refuses a
folder that holds an export's kit and report, and writes nothing when it refuses."""

import pytest

from fabkit.errors import LockedError, OutputError
from fabkit.writers import export
from fabkit.io.outputs import LOCK_NAME, OutputLock
from fabkit.templates import load_template
from fabkit.pipeline import export_many

from conftest import TEMPLATES


@pytest.fixture(scope="module")
def fourbar():
    return load_template(TEMPLATES / "fourbar.toml")


def test_export_writes_and_leaves_no_lock(tmp_path, fourbar):
    paths, _ = export(fourbar, "dxf", tmp_path / "kit")
    assert paths and all(p.is_file() for p in paths)
    assert not (tmp_path / "kit" / LOCK_NAME).exists()


def test_export_refuses_a_folder_a_running_export_holds(tmp_path, fourbar):
    kit = tmp_path / "kit"
    kit.mkdir()
    with OutputLock(kit):
        with pytest.raises(LockedError, match="kit"):
            export(fourbar, "dxf", kit)
    assert sorted(p.name for p in kit.iterdir()) == []


def test_export_refuses_a_design_folder_while_the_batch_above_runs(tmp_path, fourbar):
    out = tmp_path / "out"
    out.mkdir()
    with OutputLock(out):  # `fabkit export ... -o out` at work
        with pytest.raises(LockedError, match="out"):
            export(fourbar, "dxf", out / "fourbar")
    assert not (out / "fourbar").exists()


def test_export_refuses_a_folder_that_holds_an_exports_report(tmp_path, fourbar):
    out = tmp_path / "out"
    [result] = export_many([TEMPLATES / "fourbar.toml"], ["dxf"], out, check=False,
                           isolate=False)
    folder = out / result.name
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with pytest.raises(OutputError, match=r"holds the kit and report of a `fabkit export`"):
        export(fourbar, "dxf", folder, laser={"kerf": 0.2})
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


@pytest.mark.parametrize("isolate", [False, True], ids=["in-process", "worker"])
def test_the_batch_does_not_swap_a_folder_a_library_export_holds(tmp_path, fourbar, isolate):
    out = tmp_path / "out"
    folder = out / "fourbar"
    export(fourbar, "dxf", folder)  # a library export's kit, no report: not the batch's
    (folder / "notes.txt").write_text("mine")
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with OutputLock(folder):  # that export() still at work
        [result] = export_many(["fourbar"], ["dxf"], out, check=False, isolate=isolate,
                               previews=False, tolerance_samples=0)
    assert not result.ok
    assert "is writing into this folder (it holds its .fabkit.lock)" in result.message
    assert "nothing was swapped in" in result.message
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert sorted(p.name for p in out.iterdir()) == ["fourbar"]  # no staging folder left
    # once it has finished, the batch's export replaces the kit and keeps the other file
    [result] = export_many(["fourbar"], ["dxf"], out, check=False, isolate=isolate,
                           previews=False, tolerance_samples=0)
    assert result.ok, result.message
    assert (folder / "notes.txt").read_text() == "mine"
    assert (folder / "report.json").is_file()
    assert not (folder / LOCK_NAME).exists()
