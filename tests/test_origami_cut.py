"""The cut-ready origami sheet: creases as perforations with their dash and gap in mm, stopping
short of every vertex, mountain and valley on layers of their own, the outline as a cut; measured
against the crease pattern SVG written with it."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import fabkit
from fabkit.writers import export

from conftest import TEMPLATES

SVG = "{http://www.w3.org/2000/svg}"
INK = "{http://www.inkscape.org/namespaces/inkscape}"
#: Coordinates are written with 4 decimals.
ROUND = 2e-4


@pytest.fixture(scope="module")
def design():
    return fabkit.load_template(TEMPLATES / "origami_sheet.toml")


def _write(design, folder, **origami):
    _, report = export(design, "svg", folder, **({"origami": origami} if origami else {}))
    return report


def _cuts(path_d: str) -> np.ndarray:
    """(K, 2, 2) segments of a path of 'M x y L x y' cuts."""
    nums = [float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", path_d)]
    assert path_d.count("M") == path_d.count("L") == len(nums) // 4
    return np.array(nums).reshape(-1, 2, 2)


def _layers(root):
    return {g.get("id"): g for g in root.findall(f"{SVG}g")}


def _creases(folder, name):
    """Crease lines of the crease-pattern SVG by colour: (a, b) endpoints in drawing mm."""
    root = ET.parse(folder / name).getroot()
    out = {}
    for ln in root.findall(f"{SVG}line"):
        p = np.array([[float(ln.get("x1")), float(ln.get("y1"))],
                      [float(ln.get("x2")), float(ln.get("y2"))]])
        out.setdefault(ln.get("stroke"), []).append(p)
    return out


def _on(seg, crease, tol=1e-3):
    """A cut lies on the crease's line, between its ends."""
    a, b = crease
    u = (b - a) / np.linalg.norm(b - a)
    n = np.array([-u[1], u[0]])
    return all(abs(np.dot(p - a, n)) < tol and -tol <= np.dot(p - a, u) <= np.linalg.norm(b - a)
               + tol for p in seg)


def test_layers_in_cutting_order_with_their_perforation(design, tmp_path):
    report = _write(design, tmp_path)
    root = ET.parse(tmp_path / "origami_sheet_cut.svg").getroot()
    assert root.get("width") == "170mm" and root.get("viewBox") == "0 0 170 170"
    groups = root.findall(f"{SVG}g")
    assert [g.get("id") for g in groups] == ["engrave", "valley-perforations",
                                            "mountain-perforations", "outline"]
    assert all(g.get(f"{INK}groupmode") == "layer" for g in groups)
    assert groups[1].get(f"{INK}label") == "valley perforations (2 mm cut, 1 mm gap)"
    colours = [g.find(f"{SVG}path").get("stroke") for g in groups[1:]]
    # no cut is black: black is the engraving (filled marks), as on the laser sheets
    assert colours == ["#0000ff", "#ff0000", "#ff00ff"]
    assert not root.findall(f".//{SVG}text")  # nothing a cutter would cut as letters
    assert report["cut_file"] == "origami_sheet_cut.svg"
    assert report["cut"]["perforation"] == {"dash_mm": 2.0, "gap_mm": 1.0, "stop_mm": 3.0}


def test_perforations_stop_short_of_every_vertex(design, tmp_path):
    report = _write(design, tmp_path)
    creases = _creases(tmp_path, "origami_sheet.svg")
    root = ET.parse(tmp_path / "origami_sheet_cut.svg").getroot()
    layers = _layers(root)
    vertices = np.unique(np.round(np.concatenate([np.concatenate(v) for v in creases.values()]),
                                  4), axis=0)
    assert len(vertices) == 5  # A, B, C, D and P
    for layer, colour, n_creases in (("valley-perforations", "#0000ff", 3),
                                     ("mountain-perforations", "#ff0000", 1)):
        cuts = _cuts(layers[layer].find(f"{SVG}path").get("d"))
        lines = creases[colour]
        assert len(lines) == n_creases
        # every cut is 2 mm long and lies on a crease of its own kind
        assert np.allclose(np.linalg.norm(cuts[:, 1] - cuts[:, 0], axis=1), 2.0, atol=ROUND)
        owner = [next(k for k, c in enumerate(lines) if _on(s, c)) for s in cuts]
        for k, (a, b) in enumerate(lines):
            mine = cuts[np.array(owner) == k]
            u = (b - a) / np.linalg.norm(b - a)
            t = np.sort(np.concatenate([mine @ u]) - a @ u, axis=1)
            t = t[np.argsort(t[:, 0])]
            # 1 mm of paper between consecutive cuts
            assert np.allclose(t[1:, 0] - t[:-1, 1], 1.0, atol=ROUND)
            # and at least 3 mm whole at both ends, at most half a period more
            length = np.linalg.norm(b - a)
            ends = [t[0, 0], length - t[-1, 1]]
            assert min(ends) >= 3.0 - ROUND and max(ends) <= 3.0 + 1.5 + ROUND
            assert abs(ends[0] - ends[1]) < ROUND  # centred
        # no cut comes within 3 mm of any vertex (the crease vertex P included)
        p = vertices[:, None, None, :]
        a, b = cuts[None, :, 0][:, :, None], cuts[None, :, 1][:, :, None]
        ab = b - a
        tt = np.clip(np.sum((p - a) * ab, -1) / np.sum(ab * ab, -1), 0, 1)
        gap = np.linalg.norm(p - (a + tt[..., None] * ab), axis=-1).min()
        assert gap >= 3.0 - ROUND
    assert report["cut"]["closest_cut_to_a_vertex_mm"] == pytest.approx(3.0165, abs=1e-3)


def test_the_outline_is_one_closed_cut_around_the_sheet(design, tmp_path):
    _write(design, tmp_path)
    creases = _creases(tmp_path, "origami_sheet.svg")
    root = ET.parse(tmp_path / "origami_sheet_cut.svg").getroot()
    d = _layers(root)["outline"].find(f"{SVG}path").get("d")
    assert d.startswith("M") and d.endswith("Z") and d.count("M") == 1
    corners = np.array([float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", d)]).reshape(-1, 2)
    assert len(corners) == 4
    sides = np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1)
    assert np.allclose(sides, 150 / np.sqrt(2), atol=1e-3)  # the 106.07 mm square
    edges = np.concatenate(creases["#000000"])
    assert all(np.min(np.linalg.norm(edges - c, axis=1)) < 1e-3 for c in corners)


def test_dash_gap_and_stop_are_settings_and_short_creases_are_named(design, tmp_path):
    report = _write(design, tmp_path / "a", perforation_dash=5.0, perforation_gap=2.0,
                    perforation_stop=8.0)
    root = ET.parse(tmp_path / "a" / "origami_sheet_cut.svg").getroot()
    cuts = _cuts(_layers(root)["valley-perforations"].find(f"{SVG}path").get("d"))
    assert np.allclose(np.linalg.norm(cuts[:, 1] - cuts[:, 0], axis=1), 5.0, atol=ROUND)
    assert report["cut"]["closest_cut_to_a_vertex_mm"] >= 8.0
    # B-P is 53.0 mm: with 30 mm left whole at both ends there is no room for a 5 mm cut
    report = _write(design, tmp_path / "b", perforation_dash=5.0, perforation_stop=30.0)
    assert report["cut"]["short_creases"] == ["B–P"]
    with pytest.raises(fabkit.SettingsError, match=r"origami.perforation_stop: must be > 0"):
        _write(design, tmp_path / "c", perforation_stop=0.0)
    assert not (tmp_path / "c").exists()


#: origami_chain12's sheet_size: each sheet 100 mm corner to corner
SHEET_SIZE_MM = 100.0
#: the SVG's coordinates carry 4 decimals (and the outline's corners are printed to 0.1 mm)
ROUND_MM = 0.1


def test_a_chain_of_sheets_is_cut_sheet_by_sheet(tmp_path):
    """The twelve sheets on pages of A4 (the default medium), each page's cut file the same
    sheets at the same places as its layout, and a thread hole at every joined corner, clear
    of the perforations and inside its sheet."""
    from shapely.geometry import Point, Polygon

    chain = fabkit.load_template(TEMPLATES / "origami_chain12.toml")
    report = _write(chain, tmp_path)
    assert report["cut_files"][0] == "origami_chain12_cut.svg" == report["cut_file"]
    assert report["cut"]["cuts"]["outline"] == 12
    assert report["cut"]["closest_cut_to_a_vertex_mm"] >= 3.0
    outlines = holes = 0
    for layout_name, cut_name in zip(report["layout_files"], report["cut_files"]):
        root = ET.parse(tmp_path / cut_name).getroot()
        # every page is A4, portrait
        assert (root.get("width"), root.get("height")) == ("210mm", "297mm")
        layers = _layers(root)
        d = layers["outline"].find(f"{SVG}path").get("d")
        assert d.count("M") == d.count("Z")
        outlines += d.count("Z")
        # the same sheets as the layout, at the same places
        layout = _creases(tmp_path, layout_name)
        corners = np.array([float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", d)]).reshape(-1, 2)
        edges = np.concatenate(layout["#000000"])
        assert all(np.min(np.linalg.norm(edges - c, axis=1)) < 1e-3 for c in corners)
        assert corners.min() >= 0 and corners[:, 0].max() <= 210 and corners[:, 1].max() <= 297
        sheets = [Polygon(np.array([float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", part)])
                          .reshape(-1, 2)) for part in d.split("Z") if part.strip()]
        # every sheet cut at the size the template asks (sheet_size: corner to corner), however
        # it is turned on the page (it was once drawn 1/sqrt(2) too small once turned upright)
        for sh in sheets:
            ring = np.asarray(sh.exterior.coords)
            diameter = np.max(np.linalg.norm(ring[:, None] - ring[None], axis=-1))
            assert diameter == pytest.approx(SHEET_SIZE_MM, abs=ROUND_MM)
        perf = np.concatenate([_cuts(layers[k].find(f"{SVG}path").get("d"))
                               for k in ("valley-perforations", "mountain-perforations")])
        for c in layers["join-holes"].findall(f"{SVG}circle"):
            holes += 1
            centre, r = Point(float(c.get("cx")), float(c.get("cy"))), float(c.get("r"))
            assert r == pytest.approx(0.6)
            # inside a sheet, at least 0.9 mm of paper to its edge
            assert any(sh.contains(centre) and sh.exterior.distance(centre) - r >= 0.9
                       for sh in sheets)
            # and no perforation cuts into it
            gap = min(Point(a).distance(centre) if np.allclose(a, b) else
                      _seg_point(a, b, centre) for a, b in perf)
            assert gap > r
    assert outlines == 12
    # 23 joins of 2-4 corners each (sheet 1 corner B and sheet 2 corner A, ...)
    assert holes == sum(len(j["corners"]) for j in report["joins"]) == 46


def _seg_point(a, b, p) -> float:
    from shapely.geometry import LineString

    return LineString([a, b]).distance(p)


def _polys(d: str) -> list:
    """Closed polylines of a path of 'M x y L x y ... Z' parts (drawing mm)."""
    return [np.array([float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", part)]).reshape(-1, 2)
            for part in d.split("Z") if part.strip()]


def _check_marks(root, want_joins: bool) -> dict:
    """Every sheet of a cut page carries its engraved marks: filled, in a colour no cut has,
    inside its own sheet and at least 0.9 mm clear of every cut. Returns the marks' texts per
    sheet (read from each mark's title)."""
    from shapely.geometry import LineString, Polygon
    from shapely.ops import unary_union

    layers = _layers(root)
    engrave = layers["engrave"]
    cut_colours = {el.get("stroke") for k, g in layers.items() if k != "engrave"
                   for el in g.iter() if el.get("stroke") not in (None, "none")}
    sheets = _polys(layers["outline"].find(f"{SVG}path").get("d"))
    sheet_polys = [Polygon(s) for s in sheets]
    perf = np.concatenate([_cuts(layers[k].find(f"{SVG}path").get("d"))
                           for k in ("valley-perforations", "mountain-perforations")])
    cuts = unary_union([LineString(s) for s in perf] + [p.exterior for p in sheet_polys]
                       + [LineString([(float(c.get("cx")) + float(c.get("r")) * np.cos(t),
                                       float(c.get("cy")) + float(c.get("r")) * np.sin(t))
                                      for t in np.linspace(0, 2 * np.pi, 33)])
                          for c in (layers["join-holes"].findall(f"{SVG}circle")
                                    if "join-holes" in layers else [])])
    texts = {}
    marks = engrave.findall(f"{SVG}path")
    assert marks
    for m in marks:
        assert m.get("fill") not in cut_colours and m.get("stroke") == "none"
        glyphs = _polys(m.get("d"))
        pts = np.concatenate(glyphs)
        box = Polygon([pts.min(axis=0), (pts[:, 0].max(), pts[:, 1].min()), pts.max(axis=0),
                       (pts[:, 0].min(), pts[:, 1].max())])
        owner = [k for k, sh in enumerate(sheet_polys) if sh.contains(box)]
        assert len(owner) == 1, m.get("id")  # inside exactly one sheet
        assert box.distance(cuts) >= 0.9, m.get("id")  # clear of every cut
        texts.setdefault(owner[0], []).append(m.find(f"{SVG}title").text)
    assert sorted(texts) == list(range(len(sheets)))  # every sheet has marks
    for got in texts.values():
        assert "FRONT" in got and any(t.startswith("sheet ") for t in got)
        corners = sorted(t for t in got if t[0] in "ABCD")
        assert [c[0] for c in corners] == ["A", "B", "C", "D"]
        if want_joins:  # the joined corners carry their join numbers
            assert sum("·" in c for c in corners) >= 3
    # no two marks overlap
    boxes = []
    for m in marks:
        pts = np.concatenate(_polys(m.get("d")))
        boxes.append(Polygon([pts.min(axis=0), (pts[:, 0].max(), pts[:, 1].min()),
                              pts.max(axis=0), (pts[:, 0].min(), pts[:, 1].max())]))
    assert all(not a.intersects(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])
    return texts


def test_the_sheet_cut_file_engraves_its_corners_and_front(design, tmp_path):
    report = _write(design, tmp_path)
    root = ET.parse(tmp_path / "origami_sheet_cut.svg").getroot()
    texts = _check_marks(root, want_joins=False)
    assert sorted(texts[0]) == ["A", "B", "C", "D", "FRONT", "sheet 1"]
    assert report["cut"]["marks"] == [{"sheet": 1, "texts": ["sheet 1", "FRONT", "A", "B", "C",
                                                             "D"], "unplaced": []}]
    # FRONT is not mirrored: read left to right its first glyph (F) lies left of its last (T)
    front = _layers(root)["engrave"].find(f"{SVG}path[@id='sheet1-front']")
    glyphs = _polys(front.get("d"))
    assert glyphs[0][:, 0].mean() < glyphs[-1][:, 0].mean()
    assert "FRONT" in root.find(f"{SVG}desc").text


def test_every_sheet_of_the_chain_keeps_its_number_corners_and_joins_when_cut(tmp_path):
    chain = fabkit.load_template(TEMPLATES / "origami_chain12.toml")
    report = _write(chain, tmp_path)
    marks = {}
    for name in report["cut_files"]:
        texts = _check_marks(ET.parse(tmp_path / name).getroot(), want_joins=True)
        for got in texts.values():
            number = next(int(t.split()[1]) for t in got if t.startswith("sheet "))
            marks[number] = got
    assert sorted(marks) == list(range(1, 13))
    # the corners of one join carry one number, as the template joins them (sheet k+1's B on
    # sheet k's C, its A on sheet k-1's C): join 2 is sheet 1's C, sheet 2's B, sheet 3's A
    assert "C·2" in marks[1] and "B·2" in marks[2] and "A·2" in marks[3]
    assert all(not m["unplaced"] for m in report["cut"]["marks"])
