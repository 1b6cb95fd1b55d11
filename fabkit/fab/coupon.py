"""The kerf and fit test coupon of a laser kit: cut it first, measure it, then cut the kit.

The coupon carries the kit's own features drawn exactly as on the kit's sheets (same kerf,
width, hole and ring): a short pair of bars with two holes each at a known spacing, to be
joined by one of the kit's screws, and one spacer ring. What to measure on it, and which setting
to change when a measure is off, is written beside it (:func:`coupon_text`).

Reading a measure back: the laser burns away its real kerf ``k``; the file grew every outline
and shrank every hole by half the kerf it was drawn for, ``k0``. A bar drawn ``w + k0`` wide
comes out ``w + k0 - k``, a hole drawn ``h - k0`` comes out ``h - k0 + k``: so the real kerf
is ``k = k0 + w - w_measured``, and a hole that binds on the barrel while the bar is right
wants a larger ``hole_diameter``.
"""

from __future__ import annotations

import numpy as np

from .bars import bar_outline, hole_radius, outline_radius
from .nest import _CHAR_WIDTH, Label, Part, Sheet

__all__ = ["COUPON_SPACING", "coupon_sheet", "coupon_text", "COUPON_NAME"]

#: Hole spacing of the coupon's bars (mm): long enough to measure with calipers and to turn
#: the pair on its screw, short enough for an offcut.
COUPON_SPACING = 40.0
#: Base name of the coupon's files.
COUPON_NAME = "laser_coupon"
_GAP = 4.0      # mm between the coupon's parts
_MARGIN = 5.0   # mm around them


def _label(text: str, x: float, y: float, height: float, part: str) -> Label:
    return Label(text, (x, y), height, 0.0, part)


def coupon_sheet(settings) -> Sheet:
    """The coupon's parts placed on a small sheet of their own (mm).

    Parameters
    ----------
    settings : LaserSettings
        The kit's settings: its bar width, hole, kerf and spacer ring.

    Returns
    -------
    Sheet
        ``parts``: bars ``C0`` and ``C1`` (kind ``"bar"``, holes ``COUPON_SPACING`` apart)
        and the ring ``CR`` (kind ``"spacer"``), in sheet coordinates.

    Examples
    --------
    >>> from fabkit.fab.laser import laser_settings
    >>> sheet = coupon_sheet(laser_settings())
    >>> [p.id for p in sheet.parts], round(float(sheet.parts[0].hole_radius), 4)
    (['C0', 'C1', 'CR'], 2.025)
    """
    s = settings
    w, k, L = s.bar_width, s.kerf, COUPON_SPACING
    r_out = outline_radius(w, k)
    r_hole = hole_radius(s.screw.hole_diameter, k)
    ring = 0.5 * (s.spacer_diameter + k)
    height = min(s.label_height, 0.3 * w)
    parts = []
    for n in range(2):
        x0, y0 = _MARGIN + r_out, _MARGIN + r_out + n * (2 * r_out + _GAP)
        outline = bar_outline(L, w, k)
        outline[:, 0] += x0
        outline[:, 1] += y0
        text = f"C{n} W{w:g} H{s.screw.hole_diameter:g} K{k:g}"
        h = min(height, (L - s.screw.hole_diameter - 2.0) / (_CHAR_WIDTH * len(text)))
        labels = [_label(text, x0 + 0.5 * L, y0, round(h, 3), f"C{n}")] \
            if s.labels != "none" else []
        parts.append(Part(
            id=f"C{n}", kind="bar", outline=outline, ring=None,
            holes=np.array([[x0, y0], [x0 + L, y0]]), hole_radius=r_hole, labels=labels,
            bbox=(x0 - r_out, y0 - r_out, x0 + L + r_out, y0 + r_out),
            meta={"bar": n, "joints": [0, 1 + n], "layer": n, "length": L}))
    cx = _MARGIN + 2 * r_out + L + _GAP + ring
    cy = _MARGIN + ring
    parts.append(Part(id="CR", kind="spacer", outline=None, ring=ring,
                      holes=np.array([[cx, cy]]), hole_radius=r_hole, labels=[],
                      bbox=(cx - ring, cy - ring, cx + ring, cy + ring),
                      meta={"joint": 0, "layer": 2}))
    width = cx + ring + _MARGIN
    height_mm = max(_MARGIN + 4 * r_out + _GAP, cy + ring) + _MARGIN
    return Sheet(index=1, width=round(float(width), 3), height=round(float(height_mm), 3),
                 parts=parts)


def coupon_text(settings, design_name: str) -> str:
    """What to cut first, what to measure on the coupon and which setting to change."""
    s = settings
    w, k, hole = s.bar_width, s.kerf, s.screw.hole_diameter
    drawn_w, drawn_h = w + k, hole - k
    return "\n".join([
        f"# Test coupon: {design_name}", "",
        f"Cut `{COUPON_NAME}.dxf` (or `.svg`) from the kit's {s.thickness:g} mm sheet before "
        "the kit, with the same laser settings. Its two bars and the ring are drawn exactly as "
        "the kit's parts: "
        + (f"the kerf of {k:g} mm is already applied (outlines {drawn_w:g} mm wide, holes "
           f"{drawn_h:g} mm): cut on the line, do not let the laser program or the cutting "
           "service compensate again." if k > 0 else
           "at true size (kerf 0): the laser program must compensate its kerf."), "",
        "| check | expect | if not |", "|---|---|---|",
        f"| bar width (calipers across a bar) | {w:.2f} mm | set `laser.kerf` to kerf + "
        f"({w:.2f} - measured): a bar 0.10 mm narrow means kerf {k + 0.1:g} |",
        f"| hole spacing (centre to centre, or edge to far edge minus one hole) | "
        f"{COUPON_SPACING:.2f} mm | check the scale: engrave the 100 mm reference square |",
        f"| screw barrel ({s.screw.barrel_diameter:g} mm) through a hole | slides in by hand, "
        f"turns without wobble | binds: raise `laser.screw.hole_diameter` by 0.1 mm "
        f"(now {hole:g}); wobbles: lower it by 0.1 mm (at least the barrel) |",
        "| the bar pair on one screw, closed | turns freely, no axial rattle | "
        "tight: the sheet is thicker than `laser.thickness`; measure it and set it |",
        f"| ring (outer diameter) | {s.spacer_diameter:.2f} mm | follows the kerf like "
        "the bar width |",
        f"| sheet thickness (calipers, several places) | {s.thickness:g} +- "
        f"{s.thickness_tolerance:g} mm | set `laser.thickness` / `laser.thickness_tolerance` |",
        "", "Change a setting with `--set laser.KEY=VALUE` (or in the template's "
        "`[fabrication.laser]`), export again and cut a new coupon until every check passes.",
        ""])
