"""SVG, FOLD and ORIPA files of the origami sheet, read back and re-folded."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import fabkit
from fabkit.check import check_file
from fabkit.writers import export, get_exporter
from conftest import ROOT, TEMPLATES

SVG = "{http://www.w3.org/2000/svg}"
COLOURS = {"B": "#000000", "M": "#ff0000", "V": "#0000ff"}
D2_STAR = 2.0 - np.sqrt(2.0)


@pytest.fixture(scope="module")
def design():
    return fabkit.load_template(TEMPLATES / "origami_sheet.toml")


@pytest.fixture(scope="module")
def files(design, tmp_path_factory):
    out = tmp_path_factory.mktemp("origami")
    reports = {}
    for fmt in ("svg", "fold", "cp"):
        _, reports[fmt] = export(design, fmt, out)
    return out, reports


def test_exporters_apply_only_to_origami(design):
    plain = fabkit.load_template(TEMPLATES / "fourbar.toml")
    for fmt in ("svg", "fold", "cp"):
        mod = get_exporter(fmt)
        assert mod.FORMAT == fmt and mod.applies(design) and not mod.applies(plain)


def test_fold_file_fields_and_frames(files, design):
    out, _ = files
    doc = json.loads((out / "origami_sheet.fold").read_text())
    assert doc["file_spec"] == 1.2 and doc["frame_unit"] == "mm"
    assert doc["frame_classes"] == ["creasePattern"]
    assert doc["edges_vertices"] == design.network.edges.tolist()
    assert doc["edges_assignment"] == ["B", "B", "B", "B", "V", "V", "V", "M"]
    angles = np.array(doc["edges_foldAngle"])
    assert np.all(angles[:4] == 0) and np.all(angles[4:7] > 0) and angles[7] < 0
    assert angles[4] == pytest.approx(165.42076586, abs=1e-6)
    assert angles[5] == pytest.approx(131.06039896, abs=1e-6)
    # faces counter-clockwise in the crease pattern
    v = np.array(doc["vertices_coords"])
    for f in doc["faces_vertices"]:
        p = v[f]
        area = 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
        assert area > 0
    # mm: the bounding box's larger side is the sheet size
    assert np.ptp(v, axis=0).max() == pytest.approx(150.0)
    frames = doc["file_frames"]
    assert len(frames) == 41
    first = np.array(frames[0]["vertices_coords"])
    last = np.array(frames[-1]["vertices_coords"]) / doc["fabkit:scale"]
    assert np.allclose(first[:, 2], 0.0)
    assert np.linalg.norm(last[1] - last[3]) == pytest.approx(D2_STAR, abs=1e-9)
    assert np.linalg.norm(last[0] - last[2]) == pytest.approx(D2_STAR, abs=1e-9)
    assert frames[-1]["edges_foldAngle"] == doc["edges_foldAngle"]
    assert doc["fabkit:motion"]["branch"] == 2 and len(doc["fabkit:motion"]["branches"]) == 2


def test_svg_colours_opacity_and_creases_direct_children(files):
    out, _ = files
    root = ET.parse(out / "origami_sheet.svg").getroot()
    doc = json.loads((out / "origami_sheet.fold").read_text())
    assert root.tag == SVG + "svg" and root.get("width") == "170mm"
    # Origami Simulator reads only direct children: the creases; the legend, dimension and
    # labels are groups it ignores
    lines = [c for c in root if c.tag == SVG + "line"]
    assert len(lines) == 8 and all(c.tag in (SVG + "line", SVG + "title", SVG + "g") for c in root)
    assert {g.get("id") for g in root.findall(f"{SVG}g")} == {"legend", "fold-angles",
                                                              "vertex-labels", "dimensions"}
    assert all(line.get("opacity") is None for line in lines)
    for line, lab, ang in zip(lines, doc["edges_assignment"], doc["edges_foldAngle"]):
        assert line.get("stroke") == COLOURS[lab]
        want = abs(ang) / 180.0 if lab in "MV" else 1.0
        assert float(line.get("stroke-opacity")) == pytest.approx(want, abs=1e-4)
    # the crease vertex P: all four creases meet at one point, 10 mm margin
    ends = {(line.get("x2"), line.get("y2")) for line in lines[4:]}
    assert len(ends) == 1


def test_mountain_and_valley_differ_by_dash_pattern_as_well_as_colour(files):
    out, _ = files
    root = ET.parse(out / "origami_sheet.svg").getroot()
    lines = [c for c in root if c.tag == SVG + "line"]
    dash = {lab: {line.get("stroke-dasharray") for line, a in zip(lines, "BBBBVVVM") if a == lab}
            for lab in "BVM"}
    assert dash["B"] == {None}  # the edge: solid
    (valley,), (mountain,) = dash["V"], dash["M"]
    v = [float(x) for x in valley.split()]
    m = [float(x) for x in mountain.split()]
    # valley dashed (dash, gap); mountain dash-dot (dash, gap, dot, gap): in black and white too
    assert len(v) == 2 and len(m) == 4 and m[2] < m[0] / 2
    # the legend shows the same three styles, each with what it means
    legend = root.find(f"{SVG}g[@id='legend']")
    samples = {ln.get("stroke"): ln.get("stroke-dasharray") for ln in legend.findall(f"{SVG}line")}
    assert samples == {"#000000": None, "#0000ff": valley, "#ff0000": mountain}
    texts = [t.text for t in legend.findall(f"{SVG}text")]
    assert any(t.startswith("valley fold (dashed)") for t in texts)
    assert any(t.startswith("mountain fold (dash-dot)") for t in texts)


def test_svg_states_the_side_length_and_the_fold_angle_of_every_named_crease(files):
    out, reports = files
    root = ET.parse(out / "origami_sheet.svg").getroot()
    legend = [t.text for t in root.find(f"{SVG}g[@id='legend']").findall(f"{SVG}text")]
    # the BOM's "150 mm" is the diagonal: the sheet is a 106.07 mm square
    assert "Sheet: square, side 106.07 mm (150.00 mm corner to corner)" in legend
    geom = reports["svg"]["sheet"]
    assert geom["shape"] == "square" and geom["side_mm"] == pytest.approx(150 / np.sqrt(2), 1e-4)
    assert geom["sides_mm"] == [pytest.approx(106.066, abs=1e-3)] * 4
    assert legend[-2:] == ["A–P valley 165.4°    B–P valley 131.1°",
                           "C–P valley 165.4°    D–P mountain 131.1°"]
    assert [(c["crease"], c["fold"], c["angle_deg"]) for c in reports["svg"]["creases"]] == [
        ("A–P", "valley", 165.42), ("B–P", "valley", 131.06), ("C–P", "valley", 165.42),
        ("D–P", "mountain", 131.06)]
    # on the sheet: each crease's angle beside it, each corner named, the side dimensioned
    beside = [t.text for t in root.find(f"{SVG}g[@id='fold-angles']")]
    assert sorted(beside) == ["M 131°", "V 131°", "V 165°", "V 165°"]
    assert [t.text for t in root.find(f"{SVG}g[@id='vertex-labels']")] == list("ABCDP")
    dim = root.find(f"{SVG}g[@id='dimensions']").find(f"{SVG}text")
    assert dim.text == "106.07 mm"


def test_cp_file(files):
    out, _ = files
    rows = [r.split() for r in (out / "origami_sheet.cp").read_text().splitlines()]
    assert [int(r[0]) for r in rows] == [1, 1, 1, 1, 3, 3, 3, 2]
    xy = np.array([[float(v) for v in r[1:]] for r in rows])
    assert np.abs(xy).max() == pytest.approx(75.0)


def test_fold_round_trip_refolds_to_the_same_map(files, design):
    out, _ = files
    report = check_file(out / "origami_sheet.fold", design=design)
    assert report["ok"], report["checks"]
    checks = {c["name"]: c for c in report["checks"]}
    assert checks["refold_map"]["value"] < 1e-8
    assert checks["design_map"]["value"] < 1e-8
    assert checks["modes"]["value"] == 1
    assert report["branch"] == 2 and report["flat_foldable"] is True


def test_fold_check_catches_a_tampered_file(files, tmp_path):
    out, _ = files
    doc = json.loads((out / "origami_sheet.fold").read_text())
    doc["vertices_coords"][4][1] += 3.0  # move the crease vertex by 3 mm
    bad = tmp_path / "moved.fold"
    bad.write_text(json.dumps(doc))
    report = check_file(bad)
    checks = {c["name"]: c for c in report["checks"]}
    # the frames no longer keep the root's edge lengths, and the moved sheet cannot fold to D2*
    assert not report["ok"] and checks["frames_keep_lengths"]["value"] > 1e-3
    assert not checks["refold_map"]["ok"] and "turning point" in checks["refold_map"]["detail"]
    doc["edges_assignment"][5] = "Q"
    bad.write_text(json.dumps(doc))
    report = check_file(bad)
    assert not report["ok"]
    assert report["checks"][0]["detail"] == ("edges_assignment[5]: must be one of 'B', 'M', 'V', "
                                             "'F', 'U', 'C' or 'J', got 'Q'")
    (tmp_path / "cut.fold").write_text((out / "origami_sheet.fold").read_text()[:300])
    with pytest.raises(fabkit.FabkitError, match="not FOLD JSON"):
        check_file(tmp_path / "cut.fold")


def test_bad_settings_write_nothing(design, tmp_path):
    with pytest.raises(fabkit.SettingsError, match=r"origami.sheet_size: must be > 0, got -5"):
        export(design, "fold", tmp_path, origami={"sheet_size": -5})
    with pytest.raises(fabkit.SettingsError, match="origami.sheetsize: unknown key; known: "):
        export(design, "svg", tmp_path, origami={"sheetsize": 100})
    assert list(tmp_path.iterdir()) == []


def test_assignment_against_the_named_branch(design, tmp_path):
    # naming branch 1 (the diagonal fold) with drive d1 cannot work: d1 does not move there
    with pytest.raises(fabkit.FabricationError, match="towards the target"):
        export(design, "fold", tmp_path, origami={"branch": 1})
    assert list(tmp_path.iterdir()) == []


def _node_fold():
    node = shutil.which("node")
    folder = Path(os.environ.get("FABKIT_NODE_FOLD", ROOT / "out" / ".node-fold"))
    if node is None:
        return None, "node is not installed"
    if not (folder / "node_modules" / "fold" / "package.json").exists():
        return None, f"the fold npm library is not installed in {folder} (.ci/install.d/node-fold.sh)"
    return (node, folder / "node_modules"), ""


READER = r"""
const FOLD = require('fold');
const doc = JSON.parse(require('fs').readFileSync(process.argv[2], 'utf8'));
const copy = FOLD.convert.deepCopy(doc);
FOLD.convert.edges_vertices_to_vertices_vertices_sorted(copy);
FOLD.convert.faces_vertices_to_faces_edges(copy);
console.log(JSON.stringify({
  vertices: FOLD.filter.numVertices(doc), edges: FOLD.filter.numEdges(doc),
  faces: FOLD.filter.numFaces(doc), mountains: FOLD.filter.edgesAssigned(doc, 'M'),
  valleys: FOLD.filter.edgesAssigned(doc, 'V'), vertices_vertices: copy.vertices_vertices,
  faces_edges: copy.faces_edges, frames: (doc.file_frames || []).length}));
"""


def test_fold_library_reads_the_file(files, tmp_path):
    found, why = _node_fold()
    if found is None:
        pytest.skip(why)
    node, modules = found
    out, _ = files
    script = tmp_path / "reader.js"
    script.write_text(READER)
    res = subprocess.run([node, str(script), str(out / "origami_sheet.fold")], capture_output=True,
                         text=True, timeout=60, env={**os.environ, "NODE_PATH": str(modules)})
    assert res.returncode == 0, res.stderr
    got = json.loads(res.stdout)
    assert (got["vertices"], got["edges"], got["faces"], got["frames"]) == (5, 8, 4, 41)
    assert got["mountains"] == [7] and got["valleys"] == [4, 5, 6]
    assert sorted(got["vertices_vertices"][4]) == [0, 1, 2, 3]  # P meets the four corners
    assert all(len(f) == 3 for f in got["faces_edges"])


def test_fold_command_reports_bifurcation_and_writes_checked_files(tmp_path, capsys):
    from fabkit.cli import main

    code = main(["fold", str(TEMPLATES / "origami_sheet.toml"), "-o", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    assert "1 state(s) of self-stress" in out and "2 branch(es)" in out
    assert "taken        branch 2, direction +" in out
    assert "crease D-P      M  fold angle -131.0604 deg" in out
    assert "check        refold_map: ok" in out
    names = sorted(p.name for p in (tmp_path / "origami_sheet").iterdir())
    assert names == ["origami_sheet.cp", "origami_sheet.fold", "origami_sheet.svg",
                     "origami_sheet_cut.svg"]


def test_fold_command_folds_once_for_its_summary_and_every_file(tmp_path, capsys,
                                                                 monkeypatch):
    """The summary and the SVG, FOLD and .cp files are drawn from one origami plan: the
    sheet is folded once (it was folded for the summary, then once more per format)."""
    import fabkit.fab.creases.plan as plan
    from fabkit.cli import main

    folds = []
    real = plan.fold_model
    monkeypatch.setattr(plan, "fold_model", lambda *a, **k: folds.append(1) or real(*a, **k))
    code = main(["fold", str(TEMPLATES / "origami_sheet.toml"), "--branch", "2", "-o",
                 str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0 and "taken        branch 2" in out
    assert len(folds) == 1
    assert len(list((tmp_path / "origami_sheet").iterdir())) == 4


def test_fold_command_errors_are_one_line(tmp_path, capsys):
    from fabkit.cli import main

    bad = tmp_path / "bad_sheet.toml"
    text = (TEMPLATES / "origami_sheet.toml").read_text()
    bad.write_text(text.replace('"V", "V", "V", "M"]', '"V", "V", "M"]'))
    code = main(["fold", str(bad), "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 1 and "\n" not in err
    assert "bad_sheet.toml: fabrication.origami.assignment" in err and "8 network edges" in err
    assert not (tmp_path / "out").exists()
    code = main(["fold", str(TEMPLATES / "fourbar.toml")])
    err = capsys.readouterr().err.strip()
    assert code == 1 and err.endswith("the template has no [fabrication.origami] table")


def test_named_branch_writes_the_assignment_it_folds(design, tmp_path):
    from dataclasses import replace

    diag = replace(design, motion=replace(design.motion, drive="d2", to=1.0))
    _, rep = export(diag, "fold", tmp_path, origami={"branch": 1, "sign": 1})
    export(diag, "cp", tmp_path, origami={"branch": 1, "sign": 1})
    doc = json.loads((tmp_path / "origami_sheet.fold").read_text())
    # folding along the diagonal BD: PB and PD fold as valleys by 90 degrees, PA and PC stay flat
    assert doc["edges_assignment"] == ["B", "B", "B", "B", "U", "V", "U", "V"]
    assert doc["edges_foldAngle"][5] == pytest.approx(90.0, abs=1e-6)
    assert rep["branch"] == 1 and rep["assignment_changed"] == [4, 6, 7]
    rows = (tmp_path / "origami_sheet.cp").read_text().split("\n")
    assert [r.split()[0] for r in rows if r] == ["1", "1", "1", "1", "3", "3"]
    report = check_file(tmp_path / "origami_sheet.fold")
    assert report["ok"] and report["branch"] == 1
    # PA and PC stay flat (U): the folds at P are PB and PD, two valleys on one line, which
    # fold flat (Maekawa |0 - 2| = 2, Kawasaki 180 degrees either side)
    checks = {c["name"]: c for c in report["checks"]}
    assert checks["maekawa"]["ok"] and checks["maekawa"]["value"] == []
    assert "vertex 4: 0 mountains, 2 valleys" in checks["maekawa"]["detail"]
    assert checks["kawasaki"]["ok"] and checks["kawasaki"]["value"] < 1e-12
    assert report["flat_foldable"] is True


def test_fold_check_rejects_contradicting_angles(files, tmp_path):
    out, _ = files
    doc = json.loads((out / "origami_sheet.fold").read_text())
    doc["edges_assignment"][7] = "V"  # PD folds as a mountain (negative angle)
    bad = tmp_path / "contradiction.fold"
    bad.write_text(json.dumps(doc))
    report = check_file(bad)
    assert not report["ok"] and "edge 7 is V but its fold angle" in report["checks"][0]["detail"]
