"""The guide's text written into its PDF directly, not glyph by glyph by matplotlib.

matplotlib lays out and draws every text of a PDF glyph by glyph through FreeType (a few tens of
microseconds a glyph on the developers' machine: the running text of the AND gate's 22 pages,
some 40 000 characters, cost 2.4 s of its 6.9 s of pages). The guide's text (the headers, the
lines of its blocks and the labels of its drawings, marked with :data:`LAYER_GID`, none
rotated) needs none of that: :func:`text_runs` places each such text where matplotlib would
(its alignment measured with the font's own metrics, read once with fontTools; a label's white
patch with it), the page is saved by matplotlib with those texts hidden, and
:func:`add_text_layer` appends them to the finished PDF as an
incremental update (the PDF standard's way of adding to a file: new objects, a new cross-reference
section pointing back at the old one): a content stream per page that draws the runs in the same
DejaVu faces, embedded as TrueType subsets like matplotlib's own, with a ToUnicode map so every
reader extracts the words. The figure keeps the texts, so a page's PNG and the clipping check
draw and measure them as before.

Glyphs are set at their advance widths, without kerning (a line is at most a few tenths of a
point longer than matplotlib sets it) and without ligatures (``fi`` stays two glyphs, as a
reader searching the text wants).
"""

from __future__ import annotations

import hashlib
import io
import re
import zlib
from dataclasses import dataclass
from functools import lru_cache

from ...errors import FabkitError

__all__ = ["LAYER_GID", "TextRun", "add_text_layer", "off_page", "text_runs"]

#: ``gid`` of a figure text that goes to the text layer (set on the guide's running text).
LAYER_GID = "fabkit-pdf-text"

#: Text coordinates are written to this many decimals of a point (1/1000 pt: far below a
#: printer's dot, and the same text always gives the same bytes).
COORD_DECIMALS = 3

#: Font tables the layer's subsets leave out: glyphs are placed by their advances alone (no
#: shaping, kerning or ligatures). Removed before subsetting: the subsetter otherwise decodes
#: the layout tables only to drop them (three times the time, 0.14 → 0.05 s a face).
UNUSED_TABLES = ("GSUB", "GPOS", "GDEF", "kern", "FFTM")

#: zlib level of the layer's streams (matplotlib's own streams use zlib's default, 6).
ZLIB_LEVEL = 6


@dataclass(frozen=True)
class TextRun:
    """One line of text at its baseline.

    Attributes
    ----------
    x, y : float
        Start of the baseline, points from the page's lower-left corner.
    size : float
        Points.
    font : str
        Path of the TrueType file (as matplotlib's font manager finds it for the text).
    text : str
    rgb : tuple of float
        Fill colour, each in [0, 1].
    box : tuple of float or None
        ``(x0, y0, x1, y1)`` in points: a rectangle filled under the text (a label's white
        patch), or None.
    box_rgba : tuple of float
        The rectangle's fill colour and opacity.
    """

    x: float
    y: float
    size: float
    font: str
    text: str
    rgb: tuple = (0.0, 0.0, 0.0)
    box: tuple | None = None
    box_rgba: tuple = (1.0, 1.0, 1.0, 1.0)


class _Face:
    """A TrueType font's metrics for layout: advances and ink bounds per character."""

    def __init__(self, path: str):
        from fontTools.ttLib import TTFont

        self.path = path
        font = TTFont(path, lazy=True)
        self.upem = float(font["head"].unitsPerEm)
        self.cmap = font.getBestCmap() or {}
        self.hmtx = font["hmtx"].metrics
        self.glyf = font["glyf"] if "glyf" in font else None
        os2 = font["OS/2"] if "OS/2" in font else None
        if os2 is not None:
            self.ascent, self.descent = float(os2.sTypoAscender), float(-os2.sTypoDescender)
            self.line_gap = float(os2.sTypoLineGap)
        else:
            hhea = font["hhea"]
            self.ascent, self.descent = float(hhea.ascent), float(-hhea.descent)
            self.line_gap = float(hhea.lineGap)
        self.ps_name = re.sub(r"[^A-Za-z0-9-]", "", font["name"].getDebugName(6) or "Font")
        self._ink: dict = {}

    def glyph(self, ch: str) -> str:
        return self.cmap.get(ord(ch), ".notdef")

    def advance(self, text: str) -> float:
        """Advance width of ``text`` in font units."""
        return float(sum(self.hmtx[self.glyph(ch)][0] for ch in text))

    def ink(self, text: str) -> tuple[float, float]:
        """Highest and lowest point of the glyphs of ``text`` (font units, y up)."""
        top, bottom = 0.0, 0.0
        for ch in set(text):
            if ch not in self._ink:
                g = self.glyf[self.glyph(ch)] if self.glyf is not None else None
                box = (float(getattr(g, "yMax", 0.0)), float(getattr(g, "yMin", 0.0))) \
                    if g is not None and getattr(g, "numberOfContours", 0) != 0 else (0.0, 0.0)
                self._ink[ch] = box
            top, bottom = max(top, self._ink[ch][0]), min(bottom, self._ink[ch][1])
        return top, bottom


@lru_cache(maxsize=8)
def _face(path: str) -> _Face:
    return _Face(path)


def text_runs(fig, texts) -> list[TextRun]:
    """Where the figure's ``texts`` stand on the page, as :class:`TextRun` lines.

    Each text is laid out as matplotlib (3.11) lays out a text of ``linespacing="normal"``: a
    line reaches at least the font's typographic ascent above its baseline and its descent
    below, lines of a text of several lines are a line gap apart, and the box so made is
    aligned by the text's ``ha`` and ``va`` at its position (any transform: the position is
    taken to the figure's pixels, then to points).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Saved at 72 dpi (a PDF page: one unit is one point).
    texts : iterable of matplotlib.text.Text
        Without rotation.

    Returns
    -------
    list of TextRun

    Raises
    ------
    FabkitError
        A rotated text, or one in math mode.
    """
    from matplotlib.colors import to_rgb
    from matplotlib.font_manager import findfont

    runs = []
    for t in texts:
        if t.get_rotation() % 360.0 != 0.0:
            raise FabkitError(f"the PDF text layer sets no rotated text ({t.get_text()[:40]!r})")
        x, y = t.get_transform().transform(t.get_position())
        # display units of the figure at its dpi → points
        x, y = x * 72.0 / fig.dpi, y * 72.0 / fig.dpi
        face = _face(findfont(t.get_fontproperties()))
        size = float(t.get_fontsize())
        scale = size / face.upem
        lines = t.get_text().split("\n")
        gap = face.line_gap * scale if len(lines) > 1 else 0.0
        metrics = []
        for line in lines:
            top, bottom = face.ink(line) if line else (0.0, 0.0)
            a = max(top * scale, face.ascent * scale) + gap / 2
            d = max(-bottom * scale, face.descent * scale) + gap / 2
            metrics.append((face.advance(line) * scale, a, d))
        height = sum(a + d for _, a, d in metrics)
        width = max(w for w, _, _ in metrics)
        va, ha = t.get_verticalalignment(), t.get_horizontalalignment()
        if va == "top":
            top_y = y
        elif va == "bottom":
            top_y = y + height
        elif va == "center":
            top_y = y + height / 2
        elif va == "baseline":
            top_y = y + metrics[0][1]
        else:  # center_baseline
            top_y = y + (metrics[0][1] - metrics[0][2]) / 2 + metrics[0][2]
        left = {"left": x, "center": x - width / 2, "right": x - width}[ha]
        malign = ha  # the guide sets no multialignment of its own
        rgb = tuple(float(c) for c in to_rgb(t.get_color()))
        box, box_rgba = _box(t, left, top_y, width, height, size)
        base = top_y
        for line, (w, a, d) in zip(lines, metrics):
            base -= a
            shift = {"left": 0.0, "center": (width - w) / 2, "right": width - w}[malign]
            if line:
                runs.append(TextRun(left + shift, base, size, face.path, line, rgb, box,
                                    box_rgba))
                box = None  # a text's patch is drawn once, under its first line
            base -= d
    return runs


def _box(t, left, top, width, height, size):
    """The text's patch (``bbox=``) as the rectangle matplotlib draws for a square box style:
    the text's box grown by the style's pad (a fraction of the font size); (None, white)
    without one."""
    patch = t.get_bbox_patch()
    if patch is None or not patch.get_visible():
        return None, (1.0, 1.0, 1.0, 1.0)
    style = patch.get_boxstyle()
    edge = patch.get_edgecolor()
    if type(style).__name__ != "Square" or (patch.get_linewidth() > 0 and edge[3] > 0):
        raise FabkitError("the PDF text layer draws a text's box only as a square without an "
                          f"edge ({t.get_text()[:40]!r})")
    pad = float(style.pad) * size
    rgba = tuple(float(c) for c in patch.get_facecolor())
    return (left - pad, top - height - pad, left + width + pad, top + pad), rgba


def off_page(runs, width: float, height: float, slack: float = 0.5) -> list[str]:
    """The texts of ``runs`` whose glyphs reach past a page of ``width`` × ``height`` points.

    A run's extent is its advance along the baseline and its glyphs' ink above and below it,
    measured from the font's tables as the layer sets it; ``slack`` (points) is what a text may
    touch beyond the edge (matplotlib's clipping check allows half a pixel too).

    Parameters
    ----------
    runs : iterable of TextRun
    width, height : float
        The page, points.
    slack : float

    Returns
    -------
    list of str
        In the order of ``runs``, each text once.
    """
    out: list[str] = []
    for r in runs:
        face = _face(r.font)
        scale = r.size / face.upem
        top, bottom = face.ink(r.text)
        x1 = r.x + face.advance(r.text) * scale
        if (r.x < -slack or x1 > width + slack or r.y + bottom * scale < -slack
                or r.y + top * scale > height + slack) and r.text not in out:
            out.append(r.text)
    return out


# -- the PDF ------------------------------------------------------------------------------------

def _fmt(v: float) -> str:
    s = f"{v:.{COORD_DECIMALS}f}".rstrip("0").rstrip(".")
    return "0" if s in ("", "-0") else s


def _stream(data: bytes) -> bytes:
    packed = zlib.compress(data, ZLIB_LEVEL)
    return (b"<< /Length %d /Filter /FlateDecode >>\nstream\n" % len(packed) + packed
            + b"\nendstream")


class _Pdf:
    """The objects of a PDF written with a classic cross-reference table (matplotlib's)."""

    def __init__(self, data: bytes):
        self.data = data
        m = re.search(rb"startxref\s+(\d+)\s+%%EOF\s*$", data)
        if m is None:
            raise FabkitError("the guide's PDF has no cross-reference table at its end")
        self.xref = int(m.group(1))
        if data[self.xref:self.xref + 4] != b"xref":
            raise FabkitError("the guide's PDF uses a cross-reference stream, which the text "
                              "layer does not read")
        self.offsets: dict[int, int] = {}
        pos = self.xref + 4
        sub = re.compile(rb"\s*(\d+) (\d+)\s*\n")
        while True:
            m = sub.match(data, pos)
            if m is None:
                break
            start, count = int(m.group(1)), int(m.group(2))
            pos = m.end()
            for k in range(count):
                entry = data[pos:pos + 20]
                if entry[17:18] == b"n":
                    self.offsets[start + k] = int(entry[:10])
                pos += 20
        m = re.compile(rb"\s*trailer\s*<<(.*?)>>\s*startxref", re.S).match(data, pos)
        if m is None:
            raise FabkitError("the guide's PDF has no trailer after its cross-reference table")
        self.trailer = m.group(1)
        self.size = int(self.find(self.trailer, rb"/Size (\d+)"))

    @staticmethod
    def find(text: bytes, pattern: bytes) -> bytes:
        m = re.search(pattern, text)
        if m is None:
            raise FabkitError(f"the guide's PDF lacks {pattern.decode()!r} where the text "
                              "layer looks for it")
        return m.group(1)

    def body(self, num: int) -> bytes:
        """The text of object ``num`` between ``obj`` and ``endobj`` (dictionaries only)."""
        at = self.offsets.get(num)
        if at is None:
            raise FabkitError(f"the guide's PDF has no object {num}")
        m = re.compile(rb"%d 0 obj\s*(.*?)\s*endobj" % num, re.S).match(self.data, at)
        if m is None:
            raise FabkitError(f"object {num} of the guide's PDF is not where its table says")
        return m.group(1)

    def ref(self, num: int, key: bytes) -> int:
        return int(self.find(self.body(num), rb"/" + key + rb" (\d+) 0 R"))

    def pages(self) -> list[int]:
        root = int(self.find(self.trailer, rb"/Root (\d+) 0 R"))
        kids = self.find(self.body(self.ref(root, b"Pages")), rb"/Kids\s*\[([^\]]*)\]")
        return [int(k) for k in re.findall(rb"(\d+) 0 R", kids)]


def _subset_tag(glyphs) -> str:
    digest = hashlib.sha1("\0".join(sorted(glyphs)).encode()).digest()
    return "".join(chr(65 + b % 26) for b in digest[:6])


def _font_objects(face: _Face, chars: set, first: int) -> tuple[list[bytes], dict]:
    """The five objects of ``face`` subset to ``chars`` (numbered from ``first``: Type0 font,
    CID font, descriptor, font file, ToUnicode map) and each character's 2-byte code."""
    from fontTools import subset
    from fontTools.ttLib import TTFont

    options = subset.Options()
    options.layout_features = []
    options.name_IDs = ["*"]
    options.notdef_outline = True
    options.recalc_bounds = True
    options.drop_tables += list(UNUSED_TABLES)
    sub = subset.Subsetter(options)
    sub.populate(unicodes=sorted(ord(c) for c in chars))
    font = TTFont(face.path, recalcTimestamp=False)  # the same text, the same bytes
    for tag in UNUSED_TABLES:  # dropped before the subsetter reads them (the same bytes)
        if tag in font:
            del font[tag]
    sub.subset(font)
    order = font.getGlyphOrder()
    gid = {name: k for k, name in enumerate(order)}
    cmap = font.getBestCmap() or {}
    codes = {c: gid.get(cmap.get(ord(c), ".notdef"), 0) for c in chars}
    buf = io.BytesIO()
    font.save(buf)
    program = buf.getvalue()
    name = f"{_subset_tag(order)}+{face.ps_name}".encode()
    k = 1000.0 / face.upem
    metrics = font["hmtx"].metrics
    widths = b" ".join(b"%d [ %s ]" % (g, _fmt(metrics[n][0] * k).encode())
                       for g, n in enumerate(order))
    head = font["head"]
    bbox = " ".join(_fmt(v * k) for v in (head.xMin, head.yMin, head.xMax, head.yMax))
    t0, cid, desc, file_, tounicode = range(first, first + 5)
    unicode_of: dict = {}
    for c in sorted(chars):
        unicode_of.setdefault(codes[c], c)
    cmap_text = "\n".join(f"<{g:04X}> <{u.encode('utf-16-be').hex().upper()}>"
                          for g, u in sorted(unicode_of.items()))
    to_unicode = ("/CIDInit /ProcSet findresource begin\n12 dict begin\nbegincmap\n"
                  "/CIDSystemInfo << /Registry (Adobe) /Ordering (UCS) /Supplement 0 >> def\n"
                  "/CMapName /Adobe-Identity-UCS def\n/CMapType 2 def\n"
                  "1 begincodespacerange\n<0000> <FFFF>\nendcodespacerange\n"
                  f"{len(unicode_of)} beginbfchar\n{cmap_text}\nendbfchar\n"
                  "endcmap\nCMapName currentdict /CMap defineresource pop\nend\nend\n").encode()
    packed = zlib.compress(program, ZLIB_LEVEL)
    objects = [
        b"<< /Type /Font /Subtype /Type0 /BaseFont /%s /Encoding /Identity-H "
        b"/DescendantFonts [ %d 0 R ] /ToUnicode %d 0 R >>" % (name, cid, tounicode),
        b"<< /Type /Font /Subtype /CIDFontType2 /BaseFont /%s /CIDSystemInfo << /Registry "
        b"(Adobe) /Ordering (Identity) /Supplement 0 >> /FontDescriptor %d 0 R "
        b"/CIDToGIDMap /Identity /W [ %s ] >>" % (name, desc, widths),
        b"<< /Type /FontDescriptor /FontName /%s /Flags 32 /FontBBox [ %s ] /Ascent %s "
        b"/Descent %s /CapHeight 0 /ItalicAngle 0 /StemV 0 /FontFile2 %d 0 R >>"
        % (name, bbox.encode(), _fmt(face.ascent * k).encode(),
           _fmt(-face.descent * k).encode(), file_),
        b"<< /Length %d /Length1 %d /Filter /FlateDecode >>\nstream\n" % (len(packed),
                                                                          len(program))
        + packed + b"\nendstream",
        _stream(to_unicode),
    ]
    return objects, codes


def _page_stream(runs, names: dict, codes: dict, opacity: dict) -> bytes:
    """The page's layer: ``Q`` (matplotlib's drawing was wrapped in ``q``), then each run's
    box and text in order (a label's patch under it, as matplotlib draws them)."""
    out = ["Q"]
    for r in runs:
        if r.box is not None and r.box_rgba[3] > 0:
            x0, y0, x1, y1 = r.box
            alpha = f" /{opacity[r.box_rgba[3]]} gs" if r.box_rgba[3] < 1 else ""
            out.append(f"q{alpha} " + " ".join(_fmt(c) for c in r.box_rgba[:3])
                       + f" rg {_fmt(x0)} {_fmt(y0)} {_fmt(x1 - x0)} {_fmt(y1 - y0)} re f Q")
        hexed = "".join(f"{codes[r.font][c]:04X}" for c in r.text)
        out.append("BT " + " ".join(_fmt(c) for c in r.rgb)
                   + f" rg /{names[r.font]} {_fmt(r.size)} Tf 1 0 0 1 {_fmt(r.x)} {_fmt(r.y)} "
                   f"Tm <{hexed}> Tj ET")
    return ("\n".join(out) + "\n").encode()


def _extended(doc: _Pdf, res_body: bytes, key: bytes, entries: bytes, number: int):
    """``res_body`` (a resource dictionary) with ``entries`` added to its ``key`` dictionary:
    ``(body, new dictionary or None)``; the new dictionary, when the old one was an object of
    its own, is to be written as object ``number`` and referred to."""
    if not entries:
        return res_body, None
    m = re.search(rb"/" + key + rb"\s+(\d+) 0 R", res_body)
    if m is not None:
        inner = doc.body(int(m.group(1))).strip()
        if not (inner.startswith(b"<<") and inner.endswith(b">>")):
            raise FabkitError(f"the guide's PDF has a /{key.decode()} entry the text layer "
                              "cannot extend")
        return (res_body[:m.start()] + b"/%s %d 0 R" % (key, number) + res_body[m.end():],
                inner[:-2].rstrip() + b" " + entries + b" >>")
    if re.search(rb"/" + key + rb"\b", res_body):
        raise FabkitError(f"the guide's PDF has a /{key.decode()} entry the text layer "
                          "cannot extend")
    return res_body.replace(b"<<", b"<< /%s << %s >>" % (key, entries), 1), None


def add_text_layer(pdf: bytes, runs_per_page) -> bytes:
    """``pdf`` with each page's runs drawn over it (an incremental update of the file).

    Parameters
    ----------
    pdf : bytes
        A PDF written by matplotlib (a classic cross-reference table; pages that share one
        resource dictionary or have their own).
    runs_per_page : sequence of list of TextRun
        One list per page, in page order.

    Returns
    -------
    bytes
        The same file with the new objects appended; ``pdf`` itself when there are no runs.

    Raises
    ------
    FabkitError
        The PDF is not laid out as matplotlib writes it (then nothing is changed), or has another
        number of pages.
    """
    runs_per_page = [list(r) for r in runs_per_page]
    if not any(runs_per_page):
        return pdf
    doc = _Pdf(pdf)
    pages = doc.pages()
    if len(pages) != len(runs_per_page):
        raise FabkitError(f"the text layer has {len(runs_per_page)} pages for a PDF of "
                          f"{len(pages)}")
    fonts = sorted({r.font for runs in runs_per_page for r in runs})
    chars = {f: set() for f in fonts}
    for runs in runs_per_page:
        for r in runs:
            chars[r.font].update(r.text)
    new: dict[int, bytes] = {}
    nxt = doc.size
    names, codes, refs = {}, {}, []
    for k, path in enumerate(fonts):
        objects, codes[path] = _font_objects(_face(path), chars[path], nxt)
        names[path] = f"FkText{k + 1}"
        refs.append(b"/%s %d 0 R" % (names[path].encode(), nxt))  # the Type0 font, first
        for obj in objects:
            new[nxt] = obj
            nxt += 1
    font_refs = b" ".join(refs)
    alphas = sorted({r.box_rgba[3] for runs in runs_per_page for r in runs
                     if r.box is not None and 0 < r.box_rgba[3] < 1})
    opacity = {a: f"FkAlpha{k + 1}" for k, a in enumerate(alphas)}
    states = b" ".join(b"/%s << /ca %s >>" % (opacity[a].encode(), _fmt(a).encode())
                       for a in alphas)
    save = nxt
    new[save] = _stream(b"q\n")
    nxt += 1
    rewritten: dict[int, int] = {}  # a page's resources → their copy with the layer's fonts
    for page, runs in zip(pages, runs_per_page):
        if not runs:
            continue
        body = doc.body(page)
        res = int(doc.find(body, rb"/Resources (\d+) 0 R"))
        contents = doc.find(body, rb"/Contents (\d+ 0 R|\[[^\]]*\])")
        if res not in rewritten:
            res_body = doc.body(res)
            for key, entries in ((b"Font", font_refs), (b"ExtGState", states)):
                res_body, extended = _extended(doc, res_body, key, entries, nxt)
                if extended is not None:
                    new[nxt] = extended
                    nxt += 1
            new[nxt] = res_body
            rewritten[res] = nxt
            nxt += 1
        new[nxt] = _stream(_page_stream(runs, names, codes, opacity))
        text = nxt
        nxt += 1
        inner = contents.strip(b"[]").strip() if contents.startswith(b"[") else contents
        body = body.replace(b"/Resources %d 0 R" % res, b"/Resources %d 0 R" % rewritten[res], 1)
        body = body.replace(b"/Contents " + contents,
                            b"/Contents [ %d 0 R %s %d 0 R ]" % (save, inner, text), 1)
        new[page] = body
    out = bytearray(pdf)
    if not out.endswith(b"\n"):
        out += b"\n"
    where = {}
    for num in sorted(new):
        where[num] = len(out)
        out += b"%d 0 obj\n" % num + new[num] + b"\nendobj\n"
    xref = len(out)
    out += b"xref\n0 1\n0000000000 65535 f \n"
    for num in sorted(where):
        out += b"%d 1\n%010d 00000 n \n" % (num, where[num])
    keep = b" ".join(re.findall(rb"/(?:Root|Info) \d+ 0 R", doc.trailer))
    out += (b"trailer\n<< /Size %d %s /Prev %d >>\nstartxref\n%d\n%%%%EOF\n"
            % (max(nxt, doc.size), keep, doc.xref, xref))
    return bytes(out)
