"""Where a chain's motion went (fabkit.motion.spread): modules that moved, and localisation.

The references are the paper's maps: a chain of modules d → f(d) carries a change of its first
port on to module k as the product of the slopes on the way, so near a stable fixed point (|f'| <
1) the modules far down the chain stay where they are, each moving |f'(D*)| times as far as the
one before it; with f(d) = 4/d (the crossed 4-bar) every port alternates between the drive's
own travel and its image under the map, and every module moves.
"""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser

import numpy as np
import pytest

import fabkit
from fabkit.cli import main
from fabkit.motion import trace_motion
from fabkit.status import Status
from fabkit.motion.spread import chain_of, module_spread

from conftest import TEMPLATES


def test_a_chain_of_crossed_fourbars_spreads_its_motion_over_every_module():
    # d1 from 2 to 3: d2 = 4/d1 goes from 2 to 4/3 (2/3 of the drive's travel), d3 = d1
    # again, and so on
    d = fabkit.load_template("fourbar_chain")
    spread = module_spread(d, d.trace())
    assert spread.ports == ("d1", "d2", "d3", "d4", "d5")
    assert spread.reach == pytest.approx([2 / 3, 1.0, 2 / 3, 1.0], rel=1e-9)
    assert not spread.localised and spread.sentence() == "spread: all 4 modules moved"


def test_a_chain_that_ends_at_a_stable_fixed_point_keeps_its_motion_at_the_driven_end():
    # the physical 4-bar's map has a stable D2* = 1.90721, slope -0.537: the change the drive
    # brings dies out along the chain, each far module moving 0.537 times as far as the one
    # before it
    d = fabkit.load_template("physical_fourbar_chain")
    spread = module_spread(d, d.trace())
    assert spread.localised and spread.where() == "the driven end"
    assert spread.moved.tolist() == [True] * 3 + [False] * 9
    assert spread.sentence() == "localised at the driven end: modules 1–3 of 12 moved"
    tail = spread.reach[4:9]
    assert tail[1:] / tail[:-1] == pytest.approx(np.full(4, 0.537), rel=0.1)


def test_simulate_says_where_the_motion_went(capsys, tmp_path):
    assert main(["simulate", str(TEMPLATES / "physical_fourbar_chain.toml"), "-o",
                 str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "status        finished: reached d1 = 1.907212261; localised at the driven end: " \
           "modules 1–3 of 12 moved" in out
    strip = re.search(r"^modules\s+(\S+)\s", out, flags=re.M).group(1)
    assert len(strip) == 12 and strip[0] == "█" and strip[-1] == "▁"
    assert main(["simulate", str(TEMPLATES / "fourbar_chain.toml"), "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "spread: all 4 modules moved" in out and "localised" not in out


def test_a_shape_that_stays_local_is_not_the_shape(capsys, tmp_path):
    text = (TEMPLATES / "physical_fourbar_chain.toml").read_text()
    assert "intent" not in text
    path = tmp_path / "shape_chain.toml"
    path.write_text(text.replace("[motion]\n", '[motion]\nintent = "shape"\n', 1))
    design = fabkit.load_template(path)
    motion = trace_motion(design)
    assert motion.status is Status.ENDS_MISSED
    assert "its intent is a shape" in motion.message
    assert main(["simulate", str(path), "-o", str(tmp_path / "out")]) == 1
    cap = capsys.readouterr()
    assert "status        shape missed" in cap.out
    assert "modules 1–3 of 12 moved" in cap.err and "keep their start shape" in cap.err


def test_the_chain_is_the_drives_own():
    ports = {"d1": (0, 1), "d2": (2, 3), "d3": (4, 5), "d1_b": (6, 7), "d2_b": (8, 9),
             "d4": (1, 2)}
    assert chain_of(ports, "d1") == ["d1", "d2", "d3", "d4"]
    assert chain_of(ports, "d1_b") == ["d1_b", "d2_b"]
    assert chain_of(ports, "d2") == [] and chain_of(ports, "gap") == []
    # a single module, or a drive that is not a chain's first port: nothing to say
    d = fabkit.load_template("fourbar")
    assert module_spread(d, d.trace()) is None


class _Cells(HTMLParser):
    def __init__(self):
        super().__init__()
        self.inside, self.titles = False, []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "span" and attrs.get("class") == "strip":
            self.inside = True
        elif tag == "i" and self.inside:
            self.titles.append(attrs.get("title", ""))

    def handle_endtag(self, tag):
        if tag == "span":
            self.inside = False


def test_the_report_shows_which_modules_moved(tmp_path):
    assert main(["export", str(TEMPLATES / "physical_fourbar_chain.toml"), "--to", "dxf",
                 "--tolerance-samples", "0", "-o", str(tmp_path), "-q"]) == 0
    folder = tmp_path / "physical_fourbar_chain"
    spread = json.loads((folder / "report.json").read_text())["motion"]["spread"]
    assert spread["modules"] == 12 and spread["moved"] == 3 and spread["localised"]
    cells = _Cells()
    cells.feed((folder / "report.html").read_text())
    assert len(cells.titles) == 12
    assert cells.titles[0].startswith("module 1: ") and cells.titles[-1].startswith("module 12: ")
    assert "localised at the driven end: modules 1–3 of 12 moved" in \
        (folder / "report.md").read_text()
