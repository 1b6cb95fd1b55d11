"""Cut-ready sheets: creases as perforations a laser or a vinyl cutter can cut, the outline as a
cut.

A crease is cut as dashes of ``dash`` mm with ``gap`` mm of paper left between them, and the
perforation stops ``stop`` mm short of both ends: at a crease vertex several creases meet, and
cutting up to it would free the panels between them (the sheet falls apart); at the sheet's edge
the last bridge holds the panel to the outline. The dashes keep their length and their gaps
exactly; the pattern is centred on the crease, so both ends are left at least ``stop`` mm
uncut (at most ``stop + (dash + gap) / 2``). A crease shorter than ``2 stop + dash`` gets no
perforation (it is listed, to be scored by hand).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import PatternError

__all__ = ["PERFORATION", "Perforation", "perforate", "outline_loops", "SheetCuts", "sheet_cuts"]

#: Defaults (mm): cuts of 2 mm, bridges of 1 mm, 3 mm left whole at every vertex.
PERFORATION = {"perforation_dash": 2.0, "perforation_gap": 1.0, "perforation_stop": 3.0}


@dataclass(frozen=True)
class Perforation:
    """How a crease is perforated (mm).

    Attributes
    ----------
    dash : float
        Length of each cut.
    gap : float
        Paper left between cuts.
    stop : float
        Paper left whole at each end of a crease, at least.
    """

    dash: float
    gap: float
    stop: float

    @classmethod
    def from_settings(cls, settings) -> "Perforation":
        """From the resolved origami settings (:class:`~fabkit.settings.origami.OrigamiSettings`:
        its ``perforation_*`` fields, the defaults where they are None)."""
        values = {k: getattr(settings, k) for k in PERFORATION}
        s = {k: PERFORATION[k] if v is None else v for k, v in values.items()}
        return cls(float(s["perforation_dash"]), float(s["perforation_gap"]),
                   float(s["perforation_stop"]))


def perforate(p, q, perf: Perforation) -> np.ndarray:
    """The cuts along the segment ``p``-``q`` (mm).

    Returns
    -------
    numpy.ndarray, shape (K, 2, 2)
        Start and end of each cut; K = 0 when the crease is too short.

    Examples
    --------
    >>> perforate([0, 0], [20, 0], Perforation(2.0, 1.0, 3.0))[:, :, 0].tolist()
    [[3.0, 5.0], [6.0, 8.0], [9.0, 11.0], [12.0, 14.0], [15.0, 17.0]]
    >>> perforate([0, 0], [21, 0], Perforation(2.0, 1.0, 3.0))[[0, -1], :, 0].tolist()
    [[3.5, 5.5], [15.5, 17.5]]
    """
    p, q = np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64)
    length = float(np.linalg.norm(q - p))
    room = length - 2.0 * perf.stop
    n = int(np.floor((room + perf.gap) / (perf.dash + perf.gap))) if room > 0 else 0
    if n < 1:
        return np.zeros((0, 2, 2))
    used = n * perf.dash + (n - 1) * perf.gap
    start = perf.stop + 0.5 * (room - used)
    s0 = start + np.arange(n) * (perf.dash + perf.gap)
    u = (q - p) / length
    return np.stack([p + s0[:, None] * u, p + (s0 + perf.dash)[:, None] * u], axis=1)


def outline_loops(edges, boundary) -> list:
    """Closed loops of the boundary edges, as vertex cycles.

    Parameters
    ----------
    edges : array_like, shape (E, 2)
    boundary : array_like of bool, shape (E,)
        Which edges are the sheet's outline (assignment B or C).

    Raises
    ------
    PatternError
        A boundary vertex that does not have exactly two boundary edges (an open outline).
    """
    e = np.asarray(edges, dtype=np.int64)[np.asarray(boundary, dtype=bool)]
    nbrs: dict[int, list[int]] = {}
    for a, b in e.tolist():
        nbrs.setdefault(a, []).append(b)
        nbrs.setdefault(b, []).append(a)
    bad = [v for v, n in nbrs.items() if len(n) != 2]
    if bad:
        raise PatternError(f"the sheet's outline is not closed at vertex {bad[0]} "
                           f"({len(nbrs[bad[0]])} boundary edges meet there)", "assignment")
    loops, seen = [], set()
    for v0 in sorted(nbrs):
        if v0 in seen:
            continue
        loop, prev, v = [v0], None, v0
        seen.add(v0)
        while True:
            a, b = nbrs[v]
            nxt = a if a != prev else b
            if nxt == v0:
                break
            loop.append(nxt)
            seen.add(nxt)
            prev, v = v, nxt
        loops.append(loop)
    return loops


@dataclass(frozen=True)
class SheetCuts:
    """What a cutter cuts on one sheet (mm, the sheet's own flat coordinates).

    Attributes
    ----------
    outline : list of numpy.ndarray
        Closed polygons (the outline, and any inner cut loops).
    mountain, valley : numpy.ndarray, shape (K, 2, 2)
        Perforation cuts of the mountain and the valley creases.
    short : list of int
        Creases too short to perforate (pattern edge indices).
    """

    outline: list
    mountain: np.ndarray
    valley: np.ndarray
    short: list


def sheet_cuts(pattern, scale: float, perf: Perforation) -> SheetCuts:
    """Outline and perforations of a crease pattern at ``scale`` mm per design unit.

    Mountain and valley are the pattern's assignment; flat (F), unassigned (U) and join (J)
    edges are not cut.
    """
    v = np.asarray(pattern.vertices, dtype=np.float64) * scale
    edges = np.asarray(pattern.edges)
    lab = np.asarray(pattern.assignment)
    loops = outline_loops(edges, np.isin(lab, ["B", "C"]))
    outline = [v[loop] for loop in loops]
    cuts = {"M": [], "V": []}
    short = []
    for k, (a, b) in enumerate(edges.tolist()):
        if lab[k] not in cuts:
            continue
        seg = perforate(v[a], v[b], perf)
        if seg.shape[0] == 0:
            short.append(k)
        cuts[lab[k]].append(seg)
    stack = {m: (np.concatenate(c) if c else np.zeros((0, 2, 2))) for m, c in cuts.items()}
    return SheetCuts(outline, stack["M"], stack["V"], short)
