"""Print settings: material defaults, overrides, and one-line refusals of bad values."""

from __future__ import annotations

import pytest

from fabkit.errors import FabkitError, FabricationError, SettingsError
from fabkit.settings.printing import HINGE_STYLES, MATERIALS, print_settings


@pytest.mark.parametrize("material", sorted(MATERIALS))
def test_material_defaults_are_printable(material):
    s = print_settings({"material": material})
    d = MATERIALS[material]
    assert s.material == material
    assert s.gap == d["gap"] > 0
    assert s.hinge_width >= s.nozzle_width
    assert s.hinge_style in HINGE_STYLES
    # every height is a whole number of layers
    for height in (s.hinge_thickness, s.plate_thickness):
        layers = height / s.layer_height
        assert abs(layers - round(layers)) < 1e-9 and round(layers) >= 1
    assert s.hinge_thickness < s.plate_thickness


def test_lower_case_material_and_overrides_take_precedence():
    s = print_settings({"material": "petg", "gap": 0.5, "scale": 4.0}, {"gap": 0.3})
    assert s.material == "PETG"
    assert s.gap == 0.3
    assert s.scale == 4.0


def test_hinge_thickness_in_whole_layers():
    s = print_settings({"hinge_style": "bridge", "hinge_thickness": 0.6})
    assert s.hinge_layers == 3
    assert s.hinge_thickness == pytest.approx(0.6)
    with pytest.raises(FabricationError, match=r"0\.3 mm is not a whole number of 0\.2 mm layers; "
                                               r"use 0\.2 or 0\.4"):
        print_settings({"hinge_style": "bridge", "hinge_thickness": 0.3})


def test_neck_is_plate_less_one_layer():
    s = print_settings({"hinge_style": "neck", "plate_thickness": 2.4, "layer_height": 0.2})
    assert s.hinge_thickness == pytest.approx(2.2)


@pytest.mark.parametrize("gap", [0, 0.0, -0.2])
def test_gap_zero_or_negative_refused(gap):
    with pytest.raises(SettingsError) as err:
        print_settings({}, {"gap": gap})
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith(f"fabrication.print.gap: must be > 0, got {gap}")
    assert "not watertight" in msg


@pytest.mark.parametrize("table, pattern", [
    ({"hinge_width": 0.3}, r"hinge_width: 0\.3 mm is thinner than the 0\.4 mm nozzle"),
    ({"material": "ABS"}, r"material: must be one of 'PLA', 'PETG' or 'TPU', got 'ABS'"),
    ({"hinge_style": "film"}, r"hinge_style: must be one of 'neck' or 'bridge', got 'film'"),
    ({"kerf": 0.1}, r"fabrication\.print\.kerf: unknown key; known: bar_thickness, bar_width, "
                    r"bed, bed_margin, cap_diameter, clearance, gap,"),
    ({"scale": "big"}, r"scale: must be a number, got 'big'"),
    ({"scale": 0}, r"scale: must be > 0, got 0"),
    ({"hinge_style": "bridge", "hinge_layers": 15}, r"is not thinner than the 3 mm plates"),
    ({"hinge_style": "bridge", "hinge_layers": 0}, r"hinge_layers: must be >= 1, got 0"),
    ({"hinge_style": "bridge", "hinge_layers": 2, "hinge_thickness": 0.4},
     r"give hinge_thickness or hinge_layers"),
    ({"hinge_layers": 3}, r"hinge_layers: applies to hinge_style = \"bridge\" only; this print "
                          r"uses \"neck\" hinges \(the PLA default\)"),
    ({"plate_thickness": 2.5}, r"not a whole number of 0\.2 mm layers"),
    ({"rigid_triangles": [[0, 1]]}, r"rigid_triangles\[0\]: must have at least 3 entries"),
    ({"preview": "yes"}, r"preview: must be true or false, got 'yes'"),
])
def test_bad_values_refused_in_one_line(table, pattern):
    with pytest.raises(FabkitError, match=pattern) as err:
        print_settings(table)
    assert "\n" not in str(err.value)
