"""Print-in-place bar linkages: settings, bodies read back with trimesh, the as-built check."""

from __future__ import annotations

import io
import json
import math
import zipfile

import numpy as np
import pytest
import trimesh

import fabkit
from fabkit.check import check_file
from fabkit.check.threemf import read_package
from fabkit.cli import main
from fabkit.errors import BoundsError, FabricationError, SettingsError
from fabkit.writers import export
from fabkit.writers.stl import export_design
from fabkit.fab.pinned import bar_body, pin_profile, pinned_print
from fabkit.fab.printers import chain_pieces
from fabkit.settings.printing import default_linkage, design_print_settings, print_settings

from conftest import TEMPLATES

NAMES = ["super_stable", "fourbar_chain", "super_stable_chain8"]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = {}
    for name in NAMES:
        design = fabkit.load_template(TEMPLATES / f"{name}.toml")
        folder = tmp_path_factory.mktemp(name)
        paths, report = export(design, "stl", folder, print={"preview": False})
        out[name] = (design, folder, sorted(paths), report)
    return out


@pytest.fixture(scope="module")
def checked(exported):
    out = {}
    for name, (design, folder, paths, _) in exported.items():
        stl = next(p for p in paths if p.suffix == ".stl")
        mf = next(p for p in paths if p.suffix == ".3mf")
        out[name] = (check_file(stl, design=design), check_file(mf, design=design))
    return out


def _by_name(report):
    return {c["name"]: c for c in report["checks"]}


# --- settings -------------------------------------------------------------------------------

def test_the_kind_of_print_follows_the_network():
    assert default_linkage(fabkit.load_template(TEMPLATES / "super_stable.toml").network) == "pins"
    assert default_linkage(fabkit.load_template(
        TEMPLATES / "printed_planar.toml").network) == "hinges"
    s = design_print_settings(fabkit.load_template(TEMPLATES / "fourbar.toml"))
    assert s.linkage == "pins" and s.material == "PLA"
    assert (s.scale, s.bar_width, s.pin_diameter, s.cap_diameter) == (50.0, 7.0, 3.0, 5.0)
    assert s.hole_diameter == pytest.approx(3.6)  # 0.3 mm radial clearance, the generic printer's
    assert s.layer_pitch == pytest.approx(2.8)
    assert s.cone_height == pytest.approx(1.0)  # (5 - 3) / 2: 45 degrees, whole layers


def test_pin_clearance_comes_from_the_printer():
    assert print_settings({"printer": "x1"}, linkage="pins").pin_clearance == 0.2
    assert print_settings({"printer": "ender3"}, linkage="pins").pin_clearance == 0.35
    s = print_settings({"printer": "ender3"}, {"pin_clearance": 0.25}, linkage="pins")
    assert s.pin_clearance == 0.25 and s.hole_diameter == pytest.approx(3.5)


@pytest.mark.parametrize("table, pattern", [
    ({"bar_thickness": 2.5}, r"print\.bar_thickness: 2\.5 mm is not a whole number of 0\.2 mm "
                             r"layers; use 2\.4 or 2\.6"),
    ({"layer_gap": 0.3}, r"layer_gap: 0\.3 mm is not a whole number of 0\.2 mm layers"),
    ({"bar_width": 5.0}, r"bar_width: a 5 mm bar around a 3\.6 mm hole .* use bar_width >= 5\.2"),
    ({"cap_diameter": 4.0}, r"cap_diameter: a 4 mm cap overlaps the 3\.6 mm hole by less than"),
    ({"cap_diameter": 8.0}, r"cap_diameter: a 8 mm cap is wider than the 7 mm bars"),
    ({"pin_diameter": 1.0}, r"pin_diameter: a 1 mm pin is less than three 0\.4 mm nozzle"),
    ({"hinge_width": 0.8}, r"print\.hinge_width: applies to linkage = \"hinges\" only; this "
                           r"print is linkage = \"pins\""),
])
def test_pin_settings_that_cannot_print_are_refused(table, pattern):
    with pytest.raises(FabricationError, match=pattern) as err:
        print_settings(table, linkage="pins")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("key, value, pattern", [
    ("layer_gap", 0, r"fabrication\.print\.layer_gap: must be > 0, got 0"),
    ("max_layers", 0, r"fabrication\.print\.max_layers: must be >= 1, got 0"),
    ("linkage", "glue", r"fabrication\.print\.linkage: must be one of 'hinges' or 'pins', "
                        r"got 'glue'"),
])
def test_the_schema_declares_the_pin_keys(key, value, pattern):
    with pytest.raises(SettingsError, match=pattern) as err:
        print_settings({key: value}, linkage="pins")
    assert "\n" not in str(err.value)


def test_pin_keys_on_a_hinge_print_are_refused():
    with pytest.raises(FabricationError, match=r"print\.pin_diameter: applies to linkage = "
                                               r"\"pins\" only"):
        print_settings({"pin_diameter": 3.0})


def test_bars_too_short_for_their_caps_are_refused():
    design = fabkit.load_template(TEMPLATES / "super_stable.toml")
    with pytest.raises(FabricationError, match=r"bar 0 \(joints 0-3\) is 5\.66 mm between its "
                                               r"joints at print\.scale = 10: its two 5 mm caps "
                                               r"need >= 5\.80 mm; raise print\.scale to >= "
                                               r"10\.25"):
        export_design(design, {"print": {"scale": 10.0}})


def test_a_print_past_the_work_bound_is_refused_before_work(tmp_path, monkeypatch):
    monkeypatch.delenv("FABKIT_ALLOW_LARGE", raising=False)
    (tmp_path / "big.toml").write_text('name = "big"\n[chain]\nmodule = "fourbar.toml"\n'
                                       'copies = 6000\n[motion]\ndrive = "d1"\nto = 2.5\n')
    design = fabkit.load_template(tmp_path / "big.toml")
    with pytest.raises(BoundsError, match=r"big\.toml: print-in-place linkage: about 20 min, "
                                          r"8\.94 GB \(24000 printed bars\) is over the limit"):
        export_design(design)


# --- geometry -------------------------------------------------------------------------------

def test_bodies_have_their_exact_volumes():
    design = fabkit.load_template(TEMPLATES / "super_stable.toml")
    plan = pinned_print(design, design_print_settings(design))
    assert plan.stacking.n_layers == 3 and plan.stacking.proven_minimal
    assert len(plan.carrier) == 5  # every joint of the module holds two or more bars
    for k in range(plan.n_bars):
        body = bar_body(plan, k)
        assert body.genus() == len(plan.holes(k))  # a hole through the slab per joint it turns on
        assert body.volume() == pytest.approx(plan.volumes[k], rel=1e-8)


def test_pin_profile_is_a_pin_with_collars_and_a_cap():
    s = print_settings({}, linkage="pins")
    prof = pin_profile(1.2, [(5.6, 8.0), (11.2, 13.6)], s)
    r, z = prof[:, 0], prof[:, 1]
    assert r.max() == pytest.approx(2.5) and r[1] == pytest.approx(1.5)
    assert z[-1] == pytest.approx(13.6) and r[-1] == 0.0
    # the cones under collar and cap: 1 mm up for 1 mm out (45 degrees)
    out = (np.diff(r) > 0) & (np.diff(z) > 0)
    assert out.sum() == 2 and np.allclose(np.diff(z)[out], 1.0)
    assert np.allclose(np.diff(r)[out], 1.0)


def test_chain_pieces_own_every_bar_once():
    # the super-stable chain's modules share a node between consecutive ports (d2 = (1, 2),
    # d3 = (2, 5)): each module's inner nodes go with the module whose ports they touch
    net = fabkit.load_template(TEMPLATES / "super_stable_chain.toml").network
    pieces = chain_pieces(net, 6)
    owned = np.zeros(net.n_edges, dtype=int)
    for nodes, _ in pieces:
        keep = np.zeros(net.n_nodes, dtype=bool)
        keep[nodes] = True
        owned += keep[net.edges].all(axis=1)
    assert owned.min() == 1 and owned.max() == 1  # no bar lost, none printed twice


# --- files read back ------------------------------------------------------------------------

def test_one_watertight_body_per_bar(exported):
    for name, (design, folder, paths, report) in exported.items():
        stls = [p for p in paths if p.suffix == ".stl"]
        assert len(stls) == report["printer"]["beds"]
        bodies = []
        for p in stls:
            mesh = trimesh.load(p)
            bodies += mesh.split(only_watertight=False)
        assert len(bodies) == design.network.n_edges == report["bars"]
        assert all(b.is_watertight and b.is_winding_consistent and b.volume > 0 for b in bodies)
        vol = sum(b.volume for b in bodies)
        assert vol == pytest.approx(report["volume_mm3"], rel=1e-6)


def test_every_bed_fits_the_printer(exported):
    for name, (_, _, paths, report) in exported.items():
        for p in (p for p in paths if p.suffix == ".stl"):
            mesh = trimesh.load(p)
            # centred on the 200 x 200 mm bed, 5 mm from its edges, every piece on the bed
            assert np.abs(mesh.bounds[:, :2]).max() <= 95.0 + 1e-4, name
            assert mesh.bounds[0, 2] == pytest.approx(0.0, abs=1e-6)


def test_counts(exported):
    assert exported["super_stable"][3]["bars"] == 6
    assert exported["super_stable"][3]["printed_pins"] == 5
    assert exported["super_stable"][3]["layers"] == 3
    fc = exported["fourbar_chain"][3]
    # the two end modules (107 mm) on a bed each, the two middle ones' bars (no printed pin
    # joins them) laid flat beside them and on a third bed
    assert fc["bars"] == 16 and fc["printer"]["beds"] == 3
    assert fc["printer"]["laid_flat"] == list(range(4, 12))
    # the chain is cut at the ports between modules: those joints get holes, no pins
    assert fc["cut_joints"] == [2, 3, 4, 5, 6, 7]
    assert fc["printed_pins"] == 10 - 6
    ch = exported["super_stable_chain8"][3]
    # the parts keep 17.6 mm from the bed's edges (10 mm and the slicer's support and skirt):
    # three runs of modules
    assert ch["bars"] == 48 and len(ch["printer"]["pieces"]) == 3
    assert ch["printer"]["join"] and "bolt" in ch["printer"]["join"]
    assert {b["standard"] for b in ch["print_bom"]["buy"]} == {"ISO 4762", "ISO 7089",
                                                               "ISO 10511"}


def test_threemf_carries_the_bars_as_parts_and_the_settings(exported):
    design, folder, paths, report = exported["super_stable"]
    pkg = read_package(folder / "super_stable.3mf")
    assert pkg["objects"] == [{"name": "super_stable", "parts": 6}]
    assert pkg["project"]["filament_type"] == "PLA"
    assert pkg["project"]["layer_height"] == "0.2"
    assert pkg["project"]["first_layer_height"] == "0.2"
    assert pkg["per_object"] == [{"layer_height": "0.2", "brim_width": "0", "perimeters": "4",
                                  "support_material": "1",
                                  "support_material_buildplate_only": "1",
                                  "raft_first_layer_expansion": "3"}]
    # and in the project part too, so PrusaSlicer's G-code header shows what was applied
    assert {k: pkg["project"][k] for k in pkg["per_object"][0]} == pkg["per_object"][0]
    assert (pkg["project"]["skirts"], pkg["project"]["skirt_distance"]) == ("1", "3")
    # the project settings hold nothing of the printer, bed or nozzle
    assert not {"bed_shape", "nozzle_diameter", "printer_model"} & set(pkg["project"])
    assert report["slicer"]["material"] == "PLA"
    assert "bed shape and size" in report["slicer"]["left_to_user"]


# --- the as-built check ---------------------------------------------------------------------

@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("kind", [0, 1], ids=["stl", "3mf"])
def test_every_check_passes(checked, name, kind):
    report = checked[name][kind]
    assert [c["name"] for c in report["checks"] if not c["ok"]] == [] and report["ok"]
    c = _by_name(report)
    design = fabkit.load_template(TEMPLATES / f"{name}.toml")
    assert c["one closed body per bar"]["value"] == design.network.n_edges
    # pins turn in holes 0.3 mm wider all round, as printed (float32 takes 1e-4 mm at most)
    assert 0.3 - 1e-4 <= c["pin clearance"]["value"] <= 0.3 + 0.01
    assert c["caps hold the bars"]["value"] >= 0.6  # 2.5 mm caps over 1.83 mm holes
    assert c["lengths"]["value"] <= 1e-4
    assert c["rebuilt joints match the design"]["value"] <= 1e-4
    assert c["modes"]["value"] == 1
    # the motion re-simulated on the rebuilt joints is the design's
    assert c["motion re-simulated"]["value"] <= 1e-6 * design.network.size
    # no two parts of one layer closer than half the 0.5 mm clearance anywhere on the motion
    assert c["clearances over the motion"]["value"] >= 0.25


def test_the_threemf_check_reads_its_settings(checked):
    c = _by_name(checked["super_stable"][1])
    assert c["slicer settings"]["ok"] and c["slicer settings"]["value"] == 0


def test_a_missing_body_is_caught(exported, tmp_path):
    design, folder, _, _ = exported["super_stable"]
    mesh = trimesh.load(folder / "super_stable.stl")
    bodies = sorted(mesh.split(only_watertight=False), key=lambda b: b.volume)
    trimesh.util.concatenate(bodies[1:]).export(tmp_path / "super_stable.stl")
    r = check_file(tmp_path / "super_stable.stl", design=design)
    assert not r["ok"]
    assert _by_name(r)["one closed body per bar"]["value"] == 5


def test_a_missing_pin_is_caught(tmp_path, monkeypatch):
    import fabkit.fab.pinned as pinned

    real = pinned.pinned_print

    def without_pin(design, s, motion=None):
        plan = real(design, s, motion)
        plan.carrier.pop(3)  # joint 3 (three bars) printed with holes only, no pin
        return plan

    design = fabkit.load_template(TEMPLATES / "super_stable.toml")
    monkeypatch.setattr(pinned, "pinned_print", without_pin)
    export(design, "stl", tmp_path, print={"preview": False, "threemf": False})
    monkeypatch.undo()
    r = check_file(tmp_path / "super_stable.stl", design=design)
    c = _by_name(r)["pins -> joints"]
    assert not r["ok"] and not c["ok"]
    assert c["value"] == [5, 4] and c["limit"] == [5, None]
    assert c["detail"] == "the joint at node 3 has 3 holes and no pin"


def test_a_tighter_hole_than_asked_is_caught(exported):
    design, folder, _, _ = exported["super_stable"]
    r = check_file(folder / "super_stable.stl", design=design,
                   settings={"print": {"pin_clearance": 0.4}})
    c = _by_name(r)["pin clearance"]  # printed with 0.3 mm, checked against 0.4 mm
    assert not r["ok"] and not c["ok"]
    assert c["limit"] == 0.4 and c["value"] == pytest.approx(0.3, abs=1e-4)


def test_wrong_slicer_settings_are_caught(exported, tmp_path):
    design, folder, _, _ = exported["super_stable"]
    src = zipfile.ZipFile(folder / "super_stable.3mf")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "Metadata/Slic3r_PE.config":
                data = data.replace(b"; layer_height = 0.2", b"; layer_height = 0.3")
            z.writestr(info, data)
    (tmp_path / "super_stable.3mf").write_bytes(buf.getvalue())
    r = check_file(tmp_path / "super_stable.3mf", design=design)
    c = _by_name(r)["slicer settings"]
    assert not r["ok"] and not c["ok"] and "layer_height = '0.3'" in c["detail"]


def test_without_a_design_every_body_is_checked(exported):
    _, folder, _, _ = exported["super_stable"]
    for suffix in (".stl", ".3mf"):
        r = check_file(folder / f"super_stable{suffix}")
        c = _by_name(r)
        assert r["ok"] and c["bodies"]["value"] == 6 and c["bodies"]["limit"] is None


def test_the_beds_of_a_split_print_are_read_together(checked):
    stl, mf = checked["super_stable_chain8"]
    assert stl["files"] == [f"super_stable_chain8_bed{b}.stl" for b in (1, 2, 3)]
    assert mf["files"] == [f"super_stable_chain8_bed{b}.3mf" for b in (1, 2, 3)]
    c = _by_name(stl)["pins -> joints"]
    # 26 joints; those of the two cuts have holes in every bar, for a bolt
    assert c["value"] == [26, 22] and c["limit"] == [26, None]
    assert stl["as_built"]["pieces"] == 3 and len(stl["as_built"]["cut_joints"]) == 4


def test_the_stl_and_the_3mf_of_one_export_simulate_the_rebuilt_network_once(exported,
                                                                             monkeypatch):
    """Both read back the same joints: the second check takes the first one's re-simulation and
    sampling (its own layers still measured), and reports the same motion."""
    from fabkit.check import pinned

    monkeypatch.setattr(pinned, "_MEMO", {})
    compare, calls = pinned.compare_motion, []

    def counted(*args, **kwargs):
        calls.append(1)
        return compare(*args, **kwargs)

    monkeypatch.setattr(pinned, "compare_motion", counted)
    design, _, paths, _ = exported["super_stable_chain8"]
    stl, mf = (check_file(next(p for p in paths if p.suffix == suffix), design=design)
               for suffix in (".stl", ".3mf"))
    assert len(calls) == 1
    assert stl["ok"] and mf["ok"]
    assert stl["motion"]["samples"] == mf["motion"]["samples"] > 1000
    assert stl["motion"]["max_node_step_mm"] == mf["motion"]["max_node_step_mm"]


# --- the command line -----------------------------------------------------------------------

@pytest.mark.parametrize("name", ["super_stable", "fourbar_chain"])
def test_fabkit_export_to_stl_writes_a_print_in_place_linkage(tmp_path, capsys, name):
    code = main(["export", name, "--to", "stl", "-o", str(tmp_path), "--tolerance-samples",
                 "0"])
    assert code == 0, capsys.readouterr()
    report = json.loads((tmp_path / name / "report.json").read_text())
    stl = report["formats"]["stl"]
    assert stl["status"] == "exported"
    assert stl["report"]["linkage"] == "pins"
    assert stl["checks"] and all(c["ok"] for c in stl["checks"])
    kinds = sorted({f.rsplit(".", 1)[1] for f in stl["files"]})
    assert kinds == ["3mf", "json", "md", "png", "stl"]
    assert {"print_bom.json", "print_bom.md"} <= set(stl["files"])
    assert math.isclose(stl["report"]["clearances_mm"]["pin_radial"], 0.3)


# --- the part of the motion a printed linkage follows ----------------------------------------

@pytest.mark.parametrize("name, key, value, layers", [
    ("physical_fourbar_chain", "motion_from", 1.05, 12),  # folded flat at d1 = 1: no stacking
    ("fixed_point_chain8", "motion_to", 2.9, 6),           # stops before the unstable D2*
])
def test_a_printed_linkage_follows_the_window_its_template_sets(tmp_path, capsys, name, key,
                                                                 value, layers):
    code = main(["export", name, "--to", "stl", "-o", str(tmp_path), "--tolerance-samples",
                 "0"])
    assert code == 0, capsys.readouterr()
    stl = json.loads((tmp_path / name / "report.json").read_text())["formats"]["stl"]
    assert stl["status"] == "exported"
    assert stl["report"]["settings"][key] == value
    assert stl["report"]["layers"] == layers
    # the STL and the 3MF are each read back and re-simulated over the same window
    assert len(stl["checks"]) == 2 and all(c["ok"] for c in stl["checks"])
    for c in stl["checks"]:
        motion = _by_name(c)["motion re-simulated"]
        assert motion["ok"] and motion["value"] < 1e-12


def test_the_printed_window_is_the_laser_kits_and_has_the_same_reasons_to_refuse():
    design = fabkit.load_template("fixed_point_chain8")
    s = design_print_settings(design, {"print": {"motion_to": 2.9}})
    plan = pinned_print(design, s)
    assert plan.sweep.drive[-1] == pytest.approx(2.9, abs=1e-12)
    # the whole motion (to the unstable D2*) is what the template's window avoids
    whole = design_print_settings(design, {"print": {"motion_to": design.motion.to}})
    assert pinned_print(design, whole).sweep.drive[-1] == pytest.approx(design.motion.to)
    with pytest.raises(FabricationError, match=r"print motion_from = 5 must lie between the "
                                               r"start d1 = 1\.7320\d+ and the kit's target 2\.9"):
        pinned_print(design, design_print_settings(design, {"print": {"motion_from": 5.0}}))
    with pytest.raises(FabricationError, match=r"print\.motion_from: applies to linkage = "
                                               r"\"pins\" only"):
        print_settings({"motion_from": 1.1})


def test_a_window_the_motion_cannot_reach_fails_the_export_with_its_reason(tmp_path, capsys):
    code = main(["export", "fixed_point_chain8", "--to", "stl", "-o", str(tmp_path),
                 "--tolerance-samples", "0", "--set", "print.motion_from=3.5"])
    out = capsys.readouterr()
    assert code == 1
    report = json.loads((tmp_path / "fixed_point_chain8" / "report.json").read_text()) \
        if (tmp_path / "fixed_point_chain8" / "report.json").exists() else None
    text = out.out + out.err
    assert "print motion_from = 3.5 must lie between" in text
    assert report is None or report["formats"]["stl"]["status"] != "exported"


@pytest.mark.parametrize("name, beds", [("fourbar", 1), ("super_stable_chain", 8)])
def test_the_print_preview_keeps_every_text_inside_one_bed_or_many(name, beds):
    """The preview's fixed layout leaves room for every tick label, bed title and the heading
    (wrapped to the figure's width: on one bed it ran off both edges)."""
    from fabkit.writers.pinned import preview_figure
    from fabkit.plots.viz import clipped_texts

    design = fabkit.load_template(TEMPLATES / f"{name}.toml")
    plan = pinned_print(design, design_print_settings(design, None))
    assert plan.beds == beds
    fig = preview_figure(plan, design.name)
    assert clipped_texts(fig) == []
    heading = fig.get_suptitle()
    assert f"{plan.n_bars} bars" in heading and (beds > 1 or "\n" in heading)


def test_a_print_cut_into_pieces_lists_every_part_it_does_not_print(tmp_path):
    """fourbar_chain prints four of its joints as pins and is cut at six: the print's bill of
    materials lists the bolt, washers and lock nut of each of those six with size and count,
    the texts name no part that is neither printed nor listed, and the bare STL is reported as
    geometry only."""
    import re

    from fabkit.writers import export

    design = fabkit.load_template(TEMPLATES / "fourbar_chain.toml")
    _, report = export(design, "stl", tmp_path, print={"preview": False})
    bom = report["print_bom"]
    cut = set(report["cut_joints"])
    assert len(cut) == 6 and report["printed_pins"] == 4
    assert set(bom["joints"]) == cut
    stacks = {j["joint"]: j for j in report["joints"]}
    for j, parts in bom["joints"].items():
        kinds = {p["standard"]: p for p in parts}
        assert set(kinds) == {"ISO 4762", "ISO 7089", "ISO 10511"}
        length = float(re.fullmatch(r"M3 x (\d+) mm", kinds["ISO 4762"]["size"]).group(1))
        st = stacks[j]
        s = report["settings"]
        stack = len(st["bars"]) * s["bar_thickness"] + kinds["ISO 7089"]["count"] * 0.5
        assert length >= stack + 4.0  # the washers, the stack, the nut and a turn of thread
        assert kinds["ISO 7089"]["count"] >= 2 and kinds["ISO 4762"]["count"] == 1
    totals = {b["standard"]: b["count"] for b in bom["buy"]}
    assert totals["ISO 4762"] == totals["ISO 10511"] == 6
    assert totals["ISO 7089"] == sum(p["count"] for parts in bom["joints"].values()
                                     for p in parts if p["standard"] == "ISO 7089")
    words = report["printer"]["join"] + " ".join(j["pin"] for j in report["joints"])
    assert "joints[]" not in words and "spacer" not in words
    assert report["printer"]["stl"].startswith("geometry only: use the 3MF")
    # a print that is whole buys nothing
    _, whole = export(fabkit.load_template(TEMPLATES / "super_stable.toml"), "stl",
                      tmp_path / "whole", print={"preview": False})
    assert whole["print_bom"]["buy"] == [] and whole["printer"]["join"] is None
