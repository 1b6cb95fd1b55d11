"""The laser guide tells a maker what the design will do and how to test it: its first page and
the head of the bill of materials carry the verdict in whole sentences; a design with two inputs
(the AND gate) gets a page that pushes A only, B only and both, with the distances fabkit's own
tracer gives; its module pages follow the network's build order, a branch said where it starts.
The PDF is read back with pdftotext (poppler) and PDFium, the bill of materials with json."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from types import SimpleNamespace

import numpy as np
import pytest

import fabkit
from fabkit.fab.guide import function_test, guide_pages, verdict_rows
from fabkit.fab.laser_plan import laser_plan
from fabkit.pipeline import Checks, FormatResult, judge_design
from fabkit.status import Status
from fabkit.writers.dxf import bill_of_materials, bom_json, bom_markdown

from conftest import FLAG, TEMPLATES


def _pdftotext(pdf: bytes, tmp_path, first: int | None = None, last: int | None = None) -> list:
    """The text of every page (or pages ``first`` to ``last``) as poppler reads it."""
    if shutil.which("pdftotext") is None:
        pytest.skip("pdftotext (poppler-utils) is not installed")
    path = tmp_path / "guide.pdf"
    path.write_bytes(pdf)
    args = ["pdftotext", "-layout"]
    if first is not None:
        args += ["-f", str(first), "-l", str(last or first)]
    out = subprocess.run([*args, str(path), "-"], check=True, capture_output=True,
                         timeout=120).stdout.decode("utf-8")
    return out.split("\f")


def _flat(text: str) -> str:
    """Words joined by single spaces (a wrapped sentence read as one)."""
    return " ".join(text.split())


def test_the_gates_first_page_heads_with_its_verdict_in_whole_sentences(gate, tmp_path):
    plan, _, guide = gate
    page1 = _flat(_pdftotext(guide.pdf, tmp_path, 1)[0])
    assert "What this kit will do (the export's verdict)" in page1
    assert "Verdict: FLAG. Tolerance as laser builds: none of the 40 builds assembles within " \
           "its play" in page1
    for head in ("What to expect:", "What to adjust:", "Which joints:"):
        assert head in page1
    # the joints named are the deepest stacks, as the plan stacks them
    deepest = max(plan.stacking.joints, key=lambda js: len(js.layers))
    assert f"J{deepest.joint} ({len(deepest.layers)} bars" in page1
    # every sentence of the verdict is on the page whole: no word cut by a line's end
    for row in verdict_rows(FLAG, plan):
        assert _flat(row) in page1


def test_the_bill_of_materials_heads_with_the_same_verdict(gate):
    plan, bom, _ = gate
    data = json.loads(bom_json(bom))
    assert next(iter(data)) == "verdict"  # the first key a reader meets
    assert data["verdict"]["level"] == "FLAG"
    assert data["verdict"]["words"] == verdict_rows(FLAG, plan)
    md = bom_markdown(bom).splitlines()
    assert md[0] == "# Laser-cut kit: and_gate" and md[2] == "## Verdict: FLAG"
    assert md[4] == f"- {verdict_rows(FLAG, plan)[0]}"


def test_a_guide_made_without_the_export_says_it_is_not_judged():
    design = fabkit.load_template(TEMPLATES / "fourbar_chain.toml")
    plan = laser_plan(design)
    bom = bill_of_materials(plan, [])
    assert bom["verdict"]["level"] == "not judged"
    assert bom_markdown(bom).splitlines()[2] == "## Verdict: not judged"
    text = " ".join(guide_pages(plan, bom).texts[0])
    assert "Verdict: not judged." in text


def test_the_gate_is_tested_as_a_gate_a_only_b_only_and_both(gate, tmp_path):
    plan, _, guide = gate
    design = plan.design
    ft = guide.plan.function
    assert ft is not None and ft.inputs == ("d1", "d1_b")
    assert ft.letters == {"d1": "A", "d1_b": "B"}
    assert [c.pushed for c in ft.cases] == [("d1",), ("d1_b",), ("d1", "d1_b")]
    a, b, both = ft.cases
    s = plan.settings.scale
    # B alone is the designed motion: its ports end where the traced motion ends them
    traced = design.trace()
    end = traced.positions[-1]
    for name, start, stop in b.moved:
        assert stop == pytest.approx(float(design.network.port_distance(name, end)) * s,
                                     abs=0.05)
    assert {n for n, _, _ in b.moved} >= {f"d{k}_b" for k in range(1, 13)}
    assert not any(n in {f"d{k}" for k in range(1, 18)} for n, _, _ in b.moved)
    # A alone moves the trunk's near end only; B's branch stays
    assert a.moved and all(not n.endswith("_b") for n, _, _ in a.moved)
    assert "d17" in a.still and "d1_b" in a.still
    # both: every port that moves in either case moves
    assert {n for n, _, _ in both.moved} >= {n for n, _, _ in b.moved}
    # the page, as poppler reads it: the three cases, each with its numbers
    pages = [_flat(t) for t in _pdftotext(guide.pdf, tmp_path)]
    found = [k for k, t in enumerate(pages) if "functional test of the inputs" in t]
    assert found, "no functional test page"
    text = " ".join(pages[k] for k in found)
    assert "A = d1 (joints J" in text and "B = d1_b (joints J" in text
    for head in ("A only: push A (d1); hold B", "B only: push B (d1_b); hold A",
                 "A + B (both): push A (d1) then B (d1_b)"):
        assert head in text
    for name, start, stop in b.moved[:3]:
        assert re.search(rf"{name}: {start:.1f} → {stop:.1f} mm", text)
    # A stops where the tracer stops it, short of its target, and the page says so in words
    name, end, target, why = a.reached[0]
    assert why and end - target > 0.1
    assert (f"A (d1) stops at {end:.1f} mm, {end - target:.1f} mm short of {target:.1f} mm: "
            f"{why}; do not force it") in text


def test_a_design_with_one_input_has_no_functional_test():
    design = fabkit.load_template(TEMPLATES / "fourbar_chain.toml")
    assert function_test(design, 100.0) is None


def test_the_gates_pages_follow_its_build_order_and_name_the_branch(gate, tmp_path):
    plan, _, guide = gate
    design = plan.design
    gp = guide.plan
    pages = gp.pages
    # every page after the first grows from a page built before it, joined at shared screws
    assert pages[0].parent is None
    for p in pages[1:]:
        assert p.parent is not None and p.parent < p.number and p.joins
        assert all(q < p.number for q in p.joins)
    branches = [p for p in pages if p.parent is not None and p.parent != p.previous]
    assert len(branches) == 1
    # the trunk (bars 0-95) is built first, then the branch (bars 96-191)
    trunk = [p for p in pages if np.median(p.bars) < 96]
    assert [p.number for p in trunk] == [p.number for p in pages[:len(trunk)]]
    # the first page holds the first input's joint
    a = design.network.port("d1")[0]
    assert any(a in plan.bars.edges[k] for k in pages[0].bars)
    texts = [_flat(t) for t in _pdftotext(guide.pdf, tmp_path)]
    how = " ".join(texts[1:3])
    assert "left to right" not in how
    br = branches[0]
    assert f"page {br.number} starts a branch from page {br.parent}" in how
    on_page = texts[br.number - 1]
    assert f"Build order: a branch: it grows from page {br.parent}" in on_page
    nxt = pages[pages.index(br) + 1]
    assert f"Build order: continue from page {br.number}." in texts[nxt.number - 1]


def test_the_gates_motion_test_says_the_order_its_table_shows(gate):
    _, _, guide = gate
    m = guide.plan.motion
    assert m.order == "forward"
    words = " ".join(" ".join(t) for t in guide.texts)
    assert "not in order" not in words
    fol = sorted(m.followers, key=lambda p: p[3])
    assert [p[0] for p in fol][:3] == ["d2_b", "d3_b", "d4_b"]
    assert "The order in which they should move: d2_b → d3_b → d4_b" in _flat(words)


def _verdict_of(text: str):
    tol = SimpleNamespace(flagged=True, behaviour=None, verdict="FLAG, " + text,
                          spec=SimpleNamespace(process="laser"))
    made = {"dxf": FormatResult("dxf", Status.EXPORTED, ["laser_sheet1.dxf"])}
    return judge_design(Status.OK, made, Checks({}), None, tol, [])


def test_a_long_finding_is_shortened_at_a_clause_never_inside_a_word():
    words = ("margin 0.3: only 0.0% of laser builds keep the behaviour (need 95%): none of the "
             "40 builds assembles within their play; " + "a long clause about holes " * 12 +
             "; the end")
    v = _verdict_of(words)
    assert v.status is Status.FLAG
    kept = v.message.removeprefix("tolerance as laser builds: ").removesuffix(
        " (more in the report)")
    assert v.message.endswith(" (more in the report)")
    assert words.startswith(kept) and words[len(kept)] == ";"
    # one clause longer than the line: cut between words
    v = _verdict_of("none of the 40 builds assembles " * 20)
    kept = v.message.removeprefix("tolerance as laser builds: ").removesuffix(
        " (more in the report)")
    assert kept.split() == ("none of the 40 builds assembles " * 20).split()[:len(kept.split())]
    assert "…" not in v.message and "…" not in v.headline
