"""Marks engraved on an origami sheet's cut file, so that the cut sheets can still be told apart
and read: the sheet's number, every corner's letter (with its join number in a chain,
``C·4``) and a front mark.

A cut file carries no printed lines, so without marks twelve cut sheets are twelve identical
squares, and a sheet turned over cannot be told from one the right way up. ``FRONT`` reads
right only on the side the crease pattern is drawn from (valleys come up towards you, the side
the cutter works on); seen from the back it is mirrored.

Every mark is placed on its own sheet's paper, its box (the glyphs' extent) at least
:data:`CLEARANCE` from every cut: the outline, the perforations, the thread holes, and the
marks placed before it. A corner's mark goes as near its corner as that allows; the sheet's
number and the front mark as near the middle of the sheet's largest panel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon
from shapely.ops import unary_union

from ..nest import Label, label_outlines

__all__ = ["CLEARANCE", "CORNER_HEIGHT", "TITLE_HEIGHT", "FRONT", "Mark", "sheet_marks"]

#: Paper kept between a mark's box and any cut or other mark (mm): a laser's engraving spreads
#: a few tenths of a millimetre, and a perforation's bridge must not be weakened by it.
CLEARANCE = 1.0
#: Height of a corner's mark and of the sheet's number and front mark (mm).
CORNER_HEIGHT = 3.0
TITLE_HEIGHT = 4.0
#: Spacing of the candidate places a mark is tried at (mm).
GRID = 0.5
#: Candidates tested at once, nearest first (the nearest free one is among the first few
#: hundred: a corner's mark sits a few millimetres from its corner).
CHUNK = 256
#: A mark that finds no place is tried this many times, each smaller by :data:`SHRINK`.
TRIES, SHRINK = 3, 0.75
#: The front mark's text.
FRONT = "FRONT"


@dataclass(frozen=True)
class Mark:
    """One engraved mark.

    Attributes
    ----------
    kind : str
        ``"sheet"``, ``"front"`` or ``"corner"``.
    text : str
    centre : (float, float)
        The centre of its box (drawing mm, y down).
    height : float
        Text height (mm).
    outlines : tuple of numpy.ndarray
        Its glyphs as closed polylines (drawing mm, y down).
    """

    kind: str
    text: str
    centre: tuple
    height: float
    outlines: tuple


def _glyphs(text: str, height: float) -> list:
    """A text's glyph outlines about the origin, in drawing axes (y down)."""
    out = label_outlines(Label(text, (0.0, 0.0), height, 0.0, ""))
    return [np.column_stack([g[:, 0], -g[:, 1]]) for g in out]


def _place(free, glyphs, target, grid):
    """The candidate centre nearest ``target`` whose mark box lies in ``free``, or None:
    candidates tried nearest first, :data:`CHUNK` at a time."""
    pts = np.concatenate(glyphs)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c = grid[np.argsort(np.linalg.norm(grid - target, axis=1), kind="stable")]
    shapely.prepare(free)
    for k in range(0, c.shape[0], CHUNK):
        g = c[k:k + CHUNK]
        ok = shapely.contains(free, shapely.box(g[:, 0] + lo[0], g[:, 1] + lo[1],
                                                g[:, 0] + hi[0], g[:, 1] + hi[1]))
        if ok.any():
            best = g[int(np.argmax(ok))]
            return best, shapely.box(*(best + lo), *(best + hi))
    return None


def sheet_marks(number: int, p, loop, corners: dict, cuts, holes=(), hole: float = 0.0,
                faces=()) -> tuple[list, list]:
    """The marks of one sheet, placed clear of its cuts (see the module notes).

    Parameters
    ----------
    number : int
        The sheet's number (1-based).
    p : numpy.ndarray, shape (V, 2)
        Its vertices on the page (drawing mm, y down).
    loop : list of int
        Its outline, as a vertex cycle.
    corners : dict of int to str
        The text of each corner to mark (vertex → ``"C·4"``).
    cuts : numpy.ndarray, shape (K, 2, 2)
        Its perforation cuts (drawing mm).
    holes : sequence of (float, float)
        Centres of its thread holes (drawing mm), of diameter ``hole``.
    faces : sequence of vertex cycles
        Its panels: the sheet's number and front mark go near the middle of the largest.

    Returns
    -------
    list of Mark
        The marks placed.
    list of str
        The texts that found no place, even at the smallest size tried.
    """
    p = np.asarray(p, dtype=np.float64)
    paper = Polygon(p[loop])
    blocked = [LineString(s) for s in np.asarray(cuts).reshape(-1, 2, 2)]
    blocked += [Point(c).buffer(0.5 * hole) for c in holes]
    free = paper.buffer(-CLEARANCE)
    if blocked:
        free = free.difference(unary_union(blocked).buffer(CLEARANCE, quad_segs=4))
    lo, hi = p[loop].min(axis=0), p[loop].max(axis=0)
    xs, ys = np.arange(lo[0], hi[0] + GRID, GRID), np.arange(lo[1], hi[1] + GRID, GRID)
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    panels = [Polygon(p[list(f)]) for f in faces if len(f) >= 3]
    middle = (np.asarray(max(panels, key=lambda f: f.area).centroid.coords[0]) if panels
              else np.asarray(paper.centroid.coords[0]))
    wanted = [("sheet", f"sheet {number}", TITLE_HEIGHT, middle),
              ("front", FRONT, TITLE_HEIGHT, middle)]
    wanted += [("corner", text, CORNER_HEIGHT, p[a]) for a, text in sorted(corners.items())]
    placed, missing = [], []
    for kind, text, height, target in wanted:
        if kind == "front" and placed:  # under the sheet's number, as one would write it
            target = np.asarray(placed[0].centre) + (0.0, 1.5 * placed[0].height)
        found = None
        for k in range(TRIES):
            glyphs = _glyphs(text, height * SHRINK ** k)
            found = _place(free, glyphs, target, grid)
            if found is not None:
                break
        if found is None:
            missing.append(text)
            continue
        (centre, box), h = found, height * SHRINK ** k
        placed.append(Mark(kind, text, (float(centre[0]), float(centre[1])), h,
                           tuple(g + centre for g in glyphs)))
        free = free.difference(box.buffer(CLEARANCE))
    return placed, missing
