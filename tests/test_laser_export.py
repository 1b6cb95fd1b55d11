"""DXF export of the paper's designs: real files read back with ezdxf and checked as built."""

from __future__ import annotations

import io
import json

import ezdxf
import numpy as np
import pytest

import fabkit
from fabkit.check import check_file
from fabkit.check.dxf import check_documents
from fabkit.writers import export, get_exporter
from fabkit.writers.dxf import applies, export_design

from conftest import TEMPLATES


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    designs = {
        "fourbar": fabkit.load_template(TEMPLATES / "fourbar.toml"),
        "super_stable": fabkit.load_template(TEMPLATES / "super_stable.toml"),
    }
    out = {}
    for key, design in designs.items():
        folder = tmp_path_factory.mktemp(key)
        paths, report = export(design, "dxf", folder)
        out[key] = (design, folder, paths, report)
    return out


DESIGNS = ["fourbar", "super_stable"]  # the 8-module chain: tests/test_laser_chain.py


def test_registry_and_applies():
    assert get_exporter("dxf").FORMAT == "dxf"
    assert applies(fabkit.load_template(TEMPLATES / "fourbar.toml"))


@pytest.mark.parametrize("key", DESIGNS)
def test_files_written(exported, key):
    _, folder, paths, report = exported[key]
    names = sorted(p.name for p in paths)
    n = len(report["sheets"])
    assert names == sorted(["laser_assembly.png", "laser_bom.json", "laser_bom.md",
                            "laser_layers_motion.png", "laser_guide.pdf", "laser_guide_page1.png",
                            "laser_coupon.dxf", "laser_coupon.svg", "laser_coupon.md",
                            *[f"laser_sheet{k}.dxf" for k in range(1, n + 1)],
                            *[f"laser_sheet{k}.svg" for k in range(1, n + 1)]])
    for p in paths:
        assert p.stat().st_size > 0
    assert (folder / "laser_assembly.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (folder / "laser_layers_motion.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import xml.etree.ElementTree as ET

    ns = "{http://www.w3.org/2000/svg}"
    holes = outer = 0
    for k in range(1, n + 1):
        root = ET.parse(folder / f"laser_sheet{k}.svg").getroot()
        sheet = report["sheets"][k - 1]
        w, h = sheet["size_mm"]
        assert root.get("width") == f"{w:g}mm" and root.get("height") == f"{h:g}mm"
        assert root.get("viewBox") == f"0 0 {w:g} {h:g}"          # one unit = one mm
        assert not list(root.iter(f"{ns}text")) and not list(root.iter(f"{ns}rect"))
        assert all(e.get("transform") is None for e in root.iter())
        strokes = [e.get("stroke") for e in root.iter() if e.get("stroke") not in (None, "none")]
        assert set(strokes) <= {"#FF0000", "#0000FF", "#00FF00"}
        # no outline is stroked in the colour that fills the labels: a program set to fill the
        # black layer engraves the labels, not the reference square as a block
        fills = {e.get("fill") for e in root.iter() if e.get("fill") not in (None, "none")}
        assert fills == {"#000000"} and not fills & set(strokes)
        refs = [e for e in root.iter(f"{ns}path") if e.get("id") == "REF"]
        if k == 1:
            assert len(refs) == 1 and refs[0].get("stroke") == "#00FF00"
            group = next(g for g in root.iter(f"{ns}g") if g.get("id") == "reference")
            assert refs[0] in list(group)
        holes += sum(e.get("stroke") == "#0000FF" for e in root.iter(f"{ns}circle"))
        outer += sum(e.get("stroke") == "#FF0000" and (e.get("id") or "").startswith("B")
                     for e in root.iter(f"{ns}path"))
        # labels are filled glyph outlines (black), no TEXT
        assert any(e.get("fill") == "#000000" for e in root.iter(f"{ns}path"))
    assert outer == len(report["bars"]) and holes >= 2 * len(report["bars"])


@pytest.mark.parametrize("key", DESIGNS)
def test_dxf_structure_read_back_with_ezdxf(exported, key):
    design, folder, _, report = exported[key]
    net = design.network
    scale = report["scale_mm_per_unit"]
    kerf = report["settings"]["kerf"]
    holes, outlines = [], []
    for sheet in sorted(folder.glob("laser_sheet*.dxf")):
        doc = ezdxf.readfile(sheet)
        assert doc.dxfversion == "AC1024"                       # R2010
        assert doc.header["$INSUNITS"] == 4                     # mm, not ezdxf's default
        assert not doc.audit().has_errors
        msp = doc.modelspace()
        assert {e.dxf.layer for e in msp} <= {"CUT", "CUT_INNER", "ENGRAVE", "REFERENCE"}
        holes += [e for e in msp.query("CIRCLE[layer=='CUT_INNER']")]
        outlines += [e for e in msp.query("LWPOLYLINE[layer=='CUT']")]
        # labels are glyph outlines by default (CAM importers drop TEXT)
        assert len(msp.query("TEXT")) == 0
        assert len(msp.query("LWPOLYLINE[layer=='ENGRAVE']")) >= 1
        # drawing extents cover every entity
        from ezdxf import bbox

        box = bbox.extents(msp)
        lo, hi = np.array(doc.header["$EXTMIN"])[:2], np.array(doc.header["$EXTMAX"])[:2]
        assert np.all(lo <= np.array(box.extmin)[:2] + 1e-6)
        assert np.all(hi >= np.array(box.extmax)[:2] - 1e-6)
        assert np.all(hi - lo > 10.0)
    n_spacers = report["spacer_rings"]["count"]
    assert len(holes) == 2 * net.n_edges + n_spacers
    assert len(outlines) == net.n_edges
    for pl in outlines:
        assert pl.closed and [round(p[0], 12) for p in pl.get_points("b")] == [0.0, 1.0, 0.0, 1.0]
    # hole radius as drawn: 5.2 mm shrunk by half the kerf
    radii = {round(h.dxf.radius, 9) for h in holes}
    assert radii == {round(0.5 * (5.2 - kerf), 9)}
    # rebuild bar lengths from hole centres (pairs tagged by part) and compare with the design
    by_part = {}
    for h in holes:
        by_part.setdefault(h.get_xdata("FABKIT")[0].value, []).append(np.array(h.dxf.center)[:2])
    lengths = np.array([np.linalg.norm(by_part[f"B{k}"][0] - by_part[f"B{k}"][1])
                        for k in range(net.n_edges)])
    assert np.abs(lengths - net.edge_lengths * scale).max() <= 1e-6


@pytest.mark.parametrize("key", DESIGNS)
def test_as_built_check_passes_on_the_written_files(exported, key):
    design, folder, _, report = exported[key]
    result = check_file(folder / "laser_sheet1.dxf", design=design)
    assert result["ok"], [c for c in result["checks"] if not c["ok"]]
    checks = {c["name"]: c for c in result["checks"]}
    assert set(checks) >= {"units", "audit", "layers", "parts", "holes_centred", "width_after_kerf",
                           "hole_after_kerf", "lengths", "topology", "modes", "module_map",
                           "same_layer", "screws_close"}
    assert checks["screws_close"]["ok"] and checks["screws_close"]["value"] >= 0
    assert checks["lengths"]["value"] <= 1e-6
    assert checks["modes"]["value"] == 1
    assert checks["module_map"]["value"] <= 1e-6 * design.network.size
    assert checks["same_layer"]["value"] >= 0.5          # clearance / 2
    bom = json.loads((folder / "laser_bom.json").read_text())
    assert bom["motion"]["max_node_step_mm"] <= 0.5
    assert "as_built_check" not in report  # the exporter does not check itself


def test_expected_layers_and_screws(exported):
    layers = {k: exported[k][3]["layers"] for k in DESIGNS}
    assert layers["fourbar"]["count"] == 3 == layers["fourbar"]["lower_bound"]
    assert layers["super_stable"]["count"] == 3 == layers["super_stable"]["lower_bound"]
    for k in DESIGNS:
        report = exported[k][3]
        n_screws = sum(s["count"] for s in report["screws"])
        assert n_screws == len(report["joints"])
        for j in report["joints"]:
            assert j["screw_length_mm"] >= j["stack_mm"] + 0.1
            assert j["stack_mm"] == pytest.approx(3.0 * len(j["bottom_to_top"]))
            assert j["spacers"] == j["bottom_to_top"].count("spacer")
    md = (exported["super_stable"][1] / "laser_bom.md").read_text()
    # the screw table names the series as sold, never "M4-chicago chicago"
    assert "## Screws" in md and "| Chicago screw (sex bolt) M4, barrel 5 mm, head 10 mm |" in md
    assert "chicago chicago" not in md and "Series: Chicago screws (book screws" in md
    # the wording follows the typed proof: three layers meet the clique bound
    assert layers["super_stable"]["proven_minimal"] is True
    assert "3 layers (proven minimal)." in md


def test_identical_input_gives_identical_bytes():
    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    a = export_design(design, {"laser": {"labels": "none"}}).files
    b = export_design(design, {"laser": {"labels": "none"}}).files
    assert sorted(a) == sorted(b)
    for name in a:
        assert a[name] == b[name], name
    text = a["laser_sheet1.dxf"].decode()
    assert "$TDCREATE" in text and "$TDCREATE\n 40\n2451545.0\n" in text   # 2000-01-01, not the clock
    assert "0.0 @ 2000-01-01T00:00:00" in text


def test_line_arc_flavour_and_text_outlines(tmp_path):
    design = fabkit.load_template(TEMPLATES / "super_stable.toml")
    paths, report = export(design, "dxf", tmp_path,
                           laser={"flavour": "line-arc", "labels": "outlines"})
    doc = ezdxf.readfile(tmp_path / "laser_sheet1.dxf")
    msp = doc.modelspace()
    assert len(msp.query("LWPOLYLINE[layer=='CUT']")) == 0
    arcs = msp.query("ARC[layer=='CUT']")
    lines = msp.query("LINE[layer=='CUT']")
    assert len(arcs) == 2 * 6 and len(lines) == 2 * 6
    assert len(msp.query("TEXT")) == 0                        # labels drawn as glyph outlines
    assert len(msp.query("LWPOLYLINE[layer=='ENGRAVE']")) > 20
    result = check_file(tmp_path / "laser_sheet1.dxf", design=design)
    assert result["ok"]


def test_kerf_zero_and_check_catches_a_tampered_file(tmp_path):
    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    files = export_design(design, {"laser": {"kerf": 0.0}}).files
    text = files["laser_sheet1.dxf"].decode()
    assert check_documents({"s.dxf": text}, design=design, settings={"laser": {"kerf": 0.0}})["ok"]
    # move one hole centre by 0.01 mm: the length check must fail
    doc = ezdxf.read(io.StringIO(text))
    hole = doc.modelspace().query("CIRCLE[layer=='CUT_INNER']")[0]
    c = hole.dxf.center
    hole.dxf.center = (c.x + 0.01, c.y, 0)
    buf = io.StringIO()
    doc.write(buf)
    result = check_documents({"s.dxf": buf.getvalue()}, design=design,
                             settings={"laser": {"kerf": 0.0}})
    bad = {c["name"] for c in result["checks"] if not c["ok"]}
    assert not result["ok"] and {"lengths", "holes_centred", "module_map"} <= bad
    assert result["checks"][[c["name"] for c in result["checks"]].index("lengths")]["value"] \
        == pytest.approx(0.01, abs=1e-9)


def test_check_without_design_and_on_garbage(tmp_path, exported):
    _, folder, _, _ = exported["fourbar"]
    result = check_file(folder / "laser_sheet1.dxf")
    # what the file alone cannot say is named as not checked, not reported as a check passed
    assert result["ok"] and "lengths" in result["not_checked"]
    assert not any(c["name"] in ("design", "lengths", "modes") for c in result["checks"])
    junk = tmp_path / "junk.dxf"
    junk.write_bytes(b"\x00\x01 not a dxf")
    from fabkit.errors import InputFileError

    with pytest.raises(InputFileError) as info:  # a user's file ezdxf cannot read: damaged
        check_file(junk)
    assert info.value.kind == "damaged"


def test_cli_export_to_dxf(tmp_path, capsys):
    from fabkit.cli import main

    code = main(["export", str(TEMPLATES / "fourbar.toml"), "--to", "dxf", "-o", str(tmp_path),
                 "--tolerance-samples", "0", "--set", "laser.kerf=0.2"])
    assert code == 0, capsys.readouterr().err
    sheets = list(tmp_path.rglob("laser_sheet1.dxf"))
    assert len(sheets) == 1
    doc = ezdxf.readfile(sheets[0])
    assert doc.header.custom_vars.get("FABKIT_KERF") == "0.2"
    code = main(["export", str(TEMPLATES / "fourbar.toml"), "--to", "dxf", "-o",
                 str(tmp_path / "bad"), "--tolerance-samples", "0", "--set", "laser.kerf=-1"])
    err = capsys.readouterr().err
    assert code == 2 and "--set: laser.kerf: must be >= 0, got -1" in err  # a usage error
    assert not list((tmp_path / "bad").rglob("*.dxf"))



def test_polylines_given_as_one_array_write_the_bytes_of_ezdxf_s_own_vertex_by_vertex():
    # the writer hands ezdxf a polyline's vertices as one array; ezdxf's add_lwpolyline, which
    # appends them one at a time, must write the same file: no vertex, one, bulges of both
    # signs, coordinates that need all 17 digits
    from fabkit.writers.dxf import _add_polyline

    rng = np.random.default_rng(3)
    polylines = [np.zeros((0, 2)), np.array([[1.5, 2.25]]), rng.normal(0, 300, (40, 2)),
                 np.column_stack([rng.normal(0, 1, (7, 2)), [0.5, 0, -0.25, 1, 0, -1, 1e-9]])]

    def written(add) -> str:
        fixed = ezdxf.options.write_fixed_meta_data_for_testing
        ezdxf.options.write_fixed_meta_data_for_testing = True  # no clock, no random GUIDs
        try:
            doc = ezdxf.new("R2010", setup=False)
            for p in polylines:
                add(doc.modelspace(), p)
            out = io.StringIO()
            doc.write(out)
        finally:
            ezdxf.options.write_fixed_meta_data_for_testing = fixed
        return out.getvalue()

    ours = written(lambda msp, p: _add_polyline(msp, p, "CUT"))
    theirs = written(lambda msp, p: msp.add_lwpolyline(
        p.tolist(), format="xyb" if p.shape[1] == 3 else "xy", close=True,
        dxfattribs={"layer": "CUT"}))
    # (a polyline of no vertex is left out of the file by ezdxf, ours as its own)
    back = [e.get_points("xyb") for e in ezdxf.read(io.StringIO(ours)).modelspace()]
    assert [len(p) for p in back] == [1, 40, 7]
    assert [b for *_, b in back[2]] == [0.5, 0, -0.25, 1, 0, -1, 1e-9]
    assert ours == theirs
