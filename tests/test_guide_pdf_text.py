"""The guide's text layer (fabkit.fab.guide.pdf_text): lines written into matplotlib's PDF by an
incremental update stand where matplotlib sets the same texts, in embedded DejaVu subsets, and
read back word for word. Judged by PDFium (Chrome's PDF engine) and poppler, the readers
makers open the guide in, against matplotlib's own drawing of the same figure."""

from __future__ import annotations

import ctypes
import io
import re
import shutil
import subprocess

import numpy as np
import pytest

from fabkit.errors import FabkitError
from fabkit.fab.guide.pdf_text import LAYER_GID, TextRun, add_text_layer, off_page, text_runs

pdfium = pytest.importorskip("pypdfium2")

#: The texts of the test page: (x, y in figure fraction, text, keywords).
TEXTS = [
    (0.5, 0.95, "A centred title, bold", dict(ha="center", va="center", fontsize=12.5,
                                               weight="bold")),
    (0.07, 0.9, "Running text: bars B3, B17 and J12 (4 bars) → layer 5; fit ×2, fine flat.",
     dict(va="top", fontsize=8)),
    (0.07, 0.85, "J23: B3 L1 / B4 L2 | post 20 mm", dict(va="top", fontsize=7.5,
                                                         family="monospace")),
    (0.07, 0.8, "Two lines of a header\nthe second one, longer than the first", dict(
        va="top", fontsize=7.5)),
    (0.93, 0.7, "right-aligned at its baseline", dict(ha="right", va="baseline", fontsize=9)),
    (0.5, 0.6, "bottom, red", dict(ha="center", va="bottom", fontsize=10, color="#d00000")),
]


def _figure():
    from fabkit.plots.viz import figure_kit

    fig = figure_kit.figure(figsize=(8.27, 11.69))
    texts = [fig.text(x, y, s, gid=LAYER_GID, **kw) for x, y, s, kw in TEXTS]
    return fig, texts


def _pdf(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="pdf", metadata={"CreationDate": None, "ModDate": None})
    return buf.getvalue()


def _layered():
    """The page drawn by matplotlib, and the same page with its texts in the layer."""
    fig, texts = _figure()
    plain = _pdf(fig)
    runs = text_runs(fig, texts)
    for t in texts:
        t.set_visible(False)
    return plain, add_text_layer(_pdf(fig), [runs]), runs


def _chars(pdf: bytes):
    """Every character PDFium reads: (char, origin x, origin y, font size), in page points."""
    page = pdfium.PdfDocument(pdf)[0]
    tp = page.get_textpage()
    out = []
    x, y = ctypes.c_double(), ctypes.c_double()
    for i in range(tp.count_chars()):
        ch = chr(pdfium.raw.FPDFText_GetUnicode(tp.raw, i))
        if ch.isspace() or ch in "\r\n\ufffe":
            continue
        pdfium.raw.FPDFText_GetCharOrigin(tp.raw, i, ctypes.byref(x), ctypes.byref(y))
        out.append((ch, x.value, y.value, pdfium.raw.FPDFText_GetFontSize(tp.raw, i)))
    return out


def _lines(chars):
    """Characters grouped into lines by their baseline (0.5 pt)."""
    lines: list = []
    for c in sorted(chars, key=lambda c: (-round(c[2] * 2), c[1])):
        if lines and abs(lines[-1][0][2] - c[2]) < 0.5:
            lines[-1].append(c)
        else:
            lines.append([c])
    return {"".join(ch for ch, *_ in line): line for line in lines}


def test_every_line_stands_where_matplotlib_sets_it():
    """PDFium finds each line's characters at matplotlib's baselines (within 0.25 pt) and
    starting where matplotlib starts them (0.5 pt); without kerning a line runs at most 1.5 %
    longer or shorter than matplotlib's."""
    plain, layered, _ = _layered()
    want, got = _lines(_chars(plain)), _lines(_chars(layered))
    assert len(want) == 7
    assert sorted(want) == sorted(got)  # the same characters on the same lines
    for text, line in want.items():
        mine = got[text]
        assert abs(mine[0][2] - line[0][2]) < 0.25, text  # baseline
        assert abs(mine[0][1] - line[0][1]) < 0.5, text  # first character's origin
        span_mpl, span = line[-1][1] - line[0][1], mine[-1][1] - mine[0][1]
        if span_mpl > 20:
            assert abs(span - span_mpl) <= 0.015 * span_mpl, (text, span, span_mpl)
        assert {round(c[3], 2) for c in mine} == {round(c[3], 2) for c in line}  # sizes


def test_poppler_reads_the_words_in_embedded_subsets(tmp_path):
    """pdffonts lists every font of the layer embedded as a TrueType subset with a Unicode
    map; pdftotext reads every line word for word; pdfinfo reports no error."""
    if not (shutil.which("pdftotext") and shutil.which("pdffonts")):
        pytest.skip("poppler-utils is not installed")
    _, layered, _ = _layered()
    path = tmp_path / "page.pdf"
    path.write_bytes(layered)

    def run(*args):
        out = ["-"] if args[0] == "pdftotext" else []
        return subprocess.run([*args, str(path), *out], capture_output=True, timeout=60,
                              check=True)

    fonts = run("pdffonts").stdout.decode().splitlines()[2:]
    names = [row.split()[0] for row in fonts]
    assert {"DejaVuSans", "DejaVuSans-Bold", "DejaVuSansMono"} == {n.split("+")[1]
                                                                   for n in names}
    for row in fonts:
        tag, cols = row.split()[0].split("+")[0], row.split()
        assert re.fullmatch(r"[A-Z]{6}", tag) and cols[-5:-2] == ["yes", "yes", "yes"], row
    text = " ".join(run("pdftotext", "-layout", "-enc", "UTF-8").stdout.decode().split())
    for _, _, s, _ in TEXTS:
        for line in s.splitlines():
            assert " ".join(line.split()) in text, line
    assert run("pdfinfo").stderr == b""


def test_the_layer_is_an_update_of_the_file_and_the_same_every_time():
    """The layer leaves matplotlib's bytes as they are and appends to them (a new
    cross-reference section pointing back at the old one); the same page gives the same
    bytes; no runs, no change."""
    plain, layered, runs = _layered()
    fig, texts = _figure()
    for t in texts:
        t.set_visible(False)
    hidden = _pdf(fig)
    assert layered.startswith(hidden) and layered.endswith(b"%%EOF\n")
    assert re.search(rb"/Prev (\d+)", layered[len(hidden):]).group(1) == \
        re.search(rb"startxref\s+(\d+)", hidden).group(1)
    assert add_text_layer(hidden, [runs]) == layered
    assert add_text_layer(hidden, [[]]) == hidden
    # the page's drawing is kept under the text: PDFium renders ink at the title
    page = pdfium.PdfDocument(layered)[0]
    pixels = np.asarray(page.render(scale=1).to_pil().convert("L"))
    assert (pixels[int(0.04 * pixels.shape[0]):int(0.06 * pixels.shape[0])] < 128).any()


def test_a_character_the_font_lacks_is_set_as_its_missing_glyph():
    """A character DejaVu Sans has no glyph for is drawn as the font's missing-glyph box, and
    the text around it reads back."""
    from matplotlib.font_manager import findfont

    font = findfont("DejaVu Sans")
    runs = [TextRun(72.0, 700.0, 10.0, font, "before \U0001F642 after")]
    fig, texts = _figure()
    for t in texts:
        t.set_visible(False)
    out = add_text_layer(_pdf(fig), [runs])
    read = pdfium.PdfDocument(out)[0].get_textpage().get_text_range()
    assert "before" in read and "after" in read


def test_bad_input_is_refused_by_name_and_nothing_is_written():
    """Not a PDF, a PDF with a cross-reference stream, another page count, a rotated text:
    each a FabkitError naming the cause."""
    plain, layered, runs = _layered()
    with pytest.raises(FabkitError, match="no cross-reference table"):
        add_text_layer(b"%PDF-1.4\nnot really\n", [runs])
    at = int(re.search(rb"startxref\s+(\d+)", plain).group(1))
    streamed = plain[:at] + b"9 0 obj" + plain[at + 4:]  # where a stream's object would be
    with pytest.raises(FabkitError, match="cross-reference stream"):
        add_text_layer(streamed, [runs])
    with pytest.raises(FabkitError, match="2 pages for a PDF of 1"):
        add_text_layer(plain, [runs, runs])
    fig, texts = _figure()
    texts[0].set_rotation(90)
    with pytest.raises(FabkitError, match="rotated text"):
        text_runs(fig, texts)


def test_a_label_and_its_white_patch_stand_where_matplotlib_draws_them():
    """A label of the guide's drawings (the Labeller's text: centred, bold or not, on a white
    patch of 85 % opacity over a coloured bar): PDFium finds its characters where matplotlib
    sets them, and the rendered page shows the same patch: the pixels of the label's
    surroundings agree with matplotlib's drawing to a few levels of 255."""
    from fabkit.fab.guide.draw import Labeller
    from fabkit.plots.viz import figure_kit

    def page():
        fig = figure_kit.figure(figsize=(8.27, 11.69))
        ax = fig.add_axes([0.1, 0.5, 0.8, 0.4])
        ax.set_xlim(0, 100)
        ax.set_ylim(0, 50)
        ax.plot([0, 100], [25, 25], color="#d62728", lw=30, solid_capstyle="butt")
        lab = Labeller(ax)
        assert lab.put("B12 L3", [(50, 25)], 9) and lab.put("J7", [(20, 25)], 8, weight="bold")
        return fig, lab.placed

    fig, placed = page()
    plain = _pdf(fig)
    fig, placed = page()
    runs = text_runs(fig, placed)
    assert all(r.box is not None and r.box_rgba == (1.0, 1.0, 1.0, 0.85) for r in runs)
    for t in placed:
        t.set_visible(False)
    layered = add_text_layer(_pdf(fig), [runs])
    want, got = _lines(_chars(plain)), _lines(_chars(layered))
    assert sorted(want) == sorted(got)
    a = sorted(_chars(plain), key=lambda c: (c[1], c[2]))
    b = sorted(_chars(layered), key=lambda c: (c[1], c[2]))
    assert [c[0] for c in a] == [c[0] for c in b]
    for ca, cb in zip(a, b):
        assert abs(ca[1] - cb[1]) < 0.6 and abs(ca[2] - cb[2]) < 0.3, (ca, cb)
    # the band of the bar around the labels, rendered at 2 px per point
    shots = []
    for pdf in (plain, layered):
        img = pdfium.PdfDocument(pdf)[0].render(scale=2).to_pil().convert("RGB")
        shots.append(np.asarray(img, dtype=float))
    h = shots[0].shape[0]
    band = slice(int(h * (1 - 0.7)) - 12, int(h * (1 - 0.7)) + 12)  # y = 25 of 0..50
    diff = np.abs(shots[0][band] - shots[1][band])
    assert diff.mean() < 3.0, diff.mean()
    # the patch lightens the bar: whiter than the bar far from any label
    x_label = int(shots[0].shape[1] * 0.5)
    x_bare = int(shots[0].shape[1] * 0.7)
    mid = int(h * 0.3)
    assert shots[1][mid, x_label - 30:x_label + 30].mean() > shots[1][mid, x_bare].mean() + 40


def test_off_page_names_the_texts_pdfium_finds_past_the_page():
    """``off_page`` names exactly the runs that PDFium finds characters of beyond the page box
    (a line pushed past each edge, and lines inside), once each."""
    from matplotlib.font_manager import findfont

    font = findfont("DejaVu Sans")
    w, h = 595.44, 841.68
    runs = [TextRun(40.0, 700.0, 10.0, font, "inside, near the left"),
            TextRun(w - 60.0, 650.0, 10.0, font, "past the right edge"),
            TextRun(-5.0, 600.0, 10.0, font, "past the left edge"),
            TextRun(100.0, h - 4.0, 10.0, font, "past the top"),
            TextRun(100.0, 1.0, 10.0, font, "past the bottom (descender)"),
            TextRun(w - 120.0, 500.0, 10.0, font, "ends inside"),
            TextRun(w - 60.0, 450.0, 10.0, font, "past the right edge")]
    got = off_page(runs, w, h)
    assert got == ["past the right edge", "past the left edge", "past the top",
                   "past the bottom (descender)"]
    fig, texts = _figure()
    for t in texts:
        t.set_visible(False)
    page = pdfium.PdfDocument(add_text_layer(_pdf(fig), [runs]))[0]
    tp = page.get_textpage()
    beyond = set()
    for i in range(tp.count_chars()):
        x0, y0, x1, y1 = tp.get_charbox(i)
        if x1 > x0 and (x0 < -0.5 or x1 > w + 0.5 or y0 < -0.5 or y1 > h + 0.5):
            beyond.add(min(range(len(runs)), key=lambda k: abs(runs[k].y - 0.5 * (y0 + y1))))
    # PDFium's glyph boxes past the edge lie on the five lines of the four texts named, and on
    # no other line
    assert sorted(beyond) == [1, 2, 3, 4, 6]
    assert {runs[k].text for k in beyond} == set(got)


def test_the_guide_reports_its_texts_past_a_page():
    """A guide whose stats list texts past their page gives the laser format one warning per
    page, and the report stage adds them to the writer's warnings (the pictures')."""
    from fabkit.writers.dxf import guide_cut

    class Guide:
        stats = {"clipped": [(3, "J12: B3 L1 / B4 L2"), (3, "B7 L0"), (5, "a title")]}

    assert guide_cut(Guide()) == [
        "laser_guide.pdf: text past the edge of page 3: J12: B3 L1 / B4 L2, B7 L0",
        "laser_guide.pdf: text past the edge of page 5: a title"]
    Guide.stats = {"clipped": []}
    assert guide_cut(Guide()) == []
