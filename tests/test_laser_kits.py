"""Laser kits for the bundled chains: which templates export, the paper's 24-module collapse from
the DXF, and a collision check of the stacking that shares no code with the stacking."""

from __future__ import annotations

import json

import numpy as np
import pytest

import fabkit
from fabkit.writers import skip_reason
from fabkit.writers.dxf import export_design
from fabkit.kinematics.constructive import place, plan_construction

from conftest import TEMPLATES

#: Templates that opt out of DXF, each with a physical reason and a fix the user can apply:
#: none since deep stacks are held by the catalogue's fasteners and a kit may cover part of a
#: motion (tests/test_laser_deep_kits.py builds the four that used to opt out).
OPT_OUT: set = set()


def _planar_templates():
    out = []
    for path in sorted(TEMPLATES.glob("*.toml")):
        design = fabkit.load_template(path)
        if design.network.dim == 2:
            out.append((path.stem, design))
    return out


def test_every_planar_template_exports_dxf_or_states_a_reason_with_a_fix():
    planar = _planar_templates()
    assert len(planar) >= 24
    skipped = {name: skip_reason(d, "dxf") for name, d in planar if skip_reason(d, "dxf")}
    assert set(skipped) == OPT_OUT
    for name, reason in skipped.items():
        # a reason that holds for any stacking, never a search budget, and what to change
        assert "fix:" in reason and "budget" not in reason, name
    # the paper's own laser-cut build is no longer among them
    assert "super_stable_chain" not in skipped


@pytest.fixture(scope="module")
def chain24():
    design = fabkit.load_template(TEMPLATES / "super_stable_chain.toml")
    result = export_design(design)
    return design, result


def test_super_stable_chain_writes_sheets_svg_bom_and_guide(chain24):
    design, result = chain24
    names = set(result.files)
    n = len(result.report["sheets"])
    assert {f"laser_sheet{k}.dxf" for k in range(1, n + 1)} <= names
    assert {f"laser_sheet{k}.svg" for k in range(1, n + 1)} <= names
    assert {"laser_bom.json", "laser_bom.md"} <= names
    bom = json.loads(result.files["laser_bom.json"])
    assert design.network.n_edges == 144 and len(bom["bars"]) == 144
    # 6 bars meet where two modules join (clique), the screw columns force a 7th: proven
    assert bom["layers"]["count"] == 7 and bom["layers"]["lower_bound"] == 7
    assert bom["motion"]["method"] == "module windows"


def test_super_stable_chain_as_built_check_resimulates_the_collapse(chain24):
    from fabkit.check.dxf import check_documents

    design, result = chain24
    texts = {n: b.decode("ascii") for n, b in result.files.items() if n.endswith(".dxf")}
    check = check_documents(texts, design=design)
    assert check["ok"]
    checks = {c["name"]: c for c in check["checks"]}
    assert checks["modes"]["value"] == 1
    assert checks["lengths"]["value"] <= 1e-6
    # re-simulated from the DXF lengths: d1 collapses to D2* and the front crosses ~20 modules
    motion = check["motion"]
    assert motion["samples"] > 3000
    assert checks["same_layer"]["ok"] and checks["same_layer"]["value"] >= 0.5


def test_screws_close_on_the_thickest_sheets(chain24):
    _, result = chain24
    bom = json.loads(result.files["laser_bom.json"])
    t, tol = bom["settings"]["thickness"], bom["settings"]["thickness_tolerance"]
    assert (t, tol) == (3.0, 0.15)
    for j in bom["joints"]:
        n = len(j["bottom_to_top"])
        thickest = n * (t + tol)
        assert j["screw_length_mm"] >= thickest + 0.1 - 1e-9
        p_thick, p_thin = j["play_with_washers_mm"]
        fill = sum(t * k for _, t, k in j["shims"])
        assert j["washers"] == sum(k for _, _, k in j["shims"])
        # the shims leave at most 0.5 mm on the nominal sheet; on the thickest some come off
        # and the post still closes; on the thinnest the nominal shims leave more
        assert j["play_nominal_mm"] == pytest.approx(j["screw_length_mm"] - n * t - fill)
        assert 0.1 - 1e-9 <= j["play_nominal_mm"] <= 0.4 + 1e-9
        assert 0 <= p_thick <= 1.0 and p_thin == pytest.approx(j["play_nominal_mm"] + n * tol)
    assert bom["axial_play"]["nominal_max_mm"] <= bom["axial_play"]["limit_mm"] == 0.5
    spacers = bom["spacer_rings"]
    assert (spacers["outer_diameter_mm"] - spacers["hole_diameter_mm"]) / 2 >= 4.5 - 1e-9


# -- independent collision check --------------------------------------------------------------

def _seg_dist(p1, q1, p2, q2):
    """Exact distance between segments (arrays (..., 2)); written here, not imported."""
    def pt(x, a, b):
        d = b - a
        t = np.clip(np.einsum("...i,...i", x - a, d) / np.maximum(np.einsum("...i,...i", d, d),
                                                                 1e-300), 0, 1)
        return np.linalg.norm(a + t[..., None] * d - x, axis=-1)

    def side(a, b, c):
        return np.sign((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
                       - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))

    cross = (side(p1, q1, p2) * side(p1, q1, q2) < 0) & (side(p2, q2, p1) * side(p2, q2, q1) < 0)
    d = np.minimum.reduce([pt(p1, p2, q2), pt(q1, p2, q2), pt(p2, p1, q1), pt(q2, p1, q1)])
    return np.where(cross, 0.0, d)


def _dense_motion(design, scale, step_mm):
    """Configurations (mm) along the whole motion, bisected in d1 until no node moves more than
    ``step_mm`` between neighbours."""
    net = design.network
    plan = plan_construction(net, net.port("d1"))
    d0 = net.port_distance("d1")
    values = np.linspace(d0, design.motion.to, 201)
    for _ in range(60):
        x = place(plan, values)[0] * scale
        step = np.linalg.norm(x[1:] - x[:-1], axis=-1).max(axis=1)
        bad = np.flatnonzero(step > step_mm)
        if bad.size == 0:
            return x
        values = np.insert(values, bad + 1, 0.5 * (values[bad] + values[bad + 1]))
    raise AssertionError("motion could not be resampled")


@pytest.mark.parametrize("name", ["super_stable_chain8", "fourbar_chain", "slope_one_chain"])
def test_dense_resampling_finds_the_stacking_clear(name):
    design = fabkit.load_template(TEMPLATES / f"{name}.toml")
    result = export_design(design, {"laser": {"labels": "none"}})
    bom = json.loads(result.files["laser_bom.json"])
    scale, width = bom["scale_mm_per_unit"], bom["settings"]["bar_width"]
    clearance = bom["settings"]["clearance"]
    edges = np.array([b["joints"] for b in bom["bars"]])
    layer = np.array([b["layer"] for b in bom["bars"]])
    x = _dense_motion(design, scale, 0.2)
    a, b = np.triu_indices(len(edges), 1)
    shared = (edges[a][:, :, None] == edges[b][:, None, :]).any(axis=(1, 2))
    same = (layer[a] == layer[b]) & ~shared
    a, b = a[same], b[same]
    assert a.size > 0
    gap = np.full(a.size, np.inf)
    for start in range(0, x.shape[0], 200):
        xs = x[start:start + 200]
        d = _seg_dist(xs[:, edges[a, 0]], xs[:, edges[a, 1]], xs[:, edges[b, 0]],
                      xs[:, edges[b, 1]])
        gap = np.minimum(gap, d.min(axis=0) - width)
    # within 0.2 mm steps the gap can shrink by 0.2 mm more than at the samples
    assert gap.min() >= 0.5 * clearance - 0.2, (name, gap.min())


def test_assembly_guide_has_a4_pages_and_no_overlapping_labels(chain24):
    from fabkit.writers.dxf import bill_of_materials
    from fabkit.fab.laser_plan import laser_plan
    from fabkit.fab.guide import guide_pages

    design, result = chain24
    plan = laser_plan(design)
    guide = guide_pages(plan, bill_of_materials(plan, []))
    pdf, png, stats = guide.pdf, guide.images[0], guide.stats
    # overview, how to build, 12 pages of two modules, the motion test
    assert stats["pages"] == 15 and stats["overlaps"] == 0 and stats["dropped"] == 0
    # every bar is labelled once, every screw once per page it appears on
    assert stats["labels"] >= 144 + 25
    # the pages as a reader finds them (the text layer rewrites pages: the file holds each
    # page's first version too)
    pdfium = pytest.importorskip("pypdfium2")
    doc = pdfium.PdfDocument(pdf)
    assert len(doc) == 15
    for page in doc:   # A4 portrait in points
        w, h = page.get_size()
        assert abs(w - 595.3) < 1.0 and abs(h - 841.7) < 1.0
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert result.files["laser_guide.pdf"][:5] == b"%PDF-"


def test_chain_sampling_does_not_grow_with_the_chain(tmp_path):
    import shutil

    from fabkit.settings.laser import laser_settings
    from fabkit.fab.layers import sample_chain

    shutil.copy(TEMPLATES / "super_stable.toml", tmp_path / "super_stable.toml")
    text = (TEMPLATES / "super_stable_chain.toml").read_text()
    found = {}
    for n in (12, 60):
        (tmp_path / f"c{n}.toml").write_text(text.replace("copies = 24", f"copies = {n}"))
        design = fabkit.load_template(tmp_path / f"c{n}.toml")
        s = laser_settings()
        sweep = sample_chain(design.network, design.motion, s.scale, s.sample_step,
                             width=s.bar_width, clearance=s.clearance,
                             column_radius=0.5 * s.screw.head_diameter,
                             spacer_radius=0.5 * s.spacer_diameter, floor_limit=s.clearance)
        found[n] = sweep
    a, b = found[12], found[60]
    # one window kind (mirror-alternate strip), sampled once over the range every module sweeps
    assert a.stats["window_kinds"] == b.stats["window_kinds"] == 1
    assert a.stats["window_samples"] == b.stats["window_samples"]
    assert a.max_step <= 0.5 + 1e-9 and b.max_step <= 0.5 + 1e-9
    # conflicts grow in proportion to the modules (same pattern repeated)
    per_a = a.conflicts.pairs.shape[0] / 12
    per_b = b.conflicts.pairs.shape[0] / 60
    assert abs(per_a - per_b) / per_b < 0.1


# -- parts as sold ----------------------------------------------------------------------------

def test_every_bom_part_of_the_chain_is_a_catalogue_part(chain24):
    from fabkit.fab.hardware import spares
    from fabkit.settings.fasteners import CATALOGUE, PINS, WASHERS

    _, result = chain24
    bom = json.loads(result.files["laser_bom.json"])
    hardware = bom["buy"]["hardware"]
    assert {h["kind"] for h in hardware} == {"chicago screw", "washer"}
    screw = CATALOGUE[bom["settings"]["screw"]["name"]]
    used = {}
    for h in hardware:
        assert h["order"] == h["count"] + h["spares"] and h["spares"] == spares(h["count"])
        if h["kind"] == "chicago screw":
            # a post length the series is sold in, named with barrel, head, length, material
            assert h["post_length_mm"] in screw.lengths
            assert h["barrel_diameter_mm"] == screw.barrel_diameter == 5.0
            assert h["head_diameter_mm"] == screw.head_diameter == 10.0
            assert h["description"] == (
                f"Chicago screw (sex bolt) M4, barrel 5 mm, head 10 mm, post length "
                f"{h['post_length_mm']:g} mm, stainless steel A2")
            assert h["family"] == screw.family and "M4 x 5 mm barrel" in h["family"]
            used[h["post_length_mm"]] = h["count"]
        else:
            w = WASHERS[h["washer"]]
            assert (h["inner_diameter_mm"], h["outer_diameter_mm"], h["thickness_mm"]) == \
                (w.inner, w.outer, w.thickness) in ((5.0, 10.0, 0.5), (5.0, 10.0, 0.2))
            # DIN 988 shim rings: made to slide on the 5 mm barrel, no wider than the head
            assert w.shim and h["inner_diameter_mm"] >= h["over_mm"] == 5.0
            assert h["family"] == "DIN 988"
            kinds = {k["name"]: k["count"] for k in bom["washers"]["kinds"]}
            assert h["count"] == kinds[w.name] == sum(
                n for j in bom["joints"] for name, _, n in j["shims"] if name == w.name)
    # every joint's screw is on the list, counted once
    assert sum(used.values()) == len(bom["joints"]) == 74
    for j in bom["joints"]:
        assert j["screw_length_mm"] in used
    assert not PINS.keys() & {h.get("pin") for h in hardware}
    sheets = bom["buy"]["sheets"]
    assert sheets["count"] == len(bom["sheets"]) == 2 and sheets["size_mm"] == [600.0, 400.0]
    assert sheets["thickness_mm"] == 3.0 and "acrylic" in sheets["material"]
    md = result.files["laser_bom.md"].decode()
    assert "## What to buy" in md and "600 x 400 mm: 2 sheet(s) + 1 spare" in md
    assert "M3 washer" not in md and "(M3)" not in md


def test_the_chain_states_its_kerf_in_every_file_a_cutter_reads(chain24):
    import io

    import ezdxf

    _, result = chain24
    note = ("kerf 0.15 mm already applied: outlines grown and holes shrunk by 0.075 mm; cut on "
            "the line, do not compensate kerf again")
    for name in [n for n in result.files if n.endswith(".dxf")]:
        doc = ezdxf.read(io.StringIO(result.files[name].decode("ascii")))
        head = dict(doc.header.custom_vars)
        assert head["FABKIT_KERF"] == "0.15" and head["FABKIT_KERF_NOTE"] == note, name
    for name in [n for n in result.files if n.endswith(".svg")]:
        text = result.files[name].decode()
        assert f'<desc id="kerf">{note.capitalize()}.</desc>' in text, name
        assert 'mm="0.15" applied="true"' in text
    bom = json.loads(result.files["laser_bom.json"])
    assert bom["kerf"] == {"kerf_mm": 0.15, "applied": True, "note": note,
                           "uncompensated_files": []}
    assert f"**Kerf: {note}.**" in result.files["laser_bom.md"].decode()
    assert {"laser_coupon.dxf", "laser_coupon.svg", "laser_coupon.md"} <= set(result.files)
