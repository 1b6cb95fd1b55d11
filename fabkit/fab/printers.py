"""Bed layout: orient, arrange or split a printed network to fit a printer's bed.

The printers and their beds are a catalogue of what a design asks for
(:mod:`fabkit.settings.printers`); every profile keeps a margin free along the bed's edges
(:attr:`~fabkit.settings.printers.Printer.margin`).

:func:`bed_layout` turns the outlines of the pieces to print into a placement on beds:

1. **orient**: each piece is turned about the vertical axis to the angle (every degree, and
   every edge direction of its convex hull) whose bounding box fits the bed with the least
   area, keeping ``margin`` mm from the bed's edges;
2. **arrange**: the oriented pieces go in rows (shelves) on as few beds as needed, ``spacing``
   mm apart;
3. a piece that fits no bed in any orientation is refused with the size it needs
   (:class:`~fabkit.errors.FabricationError`).

Splitting a chain is the caller's choice of pieces (:func:`chain_pieces`): a chain of modules is
cut at a port between two modules, both pieces keep the two nodes of that port (each as a hinge
hub), and the maker joins them by laying the second piece's hubs on the first piece's and
pinning each pair (see docs/printing.md, "Joining split prints").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import FabricationError
from ..numerics import MM_SLACK
from ..settings.printers import Printer, PRINTERS
from ..model.network import chain_port_number, is_chain_port

__all__ = ["Placement", "bed_layout", "best_orientation", "chain_pieces", "split_to_fit"]

def _hull(points) -> np.ndarray:
    from scipy.spatial import ConvexHull

    p = np.asarray(points, dtype=np.float64)[:, :2]
    try:
        return p[ConvexHull(p).vertices]
    except Exception:  # degenerate (collinear) outlines: the points themselves bound it
        return p


def best_orientation(points, width: float, depth: float) -> tuple[float, float, float] | None:
    """The turn about z (degrees) that fits the points' outline in a ``width`` × ``depth``
    rectangle with the smallest bounding box, or None.

    Returns
    -------
    (angle, w, h) or None
        Angle in degrees (counter-clockwise) and the turned outline's extents (mm).

    Examples
    --------
    >>> strip = [[0, 0], [207, 0], [207, 16], [0, 16]]
    >>> round(best_orientation(strip, 190, 190)[0]) % 90 != 0
    True
    >>> best_orientation(strip, 100, 100) is None
    True
    """
    hull = _hull(points)
    edges = np.diff(np.vstack([hull, hull[:1]]), axis=0)
    candidates = np.concatenate([np.arange(0.0, 180.0, 1.0),
                                 np.degrees(np.arctan2(edges[:, 1], edges[:, 0])) % 180.0,
                                 (np.degrees(np.arctan2(edges[:, 1], edges[:, 0])) + 90) % 180])
    best = None
    for ang in np.unique(np.round(candidates, 9)):
        c, s = math.cos(math.radians(ang)), math.sin(math.radians(ang))
        x = hull[:, 0] * c - hull[:, 1] * s
        y = hull[:, 0] * s + hull[:, 1] * c
        w, h = float(np.ptp(x)), float(np.ptp(y))
        if w <= width + MM_SLACK and h <= depth + MM_SLACK and (best is None or w * h < best[1] * best[2]
                                                         - MM_SLACK):
            best = (float(ang), w, h)
    return best


@dataclass(frozen=True)
class Placement:
    """Where one piece goes: bed number, turn about z (degrees, about the piece's own origin),
    then translation (mm) that puts it on the bed (bed corner at the origin); ``size`` and
    ``box_lo`` are the turned piece's bounding box on the bed."""

    piece: int
    bed: int
    angle: float
    offset: tuple[float, float]
    size: tuple[float, float]
    box_lo: tuple[float, float] = (0.0, 0.0)

    def matrix(self) -> np.ndarray:
        """3 × 4 affine map ``x' = R x + t`` (rows), mm."""
        c, s = math.cos(math.radians(self.angle)), math.sin(math.radians(self.angle))
        return np.array([[c, -s, 0.0, self.offset[0]], [s, c, 0.0, self.offset[1]],
                         [0.0, 0.0, 1.0, 0.0]])


def _min_size(points) -> tuple[float, float]:
    """Smallest (long, short) extents of the outline over all turns."""
    hull = _hull(points)
    best = None
    for ang in np.arange(0.0, 180.0, 0.5):
        c, s = math.cos(math.radians(ang)), math.sin(math.radians(ang))
        w = float(np.ptp(hull[:, 0] * c - hull[:, 1] * s))
        h = float(np.ptp(hull[:, 0] * s + hull[:, 1] * c))
        long, short = max(w, h), min(w, h)
        if best is None or short < best[1] - MM_SLACK or (abs(short - best[1]) < MM_SLACK
                                                       and long < best[0]):
            best = (long, short)
    return best


def bed_layout(outlines, printer: Printer, *, margin: float | None = None,
               spacing: float = 5.0) -> list[Placement]:
    """Orient each piece and arrange the pieces in rows on as few beds as needed.

    Parameters
    ----------
    outlines : list of array_like, shape (n_i, 2)
        Each piece's outline points (mm), in its own frame.
    printer : Printer
    margin : float, optional
        Distance kept from the bed's edges (mm; default the printer's :attr:`Printer.margin`).
    spacing : float
        Gap between pieces (mm).

    Returns
    -------
    list of Placement
        One per piece, in the order given.

    Raises
    ------
    FabricationError
        A piece that fits the bed in no orientation; the message gives the bed it needs.
    """
    margin = printer.margin if margin is None else float(margin)
    W, H = printer.width - 2 * margin, printer.depth - 2 * margin
    oriented = []
    for k, pts in enumerate(outlines):
        fit = best_orientation(pts, W, H)
        if fit is None:
            long, short = _min_size(pts)
            raise FabricationError(
                f"piece {k + 1} needs a bed of at least {math.ceil(long + 2 * margin):d} x "
                f"{math.ceil(short + 2 * margin):d} mm (turned to fit, {margin:g} mm from each edge); "
                f"the {printer.name} bed is {printer.width:g} x {printer.depth:g} mm: choose a "
                f"larger printer (print.printer = {', '.join(PRINTERS)}) or lower print.scale")
        oriented.append(fit)
    placements: list[Placement | None] = [None] * len(outlines)
    bed, x, y, row = 0, 0.0, 0.0, 0.0
    for k in sorted(range(len(outlines)), key=lambda i: -oriented[i][2]):  # tallest rows first
        ang, w, h = oriented[k]
        if x > 0 and x + w > W + MM_SLACK:  # next row
            x, y, row = 0.0, y + row + spacing, 0.0
        if y > 0 and y + h > H + MM_SLACK:  # next bed
            bed, x, y, row = bed + 1, 0.0, 0.0, 0.0
        hull = _hull(outlines[k])
        c, s = math.cos(math.radians(ang)), math.sin(math.radians(ang))
        lo = np.array([(hull[:, 0] * c - hull[:, 1] * s).min(),
                       (hull[:, 0] * s + hull[:, 1] * c).min()])
        placements[k] = Placement(k, bed, ang, (float(margin + x - lo[0]),
                                                float(margin + y - lo[1])), (w, h),
                                  (float(margin + x), float(margin + y)))
        x += w + spacing
        row = max(row, h)
    # centre each bed's content: slicers that keep positions then print it mid-bed
    out = []
    for b in range(bed + 1):
        mine = [p for p in placements if p.bed == b]
        pts = []
        for p in mine:
            hull = _hull(outlines[p.piece])
            m = p.matrix()
            pts.append(hull @ m[:2, :2].T + m[:2, 3])
        allp = np.vstack(pts)
        shift = 0.5 * (np.array([printer.width, printer.depth]) - allp.min(0) - allp.max(0))
        out.extend(Placement(p.piece, b, p.angle, (p.offset[0] + float(shift[0]),
                                                   p.offset[1] + float(shift[1])), p.size,
                             (p.box_lo[0] + float(shift[0]), p.box_lo[1] + float(shift[1])))
                   for p in mine)
    return sorted(out, key=lambda p: p.piece)


def chain_pieces(net, n_pieces: int) -> list[tuple[np.ndarray, str]]:
    """Cut a chain of modules into ``n_pieces`` runs of whole modules.

    The chain's ports d1, d2, ... mark the joins between modules; a cut at port d_k keeps its two
    nodes in both pieces.

    Parameters
    ----------
    net : Network
        A chain (ports d1 .. d_{n+1}, each interior port separating the network).
    n_pieces : int

    Returns
    -------
    list of (nodes, cut)
        Each piece's node indices (sorted) and the port it ends at (``""`` for the last).

    Raises
    ------
    FabricationError
        Not a chain, or more pieces than modules.
    """
    chain = sorted((p for p in net.ports if is_chain_port(p)), key=chain_port_number)
    modules = len(chain) - 1
    if modules < 2 or n_pieces > modules:
        raise FabricationError(f"cannot split into {n_pieces} pieces: the network is not a chain "
                               f"of at least {n_pieces} modules (ports d1, d2, ...)")
    # module k: the ports d_k and d_{k+1} and the network's pieces between them once every
    # port node is taken out
    ports = [set(net.port(p)) for p in chain]
    port_nodes = set().union(*ports)
    adj = net.adjacency()
    members = [set(ports[k]) | ports[k + 1] for k in range(modules)]
    seen: set = set()
    for v0 in range(net.n_nodes):
        if v0 in port_nodes or v0 in seen:
            continue
        comp, stack, touched = set(), [v0], set()
        while stack:
            v = stack.pop()
            if v in comp:
                continue
            comp.add(v)
            for u in adj[v]:
                if u in port_nodes:
                    touched.add(u)
                elif u not in comp:
                    stack.append(u)
        seen |= comp
        # the module whose two ports hold every port node the piece touches (consecutive ports
        # may share a node, as in chains of the paper's three-port modules)
        fits = [k for k in range(modules) if touched <= members[k]]
        k = fits[0] if fits else min(
            (k for k, pn in enumerate(ports) if pn & touched), default=0)
        members[min(k, modules - 1)] |= comp
    bounds = np.linspace(0, modules, n_pieces + 1).round().astype(int)
    return [(np.array(sorted(set().union(*members[a:b]))), chain[b] if b < modules else "")
            for a, b in zip(bounds[:-1], bounds[1:])]


def split_to_fit(net, outline, printer: Printer, *, margin: float | None = None):
    """The whole network on the bed, or else a chain cut into the fewest runs of modules that fit.

    Parameters
    ----------
    net : Network
    outline : callable
        ``outline(nodes) -> (k, 2)`` points (mm) bounding the print of those nodes, in its own
        frame.
    printer : Printer
    margin : float, optional
        Distance kept from the bed's edges (default the printer's).

    Returns
    -------
    pieces : list of (nodes, cut)
        As :func:`chain_pieces` (one piece, ``cut = ""``, when the whole fits).
    layout : list of Placement
        One per piece (:func:`bed_layout`).

    Raises
    ------
    FabricationError
        The whole fits in no orientation and is not a chain, or even single modules do not fit.
    """
    whole = [(np.arange(net.n_nodes), "")]
    try:
        return whole, bed_layout([outline(whole[0][0])], printer, margin=margin)
    except FabricationError as exc:
        refusal = exc
    chain = [p for p in net.ports if is_chain_port(p)]
    for n in range(2, len(chain)):
        try:
            pieces = chain_pieces(net, n)
        except FabricationError:
            break
        try:
            return pieces, bed_layout([outline(nodes) for nodes, _ in pieces], printer,
                                      margin=margin)
        except FabricationError as exc:
            refusal = exc
    raise FabricationError(f"the print does not fit the {printer.name} bed ({printer.width:g} x "
                           f"{printer.depth:g} mm): {refusal}")
