"""Drawn curves: SVG paths (lines, arcs, Béziers, and shapes) and CSV polylines, as points in mm.

SVG is read with svgelements, which applies every transform, the viewBox and the units of the
document, and gives coordinates in CSS pixels (96 per inch): fabkit turns them into mm. The y
axis of SVG points down; the points returned have y up, so the curve looks as drawn. Each stroke
is sampled at equal steps of arclength (exact arcs and Béziers, evaluated by svgelements).

Functions here take the file's bytes and never open files.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from ..errors import ArgumentTypeError, FabkitError, InputFileError
from ..io.formats import damaged, parse_xml, refuse_count

__all__ = ["Curve", "CurveFileError", "read_curve", "curve_from_svg", "curve_from_csv",
           "svg_work", "MM_PER_PX"]

#: CSS pixels per inch (the SVG user unit when a document gives no other) and mm per pixel.
PX_PER_INCH = 96.0
MM_PER_PX = 25.4 / PX_PER_INCH
#: Points sampled per mm of curve, and the bounds on their number.
SAMPLES_PER_MM = 2.0
MIN_SAMPLES = 200
MAX_SAMPLES = 20_000
#: Points sampled from all the segments of a drawing together, before it is resampled.
MAX_TOTAL_SAMPLES = 200_000
#: No drawing reaches this far (mm): coordinates beyond are a damaged or hostile file.
MAX_COORDINATE_MM = 1e6
#: Largest curve file read, by the command line and by :func:`read_curve` alike.
MAX_CURVE_BYTES = 16 * 2**20
#: Most elements of an SVG drawing, counted while it is parsed and again with every ``<use>``
#: expanded (29 levels of ``<use>`` each doubling the one below would be 5e8), before
#: svgelements builds any of them.
MAX_SVG_ELEMENTS = 100_000
#: Most numbers in the path data (``d``, ``points``) of a drawing, ``<use>`` expanded, counted
#: before a segment is made: svgelements takes 14 s for 2e6 of them; a drawn curve has
#: thousands.
MAX_SVG_NUMBERS = 200_000
#: Most rows of a CSV curve (the curve is resampled to :data:`MAX_SAMPLES` points).
MAX_CSV_ROWS = 200_000
#: Strokes shorter than this (mm) are specks, not curves.
MIN_LENGTH_MM = 1.0


@dataclass(frozen=True)
class Curve:
    """A drawn curve.

    Attributes
    ----------
    points : numpy.ndarray, shape (M, 2)
        The curve in mm, y up, from its first to its last point.
    length : float
        Its length (mm).
    source : str
        ``"svg"`` or ``"csv"``.
    strokes : int
        How many strokes the file holds (the longest is used).
    """

    points: np.ndarray
    length: float
    source: str
    strokes: int = 1


def _polyline_length(p: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


def _straight(seg) -> bool:
    return type(seg).__name__ in ("Line", "Close")


def _samples(length_mm: float) -> float:
    """Points for a curved segment of this length (before the drawing's total is held)."""
    return min(MAX_SAMPLES, max(8.0, SAMPLES_PER_MM * length_mm)) if np.isfinite(
        length_mm) else 8.0


def _points(seg, t: np.ndarray) -> np.ndarray:
    """A segment's points at parameters ``t``, shape (len(t), 2)."""
    p = np.array(seg.npoint(t), dtype=np.float64) if hasattr(seg, "npoint") else \
        np.array([complex(seg.point(v)) for v in t])
    if np.iscomplexobj(p):
        p = np.column_stack([p.real, p.imag])
    return p


def _approximate_length(seg) -> float:
    """A curved segment's length to within a few per cent: its polyline through 9 points."""
    with np.errstate(over="ignore", invalid="ignore"):
        return _polyline_length(_points(seg, np.linspace(0.0, 1.0, 9)))


def svg_work(data: bytes) -> tuple:
    """The work of reading an SVG drawing, as counts of :data:`fabkit.io.workload.UNITS`, counted
    on its bytes before it is parsed.

    Besides its bytes: svgelements finds the start of a subpath for every close command (``Z``)
    by walking back to the last move (``M``), so a path of many segments and many ``Z`` without
    a move between them costs their product. Counted here as, for every piece of a path
    between two moves, its ``Z`` times its numbers (a bound on its segments).
    """
    import re

    scans = 0
    for d in re.findall(rb"\sd\s*=\s*(?:\"([^\"]*)\"|'([^']*)')", data):
        for piece in re.split(rb"[Mm]", d[0] or d[1]):
            closes = piece.count(b"z") + piece.count(b"Z")
            if closes:
                scans += closes * len(re.findall(rb"[0-9.]+", piece))
    return (("SVG byte", len(data)), ("SVG close scan", scans))


_XINCLUDE = "{http://www.w3.org/2001/XInclude}"
_XLINK_HREF = "{http://www.w3.org/1999/xlink}href"


def _numbers(element) -> int:
    import re

    text = (element.get("d") or "") + " " + (element.get("points") or "")
    return len(re.findall(r"[0-9.]+", text)) if text.strip() else 0


def svg_bounds(data: bytes, name: str) -> None:
    """Refuse a drawing past the bounds before svgelements reads it: its elements and their
    depth (counted while parsing, :func:`fabkit.io.formats.parse_xml`), and its elements and
    path numbers with every ``<use>`` expanded (each counted once per place it is used, from
    the counts of what it refers to: nothing is expanded to count it). XInclude is refused.

    Raises
    ------
    InputFileError
        ``kind="bounds"`` past :data:`MAX_SVG_ELEMENTS` or :data:`MAX_SVG_NUMBERS`;
        ``kind="damaged"`` not XML, or an XInclude.
    """
    root = parse_xml(data, name, max_elements=MAX_SVG_ELEMENTS, what="an SVG file")
    ids, elements = {}, list(root.iter())
    for el in elements:
        if str(el.tag).startswith(_XINCLUDE):
            raise damaged(name, "holds an XInclude (xi:include): fabkit reads a drawing from "
                                "its own file only; paste the included content in")
        if el.get("id") is not None:
            ids.setdefault(el.get("id"), el)
    sizes: dict = {}

    def size(el, stack=()) -> tuple[int, int]:  # (elements, numbers), <use> expanded
        key = id(el)
        if key in sizes:
            return sizes[key]
        if key in stack:  # a <use> loop: svgelements stops it; counted once here
            return (1, 0)
        n_el, n_num = 1, _numbers(el)
        href = el.get("href") or el.get(_XLINK_HREF) or ""
        targets = [ids[href[1:]]] if str(el.tag).endswith("use") and href[1:] in ids else []
        for child in [*el, *targets]:
            e, k = size(child, stack + (key,))
            n_el, n_num = min(n_el + e, 2**62), min(n_num + k, 2**62)
        sizes[key] = (n_el, n_num)
        return sizes[key]

    try:
        n_el, n_num = size(root)
    except RecursionError:  # <use> of <use> of ...: thousands deep
        raise InputFileError(name, "<use> elements that refer to each other thousands deep",
                             kind="bounds") from None
    refuse_count(name, "elements with every <use> expanded", n_el, MAX_SVG_ELEMENTS)
    refuse_count(name, "numbers in its path data with every <use> expanded", n_num,
                 MAX_SVG_NUMBERS, " (a drawn curve has thousands)")


def curve_from_svg(data: bytes, name: str = "curve.svg") -> Curve:
    """The longest stroke of an SVG document, sampled in mm.

    Parameters
    ----------
    data : bytes
        The SVG file's content.
    name : str
        For messages.

    Raises
    ------
    FabkitError
        Not SVG, or no stroke of positive length.
    """
    import svgelements as se

    svg_bounds(data, name)
    try:
        doc = se.SVG.parse(io.BytesIO(data))
    except Exception as exc:  # svgelements raises the XML parser's own errors
        raise damaged(name, f"not a readable SVG file ({type(exc).__name__}: "
                            f"{' '.join(str(exc).split())[:120]})") from None
    if not isinstance(doc, se.SVG):  # XML whose root is not <svg>
        raise FabkitError(f"{name}: not an SVG document (its root element is not <svg>)")
    subpaths = []
    for element in doc.elements():
        if not isinstance(element, se.Shape):
            continue
        path = element if isinstance(element, se.Path) else se.Path(element)
        for sub in path.as_subpaths():
            segs = [s for s in se.Path(sub) if not isinstance(s, se.Move)]
            if segs:
                subpaths.append(segs)
    # a straight segment needs its end only (the curve is resampled along straight pieces);
    # a curved one gets points by its length (a cheap one: a Bezier's exact length costs
    # 1 ms), all of them held to MAX_TOTAL_SAMPLES: 5000 long arcs would be 10^8 points
    counts = [[0.0 if _straight(seg) else _samples(_approximate_length(seg) * MM_PER_PX)
               for seg in segs] for segs in subpaths]
    total = sum(map(sum, counts))
    share = min(1.0, MAX_TOTAL_SAMPLES / total) if total else 1.0
    strokes = []
    for segs, ks in zip(subpaths, counts):
        pts, ends = [np.array([[complex(segs[0].start).real, complex(segs[0].start).imag]])], []
        for seg, k in zip(segs, ks):
            if not k:
                ends.append(complex(seg.end))
                continue
            if ends:
                pts.append(np.column_stack([np.real(ends), np.imag(ends)]))
                ends = []
            pts.append(_points(seg, np.linspace(0.0, 1.0, max(1, int(k * share)) + 1))[1:])
        if ends:
            pts.append(np.column_stack([np.real(ends), np.imag(ends)]))
        poly = np.concatenate(pts, axis=0) * MM_PER_PX
        poly[:, 1] = -poly[:, 1]
        _in_range(poly, name)
        if _polyline_length(poly) >= MIN_LENGTH_MM:
            strokes.append(poly)
    if not strokes:
        raise FabkitError(f"{name}: no path or shape of at least {MIN_LENGTH_MM:g} mm to follow")
    best = max(strokes, key=_polyline_length)
    return resampled_curve(best, "svg", len(strokes), name)


def curve_from_csv(data: bytes, name: str = "curve.csv") -> Curve:
    """A polyline from CSV rows ``x,y`` in mm (a header line and ``#`` comments are skipped).

    Raises
    ------
    FabkitError
        A row that is not two numbers, or fewer than two distinct points.
    """
    refuse_count(name, "lines", data.count(b"\n") + 1, MAX_CSV_ROWS,
                 " (a curve is resampled to 20 000 points)")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise damaged(name, "not a text file (CSV rows x,y in mm)") from None
    rows = []
    for n, line in enumerate(text.splitlines(), start=1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = [p for p in line.replace(";", ",").replace("\t", ",").split(",") if p.strip()]
        try:
            if len(parts) != 2:
                raise ValueError
            x, y = float(parts[0]), float(parts[1])
        except ValueError:
            if not rows:  # a header
                continue
            raise FabkitError(f"{name}: line {n}: expected two numbers x,y (mm), got "
                              f"{line[:60]!r}") from None
        if not (np.isfinite(x) and np.isfinite(y)):
            raise FabkitError(f"{name}: line {n}: coordinates must be finite")
        rows.append((x, y))
    pts = np.array(rows, dtype=np.float64).reshape(-1, 2)
    if pts.shape[0] < 2 or _polyline_length(pts) < MIN_LENGTH_MM:
        raise FabkitError(f"{name}: needs at least two points spanning {MIN_LENGTH_MM:g} mm")
    return resampled_curve(pts, "csv", 1, name)


class CurveFileError(FabkitError):
    """A curve file whose coordinates no drawing has (exit status 2, as a wish that cannot be
    met)."""

    code = "curve"
    exit_code = 2


def _in_range(p: np.ndarray, name: str) -> None:
    if not np.isfinite(p).all() or np.abs(p).max(initial=0.0) > MAX_COORDINATE_MM:
        raise CurveFileError(f"{name}: coordinates beyond {MAX_COORDINATE_MM:g} mm (1 km), or "
                             "not finite: not a drawing fabkit can follow")


def resampled_curve(p: np.ndarray, source: str, strokes: int, name: str = "curve") -> Curve:
    """A polyline as a :class:`Curve`, resampled evenly along its arclength.

    Repeated points are dropped; the curve gets :data:`SAMPLES_PER_MM` points a millimetre,
    at least :data:`MIN_SAMPLES` and at most :data:`MAX_SAMPLES`.

    Parameters
    ----------
    p : numpy.ndarray, shape (M, 2)
        The polyline (mm).
    source : str
        Where it came from (a file's kind, or ``"points"``), kept on the curve.
    strokes : int
        Strokes the drawing had, kept on the curve.
    name : str
        Named in the error.

    Returns
    -------
    Curve

    Raises
    ------
    CurveFileError
        Coordinates that are not finite or lie beyond :data:`MAX_COORDINATE_MM`.
    """
    _in_range(p, name)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 0])
    p = p[keep]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    length = float(s[-1])
    k = int(min(MAX_SAMPLES, max(MIN_SAMPLES, SAMPLES_PER_MM * length)))
    t = np.linspace(0.0, length, k)
    out = np.column_stack([np.interp(t, s, p[:, 0]), np.interp(t, s, p[:, 1])])
    return Curve(points=out, length=length, source=source, strokes=strokes)


def read_curve(data: bytes, name: str) -> Curve:
    """A curve from a file's bytes, by its name's suffix (``.svg`` or ``.csv``).

    Raises
    ------
    FabkitError
        Another suffix, or a file that holds no curve.
    InputFileError
        Past the readers' bounds (:data:`MAX_CURVE_BYTES`, elements, numbers, rows), or
        damaged (``kind="damaged"``).
    ArgumentTypeError
        ``data`` is not bytes (a path or the text itself: read the file in binary mode).
    """
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ArgumentTypeError("data", f"must be the file's content as bytes, got "
                                        f"{type(data).__name__} (open(path, 'rb').read())")
    data = bytes(data)
    refuse_count(name, "bytes", len(data), MAX_CURVE_BYTES)
    suffix = str(name).lower().rsplit(".", 1)[-1] if "." in str(name) else ""
    if suffix == "svg":
        return curve_from_svg(data, name)
    if suffix in ("csv", "txt"):
        return curve_from_csv(data, name)
    raise FabkitError(f"{name}: a curve is read from an .svg or a .csv file")
