"""The four bundled designs that used to get no laser kit: each writes DXF and SVG sheets, BOM,
guide and coupon, and its as-built check passes; deep stacks are proven, not capped."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

import fabkit
from fabkit.check.dxf import check_documents
from fabkit.errors import FabricationError
from fabkit.writers.dxf import export_design
from fabkit.fab.laser_plan import laser_plan
from fabkit.fab.layers import Conflicts
from fabkit.fab.layers import propagate
from fabkit.fab.layers.propagate import deep_search, propagate_layers

from conftest import TEMPLATES


def _kit(name):
    design = fabkit.load_template(TEMPLATES / f"{name}.toml")
    result = export_design(design)
    texts = {n: b.decode("ascii") for n, b in result.files.items()
             if n.startswith("laser_sheet") and n.endswith(".dxf")}
    check = check_documents(texts, design=design)
    bom = json.loads(result.files["laser_bom.json"])
    n = len(bom["sheets"])
    names = set(result.files)
    assert {f"laser_sheet{k}.{x}" for k in range(1, n + 1) for x in ("dxf", "svg")} <= names
    assert {"laser_bom.json", "laser_bom.md", "laser_guide.pdf", "laser_coupon.dxf",
            "laser_coupon.svg", "laser_coupon.md"} <= names
    # the kerf stated where a cutter reads it, the coupon drawn as the kit's parts
    assert "do not compensate kerf again" in bom["kerf"]["note"]
    assert b"do not compensate kerf again" in result.files["laser_sheet1.dxf"]
    assert b"do not compensate kerf again" in result.files["laser_coupon.dxf"]
    coupon = check_documents({"laser_coupon.dxf": result.files["laser_coupon.dxf"].decode()},
                             design=design)
    assert coupon["ok"] and coupon["coupon"]
    return design, bom, check, {c["name"]: c for c in check["checks"]}


def test_fixed_point_chain_kit_stops_before_the_unstable_crystal():
    design, bom, check, checks = _kit("fixed_point_chain8")
    assert check["ok"], checks
    # the design still goes to D2*; the kit's motion ends at the template's 2.9
    assert design.motion.to == pytest.approx(1.7 * math.sqrt(3))
    assert bom["motion"]["to"] == 2.9 and bom["motion"]["from"] == pytest.approx(math.sqrt(3))
    assert bom["layers"]["count"] == 6 and bom["layers"]["proven_minimal"]
    assert checks["module_map"]["value"] <= checks["module_map"]["limit"]
    assert checks["modes"]["value"] == 1 and checks["same_layer"]["value"] >= 0.5


def test_physical_fourbar_chain_kit_starts_where_its_bars_lie_apart():
    design, bom, check, checks = _kit("physical_fourbar_chain")
    assert check["ok"], checks
    assert bom["motion"]["from"] == pytest.approx(1.05, abs=1e-9)
    assert bom["motion"]["to"] == pytest.approx(1.9072122610809965)
    assert bom["layers"]["count"] == 12 and bom["layers"]["lower_bound"] == 12
    # the kit is assembled in its start state, d1 = 1.05, not the design's flat 1 + 1e-6; its
    # bars keep the design's lengths
    from fabkit.fab.laser import kit_design
    from fabkit.settings.laser import laser_settings

    kit = kit_design(design, laser_settings(design.fabrication["laser"]))
    assert design.network.port_distance("d1") == pytest.approx(1.000001)
    assert kit.network.port_distance("d1") == pytest.approx(1.05, abs=1e-9)
    assert np.abs(kit.network.edge_lengths - design.network.edge_lengths).max() < 1e-9
    lengths = np.array([b["length_mm"] for b in bom["bars"]])
    assert np.abs(lengths - 100 * design.network.edge_lengths).max() < 1e-6
    assert checks["same_layer"]["value"] >= 0.5 and checks["screws_close"]["ok"]


def test_curvature_chain_is_a_deep_kit_whose_bound_does_not_depend_on_the_cap():
    design, bom, check, checks = _kit("curvature_chain")
    assert check["ok"], checks
    layers = bom["layers"]
    assert (layers["count"], layers["lower_bound"], layers["method"]) == (19, 16, "propagation")
    assert layers["depth_mm"] == 57.0
    kinds = {j["fastener_kind"] for j in bom["joints"]}
    assert "clevis pin" in kinds and "chicago" in kinds
    # joints 4 and 9 pass within 0.19 mm: their columns stand one above the other
    spans = {j["joint"]: (min(j["layers"]), max(j["layers"])) for j in bom["joints"]}
    (lo4, hi4), (lo9, hi9) = spans[4], spans[9]
    head = layers["head_slots"]
    assert hi4 + 2 * head < lo9 or hi9 + 2 * head < lo4
    # the cap is applied after the search: the same layers and bound at another cap
    with pytest.raises(FabricationError) as info:
        laser_plan(design, {"laser": {"max_layers": 12}})
    assert "deeper than max_layers = 12 (19 layers found, at least 16 needed: 57 mm" in \
        str(info.value)


def test_and_gate_kit_stacks_the_branch_over_the_trunk_where_joints_coincide():
    design, bom, check, checks = _kit("and_gate")
    assert check["ok"], checks
    # the design starts at its branch point on purpose: two infinitesimal motions
    assert checks["modes"]["value"] == checks["modes"]["limit"] == 2
    assert checks["module_map"]["value"] <= checks["module_map"]["limit"]
    layers = bom["layers"]
    assert (layers["count"], layers["lower_bound"]) == (14, 13)
    head = layers["head_slots"]
    spans = {j["joint"]: (min(j["layers"]), max(j["layers"])) for j in bom["joints"]}
    x = design.network.nodes
    for a, b in ((17, 91), (22, 96), (24, 95)):
        assert np.linalg.norm(x[a] - x[b]) < 1e-12   # the same place in the plane
        (la, ha), (lb, hb) = spans[a], spans[b]
        assert ha + 2 * head < lb or hb + 2 * head < la, (a, b)
    # the deepest joint (23, ten layers) takes the 35 mm post of the M4 series (up to 50 mm)
    deep = [j for j in bom["joints"] if len(range(min(j["layers"]), max(j["layers"]) + 1)) >= 10]
    assert deep and all(j["fastener_kind"] == "chicago" and j["screw_length_mm"] >= 35
                        for j in deep)
    parts = {h["kind"] for h in bom["buy"]["hardware"]}
    assert parts == {"chicago screw", "washer"}


# -- the complete search ----------------------------------------------------------------------

def _conflicts(n_bars, pairs, keepout=(), joint_pairs=(), screw_joints=()):
    e = np.zeros((0, 2), dtype=np.int64)
    arr = lambda v: np.asarray(v, dtype=np.int64).reshape(-1, 2) if len(v) else e  # noqa: E731
    return Conflicts(pairs=arr(pairs), kind=np.array(["sweep"] * len(pairs), dtype=object),
                     gap=np.zeros(len(pairs)), sample=np.zeros(len(pairs), dtype=np.int64),
                     keepout=arr(keepout), joint_pairs=arr(joint_pairs),
                     screw_joints=np.asarray(screw_joints, dtype=np.int64))


def test_two_coincident_screws_stack_one_above_the_other_and_fewer_layers_are_ruled_out():
    # joint 0 holds bars 0, 1; joint 1 (at the same place) holds bars 2, 3; every bar of each
    # passes the other's screw, and every bar overlaps every other
    pairs = [(a, b) for a in range(4) for b in range(a + 1, 4)]
    keepout = [(0, 1), (1, 1), (2, 0), (3, 0)]
    conf = _conflicts(4, pairs, keepout, [(0, 1)], [0, 1])
    joint_bars = [np.array([0, 1]), np.array([2, 3])]
    # 2 bars + 2 head slots + 2 head slots + 2 bars: 6 layers with one-layer heads
    r = deep_search(4, conf, joint_bars, 1, range(4, 10))
    assert int(r.layer.max()) + 1 == 6 and r.bound == 6
    assert r.tried == ((4, "none"), (5, "none"), (6, "found"))
    z = r.layer
    assert abs(int(z[0]) - int(z[1])) == 1 and abs(int(z[2]) - int(z[3])) == 1
    assert min(z[2:]) - max(z[:2]) == 3 or min(z[:2]) - max(z[2:]) == 3
    layer, nodes, exhausted = propagate_layers(4, conf, joint_bars, 1, 5)
    assert layer is None and exhausted and nodes >= 1
    # a budget too small decides nothing, and proves nothing
    r = deep_search(4, conf, joint_bars, 1, range(4, 10), node_limit=1)
    assert r.layer is None or int(r.layer.max()) + 1 >= 6


@pytest.mark.parametrize("candidate_bars", [0, 10_000])
def test_the_deep_search_visits_the_same_branches_in_the_same_order(monkeypatch,
                                                                    candidate_bars):
    # A path of 14 bars (bar b joins joints b and b + 1), each conflicting with the next three,
    # bars passing screws and spacers, and close columns four joints apart: the counts 1..11
    # are ruled out and 12 found after 1111 branches. The count of branches and the stacking
    # found pin the order in which the search places bars and the failures it learns from
    # (a cheaper search must take the same branches: its budget is a count of them). The bar
    # to place is chosen among the narrowed bars or by scanning all: the same bar either way.
    monkeypatch.setattr(propagate, "CANDIDATE_BARS", candidate_bars)
    n = 14
    screw = list(range(1, n))
    pairs = [(a, b) for a in range(n) for b in range(a + 1, min(n, a + 4))]
    keepout = [(b, j) for b in range(n) for j in screw
               if j not in (b, b + 1) and (3 * b + j) % 7 == 0]
    span = [(b, j) for b in range(n) for j in screw if j not in (b, b + 1)
            and (b + 2 * j) % 9 == 0 and (b, j) not in keepout]
    conf = _conflicts(n, pairs, keepout, [(j, j + 4) for j in screw if j + 4 < n and j % 3 == 0],
                      screw)
    conf = dataclasses.replace(conf, keepout_span=np.asarray(span, dtype=np.int64))
    joint_bars = [np.array([j - 1, j]) for j in screw]
    r = deep_search(n, conf, joint_bars, 1, range(1, 20), node_limit=3000, total_limit=12000)
    assert r.nodes == 1111 and r.bound == 12
    assert r.tried == tuple((k, "none") for k in range(1, 12)) + ((12, "found"),)
    assert r.layer.tolist() == [3, 2, 0, 5, 7, 11, 10, 9, 2, 0, 4, 10, 7, 8]
    # a budget that stops inside count 11 decides nothing there
    r = deep_search(n, conf, joint_bars, 1, range(1, 20), node_limit=300, total_limit=1200)
    assert r.nodes == 1201 and r.bound == 11 and r.layer is None
    assert r.tried[-3:] == ((11, "budget"), (12, "budget"), (13, "budget"))
