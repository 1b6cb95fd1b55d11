"""The hardware catalogue (parts as sold, fasteners for deep stacks), the test coupon and the
kerf stated in the files, on small kits."""

from __future__ import annotations

import io
import json
import math
from dataclasses import fields

import ezdxf
import pytest

import fabkit
from fabkit.check.dxf import check_documents
from fabkit.errors import FabricationError
from fabkit.export.dxf import export_design
from fabkit.fab.hardware import (CATALOGUE, MAX_EXTENSIONS, PINS, WASHER_CLEARANCE, WASHERS,
                                 ScrewSpec, choose_washer, fit_fastener, inch_text, screw_spec)
from fabkit.schema import ScrewSection

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


@pytest.mark.parametrize("name", sorted(CATALOGUE))
def test_washers_go_over_the_barrel_they_are_listed_for(name):
    spec = CATALOGUE[name]
    shim = spec.shim()
    assert shim.inner >= spec.barrel_diameter + WASHER_CLEARANCE
    assert shim.outer > spec.hole_diameter  # it covers the hole it lies on
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
    assert spec.shim().name == "SAE #10" and spec.shim().inner == pytest.approx(5.5626)


@pytest.mark.parametrize("layers", [2, 7, 9])
def test_a_post_of_the_series_closes_a_shallow_stack(layers):
    f = fit_fastener(screw_spec(), layers, 3.0, 0.15)
    assert f.kind == "chicago" and f.length in CATALOGUE["M3-chicago"].lengths
    thickest = layers * 3.15
    assert f.length >= thickest + 0.1 - 1e-9
    assert f.play_min == pytest.approx(f.length - thickest - 0.5 * f.washers)
    assert 0 <= f.play_min < 0.5 + 0.1 + 1e-9   # shims take up all but one washer of play
    assert f.play_max == pytest.approx(f.play_min + 2 * 0.15 * layers)


@pytest.mark.parametrize("layers, length, washers", [(10, 40.0, 9), (13, 45.0, 0),
                                                      (14, 50.0, 4), (18, 65.0, 9)])
def test_deep_metric_stacks_take_a_clevis_pin(layers, length, washers):
    f = fit_fastener(screw_spec(), layers, 3.0, 0.15)
    pin = PINS["4-pin"]
    assert (f.kind, f.length, f.washers) == ("clevis pin", length, washers)
    # room between the head and the split pin: the stack on the thickest sheets, the pin's
    # washer, the allowance, and the shims
    room = pin.clamp(length) - WASHERS[pin.washer].thickness
    assert room - layers * 3.15 - 0.5 * washers == pytest.approx(f.play_min)
    assert 0 <= f.play_min and f.closes
    kinds: dict = {}
    for p in f.parts:
        kinds[p.kind] = kinds.get(p.kind, 0) + p.count
    # the pin's ISO 7089 washer under the split pin, and the DIN 433 shims
    assert kinds == {"clevis pin": 1, "washer": 1 + washers, "split pin": 1}
    descriptions = [p.description for p in f.parts]
    assert f"clevis pin ISO 2341 B 4 x {length:g} (with split-pin hole), head 6 mm, steel, " \
           "zinc-plated" in descriptions


def test_deep_inch_stacks_take_screw_on_extensions():
    spec = screw_spec("inch-chicago")
    f = fit_fastener(spec, 20, 3.0, 0.15)       # 63 mm of sheet: past the 2 in posts
    assert f.kind == "chicago+extensions"
    assert inch_text(f.post) == "2 in" and [inch_text(e) for e in f.extensions] == ["1/2 in"]
    assert f.length >= 20 * 3.15 + spec.allowance
    assert f.describe() == "post 2 in + extensions 1/2 in" + (
        f" + {f.washers} washers" if f.washers else "")
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
    circles = sorted(round(e.dxf.radius, 6) for e in doc.modelspace().query("CIRCLE"))
    # four holes drawn 4.2 - 0.2 mm, the ring drawn 13.2 + 0.2 mm
    assert circles == [2.0, 2.0, 2.0, 2.0, 2.0, 6.7]
    outlines = doc.modelspace().query("LWPOLYLINE[layer=='CUT']")
    assert len(outlines) == 2
    for e in outlines:
        ys = [p[1] for p in e.get_points("xy")]
        assert max(ys) - min(ys) == pytest.approx(14.2)    # 14 mm bar + the kerf
    text = result.files["laser_coupon.md"].decode()
    assert "| bar width (calipers across a bar) | 14.00 mm | set `laser.kerf`" in text
    assert "laser.screw.hole_diameter" in text and "do not let the laser program" in text
    svg = result.files["laser_coupon.svg"].decode()
    assert svg.count("<circle") == 6 and 'mm="0.2" applied="true"' in svg
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
    assert r_raw == pytest.approx([2.1] * 8) and r_kit == pytest.approx([2.0] * 8)
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
