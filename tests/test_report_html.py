"""report.html per design and index.html per batch: self-contained pages, checked as files and
in a real headless Chromium (Debian's package, driven by Playwright's client): no console errors,
the slider moves the drawing, the index's pictures move on their own, screenshots are saved."""

from __future__ import annotations

import json
import re
import shutil

import pytest

from fabkit.cli import main

from conftest import TEMPLATES

DESIGNS = ("fourbar", "origami_sheet", "printed_planar")
CHROMIUM = shutil.which("chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--no-first-run", "--disable-sync"]


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    out = tmp_path_factory.mktemp("batch")
    rc = main(["export", *(str(TEMPLATES / f"{n}.toml") for n in DESIGNS), "-o", str(out),
               "--tolerance-samples", "30"])
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
    for name in DESIGNS:
        assert f'href="{name}/report.html"' in page
    assert page.count(" data-autoplay></svg>") == len(DESIGNS)
    assert "fabkit batch: 3 designs" in page


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
    assert len(first) == len(DESIGNS)
    assert all(a != b for a, b in zip(first, later))
    page.screenshot(path=str(tmp_path / "index.png"), full_page=True)
    assert (tmp_path / "index.png").stat().st_size > 10_000
    assert errors == []
    page.close()
