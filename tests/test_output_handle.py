"""One handle on the output folder: a folder swapped for a link (or another folder) while a
command works is noticed, the command fails with one line, and nothing is written elsewhere.

The swap is made at a fixed point of the run (inside a stage the test wraps, or inside an
exporter that a worker runs), never after a sleep.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import fabkit.commands.design as design_command
from fabkit.cli import main
from fabkit.errors import FolderChangedError, OutputError
from fabkit.io.folder import OutputFolder

TEMPLATES = Path(__file__).resolve().parents[1] / "templates"


def _files(folder: Path) -> list[str]:
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))


def _swap_for_link(out: Path, victim: Path) -> None:
    """What the attacker does: ``rm -rf out && ln -s victim out``."""
    shutil.rmtree(out)
    out.symlink_to(victim)


# --- the handle itself ------------------------------------------------------------------------

def test_a_handle_writes_into_the_folder_it_holds_and_refuses_a_swapped_one(tmp_path):
    out, victim = tmp_path / "out", tmp_path / "victim"
    victim.mkdir()
    held = OutputFolder.open(out)
    assert held.write_files({"a/b.txt": b"1"}) == [out / "a" / "b.txt"]
    assert (out / "a" / "b.txt").read_bytes() == b"1"
    sub = held.folder("a", create=False)
    _swap_for_link(out, victim)
    for write in (lambda: held.write("c.txt", b"2"), lambda: sub.write("d.txt", b"3"),
                  held.verify):
        with pytest.raises(FolderChangedError) as info:
            write()
        assert str(info.value).startswith(f"{out}: the output folder was moved")
        assert len(str(info.value).splitlines()) == 1
    assert _files(victim) == []


def test_a_folder_put_in_place_of_the_held_one_is_noticed(tmp_path):
    out, other = tmp_path / "out", tmp_path / "other"
    out.mkdir()
    other.mkdir()
    held = OutputFolder.open(out)
    out.rename(tmp_path / "moved")
    other.rename(out)  # a real folder now, not the one held
    with pytest.raises(FolderChangedError):
        held.write("x.txt", b"x")
    assert _files(out) == [] and _files(tmp_path / "moved") == []


def test_a_link_given_as_the_output_folder_is_refused(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "link").symlink_to(real)
    with pytest.raises(OutputError, match="link: is a symbolic link; fabkit does not write "
                                          "through it"):
        OutputFolder.open(tmp_path / "link").write("x.txt", b"x")
    assert _files(real) == []


def test_a_handle_reopened_in_another_process_must_be_the_same_folder(tmp_path):
    import pickle

    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.mkdir()
    travelled = pickle.loads(pickle.dumps(OutputFolder.open(out)))
    assert travelled.write("same.txt", b"1") == out / "same.txt"
    again = pickle.dumps(OutputFolder.open(out))
    _swap_for_link(out, victim)
    with pytest.raises(FolderChangedError):
        pickle.loads(again).write("x.txt", b"x")
    assert _files(victim) == []


def test_a_link_in_place_of_a_file_of_its_own_is_not_read(tmp_path):
    out = tmp_path / "out"
    held = OutputFolder.open(out)
    held.write("mine.json", b"{}")
    (tmp_path / "edited.json").write_text('{"edited": true}')
    (out / "mine.json").unlink()
    (out / "mine.json").symlink_to(tmp_path / "edited.json")
    with pytest.raises(OutputError, match="mine.json: is a symbolic link, not a regular file: "
                                          "refused"):
        held.read_bytes("mine.json")


# --- commands ---------------------------------------------------------------------------------

def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_tolerance_into_a_folder_swapped_midway_writes_nothing_elsewhere(tmp_path, monkeypatch,
                                                                        capsys):
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.mkdir()
    import fabkit.tolerance as tolerance_package

    analyse = tolerance_package.analyse_tolerance

    def swapped_midway(*args, **kwargs):  # the analysis runs; the folder is swapped meanwhile
        result = analyse(*args, **kwargs)
        _swap_for_link(out, victim)
        return result

    monkeypatch.setattr(tolerance_package, "analyse_tolerance", swapped_midway)
    rc = main(["tolerance", str(TEMPLATES / "fourbar.toml"), "--samples", "20", "-q", "-o",
               str(out)])
    line = _one_line(capsys)
    assert rc == 1, line
    assert "the output folder was moved, removed or replaced" in line
    assert _files(victim) == []


def test_design_curve_into_a_folder_swapped_midway_writes_nothing_elsewhere(tmp_path,
                                                                           monkeypatch, capsys):
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.mkdir()
    real = design_command.curve_design_figure

    def swapped_midway(result):  # drawn after the design work: the folder is swapped then
        _swap_for_link(out, victim)
        return real(result)

    monkeypatch.setattr(design_command, "curve_design_figure", swapped_midway)
    radius = 250.0  # a quarter circle of 250 mm: a chain that builds
    src = tmp_path / "arc.csv"
    src.write_text("x,y\n" + "\n".join(f"{radius * math.cos(a):.6f},{radius * math.sin(a):.6f}"
                                        for a in np.linspace(0, np.pi / 2, 60)) + "\n")
    rc = main(["design", "--curve", str(src), "-q", "-o", str(out)])
    line = _one_line(capsys)
    assert rc == 1, line
    assert "the output folder was moved, removed or replaced" in line
    assert _files(victim) == []


SWAPPING_RUNNER = textwrap.dedent('''
    import os
    import shutil
    import sys

    import fabkit.writers.dxf as dxf
    from fabkit.cli import main

    real = dxf.write


    def write(plan, **options):
        # the attacker's moment, while the laser kit is made: rm -rf out && ln -s victim out
        out, victim = os.environ["FABKIT_TEST_OUT"], os.environ["FABKIT_TEST_VICTIM"]
        if not os.path.islink(out):
            shutil.rmtree(out)
            os.symlink(victim, out)
        return real(plan, **options)


    dxf.write = write  # in spawned workers too: they import this file

    if __name__ == "__main__":
        sys.exit(main(sys.argv[1:]))
''')


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_export_into_a_folder_swapped_midway_writes_nothing_elsewhere(tmp_path, jobs):
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.mkdir()
    runner = tmp_path / "runner.py"
    runner.write_text(SWAPPING_RUNNER)
    env = {**os.environ, "FABKIT_TEST_OUT": str(out), "FABKIT_TEST_VICTIM": str(victim)}
    proc = subprocess.run([sys.executable, str(runner), "export", "fourbar", "--to", "dxf", "-o",
                           str(out), "--jobs", jobs, "--no-previews", "-q"],
                          env=env, capture_output=True, text=True, timeout=300)
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 1 and len(err) == 1, proc.stderr
    assert "the output folder was moved, removed or replaced" in err[0]
    assert _files(victim) == []  # no fourbar/, no index.html, no staging folder, no lock


# --- the sweep's chunks -----------------------------------------------------------------------

SWEEP = ["sweep", "chaotic", "--vary", "nodes[4].x=-0.4:-0.3:2", "--measure", "fixed_points",
         "--jobs", "1", "--no-plots", "--chunk-size", "1", "-q"]


def test_a_chunk_replaced_by_a_link_to_an_edited_file_is_set_aside_not_read(tmp_path, capsys):
    out, outside = tmp_path / "out", tmp_path / "outside"
    outside.mkdir()
    assert main([*SWEEP, "-o", str(out)]) == 0
    first = (out / "sweep.csv").read_text()
    chunk = out / "chunks" / "chunk-0000001-0000001.json"
    records = json.loads(chunk.read_text())
    records[0]["domain_lo"] = 12345.5  # the edit that must never reach sweep.csv
    edited = outside / chunk.name
    edited.write_text(json.dumps(records))
    chunk.unlink()
    chunk.symlink_to(edited)
    capsys.readouterr()
    assert main([*SWEEP, "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "damaged chunk chunk-0000001-0000001.json set aside" in said
    assert "is a symbolic link, not a regular file: refused" in said
    assert "12345.5" not in (out / "sweep.csv").read_text()
    assert (out / "sweep.csv").read_text() == first  # the point computed again, as before
    assert (out / "chunks" / (chunk.name + ".damaged")).is_symlink()  # the link set aside
    assert chunk.is_file() and not chunk.is_symlink()
    assert json.loads(edited.read_text()) == records  # the file outside untouched


# --- leftovers of a killed export: only fabkit's own folders are removed ----------------------

EXPORT = ["export", "fourbar", "--to", "dxf", "--tolerance-samples", "0", "--no-previews", "-q"]


def test_a_backup_folder_fabkit_did_not_make_is_never_removed(tmp_path, capsys):
    out = tmp_path / "out"
    assert main([*EXPORT, "-o", str(out)]) == 0
    mine = out / ".fourbar.old"
    mine.mkdir()
    (mine / "notes.txt").write_text("the user's own\n")
    rc = main([*EXPORT, "-o", str(out)])
    line = _one_line(capsys)
    assert rc == 1
    assert line == (f"fabkit: error: {mine}: is in the way: a folder fabkit did not make (it "
                    "lacks fabkit's mark .fabkit-folder); move it away")
    assert (mine / "notes.txt").read_text() == "the user's own\n"
    assert (out / "fourbar" / "exports.json").is_file()  # the export before stays as it was


def test_a_backup_folder_left_by_a_killed_export_is_removed(tmp_path, capsys):
    from fabkit.pipeline.folders import MARK

    out = tmp_path / "out"
    assert main([*EXPORT, "-o", str(out)]) == 0
    # killed after its two renames, before the backup's removal: the backup holds the mark
    shutil.copytree(out / "fourbar", out / ".fourbar.old")
    (out / ".fourbar.old" / MARK).write_text("made by fabkit export\n")
    assert main([*EXPORT, "-o", str(out)]) == 0, capsys.readouterr().err
    assert not (out / ".fourbar.old").exists()
    assert not (out / "fourbar" / MARK).exists()  # a design's folder carries no mark
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []


def test_a_backup_folder_put_back_when_the_new_one_never_arrived(tmp_path, capsys):
    from fabkit.pipeline.folders import MARK

    out = tmp_path / "out"
    assert main([*EXPORT, "-o", str(out)]) == 0
    before = (out / "fourbar" / "exports.json").read_bytes()
    (out / "fourbar" / MARK).write_text("made by fabkit export\n")
    (out / "fourbar").rename(out / ".fourbar.old")  # killed between the two renames
    assert main([*EXPORT, "-o", str(out)]) == 0, capsys.readouterr().err
    assert (out / "fourbar" / "exports.json").read_bytes() == before
    assert not (out / ".fourbar.old").exists() and not (out / "fourbar" / MARK).exists()


# --- the as-built checks read the staged files through the folder held ------------------------

def test_a_check_given_the_held_folder_reads_the_folder_it_holds_not_the_path(tmp_path):
    from fabkit.check import check_file
    from fabkit.templates import load_template
    from fabkit.writers import get_exporter

    design = load_template(TEMPLATES / "origami_sheet.toml")
    files = get_exporter("fold").export_design(design, {}).files
    out, victim = tmp_path / "out", tmp_path / "victim"
    victim.mkdir()
    held = OutputFolder.open(out)
    held.write_files(files)
    name = next(n for n in files if n.endswith(".fold"))
    (victim / name).write_text('{"file_spec": 1.1, "edited": [[[')  # what the path names now
    out.rename(tmp_path / "moved")
    out.symlink_to(victim)
    report = check_file(out / name, design=design, folder=held)
    assert report["ok"], report["checks"]  # the file written, read through the handle
    assert report["max_map_difference"] < 1e-6
    from fabkit.errors import InputFileError

    with pytest.raises(InputFileError) as info:  # by path: the file the link leads to
        check_file(out / name, design=design)
    assert info.value.kind == "damaged"


def test_a_staged_file_replaced_by_a_link_is_not_read_by_the_check(tmp_path, monkeypatch):
    import fabkit.writers as writers
    from fabkit.pipeline import export_one

    out, outside = tmp_path / "out", tmp_path / "outside"
    outside.mkdir()
    (outside / "edited.dxf").write_text("0\nSECTION\n2\nHEADER\n0\nBOGUS\nxx\n")
    real = writers.write_outputs

    def linked_after_writing(files, stage_dir):  # the staged sheet swapped for a link
        written = real(files, stage_dir)
        sheet = stage_dir.path / "laser_sheet1.dxf"
        sheet.unlink()
        sheet.symlink_to(outside / "edited.dxf")
        return written

    monkeypatch.setattr(writers, "write_outputs", linked_after_writing)
    res = export_one(TEMPLATES / "fourbar.toml", ["dxf"], out, {}, tolerance_samples=0,
                     previews=False)
    checks = {c.file: c for c in res.formats["dxf"].checks}
    sheet = checks["laser_sheet1.dxf"]
    assert not sheet.ok
    assert "is a symbolic link, not a regular file: refused" in sheet.error, sheet
    assert "group code" not in sheet.error  # the edited file was never parsed


# --- the library's export, fabkit bench and templates --copy hold their folder too ------------

def _swap_parent_for_link(base: Path, victim: Path) -> None:
    """A link higher up than the output folder's own name: ``mv base moved && ln -s victim
    base`` (``base/out`` now names ``victim/out``)."""
    base.rename(base.parent / "moved")
    base.symlink_to(victim)


def test_the_librarys_export_into_a_folder_swapped_midway_writes_nothing_elsewhere(
        tmp_path, monkeypatch):
    import fabkit.writers.dxf as dxf_writer
    from fabkit.templates import load_template
    from fabkit.writers import export

    base, victim = tmp_path / "base", tmp_path / "victim"
    (base / "out").mkdir(parents=True)
    (victim / "out").mkdir(parents=True)
    real = dxf_writer.export_design

    def swapped_midway(*args, **kwargs):  # computed; the folder above is swapped meanwhile
        result = real(*args, **kwargs)
        _swap_parent_for_link(base, victim)
        return result

    monkeypatch.setattr(dxf_writer, "export_design", swapped_midway)
    with pytest.raises(FolderChangedError):
        export(load_template(TEMPLATES / "fourbar.toml"), "dxf", base / "out")
    assert _files(victim) == ["out"]  # nothing written through the link


def test_bench_into_a_folder_swapped_midway_writes_nothing_elsewhere(tmp_path, monkeypatch,
                                                                     capsys):
    import fabkit.bench.study as study

    base, victim = tmp_path / "base", tmp_path / "victim"
    (base / "out").mkdir(parents=True)
    (victim / "out").mkdir(parents=True)
    real = study.finite

    def swapped_midway(doc):  # every result made; the folder above is swapped before writing
        _swap_parent_for_link(base, victim)
        return real(doc)

    monkeypatch.setattr(study, "finite", swapped_midway)
    monkeypatch.setattr("fabkit.commands.bench._parts", lambda parts: [])  # nothing measured
    rc = main(["bench", "--quick", "-q", "-o", str(base / "out")])
    line = _one_line(capsys)
    assert rc == 1 and "the output folder was moved, removed or replaced" in line, line
    assert _files(victim) == ["out"]
    assert _files(tmp_path / "moved") == ["out"]  # and nothing half-made in the folder held


def test_templates_copy_into_a_folder_swapped_midway_writes_nothing_elsewhere(
        tmp_path, monkeypatch, capsys):
    import fabkit.commands.templates as templates_command

    base, victim = tmp_path / "base", tmp_path / "victim"
    (base / "mine").mkdir(parents=True)
    (victim / "mine").mkdir(parents=True)
    real = templates_command.template_files

    def swapped_midway(name):  # the templates found; the folder above swapped meanwhile
        found = real(name)
        _swap_parent_for_link(base, victim)
        return found

    monkeypatch.setattr(templates_command, "template_files", swapped_midway)
    rc = main(["templates", "--copy", "super_stable_chain", "-o", str(base / "mine")])
    line = _one_line(capsys)
    assert rc == 1 and "the output folder was moved, removed or replaced" in line, line
    assert _files(victim) == ["mine"]
