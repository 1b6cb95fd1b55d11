"""As-built check of printed STL files: solid checks, the rebuilt linkage, the transition."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import fabkit
from fabkit.check import check_file
from fabkit.check.stl import module_fixed_points
from fabkit.writers import export

from conftest import TEMPLATES


@pytest.fixture(scope="module")
def checked(tmp_path_factory):
    out = {}
    for name in ("printed_planar", "printed_planar_chain10"):
        design = fabkit.load_template(TEMPLATES / f"{name}.toml")
        folder = tmp_path_factory.mktemp(name)
        export(design, "stl", folder, print={"preview": False, "threemf": False})
        path = folder / f"{name}.stl"
        out[name] = (design, path, check_file(path, design=design, settings={}))
    return out


def _by_name(report):
    return {c["name"]: c for c in report["checks"]}


@pytest.mark.parametrize("name", ["printed_planar", "printed_planar_chain10"])
def test_every_check_passes(checked, name):
    _, _, report = checked[name]
    failed = [c["name"] for c in report["checks"] if not c["ok"]]
    assert failed == [] and report["ok"]
    c = _by_name(report)
    assert c["one body"]["value"] == 1
    assert c["no feature thinner than the nozzle"]["value"] == 0
    assert c["one conformational motion"]["value"] == 1
    # the rebuilt nodes sit where the design puts them, to float32 rounding of the STL
    assert c["rebuilt nodes match the design"]["value"] < 1e-4


def test_module_as_built(checked):
    report = checked["printed_planar"][2]
    assert report["as_built"]["triangles"] == 4
    assert report["as_built"]["joints"] == 4
    assert report["as_built"]["edges"] == 12
    tr = report["transition"]
    assert tr["sequential"] and tr["ok"]
    assert tr["pulled"] == [0, 5]  # the two hinges farthest apart: the module's long diagonal
    assert np.allclose(tr["final"], tr["D2"], rtol=1e-4)


def test_chain_transition_is_sequential(checked):
    report = checked["printed_planar_chain10"][2]
    assert report["as_built"]["triangles"] == 40
    assert report["as_built"]["joints"] == 58
    tr = report["transition"]
    assert tr["ok"] and tr["sequential"]
    # d1 .. d11 pass halfway from D1* to D2* one after the other
    order = np.array(tr["order"])
    assert np.all(np.diff(order) > 0)
    assert np.allclose(tr["final"], tr["D2"], rtol=1e-4)
    # pulling the end hinges apart carries the front through the chain until the span turns
    # back near the far end; the last port then finishes the transition
    assert [s["status"] for s in tr["stages"]][-2:] == ["turning_point", "finished"]
    assert tr["stages"][-1]["drive"] == "d11"
    assert tr["max_edge_error"] < 1e-10


def test_fixed_points_of_the_printed_module(module):
    fp = module_fixed_points(module("printed_planar"))
    assert fp["D1"] == 4.0
    assert abs(fp["slope1"]) < 1e-12  # super-stable (the exact derivative of the map)
    assert fp["D2"] == pytest.approx(1.18556434856, abs=1e-10)
    # strongly unstable, next to the turning point of d1 at 1.18437 (where the slope is infinite)
    assert fp["slope2"] == pytest.approx(-33.378, abs=2e-3)
    assert fp["d_in_turning"] == pytest.approx(1.18437162416, abs=1e-9)
    x = fp["positions"]
    net = module("printed_planar")
    assert np.abs(net.lengths_at(x) / net.edge_lengths - 1).max() < 1e-12
    assert net.port_distance("d1", x) == pytest.approx(fp["D2"], abs=1e-12)
    assert net.port_distance("d2", x) == pytest.approx(fp["D2"], abs=1e-12)


def test_broken_meshes_fail(checked, tmp_path):
    design, path, _ = checked["printed_planar"]
    mesh = trimesh.load(path)
    open_mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[:-3], process=False)
    p1 = tmp_path / "open.stl"
    open_mesh.export(p1)
    r1 = check_file(p1, design=design)
    assert not r1["ok"] and not _by_name(r1)["watertight"]["ok"]
    twice = trimesh.util.concatenate([mesh, mesh.copy().apply_translation([0, 40, 0])])
    p2 = tmp_path / "two.stl"
    twice.export(p2)
    r2 = check_file(p2)
    assert not r2["ok"]
    assert _by_name(r2)["one body"]["value"] == 2
    assert _by_name(r2)["watertight"]["ok"]


def test_without_design_only_solid_checks(checked):
    _, path, _ = checked["printed_planar"]
    r = check_file(path)
    assert r["ok"]
    assert [c["name"] for c in r["checks"]] == ["watertight", "winding consistent", "one body",
                                                "outward normals"]


def test_wrong_settings_are_caught(checked):
    design, path, _ = checked["printed_planar"]
    # checking against a bigger gap than printed: the plate sides, moved out by half the gap
    # the template now says, no longer meet at the hinges
    r = check_file(path, design=design, settings={"print": {"gap": 0.5}})
    assert not r["ok"]
    c = _by_name(r)["plates -> triangles, hinges -> joints"]
    assert not c["ok"] and c["detail"] == "4 hinge(s) hold no joint or several"


def test_unreadable_file(tmp_path):
    bad = tmp_path / "bad.stl"
    bad.write_bytes(b"\x00" * 10)
    with pytest.raises(fabkit.FabkitError, match="bad.stl"):
        check_file(bad)


def test_file_of_another_design_fails_cleanly(checked):
    chain_path = checked["printed_planar_chain10"][1]
    module_design = checked["printed_planar"][0]
    r = check_file(chain_path, design=module_design)
    assert not r["ok"]
    c = _by_name(r)
    assert not c["rebuilt nodes match the design"]["ok"]
    assert c["rebuilt nodes match the design"]["detail"] == (
        "two rebuilt nodes match one design node")


def test_any_triangle_network_prints_and_checks(tmp_path):
    # two triangles joined at one vertex: 5 nodes, 6 edges, one motion, no fixed-point ports
    (tmp_path / "pair.toml").write_text(
        'name = "pair"\n[network]\nnodes = [[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [20.0, 10.0], '
        '[12.0, 18.0]]\nedges = [[0, 1], [1, 2], [0, 2], [2, 3], [3, 4], [2, 4]]\n'
        'ports = { d1 = [0, 4] }\n'
        '[fabrication.print]\nscale = 2.0\nhinge_length = 4.0\n')
    design = fabkit.load_template(tmp_path / "pair.toml")
    export(design, "stl", tmp_path / "out")
    r = check_file(tmp_path / "out" / "pair.stl", design=design)
    assert r["ok"], [c for c in r["checks"] if not c["ok"]]
    assert _by_name(r)["one conformational motion"]["value"] == 1
    assert r["transition"]["status"].startswith("not applicable")
    assert r["as_built"]["joints"] == 1


def test_the_pinned_3mf_of_the_slope_one_chain_reads_back_whole(tmp_path):
    """The 3MF's nine-digit decimals read back as float64 put a bar's mid-height cut where the
    two triangles beside an edge computed their crossing points one rounding apart; the outline
    of body 45 fell into two pieces. Crossing points are now computed once per edge: every
    segment end meets exactly one other, and every check of both files passes."""
    from fabkit.check.stl import _plane_segments
    from fabkit.check.threemf import read_package

    design = fabkit.load_template(TEMPLATES / "slope_one_chain.toml")
    export(design, "stl", tmp_path, print={"preview": False})
    for suffix in ("3mf", "stl"):
        report = check_file(tmp_path / f"slope_one_chain_bed1.{suffix}", design=design,
                            settings={})
        assert report["ok"], [c for c in report["checks"] if not c["ok"]]
    mesh = read_package(tmp_path / "slope_one_chain_bed1.3mf")["mesh"]
    for z in np.linspace(mesh.bounds[0, 2], mesh.bounds[1, 2], 23)[1:-1]:
        seg = _plane_segments(mesh, float(z))
        _, counts = np.unique(seg.reshape(-1, 2), axis=0, return_counts=True)
        assert (counts % 2 == 0).all()  # loops close exactly, bit for bit
