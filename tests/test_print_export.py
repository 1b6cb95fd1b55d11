"""STL export of the paper's printed module and a 10-module chain, read back with trimesh."""

from __future__ import annotations

import io
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest
import trimesh

import fabkit
from fabkit.errors import SettingsError
from fabkit.writers import export, get_exporter
from fabkit.writers.stl import applies, binary_stl, export_design, stored_mesh_is_closed
from fabkit.fab.hinges import print_geometry
from fabkit.settings.printing import print_settings

from conftest import TEMPLATES

NAMES = ["printed_planar", "printed_planar_chain10"]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = {}
    for name in NAMES:
        design = fabkit.load_template(TEMPLATES / f"{name}.toml")
        folder = tmp_path_factory.mktemp(name)
        paths, report = export(design, "stl", folder)
        out[name] = (design, folder, paths, report)
    return out


@pytest.mark.parametrize("name", NAMES)
def test_one_watertight_body_with_the_analytic_volume(exported, name):
    design, folder, paths, report = exported[name]
    assert sorted(p.name for p in paths) == sorted([f"{name}.3mf", f"{name}.stl",
                                                    f"{name}_print.png", "print_bom.json",
                                                    "print_bom.md"])
    mesh = trimesh.load(folder / f"{name}.stl")
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.body_count == 1
    assert mesh.volume > 0
    # the analytic volume is recomputed here from the geometry, not taken from the report
    geo = print_geometry(design.network, print_settings(design.fabrication["print"]))
    assert abs(mesh.volume - geo.volume) / geo.volume <= 1e-6
    assert report["volume_mm3"] == pytest.approx(geo.volume, rel=1e-15)
    # millimetres: the solid spans the scaled network (turned onto the bed when it does not fit
    # as it lies) and the plate thickness
    ext = mesh.bounds[1] - mesh.bounds[0]
    assert ext[2] == pytest.approx(3.0, abs=1e-6)
    (piece,) = report["printer"]["pieces"]
    assert np.allclose(ext[:2], piece["size_mm"], atol=1e-4)
    if piece["angle_deg"] == 0:
        assert np.allclose(ext[:2], geo.size[:2], atol=1e-4)
    # the STL is centred on the 200 x 200 mm bed and keeps 5 mm from its edges
    assert np.abs(mesh.bounds[:, :2]).max() <= 100.0 - 5.0 + 1e-4
    assert report["plates"] == len(geo.triangles)


def test_the_bare_stl_fits_the_bed_turned():
    # 207 mm long as designed: turned by 38 degrees, it fits PrusaSlicer's 200 x 200 mm bed
    # 13.8 mm from its edges (the 10 mm kept free, and the skirt 3 mm out with its loop)
    design = fabkit.load_template(TEMPLATES / "printed_planar_chain10.toml")
    res = export_design(design, {"print": {"preview": False}})
    mesh = trimesh.load(io.BytesIO(res.files["printed_planar_chain10.stl"]), file_type="stl")
    ext = mesh.bounds[1] - mesh.bounds[0]
    assert res.report["size_mm"][0] > 200.0
    assert res.report["printer"]["parts_margin_mm"] == pytest.approx(13.8)
    assert ext[0] == pytest.approx(172.11, abs=0.01) and ext[1] == pytest.approx(139.01, abs=0.01)
    assert ext.max() <= 200.0 - 2 * 13.8
    assert res.report["printer"]["pieces"][0]["angle_deg"] == 38.0


def test_chain_dimensions(exported):
    design, folder, paths, report = exported["printed_planar_chain10"]
    assert report["plates"] == 40
    assert report["hinges"] == 58  # 4 per module + 2 between consecutive modules: 40 + 18
    # ten modules of 5.2 units at 4 mm per unit, plus the hinge hubs and plate insets
    assert 206.0 < report["size_mm"][0] < 210.0
    assert report["warnings"] == []


def test_binary_stl_layout(exported):
    _, folder, _, report = exported["printed_planar"]
    data = (folder / "printed_planar.stl").read_bytes()
    count = int(np.frombuffer(data[80:84], dtype="<u4")[0])
    assert count == report["mesh"]["triangles"]
    assert len(data) == 84 + 50 * count
    assert not data[:5].lower().startswith(b"solid")  # readers would take it for ASCII
    assert b"mm" in data[:80]


def test_threemf_holds_the_same_mesh_in_millimetres(exported):
    _, folder, _, report = exported["printed_planar"]
    with zipfile.ZipFile(folder / "printed_planar.3mf") as z:
        assert set(z.namelist()) == {"[Content_Types].xml", "_rels/.rels", "3D/3dmodel.model",
                                     "Metadata/Slic3r_PE.config",
                                     "Metadata/Slic3r_PE_model.config"}
        root = ET.fromstring(z.read("3D/3dmodel.model"))
    ns = {"m": "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"}
    assert root.get("unit") == "millimeter"
    verts = root.findall(".//m:vertex", ns)
    tris = root.findall(".//m:triangle", ns)
    assert len(verts) == report["mesh"]["vertices"]
    assert len(tris) == report["mesh"]["triangles"]
    v = np.array([[float(e.get(k)) for k in "xyz"] for e in verts])
    f = np.array([[int(e.get(k)) for k in ("v1", "v2", "v3")] for e in tris])
    mesh = trimesh.Trimesh(v, f)
    assert mesh.is_watertight and mesh.volume == pytest.approx(report["volume_mm3"], rel=1e-6)


def test_preview_is_a_png(exported):
    _, folder, _, _ = exported["printed_planar"]
    assert (folder / "printed_planar_print.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_hinge_motion_reported(exported):
    report = exported["printed_planar"][3]
    hm = report["hinge_motion"]
    assert hm["status"] == "finished"
    # the module folds hard: its hinges turn by more than 100 degrees on the way to d1 = 1.19
    assert 100.0 < hm["max_rotation_deg"] < 180.0
    assert hm["bending_strain"] <= hm["strain_limit"]  # TPU, 4 mm hinges


def test_pla_warns_about_strain():
    design = fabkit.load_template(TEMPLATES / "printed_planar.toml")
    res = export_design(design, {"print": {"material": "PLA", "preview": False,
                                           "threemf": False}})
    assert any("exceeds 0.02 for PLA" in w for w in res.report["warnings"])


@pytest.mark.parametrize("style", ["neck", "bridge"])
@pytest.mark.parametrize("material", ["PLA", "PETG", "TPU"])
def test_every_material_and_style_gives_a_sound_solid(style, material):
    design = fabkit.load_template(TEMPLATES / "printed_planar.toml")
    over = {"print": {"material": material, "hinge_style": style, "preview": False,
                      "threemf": False}}
    res = export_design(design, over)
    mesh = trimesh.load(io.BytesIO(res.files["printed_planar.stl"]), file_type="stl")
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.body_count == 1
    assert abs(mesh.volume - res.report["volume_mm3"]) <= 1e-6 * res.report["volume_mm3"]
    levels = np.unique(np.round(mesh.vertices[:, 2], 5))
    t_h = res.report["settings"]["hinge_thickness"]
    assert levels.tolist() == pytest.approx([0.0, t_h, 3.0], abs=1e-5)


def test_gap_zero_refused_and_nothing_written(tmp_path):
    design = fabkit.load_template(TEMPLATES / "printed_planar_chain10.toml")
    out = tmp_path / "out"
    with pytest.raises(SettingsError, match=r"print.gap: must be > 0, got 0 \(smallest distance"):
        export(design, "stl", out, print={"gap": 0})
    assert not out.exists()


def test_export_is_reproducible():
    design = fabkit.load_template(TEMPLATES / "printed_planar.toml")
    over = {"print": {"preview": False}}
    a, b = export_design(design, over), export_design(design, over)
    assert a.files == b.files


def test_registry_and_applies():
    assert get_exporter("stl").FORMAT == "stl"
    assert applies(fabkit.load_template(TEMPLATES / "printed_planar.toml"))
    assert applies(fabkit.load_template(TEMPLATES / "printed_planar_chain10.toml"))
    # bars, no triangles: a print-in-place linkage on pins; origami sheets fold in 3D
    assert applies(fabkit.load_template(TEMPLATES / "fourbar.toml"))
    assert not applies(fabkit.load_template(TEMPLATES / "origami_sheet.toml"))


def test_stored_mesh_check_catches_merging_vertices():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    f = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    assert stored_mesh_is_closed(v, f)
    assert not stored_mesh_is_closed(v, f[:3])  # a face missing: open
    assert not stored_mesh_is_closed(v, f[:, ::-1][[0, 1, 2]].tolist() + [f[3].tolist()])
    # vertex 4 differs from vertex 1 by 1e-9: float32 merges them, and the face (1, 4, 2)
    # between the two copies collapses
    v5 = np.vstack([v, [1 + 1e-9, 0, 0]])
    f5 = np.vstack([f, [[1, 4, 2]]])
    assert not stored_mesh_is_closed(v5, f5)
    assert len(binary_stl(v, f)) == 84 + 50 * 4


def test_3mf_vertices_read_back_as_the_same_float32_coordinates(tmp_path):
    """The 3MF writes nine significant digits: read back, every coordinate is the float32 the
    mesh was rounded to (as a slicer reads it), bit for bit."""
    import trimesh

    from fabkit.check.threemf import read_package
    from fabkit.writers.threemf import threemf_package

    rng = np.random.default_rng(7)
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    # awkward coordinates: large and small, negative, many digits
    v = box.vertices * rng.uniform(0.1, 250.0, 3) + rng.uniform(-300.0, 300.0, 3)
    v32 = v.astype(np.float32)
    path = tmp_path / "box.3mf"
    path.write_bytes(threemf_package(v, box.faces, "box"))
    mesh = read_package(path)["mesh"]
    assert mesh.is_watertight and len(mesh.vertices) == 8
    ours = {tuple(p) for p in np.asarray(mesh.vertices).astype(np.float32).tolist()}
    assert ours == {tuple(p) for p in v32.tolist()}
