"""Hostile input, round two: sizes hidden inside files, files that are not files, and signals
that must stop work inside C extensions.

Every case asserts the exit code and the one line (or the typed exception), never a time: the
work is bounded by counting before it starts (placed triangles of a 3MF, inflated XML, curve
segments, referenced templates, samples x nodes), by the kernel's limits on a check held to its
estimate, or it ends on a signal. Time and memory figures belong in docs/batch.md, measured
with the commands it gives.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import ezdxf
import numpy as np
import pytest

import fabkit
from fabkit.cli import main
from fabkit.errors import BoundsError

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"
NS = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("fabkit: error: ") and "Traceback" not in err
    return lines[0]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("exported")
    rc = main(["export", "fourbar", "printed_planar", "-o", str(out), "--tolerance-samples", "0",
               "--no-previews", "-q"])
    assert rc == 0
    return out


def tetrahedra_3mf(path: Path, items: int) -> Path:
    """A 3MF of one tetrahedron placed ``items`` times at one spot: a few kB of ZIP, and
    thousands of coincident bodies for any cross-section."""
    model = (f'<?xml version="1.0" encoding="UTF-8"?><model unit="millimeter" xmlns="{NS}">'
             '<resources><object id="1" type="model"><mesh><vertices>'
             '<vertex x="0" y="0" z="0"/><vertex x="10" y="0" z="0"/><vertex x="0" y="10" z="0"/>'
             '<vertex x="0" y="0" z="10"/></vertices><triangles>'
             '<triangle v1="0" v2="2" v3="1"/><triangle v1="0" v2="1" v3="3"/>'
             '<triangle v1="0" v2="3" v3="2"/><triangle v1="1" v2="2" v3="3"/></triangles>'
             '</mesh></object></resources><build>'
             + '<item objectid="1" transform="1 0 0 0 1 0 0 0 1 0 0 0"/>' * items
             + "</build></model>")
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("3D/3dmodel.model", model)
    return path


def rewrite_model(src: Path, dst: Path, change) -> Path:
    """A copy of a 3MF whose model XML is ``change(text)``."""
    with zipfile.ZipFile(src) as z, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as out:
        for info in z.infolist():
            data = z.read(info.filename)
            if info.filename.lower().endswith(".model"):
                data = change(data.decode()).encode()
            out.writestr(info.filename, data)
    return dst


# --- 3MF: counts inside the package ---------------------------------------------------------

def test_twenty_thousand_build_items_are_counted_before_any_is_placed(exported, tmp_path,
                                                                      capsys):
    src = exported / "printed_planar" / "printed_planar.3mf"
    item = re.compile(r"<item [^>]*/>")
    bomb = rewrite_model(src, tmp_path / "items.3mf",
                         lambda t: item.sub(lambda m: m.group(0) * 20_000, t, count=1))
    assert bomb.stat().st_size < 20_000  # a few kB of ZIP
    rc = main(["check", str(bomb), "--design", "printed_planar"])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert "items.3mf: 20000 build items: about" in line
    assert "placed triangles) is over the limit of 2 GB of memory" in line


def test_a_model_that_inflates_to_gigabytes_is_refused_before_it_is_inflated(tmp_path, capsys):
    bomb = tmp_path / "bomb.3mf"
    vertex = b'<vertex x="0" y="0" z="0"/>' * 40_000  # 1 MB
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as z:
        with z.open("3D/3dmodel.model", "w", force_zip64=True) as fh:
            fh.write(f'<model unit="millimeter" xmlns="{NS}"><resources><object id="1">'
                     '<mesh><vertices>'.encode())
            for _ in range(200):  # 200 MB of XML in a ZIP of about 1 MB
                fh.write(vertex)
            fh.write(b"</vertices></mesh></object></resources></model>")
    assert bomb.stat().st_size < 2 * 2**20
    rc = main(["check", str(bomb)])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert "bomb.3mf: inflated XML: about" in line and "XML bytes" in line
    assert "over the limit of 2 GB of memory" in line


DAMAGED_3MF = {
    "vertex x not a number": (r'x="[^"]*"', 'x="abc"',
                              "object '1' vertex 0 x: must be a finite number, got 'abc'"),
    "vertex x missing": (r'x="[^"]*" ', "", "object '1' vertex 0 x: must be a finite number, "
                                            "is missing"),
    "vertex x of 1e400": (r'x="[^"]*"', 'x="1e400"', "object '1' vertex 0 x: must be a finite number, got '1e400'"),
    "triangle index 0.5": (r'v1="[^"]*"', 'v1="0.5"', "object '1' triangle 0 v1: must be an "
                                                      "index (a whole number from 0), got '0.5'"),
    "triangle index missing": (r'v1="[^"]*" ', "", "object '1' triangle 0 v1: must be an index "
                                                   "(a whole number from 0), is missing"),
    "triangle index 10^23": (r'v1="[^"]*"', 'v1="100000000000000000000000"',
                             "object '1' triangle 0 v1: must be an index"),
    "triangle index of a superscript digit": (r'v1="[^"]*"', 'v1="²"',
                                              "object '1' triangle 0 v1: must be an index (a "
                                              "whole number from 0), got '²'"),
    "triangle index of Arabic-Indic digits": (r'v1="[^"]*"', 'v1="١"',
                                              "object '1' triangle 0 v1: must be an index"),
    "triangle index negative": (r'v1="[^"]*"', 'v1="-1"',
                                "object '1' triangle 0 v1: must be an index"),
    "triangle index past the vertices": (r'v1="[^"]*"', 'v1="99999"',
                                         "object '1' has triangle indices out of range"),
    "transform of letters": (r'transform="[^"]*"', 'transform="a b c d e f g h i j k l"',
                             "build item 0 transform[0]: must be a finite number, got 'a'"),
    "transform of 1e300": (r'transform="[^"]*"',
                           'transform="1e300 0 0 0 1 0 0 0 1 0 0 0"',
                           "build item 0 places object '1' beyond 100000 mm"),
    "transform of three numbers": (r'transform="[^"]*"', 'transform="1 0 0"',
                                   "build item 0 transform of 3 numbers, not 12"),
    "unknown unit": (r'unit="millimeter"', 'unit="parsec"', "unknown unit 'parsec'"),
    "item of a missing object": (r'objectid="1"', 'objectid="7"',
                                 "a build item names object '7', which is not there"),
}


@pytest.mark.parametrize("case", sorted(DAMAGED_3MF))
def test_a_damaged_3mf_is_one_line_never_an_internal_error(case, exported, tmp_path, capsys):
    pattern, repl, words = DAMAGED_3MF[case]
    src = exported / "printed_planar" / "printed_planar.3mf"
    bad = rewrite_model(src, tmp_path / "bad.3mf", lambda t: re.sub(pattern, repl, t, count=1))
    rc = main(["check", str(bad), "--design", "printed_planar"])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert f"{bad}: {words}" in line, line


def test_a_3mf_of_no_bar_of_the_design_is_a_failed_check(tmp_path, capsys):
    # every body lies outside the pieces of the print: a failed check, not an internal error
    rc = main(["check", str(tetrahedra_3mf(tmp_path / "t.3mf", 20)), "--design", "super_stable"])
    out = capsys.readouterr()
    assert rc == 1 and out.err == ""
    assert "FAIL  one closed body per bar: 20 (limit 6)" in out.out
    assert "body 0 on t.3mf: 0 holes and 0 pins, not two joints" in out.out
    assert out.out.strip().endswith("t.3mf: FAILED")


# --- STL: the triangles it holds ------------------------------------------------------------

def test_an_stl_is_counted_by_its_triangles_not_only_its_bytes(tmp_path, capsys):
    n = 1_200_000  # 60 MB on disk: within the file-size estimate, over the triangle estimate
    big = tmp_path / "big.stl"
    with open(big, "wb") as fh:
        fh.write(b"\0" * 80 + n.to_bytes(4, "little"))
        fh.truncate(84 + 50 * n)
    rc = main(["check", str(big)])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert "big.stl: about" in line and "1e+06 placed triangles" in line
    assert "over the limit of 2 GB of memory" in line


# --- a check stops on a signal and keeps to its estimate -----------------------------------

def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(v) for v in text.split()]


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="reads /proc (Linux)")
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_ends_a_check_inside_geos(signum, tmp_path):
    """14 000 coincident tetrahedra (56 000 triangles, within the 60 000 printed_planar's 12 bars
    allow): the hinge check's cross-section sends 42 000 overlapping segments to GEOS's
    polygonize, which computes for minutes without returning to Python. The check runs in a
    child process: the signal ends the command, and the child with it."""
    bomb = tetrahedra_3mf(tmp_path / "coincident.3mf", 14_000)
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    proc = subprocess.Popen([sys.executable, "-m", "fabkit", "check", str(bomb), "--design",
                             "printed_planar"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=env)
    try:
        child = None
        deadline = time.monotonic() + 240  # a guard against a hang, not a speed bound
        while time.monotonic() < deadline and proc.poll() is None:
            kids = _children(proc.pid)
            if kids and _cpu_seconds(kids[0]) > 3.0:  # well inside the cross-sections
                child = kids[0]
                break
            time.sleep(0.2)
        assert child is not None, proc.communicate()
        proc.send_signal(signum)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signum, err
    assert err.decode().strip() == f"fabkit: interrupted ({signal.Signals(signum).name})"
    for _ in range(50):  # the child was killed with the command (reaped by init at once)
        if not Path(f"/proc/{child}").exists() or "Z" in Path(
                f"/proc/{child}/stat").read_text().rsplit(")", 1)[1].split()[0]:
            break
        time.sleep(0.1)
    else:
        pytest.fail(f"the check's process {child} outlived the command")


def test_a_check_that_runs_past_its_estimate_is_stopped(tmp_path, monkeypatch, capsys):
    import fabkit.stoppable as stoppable

    # the CPU time allowed is four times the estimate and at least a minute; lowered here so
    # that the test needs a few seconds: the same kernel limit (RLIMIT_CPU) stops it either way
    monkeypatch.setattr(stoppable, "MIN_SECONDS", 2.0)
    monkeypatch.setattr(stoppable, "TIME_FACTOR", 0.1)
    bomb = tetrahedra_3mf(tmp_path / "coincident.3mf", 14_000)
    rc = main(["check", str(bomb), "--design", "printed_planar"])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert line.startswith(f"fabkit: error: {bomb}: ran past the 2 s of CPU time allowed for "
                           "work estimated at about")
    assert "56000 placed triangles" in line and "fabkit --allow-large lifts the limit" in line


# --- DXF: sibling sheets and nested blocks --------------------------------------------------

def test_a_huge_sibling_sheet_is_counted_before_any_sheet_is_read(exported, tmp_path, capsys):
    kit = tmp_path / "kit"
    kit.mkdir()
    (kit / "laser_sheet1.dxf").write_bytes((exported / "fourbar" / "laser_sheet1.dxf").read_bytes())
    with open(kit / "laser_sheet2.dxf", "wb") as fh:  # sparse: 1.5 GB on paper
        fh.truncate(1500 * 2**20)
    rc = main(["check", str(kit / "laser_sheet1.dxf"), "--design", "fourbar"])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert (f"{kit / 'laser_sheet1.dxf'} with the files of its export beside it "
            "(laser_sheet2.dxf): about") in line
    assert "over the limit of 2 GB of memory" in line


def test_blocks_nested_thousands_deep_fail_the_audit(tmp_path, capsys):
    doc = ezdxf.new()
    prev = None
    for k in range(3000):
        block = doc.blocks.new(f"B{k}")
        if prev is None:
            block.add_line((0, 0), (1, 0))
        else:
            block.add_blockref(prev, (0, 0))
        prev = f"B{k}"
    doc.modelspace().add_blockref(prev, (0, 0))
    path = tmp_path / "laser_sheet1.dxf"
    doc.saveas(path)
    rc = main(["check", str(path)])
    out = capsys.readouterr()
    assert rc == 1 and out.err == ""
    assert "FAIL  audit: 1 (limit 0)  laser_sheet1.dxf: block references nested too deeply " \
           "to audit" in out.out


# --- files that are not files ---------------------------------------------------------------

SWEEP = ["sweep", "chaotic", "--vary", "nodes[4].x=-0.4:-0.3:2", "--measure", "fixed_points",
         "--jobs", "1", "--no-plots", "--chunk-size", "1"]


def test_a_fifo_for_the_sweep_spec_is_refused_not_waited_on(tmp_path, capsys):
    (tmp_path / "out" / "chunks").mkdir(parents=True)
    os.mkfifo(tmp_path / "out" / "chunks" / "spec.json")
    rc = main([*SWEEP, "-o", str(tmp_path / "out")])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert line.endswith("chunks/spec.json: is a FIFO (named pipe), not a regular file: refused")


def test_a_fifo_for_a_chunk_is_set_aside_and_its_points_computed(tmp_path, capsys):
    chunks = tmp_path / "out" / "chunks"
    chunks.mkdir(parents=True)
    os.mkfifo(chunks / "chunk-0000000-0000000.json")
    assert main([*SWEEP, "-o", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "damaged chunk chunk-0000000-0000000.json set aside" in out
    assert "is a FIFO (named pipe), not a regular file: refused" in out
    assert (chunks / "chunk-0000000-0000000.json").is_file()  # computed again, a real file
    assert len((tmp_path / "out" / "sweep.csv").read_text().splitlines()) == 3


@pytest.mark.parametrize("command", ["sweep", "design"])
def test_a_fifo_given_as_input_is_refused_not_waited_on(command, tmp_path, capsys):
    fifo = tmp_path / ("t.toml" if command == "sweep" else "curve.svg")
    os.mkfifo(fifo)
    argv = ([*SWEEP[:1], str(fifo), *SWEEP[2:]] if command == "sweep"
            else ["design", "--curve", str(fifo)])
    rc = main([*argv, "-o", str(tmp_path / "out")])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert line == f"fabkit: error: {fifo}: is a FIFO (named pipe), not a regular file: refused"
    assert not (tmp_path / "out").exists()


# --- templates: references and samples ------------------------------------------------------

def test_a_sheet_named_by_many_spellings_is_read_once(tmp_path, monkeypatch, capsys):
    import fabkit.templates as templates

    (tmp_path / "sheet.toml").write_text('[chain]\nmodule = "fourbar"\ncopies = 2000\n')
    wrapper = (TEMPLATES / "fourbar.toml").read_text().replace('name = "fourbar"', "")
    (tmp_path / "w.toml").write_text(wrapper + '\n[fabrication.origami]\nsheet = "sheet.toml"\n')
    spellings = ", ".join('"' + "./" * k + 'w.toml"' for k in range(1, 301))
    top = tmp_path / "top.toml"
    top.write_text(f"[chain]\nmodules = [{spellings}]\n")
    reads = []
    real = templates.load_template

    def counting(path, **kw):
        reads.append(Path(path).name)
        return real(path, **kw)

    monkeypatch.setattr(templates, "load_template", counting)
    assert main(["info", str(top)]) == 0, capsys.readouterr().err
    assert sorted(reads) == ["fourbar.toml", "sheet.toml", "top.toml", "w.toml"]  # once each
    assert "301 ports" in capsys.readouterr().out


def test_referenced_sheets_count_together_against_the_estimate(tmp_path, monkeypatch, capsys):
    import fabkit.io.workload as workload

    # five distinct sheets of 5000 modules (20 002 nodes each, 8 MB by the estimate): with the
    # memory bound lowered to 30 MB the fourth is refused before it is built, whatever each
    # alone would need
    monkeypatch.setattr(workload, "MAX_BYTES", 30 * 2**20)
    wrapper = (TEMPLATES / "fourbar.toml").read_text().replace('name = "fourbar"', "")
    for k in range(5):
        (tmp_path / f"s{k}.toml").write_text('[chain]\nmodule = "fourbar"\ncopies = 5000\n')
        (tmp_path / f"w{k}.toml").write_text(wrapper + f'\n[fabrication.origami]\nsheet = '
                                                       f'"s{k}.toml"\n')
    mods = ", ".join(f'"w{k}.toml"' for k in range(5))
    (tmp_path / "top.toml").write_text(f"[chain]\nmodules = [{mods}]\n")
    rc = main(["info", str(tmp_path / "top.toml")])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    found = re.search(r"s3\.toml: chain\.copies: about .*\((\d+) nodes\) is over the limit of "
                      r"30 MB of memory", line)
    assert found, line
    assert int(found.group(1)) >= 4 * 20_002  # the four sheets together, not the fourth alone


def test_samples_times_nodes_of_a_sampled_trace_are_bounded(tmp_path, capsys):
    path = tmp_path / "sampled.toml"
    path.write_text('[chain]\nmodule = "fourbar"\ncopies = 10000\n[motion]\nto = 2.1\n'
                    'method = "constructive"\noptions = { samples = 100000 }\n')
    rc = main(["simulate", str(path), "-o", str(tmp_path / "out")])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert "sampled.toml: motion.options.samples: about" in line
    assert "2e+09 trace configuration nodes" in line and "over the limit" in line
    assert not (tmp_path / "out").exists()


# --- design --curve: drawings of any size ---------------------------------------------------

SVG = ('<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="300mm" '
       'viewBox="0 0 300 300">{}</svg>')
CURVES = {
    "line to 1e300": ("c.svg", SVG.format('<path d="M 0 0 L 1e300 0" stroke="black"/>')),
    "scale(1e300)": ("c.svg", SVG.format('<g transform="scale(1e300)"><path d="M 0 0 L 100 0" '
                                         'stroke="black"/></g>')),
    "1e308 overflowing": ("c.svg", SVG.format('<path d="M 0 0 L 1e308 0 L 1e308 1e308" '
                                              'stroke="black"/>')),
    "csv of 1e308": ("c.csv", "x,y\n0,0\n1e308,0\n"),
}


@pytest.mark.parametrize("case", sorted(CURVES))
def test_a_curve_of_astronomic_coordinates_is_one_line_exit_2(case, tmp_path, capsys):
    name, text = CURVES[case]
    src = tmp_path / name
    src.write_text(text)
    rc = main(["design", "--curve", str(src), "-o", str(tmp_path / "out")])
    line = one_line(capsys.readouterr().err)
    assert rc == 2
    assert line == (f"fabkit: error: {src}: coordinates beyond 1e+06 mm (1 km), or not finite: "
                    "not a drawing fabkit can follow")
    assert not (tmp_path / "out").exists()


def test_a_curve_scaled_past_any_chain_is_refused_before_design(tmp_path, capsys):
    src = tmp_path / "c.csv"
    src.write_text("x,y\n0,0\n100,0\n")
    for scale, words in (("1e300", "--curve-scale: 1e+300 makes the curve 1e+302 mm long; with "
                                   "modules of 50 mm it must be from 2 to 2000 modules long"),
                         ("1e308", "--curve-scale: makes the curve's coordinates overflow")):
        rc = main(["design", "--curve", str(src), "--curve-scale", scale, "-o",
                   str(tmp_path / "out")])
        assert rc == 2
        assert words in one_line(capsys.readouterr().err)


def test_long_segments_are_sampled_within_one_budget(monkeypatch):
    import fabkit.design.curve_files as cf

    sampled = []
    real = cf._points

    def counting(seg, t):
        sampled.append(len(t))
        return real(seg, t)

    monkeypatch.setattr(cf, "_points", counting)
    # 5000 half circles of 5 m each (95 kB): 2 points per mm would be 7.9e7 points
    arcs = " ".join(f"A 4999 4999 0 0 1 {(k % 2) * 9999} 0" for k in range(5000))
    curve = cf.read_curve(SVG.format(f'<path d="M 0 0 {arcs}" stroke="black"/>').encode(),
                          "arcs.svg")
    assert len(curve.points) == cf.MAX_SAMPLES
    # 9 points per arc to estimate its length, then the drawing's budget shared out
    assert sum(sampled) <= 9 * 5000 + cf.MAX_TOTAL_SAMPLES + 5000


def test_closed_subpaths_without_a_move_are_counted_before_parsing(tmp_path, capsys):
    # every Z makes svgelements walk back to the last M: 40 000 pieces with no M between them
    # cost their product (a fuzzed drawing of 12 MB ran past 5 min of CPU before this count)
    piece = " l 10 0 l 0 10 z"
    src = tmp_path / "closed.svg"
    src.write_text(SVG.format(f'<path d="M 0 0{piece * 40_000}" stroke="black"/>'))
    rc = main(["design", "--curve", str(src), "-o", str(tmp_path / "out")])
    line = one_line(capsys.readouterr().err)
    assert rc == 2
    assert f"{src}: about" in line and "SVG close scans" in line and "over the limit" in line


def test_a_drawing_of_a_million_segments_is_refused_by_its_estimate(tmp_path, monkeypatch,
                                                                    capsys):
    import fabkit.io.workload as workload

    src = tmp_path / "many.svg"
    src.write_text(SVG.format('<path d="M 0 0 ' + " ".join(f"L {k % 97} {k % 89}"
                                                            for k in range(200_000))
                              + '" stroke="black"/>'))
    monkeypatch.setattr(workload, "MAX_BYTES", 64 * 2**20)  # 1.5 MB of SVG: about 150 MB
    rc = main(["design", "--curve", str(src), "-o", str(tmp_path / "out")])
    line = one_line(capsys.readouterr().err)
    assert rc == 2
    assert f"{src}: about" in line and "SVG bytes" in line and "over the limit of 64 MB" in line


def test_a_sampled_trace_of_a_long_chain_is_refused_by_the_api_before_work():
    chain = fabkit.chain(fabkit.load_template("fourbar").network, copies=10_000)
    with pytest.raises(BoundsError, match=f"trace: samples = 900,000 on {chain.n_nodes:,} "
                                          "nodes: about"):
        fabkit.trace(chain, to=2.1, method="constructive", samples=900_000)


def test_check_reads_only_regular_siblings(exported, tmp_path, capsys):
    kit = tmp_path / "kit"
    kit.mkdir()
    (kit / "printed_planar_bed1.stl").write_bytes(
        (exported / "printed_planar" / "printed_planar.stl").read_bytes())
    os.mkfifo(kit / "printed_planar_bed2.stl")  # not a bed: never opened
    rc = main(["check", str(kit / "printed_planar_bed1.stl")])
    out = capsys.readouterr()
    assert rc == 0, out.err
    assert out.out.strip().endswith("printed_planar_bed1.stl: ok")


def test_the_fixture_files_are_what_the_cases_say(tmp_path, monkeypatch):
    # the coincident tetrahedra really are 20 000 bodies in a few kB
    path = tetrahedra_3mf(tmp_path / "t.3mf", 20_000)
    assert path.stat().st_size < 8_000
    from fabkit.check.threemf import read_package

    pkg = read_package(path)
    assert len(pkg["mesh"].faces) == 80_000
    assert np.allclose(pkg["mesh"].bounds, [[0, 0, 0], [10, 10, 10]])


# --- names: a chain's ports are d and ASCII digits --------------------------------------------

def test_a_port_named_with_a_superscript_digit_is_a_port_not_a_chain_place(tmp_path, capsys):
    """"d²" passes str.isdigit but not int: it names a port like any other (the export of such a
    design ended in an internal error in the tolerance analysis's slop table)."""
    text = (TEMPLATES / "fourbar.toml").read_text()
    text = text.replace("ports = { d1 = [0, 1], d2 = [2, 3] }",
                        'ports = { d1 = [0, 1], "d²" = [2, 3] }')
    assert '"d²"' in text
    (tmp_path / "fb.toml").write_text(text, encoding="utf-8")
    rc = main(["export", str(tmp_path / "fb.toml"), "--to", "dxf", "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 0 and "internal error" not in err, err
    report = json.loads((tmp_path / "out" / "fourbar" / "report.json").read_text())
    slop = {row["port"] for row in report["tolerance"]["slop"]["ports"]}
    assert "d²" in slop
