"""report.html per design and index.html per batch: self-contained pages, checked as files and
in a real headless Chromium (Debian's package, driven by Playwright's client): no console errors,
the slider moves the drawing, the index's pictures move on their own, every link resolves to a
file the design wrote, no picture is shown smaller than it is drawn, nothing overflows a 500 px
window, screenshots are saved."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from fabkit.cli import main

from conftest import TEMPLATES

DESIGNS = ("fourbar", "origami_sheet", "printed_planar")
#: A design that exports nothing (its template opts out of the only format that applies).
NO_KIT = "no_kit"
NO_KIT_REASON = "the bars would collide at the start; fix: move joint 3"
CHROMIUM = shutil.which("chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--no-first-run", "--disable-sync"]


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    out = tmp_path_factory.mktemp("batch")
    src = tmp_path_factory.mktemp("templates")
    text = (TEMPLATES / "fourbar.toml").read_text().replace('name = "fourbar"',
                                                           f'name = "{NO_KIT}"')
    (src / f"{NO_KIT}.toml").write_text(
        text + f'\n[fabrication]\nskip = {{ dxf = "{NO_KIT_REASON}", stl = "{NO_KIT_REASON}" }}\n')
    rc = main(["export", *(str(TEMPLATES / f"{n}.toml") for n in DESIGNS),
               str(src / f"{NO_KIT}.toml"), "-o", str(out), "--tolerance-samples", "30"])
    assert rc == 0
    return out


def _motion(page: str) -> dict:
    m = re.search(r'<script type="application/json" id="fabkit-motion">(.*?)</script>', page,
                  flags=re.S)
    return json.loads(m.group(1).replace("<\\/", "</"))


def test_every_design_has_a_self_contained_page_with_its_motion(out):
    for name in DESIGNS:
        page = (out / name / "report.html").read_text(encoding="utf-8")
        # nothing is fetched: no external scripts, styles or pictures
        assert not re.search(r'(src|href)="(https?:)?//', page)
        assert "<link" not in page
        for src in re.findall(r'<img src="([^"]+)"', page):
            assert src.startswith("data:image/")
        data = _motion(page)
        net_edges = json.loads((out / name / "report.json").read_text())["design"]["edges"]
        assert len(data["edges"]) == net_edges and len(data["frames"]) > 10
        assert data["frames"][0] != data["frames"][-1]  # it moves
        assert data["values"][0] == pytest.approx(
            json.loads((out / name / "report.json").read_text())["motion"]["start"])
        for section in ("id=map", "id=tolerance", "id=checks"):
            assert section in page
    assert "id=laser" in (out / "fourbar" / "report.html").read_text()
    assert "id=bom" in (out / "fourbar" / "report.html").read_text()
    sheet = (out / "origami_sheet" / "report.html").read_text()
    assert "id=origami" in sheet and "mountain" in sheet
    printed = (out / "printed_planar" / "report.html").read_text()
    assert "id=print" in printed
    assert len(_motion(printed)["faces"]) == 4  # the module's four rigid plates, filled
    assert len(_motion(sheet)["faces"]) == 4  # the sheet's four panels


def test_the_index_lists_every_design_with_a_moving_picture(out):
    page = (out / "index.html").read_text(encoding="utf-8")
    for name in (*DESIGNS, NO_KIT):
        assert f'href="{name}/report.html"' in page
    assert page.count(" data-autoplay></svg>") == len(DESIGNS) + 1
    assert "fabkit batch: 4 designs" in page


def _cards(page: str) -> dict:
    return {m.group(1): m.group(0) for m in re.finditer(
        r'<div class="card"><h3><a href="([^/"]+)/report.html">.*?</div>(?=<div class="card"|'
        r"</div></main>)", page, flags=re.S)}


def test_an_index_card_says_why_a_design_exported_nothing(out):
    cards = _cards((out / "index.html").read_text(encoding="utf-8"))
    assert set(cards) == {*DESIGNS, NO_KIT}
    card = cards[NO_KIT]
    assert f"No files to build: dxf: skipped by the template – {NO_KIT_REASON}; stl: " \
           f"skipped by the template – {NO_KIT_REASON}" in card
    assert "checks:" not in card  # nothing was checked: no verdict that reads as a pass
    # a laser design also gets its print-in-place linkage: still made for the laser
    assert "made for laser-cut acrylic (Chicago screws) · formats: dxf, stl" in cards["fourbar"]
    assert re.search(r'<p class="verdict-line"><span class="ok">ok</span>: every as-built check '
                     r"passed \((\d+) files read back\)", cards["fourbar"])
    assert re.search(r"formats: dxf, stl · \d+ files read back", cards["fourbar"])
    assert "made for a 3D print" in cards["printed_planar"]
    assert "made for folded paper (origami) · formats: cp, fold, svg" in cards["origami_sheet"]


def _hrefs(page: str) -> list:
    return re.findall(r'<a href="([^"]+)"', page)


def test_every_file_a_design_wrote_is_linked_from_its_page(out):
    for name in (*DESIGNS, NO_KIT):
        folder = out / name
        page = (folder / "report.html").read_text(encoding="utf-8")
        files = {p.name for p in folder.iterdir()} - {"report.html"}
        links = {h for h in _hrefs(page) if not h.startswith("#")}
        assert links == files, name
        assert set(json.loads((folder / "report.json").read_text())["files"]) == files | {
            "report.html"}
        for h in _hrefs(page):
            if h.startswith("#"):
                assert f"id={h[1:]}" in page or f'id="{h[1:]}"' in page
    fourbar = (out / "fourbar" / "report.html").read_text(encoding="utf-8")
    assert '<b>Start here:</b> <a href="laser_guide.pdf">laser_guide.pdf</a>, the assembly ' \
           "guide (4 A4 pages" in fourbar


def test_a_page_leads_with_the_process_the_design_was_made_for(out):
    def order(page, *marks):
        return [page.index(m) for m in marks]

    fourbar = (out / "fourbar" / "report.html").read_text(encoding="utf-8")
    assert "<h2>Made for laser-cut acrylic (Chicago screws)</h2>" in fourbar
    a, b, c, d = order(fourbar, "id=made-for", "id=files", "id=motion", "id=laser")
    assert a < b < c < d
    # the printed design also gets a laser kit: folded below its print, never above it
    printed = (out / "printed_planar" / "report.html").read_text(encoding="utf-8")
    assert "<h2>Made for a 3D print</h2>" in printed and "plates joined by" in printed
    assert '<b>Start here:</b> <a href="printed_planar.3mf">' in printed
    p, also, laser = order(printed, "id=print", '<details id="also-laser">', "id=laser")
    assert p < also < laser
    assert 'id=bom-laser' in printed[also:] and "id=bom>" in printed[p:also]
    sheet = (out / "origami_sheet" / "report.html").read_text(encoding="utf-8")
    assert "One sheet of paper, a square of side 106.07 mm (150.00 mm corner to corner)" in sheet
    assert "<tr><td>D–P</td><td>mountain</td><td>131.1°</td></tr>" in sheet
    nothing = (out / NO_KIT / "report.html").read_text(encoding="utf-8")
    assert "Made for laser-cut acrylic (Chicago screws): no files" in nothing
    assert NO_KIT_REASON in nothing


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    if CHROMIUM is None:
        pytest.skip("chromium is not installed (.ci/install.d/chromium.sh installs it)")
    from playwright import sync_api  # a test extra: installed with the venv
    with sync_api.sync_playwright() as p:
        ctx = p.chromium.launch_persistent_context(
            str(tmp_path_factory.mktemp("profile")), executable_path=CHROMIUM, headless=True,
            args=FLAGS[1:], viewport={"width": 1200, "height": 900})
        yield ctx
        ctx.close()


def _open(ctx, path):
    page = ctx.new_page()
    errors = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("request", lambda r: errors.append(f"network: {r.url}")
            if not r.url.startswith(("file:", "data:")) else None)
    page.goto(path.as_uri())
    page.wait_for_load_state("load")
    return page, errors


def _line(page):
    return page.eval_on_selector("svg[data-motion] line:last-of-type",
                                 "l => [l.getAttribute('x1'), l.getAttribute('y1'), "
                                 "l.getAttribute('x2'), l.getAttribute('y2')]")


@pytest.mark.parametrize("name", DESIGNS)
def test_dragging_the_slider_folds_the_network_in_chromium(out, browser, name, tmp_path):
    page, errors = _open(browser, out / name / "report.html")
    before = _line(page)
    assert page.eval_on_selector("svg[data-motion]", "s => s.getAttribute('data-frame')") == "0"
    page.locator("#frame").scroll_into_view_if_needed()  # below the lead and the files
    box = page.locator("#frame").bounding_box()
    y = box["y"] + box["height"] / 2
    page.mouse.move(box["x"] + 2, y)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] * 0.7, y, steps=8)
    page.mouse.up()
    frame = int(page.eval_on_selector("svg[data-motion]", "s => s.getAttribute('data-frame')"))
    after = _line(page)
    assert frame > 0 and after != before
    assert page.locator("output").inner_text().startswith("d1 = ")
    shot = tmp_path / f"{name}.png"
    page.locator("#motion").screenshot(path=str(shot))
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert errors == []
    page.close()


def test_the_index_pictures_move_on_their_own_in_chromium(out, browser, tmp_path):
    page, errors = _open(browser, out / "index.html")
    first = page.eval_on_selector_all("svg[data-motion]", "s => s.map(x => x.innerHTML)")
    page.wait_for_timeout(600)
    later = page.eval_on_selector_all("svg[data-motion]", "s => s.map(x => x.innerHTML)")
    assert len(first) == len(DESIGNS) + 1  # the design with no kit still moves
    assert all(a != b for a, b in zip(first, later))
    page.screenshot(path=str(tmp_path / "index.png"), full_page=True)
    assert (tmp_path / "index.png").stat().st_size > 10_000
    assert errors == []
    page.close()


_OPEN_ALL = "() => document.querySelectorAll('details').forEach(d => d.open = true)"

_LINKS = """() => Array.from(document.querySelectorAll('a[href]')).map(a => a.href)"""

_IMAGES = """() => Array.from(document.querySelectorAll('img')).map(i => ({
    alt: i.alt, shown: i.getBoundingClientRect().width, natural: i.naturalWidth,
    complete: i.complete}))"""

# elements that stick out of the window, other than what sits in a box that scrolls sideways
_OVERFLOW = """(w) => Array.from(document.querySelectorAll('body *')).filter(e => {
    for (let p = e.parentElement; p; p = p.parentElement) {
        const o = getComputedStyle(p).overflowX;
        if (o === 'auto' || o === 'scroll' || o === 'hidden') return false;
    }
    const r = e.getBoundingClientRect();
    return r.width > 0 && r.right > w + 0.5;
}).map(e => e.tagName + (e.id ? '#' + e.id : '') + ' ' + (e.textContent || '').slice(0, 40))"""


@pytest.mark.parametrize("width", [500, 1200])
def test_links_resolve_pictures_keep_their_size_and_nothing_overflows_in_chromium(
        out, browser, width):
    from urllib.parse import unquote, urlparse

    for name in (*DESIGNS, NO_KIT):
        folder = out / name
        page, errors = _open(browser, folder / "report.html")
        page.set_viewport_size({"width": width, "height": 900})
        page.evaluate(_OPEN_ALL)
        page.wait_for_timeout(100)
        followed = set()
        for href in page.evaluate(_LINKS):
            url = urlparse(href)
            assert url.scheme == "file", href
            target = Path(unquote(url.path))
            if url.fragment and target == folder / "report.html":
                assert page.locator(f"[id='{url.fragment}']").count() == 1, href
                continue
            # a file the design wrote, in its own folder
            assert target.parent == folder and target.is_file(), href
            followed.add(target.name)
        assert followed == {p.name for p in folder.iterdir()} - {"report.html"}
        images = page.evaluate(_IMAGES)
        assert images or name == NO_KIT
        for img in images:
            # every picture at least as wide as it is drawn: its text at its own size
            assert img["complete"] and img["natural"] > 0, (name, img["alt"])
            assert img["shown"] >= img["natural"] - 0.5, (name, width, img)
        assert page.evaluate("document.documentElement.scrollWidth") <= width, name
        assert page.evaluate(_OVERFLOW, width) == [], (name, width)
        assert errors == []
        page.close()


def test_the_index_links_open_the_design_pages_in_chromium(out, browser):
    page, errors = _open(browser, out / "index.html")
    page.set_viewport_size({"width": 500, "height": 900})
    hrefs = page.evaluate(_LINKS)
    assert len(hrefs) == len(DESIGNS) + 1
    assert page.evaluate("document.documentElement.scrollWidth") <= 500
    for href in hrefs:
        page.goto(href)
        page.wait_for_load_state("load")
        assert page.locator("section#made-for").count() == 1, href
    assert errors == []
    page.close()
