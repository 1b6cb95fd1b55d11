"""``fabkit sweep``: grids of module geometries through their maps, on processes and on dask."""

from __future__ import annotations

import csv
import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import fabkit
import fabkit.sweep as fsweep
from fabkit.cli import main
from fabkit.maps import module_map
from fabkit.sweep import Protocol, Status, SweepError, parse_vary

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"
SWEEPS = TEMPLATES / "sweeps"
PNG = b"\x89PNG\r\n\x1a\n"
# a light protocol: the tests check identities and statuses, not converged exponents
LIGHT = Protocol(orbits=4, discard=400, keep=32, lyapunov_orbits=8, lyapunov_discard=200,
                 lyapunov_average=800)

MODULE = """
name = "{name}"
[network]
nodes = [[-0.8660254037844386, -0.5], [0.0, 1.0], [0.8660254037844386, -0.5],
         [0.1, -0.25], [{x4}, {y4}]]
edges = [[0, 3], [1, 3], [2, 3], [0, 4], [1, 4], [2, 4]]
ports = {{ d1 = [0, 1], d2 = [1, 2] }}
[motion]
drive = "d1"
to = 2.25
"""

# nodes 0 and 1 of the module above, and the midpoint between them: node 4 there is flat
MID = (-0.4330127018922193, 0.25)


def _table(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


# --------------------------------------------------------------------------------------------
# what to vary
# --------------------------------------------------------------------------------------------
def test_parse_vary_gives_evenly_spaced_values_with_both_ends():
    ax = parse_vary("nodes[4].x=-0.4:0.0:5")
    assert ax.key == "nodes[4].x"
    assert ax.values == tuple(np.linspace(-0.4, 0.0, 5))
    assert parse_vary("motion.to=2:2:1").values == (2.0,)


@pytest.mark.parametrize("text", ["nodes[4].x=0:1:0", "nodes[4].x=1:1:3", "nodes[4].x=0:1",
                                  "nodes[4].x", "nodes[4].x=a:1:3", "nodes[4].x=0:1:2.5",
                                  "=0:1:3", "nodes[4].x=0:inf:3"])
def test_parse_vary_rejects_bad_grids(text):
    with pytest.raises(SweepError):
        parse_vary(text)


def test_key_paths_name_the_same_number_and_must_exist():
    spec = fsweep.make_spec(TEMPLATES / "chaotic.toml", {"nodes[4].x": [-0.3]}, "modes")
    spec2 = fsweep.make_spec(TEMPLATES / "chaotic.toml", {"network.nodes[4][0]": [-0.3]}, "modes")
    r1, r2 = fsweep.evaluate_point(spec, 0), fsweep.evaluate_point(spec2, 0)
    assert r1["modes_conformational"] == r2["modes_conformational"] == 1
    for bad in ("nodes[9].x", "network.nodez[4][0]", "name", "nodes[4].w", "motion.speed"):
        with pytest.raises(SweepError):
            fsweep.make_spec(TEMPLATES / "chaotic.toml", {bad: [0.1]})
    with pytest.raises(SweepError):  # the same number twice
        fsweep.make_spec(TEMPLATES / "chaotic.toml", {"nodes[4].x": [0.1],
                                                       "network.nodes[4][0]": [0.2]})
    with pytest.raises(SweepError):
        fsweep.make_spec(TEMPLATES / "chaotic.toml", {"nodes[4].x": [0.1]}, "fixed,modes")


def test_the_module_is_callable_as_fabkit_sweep():
    r = fabkit.sweep(TEMPLATES / "period_two.toml", vary={"nodes[4].y": (-0.9, -0.9, 1)},
                     measure=["fixed_points"], protocol=LIGHT)
    assert r.column("fixed_value")[0] == pytest.approx(math.sqrt(3), abs=1e-12)


# --------------------------------------------------------------------------------------------
# the paper's modules on their families' diagrams
# --------------------------------------------------------------------------------------------
def test_period_two_module_sits_on_a_stable_two_cycle(tmp_path):
    out = tmp_path / "p2"
    rc = main(["sweep", str(SWEEPS / "period_two_family.toml"), "--vary",
               "nodes[4].x=-0.34:-0.3:5", "--measure", "fixed_points,slopes,cycles,attractor",
               "-o", str(out), "--jobs", "1"])
    assert rc == 0
    rows = _table(out / "sweep.csv")
    by_x = {float(r["nodes[4].x"]): r for r in rows}
    paper = by_x[-0.3]  # the template's own geometry
    fmap = module_map(fabkit.load_template(TEMPLATES / "period_two.toml").network, toward=2.25)
    (cyc,) = fmap.cycles(2)
    assert paper["status"] == "ok" and int(paper["attractor_period"]) == 2
    assert float(paper["cycle2_low"]) == cyc.values[0]
    assert float(paper["cycle2_high"]) == cyc.values[1]
    assert float(paper["cycle2_multiplier"]) == pytest.approx(-0.7053411475786, abs=1e-10)
    assert float(paper["fixed_value"]) == pytest.approx(math.sqrt(3), abs=1e-12)
    assert float(paper["fixed_slope"]) < -1  # the fixed point is unstable
    # the attractor is that cycle
    assert float(paper["attractor_min"]) == pytest.approx(cyc.values[0], abs=1e-9)
    assert float(paper["attractor_max"]) == pytest.approx(cyc.values[1], abs=1e-9)
    # past the crisis the orbits leave the domain: recorded, not dropped
    assert by_x[-0.34]["status"] == "escapes" and by_x[-0.34]["attractor_period"] == "-1"
    assert (out / "bifurcation.png").read_bytes().startswith(PNG)
    summary = json.loads((out / "sweep.json").read_text())
    assert summary["counts"] == {"ok": 2, "escapes": 3}
    assert [p["index"] for p in summary["points"]] == list(range(5))
    assert all(p["reason"] for p in summary["points"] if p["status"] != "ok")


def test_chaotic_module_has_the_papers_exponent(tmp_path):
    out = tmp_path / "pd"
    rc = main(["sweep", str(SWEEPS / "period_doubling.toml"), "--vary",
               "nodes[4].x=-0.33:-0.33:1", "--measure", "lyapunov,attractor", "-o", str(out),
               "--jobs", "1"])
    assert rc == 0
    (row,) = _table(out / "sweep.csv")
    assert row["status"] == "ok" and row["attractor_period"] == "0"  # no period: chaos
    lam = float(row["lyapunov"])
    assert lam == pytest.approx(0.312, abs=0.005)
    # the same number as the module's own map with the same protocol
    fmap = module_map(fabkit.load_template(TEMPLATES / "chaotic.toml").network, toward=0.75)
    p = Protocol()
    ref = fmap.lyapunov(initial=p.lyapunov_orbits, discard=p.lyapunov_discard,
                        average=p.lyapunov_average)
    assert lam == ref.mean


@pytest.mark.slow
def test_bundled_period_doubling_example_in_full(tmp_path):
    out = tmp_path / "pd"
    assert main(["sweep", str(SWEEPS / "period_doubling.toml"), "-o", str(out)]) == 0
    rows = _table(out / "sweep.csv")
    x = np.array([float(r["nodes[4].x"]) for r in rows])
    per = np.array([int(r["attractor_period"]) for r in rows])
    k = int(np.argmin(np.abs(x + 0.33)))
    assert x[k] == -0.33  # the template's own geometry is a grid point
    assert per[k] == 0 and float(rows[k]["lyapunov"]) == pytest.approx(0.312, abs=0.005)
    # the cascade: 2-cycle, 4-cycle, 8-cycle, chaos, crisis (orbits leave the domain)
    assert set(per[x > -0.275]) == {2}
    assert set(per[(x < -0.278) & (x > -0.3005)]) == {4}
    assert set(per[(x < -0.3025) & (x > -0.3055)]) == {8}
    assert {r["status"] for r, xi in zip(rows, x) if xi < -0.333} == {"escapes"}
    assert {r["status"] for r, xi in zip(rows, x) if xi > -0.332} == {"ok"}
    assert (out / "bifurcation.png").read_bytes().startswith(PNG)


# --------------------------------------------------------------------------------------------
# points that are not ok: typed statuses, drawn as such
# --------------------------------------------------------------------------------------------
def test_flat_and_failed_points_are_recorded_and_drawn(tmp_path):
    tpl = tmp_path / "module.toml"
    tpl.write_text(MODULE.format(name="module", x4=-0.3, y4=-0.9))
    out = tmp_path / "grid"
    # node 4 through the midpoint of nodes 0 and 1 (flat: collinear with both) and onto
    # node 0 (a bar of zero length: no network)
    r = fsweep.sweep(tpl, {"nodes[4].x": [MID[0], -0.8660254037844386, -0.3],
                           "nodes[4].y": [-0.9, MID[1], -0.5]},
                     ["fixed_points", "modes", "attractor"], outdir=out, protocol=LIGHT)
    status = r.status
    assert status.shape == (3, 3)
    assert status[0, 1] is Status.FLAT
    assert status[1, 2] is Status.FAILED
    assert status[0, 0] is Status.ESCAPES and status[2, 0] is Status.OK
    assert r.counts() == {"ok": 4, "flat": 1, "failed": 1, "escapes": 3}
    assert "zero length" in r.records[5]["reason"]
    assert "flat state" in r.records[1]["reason"]
    # the flat start lies at the end of its branch: d1 can only shrink from there
    assert r.records[1]["reference"] == pytest.approx(r.records[1]["domain_hi"], abs=1e-9)
    names = {p.name for p in _files(out) if p.suffix == ".png"}
    assert "heatmap_fixed_value.png" in names and "heatmap_modes_conformational.png" in names
    from PIL import Image

    img = np.asarray(Image.open(out / "heatmap_fixed_value.png").convert("RGB")).reshape(-1, 3)
    flat = np.array([0xD6, 0x27, 0x28])  # the flat status colour, drawn over its cell
    assert (np.abs(img.astype(int) - flat).sum(axis=1) < 60).sum() > 500


def test_a_rigid_geometry_is_rigid_at_every_point(tmp_path):
    tpl = tmp_path / "braced.toml"
    tpl.write_text('[network]\nnodes = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]\n'
                   'edges = [[0, 1], [0, 2], [1, 3], [2, 3], [0, 3]]\n'
                   'ports = { d1 = [1, 2], d2 = [0, 3] }\n')
    r = fsweep.sweep(tpl, {"nodes[3].x": (0.8, 1.2, 3)}, outdir=tmp_path / "o", protocol=LIGHT)
    assert set(r.column("status")) == {"rigid"}
    assert list(r.column("modes_conformational")) == [0, 0, 0]
    assert (tmp_path / "o" / "bifurcation.png").read_bytes().startswith(PNG)


@pytest.mark.parametrize("motion", ["", '[motion]\ndrive = "d1"\nto = 2.5\n'])
def test_a_motion_that_d1_does_not_drive_is_no_motion(tmp_path, motion):
    # d1 is a bar of the 4-bar: the linkage moves, but d1 never changes
    tpl = tmp_path / "bar.toml"
    tpl.write_text('[network]\nnodes = [[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]\n'
                   'edges = [[0, 2], [0, 3], [1, 2], [1, 3]]\n'
                   'ports = { d1 = [0, 2], d2 = [1, 3] }\n' + motion)
    r = fsweep.sweep(tpl, {"nodes[3].y": (0.9, 1.1, 2)}, ["modes", "fixed_points"],
                     protocol=LIGHT)
    assert set(r.column("status")) == {"no_motion"}
    assert list(r.column("modes_conformational")) == [1, 1]
    assert all(r.column("reason"))


# --------------------------------------------------------------------------------------------
# streaming, resume, processes, dask
# --------------------------------------------------------------------------------------------
GRID = {"nodes[4].x": (-0.34, -0.2, 3), "nodes[4].y": (-1.4, -1.3, 2)}


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref") / "sweep"
    return fsweep.sweep(TEMPLATES / "chaotic.toml", GRID, outdir=out, protocol=LIGHT)


def test_interrupted_sweep_resumes_to_the_same_table(tmp_path, reference_run):
    out = tmp_path / "sweep"
    calls = []

    def stop_after_two_chunks(done, total):
        calls.append(done)
        if len(calls) == 3:  # the start, then two chunks written
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        fsweep.sweep(TEMPLATES / "chaotic.toml", GRID, outdir=out, protocol=LIGHT,
                     chunk_size=2, progress=stop_after_two_chunks)
    chunks = sorted((out / "chunks").glob("chunk-*.json"))
    assert len(chunks) == 2 and not (out / "sweep.csv").exists()
    r = fsweep.sweep(TEMPLATES / "chaotic.toml", GRID, outdir=out, protocol=LIGHT, chunk_size=3)
    assert r.computed == 2
    assert (out / "sweep.csv").read_bytes() == (reference_run.outdir / "sweep.csv").read_bytes()
    assert r.records == reference_run.records
    # a finished sweep run again computes nothing and writes the same files
    again = fsweep.sweep(TEMPLATES / "chaotic.toml", GRID, outdir=out, protocol=LIGHT)
    assert again.computed == 0 and again.records == reference_run.records


def test_a_folder_of_another_sweep_is_refused(tmp_path, reference_run):
    before = _files(reference_run.outdir)
    with pytest.raises(fabkit.FabkitError):
        fsweep.sweep(TEMPLATES / "chaotic.toml", {"nodes[4].x": (-0.3, -0.2, 2)},
                     outdir=reference_run.outdir, protocol=LIGHT)
    assert _files(reference_run.outdir) == before


def test_local_processes_give_identical_numbers(tmp_path, reference_run):
    r = fsweep.sweep(TEMPLATES / "chaotic.toml", GRID, outdir=tmp_path / "p", protocol=LIGHT,
                     jobs=2, chunk_size=1)
    assert r.where == "processes" and r.workers == 2
    assert r.records == reference_run.records
    assert (tmp_path / "p" / "sweep.csv").read_bytes() == \
        (reference_run.outdir / "sweep.csv").read_bytes()


def test_local_cluster_with_two_workers_gives_identical_numbers(tmp_path, reference_run):
    LocalCluster = pytest.importorskip("distributed", reason="the cluster extra: pip install "
                                       "'fabkit[cluster]'").LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster:
        r = fsweep.sweep(TEMPLATES / "chaotic.toml", GRID, outdir=tmp_path / "c",
                         protocol=LIGHT, scheduler=cluster.scheduler_address, chunk_size=2)
    assert r.workers == 2 and r.where == cluster.scheduler_address
    assert r.records == reference_run.records
    assert (tmp_path / "c" / "sweep.csv").read_bytes() == \
        (reference_run.outdir / "sweep.csv").read_bytes()
    assert len(list((tmp_path / "c" / "chunks").glob("chunk-*.json"))) == 3


def test_cli_interrupt_then_restart_resumes(tmp_path, reference_run):
    out = tmp_path / "cli"
    cmd = [sys.executable, "-m", "fabkit.cli", "sweep", str(TEMPLATES / "chaotic.toml"),
           "--vary", "nodes[4].x=-0.34:-0.2:3", "--vary", "nodes[4].y=-1.4:-1.3:2",
           "-o", str(out), "--jobs", "1", "--chunk-size", "1"]
    light = ["--lyapunov-protocol", "8:200:800"]
    proc = subprocess.Popen(cmd + light, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        if len(list((out / "chunks").glob("chunk-*.json"))) >= 2:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the sweep finished before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert err.decode().strip().splitlines() == [
        f"fabkit: interrupted (SIGINT); finished chunks are in {out / 'chunks'}: run the same "
        "command again to resume"]
    assert not (out / "sweep.csv").exists()
    done = len(list((out / "chunks").glob("chunk-*.json")))
    assert 2 <= done < 6
    # the same command again finishes the rest, and gives the table of an uninterrupted run
    rerun = subprocess.run(cmd + light, capture_output=True, timeout=120)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{done} read back".encode() in rerun.stdout
    fresh = tmp_path / "fresh"
    whole = subprocess.run(cmd[:-6] + ["-o", str(fresh), "--jobs", "1"] + light,
                           capture_output=True, timeout=120)
    assert whole.returncode == 0, whole.stderr
    assert (out / "sweep.csv").read_bytes() == (fresh / "sweep.csv").read_bytes()


# --------------------------------------------------------------------------------------------
# bad input: one line, the right exit code, no files
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("vary, code", [
    ("nodes[7].x=0:1:3", 2),          # unknown key
    ("nodes[4].x=-0.3:-0.2:0", 2),    # N = 0
    ("nodes[4].x=-0.3:-0.3:4", 2),    # START = STOP with N > 1
    ("nodes[4].x=-0.3:-0.2", 2),      # malformed
    ("name=0:1:2", 2),                # not a number
])
def test_bad_vary_is_one_line_exit_2_and_no_files(tmp_path, capsys, vary, code):
    out = tmp_path / "o"
    rc = main(["sweep", str(TEMPLATES / "chaotic.toml"), "--vary", vary, "-o", str(out)])
    assert rc == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("fabkit: error:")
    assert not out.exists()


def test_unknown_measure_and_missing_template(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["sweep", str(TEMPLATES / "chaotic.toml"), "--vary", "nodes[4].x=0:1:2",
                 "--measure", "fixed_points,entropy", "-o", str(out)]) == 2
    assert main(["sweep", str(tmp_path / "nope.toml"), "--vary", "nodes[4].x=0:1:2",
                 "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "entropy" in err[0] and "nope.toml" in err[1]
    assert not out.exists()


def test_output_folder_that_is_a_file(tmp_path, capsys):
    target = tmp_path / "taken"
    target.write_text("keep me")
    rc = main(["sweep", str(TEMPLATES / "chaotic.toml"), "--vary", "nodes[4].x=-0.3:-0.2:2",
               "-o", str(target)])
    assert rc == 1 and target.read_text() == "keep me"
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("fabkit: error:") and str(target) in line
    assert _files(tmp_path) == [target]


def test_unreachable_scheduler(tmp_path, capsys):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "o"
    rc = main(["sweep", str(TEMPLATES / "chaotic.toml"), "--vary", "nodes[4].x=-0.3:-0.2:2",
               "-o", str(out), "--scheduler", f"tcp://127.0.0.1:{port}",
               "--connect-timeout", "1"])
    assert rc == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "cannot reach the dask scheduler" in line
    assert not out.exists()


def test_a_scheduler_without_workers(tmp_path, capsys):
    LocalCluster = pytest.importorskip("distributed", reason="the cluster extra: pip install "
                                       "'fabkit[cluster]'").LocalCluster

    out = tmp_path / "o"
    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        rc = main(["sweep", str(TEMPLATES / "chaotic.toml"), "--vary", "nodes[4].x=-0.3:-0.2:2",
                   "-o", str(out), "--scheduler", cluster.scheduler_address,
                   "--connect-timeout", "1"])
    assert rc == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "has no workers" in line
    assert not out.exists()


def test_without_the_cluster_extra_local_sweeps_run_and_a_cluster_names_it(tmp_path, capsys,
                                                                            monkeypatch):
    """dask is an optional extra: without it (its imports fail here) a sweep on this machine
    runs as before, and one on a cluster is refused in one line that names the extra."""
    for name in ("dask", "distributed"):
        monkeypatch.setitem(sys.modules, name, None)  # import dask -> ImportError
    grid = ["--vary", "nodes[4].x=-0.3:-0.2:2", "--measure", "fixed_points"]
    assert main(["sweep", str(TEMPLATES / "chaotic.toml"), *grid, "-o", str(tmp_path / "here"),
                 "--jobs", "1", "--no-plots", "-q"]) == 0
    assert (tmp_path / "here" / "sweep.csv").is_file()
    out = tmp_path / "o"
    rc = main(["sweep", str(TEMPLATES / "chaotic.toml"), *grid, "-o", str(out),
               "--scheduler", "tcp://127.0.0.1:1", "--connect-timeout", "1"])
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and line == (
        "fabkit: error: running on a cluster (--scheduler) needs dask.distributed, which this "
        "installation lacks: pip install 'fabkit[cluster]'")
    assert not out.exists()


def test_scheduler_address_from_the_environment(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:1")
    rc = main(["sweep", str(TEMPLATES / "chaotic.toml"), "--vary", "nodes[4].x=-0.3:-0.2:2",
               "-o", str(tmp_path / "o"), "--connect-timeout", "1"])
    assert rc == 1 and "tcp://127.0.0.1:1" in capsys.readouterr().err


def test_sweep_specs_are_not_design_templates():
    from fabkit.commands import expand_templates

    found = expand_templates([str(TEMPLATES)])
    assert found and not any("sweeps" in p.parts for p in found)
    for spec in SWEEPS.glob("*.toml"):
        s = fsweep.read_sweep_file(spec)
        assert s is not None and s.template.exists() and len(s.axes) == 1
        with pytest.raises(fabkit.TemplateError):
            fabkit.load_template(spec)
    assert fsweep.read_sweep_file(TEMPLATES / "chaotic.toml") is None


def test_bad_sweep_spec_file(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\ntemplate = "x.toml"\nvary = ["a=0:1:2"]\nspeed = 3\n')
    assert main(["sweep", str(spec), "-o", str(tmp_path / "o")]) == 2
    assert "speed" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
