"""Cut-ready sheets for a laser or a vinyl cutter (``<name>_cut.svg``, written with the SVG
crease pattern).

Three layers (Inkscape layers, which LightBurn, Silhouette Studio, Cricut Design Space and
Inkscape read as separate operations), in cutting order:

* ``valley-perforations`` (#0000ff) and ``mountain-perforations`` (#ff0000): each crease as
  perforation cuts (:mod:`fabkit.fab.creases.perforation`) that stop short of every vertex, so
  each fold type can get its own power or be scored from its own side;
* ``join-holes`` (#000000): the thread holes at the corners a chain's sheets are joined by
  (circles), cut before the outline;
* ``outline`` (#000000): the sheet's edge as closed paths, cut last so the sheet stays in place
  while its creases are cut.

Cuts are paths of straight segments (``M x y L x y`` per cut), hairlines of 0.1 mm, in mm
(``viewBox`` = ``width``/``height`` in mm), y down, the sheet drawn as in the crease pattern; no
text, no fill.
"""

from __future__ import annotations

from xml.sax.saxutils import escape

import numpy as np

__all__ = ["LAYERS", "cut_svg"]

#: Layer id → stroke colour, in cutting order.
LAYERS = {"valley-perforations": "#0000ff", "mountain-perforations": "#ff0000",
          "join-holes": "#000000", "outline": "#000000"}
_STROKE = 0.1  # mm


def _f(v: float) -> str:
    return f"{v:.4f}".rstrip("0").rstrip(".")


def _to_drawing(points, lo, top, dx, dy):
    p = np.asarray(points, dtype=np.float64)
    return np.stack([dx + p[..., 0] - lo[0], dy + top - p[..., 1]], axis=-1)


def cut_svg(model, perf, offsets, size, *, holes=None, hole: float = 0.0) -> tuple[bytes, dict]:
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

    Returns
    -------
    bytes
        UTF-8 SVG.
    dict
        ``perforation`` (dash, gap, stop in mm), ``cuts`` per layer, ``short_creases`` (too short
        to perforate, to score by hand), ``closest_cut_to_a_vertex_mm`` (measured).
    """
    from ..fab.creases.perforation import sheet_cuts

    scale = model.scale
    paths = {k: [] for k in LAYERS}
    counts = {k: 0 for k in LAYERS}
    short, closest = [], np.inf
    for i, (sh, (dx, dy)) in enumerate(zip(model.sheets, offsets)):
        pat = sh.pattern
        v = np.asarray(pat.vertices, dtype=np.float64) * scale
        lo, top = v.min(axis=0), v[:, 1].max()
        cuts = sheet_cuts(pat, scale, perf)
        labels = pat.labels or tuple(str(i) for i in range(pat.n_vertices))
        short += [f"{labels[pat.edges[k, 0]]}–{labels[pat.edges[k, 1]]}" for k in cuts.short]
        for layer, segs in (("valley-perforations", cuts.valley),
                            ("mountain-perforations", cuts.mountain)):
            counts[layer] += segs.shape[0]
            d = _to_drawing(segs, lo, top, dx, dy)
            paths[layer] += [f"M {_f(a[0])} {_f(a[1])} L {_f(b[0])} {_f(b[1])}" for a, b in d]
            if segs.shape[0]:
                closest = min(closest, _closest(v, segs))
        for c in (holes[i] if holes else []):
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
    names = {"valley-perforations": f"valley perforations ({perf.dash:g} mm cut, {perf.gap:g} "
                                    "mm gap)",
             "mountain-perforations": f"mountain perforations ({perf.dash:g} mm cut, "
                                      f"{perf.gap:g} mm gap)",
             "join-holes": f"thread holes of the joins ({hole:g} mm)",
             "outline": "outline (cut through, last)"}
    W, H = size
    desc = (f"Cut-ready sheet: creases as perforations, {perf.dash:g} mm cuts with {perf.gap:g} mm "
            f"of paper between them, stopping at least {perf.stop:g} mm short of every vertex so "
            "the sheet holds together; the outline as a cut. Layers in cutting order: valley "
            "perforations (blue), mountain perforations (red), "
            + ("thread holes of the joins (black), " if holes else "")
            + "outline (black). Give each layer "
            "its own power, or score the valleys on this side and the mountains from the back "
            "(turn the sheet over left to right and mirror that layer). 1 unit = 1 mm.")
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<svg xmlns="http://www.w3.org/2000/svg" '
           f'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" width="{_f(W)}mm" '
           f'height="{_f(H)}mm" viewBox="0 0 {_f(W)} {_f(H)}">',
           f"<title>{escape(model.name)}: cut-ready sheet</title>", f"<desc>{escape(desc)}</desc>"]
    for layer, colour in LAYERS.items():
        if layer == "join-holes" and not paths[layer]:
            continue  # a single sheet has no joins
        out.append(f'<g id="{layer}" inkscape:groupmode="layer" '
                   f'inkscape:label="{escape(names[layer])}">')
        if layer == "join-holes":
            out += paths[layer]
        elif paths[layer]:
            out.append(f'<path d="{" ".join(paths[layer])}" fill="none" stroke="{colour}" '
                       f'stroke-width="{_STROKE}"/>')
        out.append("</g>")
    out.append("</svg>")
    report = {"perforation": {"dash_mm": perf.dash, "gap_mm": perf.gap, "stop_mm": perf.stop},
              "cuts": counts, "short_creases": short,
              "closest_cut_to_a_vertex_mm": None if not np.isfinite(closest)
              else round(float(closest), 6)}
    return ("\n".join(out) + "\n").encode("utf-8"), report


def _closest(vertices, segs) -> float:
    """Smallest distance from any vertex to any cut (mm)."""
    a, b = segs[:, 0][None], segs[:, 1][None]
    p = vertices[:, None]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.sum(ab * ab, axis=-1), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t[..., None] * ab), axis=-1).min())
