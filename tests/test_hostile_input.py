"""The hostile-input corpus: what careless and malicious users give fabkit, grouped by cause.

Every case asserts the exit code, the one line (or the typed exception of the API), and that
nothing was written. The groups follow the causes: sizes bounded before work, damaged files
answered by a failed check (never an internal error), settings that were silently ignored, wrong
exit codes, and messages. Paths that leave the output folder and full disks are in
tests/test_output_guard.py.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import ezdxf
import numpy as np
import pytest

import fabkit
from fabkit.cli import main
from fabkit.errors import (ArgumentError, BoundsError, FabkitError, SettingsError,
                           TemplateError)

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("fabkit: error: ") and "Traceback" not in err
    return lines[0]


def files_under(folder: Path) -> list:
    return sorted(p for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


FOURBAR_NET = """
[network]
nodes = [[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]
edges = [[0, 2], [0, 3], [1, 2], [1, 3]]
ports = { d1 = [0, 1], d2 = [2, 3] }
"""


# --- sizes: one estimate of the work, before the work ---------------------------------------

def test_a_chain_of_chains_is_counted_through_every_level(tmp_path, capsys, monkeypatch):
    write(tmp_path, "inner.toml", '[chain]\nmodule = "fourbar"\ncopies = 1000\n')
    outer = write(tmp_path, "outer.toml", '[chain]\nmodule = "inner.toml"\ncopies = 1000\n'
                                          '[motion]\nto = 2.1\n')
    built = []
    network_init = fabkit.Network.__init__

    def record(self, *args, **kwargs):
        network_init(self, *args, **kwargs)
        built.append(self.n_nodes)

    monkeypatch.setattr(fabkit.Network, "__init__", record)
    rc = main(["info", str(outer)])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert "outer.toml: chain.copies: 1,000,000 is over the limit of 20,000 modules (after " \
           "every level of nesting); fabkit --allow-large lifts the limit" in line
    # refused before the 10^6 modules are built (42 s and 2.8 GB before): the largest network
    # made is the inner chain of 1000 4-bars
    assert max(built) == 2002, built


@pytest.mark.parametrize("argv, words", [
    (["map", "chaotic", "--lyapunov", "--orbits", "100000", "--average", "10000000"],
     ["map --lyapunov: about 1.16 days", "1e+12 map evaluations", "limit of 30 min of work",
      "--allow-large"]),
    (["sweep", "chaotic", "--vary", "nodes[4].x=-0.4:-0.2:1000000000"],
     ["--vary nodes[4].x: about", "1e+09 sweep points", "over the limit"]),
    (["sweep", "chaotic", "--vary", "nodes[4].x=-0.4:-0.2:1000", "--vary",
      "nodes[3].x=0:1:1000"], ["sweep: about", "1e+06 sweep points"]),
    (["sweep", "chaotic", "--vary", "nodes[4].x=-0.4:-0.2:3", "--jobs", "24"],
     ["--jobs: 24 is over the limit of", "worker processes (this machine has"]),
    (["export", "fourbar", "--jobs", "24"], ["--jobs: 24 is over the limit of"]),
    (["map", "chaotic", "--d1", ",".join(["1.5"] * 1001)], ["--d1: 1,001 is over the limit"]),
    (["export", "origami_sheet", "--set", "origami.samples=5000000"],
     ["origami.samples: must be <= 1000000"]),
    (["bench", "--sizes", "100000"], ["--sizes: 100,000 is over the limit of 10,000 modules"]),
])
def test_sizes_past_the_bounds_are_refused_before_work(argv, words, tmp_path, capsys):
    out = tmp_path / "out"
    rc = main([*argv, "-o", str(out)])
    line = one_line(capsys.readouterr().err)
    assert rc == 2, line
    for w in words:
        assert w in line, line
    assert files_under(out) == []


def test_the_api_bounds_sizes_too():
    four = fabkit.load_template("fourbar").network
    with pytest.raises(BoundsError, match="over the limit of 2 GB of memory"):
        fabkit.chain(four, copies=10**7)
    fmap = fabkit.module_map(fabkit.load_template("chaotic").network)
    with pytest.raises(BoundsError, match="Map1D.iterate: about"):
        fmap.iterate(1.5, 10**10)
    with pytest.raises(BoundsError, match="Map1D.lyapunov: about"):
        fmap.lyapunov(initial=100_000, discard=0, average=10_000_000)
    with pytest.raises(BoundsError):
        fabkit.sweep("chaotic", vary={"nodes[4].x": (-0.4, -0.2, 10**9)})


def test_a_huge_file_is_refused_by_its_size_before_it_is_read(tmp_path, capsys):
    big = tmp_path / "big.stl"
    with open(big, "wb") as fh:  # sparse: 1 GB on paper, nothing on disk
        fh.truncate(2**30)
    rc = main(["check", str(big)])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert "big.stl: about" in line and "1e+09 file bytes" in line and "over the limit" in line


# --- damaged files: a failed check, one line, never an internal error ------------------------

@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("exported")
    rc = main(["export", "fourbar", "origami_sheet", "printed_planar", "-o", str(out),
               "--tolerance-samples", "0", "--no-previews", "-q"])
    assert rc == 0
    return out


FOLD_DAMAGE = {
    "fold angle not a number": (("edges_foldAngle", 5), "x",
                                "edges_foldAngle[5]: must be a number, got 'x'"),
    "ragged vertices": (("vertices_coords", 0), [1.0], "vertices_coords[0]: must have at least"),
    "vertex with 4 coordinates": (("vertices_coords", 0), [1, 2, 3, 4],
                                  "vertices_coords[0]: must have at most 3 entries"),
    "map shorter than the frames": (("fabkit:map", "d1"), [1.4],
                                    "fabkit:map's arrays differ in length"),
    "motion without drive": (("fabkit:motion", "drive"), None,
                             "fabkit:motion.drive: must be a string"),
    "samples from the file": (("fabkit:motion", "samples"), 30_000_000,
                              "fabkit:motion.samples: must be <= 1000000"),
    "samples not whole": (("fabkit:motion", "samples"), 3e7,
                          "fabkit:motion.samples: must be a whole number"),
    "NaN in the map": (("fabkit:map", "d2", 3), float("nan"),
                       "fabkit:map.d2[3]: must be a finite number"),
    "scale zero": (("fabkit:scale",), 0, "fabkit:scale: must be > 0, got 0"),
    "scale text": (("fabkit:scale",), "big", "fabkit:scale: must be a number, got 'big'"),
    "ports not a table": (("fabkit:ports",), [1, 2], "fabkit:ports: must be a table"),
    "port out of range": (("fabkit:ports", "d1"), [0, 99], "fabkit:ports.d1 names vertices 0, 99"),
    "edge to a missing vertex": (("edges_vertices", 0), [0, 99],
                                 "edges_vertices names vertices that do not exist"),
    "unknown assignment": (("edges_assignment", 4), "Q", "must be one of 'B', 'M', 'V'"),
    "fold angle out of range": (("edges_foldAngle", 4), 720.0,
                                "edges_foldAngle[4]: must be <= 180, got 720.0"),
    "frames not a list": (("file_frames",), "x", "file_frames: must be an array, got 'x'"),
    "frame with too few vertices": (("file_frames", 1, "vertices_coords"), [[0, 0, 0]],
                                    "file_frames[1] has 1 vertices, not 5"),
    "huge coordinate": (("vertices_coords", 2, 0), 1e300, "vertices_coords[2][0]: must be <="),
    "drive not a port": (("fabkit:motion", "drive"), "d9",
                         "fabkit:motion.drive 'd9' is not one of fabkit:ports"),
}


@pytest.mark.parametrize("case", sorted(FOLD_DAMAGE))
def test_a_damaged_fold_file_fails_its_check_in_one_line(case, exported, tmp_path, capsys):
    path, value, words = FOLD_DAMAGE[case]
    doc = json.loads((exported / "origami_sheet" / "origami_sheet.fold").read_text())
    node = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    bad = tmp_path / "bad.fold"
    bad.write_text(json.dumps(doc))
    rc = main(["check", str(bad), "--design", "origami_sheet"])
    out = capsys.readouterr()
    assert rc == 1 and out.err == ""
    assert "FAIL  structure" in out.out and words in out.out, out.out
    assert out.out.strip().endswith("bad.fold: FAILED")


def _dxf_with(exported, tmp_path, change) -> Path:
    doc = ezdxf.readfile(exported / "fourbar" / "laser_sheet1.dxf")
    change(doc)
    out = tmp_path / "laser_sheet1.dxf"
    doc.saveas(out)
    return out


def _tags(doc, k=0):
    return [e for e in doc.modelspace() if e.has_xdata("FABKIT")][k]


DXF_DAMAGE = {
    "bar count zero": (lambda d: d.header.custom_vars.replace("FABKIT_BARS", "0"),
                       "header FABKIT_BARS: must be >= 1, got '0'"),
    "bar count huge": (lambda d: d.header.custom_vars.replace("FABKIT_BARS", "400000000"),
                       "header FABKIT_BARS: must be <= 10000000"),
    "bar count text": (lambda d: d.header.custom_vars.replace("FABKIT_BARS", "4e8"),
                       "header FABKIT_BARS: must be a whole number"),
    "kerf nan": (lambda d: d.header.custom_vars.replace("FABKIT_KERF", "nan"),
                 "header FABKIT_KERF: must be a finite number"),
    "no header": (lambda d: d.header.custom_vars.remove("FABKIT_BARS"),
                  "carry no fabkit header"),
    "xdata cut short": (lambda d: _tags(d).set_xdata("FABKIT", [(1000, "B0")]),
                        "its fabkit xdata lacks the part id and kind"),
    "xdata wrong count": (lambda d: _tags(d).set_xdata("FABKIT", [(1000, "B0"), (1000, "bar"),
                                                                  (1071, 0)]),
                          "part B0: a bar carries 4 numbers, this one 1"),
    "xdata text for a number": (lambda d: _tags(d).set_xdata(
        "FABKIT", [(1000, "B0"), (1000, "bar"), (1071, 0), (1071, 0), (1071, 1), (1000, "x")]),
        "part B0: its numbers must be whole numbers from 0"),
    "xdata unknown kind": (lambda d: _tags(d).set_xdata("FABKIT", [(1000, "B0"), (1000, "gear")]),
                           "part B0: unknown kind 'gear'"),
}


@pytest.mark.parametrize("case", sorted(DXF_DAMAGE))
def test_a_damaged_dxf_fails_its_check_in_one_line(case, exported, tmp_path, capsys):
    change, words = DXF_DAMAGE[case]
    bad = _dxf_with(exported, tmp_path, change)
    rc = main(["check", str(bad), "--design", "fourbar"])
    out = capsys.readouterr()
    assert rc == 1 and out.err == ""
    assert words in out.out, out.out


def test_a_sheet_checked_against_another_design_fails_a_check(exported, capsys):
    rc = main(["check", str(exported / "fourbar" / "laser_sheet1.dxf"), "--design",
               "super_stable"])
    out = capsys.readouterr()
    assert rc == 1 and out.err == ""
    assert "FAIL  topology: 4 (limit 6)  the file holds 4 bars, the design super_stable 6 " \
           "edges: not this design's file" in out.out


def test_a_stray_dxf_beside_the_sheets_is_not_a_sheet(exported, tmp_path, capsys):
    folder = tmp_path / "kit"
    folder.mkdir()
    (folder / "laser_sheet1.dxf").write_bytes(
        (exported / "fourbar" / "laser_sheet1.dxf").read_bytes())
    (folder / "laser_sheet_notes.dxf").write_text("notes, not a sheet\n")
    assert main(["check", str(folder / "laser_sheet1.dxf"), "--design", "fourbar"]) == 0
    assert capsys.readouterr().out.strip().endswith("laser_sheet1.dxf: ok")


STL_DAMAGE = {
    "cut short": lambda d: d[: len(d) // 2],
    "announces 4e8 triangles": lambda d: d[:80] + (400_000_000).to_bytes(4, "little") + d[84:],
    "NaN vertex": lambda d: d[:84 + 12] + np.array([np.nan] * 3, "<f4").tobytes() + d[84 + 24:],
    "far vertex": lambda d: d[:84 + 12] + np.array([1e30] * 3, "<f4").tobytes() + d[84 + 24:],
    "text": lambda d: b"hello" * 40,
    "empty": lambda d: b"",
}


@pytest.mark.parametrize("case", sorted(STL_DAMAGE))
def test_a_damaged_stl_is_one_line(case, exported, tmp_path, capsys):
    data = (exported / "printed_planar" / "printed_planar.stl").read_bytes()
    bad = tmp_path / "bad.stl"
    bad.write_bytes(STL_DAMAGE[case](data))
    rc = main(["check", str(bad), "--design", "printed_planar"])
    err = capsys.readouterr().err
    assert rc == 1
    assert "bad.stl" in one_line(err)


@pytest.mark.parametrize("path_kind", ["folder", "missing", "fifo"])
def test_check_refuses_what_is_not_a_regular_file(path_kind, tmp_path, capsys):
    p = tmp_path / "x.fold"
    if path_kind == "folder":
        p.mkdir()
    elif path_kind == "fifo":
        os.mkfifo(p)
    rc = main(["check", str(p)])
    line = one_line(capsys.readouterr().err)
    assert rc == 1 and "x.fold" in line


def test_a_resumed_sweep_sets_damaged_chunks_aside(tmp_path, capsys):
    argv = ["sweep", "chaotic", "--vary", "nodes[4].x=-0.4:-0.3:3", "-o", str(tmp_path / "sw"),
            "--chunk-size", "1", "--jobs", "1", "--no-plots", "--measure", "fixed_points"]
    assert main(argv) == 0
    chunks = tmp_path / "sw" / "chunks"
    hacked = chunks / "chunk-0000001-0000001.json"
    recs = json.loads(hacked.read_text())
    recs[0]["fixed_value"] = "hacked"
    hacked.write_text(json.dumps(recs))
    (chunks / "chunk-0000002-0000002.json").write_text('[{"index": 2, "par')
    capsys.readouterr()
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "damaged chunk chunk-0000001-0000001.json set aside" in out
    assert "fixed_value: must be a number, got 'hacked'" in out
    assert "damaged chunk chunk-0000002-0000002.json set aside" in out and "not JSON" in out
    assert "hacked" not in (tmp_path / "sw" / "sweep.csv").read_text()
    assert (chunks / "chunk-0000001-0000001.json.damaged").exists()


STUCK_SOURCE = """
import time

from fabkit.sweep.chunks import run_chunk


def stuck_at_one(spec_dict, indices):
    if 1 in indices:
        time.sleep(3600)
    return run_chunk(spec_dict, indices)
"""


def test_a_sweep_point_that_stops_answering_is_recorded_and_the_rest_goes_on(tmp_path,
                                                                            monkeypatch):
    # the worker processes are spawned: the stuck chunk is a module file they import too
    mods = tmp_path / "mods"
    mods.mkdir()
    (mods / "fabkit_test_stuck_chunk.py").write_text(STUCK_SOURCE)
    monkeypatch.syspath_prepend(str(mods))
    monkeypatch.setenv("PYTHONPATH", str(mods) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    import fabkit_test_stuck_chunk

    monkeypatch.setattr(sys.modules["fabkit.sweep"], "run_chunk",
                        fabkit_test_stuck_chunk.stuck_at_one)
    r = fabkit.sweep("chaotic", {"nodes[4].x": (-0.4, -0.3, 4)}, measure="fixed_points",
                     jobs=2, chunk_size=1, point_timeout=2.0, plots=False)
    assert r.counts() == {"ok": 3, "failed": 1}
    failed = [rec for rec in r.records if rec["status"] == "failed"]
    assert failed[0]["index"] == 1 and failed[0]["reason"] == (
        "stopped answering: the worker ran past 2 s a point and was stopped")


# --- settings that were silently ignored -----------------------------------------------------

@pytest.mark.parametrize("argv, code, words", [
    (["export", "fourbar", "--set", "lasre.kerf=0.2"], 2,
     "--set: lasre: unknown section; known: laser, motion, origami, print, tolerance"),
    (["export", "fourbar", "--set", "laser.min_web=-5"], 2, "laser.min_web: must be >= 0"),
    (["export", "printed_planar", "--set", "print.hinge_layers=1000"], 1,
     "hinge_layers: applies to hinge_style = \"bridge\" only"),
    (["export", "fourbar", "--set", "laser.screw.name=\"M5-chicgo\""], 1,
     "unknown screw 'M5-chicgo'"),
    (["map", "chaotic", "--orbits", "10"], 2, "--orbits: applies only with --lyapunov"),
    (["map", "chaotic", "--average", "10"], 2, "--average: applies only with --lyapunov"),
    (["bench", "--sizes", ""], 2, "--sizes: must list positive numbers of modules"),
    (["bench", "--parts", "speed"], 2, "--parts: must name some of"),
    (["export", "fourbar", "--set", "motion.to=-2"], 2, "motion.to: must be > 0, got -2"),
    (["tolerance", "fourbar", "--set", "tolerance.seed=-1"], 2,
     "tolerance.seed: must be >= 0, got -1"),
    (["export", "fourbar", "--set", "print.preview=no"], 2,
     "print.preview: must be true or false, got 'no'"),
    (["export", "fourbar", "--timeout", "-1"], 2, "--timeout: must be 0 (no limit) or a number"),
    (["sweep", "chaotic", "--vary", "nodes[4].x=-0.4:-0.2:3", "--point-timeout", "0"], 2,
     "--point-timeout: must be positive"),
])
def test_settings_are_refused_not_dropped(argv, code, words, tmp_path, capsys):
    out = tmp_path / "out"
    rc = main([*argv, "-o", str(out), *(["--tolerance-samples", "0"] if argv[0] == "export"
                                          else [])])
    line = one_line(capsys.readouterr().err)
    assert rc == code, line
    assert words in line, line
    assert files_under(out) == []


TEMPLATE_SETTINGS = {
    "misspelt section": ("[fabrication.lasre]\nkerf = 0.2\n",
                         "fabrication.lasre: unknown section; known: laser, origami, print, "
                         "skip, tolerance"),
    "string for a boolean": ('[motion]\nto = 2.5\nmethod = "projected"\noptions = { '
                             'detect_branch_points = "no" }\n',
                             "motion.options.detect_branch_points: must be true or false"),
    "negative seed": ("[fabrication.tolerance]\nseed = -1\n",
                      "fabrication.tolerance.seed: must be >= 0, got -1"),
    "skip without a reason": ("[fabrication]\nskip = { dxf = 3 }\n",
                              "fabrication.skip: must be a table of format = \"reason\""),
    "whole number as text": ("[fabrication.laser]\nmax_layers = \"12\"\n",
                             "fabrication.laser.max_layers: must be a whole number"),
    "kerf infinite": ("[fabrication.laser]\nkerf = inf\n",
                      "fabrication.laser.kerf: must be a finite number"),
}


@pytest.mark.parametrize("case", sorted(TEMPLATE_SETTINGS))
def test_template_settings_are_checked_when_read(case, tmp_path, capsys):
    extra, words = TEMPLATE_SETTINGS[case]
    path = write(tmp_path, "t.toml", FOURBAR_NET + extra)
    rc = main(["info", str(path)])
    line = one_line(capsys.readouterr().err)
    assert rc == 1 and "t.toml: " in line and words in line, line


def test_check_honours_the_kerf_it_is_given(exported, capsys):
    sheet = str(exported / "fourbar" / "laser_sheet1.dxf")
    assert main(["check", sheet, "--design", "fourbar", "--set", "laser.kerf=0.15"]) == 0
    assert main(["check", sheet, "--design", "fourbar", "--set", "laser.kerf=0.3"]) == 1
    out = capsys.readouterr().out
    assert "FAIL  kerf: 0.3 (limit 0.15)" in out and "re-export with the kerf of your laser" in out


# --- exit codes and results ------------------------------------------------------------------

def test_simulate_exits_1_when_the_target_is_not_reached(tmp_path, capsys):
    rc = main(["simulate", str(ROOT / "tests" / "bad_templates" / "unreachable_target.toml"),
               "-o", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 1
    assert "motion.to: target d1 = 10 is not reached: stopped at a turning point of d1 = " \
           "4.828427125" in one_line(err)


def test_a_target_beyond_reach_is_a_turning_point_not_an_overflow(tmp_path, capsys):
    rc = main(["simulate", "fourbar", "--to", "1e308", "-o", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 1
    assert "target d1 = 1e+308 is not reached: stopped at a turning point of d1 = 4.82842712" \
        in one_line(err)


def test_several_templates_name_the_bad_one_and_go_on(tmp_path, capsys):
    bad = write(tmp_path, "bad.toml", "[network\n")
    rc = main(["simulate", "fourbar", str(bad), "super_stable", "-o", str(tmp_path / "o")])
    cap = capsys.readouterr()
    assert rc == 1
    assert one_line(cap.err).startswith(f"fabkit: error: {bad}: not valid TOML")
    assert "== fourbar" in cap.out and "== super_stable" in cap.out  # the third still ran
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["fourbar", "super_stable"]


def test_a_file_with_brackets_in_its_name_is_a_file(tmp_path, capsys):
    path = write(tmp_path, "four[1].toml", FOURBAR_NET)
    assert main(["info", str(path)]) == 0
    assert "four_1_" in capsys.readouterr().out  # the name made safe from the stem


def test_a_closed_pipe_ends_quietly():
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    proc = subprocess.Popen([sys.executable, "-m", "fabkit", "templates"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=60) == 141
    assert err == b""


def test_library_warnings_do_not_reach_the_terminal(exported, capsys):
    # the printed solid's check computes mass properties of open slices (numpy warns there)
    main(["check", str(exported / "printed_planar" / "printed_planar.stl"), "--design",
          "printed_planar"])
    assert "Warning" not in capsys.readouterr().err


# --- the Python API speaks fabkit ------------------------------------------------------------

@pytest.mark.parametrize("call, kind, words", [
    (lambda n: fabkit.chain(n, copies=2.5), TypeError, "copies must be a whole number, got 2.5"),
    (lambda n: fabkit.chain(n), TypeError, "copies is needed with one module"),
    (lambda n: fabkit.chain("fourbar", copies=2), TypeError, "modules must be a fabkit.Network"),
    (lambda n: fabkit.chain([n, None], copies=2), TypeError, "modules[1] must be a fabkit.Network"),
    (lambda n: fabkit.tessellate(n, "2x2", y_join=("d1", "d2")), TypeError,
     "shape must be (rows, columns)"),
    (lambda n: fabkit.tessellate(n, (2, -1), y_join=("d1", "d2")), ValueError,
     "shape[1] must be at least 1"),
    (lambda n: fabkit.module_map(None), TypeError, "net must be a fabkit.Network, got None"),
    (lambda n: fabkit.count_modes(None), TypeError, "net must be a fabkit.Network, got None"),
    (lambda n: fabkit.count_modes(n, [[0, 0]]), ValueError, "positions must have shape (4, 2)"),
    (lambda n: fabkit.count_modes(n, method="svd"), ValueError,
     "method must be one of 'auto', 'structure', 'dense', 'sparse'"),
    (lambda n: fabkit.trace(n, to="far"), TypeError, "to must be a number, got 'far'"),
    (lambda n: fabkit.trace(n, drive=[0], to=2.5), TypeError,
     "drive must be a port name or a pair of node indices"),
    (lambda n: fabkit.module_map(n, toward="x"), TypeError, "toward must be a number, got 'x'"),
    (lambda n: fabkit.module_map(n, branch=-1), ValueError, "branch must be at least 0"),
    (lambda n: fabkit.module_map(n, d_in=["a"]), TypeError, "port must be a port name or a pair"),
    (lambda n: fabkit.module_map(n).iterate(2.5, 2.5), TypeError,
     "steps must be a whole number"),
    (lambda n: fabkit.module_map(n).iterate("x", 2), TypeError, "d must be a number"),
    (lambda n: fabkit.module_map(n).cycles(2.5), TypeError, "period must be a whole number"),
    (lambda n: fabkit.module_map(n).lyapunov(method="fast"), ValueError,
     "method must be one of 'auto', 'exact', 'table'"),
    (lambda n: fabkit.Network([[0, 0], [1, 0]], [[0, 1]], ports=None), ValueError,
     "`ports` must be a mapping"),
    (lambda n: fabkit.Network([[0, 0], [1e300, 0]], [[0, 1]]), ValueError,
     "beyond ±1e+09 design units"),
    (lambda n: fabkit.Network("nodes", [[0, 1]]), ValueError, "`nodes` must be an array"),
    (lambda n: fabkit.load_template(None), TypeError, "path must be a file path"),
    (lambda n: __import__("fabkit.writers").writers.export(
        fabkit.load_template("fourbar"), "dxf", "/nonexistent", lazer={"kerf": 0.2}),
     ValueError, "lazer: unknown section"),
    (lambda n: __import__("fabkit.writers").writers.export(
        fabkit.load_template("fourbar"), ["dxf"], "/nonexistent"), FabkitError,
     "unknown export format ['dxf']"),
    (lambda n: fabkit.count_modes(n, np.zeros((4, 2))), ValueError,
     "positions puts nodes 0 and 2 of edge 0 at one point; every edge needs a length"),
    (lambda n: fabkit.trace(n, to=2.5, method="bogus"), ValueError,
     "method 'bogus' is unknown; valid methods: auto, constructive, projected"),
    (lambda n: fabkit.trace(n, to=2.5, bogus=1), TypeError,
     "bogus is an unknown option of every method"),
    (lambda n: fabkit.trace(n, to=2.5, method="projected", bogus=1), TypeError,
     "bogus is an unknown option of method 'projected'"),
    (lambda n: fabkit.trace(n, to=2.5, samples=10**9), ValueError,
     "samples must be <= 1000000, got 1000000000"),
    (lambda n: fabkit.trace(n, to=2.5, method="projected", max_step=float("nan")), ValueError,
     "max_step must be a finite number, got nan"),
    (lambda n: fabkit.trace(n, to=2.5, method="constructive", samples=2.5), TypeError,
     "samples must be a whole number, got 2.5"),
    (lambda n: fabkit.load_template("a\x00b"), ValueError,
     "path holds a NUL character, which no file name has"),
    (lambda n: fabkit.design_map([1e300]), FabkitError, "--fixed-point 1e+300: "),
    (lambda n: fabkit.export(None), TypeError,
     "design must be a fabkit Design, a template file or a bundled template's name, got "
     "NoneType"),
    (lambda n: fabkit.export("fourbar", to="stll"), ValueError,
     "to names an unknown format 'stll'; did you mean 'stl'?"),
    (lambda n: fabkit.Design.from_network(None), TypeError,
     "network must be a fabkit.Network, got NoneType"),
    (lambda n: fabkit.plot.motion(n), TypeError,
     "trajectory must be a fabkit Trajectory (fabkit.trace), got Network"),
    (lambda n: __import__("fabkit.writers").writers.export(None, "dxf", "/nonexistent"),
     TypeError, "design must be a fabkit Design (fabkit.load_template), got NoneType"),
    (lambda n: __import__("fabkit.writers").writers.export(fabkit.load_template("fourbar"),
                                                         "dxf", 5),
     FabkitError, "outdir: must be a folder path, got int"),
])
def test_public_functions_name_the_wrong_argument(call, kind, words):
    four = fabkit.load_template("fourbar").network
    with pytest.raises(kind) as info:
        call(four)
    assert isinstance(info.value, FabkitError)  # fabkit's own classes, also Python's
    assert words in str(info.value)
    assert "\n" not in str(info.value)


def test_error_classes_of_arguments_and_settings():
    assert issubclass(SettingsError, ValueError) and issubclass(SettingsError, FabkitError)
    with pytest.raises(ArgumentError) as info:
        fabkit.chain(fabkit.load_template("fourbar").network, copies=0)
    assert info.value.argument == "copies"
    with pytest.raises(TemplateError):
        fabkit.load_template(ROOT / "tests" / "bad_templates" / "name_not_a_folder.toml")



def test_no_lapack_line_reaches_the_terminal(capfd):
    with pytest.raises(FabkitError):
        fabkit.design_map([1e300])
    assert "DLASCL" not in capfd.readouterr().err  # LAPACK never saw the overflowing numbers


# --- round two: silent settings, messages ----------------------------------------------------

def test_a_pin_clearance_no_printer_keeps_is_refused(tmp_path, capsys):
    rc = main(["export", "super_stable", "--to", "stl", "--set", "print.pin_clearance=0.000001",
               "-o", str(tmp_path / "out"), "--tolerance-samples", "0", "--no-previews", "-q"])
    cap = capsys.readouterr()
    assert rc == 1
    assert "print.pin_clearance: a 1e-06 mm gap between pin and hole is below what an extruded " \
           "wall keeps (about 0.05 mm): the pin prints fused to its hole" in one_line(cap.err)
    assert files_under(tmp_path / "out") == []


@pytest.mark.parametrize("argv, words", [
    (["export", "fourbar", "--to", "dxf", "--set", "print.scale=5"],
     "--set: print.scale: print settings have no effect here: this export (dxf; tolerance "
     "analysis as laser) reads laser, tolerance settings only; remove them"),
    (["export", "fourbar", "--to", "dxf", "--set", "origami.faces=[[0,1,2,99]]"],
     "--set: origami.faces: origami settings have no effect here"),
    (["export", "fourbar", "--to", "dxf", "--set", "print.bed=[1e308,1e308]"],
     "--set: print.bed: print settings have no effect here"),
    (["export", "origami_sheet", "--set", "laser.kerf=0.5"],
     "--set: laser.kerf: laser settings have no effect here: this export (cp, fold, svg; "
     "tolerance analysis as origami) reads origami, tolerance settings only"),
    (["export", "fourbar", "--to", "dxf", "--tolerance-samples", "0", "--set",
      "tolerance.samples=5"], "--set: tolerance.samples: tolerance settings have no effect"),
    (["export", "fourbar", "--to", "dxf", "--set", "tolerance.xy_sigma=0.1"],
     "--set: tolerance.xy_sigma: is a print error; the designs here are analysed as laser (set "
     "tolerance.process = \"print\" to change that)"),
    (["tolerance", "fourbar", "--samples", "5", "--set", "print.scale=5"],
     "fourbar.toml: --set: print.scale: print settings have no effect here: fourbar is "
     "analysed as laser (set tolerance.process = \"print\" to change that); remove them"),
    (["tolerance", "fourbar", "--samples", "5", "--set", "tolerance.xy_sigma=0.1"],
     "fourbar.toml: --set: tolerance.xy_sigma: is a print error; fourbar is analysed as laser "
     "(set tolerance.process = \"print\" to change that)"),
])
def test_settings_no_stage_reads_are_refused_the_same_way(argv, words, tmp_path, capsys):
    out = tmp_path / "out"
    rc = main([*argv, "-o", str(out)])
    line = one_line(capsys.readouterr().err)
    assert rc == 2, line
    assert words in line, line
    assert files_under(out) == []


def test_check_refuses_settings_its_files_do_not_read(exported, capsys):
    sheet = str(exported / "fourbar" / "laser_sheet1.dxf")
    rc = main(["check", sheet, "--design", "fourbar", "--set", "print.scale=5"])
    assert rc == 2
    assert "--set: print.scale: print settings have no effect here: the checks of these files " \
           "read laser settings only" in one_line(capsys.readouterr().err)


def test_settings_that_some_design_reads_are_kept(tmp_path, capsys):
    # laser.kerf reaches fourbar's sheets; the origami sheet in the same run ignores it
    rc = main(["export", "fourbar", "origami_sheet", "--set", "laser.kerf=0.2", "-o",
               str(tmp_path), "--tolerance-samples", "0", "--no-previews", "-q"])
    assert rc == 0, capsys.readouterr().err
    report = json.loads((tmp_path / "fourbar" / "report.json").read_text())
    assert report["formats"]["dxf"]["status"] == "exported"


def test_a_projected_trace_with_a_nan_step_never_starts():
    four = fabkit.load_template("fourbar").network
    with pytest.raises(ArgumentError) as info:
        fabkit.trace(four, to=2.5, method="projected", max_step=float("nan"))
    assert info.value.argument == "max_step"


@pytest.mark.parametrize("body, words", [
    ('[chain]\nmodule = ""\ncopies = 3\n',
     "t.toml: chain.module: is empty: name a template file"),
    ('[chain]\nmodules = ["fourbar", ""]\n',
     "t.toml: chain.modules[1]: is empty: name a template file"),
])
def test_an_empty_reference_names_its_chain_and_key(body, words, tmp_path, capsys):
    path = write(tmp_path, "t.toml", body)
    assert main(["info", str(path)]) == 1
    assert words in one_line(capsys.readouterr().err)


@pytest.mark.parametrize("argv", [
    lambda t, o: ["info", str(t)],
    lambda t, o: ["simulate", str(t), "-o", str(o)],
    lambda t, o: ["design", "--fixed-point", "1.6:0", "--name", "y" * 100_000, "-o", str(o)],
])
def test_a_name_of_100000_characters_is_not_echoed_whole(argv, tmp_path, capsys):
    t = write(tmp_path, "t.toml", f'name = "{"x" * 100_000}"\n' + FOURBAR_NET)
    rc = main(argv(t, tmp_path / "out"))
    line = one_line(capsys.readouterr().err)
    assert rc in (1, 2)
    assert len(line) < 400 and "... (100000 characters)" in line
