"""Drawing bars by layer and placing labels that never overlap (shared by the guide's pages and
the kit's pictures).

Each label tries positions (beside its joint, along its bar and beside it) until its box, as
the renderer measures it, is inside the axes and free of the labels already placed; when none
is free it tries again smaller, and as a last resort it is left out and counted (``dropped``).
"""

from __future__ import annotations

import functools

import numpy as np

from ...numerics import MM_SLACK
from ...plots.viz import figure_kit
from ..bars import stadium_polygon
from .pdf_text import LAYER_GID

__all__ = ["Labeller", "draw_bars", "label_joints", "label_bars", "layer_colour",
           "split_evenly", "extent", "best_rows", "row_axes", "page_brackets"]

#: Joint label offsets (in label heights) tried in order around the joint.
_JOINT_OFFSETS = ((0, 1), (1, 1), (-1, 1), (1, 0), (-1, 0), (0, -1), (1, -1), (-1, -1),
                  (0, 2), (2, 0), (-2, 0), (0, -2), (2, 2), (-2, 2), (2, -2), (-2, -2))


def layer_colour(layer: int):
    """The colour of a stacking layer (matplotlib's tab10, repeating)."""
    return _tab10(int(layer) % 10)


@functools.lru_cache(maxsize=10)
def _tab10(k: int) -> tuple:
    # the registry hands out a copy of the colormap on each look-up (160 µs a colour, asked
    # for every bar drawn: a twentieth of the time of drawing a guide); tab10 is fixed
    return figure_kit.get_cmap("tab10")(k)


class Labeller:
    """Places text labels in one axes without overlaps.

    A label's box is measured once per text and size (a text's extent does not depend on
    where it stands) and moved to each candidate; the labels placed are measured again, as
    drawn, by :meth:`overlaps`.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Its view limits and aspect must be final.
    min_size : float
        No label is shrunk below this size (points); one that finds no free place at it is
        left out and counted.
    """

    def __init__(self, ax, min_size: float = 0.0):
        self.ax = ax
        self.min_size = float(min_size)
        ax.apply_aspect()
        self.renderer = ax.figure.canvas.get_renderer()
        self.boxes, self.placed = [], []
        self._extents: dict = {}
        self._ruler = None  # the text that measures labels
        self.stats = {"labels": 0, "shrunk": 0, "dropped": 0}

    def _text(self, x, y, text, fs, colour, weight):
        # a guide page sets it in its PDF's text layer (.pdf_text), its white patch with it
        return self.ax.text(x, y, text, fontsize=fs, ha="center", va="center", color=colour,
                            weight=weight, zorder=10, gid=LAYER_GID,
                            bbox=dict(boxstyle="square,pad=0.1", fc="white", ec="none",
                                      alpha=0.85))

    def _extent(self, text, fs, weight):
        """The label's box relative to its anchor (display units), with a little margin."""
        key = (text, fs, weight)
        if key not in self._extents:
            t = self._ruler
            if t is None:
                from matplotlib.text import Text

                # measured on one bare text, never added to the axes: its box does not include
                # the white patch behind a placed label, and making that patch (or a text for
                # each measurement) costs more than the measurement
                t = self._ruler = Text(0.0, 0.0, "", ha="center", va="center",
                                       transform=self.ax.transData)
                t.set_figure(self.ax.figure)
            t.set_text(text)
            t.set_fontsize(fs)
            t.set_fontweight(weight)
            e = t.get_window_extent(self.renderer).expanded(1.05, 1.1)
            ax0, ay0 = self.ax.transData.transform((0.0, 0.0))
            self._extents[key] = (e.x0 - ax0, e.y0 - ay0, e.x1 - ax0, e.y1 - ay0)
        return self._extents[key]

    def put(self, text: str, candidates, size: float, colour="black", weight="normal") -> bool:
        """Place ``text`` at the first free candidate (data coordinates); True when placed."""
        candidates = np.asarray(candidates, dtype=np.float64).reshape(-1, 2)
        where = self.ax.transData.transform(candidates)
        fx0, fy0, fx1, fy1 = self.ax.bbox.extents
        taken = np.asarray(self.boxes, dtype=np.float64).reshape(-1, 4)
        sizes = sorted({max(f * size, min(self.min_size, size)) for f in (1.0, 0.8, 0.65)},
                       reverse=True)
        for fs in sizes:
            # every candidate's box at once: inside the axes (edges included) and touching no
            # box placed (closed boxes, as matplotlib's Bbox.overlaps)
            box = where[:, [0, 1, 0, 1]] + np.asarray(self._extent(text, fs, weight))
            free = ((box[:, 0] >= fx0) & (box[:, 2] <= fx1)
                    & (box[:, 1] >= fy0) & (box[:, 3] <= fy1))
            if taken.size:
                b, t = box[:, None, :], taken[None, :, :]
                hit = ((b[..., 0] <= t[..., 2]) & (t[..., 0] <= b[..., 2])
                       & (b[..., 1] <= t[..., 3]) & (t[..., 1] <= b[..., 3]))
                free &= ~hit.any(axis=1)
            if free.any():
                k = int(np.argmax(free))
                self.boxes.append(tuple(box[k]))
                x, y = candidates[k]
                self.placed.append(self._text(x, y, text, fs, colour, weight))
                self.stats["labels"] += 1
                self.stats["shrunk"] += fs < size
                return True
        self.stats["dropped"] += 1
        return False

    def overlaps(self) -> int:
        """Pairs of placed labels whose boxes, measured as drawn, overlap (0)."""
        b = np.array([t.get_window_extent(self.renderer).extents for t in self.placed],
                     dtype=np.float64).reshape(-1, 4)
        n, count = b.shape[0], 0
        for lo in range(0, n, 256):  # a block of rows at a time: memory stays linear in n
            a = b[lo:lo + 256, None, :]
            # closed boxes, as matplotlib's Bbox.overlaps
            hit = ((a[..., 0] <= b[None, :, 2]) & (b[None, :, 0] <= a[..., 2])
                   & (a[..., 1] <= b[None, :, 3]) & (b[None, :, 1] <= a[..., 3]))
            rows = np.arange(lo, min(lo + 256, n))[:, None]
            count += int((hit & (np.arange(n)[None, :] > rows)).sum())  # each pair once
        return count

    def mm_per_point(self) -> float:
        """Data units (mm) per typographic point, along x."""
        ax = self.ax
        x0, x1 = ax.get_xlim()
        return abs(x1 - x0) / max(ax.bbox.width * 72.0 / ax.figure.dpi, MM_SLACK)


def draw_bars(ax, x, edges, bars, layers, radius, *, ghost=False, alpha=0.45, lw=0.5):
    """Bars as stadiums coloured by layer, lowest layer first.

    ``ghost`` bars (of another page) are drawn paler with dashed outlines.
    """
    from matplotlib.collections import PolyCollection

    bars = np.asarray(bars, dtype=np.int64)
    if bars.size == 0:
        return
    order = bars[np.argsort(layers[bars], kind="stable")]
    polys = [stadium_polygon(x[edges[k, 0]], x[edges[k, 1]], radius) for k in order]
    ax.add_collection(PolyCollection(
        polys, facecolors=[layer_colour(layers[k]) for k in order],
        edgecolors="0.35" if ghost else "k", linewidths=lw,
        linestyles="--" if ghost else "-", alpha=0.18 if ghost else alpha,
        hatch="//" if ghost else None, zorder=1 if ghost else 2))


def label_joints(lab: Labeller, x, joints, texts, size=8, colours=None, weights=None):
    """One label per joint, beside it."""
    off = 1.3 * size * lab.mm_per_point()
    for k, j in enumerate(joints):
        cands = [x[j] + np.array(d) * off for d in _JOINT_OFFSETS]
        lab.put(texts[k], cands, size, (colours or {}).get(j, "black"),
                (weights or {}).get(j, "normal"))


def label_bars(lab: Labeller, x, edges, bars, texts, radius, size=7, colour="#222222",
               near=None):
    """One label per bar, along it or beside it; a bar in ``near`` (bar → joint) is labelled
    close to that joint (a bar of another page, mostly outside the view)."""
    for k, text in zip(bars, texts):
        a, b = x[edges[k, 0]], x[edges[k, 1]]
        ts, offsets = (0.5, 0.38, 0.62, 0.28, 0.72, 0.18, 0.82), (0.0, 1.6, -1.6)
        if near and k in near:
            if int(edges[k, 1]) == near[k]:
                a, b = b, a
            ts, offsets = (0.14, 0.22, 0.3, 0.4, 0.5, 0.6), (0.0, 1.6, -1.6, 2.8, -2.8)
        normal = np.array([a[1] - b[1], b[0] - a[0]]) / max(float(np.linalg.norm(b - a)),
                                                              MM_SLACK)
        cands = [a + t * (b - a) + o * normal * radius for o in offsets for t in ts]
        lab.put(text, cands, size, colour)

def split_evenly(n: int, parts: int) -> list:
    """``range(n)`` cut into ``parts`` consecutive runs of near-equal length."""
    edges = np.linspace(0, n, parts + 1).round().astype(int)
    return [list(range(edges[k], edges[k + 1])) for k in range(parts) if edges[k + 1] > edges[k]]


def extent(points, margin: float):
    """(x0, y0, x1, y1) of points (mm) grown by ``margin``."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    lo, hi = p.min(axis=0) - margin, p.max(axis=0) + margin
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def best_rows(n_items: int, row_extent, width_in: float, height_in: float | None,
              gap_in: float, *, max_scale: float, min_scale: float = 0.0, band_in: float = 0.0):
    """Cut ``n_items`` consecutive items into rows drawn at one scale.

    Parameters
    ----------
    n_items : int
    row_extent : callable
        ``row_extent(list of item indices) -> (x0, y0, x1, y1)`` in mm.
    width_in : float
        Width available (inches).
    height_in : float or None
        Height available; None: choose the fewest rows that reach ``min_scale`` (or, failing
        that, the rows with the largest scale).
    gap_in : float
        Space between rows (inches).
    max_scale : float
        Largest scale (inches per mm).
    min_scale : float
        With ``height_in`` None, the scale to reach.
    band_in : float
        Height of the band above each row (inches), for :func:`page_brackets`.

    Returns
    -------
    rows : list of list of int
    extents : list of (x0, y0, x1, y1)
    scale : float
        Inches per mm.
    """
    best = None
    for k in range(1, n_items + 1):
        rows = split_evenly(n_items, k)
        ext = [row_extent(r) for r in rows]
        w = max(e[2] - e[0] for e in ext)
        h = sum(e[3] - e[1] for e in ext)
        scale = min(max_scale, width_in / max(w, MM_SLACK))
        if height_in is not None:
            room = height_in - gap_in * (len(rows) - 1) - band_in * len(rows)
            scale = min(scale, max(room, 0.0) / max(h, MM_SLACK))
        if best is None or scale > best[2] + MM_SLACK:
            best = (rows, ext, scale)
        if height_in is None and scale >= min_scale:
            return rows, ext, scale
    return best


def row_axes(fig, extents, scale: float, left_in: float, top_in: float, gap_in: float,
             width_in: float, *, band_in: float = 0.0, align: str = "center"):
    """One axes per row, top down, each showing its extent at ``scale`` (inches per mm) in
    ``width_in`` (centred, or at the left with ``align="left"``); no ticks. With ``band_in``,
    a band of that height above each row (same x range, no frame) is returned with it.

    Returns
    -------
    list of (Axes, Axes or None)

    Raises
    ------
    ValueError
        ``scale`` is not positive (no room for the rows).
    """
    if not scale > 0:
        # a page with no room left for its rows (the caller must give them a page of their own)
        raise ValueError(f"rows need a positive scale, got {scale!r} inches per mm")
    W, H = fig.get_size_inches()
    axes, y = [], top_in
    for x0, y0, x1, y1 in extents:
        w, h = (x1 - x0) * scale, (y1 - y0) * scale
        left = left_in + (0.5 * (width_in - w) if align == "center" else 0.0)
        band = None
        if band_in > 0:
            band = fig.add_axes([left / W, (H - y - band_in) / H, w / W, band_in / H])
            band.set_xlim(x0, x1)
            band.set_ylim(0.0, 1.0)
            band.axis("off")
            y += band_in
        ax = fig.add_axes([left / W, (H - y - h) / H, w / W, h / H])
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xticks([])
        ax.set_yticks([])
        axes.append((ax, band))
        y += h + gap_in
    return axes


def page_brackets(band, spans, size: float = 9.5):
    """Brackets in a row's band, one per page: a line over the page's x span with its name
    above, on two alternating levels so that neighbours that overlap stay apart.

    Parameters
    ----------
    band : Axes
        From :func:`row_axes` (y from 0 to 1).
    spans : list of (str, float, float)
        Page name and x span (mm).
    """
    for k, (name, x0, x1) in enumerate(spans):
        y = 0.12 + 0.45 * (k % 2)
        band.plot([x0, x0, x1, x1], [y - 0.1, y, y, y - 0.1], "-", color="0.25", lw=0.9,
                  clip_on=False)
        band.text(0.5 * (x0 + x1), y + 0.03, name, ha="center", va="bottom", fontsize=size,
                  weight="bold", clip_on=False)
