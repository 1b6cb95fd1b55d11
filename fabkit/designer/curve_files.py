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

from ..errors import FabkitError

__all__ = ["Curve", "read_curve", "curve_from_svg", "curve_from_csv", "MM_PER_PX"]

#: CSS pixels per inch (the SVG user unit when a document gives no other) and mm per pixel.
PX_PER_INCH = 96.0
MM_PER_PX = 25.4 / PX_PER_INCH
#: Points sampled per mm of curve, and the bounds on their number.
SAMPLES_PER_MM = 2.0
MIN_SAMPLES = 200
MAX_SAMPLES = 20_000
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

    try:
        doc = se.SVG.parse(io.BytesIO(data))
    except Exception as exc:  # svgelements raises the XML parser's own errors
        raise FabkitError(f"{name}: not a readable SVG file ({type(exc).__name__}: "
                          f"{' '.join(str(exc).split())[:120]})") from None
    strokes = []
    for element in doc.elements():
        if not isinstance(element, se.Shape):
            continue
        path = element if isinstance(element, se.Path) else se.Path(element)
        for sub in path.as_subpaths():
            sub = se.Path(sub)
            segs = [s for s in sub if not isinstance(s, se.Move)]
            if not segs:
                continue
            pts = []
            for seg in segs:
                length = float(seg.length()) * MM_PER_PX
                k = int(min(MAX_SAMPLES, max(8, SAMPLES_PER_MM * length)))
                t = np.linspace(0.0, 1.0, k + 1)
                p = np.array(seg.npoint(t), dtype=np.float64) if hasattr(seg, "npoint") else \
                    np.array([complex(seg.point(v)) for v in t])
                if np.iscomplexobj(p):
                    p = np.column_stack([p.real, p.imag])
                pts.append(p if not pts else p[1:])
            poly = np.concatenate(pts, axis=0) * MM_PER_PX
            poly[:, 1] = -poly[:, 1]
            if _polyline_length(poly) >= MIN_LENGTH_MM:
                strokes.append(poly)
    if not strokes:
        raise FabkitError(f"{name}: no path or shape of at least {MIN_LENGTH_MM:g} mm to follow")
    best = max(strokes, key=_polyline_length)
    return _resampled(best, "svg", len(strokes))


def curve_from_csv(data: bytes, name: str = "curve.csv") -> Curve:
    """A polyline from CSV rows ``x,y`` in mm (a header line and ``#`` comments are skipped).

    Raises
    ------
    FabkitError
        A row that is not two numbers, or fewer than two distinct points.
    """
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise FabkitError(f"{name}: not a text file (CSV rows x,y in mm)") from None
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
    return _resampled(pts, "csv", 1)


def _resampled(p: np.ndarray, source: str, strokes: int) -> Curve:
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
    """
    suffix = str(name).lower().rsplit(".", 1)[-1] if "." in str(name) else ""
    if suffix == "svg":
        return curve_from_svg(data, name)
    if suffix in ("csv", "txt"):
        return curve_from_csv(data, name)
    raise FabkitError(f"{name}: a curve is read from an .svg or a .csv file")
