"""The hardware catalogue (parts as sold, fasteners for deep stacks), the test coupon and the
kerf stated in the files, on small kits."""

from __future__ import annotations

import io
import json
import math
from dataclasses import fields

import ezdxf
import numpy as np
import pytest

import fabkit
from fabkit.check.dxf import check_documents
from fabkit.errors import FabricationError
from fabkit.writers.dxf import export_design
from fabkit.settings.fasteners import (CATALOGUE, DEFAULT_SCREW, MAX_AXIAL_PLAY, MAX_EXTENSIONS,
                                       PINS, WASHER_CLEARANCE, WASHERS, ScrewSpec, choose_washer,
                                       fit_fastener, inch_text, screw_spec)
from fabkit.io.schema import ScrewSection

from conftest import TEMPLATES


def test_the_declared_screw_setting_names_fields_of_the_catalogue():
    # laser.screw as a table overrides fields of a catalogue entry: every key is one
    assert set(ScrewSection.model_fields) <= {f.name for f in fields(ScrewSpec)}
    for name, spec in CATALOGUE.items():
        assert spec.name == name and screw_spec(name) is spec
        assert screw_spec({"name": name}) == spec
        assert list(spec.lengths) == sorted(spec.lengths)
        # the running hole clears the barrel, the head covers the hole
        assert spec.barrel_diameter < spec.hole_diameter < spec.head_diameter
        assert spec.pin is None or PINS[spec.pin].diameter == spec.barrel_diameter
        # every entry names the product family a buyer searches for
        assert spec.family and spec.thread in spec.family


def test_the_default_screw_is_the_widely_sold_m4_book_screw_and_inch_kits_take_3_16():
    spec = screw_spec()
    assert DEFAULT_SCREW == "M4-chicago" and spec is CATALOGUE["M4-chicago"]
    assert (spec.thread, spec.barrel_diameter, spec.head_diameter) == ("M4", 5.0, 10.0)
    assert "5 mm barrel" in spec.family and "M4" in spec.family
    inch = screw_spec("inch-chicago")
    assert inch_text(inch.barrel_diameter) == "3/16 in" and "3/16 in barrel" in inch.family
    # through the settings, as --set laser.screw=inch-chicago gives it
    from fabkit.settings.laser import laser_settings

    s = laser_settings({}, {"screw": "inch-chicago"})
    assert s.screw is inch and s.bar_width == 14.0    # 5.0 mm hole + 2 x 4.5 mm web
    d = laser_settings({}, {})
    assert d.screw is spec and d.bar_width == 14.5 and d.spacer_diameter == pytest.approx(14.2)


@pytest.mark.parametrize("name", sorted(CATALOGUE))
def test_washers_go_over_the_barrel_they_are_listed_for(name):
    spec = CATALOGUE[name]
    for shim in spec.shim_set():
        # a shim ring (DIN 988) is made to slide on a shaft of its inner diameter; a flat
        # washer clears the shaft
        assert shim.inner >= spec.barrel_diameter + (0.0 if shim.shim else WASHER_CLEARANCE)
        assert shim.outer > spec.hole_diameter  # it covers the hole it lies on
        assert shim.outer <= spec.head_diameter  # and stays under the head
    # the thinnest shim bounds the play the shims leave
    assert spec.shim_set()[-1].thickness + spec.allowance <= MAX_AXIAL_PLAY
    if spec.pin:
        pin = PINS[spec.pin]
        assert WASHERS[pin.washer].inner >= pin.diameter + WASHER_CLEARANCE


def test_an_m3_washer_does_not_go_over_the_4_mm_barrel():
    assert WASHERS["DIN 433 M3"].inner == 3.2 < 4.0
    assert choose_washer(4.0).name == "DIN 433 M4" and choose_washer(4.0).inner == 4.3
    assert choose_washer(4.0, family="ISO 7089").name == "ISO 7089 M4"
    with pytest.raises(FabricationError, match="no DIN 433 washer"):
        choose_washer(20.0)


def test_inch_sizes_read_as_a_shop_lists_them():
    spec = CATALOGUE["inch-chicago"]
    assert spec.barrel_diameter == pytest.approx(4.7625) and inch_text(spec.barrel_diameter) \
        == "3/16 in"
    assert [inch_text(v) for v in spec.lengths[:3]] == ["1/8 in", "3/16 in", "1/4 in"]
    assert inch_text(spec.lengths[-1]) == "2 in"
    assert spec.post(spec.lengths[2]) == ("Chicago screw (sex bolt) #8-32, barrel 3/16 in "
                                          "(4.76 mm), head 3/8 in (9.53 mm), post length "
                                          "1/4 in, aluminium")
    assert spec.shim().name == "shim 3/16 x 3/8 x 0.020 in"
    assert spec.shim().inner == pytest.approx(4.9276) and spec.shim().outer == \
        pytest.approx(spec.head_diameter)


@pytest.mark.parametrize("layers", [1, 2, 3, 4, 5, 6, 7, 9, 12, 15])
@pytest.mark.parametrize("thickness", [3.0, 2.85, 3.175])
def test_posts_close_on_the_thickest_sheet_and_shims_leave_half_a_mm_on_the_nominal(
        layers, thickness):
    spec = screw_spec()
    f = fit_fastener(spec, layers, thickness, 0.15)
    assert f.kind == "chicago" and f.length in spec.lengths
    nominal, thickest, thinnest = (layers * t for t in (thickness, thickness + 0.15,
                                                        thickness - 0.15))
    assert f.length >= thickest + spec.allowance - 1e-9     # closes on the thickest sheets
    fill = sum(t * n for _, t, n in f.shims)
    assert f.washers == sum(n for _, _, n in f.shims)
    assert f.play_nominal == pytest.approx(f.length - nominal - fill)
    assert spec.allowance - 1e-9 <= f.play_nominal <= MAX_AXIAL_PLAY - 0.1 + 1e-9
    # a thin shim only where the thick ones leave more than 0.4 mm: few small parts
    assert [n for _, _, n in f.shims][1] <= 1
    # on the thickest sheets some shims come off and it still closes; on the thinnest, the
    # nominal shims leave the play that grows with the layers
    assert spec.allowance - 1e-9 <= f.play_min <= MAX_AXIAL_PLAY + 0.5
    assert f.play_max == pytest.approx(f.length - thinnest - fill)


@pytest.mark.parametrize("layers, length, washers", [(16, 55.0, 5), (17, 60.0, 9),
                                                      (18, 65.0, 13)])
def test_deep_metric_stacks_take_a_clevis_pin(layers, length, washers):
    f = fit_fastener(screw_spec(), layers, 3.0, 0.15)
    pin = PINS["5-pin"]
    assert (f.kind, f.length, f.washers) == ("clevis pin", length, washers)
    # room between the head and the split pin: the stack on the nominal sheets, the pin's
    # washer, the shims and the play left
    room = pin.clamp(length) - WASHERS[pin.washer].thickness
    fill = sum(t * n for _, t, n in f.shims)
    assert room - layers * 3.0 - fill == pytest.approx(f.play_nominal)
    assert f.play_nominal <= MAX_AXIAL_PLAY and 0 <= f.play_min and f.closes
    kinds: dict = {}
    for p in f.parts:
        kinds[p.kind] = kinds.get(p.kind, 0) + p.count
    # the pin's ISO 7089 washer under the split pin, and the DIN 988 shims
    assert kinds == {"clevis pin": 1, "washer": 1 + washers, "split pin": 1}
    descriptions = [p.description for p in f.parts]
    assert f"clevis pin ISO 2341 B 5 x {length:g} (with split-pin hole), head 8 mm, steel, " \
           "zinc-plated" in descriptions


def test_deep_inch_stacks_take_screw_on_extensions():
    spec = screw_spec("inch-chicago")
    f = fit_fastener(spec, 20, 3.0, 0.15)       # 63 mm of sheet: past the 2 in posts
    assert f.kind == "chicago+extensions"
    assert inch_text(f.post) == "2 in" and [inch_text(e) for e in f.extensions] == ["1/2 in"]
    assert f.length >= 20 * 3.15 + spec.allowance
    assert f.describe().startswith("post 2 in + extensions 1/2 in")
    assert f.play_nominal <= MAX_AXIAL_PLAY
    with pytest.raises(FabricationError, match="deeper than any inch-chicago fastener"):
        fit_fastener(spec, 41, 3.0, 0.15)  # 129 mm: more than 2 in + 3 x 1 in (127 mm)
    assert MAX_EXTENSIONS == 3


# -- coupon, kerf, uncompensated variant ------------------------------------------------------

@pytest.fixture(scope="module")
def fourbar_kit():
    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    return design, export_design(design, {"laser": {"uncompensated": True, "kerf": 0.2}})


def test_every_kit_has_a_coupon_drawn_as_its_parts(fourbar_kit):
    design, result = fourbar_kit
    doc = ezdxf.read(io.StringIO(result.files["laser_coupon.dxf"].decode("ascii")))
    head = dict(doc.header.custom_vars)
    assert head["FABKIT_COUPON"] == "laser_coupon" and head["FABKIT_KERF"] == "0.2"
    msp = doc.modelspace()
    tagged = {}
    for e in msp.query("CIRCLE"):
        tagged.setdefault(e.get_xdata("FABKIT")[0].value, []).append(round(e.dxf.radius, 6))
    # the kit's pair: four holes drawn 5.2 - 0.2 mm; the ring drawn 14.2 + 0.2 mm
    assert sorted(tagged["C0"] + tagged["C1"]) == [2.5] * 4 and tagged["CR"] == [2.5, 7.2]
    # the ladder: five holes of 5.0 ... 5.4 mm as cut, 0.1 mm apart
    cut = sorted(round(2 * r + 0.2, 6) for r in tagged["CL"])
    assert cut == [5.0, 5.1, 5.2, 5.3, 5.4]
    bars = [e for e in msp.query("LWPOLYLINE[layer=='CUT']")
            if e.get_xdata("FABKIT")[0].value in ("C0", "C1")]
    assert len(bars) == 2
    for e in bars:
        ys = [p[1] for p in e.get_points("xy")]
        assert max(ys) - min(ys) == pytest.approx(14.7)    # 14.5 mm bar + the kerf
    text = result.files["laser_coupon.md"].decode()
    assert "| bar width of C0 (calipers across a bar) | 14.50 mm |" in text
    assert "laser.screw.hole_diameter" in text and "do not let the laser program" in text
    svg = result.files["laser_coupon.svg"].decode()
    assert svg.count("<circle") == 11 and 'mm="0.2" applied="true"' in svg
    check = check_documents({"laser_coupon.dxf": result.files["laser_coupon.dxf"].decode()},
                            design=design, settings={"laser": {"kerf": 0.2}})
    names = {c["name"]: c for c in check["checks"]}
    assert check["ok"] and names["spacing"]["value"] == pytest.approx(0.0, abs=1e-9)
    assert names["same_as_kit"]["ok"]
    # the coupon of another kerf is not this kit's
    other = check_documents({"laser_coupon.dxf": result.files["laser_coupon.dxf"].decode()},
                            design=design, settings={"laser": {"kerf": 0.1}})
    assert not other["ok"] and "kerf" in {c["name"]: c for c in other["checks"]}[
        "same_as_kit"]["value"]


@pytest.mark.parametrize("labels", ["outlines", "text"])
def test_the_coupon_measures_kerf_hole_and_scale_in_one_cut(labels):
    """Engravings stand 1 mm or more from every hole (as cut); the ladder's fingers, drawn
    for kerfs 0.05 mm apart, measure the kit's width after their own kerf; the 100 mm square
    is engraved around the coupon; the pair's play is the kit's designed play."""
    from shapely.geometry import Point, Polygon

    from fabkit.fab.coupon import LABEL_CLEARANCE, coupon_sheet, coupon_text, ladder
    from fabkit.settings.laser import laser_settings

    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    result = export_design(design, {"laser": {"labels": labels}})
    doc = ezdxf.read(io.StringIO(result.files["laser_coupon.dxf"].decode("ascii")))
    msp = doc.modelspace()
    kerf = float(dict(doc.header.custom_vars)["FABKIT_KERF"])
    holes = [(Point(e.dxf.center.x, e.dxf.center.y), e.dxf.radius + 0.5 * kerf)
             for e in msp.query("CIRCLE[layer=='CUT_INNER']")]
    assert len(holes) == 10  # four of the pair, the ring's, five of the ladder
    engraved = []
    if labels == "outlines":
        for e in msp.query("LWPOLYLINE[layer=='ENGRAVE']"):
            engraved += [Point(p) for p in e.get_points("xy")]
    else:
        from ezdxf.addons import text2path

        for e in msp.query("TEXT[layer=='ENGRAVE']"):
            for path in text2path.make_paths_from_entity(e):
                engraved += [Point(v.x, v.y) for v in path.flattening(0.05)]
    assert len(engraved) > 100
    gap = min(pt.distance(c) - r for pt in engraved for c, r in holes)
    assert gap >= LABEL_CLEARANCE
    # the fingers: widths drawn w + K for each K, so the one burnt by K measures w
    s = laser_settings({}, {})
    sheet = coupon_sheet(s)
    plate = next(p for p in sheet.parts if p.id == "CL")
    poly = Polygon(plate.outline[:, :2])
    _, kerfs = ladder(s)
    top = plate.outline[:, 1].max()
    tip = poly.intersection(Polygon([(0, top - 1), (200, top - 1), (200, top + 1),
                                     (0, top + 1)]))
    widths = sorted(round(g.bounds[2] - g.bounds[0], 6) for g in tip.geoms)
    assert widths == sorted(round(s.bar_width + k, 6) for k in kerfs)
    assert len(kerfs) >= 5 and np.allclose(np.diff(kerfs), 0.05)
    # the scale reference: a 100 mm square engraved on the coupon, every part inside it
    ref = next(p for p in sheet.parts if p.id == "REF")
    assert np.ptp(ref.outline[:, 0]) == 100.0 == np.ptp(ref.outline[:, 1])
    assert ref.engrave_outline
    for p in sheet.parts:
        assert 0 <= p.bbox[0] and p.bbox[2] <= 100 and 0 <= p.bbox[1] and p.bbox[3] <= 100
    # what it asks of the pair is what the kit is designed for
    text = coupon_text(s, "fourbar")
    assert "at most 0.5 mm" in text and "no axial rattle" not in text
    assert "post 7 mm + 1 x 0.5 + 1 x 0.2 mm shims" in text


def test_the_uncompensated_variant_is_drawn_at_true_size(fourbar_kit):
    design, result = fourbar_kit
    kit = ezdxf.read(io.StringIO(result.files["laser_sheet1.dxf"].decode("ascii")))
    raw = ezdxf.read(io.StringIO(result.files["laser_sheet1_uncompensated.dxf"].decode("ascii")))
    assert dict(raw.header.custom_vars)["FABKIT_KERF"] == "0.0"
    assert dict(raw.header.custom_vars)["FABKIT_VARIANT"] == "uncompensated"
    assert "let the laser or the cutting service compensate" in \
        dict(raw.header.custom_vars)["FABKIT_KERF_NOTE"]
    r_kit = sorted(e.dxf.radius for e in kit.modelspace().query("CIRCLE"))
    r_raw = sorted(e.dxf.radius for e in raw.modelspace().query("CIRCLE"))
    assert r_raw == pytest.approx([2.6] * 8) and r_kit == pytest.approx([2.5] * 8)
    # every hole where the compensated sheet has it
    c_kit = sorted(tuple(round(v, 9) for v in e.dxf.center)[:2]
                   for e in kit.modelspace().query("CIRCLE"))
    c_raw = sorted(tuple(round(v, 9) for v in e.dxf.center)[:2]
                   for e in raw.modelspace().query("CIRCLE"))
    assert c_kit == c_raw
    check = check_documents({"laser_sheet1_uncompensated.dxf":
                             result.files["laser_sheet1_uncompensated.dxf"].decode()},
                            design=design, settings={"laser": {"kerf": 0.2}})
    assert check["ok"]
    bom = json.loads(result.files["laser_bom.json"])
    assert bom["kerf"]["uncompensated_files"] == ["laser_sheet1_uncompensated.dxf",
                                                  "laser_sheet1_uncompensated.svg"]
    assert 'applied="false"' in result.files["laser_sheet1_uncompensated.svg"].decode()


def test_a_kit_without_kerf_says_the_service_compensates():
    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    result = export_design(design, {"laser": {"kerf": 0.0, "uncompensated": True}})
    assert not any("_uncompensated" in n for n in result.files)  # it already is
    bom = json.loads(result.files["laser_bom.json"])
    assert bom["kerf"]["applied"] is False and "compensate its kerf" in bom["kerf"]["note"]
    assert math.isclose(bom["settings"]["kerf"], 0.0)
