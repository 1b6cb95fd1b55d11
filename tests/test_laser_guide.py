"""The assembly guide a person follows alone: an overview of how the pages join, how to build,
every screw closed on exactly one page (the others name that page), hardware per page that adds
up to the bill of materials, and the motion test's numbers; the kit's pictures split into rows
where labels read."""

from __future__ import annotations

import io
import re

import numpy as np
import pytest

import fabkit
from fabkit.writers.dxf import bill_of_materials
from fabkit.fab.laser_plan import laser_plan
from fabkit.fab.guide import assembly_picture, guide_pages, motion_picture

from conftest import TEMPLATES


@pytest.fixture(scope="module")
def chain():
    design = fabkit.load_template(TEMPLATES / "super_stable_chain.toml")
    plan = laser_plan(design)
    bom = bill_of_materials(plan, [])
    return plan, bom, guide_pages(plan, bom, pngs=True, check=True)


def _text(guide, page: int) -> str:
    return "\n".join(guide.texts[page - 1])


def _stack_lines(text: str) -> dict:
    """Joint → the parts of its stack line ("J5: B18 L0 / B8 L2 (p3) / S5.5 ... | post ...")."""
    out = {}
    for m in re.finditer(r"^J(\d+): (.*?)\s+\| post ([\d.]+) mm", text, flags=re.M):
        out[int(m.group(1))] = (m.group(2).split(" / "), float(m.group(3)))
    return out


def test_pages_overview_method_modules_and_motion_test(chain):
    plan, bom, guide = chain
    gp = guide.plan
    assert guide.stats["pages"] == gp.n_pages == 15 == len(guide.texts) == len(guide.images)
    assert [p.number for p in gp.pages] == list(range(3, 15))
    assert [p.modules for p in gp.pages] == [(2 * k + 1, 2 * k + 2) for k in range(12)]
    one = _text(guide, 1)
    assert "page 1 of 15: overview" in one and "How the pages join" in one
    # the chain as built is about 2.1 m long: its size, and a table long enough for it
    w, h = gp.size_mm
    assert 2100 < w < 2250 and 150 < h < 200
    assert f"Built size {w:.0f} × {h:.0f} mm" in one
    # every page is named in the overview with its modules, and what it leaves for the next
    for p in gp.pages[:-1]:
        assert re.search(rf"^p{p.number}: modules {p.modules[0]}-{p.modules[1]}; leaves .* "
                         rf"loose for p{p.number + 1}$", one, flags=re.M)
    two = _text(guide, 2)
    assert "how to build" in two and "up from below" in two
    assert "shims the page lists: on top, under the screw head" in two
    assert "BUILD ORDER, PAGE BY PAGE" in two and "Work from page 3 to page 14" in two
    for k, im in enumerate(guide.images):  # A4 at 100 dpi
        assert im[:8] == b"\x89PNG\r\n\x1a\n"
        from PIL import Image

        assert Image.open(io.BytesIO(im)).size == (827, 1169), k


def test_every_stack_is_listed_whole_on_one_page_and_named_on_the_others(chain):
    plan, bom, guide = chain
    gp = guide.plan
    stacks = {js.joint: js for js in plan.stacking.joints}
    edges = np.asarray(plan.bars.edges)
    listed = {}
    for p in gp.pages:
        text = _text(guide, p.number)
        lines = _stack_lines(text)
        assert set(lines) == set(p.closes)
        for j, (parts, post) in lines.items():
            assert j not in listed, f"J{j} listed on pages {listed[j]} and {p.number}"
            listed[j] = p.number
            js = stacks[j]
            assert post == js.screw_length
            # bottom to top: every layer from the lowest to the highest, a bar or a ring
            assert len(parts) == max(js.layers) - min(js.layers) + 1
            for z, b in zip(js.layers, js.bars):
                own = gp.closing_page[j] == p.number and b in p.bars
                # the bar as it is engraved, and the page that draws it when another does
                want = f"B{b} L{z}" if own else f"B{b} L{z} (p{p.bar_page[b]})"
                assert parts[z - min(js.layers)] == want
            for z in js.spacers:
                assert parts[z - min(js.layers)] == f"S{j}.{z}"
        # a joint this page's bars reach but another page closes: named with that page
        reach = {int(j) for j in edges[np.asarray(p.bars)].ravel()} & set(stacks)
        for j in reach - set(p.closes):
            assert f"J{j}→p{gp.closing_page[j]}" in text
            assert gp.closing_page[j] > p.number
    assert set(listed) == set(stacks)
    # the paper's chain: two modules meet at two screws, so each page but the last leaves two
    assert [len(p.open_joints) for p in gp.pages] == [2] * 11 + [0]
    assert sum(len(p.ghosts) for p in gp.pages) > 0


def test_hardware_per_page_adds_up_to_the_bill_of_materials(chain):
    plan, bom, guide = chain
    per_name: dict = {}
    for p in guide.plan.pages:
        for name, n in p.hardware:
            per_name[name] = per_name.get(name, 0) + n
        text = _text(guide, p.number)
        for name, n in p.hardware:
            assert re.search(rf"^\s*{n} × {re.escape(name)}$", text, flags=re.M)
    for s in bom["screws"]:
        name = next(k for k in per_name if k.startswith(s["description"]) and
                    k.endswith(f"post {s['post_length_mm']:g} mm"))
        assert per_name[name] == s["count"]
    assert sum(s["count"] for s in bom["screws"]) == 74
    # the shim rings as the bill of materials names them, every kind
    kinds = {k["name"]: k["count"] for k in bom["washers"]["kinds"]}
    assert kinds == {"DIN 988 5x10x0.5": 204, "DIN 988 5x10x0.2": 74}
    for name, n in kinds.items():
        assert per_name[f"shim ring {name}"] == n
    assert bom["washers"]["count"] == 278
    rings = next(v for k, v in per_name.items() if k.startswith("spacer ring"))
    assert rings == bom["spacer_rings"]["count"] == 44
    # and the overview lists the same totals
    one = _text(guide, 1)
    assert re.search(r"^\s*204 × shim ring DIN 988 5x10x0\.5$", one, flags=re.M)
    assert re.search(r"^\s*144 × bars", one, flags=re.M)


def test_the_motion_test_says_what_to_push_from_what_to_what(chain):
    plan, bom, guide = chain
    m = guide.plan.motion
    assert m.drive == "d1" and m.joints == (0, 1)
    assert m.start_mm == pytest.approx(100 * np.sqrt(3), abs=1e-9)   # D1* = sqrt(3)
    assert m.end_mm == pytest.approx(100.9950493837, abs=1e-6)       # D2* + 1e-12
    text = _text(guide, 15)
    assert "Push joints J0 and J1 together" in text
    assert "d1 goes from 173.2 mm to 101.0 mm" in text
    assert re.search(r"^\s+d1:\s+173\.2 →\s+101\.0 mm \(pushed\)", text, flags=re.M)
    # the front runs from the pushed end: d2 ... d20 follow in order, d21 ... d25 stay open
    assert m.order == "forward"
    assert [p[0] for p in m.followers] == [f"d{k}" for k in range(2, 21)]
    ends = {p[0]: p[2] for p in m.ports}
    assert all(abs(ends[f"d{k}"] - 101.0) < 0.5 for k in range(2, 16))
    assert ends["d25"] == pytest.approx(173.2, abs=0.1)
    assert "one after another, starting next to d1" in text
    # the pictures: start, the front a quarter, half, three quarters of the way, the end
    assert [int(m.moved[f]) for f in m.frames] == [0, 5, 10, 15, 19]
    assert "d1 = 173.21 mm (start): 0 of 19 following ports past half way" in text
    assert "d1 = 101.00 mm (end): 19 of 19 following ports past half way" in text


def test_labels_never_overlap_and_the_assembly_picture_is_split_into_rows(chain):
    from PIL import Image

    plan, bom, guide = chain
    assert guide.stats["overlaps"] == 0 and guide.stats["dropped"] == 0
    assert guide.stats["clipped"] == []  # every text fits on its page
    png, stats = assembly_picture(plan, guide.plan)
    assert stats["overlaps"] == 0 and stats["dropped"] == 0 and stats["clipped"] == []
    # every bar once, every joint once, and the two joints where rows meet in both rows
    assert stats["labels"] == 144 + 74 + 2 * (stats["rows"] - 1)
    # 2.1 m cut into rows (never one squashed strip), at least 1.6 px per mm
    assert stats["rows"] >= 3 and stats["px_per_mm"] >= 1.6
    w, h = Image.open(io.BytesIO(png)).size
    assert w == 1100 and h > 1000
    png, stats = motion_picture(plan, guide.plan)
    w, h = Image.open(io.BytesIO(png)).size
    # five moments of the 2.1 m chain, each a full-width row, to one scale
    assert w == 1100 and h >= 5 * 100 and stats["columns"] == 1 and stats["clipped"] == []


def test_a_network_that_is_not_a_chain_is_one_page():
    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    plan = laser_plan(design)
    guide = guide_pages(plan, bill_of_materials(plan, []))
    gp = guide.plan
    assert gp.n_pages == 4 and len(gp.pages) == 1
    page = gp.pages[0]
    assert page.modules == () and page.open_joints == {} and page.ghosts == ()
    assert set(page.closes) == {0, 1, 2, 3}
    assert guide.stats["overlaps"] == 0 and guide.stats["dropped"] == 0
    text = "\n".join(guide.texts[3])
    assert "d1 goes from 200.0 mm to 300.0 mm" in text and "Pull joints J0 and J1 apart" in text
    # a compact design's moments side by side (not four rows of 1.2 m each)
    png, stats = motion_picture(plan, gp)
    assert stats["columns"] >= 2 and stats["px_per_mm"] >= 1.6 and stats["clipped"] == []


@pytest.mark.parametrize("name, order", [("slope_one_chain", "together"),
                                         ("period_two_chain16", "backward"),
                                         ("super_stable_chain8", "forward")])
def test_the_motion_test_says_how_the_ports_follow(name, order):
    from fabkit.fab.guide import guide_plan

    plan = laser_plan(fabkit.load_template(TEMPLATES / f"{name}.toml"))
    m = guide_plan(plan, bill_of_materials(plan, [])).motion
    assert m.order == order
    halves = np.array([p[3] for p in m.followers])
    if order == "together":  # slope one: every port goes the drive's way, at the same time
        assert np.ptp(halves) <= 2 and all(abs(p[2] - m.end_mm) < 0.1 for p in m.ports)
    elif order == "backward":  # an expanding map: the far end moves first
        assert halves[-1] < halves[0]
    else:
        assert np.all(np.diff(halves) >= 0)


def test_labeller_counts_overlapping_labels_as_matplotlib_measures_them():
    """Labels placed never overlap; ``overlaps`` counts the pairs whose drawn boxes meet, as
    matplotlib's Bbox.overlaps does, when labels are forced on top of each other."""
    from fabkit.fab.guide.draw import Labeller
    from fabkit.plots.viz import figure_kit

    fig, ax = figure_kit.subplots(figsize=(4, 4))
    ax.set_xlim(0, 100)
    ax.set_ylim(0, 100)
    lab = Labeller(ax)
    for k in range(12):  # all want the same spot: each is moved to a free candidate
        assert lab.put(f"B{k} L{k % 3}", [(50, 50), (50, 20 + 6 * k), (20 + 6 * k, 80)], 8)
    assert lab.overlaps() == 0 and lab.stats["labels"] == 12
    for x in (50.0, 51.0, 90.0):  # two on top of the first label's spot, one far away
        lab.placed.append(lab._text(x, 50.0, "B99 L9", 8, "black", "normal"))
    boxes = [t.get_window_extent(lab.renderer) for t in lab.placed]
    pairs = sum(boxes[i].overlaps(boxes[j])
                for i in range(len(boxes)) for j in range(i + 1, len(boxes)))
    assert lab.overlaps() == pairs >= 3


def _pdf_words(text: str) -> str:
    return " ".join(text.split())


def test_pdfium_and_poppler_read_every_word_of_the_guide_in_its_embedded_fonts(chain):
    """Chrome's PDF engine (PDFium) and poppler (pdftotext, pdffonts) open the guide: 15 A4
    pages whose fonts are all embedded (TrueType subsets: a reader never substitutes a font of
    other widths, which set "S tand" for "Stand"), whose text reads back as drawn."""
    pdfium = pytest.importorskip("pypdfium2")
    plan, bom, guide = chain
    pdf = guide.pdf
    fonts = set(re.findall(rb"/BaseFont /([A-Za-z+-]+)", pdf))
    assert fonts and all(b"+DejaVu" in f for f in fonts), fonts
    assert pdf.count(b"/FontFile2") >= 3 and b"/Type3" not in pdf
    doc = pdfium.PdfDocument(pdf)
    assert len(doc) == 15
    for k, page in enumerate(doc):
        w, h = page.get_size()
        assert abs(w - 8.27 * 72) < 1 and abs(h - 11.69 * 72) < 1  # A4 points
        read = _pdf_words(page.get_textpage().get_text_range())
        for text in guide.texts[k]:
            for line in text.splitlines():
                assert _pdf_words(line) in read, (k + 1, line)
    # a stack as the builder reads it on page 3, and a joint left for page 4
    page3 = _pdf_words(doc[2].get_textpage().get_text_range())
    assert re.search(r"J\d+: B\d+ L\d / .* \| post \d+ mm", page3)
    assert "J2→p4" in page3
    # rendered, the pages carry ink where the bars and words are
    pixels = np.asarray(doc[3].render(scale=50 / 72).to_pil().convert("L"))
    assert (pixels < 128).mean() > 0.005
    popp = _poppler(pdf)
    if popp is not None:
        fonts_table, pages = popp
        assert all(row.split()[-5] == "yes" for row in fonts_table), fonts_table  # emb
        for k in range(15):
            for text in guide.texts[k]:
                for line in text.splitlines():
                    assert _pdf_words(line) in _pdf_words(pages[k]), (k + 1, line)


def _poppler(pdf: bytes):
    """(pdffonts rows, pdftotext text of each page), or None when poppler is not installed."""
    import shutil
    import subprocess
    import tempfile

    if not (shutil.which("pdftotext") and shutil.which("pdffonts")):
        return None
    with tempfile.TemporaryDirectory() as tmp:
        path = f"{tmp}/guide.pdf"
        with open(path, "wb") as f:
            f.write(pdf)
        fonts = subprocess.run(["pdffonts", path], capture_output=True, text=True,
                               timeout=60, check=True).stdout.splitlines()[2:]
        text = subprocess.run(["pdftotext", "-layout", "-enc", "UTF-8", path, "-"], capture_output=True,
                              text=True, timeout=120, check=True).stdout
    return fonts, text.split("\f")


def _words_in_page_box(pdf: bytes):
    """Every word pdftotext finds with its box, per page, and the page sizes (points)."""
    import shutil
    import subprocess
    import tempfile
    from html import unescape

    if not shutil.which("pdftotext"):
        pytest.skip("pdftotext (poppler-utils) is not installed")
    with tempfile.TemporaryDirectory() as tmp:
        with open(f"{tmp}/g.pdf", "wb") as f:
            f.write(pdf)
        subprocess.run(["pdftotext", "-bbox", f"{tmp}/g.pdf", f"{tmp}/g.html"], check=True,
                       timeout=120, capture_output=True)
        html = open(f"{tmp}/g.html", encoding="utf-8").read()
    pages = []
    for m in re.finditer(r'<page width="([\d.]+)" height="([\d.]+)">(.*?)</page>', html, re.S):
        words = [(float(a), float(b), float(c), float(d), unescape(t)) for a, b, c, d, t in
                 re.findall(r'<word xMin="([-\d.]+)" yMin="([-\d.]+)" xMax="([-\d.]+)" '
                            r'yMax="([-\d.]+)">(.*?)</word>', m.group(3))]
        pages.append((float(m.group(1)), float(m.group(2)), words))
    return pages


def test_the_and_gates_guide_sets_every_stack_once_inside_a_page(gate):
    """The and-gate's 98 screws (a network that is not a chain): its drawing is cut into parts
    of the network a page each, where every 7 pt label finds a place, and every stack line
    stands inside a page's box once, as pdftotext (which leaves out what lies off the page) and
    PDFium read the PDF; nothing is set below 7 pt or past a page's edge."""
    pdfium = pytest.importorskip("pypdfium2")
    plan, bom, guide = gate
    assert guide.stats["clipped"] == [] and guide.stats["dropped"] == 0
    assert guide.stats["overlaps"] == 0 and guide.stats["smallest_pt"] >= 7.0
    joints = {int(j["joint"]) for j in bom["joints"]}
    assert len(joints) == 98
    pages = _words_in_page_box(guide.pdf)
    assert len(pages) == guide.stats["pages"] == guide.plan.n_pages > 3
    found: dict = {}
    for k, (w, h, words) in enumerate(pages):
        for x0, y0, x1, y1, t in words:
            assert 0 <= x0 and x1 <= w and 0 <= y0 and y1 <= h, (k + 1, t)
        # a stack line starts a line: "J23:" then the bottom bar
        line_starts = [t for (x0, _, _, _, t) in words if x0 < 45]
        for t in line_starts:
            m = re.fullmatch(r"J(\d+):", t)
            if m:
                found.setdefault(int(m.group(1)), []).append(k + 1)
    assert set(found) == joints
    assert all(len(v) == 1 for v in found.values()), {j: v for j, v in found.items()
                                                      if len(v) > 1}
    # the deepest stacks (J91, J95, J96: branch joints on trunk joints) among them
    assert {91, 95, 96} <= set(found)
    # PDFium: the same lines, every character inside its page, none smaller than 7 pt
    doc = pdfium.PdfDocument(guide.pdf)
    stacks = 0
    for k, page in enumerate(doc):
        w, h = page.get_size()
        tp = page.get_textpage()
        n = tp.count_chars()
        for i in range(0, n, 7):
            x0, y0, x1, y1 = tp.get_charbox(i)
            if x1 > x0:
                assert -0.5 <= x0 and x1 <= w + 0.5 and -0.5 <= y0 and y1 <= h + 0.5
                assert pdfium.raw.FPDFText_GetFontSize(tp.raw, i) >= 7.0 - 1e-6
        stacks += len(re.findall(r"(?m)^J\d+: ", tp.get_text_range()))
    assert stacks == 98
    # every joint's parts: bars named as engraved, "B<bar> L<layer>"
    text = "\n".join(line for page in guide.texts for line in page)
    for b in bom["bars"][:20]:
        assert f"{b['id']} L{b['layer']}" in text


def test_a_long_motion_table_continues_and_its_pictures_get_a_page(chain):
    """A chain of 209 modules has 210 ports: the motion test's table runs over a page, and its
    pictures no longer fit below it. They used to be drawn in the room left, a negative height
    (row_axes: negative width); now the table continues and the pictures get a page of their
    own, drawn from the same pages code."""
    from dataclasses import replace

    from fabkit.fab.guide.pages import render_pages
    from fabkit.fab.guide.plan import motion_sheets

    plan, bom, guide = chain
    gp = guide.plan
    m = gp.motion
    ports = [(f"d{k}", 173.2, 101.0, k) for k in range(1, 211)]
    long = replace(m, ports=ports)
    barrel = plan.settings.screw.barrel_diameter
    sheets = motion_sheets(long, barrel, gp.sheets[-1].number)
    assert len(sheets) >= 2 and sheets[-1].pictures
    assert not any(s.pictures for s in sheets[:-1])
    assert [s.number for s in sheets] == list(range(15, 15 + len(sheets)))
    # at any length the pictures have their room: below the table, or on a page of their own
    from fabkit.fab.guide.flow import block_height
    from fabkit.fab.guide.plan import PICTURES_MIN_PT, ROOM_PT

    kinds = set()
    for n in (9, 30, 60, 120, 210, 400):
        these = motion_sheets(replace(m, ports=ports[:n]), barrel, 15)
        last = these[-1]
        kinds.add(last.kind)
        room = ROOM_PT["motion" if last.first else "continued"]
        assert last.kind == "pictures" or \
            room - sum(block_height(b) for b in last.blocks) >= PICTURES_MIN_PT
    assert kinds == {"motion", "pictures"}
    gp2 = replace(gp, motion=long, sheets=gp.sheets[:-1] + sheets)
    pdf, _, texts, stats = render_pages(gp2, plan, check=True)
    assert stats["clipped"] == [] and stats["smallest_pt"] >= 7.0
    rows = [line for page in texts[14:] for line in page if re.match(r"^\s*d\d+: ", line)]
    assert len(rows) == 210
    # the old layout: the pictures in what was left below three columns of 70 rows
    from fabkit.fab.guide.draw import row_axes
    from fabkit.plots.viz import figure_kit

    fig = figure_kit.figure(figsize=(8.27, 11.69))
    with pytest.raises(ValueError, match="positive scale"):
        row_axes(fig, [(0, 0, 100, 50)], -0.004, 0.55, 11.0, 0.2, 7.17)


def test_flow_cuts_blocks_into_pages_that_hold_them():
    from fabkit.fab.guide.flow import Block, block_height, flow

    rows = tuple(f"J{k}: " + " / ".join(f"B{k * 10 + i} L{i}" for i in range(k % 17))
                 + "  | post 20 mm" for k in range(120))
    blocks = [Block("Stacks", rows), Block(None, ("loose: J1→p4",), style="body"),
              Block("Hardware", tuple(f"{k:>4} × part {k}" for k in range(12)), columns=2)]
    pages = flow(blocks, 280.0, 750.0)
    assert len(pages) >= 3
    for k, page in enumerate(pages):
        assert sum(block_height(b) for b in page) <= (280.0 if k == 0 else 750.0) + 1e-9
    got = [r for page in pages for b in page if b.head == "Stacks" for r in b.rows]
    assert tuple(got) == rows  # every row once, in order
    heads = [b.title for page in pages for b in page if b.head == "Stacks"]
    assert heads[0] == "Stacks" and all(h == "Stacks (continued)" for h in heads[1:])


@pytest.mark.slow
def test_the_laser_kit_of_a_long_designed_chain_has_its_guide(tmp_path):
    """A 10.4 m sine drawn as a CSV, made a chain of about 200 modules by `fabkit design
    --curve`, exported as a laser kit: its guide used to fail in row_axes (a negative width)
    when the motion test's table of every port left no room for its pictures."""
    from fabkit.cli import main
    from fabkit.writers import export

    x = np.linspace(0.0, 8700.0, 2000)
    np.savetxt(tmp_path / "sine.csv", np.c_[x, 300.0 * np.sin(2 * np.pi * x / 2000.0)],
               delimiter=",", fmt="%.4f")
    assert main(["design", "--curve", str(tmp_path / "sine.csv"), "-o",
                 str(tmp_path / "design")]) == 0
    design = fabkit.load_template(tmp_path / "design" / "sine.toml")
    ports = design.network.ports
    modules = sum(bool(re.fullmatch(r"d\d+", p)) for p in ports) - 1
    assert modules >= 200
    paths, report = export(design, "dxf", tmp_path / "kit")
    guide = (tmp_path / "kit" / "laser_guide.pdf").read_bytes()
    pdfium = pytest.importorskip("pypdfium2")
    doc = pdfium.PdfDocument(guide)
    text = "\n".join(page.get_textpage().get_text_range() for page in doc)
    # every port's row of the motion test (d1 ... and the chain's other ports), and its
    # pictures on a page of their own or below the table
    assert len(re.findall(r"(?m)^\s*\w+:\s+[\d.]+ → ", text)) == len(ports)
    assert "motion test, pictures" in text or "(start):" in text
    # every joint's stack once
    joints = {int(m) for m in re.findall(r"(?m)^J(\d+): ", text)}
    assert joints == {int(j["joint"]) for j in report["joints"]}


def test_a_chains_motion_test_lists_the_order_its_modules_move_in(chain):
    """The ports that follow the drive, in the order they pass half their change: the modules
    of a super-stable chain one after another from the pushed end."""
    plan, bom, guide = chain
    m = guide.plan.motion
    assert m.order == "forward"
    seq = [p[0] for p in sorted(m.followers, key=lambda p: p[3])]
    assert seq[:5] == ["d2", "d3", "d4", "d5", "d6"]
    words = " ".join(" ".join(line for line in page) for page in guide.texts)
    assert "The order in which they should move: d2 → d3 → d4 → d5 → d6 → ..." in \
        " ".join(words.split())
