"""``fabkit export`` / ``check`` / ``templates``: folders per design, reports, identical bytes on
a second run, no partial file after a kill or a failing writer, settings and format parsing."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import fabkit.writers
from fabkit.cli import main
from fabkit.pipeline import Status, export_many
from fabkit.commands.export import parse_formats
from fabkit.commands.settings import parse_settings
from fabkit.errors import UsageError
from fabkit.templates import load_template

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"
FAKE_MODULE = "fabkit_test_lengths_format"

# A small format of our own, so these tests do not depend on the state of the real exporters:
# one text file with every edge length in mm (scale from --set lengths.scale or the template).
FAKE_SOURCE = textwrap.dedent('''
    from typing import Optional

    from pydantic import Field

    from fabkit.io.schema import Section

    FORMAT = "lengths"


    class SETTINGS(Section):
        """--set lengths.KEY=VALUE: the format declares its own section."""

        scale: Optional[float] = Field(None, gt=0)

    def applies(design):
        return design.network.dim == 2

    def export_design(design, settings):
        from fabkit.writers import ExportResult

        table = dict(design.fabrication.get("lengths", {}))
        table.update(settings.get("lengths", {}))
        scale = float(table.get("scale", 1.0))
        text = "".join(f"{v * scale:.12g}\\n" for v in design.network.edge_lengths)
        return ExportResult(files={design.name + "_lengths.txt": text.encode()},
                            report={"edges": design.network.n_edges, "scale": scale})
''')


@pytest.fixture
def lengths_format(tmp_path, monkeypatch):
    """Register the small format (a real module file, so spawned workers import it too)."""
    mods = tmp_path / "mods"
    mods.mkdir()
    (mods / f"{FAKE_MODULE}.py").write_text(FAKE_SOURCE)
    monkeypatch.syspath_prepend(str(mods))
    monkeypatch.setenv("PYTHONPATH", str(mods) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    monkeypatch.setattr(fabkit.writers, "EXPORTERS", {"lengths": FAKE_MODULE})
    return mods


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under a folder (hidden ones too) → its bytes."""
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_export_writes_a_folder_per_design_with_reports_identically_twice(tmp_path,
                                                                         lengths_format, capsys):
    out = tmp_path / "out"
    rc = main(["export", str(TEMPLATES / "fourbar.toml"),
               str(TEMPLATES / "super_stable_chain8.toml"), "-o", str(out), "--jobs", "2",
               "--set", "lengths.scale=10", "--tolerance-samples", "40", "--progress"])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    # progress on stderr (asked for: it is not a terminal), the summary on stdout
    progress = captured.err.splitlines()
    assert all(line.startswith("fabkit export [") for line in progress), progress
    assert "fourbar: ok in " in captured.err and "super_stable_chain8: ok in " in captured.err
    assert "2 exported, 0 failed" in captured.out and "ok in" not in captured.out
    assert captured.out.splitlines()[-1] == f"open {out / 'index.html'} (every design's report)"
    assert sorted(p.name for p in out.iterdir()) == ["fourbar", "index.html",
                                                     "super_stable_chain8"]

    files = snapshot(out / "fourbar")
    assert set(files) == {"fourbar_lengths.txt", "exports.json", "report.json", "report.md",
                          "report.html",
                          "preview_motion.png", "preview_map.png", "preview_tolerance.png"}
    for name in ("preview_motion.png", "preview_map.png", "preview_tolerance.png"):
        assert files[name][:8] == b"\x89PNG\r\n\x1a\n"
    # the --set value reached the exporter: lengths in mm at 10 mm per unit
    mm = np.array(files["fourbar_lengths.txt"].decode().split(), dtype=float)
    net = load_template(TEMPLATES / "fourbar.toml").network
    np.testing.assert_allclose(mm, 10 * net.edge_lengths, rtol=1e-11)

    report = json.loads(files["report.json"])
    assert report["ok"] is True and report["outcome"] == "ok"
    assert report["files"] == sorted(files)  # the manifest: exactly what the export wrote
    assert report["formats"]["lengths"]["status"] == "exported"
    assert report["formats"]["lengths"]["report"] == {"edges": 4, "scale": 10.0}
    motion = report["motion"]
    assert motion["status"] == "finished" and motion["method"] == "constructive"
    # the antiparallelogram keeps d1 * d2 = 4
    assert motion["final_distances"]["d1"] == pytest.approx(3.0, abs=1e-12)
    assert motion["final_distances"]["d2"] == pytest.approx(4.0 / 3.0, abs=1e-12)
    assert motion["max_edge_error"] < 1e-12
    assert report["design"]["modes"] == {"total": 4, "rigid": 3, "conformational": 1,
                                         "self_stress": 0}
    assert report["tolerance"]["samples"] == 40
    assert report["previews"] == ["preview_map.png", "preview_motion.png",
                                  "preview_tolerance.png"]
    # every picture the Markdown report shows is in the folder
    md = files["report.md"].decode()
    for name in report["previews"]:
        assert f"]({name})" in md
    assert "[`fourbar_lengths.txt`](fourbar_lengths.txt)" in md

    chain = json.loads((out / "super_stable_chain8" / "report.json").read_text())
    assert chain["design"]["nodes"] == 26 and chain["design"]["edges"] == 48
    assert len(chain["motion"]["final_distances"]) == 9

    # a second run, now in one process at a time, gives the same bytes (pictures included)
    first = snapshot(out)
    assert main(["export", str(TEMPLATES / "fourbar.toml"),
                 str(TEMPLATES / "super_stable_chain8.toml"), "-o", str(out), "--set",
                 "lengths.scale=10", "--tolerance-samples", "40"]) == 0
    second = snapshot(out)
    assert first.keys() == second.keys()
    assert [k for k in first if first[k] != second[k]] == []
    assert not [k for k in second if "/." in "/" + k]  # no hidden staging or temporary file left


def test_no_previews_leaves_the_pictures_out(tmp_path, lengths_format):
    out = tmp_path / "out"
    rc = main(["export", str(TEMPLATES / "fourbar.toml"), "-o", str(out), "--no-previews"])
    assert rc == 0
    assert set(snapshot(out)) == {"fourbar/fourbar_lengths.txt", "fourbar/exports.json",
                                  "fourbar/report.json", "fourbar/report.md",
                                  "fourbar/report.html", "index.html"}
    report = json.loads((out / "fourbar" / "report.json").read_text())
    assert report["previews"] == [] and report["tolerance"]["samples"] == 200


def test_folders_and_globs_expand_to_templates(tmp_path, lengths_format, capsys):
    folder = tmp_path / "designs"
    folder.mkdir()
    for name in ("bar_a", "bar_b", "other"):
        (folder / f"{name}.toml").write_text((TEMPLATES / "fourbar.toml").read_text().replace(
            'name = "fourbar"', f'name = "{name}"'))
    (folder / "notes.txt").write_text("not a template")
    out = tmp_path / "out"
    rc = main(["export", str(folder / "bar_*.toml"), "-o", str(out), "--tolerance-samples", "0",
               "--no-previews", "--no-check"])
    assert rc == 0
    assert sorted(p.name for p in out.iterdir()) == ["bar_a", "bar_b", "index.html"]
    assert "tolerance" not in json.loads((out / "bar_a" / "report.json").read_text())
    rc = main(["export", str(folder), "-o", str(out), "--tolerance-samples", "0", "--no-previews"])
    assert rc == 0
    assert sorted(p.name for p in out.iterdir()) == ["bar_a", "bar_b", "index.html", "other"]
    assert (out / "other" / "other_lengths.txt").is_file()
    assert "3 exported, 0 failed" in capsys.readouterr().out
    assert main(["export", str(folder / "nothing_*.toml"), "-o", str(out)]) == 1
    assert "no file matches" in capsys.readouterr().err


def test_two_designs_with_one_name_do_not_share_a_folder(tmp_path, lengths_format, capsys):
    for sub in ("x", "y"):
        (tmp_path / sub).mkdir()
        (tmp_path / sub / "fourbar.toml").write_text((TEMPLATES / "fourbar.toml").read_text())
    out = tmp_path / "out"
    rc = main(["export", str(tmp_path / "x" / "fourbar.toml"), str(tmp_path / "y" / "fourbar.toml"),
               "-o", str(out), "--tolerance-samples", "0", "--no-previews"])
    err = capsys.readouterr().err
    assert rc == 1
    assert "name: 'fourbar' is also the name of" in err
    assert (out / "fourbar" / "report.json").is_file()


def test_other_commands_outputs_survive_an_export(tmp_path, lengths_format, capsys,
                                                  monkeypatch):
    """simulate, map and a user's own file in the design's folder are kept by export and by a
    re-export; the export's own files of a format no longer exported are removed."""
    out = tmp_path / "out"
    fourbar = str(TEMPLATES / "fourbar.toml")
    assert main(["simulate", fourbar, "-o", str(out)]) == 0
    assert main(["map", fourbar, "-o", str(out), "--steps", "4"]) == 0
    (out / "fourbar" / "notes.txt").write_text("mine")
    others = snapshot(out / "fourbar")
    assert {"trajectory.npz", "motion.png", "map.json", "map.png", "cobweb.png",
            "notes.txt"} <= set(others)
    assert main(["export", fourbar, "-o", str(out), "--no-previews"]) == 0
    first = snapshot(out / "fourbar")
    assert {k: first[k] for k in others} == others  # byte for byte
    assert set(first) == set(others) | {"fourbar_lengths.txt", "exports.json", "report.json",
                                        "report.md", "report.html"}
    # export again with a format of another name: the old export file goes, the others stay
    source = (lengths_format / f"{FAKE_MODULE}.py").read_text()
    (lengths_format / "fabkit_test_widths_format.py").write_text(
        source.replace('"_lengths.txt"', '"_widths.txt"'))
    monkeypatch.setattr(fabkit.writers, "EXPORTERS", {"widths": "fabkit_test_widths_format"})
    assert main(["export", fourbar, "-o", str(out), "--no-previews"]) == 0
    second = snapshot(out / "fourbar")
    assert {k: second[k] for k in others} == others
    assert set(second) == set(others) | {"fourbar_widths.txt", "exports.json", "report.json",
                                         "report.md", "report.html"}
    report = json.loads(second["report.json"])
    assert report["files"] == ["exports.json", "fourbar_widths.txt", "report.html", "report.json",
                               "report.md"]
    assert report["removed"] == ["lengths (fourbar_lengths.txt) from export 1 removed: its "
                                 "exporter is not available: unknown export format 'lengths'; "
                                 "valid: widths"]
    capsys.readouterr()


def test_a_file_in_place_of_the_design_folder_is_never_replaced(tmp_path, lengths_format,
                                                                 capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "fourbar").write_text("mine")
    rc = main(["export", str(TEMPLATES / "fourbar.toml"), "-o", str(out), "--no-previews"])
    assert rc == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "exists and is not a folder" in err[0]
    assert snapshot(out) == {"fourbar": b"mine"}


def test_singular_start_without_an_exporter_that_resolves_it_fails(tmp_path, lengths_format,
                                                                    capsys):
    # the flat creased sheet traced with the plain methods: its start is a bifurcation; only a
    # format that picks the branch itself may export it, and the small 2D-only format does not
    # apply, so the design fails with the simulator's reason
    sheet = json.loads((ROOT / "tests" / "data" / "paper_modules.json").read_text())
    m = sheet["modules"]["origami_sheet"]
    template = tmp_path / "flat_sheet.toml"
    template.write_text(
        f"[network]\nnodes = {m['nodes']}\nedges = {m['edges']}\n"
        f"ports = {{ d1 = {list(m['d1'])}, d2 = {list(m['d2'])} }}\n"
        "[motion]\nto = 0.5857864376269051\nmethod = \"auto\"\n")
    out = tmp_path / "out"
    rc = main(["export", str(template), "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1
    assert "flat_sheet.toml: network.nodes:" in err[0] and "singular" in err[0]
    assert not out.exists() or snapshot(out) == {}


# --- interrupted and failing writes -----------------------------------------------------------

RUNNER = textwrap.dedent('''
    import os, sys, time
    from pathlib import Path

    import fabkit.writers
    from fabkit.pipeline import export_many

    fabkit.writers.EXPORTERS.clear()
    fabkit.writers.EXPORTERS["lengths"] = sys.argv[3]
    marker, victim = Path(sys.argv[2]), sys.argv[4]
    real_fdopen = os.fdopen

    class SlowFile:
        """Writes half of the data, tells the test, then hangs until it is killed."""
        def __init__(self, fh):
            self.fh = fh
        def write(self, data):
            self.fh.write(data[: len(data) // 2])
            self.fh.flush()
            marker.write_text("writing")
            time.sleep(120)
        def __getattr__(self, name):
            return getattr(self.fh, name)
        def __enter__(self):
            return self
        def __exit__(self, *exc):
            return self.fh.__exit__(*exc)

    def fdopen(fd, *args, **kwargs):
        fh = real_fdopen(fd, *args, **kwargs)
        target = os.readlink(f"/proc/self/fd/{fd}")
        return SlowFile(fh) if victim and victim in os.path.basename(target) else fh

    os.fdopen = fdopen
    rows = export_many([sys.argv[5]], None, sys.argv[1], {}, isolate=False, tolerance_samples=20,
                       previews=False)
    print(rows[0].status, rows[0].message)
''')


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs /proc (Linux)")
def test_killing_an_export_midway_leaves_no_partial_file(tmp_path, lengths_format):
    runner = tmp_path / "runner.py"
    runner.write_text(RUNNER)
    out = tmp_path / "out"
    template = str(TEMPLATES / "fourbar.toml")
    env = {**os.environ, "PYTHONHASHSEED": "0"}

    def run(victim, marker):
        return subprocess.Popen([sys.executable, str(runner), str(out), str(marker), FAKE_MODULE,
                                 victim, template], env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)

    done = run("", tmp_path / "unused")
    assert done.wait(timeout=120) == 0 and done.stdout.read().startswith("ok")
    reference = snapshot(out)
    assert "fourbar/report.md" in reference

    # kill the second export while it writes the Markdown report
    marker = tmp_path / "marker"
    proc = run("report.md", marker)
    deadline = time.monotonic() + 120
    while not marker.exists():
        assert proc.poll() is None, proc.stderr.read()
        assert time.monotonic() < deadline, "the export never reached the file to interrupt"
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    after = snapshot(out)
    visible = {k: v for k, v in after.items() if not any(p.startswith(".") for p in k.split("/"))}
    assert visible == reference  # the earlier export is untouched
    partial = [k for k in after if k.endswith(".part")]
    assert partial and all(k.startswith(".fourbar.staging/") for k in partial)
    assert 0 < len(after[partial[0]]) < len(reference["fourbar/report.md"])  # really cut off

    # the next run clears what the killed one left and writes the same bytes
    again = run("", tmp_path / "unused")
    assert again.wait(timeout=120) == 0
    assert snapshot(out) == reference


def test_a_writer_that_raises_midway_leaves_no_partial_file(tmp_path, lengths_format,
                                                             monkeypatch):
    out = tmp_path / "out"
    template = TEMPLATES / "fourbar.toml"
    rows = export_many([template], None, out, {}, isolate=False, tolerance_samples=20,
                       previews=False)
    assert rows[0].ok, rows[0].message
    reference = snapshot(out)

    real_fdopen = os.fdopen

    class FullDisk:
        def __init__(self, fh):
            self.fh = fh

        def write(self, data):
            self.fh.write(data[: len(data) // 3])
            raise OSError(28, "No space left on device")

        def __getattr__(self, name):
            return getattr(self.fh, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return self.fh.__exit__(*exc)

    def fdopen(fd, *args, **kwargs):
        fh = real_fdopen(fd, *args, **kwargs)
        name = os.path.basename(os.readlink(f"/proc/self/fd/{fd}"))
        return FullDisk(fh) if "report.json" in name else fh

    monkeypatch.setattr(os, "fdopen", fdopen)
    rows = export_many([template], None, out, {}, isolate=False, tolerance_samples=20,
                       previews=False)
    monkeypatch.undo()
    assert rows[0].status is Status.FAILED and rows[0].error_code == "output"
    assert "cannot write the export" in rows[0].message
    assert "No space left on device" in rows[0].message
    assert snapshot(out) == reference  # nothing half-written, staging removed, old export intact


# --- command-line values ----------------------------------------------------------------------

def test_settings_are_parsed_as_toml_values():
    got = parse_settings(["laser.kerf=0.2", "laser.screw.name=\"M4-chicago\"",
                          "print.preview=false", "print.bed=[300, 250]", "laser.labels=none",
                          "origami.branch=assignment"])
    assert got == {"laser": {"kerf": 0.2, "screw": {"name": "M4-chicago"}, "labels": "none"},
                   "print": {"preview": False, "bed": [300, 250]},
                   "origami": {"branch": "assignment"}}


@pytest.mark.parametrize("item, words", [
    ("lasre.kerf=0.2", "lasre: unknown section; known: laser, motion, origami, print, tolerance"),
    ("laser.kerff=0.2", "laser.kerff: unknown key; known: bar_width,"),
    ("laser.kerf=-1", "laser.kerf: must be >= 0, got -1"),
    ("laser.kerf=wide", "laser.kerf: must be a number, got 'wide'"),
    ("print.preview=no", "print.preview: must be true or false, got 'no'"),
    ("print.hinge_layers=2.5", "print.hinge_layers: must be a whole number, got 2.5"),
    ("laser.min_web=-5", "laser.min_web: must be >= 0, got -5"),
    ("origami.samples=5000000", "origami.samples: must be <= 1000000"),
    ("motion.to=-2", "motion.to: must be > 0, got -2"),
    ("tolerance.seed=-1", "tolerance.seed: must be >= 0, got -1"),
])
def test_settings_the_schema_refuses_are_usage_errors(item, words):
    with pytest.raises(UsageError) as info:
        parse_settings([item])
    assert info.value.exit_code == 2
    assert str(info.value).startswith("--set: ") and words in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("item, words", [
    ("laser.kerf", "expected SECTION.KEY=VALUE"),
    ("kerf=0.2", "must name a section and a key"),
    ("laser..kerf=1", "must name a section and a key"),
])
def test_bad_settings_are_one_line_errors(item, words):
    with pytest.raises(UsageError, match=words) as info:
        parse_settings([item])
    assert info.value.option == "--set" and info.value.exit_code == 2


def test_a_setting_given_twice_is_an_error():
    with pytest.raises(UsageError, match="given twice"):
        parse_settings(["laser.kerf=0.1", "laser.kerf=0.2"])


def test_formats_are_checked_against_the_registry(capsys, tmp_path):
    assert parse_formats("dxf, STL,dxf") == ["dxf", "stl"]
    assert parse_formats(None) is None
    with pytest.raises(UsageError, match="unknown format 'png'; valid: dxf"):
        parse_formats("dxf,png")
    rc = main(["export", str(TEMPLATES / "fourbar.toml"), "--to", "gcode", "-o", str(tmp_path)])
    assert rc == 2
    assert capsys.readouterr().err.strip() == (
        "fabkit: error: --to: unknown format 'gcode'; valid: " + ", ".join(fabkit.writers.EXPORTERS))
    assert list(tmp_path.iterdir()) == []


def test_export_progress_is_the_commands_progress_one_line_per_stage():
    """export_many's stages and ends reach the one progress of the command line (stderr, the
    designs done of all, the time left) through DesignProgress; -q prints nothing."""
    import io

    from fabkit.commands.export import DesignProgress
    from fabkit.io.progress import Progress
    from fabkit.pipeline import DesignResult, Stage

    stream = io.StringIO()  # not a terminal: shown because asked (--progress)
    clock = iter([0.0, 0.0, 0.5, 1.0, 2.0, 4.0, 4.0]).__next__
    progress = Progress("fabkit export", show=True, stream=stream, clock=clock)
    progress.stage("2 designs into out, 1 at a time", total=2, unit="designs")
    bar = DesignProgress(progress)
    bar.stage("a", Stage.MOTION)
    bar.finished(DesignResult("a.toml", "a", Status.OK, seconds=1.25))
    bar.finished(DesignResult("b.toml", "b", Status.FAILED, seconds=0.5))
    bar.close()
    lines = stream.getvalue().splitlines()
    assert lines[0] == "fabkit export [0/2 designs, 0.0 s] 2 designs into out, 1 at a time"
    assert any(line.endswith("] a: motion") for line in lines), lines
    assert any("[1/2 designs" in line and line.endswith("] a: ok in 1.2 s") for line in lines)
    assert any("[2/2 designs" in line and line.endswith("] b: failed in 0.5 s") for line in lines)
    silent = io.StringIO()
    quiet = Progress("fabkit export", show=False, stream=silent)
    DesignProgress(quiet).stage("a", Stage.LOAD)
    assert silent.getvalue() == ""


def test_progress_counts_the_stages_of_the_one_design_in_hand():
    """Said through the one progress of every command: a design alone in hand counts its
    stages with the time left; designs side by side say each stage as it starts."""
    import io

    from fabkit.commands.export import DesignProgress
    from fabkit.io.progress import Progress
    from fabkit.pipeline import DesignResult, Stage

    stream = io.StringIO()  # not a terminal: shown because asked (--progress)
    ticks = iter([0, 0, 0, 2, 4, 5, 6, 7, 8, 9, 10])
    bar = Progress("fabkit export", show=True, stream=stream, clock=ticks.__next__)
    bar.stage("2 designs", total=2, unit="designs")
    said = DesignProgress(bar)
    said.stage("a", Stage.LOAD)
    said.stage("a", Stage.MOTION)
    said.stage("a", Stage.CHECK)
    said.stage("b", Stage.LOAD)  # b starts beside a: stages are said, not counted
    said.finished(DesignResult("a.toml", "a", Status.OK, seconds=1.25))
    said.stage("b", Stage.MOTION)  # b alone again: counted
    said.finished(DesignResult("b.toml", "b", Status.FAILED, seconds=0.5))
    lines = stream.getvalue().splitlines()
    assert lines == [
        "fabkit export [0/2 designs, 0.0 s] 2 designs",
        "fabkit export [0/2 designs, 0/7 stages, 0.0 s] a: load",
        "fabkit export [0/2 designs, 1/7 stages, 2.0 s, about 12 s left in this one] a: motion",
        "fabkit export [0/2 designs, 6/7 stages, 4.0 s, about 0.7 s left in this one] a: check",
        "fabkit export [0/2 designs, 5.0 s] b: load",
        "fabkit export [1/2 designs, 6.0 s, about 6.0 s left] a: ok in 1.2 s",
        "fabkit export [1/2 designs, 1/7 stages, 7.0 s, about 5.0 s left] b: motion",
        "fabkit export [2/2 designs, 8.0 s] b: failed in 0.5 s"]
    silent = io.StringIO()
    bar = Progress("fabkit export", show=False, stream=silent)
    DesignProgress(bar).stage("a", Stage.LOAD)
    assert silent.getvalue() == ""


# --- fabkit check, fabkit templates -----------------------------------------------------------

def test_check_needs_an_existing_file_of_a_known_kind(tmp_path, capsys):
    assert main(["check", str(tmp_path / "missing.dxf")]) == 1
    missing = tmp_path / "missing.dxf"
    assert capsys.readouterr().err.strip() == f"fabkit: error: {missing}: no such file"
    odd = tmp_path / "part.gcode"
    odd.write_text("G1 X0")
    assert main(["check", str(odd)]) == 1
    assert "no as-built check for .gcode files" in capsys.readouterr().err


def test_templates_lists_every_bundled_template(capsys):
    assert main(["templates"]) == 0
    header, *lines, footer = capsys.readouterr().out.strip().splitlines()
    stems = sorted(p.stem for p in TEMPLATES.glob("*.toml"))
    assert header == f"{len(stems)} bundled templates in {TEMPLATES}:"
    assert "fabkit templates --copy NAME" in footer
    assert len(lines) == len(stems)
    names = [load_template(TEMPLATES / f"{s}.toml").name for s in stems]
    assert [ln.split()[0] for ln in lines] == names
    fourbar = next(ln for ln in lines if ln.startswith("fourbar "))
    assert "[Fig 1a-c, 2a-c]" in fourbar and "d1 * d2 = 4" in fourbar


def test_templates_of_a_folder_are_loaded_with_their_size(tmp_path, capsys):
    (tmp_path / "fourbar.toml").write_bytes((TEMPLATES / "fourbar.toml").read_bytes())
    (tmp_path / "broken.toml").write_text("name = \"broken\"\n[motion]\ndrive = \"d1\"\n")
    assert main(["templates", str(tmp_path)]) == 0
    broken, fourbar = capsys.readouterr().out.strip().splitlines()
    assert "2D 4n/4e" in fourbar and "d1 * d2 = 4" in fourbar
    assert broken.startswith("broken ") and "(invalid: " in broken


def test_templates_of_a_missing_folder_is_an_error(tmp_path, capsys):
    assert main(["templates", str(tmp_path / "nowhere")]) == 1
    assert "no such folder of templates" in capsys.readouterr().err


# --- the real formats -------------------------------------------------------------------------

@pytest.mark.slow
def test_every_bundled_template_exports_identically_twice(tmp_path):
    """The acceptance run: every template, every format that applies, twice. Every design is
    exported or refused with one line by a fabrication stage (never an internal error), and the
    second run writes the same bytes."""
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "fabkit.cli", "export", str(TEMPLATES), "-o", str(out),
           "--jobs", "2"]
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
    reference = snapshot(out)
    second = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
    again = snapshot(out)
    assert first.returncode == second.returncode
    assert first.stderr == second.stderr
    assert "internal error" not in first.stderr and "Traceback" not in first.stderr
    assert reference.keys() == again.keys()
    assert [k for k in reference if reference[k] != again[k]] == []
    refused = {Path(line.split(": ")[2]).stem for line in first.stderr.splitlines()
               if line.startswith("fabkit: error: ")}
    for path in TEMPLATES.glob("*.toml"):
        name = load_template(path).name
        assert (out / name / "report.json").is_file() or path.stem in refused, path


def test_check_reads_an_exported_fold_file_back(tmp_path, capsys):
    out = tmp_path / "out"
    design = TEMPLATES / "origami_sheet.toml"
    assert main(["export", str(design), "--to", "fold", "-o", str(out), "--no-check"]) == 0
    fold = out / "origami_sheet" / "origami_sheet.fold"
    capsys.readouterr()
    assert main(["check", str(fold), "--design", str(design)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[-1] == f"{fold}: ok"
    assert any(ln.strip().startswith("ok    modes: 1") for ln in lines)
    assert main(["check", str(fold), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data[str(fold)]["ok"] is True


# --- report bytes -----------------------------------------------------------------------------

def test_report_json_is_plain_sorted_and_stable():
    from fabkit.report.text import jsonable, report_json

    report = {"b": np.float64(1.5), "a": (np.int64(2), float("nan")), "c": {"z": np.bool_(True)},
              "p": Path("x/y.png")}
    assert jsonable(report) == {"b": 1.5, "a": [2, None], "c": {"z": True}, "p": "x/y.png"}
    text = report_json(report)
    assert text == report_json(dict(reversed(list(report.items()))))
    assert text.decode().splitlines()[1] == '  "a": ['
    assert text.endswith(b"}\n")


# --- signals, orphans and the lock -------------------------------------------------------------

SLOW_FORMAT = textwrap.dedent('''
    import os, time
    from pathlib import Path

    FORMAT = "slow"

    def export_design(design, settings):
        from fabkit.writers import ExportResult

        marks = Path(os.environ["FABKIT_TEST_MARKS"])
        (marks / f"started-{os.getpid()}").write_text(design.name)
        # until the test says go, or for FABKIT_TEST_SLEEP seconds
        end = time.monotonic() + float(os.environ.get("FABKIT_TEST_SLEEP", "60"))
        while not (marks / "go").exists() and time.monotonic() < end:
            time.sleep(0.02)
        (marks / f"finished-{os.getpid()}").write_text(design.name)
        return ExportResult(files={design.name + ".txt": b"slow\\n"}, report={})
''')

SLOW_RUNNER = textwrap.dedent('''
    import sys

    import fabkit.writers
    from fabkit.cli import main

    if __name__ == "__main__":  # spawned workers import this file too
        fabkit.writers.EXPORTERS.clear()
        fabkit.writers.EXPORTERS["slow"] = "fabkit_test_slow_format"
        sys.exit(main(sys.argv[1:]))
''')


@pytest.fixture
def slow_export(tmp_path):
    """Start ``fabkit export`` of two designs with --jobs 2 and a format that sleeps; returns a
    function that starts it and waits until both workers are inside the exporter."""
    mods = tmp_path / "slow_mods"
    mods.mkdir()
    (mods / "fabkit_test_slow_format.py").write_text(SLOW_FORMAT)
    runner = tmp_path / "runner.py"
    runner.write_text(SLOW_RUNNER)
    marks = tmp_path / "marks"
    marks.mkdir()
    procs = []

    def start(out, sleep=60.0, wait_workers=2, group=False):
        env = {**os.environ, "FABKIT_TEST_MARKS": str(marks), "FABKIT_TEST_SLEEP": str(sleep),
               "PYTHONPATH": str(mods) + os.pathsep + os.environ.get("PYTHONPATH", "")}
        proc = subprocess.Popen([sys.executable, str(runner), "export",
                                 str(TEMPLATES / "fourbar.toml"),
                                 str(TEMPLATES / "super_stable_chain8.toml"), "-o", str(out),
                                 "--jobs", "2", "--no-check", "--no-previews",
                                 "--tolerance-samples", "0"],
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, start_new_session=group)
        procs.append(proc)
        deadline = time.monotonic() + 120
        while len(list(marks.glob("started-*"))) < wait_workers:
            assert proc.poll() is None, proc.stderr.read()
            assert time.monotonic() < deadline, "the workers never started"
            time.sleep(0.05)
        pids = [int(p.name.split("-")[1]) for p in marks.glob("started-*")]
        return proc, pids

    yield start
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie is dead for our purpose: it runs no code and writes nothing
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z"
    except (OSError, IndexError):  # reaped between the two looks (ProcessLookupError, ENOENT)
        return False


def _wait_dead(pids, timeout):
    deadline = time.monotonic() + timeout
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    return [p for p in pids if _alive(p)]


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs /proc (Linux)")
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT,
                                    signal.SIGUSR1, signal.SIGUSR2])
def test_a_signal_stops_every_worker_promptly_and_leaves_no_file(tmp_path, slow_export, signum):
    out = tmp_path / "out"
    # the exporters would sleep for an hour: the export ends only if its signal stops them
    proc, workers = slow_export(out, sleep=3600.0)
    assert len(workers) == 2 and all(_alive(p) for p in workers)
    proc.send_signal(signum)
    rc = proc.wait(timeout=300)
    assert rc == 128 + signum
    assert _wait_dead(workers, 30) == []
    assert list((tmp_path / "marks").glob("finished-*")) == []  # no exporter ran to its end
    err = proc.stderr.read().strip().splitlines()
    assert err == [f"fabkit: interrupted ({signal.Signals(signum).name})"]
    assert snapshot(out) == {}  # no design folder, no staging folder, no lock file


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs /proc (Linux)")
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGHUP, signal.SIGQUIT])
def test_signals_a_terminal_sends_to_the_group_twice_end_in_one_line(tmp_path, slow_export,
                                                                       signum):
    # a terminal sends Ctrl-C (Ctrl-\, a hang-up) to every process of the group, workers too;
    # the second comes while the first one's clean-up runs
    out = tmp_path / "out"
    proc, workers = slow_export(out, sleep=3600.0, group=True)
    os.killpg(proc.pid, signum)
    time.sleep(0.2)
    try:
        os.killpg(proc.pid, signum)
    except ProcessLookupError:  # every process of the group had already ended
        pass
    assert proc.wait(timeout=300) == 128 + signum
    assert _wait_dead(workers, 30) == []
    err = proc.stderr.read()
    assert "Traceback" not in err
    assert err.strip().splitlines() == [f"fabkit: interrupted ({signal.Signals(signum).name})"]
    assert snapshot(out) == {}  # no design folder, no staging folder, no lock file


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs /proc (Linux)")
def test_workers_die_with_a_killed_parent_and_write_nothing_later(tmp_path, slow_export):
    out = tmp_path / "out"
    proc, workers = slow_export(out, sleep=3600.0)
    proc.kill()  # SIGKILL: no handler runs in the parent
    proc.wait(timeout=30)
    assert _wait_dead(workers, 30) == []
    # let the exporters return: a worker left behind would now write its design
    (tmp_path / "marks" / "go").touch()
    time.sleep(1.0)
    assert list((tmp_path / "marks").glob("finished-*")) == []
    visible = [k for k in snapshot(out) if not k.startswith(".")]
    assert visible == []


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs /proc (Linux)")
def test_a_second_export_into_the_same_folder_is_refused(tmp_path, slow_export, lengths_format,
                                                         capsys):
    out = tmp_path / "out"
    proc, _ = slow_export(out)
    rc = main(["export", str(TEMPLATES / "fourbar.toml"), "-o", str(out), "--no-previews"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1
    assert f"process {proc.pid} is exporting into this folder" in err[0] and "--wait" in err[0]
    assert not (out / "fourbar").exists()
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    # the lock went with its holder: now the same export runs
    assert main(["export", str(TEMPLATES / "fourbar.toml"), "-o", str(out), "--no-previews",
                 "--wait", "-q"]) == 0
    assert (out / "fourbar" / "fourbar_lengths.txt").is_file()
    assert not (out / ".fabkit.lock").exists()


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs /proc (Linux)")
def test_a_worker_killed_by_the_system_fails_its_design_only(tmp_path, slow_export):
    out = tmp_path / "out"
    proc, workers = slow_export(out, sleep=3600.0)
    marks = {int(p.name.split("-")[1]): p.read_text() for p in
             (tmp_path / "marks").glob("started-*")}
    victim = next(pid for pid, name in marks.items() if name == "fourbar")
    os.kill(victim, signal.SIGKILL)  # as the out-of-memory killer would
    assert _wait_dead([victim], 30) == []
    (tmp_path / "marks" / "go").touch()  # the other design's exporter returns
    rc = proc.wait(timeout=120)
    err = proc.stderr.read().strip().splitlines()
    assert rc == 1 and len(err) == 1, err
    assert "fourbar.toml: worker died (signal 9, SIGKILL) while exporting fourbar; nothing of " \
           "it was written" in err[0]
    files = snapshot(out)
    assert sorted(files) == ["index.html", "super_stable_chain8/exports.json",
                             "super_stable_chain8/report.html",
                             "super_stable_chain8/report.json", "super_stable_chain8/report.md",
                             "super_stable_chain8/super_stable_chain8.txt"]
