"""The library's ``export()`` keeps out of folders another export owns: it waits for no one,
refuses a folder a running ``fabkit export`` holds (the folder or the one above it), refuses a
folder that holds an export's kit and report, and writes nothing when it refuses."""

import pytest

from fabkit.errors import LockedError, OutputError
from fabkit.export import export
from fabkit.io.outputs import LOCK_NAME, OutputLock
from fabkit.io.templates import load_template
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
