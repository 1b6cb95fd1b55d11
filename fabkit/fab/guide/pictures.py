"""The kit's pictures for the report: the assembly cut into rows at a scale where labels read,
and the motion with the stacking layers, one full-width row per moment.

A long chain is never squashed into one strip: the assembly is cut between the guide's pages
into the fewest rows that keep at least :data:`MIN_PX_PER_MM` pixels per millimetre, each page
outlined and numbered as in the guide.
"""

from __future__ import annotations

import numpy as np

from ...plots.viz import checked_png, figure_kit, frozen_heap
from .draw import (best_rows, draw_bars, extent, label_bars, label_joints, Labeller, layer_colour,
                   page_brackets, row_axes)
from .plan import bar_name, frame_caption, GuidePlan

__all__ = ["assembly_picture", "assembly_figure", "bottom_margin", "layer_legend", "LEGEND_COLUMNS",
           "motion_picture", "MIN_PX_PER_MM", "PICTURE_WIDTH"]

#: Width of the pictures (inches at :data:`_DPI`: 1100 pixels, the width of a report's column,
#: where they show at their own size).
PICTURE_WIDTH = 11.0
_DPI = 100
#: Rows are added until the drawing has at least this many pixels per mm (a 7 pt label is
#: about 40 px wide and 10 px tall; a bar of the paper's chain is 100 mm long and 13 mm wide).
MIN_PX_PER_MM = 1.6
#: No more than this (a small design is not blown up past legibility into a poster).
MAX_PX_PER_MM = 4.0
_MARGIN, _GAP, _TOP, _BOTTOM, _BAND = 0.3, 0.45, 0.75, 0.55, 0.5
#: Columns of the layer legend: at 9 pt an entry ("layer 13" and its swatch) takes about 1.05
#: inches, so nine fill the picture's width; 12 ran off both edges of the AND gate's pictures
#: (14 layers: "layer 0", "layer 1" and "layer 13" cut off).
LEGEND_COLUMNS = 8
#: Height of a further row of the legend (inches): the bottom margin grows by it.
_LEGEND_ROW = 0.2


def _legend_rows(n_layers: int) -> int:
    return max(1, -(-int(n_layers) // LEGEND_COLUMNS))


def bottom_margin(n_layers: int) -> float:
    """The bottom margin of a picture (inches): room under the drawing for the rows of
    :func:`layer_legend`.

    Parameters
    ----------
    n_layers : int

    Returns
    -------
    float
    """
    return _BOTTOM + _LEGEND_ROW * (_legend_rows(n_layers) - 1)


def layer_legend(fig, n_layers: int):
    """The layers' colours, in rows of at most :data:`LEGEND_COLUMNS` at the bottom of ``fig``
    (in the room :func:`bottom_margin` keeps).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    n_layers : int
    """
    from matplotlib.patches import Rectangle

    handles = [Rectangle((0, 0), 1, 1, fc=layer_colour(z), alpha=0.5, ec="k", lw=0.5)
               for z in range(n_layers)]
    fig.legend(handles, [f"layer {z}" for z in range(n_layers)], loc="lower center",
               ncol=min(n_layers, LEGEND_COLUMNS), fontsize=9, frameon=False)


def assembly_picture(plan, gp: GuidePlan) -> tuple[bytes, dict]:
    """Bars in the reference configuration, by layer, cut into rows between guide pages
    (:func:`assembly_figure`), as PNG.

    Returns
    -------
    png : bytes
    stats : dict
        ``rows``, ``px_per_mm``, ``labels``, ``overlaps`` (0), ``shrunk``, ``dropped``,
        ``clipped`` (texts that do not fit in the picture).
    """
    with frozen_heap():
        fig, stats = assembly_figure(plan, gp)
        png, stats["clipped"] = checked_png(fig, dpi=_DPI)
    return png, stats


def assembly_figure(plan, gp: GuidePlan):
    """The figure of :func:`assembly_picture`, drawn for :data:`_DPI` dots per inch.

    Returns
    -------
    fig : matplotlib.figure.Figure
    stats : dict
        ``rows``, ``px_per_mm``, ``labels``, ``overlaps`` (0), ``shrunk``, ``dropped``.
    """
    s = plan.settings
    edges = np.asarray(plan.bars.edges)
    x = plan.design.network.nodes * s.scale
    r = 0.5 * s.bar_width
    layers = plan.stacking.layer
    pages = gp.pages
    width = PICTURE_WIDTH - 2 * _MARGIN

    def row_ext(idx):
        bars = np.concatenate([np.asarray(pages[i].bars) for i in idx])
        return extent(x[edges[bars]], 3 * r)

    chain = len(pages) > 1
    band = _BAND if chain else 0.0
    rows, ext, scale = best_rows(len(pages), row_ext, width, None, _GAP,
                                 max_scale=MAX_PX_PER_MM / _DPI, min_scale=MIN_PX_PER_MM / _DPI,
                                 band_in=band)
    height = (_TOP + sum((e[3] - e[1]) * scale for e in ext) + _GAP * (len(ext) - 1)
              + band * len(ext) + bottom_margin(plan.stacking.n_layers))
    fig = figure_kit.figure(figsize=(PICTURE_WIDTH, height))
    stats = {"rows": len(rows), "px_per_mm": scale * _DPI, "labels": 0, "overlaps": 0,
             "shrunk": 0, "dropped": 0}
    placed = row_axes(fig, ext, scale, _MARGIN, _TOP, _GAP, width, band_in=band)
    for row, (ax, strip) in zip(rows, placed):
        bars = np.concatenate([np.asarray(pages[i].bars) for i in row])
        draw_bars(ax, x, edges, bars, layers, r, alpha=0.5)
        joints = sorted({int(j) for j in edges[bars].ravel()})
        ax.plot(x[joints, 0], x[joints, 1], "o", ms=3, color="k", zorder=5)
        if strip is not None:
            spans = []
            for i in row:
                p = x[edges[np.asarray(pages[i].bars)]].reshape(-1, 2)
                spans.append((f"p{pages[i].number}", float(p[:, 0].min()),
                              float(p[:, 0].max())))
            page_brackets(strip, spans, 11)
        for side in ax.spines.values():
            side.set_visible(False)
        lab = Labeller(ax)
        label_joints(lab, x, joints, [f"J{j}" for j in joints], 8)
        label_bars(lab, x, edges, bars, [bar_name(k, int(layers[k])) for k in bars], r)
        stats["overlaps"] += lab.overlaps()
        for key in ("labels", "shrunk", "dropped"):
            stats[key] += lab.stats[key]
    pages_note = "; p<k>: page k of laser_guide.pdf" if chain else ""
    fig.suptitle(f"{plan.design.name}: assembly, {plan.stacking.n_layers} layers (0 = bottom), "
                 f"{len(rows)} row{'s' if len(rows) > 1 else ''}, {scale * _DPI:.2g} px per mm"
                 f"{pages_note}", fontsize=11, y=1 - 0.3 / height)
    layer_legend(fig, plan.stacking.n_layers)
    return fig, stats


def motion_picture(plan, gp: GuidePlan) -> tuple[bytes, dict]:
    """The kit at the motion test's moments (start, the collapse on its way, end), bars by
    layer, the pushed pair in red: one full-width row each for a long design, side by side for
    a compact one (as many as keep :data:`MIN_PX_PER_MM`), always to one scale.

    Returns
    -------
    png : bytes
    stats : dict
        ``columns``, ``px_per_mm``, ``clipped`` (texts that do not fit in the picture).
    """
    s = plan.settings
    edges = np.asarray(plan.bars.edges)
    r = 0.5 * s.bar_width
    m = gp.motion
    if m is not None:
        pts, frames, pair = m.positions, list(m.frames), m.joints
        titles = [frame_caption(m, f) for f in frames]
    else:
        pts = np.asarray(plan.sweep.positions)
        frames = sorted(set(np.linspace(0, pts.shape[0] - 1, 4).round().astype(int).tolist()))
        titles = [f"sample {f + 1} of {pts.shape[0]}" for f in frames]
        pair = None
    used = np.unique(edges)
    ext = [extent(pts[f][used], 2 * r) for f in frames]
    x0, x1 = min(e[0] for e in ext), max(e[2] for e in ext)
    width = PICTURE_WIDTH - 2 * _MARGIN
    # a compact design: the moments side by side, as many as keep MIN_PX_PER_MM
    cols = 1
    for c in range(len(frames), 1, -1):
        if (width - _GAP * (c - 1)) / (c * (x1 - x0)) >= MIN_PX_PER_MM / _DPI:
            cols = c
            break
    if cols == 1:
        ext = [(x0, e[1], x1, e[3]) for e in ext]  # one x range: the held joint stays put
        scale = min(width / (x1 - x0), MAX_PX_PER_MM / _DPI)
        height = (_TOP + sum((e[3] - e[1]) * scale for e in ext) + _GAP * (len(ext) - 1)
                  + bottom_margin(plan.stacking.n_layers))
        fig = figure_kit.figure(figsize=(PICTURE_WIDTH, height))
        axes = [ax for ax, _ in row_axes(fig, ext, scale, _MARGIN, _TOP, _GAP, width)]
    else:
        y0, y1 = min(e[1] for e in ext), max(e[3] for e in ext)
        rows = int(np.ceil(len(frames) / cols))
        scale = min((width - _GAP * (cols - 1)) / (cols * (x1 - x0)), MAX_PX_PER_MM / _DPI)
        w, h = (x1 - x0) * scale, (y1 - y0) * scale
        height = _TOP + rows * h + _GAP * (rows - 1) + bottom_margin(plan.stacking.n_layers)
        fig = figure_kit.figure(figsize=(PICTURE_WIDTH, height))
        axes = []
        for k in range(len(frames)):
            row, col = divmod(k, cols)
            left = _MARGIN + col * (w + _GAP)
            top = _TOP + row * (h + _GAP)
            ax = fig.add_axes([left / PICTURE_WIDTH, (height - top - h) / height,
                               w / PICTURE_WIDTH, h / height])
            ax.set_xlim(x0, x1)
            ax.set_ylim(y0, y1)
            ax.set_aspect("equal", adjustable="box")
            ax.set_xticks([])
            ax.set_yticks([])
            axes.append(ax)
    for f, title, ax in zip(frames, titles, axes):
        draw_bars(ax, pts[f], edges, np.arange(edges.shape[0]), plan.stacking.layer, r,
                  alpha=0.55, lw=0.4)
        if pair is not None:
            ax.plot(pts[f][list(pair), 0], pts[f][list(pair), 1], "-o", color="#d00000", lw=2,
                    ms=4, zorder=6)
        ax.set_title(title, fontsize=10 if cols == 1 else 8, loc="left", pad=3)
        for side in ax.spines.values():
            side.set_color("0.85")
    fig.suptitle(f"{plan.design.name}: the motion test with the stacking layers, to one scale "
                 f"({scale * _DPI:.2g} px per mm)", fontsize=11, y=1 - 0.3 / height)
    layer_legend(fig, plan.stacking.n_layers)
    png, clipped = checked_png(fig, dpi=_DPI)
    return png, {"columns": cols, "px_per_mm": scale * _DPI, "clipped": clipped}
