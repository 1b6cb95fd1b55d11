"""report.html, report.md and the index card of a design head with its verdict: the worst of its
as-built checks, its motion and its tolerance analysis. A FLAG is never shown under a pass; a
design flagged by what it is for (a chaotic chain) says so in words; a print-only export is
reported and judged as a print."""

from __future__ import annotations

import json
import re

import pytest

from fabkit.cli import main

from conftest import TEMPLATES

#: origami_sheet folded by a careless hand: its own tolerance analysis flags it.
SLOPPY = "origami_sloppy"


@pytest.fixture(scope="module")
def pages(tmp_path_factory):
    """One checked export of chaotic_chain, origami_sheet and a sloppy origami_sheet; and_gate
    unchecked and with 10 builds (its whole export takes a minute); super_stable as a print
    only."""
    out = tmp_path_factory.mktemp("verdicts")
    src = tmp_path_factory.mktemp("templates")
    text = (TEMPLATES / "origami_sheet.toml").read_text().replace(
        'name = "origami_sheet"', f'name = "{SLOPPY}"')
    (src / f"{SLOPPY}.toml").write_text(text + "\n[fabrication.tolerance]\ncrease_sigma = 4.0\n")
    for name, args in [
            ("checked", [str(TEMPLATES / "chaotic_chain.toml"), str(TEMPLATES / "origami_sheet.toml"),
                         str(src / f"{SLOPPY}.toml"), "-o", str(out / "checked")]),
            ("and_gate", [str(TEMPLATES / "and_gate.toml"), "-o", str(out / "and_gate"),
                          "--no-check", "--no-previews", "--tolerance-samples", "10"]),
            ("print", [str(TEMPLATES / "super_stable.toml"), "--to", "stl", "-o",
                       str(out / "print")])]:
        assert main(["export", *args, "-q"]) == 0, name
    return out


def _read(out, run, name, file):
    return (out / run / name / file).read_text(encoding="utf-8")


def _text(html: str) -> str:
    """The page without style, scripts and drawings."""
    return re.sub(r"<style>.*?</style>|<script.*?</script>|<svg.*?</svg>", "", html, flags=re.S)


def _card(out, run, name) -> str:
    page = (out / run / "index.html").read_text(encoding="utf-8")
    m = re.search(rf'<div class="card"><h3><a href="{name}/report.html">.*?</div>'
                  r'(?=<div class="card"|</div></main>)', page, flags=re.S)
    assert m, name
    return _text(m.group(0))


def _head(html: str) -> tuple[str, str]:
    """The title badge and the first section of a design's page."""
    page = _text(html)
    badge = re.search(r"<h1>[^<]*<span[^>]*>([^<]+)</span></h1>", page).group(1)
    first = re.search(r"<main>(<section[^>]*>.*?</section>)", page, flags=re.S).group(1)
    return badge, first


def test_and_gate_is_judged_as_built_with_its_play(pages):
    # the gate's one state of self-stress closes within 0.2 mm of hole play in every build;
    # put together, each build's branch collapses until the target or until its loops run out
    # of play (a lock, where a maker's pull stops), and the trunk stays still: its verdict is
    # ok, by the switch it makes, and every page heads with it
    out = pages
    report = json.loads(_read(out, "and_gate", "and_gate", "report.json"))
    tol = report["tolerance"]
    assert tol["flagged"] is False
    assert tol["behaviour"]["criteria"] == ["driven state", "still ports"]
    assert tol["assembly"]["assemble"] == 10 and tol["assembly"]["model"] == "play"
    kept = {c["criterion"]: c["kept_fraction"] for c in tol["criteria"]}
    assert kept == {"driven state": 1.0, "still ports": 1.0}
    assert report["verdict"]["level"] == "ok"
    assert report["verdict"]["text"].startswith("tolerance as laser builds: ok, margin")
    badge, first = _head(_read(out, "and_gate", "and_gate", "report.html"))
    assert badge == "ok"
    md = _read(out, "and_gate", "and_gate", "report.md")
    assert md.splitlines()[2].startswith("**ok**: tolerance as laser builds: ok, margin")
    assert "10 of 10 builds assemble within their play" in md
    assert "the driven chain's front ends" in md


def test_a_flag_is_never_shown_under_a_pass(pages):
    out = pages
    # every as-built check of the sloppy sheet passes; its tolerance analysis flags it
    report = json.loads(_read(out, "checked", SLOPPY, "report.json"))
    checks = [c for f in report["formats"].values() for c in f.get("checks", [])]
    assert checks and all(c["ok"] for c in checks)
    assert report["tolerance"]["flagged"] is True and report["verdict"]["level"] == "FLAG"
    badge, first = _head(_read(out, "checked", SLOPPY, "report.html"))
    assert badge == "FLAG" and 'class="verdict FLAG"' in first
    assert "tolerance as origami builds: margin" in first
    assert _read(out, "checked", SLOPPY, "report.md").splitlines()[2].startswith(
        "**FLAG**: tolerance as origami builds: margin")
    card = _card(out, "checked", SLOPPY)
    assert '<span class="bad">FLAG</span>: tolerance as origami builds' in card
    assert "pass" not in card and 'class="ok"' not in card
    # in the checks table the tolerance row is FLAG, under the passing checks, never "pass"
    page = _read(out, "checked", SLOPPY, "report.html")
    tol_row = re.search(r"<th colspan=5>tolerance</th></tr><tr><td>as built</td><td>(.*?)</td>",
                        page).group(1)
    assert tol_row == '<span class="bad">FLAG</span>'
    # the same sheet folded with care is ok, and says why
    report = json.loads(_read(out, "checked", "origami_sheet", "report.json"))
    assert report["tolerance"]["flagged"] is False and report["verdict"]["level"] == "ok"
    badge, first = _head(_read(out, "checked", "origami_sheet", "report.html"))
    assert badge == "ok"
    assert re.search(r"every as-built check passed \(1 file read back\); tolerance as origami "
                     r"builds: ok, margin \d", first)
    assert '<span class="ok">ok</span>: every as-built check passed' in \
        _card(out, "checked", "origami_sheet")


def test_a_chain_chaotic_by_design_says_so_in_words(pages):
    out = pages
    report = json.loads(_read(out, "checked", "chaotic_chain", "report.json"))
    assert report["tolerance"]["flagged"] is True  # its far end cannot be predicted
    assert report["verdict"]["level"] == "by design"
    badge, first = _head(_read(out, "checked", "chaotic_chain", "report.html"))
    assert badge == "flagged by design"
    assert first.startswith('<section id=verdict class="verdict by-design"><h2>Verdict: '
                            '<span class="note">flagged by design</span></h2><p>chaotic by '
                            "design: its module map stretches errors by e^0.31 a module")
    assert "as the design intends" in first
    assert 'class="bad"' not in first  # said in words, not alarmed in red
    assert _read(out, "checked", "chaotic_chain", "report.md").splitlines()[2].startswith(
        "**flagged by design**: chaotic by design:")
    card = _card(out, "checked", "chaotic_chain")
    assert '<span class="note">flagged by design</span>: chaotic by design' in card
    assert 'class="bad"' not in card


def test_a_print_only_export_is_reported_and_judged_as_a_print(pages):
    out = pages
    report = json.loads(_read(out, "print", "super_stable", "report.json"))
    assert report["process"] == "print"
    tol = report["tolerance"]
    assert tol["process"] == "print" and tol["scale_mm"] == 50.0
    # bars printed in place on pins: judged with their pins' play, not a flexure's bending
    assert tol["model"].startswith("print (pin-jointed): xy accuracy σ 0.1 mm")
    assert "pin play 0.3 mm radial" in tol["model"] and "hinge flexure" not in tol["model"]
    assert "radial pin play" in tol["slop"]["sentence"]
    page = _text(_read(out, "print", "super_stable", "report.html"))
    assert "<h2>Made for a 3D print</h2>" in page
    assert ("Printed in place: 6 bars in 3 layers on 5 printed pins (PLA), 50 mm a design unit, "
            "0.3 mm pin clearance, 0.5 mm between bars.") in page
    assert "Nothing to build was written" not in page and "laser-cut acrylic" not in page
    assert "hole play" not in page and "100 mm" not in page
    assert "Judged as a 3D print: print (pin-jointed): xy accuracy" in page
    md = _read(out, "print", "super_stable", "report.md")
    assert "- export: **ok**; made for a 3D print" in md
    assert md.splitlines()[2].startswith("**ok**: every as-built check passed (2 files read "
                                         "back); tolerance as print builds: ok")
    assert "error model of the process: print (pin-jointed): xy accuracy σ 0.1 mm" in md
    card = _card(out, "print", "super_stable")
    assert "made for a 3D print · formats: stl · 2 files read back" in card


def test_the_and_gates_guide_and_bill_of_materials_carry_the_reports_verdict(pages, tmp_path):
    """The report stage makes the guide and the bill of materials again with the verdict: the
    first page of laser_guide.pdf (as poppler reads it) and the head of laser_bom.md and .json
    say what report.json's verdict says, in whole sentences; the format's report says so too."""
    import shutil
    import subprocess

    folder = pages / "and_gate" / "and_gate"
    report = json.loads((folder / "report.json").read_text(encoding="utf-8"))
    verdict = report["verdict"]
    bom = json.loads((folder / "laser_bom.json").read_text(encoding="utf-8"))
    assert next(iter(bom)) == "verdict"
    assert bom["verdict"]["level"] == verdict["level"] != "not judged"
    assert bom["verdict"]["headline"] == verdict["headline"]
    assert report["formats"]["dxf"]["report"]["verdict"] == bom["verdict"]
    md = (folder / "laser_bom.md").read_text(encoding="utf-8").splitlines()
    assert md[2] == f"## Verdict: {verdict['level']}"
    said = f"Verdict: {verdict['level']}. {verdict['text'][:1].upper()}{verdict['text'][1:]}"
    assert md[4] == f"- {said}"
    if shutil.which("pdftotext") is None:
        pytest.skip("pdftotext (poppler-utils) is not installed")
    page1 = subprocess.run(["pdftotext", "-f", "1", "-l", "1", str(folder / "laser_guide.pdf"),
                            "-"], check=True, capture_output=True, timeout=120).stdout.decode()
    assert " ".join(said.split()) in " ".join(page1.split())
    # nowhere is the verdict cut inside a word
    for text in (verdict["headline"], md[4], page1):
        assert "…" not in text
