"""Laser-ready SVG sheets: the same parts as the DXF, in millimetres, colours by operation.

Colour convention (the RGB primaries that laser programs such as LightBurn, RDWorks, Visicut
and most cutting services map to operations):

* ``#FF0000`` red: outer cut (bar outlines, spacer rings; the reference square when it is cut);
* ``#0000FF`` blue: inner cut (holes; cut before the outer contours);
* ``#000000`` black: engrave (labels as filled glyph outlines: a program set to fill the
  black layer fills only them);
* ``#00FF00`` green: reference line (the 100 mm square when engraved, a hairline scored once,
  in its own group: filled with the labels it would engrave a 100 mm block). The DXF keeps it on
  its own REFERENCE layer (ACI 3, green) likewise.

The file is ``width="<W>mm" height="<H>mm"`` with ``viewBox="0 0 W H"``, so one user unit is
one millimetre; strokes are 0.1 mm hairlines, there is no background shape, no group
transform (y is flipped into SVG's downward axis in the coordinates themselves) and no text:
labels are glyph outlines, so a program without the font cuts the same shapes.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["CUT", "INNER", "ENGRAVE", "REFERENCE", "sheet_svg"]

CUT = "#FF0000"
INNER = "#0000FF"
ENGRAVE = "#000000"
REFERENCE = "#00FF00"
_STROKE = 0.1  # mm


def _f(v: float) -> str:
    return f"{v:.4f}".rstrip("0").rstrip(".")


def _outline_path(vertices, H: float) -> str:
    """A closed bulge polyline as an SVG path (y flipped: arcs change their sweep flag)."""
    v = np.asarray(vertices, dtype=np.float64)
    parts = [f"M {_f(v[0, 0])} {_f(H - v[0, 1])}"]
    for k in range(v.shape[0]):
        q = v[(k + 1) % v.shape[0]]
        b = v[k, 2]
        if b == 0:
            parts.append(f"L {_f(q[0])} {_f(H - q[1])}")
        else:
            chord = math.hypot(q[0] - v[k, 0], q[1] - v[k, 1])
            theta = 4 * math.atan(b)
            r = chord / (2 * math.sin(abs(theta) / 2))
            large = 1 if abs(theta) > math.pi else 0
            sweep = 0 if b > 0 else 1  # counter-clockwise in y-up is clockwise in y-down
            parts.append(f"A {_f(r)} {_f(r)} 0 {large} {sweep} {_f(q[0])} {_f(H - q[1])}")
    return " ".join(parts) + " Z"


def _poly_path(points, H: float) -> str:
    p = np.asarray(points, dtype=np.float64)
    # Python floats, flipped at once: iterating the array's rows made two numpy scalars a vertex
    xs, ys = p[:, 0].tolist(), (H - p[:, 1]).tolist()
    head = f"M {_f(xs[0])} {_f(ys[0])}"
    return head + " " + " ".join(f"L {_f(x)} {_f(y)}" for x, y in zip(xs[1:], ys[1:])) + " Z"


def _kerf_text(settings) -> str:
    from ..fab.laser import kerf_note

    return kerf_note(settings).capitalize() + "."


def sheet_svg(sheet, settings) -> bytes:
    """One nested sheet as a laser-ready SVG (see the module notes for the conventions).

    Parameters
    ----------
    sheet : fabkit.fab.nest.Sheet
    settings : LaserSettings
        ``labels`` decides whether labels are drawn (always as outlines here).

    Returns
    -------
    bytes
        UTF-8 SVG: engraving first, then inner cuts, then outer cuts (the order lasers cut in
        when they follow the file).
    """
    from ..fab.nest import label_outlines

    W, H = float(sheet.width), float(sheet.height)
    reference, engrave, inner, outer = [], [], [], []
    for part in sheet.parts:
        if part.engrave_outline:
            reference.append(f'<path id="{part.id}" d="{_outline_path(part.outline, H)}" '
                             f'fill="none" stroke="{REFERENCE}" stroke-width="{_STROKE}"/>')
        if settings.labels != "none":
            glyphs = [_poly_path(poly, H) for lb in part.labels for poly in label_outlines(lb)]
            if glyphs:
                engrave.append(f'<path id="label-{part.id}" d="{" ".join(glyphs)}" '
                               f'fill="{ENGRAVE}" fill-rule="evenodd" stroke="none"/>')
        radii = part.meta.get("hole_radii") or [part.hole_radius] * len(part.holes)
        for c, radius in zip(part.holes, radii):
            inner.append(f'<circle cx="{_f(c[0])}" cy="{_f(H - c[1])}" r="{_f(radius)}" '
                         f'fill="none" stroke="{INNER}" stroke-width="{_STROKE}"/>')
        if part.ring is not None:
            c = part.holes[0]
            outer.append(f'<circle id="{part.id}" cx="{_f(c[0])}" cy="{_f(H - c[1])}" '
                         f'r="{_f(part.ring)}" fill="none" stroke="{CUT}" '
                         f'stroke-width="{_STROKE}"/>')
        elif not part.engrave_outline:
            outer.append(f'<path id="{part.id}" d="{_outline_path(part.outline, H)}" '
                         f'fill="none" stroke="{CUT}" stroke-width="{_STROKE}"/>')
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{_f(W)}mm" height="{_f(H)}mm" '
           f'viewBox="0 0 {_f(W)} {_f(H)}">',
           f"<title>sheet {sheet.index}: red {CUT} outer cut, blue {INNER} inner cut, "
           f"black {ENGRAVE} engrave (filled labels), green {REFERENCE} reference line; "
           f"1 unit = 1 mm</title>",
           f'<desc id="kerf">{_kerf_text(settings)}</desc>',
           f'<metadata><fabkit:kerf xmlns:fabkit="urn:fabkit" mm="{_f(settings.kerf)}" '
           f'applied="{"true" if settings.kerf > 0 else "false"}"/></metadata>',
           '<g id="reference">', *reference, "</g>",
           '<g id="engrave">', *engrave, "</g>",
           '<g id="inner-cut">', *inner, "</g>",
           '<g id="outer-cut">', *outer, "</g>",
           "</svg>"]
    return ("\n".join(out) + "\n").encode("utf-8")
