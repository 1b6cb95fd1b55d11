"""Cut-ready sheets for a laser or a vinyl cutter (``<name>_cut.svg``, written with the SVG
crease pattern).

Layers (Inkscape layers, which LightBurn, Silhouette Studio, Cricut Design Space and
Inkscape read as separate operations), in working order:

* ``engrave`` (#000000, the laser sheets' engrave colour, :data:`fabkit.writers.laser_svg.ENGRAVE`):
  each sheet's number, its corners' letters (with their join numbers in a chain) and a front
  mark, as filled glyph outlines (:mod:`fabkit.fab.creases.marks`), clear of every cut; a
  program set to fill the black layer fills only them, and no cut is black;
* ``valley-perforations`` (#0000ff) and ``mountain-perforations`` (#ff0000): each crease as
  perforation cuts (:mod:`fabkit.fab.creases.perforation`) that stop short of every vertex, so
  each fold type can get its own power or be scored from its own side;
* ``join-holes`` (#ff00ff): the thread holes at the corners a chain's sheets are joined by
  (circles), cut before the outline;
* ``outline`` (#ff00ff): the sheet's edge as closed paths, cut last so the sheet stays in place
  while its creases are cut.

Cuts are paths of straight segments (``M x y L x y`` per cut), hairlines of 0.1 mm, in mm
(``viewBox`` = ``width``/``height`` in mm), y down, the sheet drawn as in the crease pattern; no
text (the marks are glyph outlines, so a program without the font engraves the same shapes), no
fill but the marks'.
"""

from __future__ import annotations

from xml.sax.saxutils import escape

import numpy as np

from ..fab.creases.layout import corner_text
from ..fab.creases.marks import sheet_marks
from ..fab.creases.perforation import outline_loops, sheet_cuts
from .laser_svg import ENGRAVE

__all__ = ["LAYERS", "cut_svg"]

#: Layer id → colour, in working order: the marks in the laser sheets' engrave colour (filled),
#: the cuts in colours of their own, none of them black.
LAYERS = {"engrave": ENGRAVE.lower(), "valley-perforations": "#0000ff",
          "mountain-perforations": "#ff0000", "join-holes": "#ff00ff", "outline": "#ff00ff"}
_STROKE = 0.1  # mm


def _f(v: float) -> str:
    return f"{v:.4f}".rstrip("0").rstrip(".")


def _to_drawing(points, lo, top, dx, dy):
    p = np.asarray(points, dtype=np.float64)
    return np.stack([dx + p[..., 0] - lo[0], dy + top - p[..., 1]], axis=-1)


def cut_svg(model, perf, offsets, size, *, holes=None, hole: float = 0.0, numbers=None,
            sheet_numbers=None) -> tuple[bytes, dict]:
    """The cut-ready SVG of every sheet of an origami model.

    Parameters
    ----------
    model : OrigamiModel
        With the assignment the folding realises (:func:`fabkit.fab.creases.layout.realised_model`).
    perf : fabkit.fab.creases.perforation.Perforation
    offsets : list of (float, float)
        Where each sheet's bounding box goes (mm), as in the crease pattern.
    size : (float, float)
        Width and height of the document (mm).
    holes : list of list of (float, float), optional
        Per sheet, the centres of its thread holes (drawing mm).
    hole : float
        Their diameter (mm).
    numbers : list of dict, optional
        Per sheet, {vertex: join number} (:func:`fabkit.fab.creases.layout.join_numbers`): its
        corners are marked ``C·4``.
    sheet_numbers : list of int, optional
        Per sheet, its number in the design (1-based; default 1, 2, ...).

    Returns
    -------
    bytes
        UTF-8 SVG.
    dict
        ``perforation`` (dash, gap, stop in mm), ``cuts`` per layer, ``short_creases`` (too short
        to perforate, to score by hand), ``closest_cut_to_a_vertex_mm`` (measured), ``marks``
        (the engraved marks per sheet: ``sheet``, ``texts``, ``unplaced``).
    """
    scale = model.scale
    paths = {k: [] for k in LAYERS}
    counts = {k: 0 for k in LAYERS}
    short, closest, marks = [], np.inf, []
    for i, (sh, (dx, dy)) in enumerate(zip(model.sheets, offsets)):
        pat = sh.pattern
        v = np.asarray(pat.vertices, dtype=np.float64) * scale
        lo, top = v.min(axis=0), v[:, 1].max()
        cuts = sheet_cuts(pat, scale, perf)
        labels = pat.labels or tuple(str(i) for i in range(pat.n_vertices))
        short += [f"{labels[pat.edges[k, 0]]}–{labels[pat.edges[k, 1]]}" for k in cuts.short]
        drawn = []
        for layer, segs in (("valley-perforations", cuts.valley),
                            ("mountain-perforations", cuts.mountain)):
            counts[layer] += segs.shape[0]
            d = _to_drawing(segs, lo, top, dx, dy)
            drawn.append(d.reshape(-1, 2, 2))
            paths[layer] += [f"M {_f(a[0])} {_f(a[1])} L {_f(b[0])} {_f(b[1])}" for a, b in d]
            if segs.shape[0]:
                closest = min(closest, _closest(v, segs))
        mine = holes[i] if holes else []
        for c in mine:
            counts["join-holes"] += 1
            paths["join-holes"].append(f'<circle cx="{_f(c[0])}" cy="{_f(c[1])}" '
                                       f'r="{_f(0.5 * hole)}" fill="none" '
                                       f'stroke="{LAYERS["join-holes"]}" '
                                       f'stroke-width="{_STROKE}"/>')
        for loop in cuts.outline:
            d = _to_drawing(loop, lo, top, dx, dy)
            counts["outline"] += 1
            paths["outline"].append(f"M {_f(d[0, 0])} {_f(d[0, 1])} "
                                    + " ".join(f"L {_f(x)} {_f(y)}" for x, y in d[1:]) + " Z")
        number = sheet_numbers[i] if sheet_numbers else i + 1
        placed, report = _sheet_marks(pat, _to_drawing(v, lo, top, dx, dy), number,
                                      numbers[i] if numbers else {}, np.concatenate(drawn),
                                      mine, hole)
        paths["engrave"] += placed
        counts["engrave"] += len(placed)
        marks.append(report)
    out = _head(model, perf, size, bool(holes))
    for layer, colour in LAYERS.items():
        if layer == "join-holes" and not paths[layer]:
            continue  # a single sheet has no joins
        out.append(f'<g id="{layer}" inkscape:groupmode="layer" '
                   f'inkscape:label="{escape(_names(perf, hole)[layer])}">')
        if layer in ("join-holes", "engrave"):
            out += paths[layer]
        elif paths[layer]:
            out.append(f'<path d="{" ".join(paths[layer])}" fill="none" stroke="{colour}" '
                       f'stroke-width="{_STROKE}"/>')
        out.append("</g>")
    out.append("</svg>")
    report = {"perforation": {"dash_mm": perf.dash, "gap_mm": perf.gap, "stop_mm": perf.stop},
              "cuts": {k: n for k, n in counts.items() if k != "engrave"}, "short_creases": short,
              "closest_cut_to_a_vertex_mm": None if not np.isfinite(closest)
              else round(float(closest), 6), "marks": marks}
    return ("\n".join(out) + "\n").encode("utf-8"), report


def _names(perf, hole) -> dict:
    """Each layer's name as a laser program shows it."""
    return {"engrave": "engrave: sheet numbers, corner letters, joins, front mark (filled)",
            "valley-perforations": f"valley perforations ({perf.dash:g} mm cut, {perf.gap:g} "
                                   "mm gap)",
            "mountain-perforations": f"mountain perforations ({perf.dash:g} mm cut, "
                                     f"{perf.gap:g} mm gap)",
            "join-holes": f"thread holes of the joins ({hole:g} mm)",
            "outline": "outline (cut through, last)"}


def _head(model, perf, size, joined: bool) -> list:
    """The document's opening, title and description (the legend of its colours)."""
    W, H = size
    desc = (f"Cut-ready sheet: creases as perforations, {perf.dash:g} mm cuts with {perf.gap:g} mm "
            f"of paper between them, stopping at least {perf.stop:g} mm short of every vertex so "
            "the sheet holds together; the outline as a cut. Layers in working order: engrave "
            f"({LAYERS['engrave']} black, filled: each sheet's number, its corners' letters"
            + (" and join numbers" if joined else "")
            + f", and FRONT, which reads right only on the side the valleys fold towards), "
            f"valley perforations ({LAYERS['valley-perforations']} blue), mountain perforations "
            f"({LAYERS['mountain-perforations']} red), "
            + (f"thread holes of the joins ({LAYERS['join-holes']} magenta), " if joined else "")
            + f"outline ({LAYERS['outline']} magenta). Engrave the black layer lightly (fill), "
            "cut the others; give each its own power, or score the valleys on this side and the "
            "mountains from the back (turn the sheet over left to right and mirror that layer). "
            "1 unit = 1 mm.")
    return ['<?xml version="1.0" encoding="UTF-8"?>',
            f'<svg xmlns="http://www.w3.org/2000/svg" '
            f'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" width="{_f(W)}mm" '
            f'height="{_f(H)}mm" viewBox="0 0 {_f(W)} {_f(H)}">',
            f"<title>{escape(model.name)}: cut-ready sheet; black {LAYERS['engrave']} engrave "
            f"(filled marks), blue {LAYERS['valley-perforations']} valley perforations, red "
            f"{LAYERS['mountain-perforations']} mountain perforations, magenta "
            f"{LAYERS['outline']} cut through</title>", f"<desc>{escape(desc)}</desc>"]


def _sheet_marks(pat, p, number: int, joins: dict, cuts, holes, hole) -> tuple[list, dict]:
    """One sheet's engraved marks (SVG paths) and what was placed."""
    loop = max(outline_loops(pat.edges, np.isin(pat.assignment, ["B", "C"])), key=len)
    corners = {a: corner_text(pat, joins, a) for a in loop}
    placed, missing = sheet_marks(number, p, loop, corners, cuts, holes, hole, pat.faces)
    out = []
    for m in placed:
        d = " ".join(f"M {_f(g[0, 0])} {_f(g[0, 1])} "
                     + " ".join(f"L {_f(x)} {_f(y)}" for x, y in g[1:]) + " Z"
                     for g in m.outlines)
        tag = m.kind if m.kind != "corner" else "corner-" + m.text.replace("·", "-")
        out.append(f'<path id="sheet{number}-{escape(tag)}" d="{d}" fill="{LAYERS["engrave"]}" '
                   f'fill-rule="evenodd" stroke="none"><title>{escape(m.text)}</title></path>')
    return out, {"sheet": number, "texts": [m.text for m in placed], "unplaced": missing}


def _closest(vertices, segs) -> float:
    """Smallest distance from any vertex to any cut (mm)."""
    a, b = segs[:, 0][None], segs[:, 1][None]
    p = vertices[:, None]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.sum(ab * ab, axis=-1), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t[..., None] * ab), axis=-1).min())
