"""The kerf and fit test coupon of a laser kit: cut it first, measure it, then cut the kit.

One cut tells the kerf, the hole and the scale. The coupon lies inside an engraved 100 mm
square (the scale reference) and carries:

* the kit's own pair of bars (``C0``, ``C1``: the kit's width, hole and kerf, holes
  :data:`COUPON_SPACING` apart) and one spacer ring (``CR``), drawn exactly as on the kit's
  sheets, to be joined by one of the kit's screws with the shims a two-layer joint takes;
* a ladder plate (``CL``): :data:`LADDER_STEPS` holes from the kit's hole less 0.2 mm to more
  0.2 mm in 0.1 mm steps (engraved with their size), and as many fingers of the kit's bar
  width, each drawn for another kerf (0.05 mm apart, engraved ``K<kerf>``): the finger that
  measures the bar width names the kerf to set, the smallest hole the barrel turns in without
  binding names the hole to set.

Every engraving stands at least :data:`LABEL_CLEARANCE` from every hole (measured on the glyph
outlines as they are cut, the holes at their size after the kerf).

Reading a measure back: the laser burns away its real kerf ``k``; the file grew every outline
and shrank every hole by half the kerf it was drawn for, ``k0``. A bar drawn ``w + k0`` wide
comes out ``w + k0 - k``, a hole drawn ``h - k0`` comes out ``h - k0 + k``: so the real kerf
is ``k = k0 + w - w_measured``, and a hole that binds on the barrel while the bar is right
wants a larger ``hole_diameter``.
"""

from __future__ import annotations

import numpy as np

from .bars import bar_outline, hole_radius, outline_radius
from .nest import REFERENCE_SIZE, Label, Part, Sheet, label_outlines

__all__ = ["COUPON_SPACING", "coupon_sheet", "coupon_text", "COUPON_NAME", "LADDER_STEPS",
           "HOLE_STEP", "KERF_STEP", "LABEL_CLEARANCE", "ladder"]

#: Hole spacing of the coupon's bars (mm): long enough to measure with calipers and to turn
#: the pair on its screw, short enough for an offcut.
COUPON_SPACING = 40.0
#: Base name of the coupon's files.
COUPON_NAME = "laser_coupon"
#: Holes and fingers of the ladder plate.
LADDER_STEPS = 5
#: Hole sizes of the ladder, around the kit's hole (mm).
HOLE_STEP = 0.1
#: Kerfs the ladder's fingers are drawn for, around the kit's kerf (mm).
KERF_STEP = 0.05
#: Least distance from an engraving to the edge of any hole (mm), so a label never runs into
#: the hole whose fit it tests.
LABEL_CLEARANCE = 1.0
_MARGIN = 5.0   # mm inside the 100 mm square
_LABEL = 2.5    # mm, text height of the ladder's engravings
_FINGER = 12.0  # mm, length of a finger


def ladder(settings) -> tuple:
    """The ladder's hole sizes (as cut, mm) and the kerfs its fingers are drawn for (mm).

    Examples
    --------
    >>> from fabkit.settings.laser import laser_settings
    >>> holes, kerfs = ladder(laser_settings())
    >>> [round(h, 2) for h in holes], [round(k, 2) for k in kerfs]
    ([5.0, 5.1, 5.2, 5.3, 5.4], [0.05, 0.1, 0.15, 0.2, 0.25])
    """
    s = settings
    half = LADDER_STEPS // 2
    steps = [i - half for i in range(LADDER_STEPS)]
    holes = [round(s.screw.hole_diameter + HOLE_STEP * i, 6) for i in steps]
    kerfs = [round(max(s.kerf + KERF_STEP * i, 0.0), 6) for i in steps]
    return holes, kerfs


def _text_fitting(text: str, x: float, y: float, height: float, part: str, holes,
                  radii) -> Label:
    """``text`` centred at (x, y), made smaller until its glyphs keep
    :data:`LABEL_CLEARANCE` from every hole (centres ``holes``, radii ``radii`` as cut)."""
    h = height
    while True:
        label = Label(text, (x, y), round(h, 3), 0.0, part)
        pts = np.concatenate(label_outlines(label)) if text else np.zeros((0, 2))
        if not len(holes) or not len(pts):
            return label
        d = np.linalg.norm(pts[:, None, :] - np.asarray(holes)[None, :, :], axis=2) \
            - np.asarray(radii)[None, :]
        if d.min() >= LABEL_CLEARANCE or h < 0.8:
            return label
        h *= 0.9


def _pair(s, x0: float, y0: float, n: int, labels: bool) -> Part:
    """One of the kit's bars, its first hole at (x0, y0)."""
    w, k, L = s.bar_width, s.kerf, COUPON_SPACING
    r_out = outline_radius(w, k)
    r_hole = hole_radius(s.screw.hole_diameter, k)
    outline = bar_outline(L, w, k)
    outline[:, 0] += x0
    outline[:, 1] += y0
    holes = np.array([[x0, y0], [x0 + L, y0]])
    cut = 0.5 * s.screw.hole_diameter  # a hole's edge as cut (the kerf opens it)
    text = [_text_fitting(f"C{n}", x0 + 0.5 * L, y0, min(s.label_height, 0.3 * w), f"C{n}",
                          holes, [cut, cut])] if labels else []
    return Part(id=f"C{n}", kind="bar", outline=outline, ring=None, holes=holes,
                hole_radius=r_hole, labels=text,
                bbox=(x0 - r_out, y0 - r_out, x0 + L + r_out, y0 + r_out),
                meta={"bar": n, "joints": [0, 1 + n], "layer": n, "length": L})


def _ladder_plate(s, x0: float, y0: float, width: float, labels: bool) -> Part:
    """The ladder plate: a body with the holes, fingers on its top edge (kerf applied to the
    body; each finger drawn for its own kerf)."""
    holes_cut, kerfs = ladder(s)
    k, w = s.kerf, s.bar_width
    body = 2 * _LABEL + 2 * max(holes_cut) + 4 * LABEL_CLEARANCE + 2 * _LABEL + 6.0
    g = 0.5 * k
    pitch = width / LADDER_STEPS
    # the outline, counter-clockwise from the lower-left corner, grown by half the kerf
    pts = [(x0 - g, y0 - g), (x0 + width + g, y0 - g), (x0 + width + g, y0 + body + g)]
    centres = [x0 + pitch * (i + 0.5) for i in range(LADDER_STEPS)]
    for c, kf in zip(reversed(centres), reversed(kerfs)):
        half = 0.5 * (w + kf)  # the finger measures w when the laser burns kf
        pts += [(c + half, y0 + body + g), (c + half, y0 + body + _FINGER + 0.5 * kf),
                (c - half, y0 + body + _FINGER + 0.5 * kf), (c - half, y0 + body + g)]
    pts.append((x0 - g, y0 + body + g))
    outline = np.array([(x, y, 0.0) for x, y in pts])
    hy = y0 + 2 * _LABEL + LABEL_CLEARANCE + max(holes_cut) / 2 + 1.0
    holes = np.array([[c, hy] for c in centres])
    drawn = [0.5 * max(h - k, 0.1) for h in holes_cut]
    cut = [0.5 * h for h in holes_cut]
    text = []
    if labels:
        for c, h in zip(centres, holes_cut):
            text.append(_text_fitting(f"{h:.1f}", c, y0 + _LABEL, _LABEL, "CL", holes, cut))
        for c, kf in zip(centres, kerfs):
            text.append(_text_fitting(f"K{kf:g}", c, y0 + body - _LABEL, _LABEL, "CL", holes,
                                      cut))
        text.append(_text_fitting(f"W{w:g} H{s.screw.hole_diameter:g} K{k:g} T{s.thickness:g}",
                                  x0 + 0.5 * width, hy + max(holes_cut) / 2 + LABEL_CLEARANCE
                                  + 0.5 * _LABEL + 0.5, _LABEL, "CL", holes, cut))
    top = y0 + body + _FINGER + 0.5 * max(kerfs)
    return Part(id="CL", kind="reference", outline=outline, ring=None, holes=holes,
                hole_radius=min(drawn), labels=text,
                bbox=(x0 - g, y0 - g, x0 + width + g, top),
                meta={"cut": True, "hole_radii": drawn, "holes_mm": holes_cut, "kerfs": kerfs})


def coupon_sheet(settings) -> Sheet:
    """The coupon's parts inside the engraved 100 mm square (mm).

    Parameters
    ----------
    settings : LaserSettings
        The kit's settings: its bar width, hole, kerf and spacer ring.

    Returns
    -------
    Sheet
        ``parts``: bars ``C0`` and ``C1`` (kind ``"bar"``, holes ``COUPON_SPACING`` apart),
        the ring ``CR`` (kind ``"spacer"``), the ladder plate ``CL`` (kind ``"reference"``,
        cut) and the square ``REF`` (kind ``"reference"``, as ``reference_square`` says; left
        out with ``"none"``), in sheet coordinates.

    Examples
    --------
    >>> from fabkit.settings.laser import laser_settings
    >>> sheet = coupon_sheet(laser_settings())
    >>> [p.id for p in sheet.parts], round(float(sheet.parts[0].hole_radius), 4)
    (['C0', 'C1', 'CR', 'CL', 'REF'], 2.525)
    """
    s = settings
    labels = s.labels != "none"
    size = REFERENCE_SIZE
    r_out = outline_radius(s.bar_width, s.kerf)
    ring = 0.5 * (s.spacer_diameter + s.kerf)
    # the ladder's fingers need their width and a gap each
    width = max(size - 2 * _MARGIN, LADDER_STEPS * (s.bar_width + max(ladder(s)[1]) + 3.0))
    plate = _ladder_plate(s, _MARGIN, _MARGIN, width, labels)
    top = max(size - _MARGIN - r_out, plate.bbox[3] + 2.0 + 3 * r_out + 3.0)
    parts = [_pair(s, _MARGIN + r_out, top - n * (2 * r_out + 3.0), n, labels) for n in range(2)]
    cx = max(_MARGIN + width - ring, parts[0].bbox[2] + 3.0 + ring)
    cy = top - r_out - 1.5
    parts.append(Part(id="CR", kind="spacer", outline=None, ring=ring,
                      holes=np.array([[cx, cy]]), hole_radius=hole_radius(
                          s.screw.hole_diameter, s.kerf), labels=[],
                      bbox=(cx - ring, cy - ring, cx + ring, cy + ring),
                      meta={"joint": 0, "layer": 2}))
    parts.append(plate)
    right = max(p.bbox[2] for p in parts) + _MARGIN
    high = max(p.bbox[3] for p in parts) + _MARGIN
    # the scale reference: a 100 mm square around the parts (2 mm clear of its lines), or
    # beside them when a wide kit's parts do not fit inside it
    inside = right - _MARGIN <= size - 2.0 and high - _MARGIN <= size - 2.0
    x0 = 0.0 if inside else right
    if s.reference_square != "none":
        square = np.array([[0.0, 0.0, 0.0], [size, 0.0, 0.0], [size, size, 0.0],
                           [0.0, size, 0.0]])
        if s.reference_square == "cut":
            h = 0.5 * s.kerf
            square[:, :2] = square[:, :2] * ((size + 2 * h) / size) - h
        square[:, 0] += x0
        lo = (float(square[:, 0].min()), float(square[:, 1].min()))
        hi = (float(square[:, 0].max()), float(square[:, 1].max()))
        parts.append(Part(id="REF", kind="reference", outline=square, ring=None,
                          holes=np.zeros((0, 2)), hole_radius=0.0, labels=[],
                          bbox=(lo[0], lo[1], hi[0], hi[1]), meta={"size": size},
                          engrave_outline=s.reference_square == "engrave"))
    w_sheet = size if inside else x0 + size
    return Sheet(index=1, width=round(float(w_sheet), 3),
                 height=round(float(max(size, high)), 3), parts=parts)


def coupon_text(settings, design_name: str) -> str:
    """What to cut first, what to measure on the coupon and which setting to change."""
    from ..settings.fasteners import fit_fastener

    s = settings
    w, k, hole = s.bar_width, s.kerf, s.screw.hole_diameter
    drawn_w, drawn_h = w + k, hole - k
    holes, kerfs = ladder(s)
    pair = fit_fastener(s.screw, 2, s.thickness, s.thickness_tolerance)
    return "\n".join([
        f"# Test coupon: {design_name}", "",
        f"Cut `{COUPON_NAME}.dxf` (or `.svg`) from the kit's {s.thickness:g} mm sheet before "
        "the kit, with the same laser settings. It lies inside an engraved 100 mm square: "
        "measure the square first. The two bars C0, C1 and the ring are drawn exactly as "
        "the kit's parts: "
        + (f"the kerf of {k:g} mm is already applied (outlines {drawn_w:g} mm wide, holes "
           f"{drawn_h:g} mm): cut on the line, do not let the laser program or the cutting "
           "service compensate again." if k > 0 else
           "at true size (kerf 0): the laser program must compensate its kerf."), "",
        f"The ladder plate CL: {len(holes)} holes of {holes[0]:.1f} to {holes[-1]:.1f} mm "
        f"(engraved under each), and {len(kerfs)} fingers of the kit's {w:g} mm bar width, "
        f"each drawn for another kerf, {kerfs[0]:g} to {kerfs[-1]:g} mm (engraved K<kerf> "
        "under each).", "",
        "| check | expect | if not |", "|---|---|---|",
        "| the 100 mm square (ruler or calipers, both sides) | 100.0 mm | the scale is off: "
        "check the units the laser program imported (mm) |",
        f"| bar width of C0 (calipers across a bar) | {w:.2f} mm | the finger of the plate that "
        f"measures {w:.2f} mm names the kerf: set `laser.kerf` to its K (or kerf + "
        f"({w:.2f} - measured): a bar 0.10 mm narrow means kerf {k + 0.1:g}) |",
        f"| hole spacing of C0 (centre to centre, or edge to far edge minus one hole) | "
        f"{COUPON_SPACING:.2f} mm | the scale is off (see the square) |",
        f"| screw barrel ({s.screw.barrel_diameter:g} mm) in the holes of C0 and of the "
        f"ladder | slides into the {hole:.1f} hole by hand, turns without wobble | set "
        "`laser.screw.hole_diameter` to the smallest ladder hole the barrel turns in "
        f"without binding (now {hole:g}) |",
        f"| C0 and C1 on one screw ({pair.describe()}) | turns freely, play along the "
        f"screw about {pair.play_nominal:.1f} mm, at most 0.5 mm: the kit's joints are "
        "shimmed the same way | no play, or the screw does not close: the sheet is thicker "
        "than `laser.thickness` (take a shim off); more than 0.5 mm: thinner (add one); "
        "measure the sheet and set `laser.thickness` |",
        f"| ring (outer diameter) | {s.spacer_diameter:.2f} mm | follows the kerf like "
        "the bar width |",
        f"| sheet thickness (calipers, several places) | {s.thickness:g} +- "
        f"{s.thickness_tolerance:g} mm | set `laser.thickness` / `laser.thickness_tolerance` |",
        "", "Change a setting with `--set laser.KEY=VALUE` (or in the template's "
        "`[fabrication.laser]`), export again and cut a new coupon until every check passes.",
        ""])
