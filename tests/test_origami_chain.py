"""The 12-sheet origami chain (Fig 5g-h): joining, one motion, sequential unfolding, files."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import fabkit
from fabkit.check import check_file
from fabkit.writers import export
from fabkit.fab.creases import fold_model, origami_model, sheet_chain
from fabkit.numerics import rigid_fit
from fabkit.kinematics.branching import analyze_bifurcation, step_off
from conftest import TEMPLATES

D2_STAR = 2.0 - np.sqrt(2.0)
FLAT = np.sqrt(2.0)
SVG = "{http://www.w3.org/2000/svg}"


@pytest.fixture(scope="module")
def sheet_design():
    return fabkit.load_template(TEMPLATES / "origami_sheet.toml")


@pytest.fixture(scope="module")
def reference(sheet_design):
    net = sheet_design.network
    return step_off(net, analyze_bifurcation(net), 2, 1.0, 1e-2)  # the side of the assignment


@pytest.fixture(scope="module")
def design():
    return fabkit.load_template(TEMPLATES / "origami_chain12.toml")


def _two_corner_chain(sheet, x, copies):
    """Sheets joined by the d2/d1 corner pair only (no third node), for comparison."""
    nodes, edges, last = [x], [tuple(e) for e in sheet.edges.tolist()], list(range(5))
    n = 5
    for _ in range(copies - 1):
        allx = np.vstack(nodes)
        fit = rigid_fit(x[[0, 2, 1]], allx[[last[1], last[3], last[0]]])
        rot, shift = fit.rotation, fit.shift
        y = x @ rot.T + shift
        local = [last[1], n, last[3], n + 1, n + 2]  # A', C' shared; B', D', P' new
        nodes.append(y[[1, 3, 4]])
        n += 3
        edges += [(local[a], local[b]) for a, b in sheet.edges.tolist()]
        last = local
    return fabkit.Network(np.vstack(nodes), edges)


@pytest.mark.parametrize("copies", [2, 3, 12])
def test_three_corner_join_keeps_one_motion(sheet_design, reference, copies):
    net, maps = sheet_chain(sheet_design.network, copies, D2_STAR, reference=reference)
    assert (net.n_nodes, net.n_edges) == (3 + 2 * copies, 2 + 6 * copies)
    m = fabkit.count_modes(net)
    assert (m.conformational, m.self_stress) == (1, 0)
    # two shared corners leave a hinge about the shared diagonal at every join
    x = sheet_design.network.nodes * 0 + net.nodes[:5]
    loose = _two_corner_chain(sheet_design.network, x, copies)
    assert fabkit.count_modes(loose).conformational == copies


def test_template_is_the_generated_chain(design, sheet_design, reference):
    net, maps = sheet_chain(sheet_design.network, 12, D2_STAR, reference=reference)
    assert np.abs(design.network.nodes - net.nodes).max() < 1e-12
    assert design.network.edges.tolist() == net.edges.tolist()
    assert design.network.ports == net.ports
    assert design.fabrication["origami"]["sheets"] == maps
    # the crystal D2*: every distance of the chain at the fixed point
    for name in design.network.ports:
        assert design.network.port_distance(name) == pytest.approx(D2_STAR, abs=1e-12)


def test_unfolds_sequentially_from_sheet_one(design):
    model = origami_model(design)
    fold = fold_model(model, design.motion.drive, design.motion.to)
    assert fold.max_edge_error < 1e-12
    d = np.array([fold.ports[f"d{k}"] for k in range(1, 14)]).T  # (frames, 13)
    u = (d - D2_STAR) / (FLAT - D2_STAR)  # 0 folded, 1 flat
    assert np.all(np.diff(u, axis=1) <= 1e-12)  # at every frame: sheet k ahead of sheet k+1
    assert np.all(u[-1] > 1.0 - 1e-9)  # every sheet ends flat (the relay port resolves the end)
    half = [int(np.argmax(u[:, k] >= 0.5)) for k in range(13)]
    assert np.all(np.diff(half) > 0)  # the front passes one sheet after another, from sheet 1
    assert "handed the drive to d13" in fold.message
    # the chain's map: d_k = f(d_{k+1}) with f the sheet's map, stable fixed point at D2*
    assert u[1, 1] < 0.3 * u[1, 0]


def test_assignment_matches_the_folded_sheets(design):
    model = origami_model(design)
    angles = fold_model(model, design.motion.drive, design.motion.to, samples=2).angles[0]
    lab = np.array(model.assignment)
    assert np.all(angles[lab == "V"] > 100) and np.all(angles[lab == "M"] < -100)
    assert np.all(angles[lab == "B"] == 0)


def test_layout_svg_marks_every_join(design, tmp_path):
    """Twelve sheets of 70.7 mm on A4 pages (four a page), every corner labelled with its
    join, the join method and the joins of each page in its legend."""
    _, report = export(design, "svg", tmp_path)
    assert report["pages"] == 3 and report["sheets_per_page"] == [4, 4, 4]
    assert report["medium"] == "A4 (210 x 297 mm)"
    assert report["layout_files"] == ["origami_chain12_layout.svg",
                                      "origami_chain12_layout_p2.svg",
                                      "origami_chain12_layout_p3.svg"]
    texts, lines = [], 0
    for name in report["layout_files"]:
        root = ET.parse(tmp_path / name).getroot()
        assert (root.get("width"), root.get("height")) == ("210mm", "297mm")
        # creases are direct children (what Origami Simulator reads); the rest in groups
        assert {g.get("id") for g in root.findall(f"{SVG}g")} == {
            "fold-angles", "legend", "join-holes", "join-legend"}
        lines += len(root.findall(f"{SVG}line"))
        texts += [t.text for t in root.iter(f"{SVG}text")]
        for ln in root.findall(f"{SVG}line"):  # every crease on the page
            for k in ("x1", "x2"):
                assert 0 <= float(ln.get(k)) <= 210
            for k in ("y1", "y2"):
                assert 0 <= float(ln.get(k)) <= 297
    assert lines == 12 * 8 and sum(t.startswith("sheet ") for t in texts) == 12
    # sheet 2's corners: A at join 1 (with sheet 1's B), B at 2, C at 3, D at 4
    i = texts.index("sheet 2")
    assert sorted(texts[i + 1:i + 5]) == ["A·1", "B·2", "C·3", "D·4"]
    words = " ".join(texts)
    assert "pass a thread through their 1.2 mm holes" in words
    assert "·3 = 1D + 2C + 3B + 4A" in words
    joins = {j["join"]: j["corners"] for j in report["joins"]}
    assert joins[1] == ["1B", "2A"] and joins[3] == ["1D", "2C", "3B", "4A"]
    assert report["sheets"] == 12


def test_the_medium_is_a_setting(design, tmp_path):
    _, report = export(design, "svg", tmp_path, origami={"medium": "305x1000"})
    assert report["pages"] == 1 and report["medium"] == "305 x 1000 mm (305 x 1000 mm)"
    _, letter = export(design, "svg", tmp_path / "l", origami={"medium": "Letter"})
    assert letter["medium_mm"] == [215.9, 279.4]
    # twelve sheets need more than one Letter page, and every page holds what it says
    assert letter["pages"] == len(letter["sheets_per_page"]) >= 2
    assert sum(letter["sheets_per_page"]) == 12
    for page in sorted((tmp_path / "l").glob("*_layout*.svg")):
        root = ET.parse(page).getroot()
        for ln in root.iter(f"{SVG}line"):
            assert 0 <= min(float(ln.get("x1")), float(ln.get("x2")))
            assert max(float(ln.get("x1")), float(ln.get("x2"))) <= 215.9
            assert 0 <= min(float(ln.get("y1")), float(ln.get("y2")))
            assert max(float(ln.get("y1")), float(ln.get("y2"))) <= 279.4
    with pytest.raises(fabkit.FabricationError, match="not a medium; give A4"):
        export(design, "svg", tmp_path / "x", origami={"medium": "napkin"})
    assert not (tmp_path / "x").exists() or list((tmp_path / "x").iterdir()) == []
    with pytest.raises(fabkit.FabricationError, match="choose a larger one"):
        export(design, "svg", tmp_path / "y", origami={"medium": "60x60"})


def test_the_plan_lays_out_the_pages_and_the_writer_draws_them(design):
    # which sheet goes on which page, the join numbers and the thread holes are the origami
    # plan's (fab/creases/layout.py); the SVG writer draws them where the plan says
    from dataclasses import replace

    from fabkit.writers import svg
    from fabkit.fab.creases.layout import place
    from fabkit.fab.plans import make_plan

    plan = make_plan("origami", design)
    lay = plan.layout
    assert [p.indices for p in lay.pages] == [[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11]]
    assert lay.joins[0] == ((1, "B"), (2, "A")) and lay.numbers[1] == {0: 1, 1: 2, 2: 3, 3: 4}
    # a page lists the joins that touch its sheets: page 2 (sheets 5-8) starts with join 4
    assert lay.pages[1].joins[0][0] == 4 and lay.pages[0].joins[-1][0] < lay.pages[1].joins[-1][0]
    # every thread hole sits 2.2 mm in from the corner it holds
    first = lay.pages[0].sheets[1]
    corners = place(lay.drawn.sheets[1].pattern, lay.drawn.scale, *first.offset)
    gaps = [min(float(np.linalg.norm(np.subtract(h, c))) for c in corners) for h in first.holes]
    assert len(first.holes) == 4 and gaps == pytest.approx([2.2] * 4)
    # moved in the plan, a sheet is drawn moved: the writer decides nothing of where it goes
    page = lay.pages[0]
    moved = replace(page.sheets[0], offset=(page.sheets[0].offset[0] + 5.0,
                                            page.sheets[0].offset[1]))
    shifted = replace(plan, layout=replace(lay, pages=(replace(
        page, sheets=(moved, *page.sheets[1:])), *lay.pages[1:])))
    a = ET.fromstring(svg.write(plan).files["origami_chain12_layout.svg"])
    b = ET.fromstring(svg.write(shifted).files["origami_chain12_layout.svg"])
    xa = [float(ln.get("x1")) for ln in a.findall(f"{SVG}line")][:8]
    xb = [float(ln.get("x1")) for ln in b.findall(f"{SVG}line")][:8]
    assert np.subtract(xb, xa) == pytest.approx([5.0] * 8)


def test_chain_fold_file_round_trip(design, tmp_path):
    export(design, "fold", tmp_path)
    doc = json.loads((tmp_path / "origami_chain12.fold").read_text())
    assert doc["frame_classes"] == ["foldedForm"] and len(doc["file_frames"]) == 61
    assert len(doc["faces_vertices"]) == 48 and len(doc["vertices_coords"]) == 27
    report = check_file(tmp_path / "origami_chain12.fold", design=design)
    assert report["ok"], report["checks"]
    assert {c["name"]: c for c in report["checks"]}["refold_map"]["value"] < 1e-8


def test_cp_refuses_a_chain(design, tmp_path):
    with pytest.raises(fabkit.FabricationError, match="one sheet"):
        export(design, "cp", tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_layout_opacity_is_the_folded_crystal(design, tmp_path):
    _, report = export(design, "svg", tmp_path)
    ops = sorted({round(float(x.get("stroke-opacity")), 4)
                  for name in report["layout_files"]
                  for x in ET.parse(tmp_path / name).getroot().findall(f"{SVG}line")
                  if x.get("stroke") != "#000000"})
    assert ops == [0.7281, 0.919]  # |131.06| / 180 and |165.42| / 180 on every sheet
