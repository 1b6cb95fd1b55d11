"""The cut outlines of a sheet read back from the DXF keep their parts apart.

The check rebuilds each part from what the file says (a bar's two round ends, a ring's circle)
and measures the least gap between two parts' cut lines; it is tested on real sheets written by
the DXF writer and read with ezdxf, and on the same sheets damaged (a ring moved onto a bar, a
bar moved half its width onto its neighbour), with the gaps computed by hand.
"""

from __future__ import annotations

import io
from dataclasses import replace

import ezdxf
import pytest

from fabkit.check.dxf import read_sheet
from fabkit.check.sheet_layout import least_gap, MIN_WEB_MM, part_shapes
from fabkit.writers.dxf import sheet_dxf
from fabkit.fab.laser_plan import laser_plan
from fabkit.templates import load_template

from conftest import TEMPLATES

#: a polygonal circle lies inside the true one by r (1 - cos(pi/64)): 0.01 mm on these parts
SHAPE_TOL = 0.02


@pytest.fixture(scope="module")
def plan():
    return laser_plan(load_template(TEMPLATES / "physical_fourbar_chain.toml"))


def _read(sheet, plan) -> dict:
    doc = ezdxf.read(io.StringIO(sheet_dxf(sheet, plan, len(plan.sheets)).decode("ascii")))
    return read_sheet(doc)["parts"]


def test_a_written_sheet_keeps_its_parts_the_spacing_apart(plan):
    parts = _read(plan.sheets[0], plan)
    shapes = part_shapes(parts)
    bars = [p for p in parts.values() if p["kind"] == "bar"]
    assert len(shapes) >= len(bars) > 2  # every bar rebuilt (the square has no round ends)
    gap, pair = least_gap(parts)
    # the nesting's spacing, less the kerf the outlines were grown by (half on each side)
    s = plan.settings
    assert gap >= min(s.spacing - s.kerf, 4 * MIN_WEB_MM) - SHAPE_TOL, pair




def _lowest_bar_and_the_one_above(sheet):
    """The lowest bar of a sheet and the nearest bar above it that overlaps it along x."""
    bars = sorted((p for p in sheet.parts if p.kind == "bar"), key=lambda p: p.bbox[1])
    a = bars[0]
    above = min((p for p in bars[1:] if p.bbox[0] < a.bbox[2] and a.bbox[0] < p.bbox[2]
                 and p.bbox[1] > a.bbox[1]), key=lambda p: p.bbox[1])
    return a, above


def test_a_bar_moved_half_its_width_onto_its_neighbour_is_caught(plan):
    sheet = plan.sheets[0]
    a, above = _lowest_bar_and_the_one_above(sheet)  # the bar above moved down onto a
    drop = above.bbox[1] - a.bbox[3] + 0.5 * (a.bbox[3] - a.bbox[1])
    moved = _shift_part(sheet, above.id, 0.0, -drop)
    gap, pair = least_gap(_read(moved, plan))
    assert gap == -1.0 and set(pair) == {a.id, above.id}


def test_a_gap_narrower_than_the_web_is_measured(plan):
    sheet = plan.sheets[0]
    a, above = _lowest_bar_and_the_one_above(sheet)
    gap_before = above.bbox[1] - a.bbox[3]  # both horizontal: the boxes' gap is the true gap
    want = 0.4
    moved = _shift_part(sheet, above.id, 0.0, -(gap_before - want))
    gap, pair = least_gap(_read(moved, plan))
    assert gap == pytest.approx(want, abs=SHAPE_TOL)
    assert gap < MIN_WEB_MM


def _shift_part(sheet, pid, dx, dy):
    """The sheet with one placed part shifted (holes, outline, labels alike)."""
    from fabkit.fab.nest import Sheet

    out = Sheet(index=sheet.index, width=sheet.width, height=sheet.height,
                placements=dict(sheet.placements))
    for p in sheet.parts:
        if p.id == pid:
            outline = p.outline.copy()
            outline[:, :2] += [dx, dy]
            x0, y0, x1, y1 = p.bbox
            p = replace(p, outline=outline, holes=p.holes + [dx, dy],
                        bbox=(x0 + dx, y0 + dy, x1 + dx, y1 + dy), labels=[])
        out.parts.append(p)
    return out
