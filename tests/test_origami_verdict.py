"""The origami verdict in the fold's own terms: a built sheet keeps a state while every crease's
fold angle stays within ``state_fraction`` (0.25) of the designed states' distance apart, here
checked against sheets built and folded by hand (numpy circle-sphere placement, dihedral angles)
rather than by the analysis' own placement."""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from fabkit.kinematics import make_problem
from fabkit.tolerance import analyse_tolerance, tolerance_spec
from fabkit.tolerance.placement import process_geometry
from fabkit.tolerance.processes import sample_builds

from conftest import TEMPLATES

A, B, C, D, P = range(5)
#: origami_sheet's bars, in the template's order: AB, AD, BC, CD, PA, PB, PC, PD
BARS = [(A, B), (A, D), (B, C), (C, D), (P, A), (P, B), (P, C), (P, D)]
#: its panels, counter-clockwise in the flat pattern, and the creases between them
PANELS = {"PA": ((A, D, P), (A, P, B)), "PB": ((A, P, B), (B, P, C)),
          "PC": ((B, P, C), (C, P, D)), "PD": ((C, P, D), (A, D, P))}


def _normal(x, tri):
    a, b, c = (x[i] for i in tri)
    n = np.cross(b - a, c - a)
    return n / np.linalg.norm(n)


def _folds(x) -> np.ndarray:
    """|fold angle| of the creases PA, PB, PC, PD (degrees): the angle between the normals of
    the two panels beside each (0 flat)."""
    return np.array([np.degrees(np.arccos(np.clip(np.dot(_normal(x, s), _normal(x, t)), -1, 1)))
                     for s, t in PANELS.values()])


def _sphere3(c1, r1, c2, r2, c3, r3, side):
    """The point at distances r1, r2, r3 from c1, c2, c3 on the ``side`` of their plane."""
    ex = (c2 - c1) / np.linalg.norm(c2 - c1)
    i = np.dot(ex, c3 - c1)
    ey = c3 - c1 - i * ex
    ey /= np.linalg.norm(ey)
    ez = np.cross(ex, ey)
    d, j = np.linalg.norm(c2 - c1), np.dot(ey, c3 - c1)
    x = (r1 ** 2 - r2 ** 2 + d ** 2) / (2 * d)
    y = (r1 ** 2 - r3 ** 2 + i ** 2 + j ** 2) / (2 * j) - i / j * x
    z2 = r1 ** 2 - x ** 2 - y ** 2
    if z2 < 0:
        return None
    return c1 + x * ex + y * ey + side * np.sqrt(z2) * ez


def _sheet(lengths, d1, sides):
    """The sheet with these bar lengths and B-D = d1: B, D on the x axis, P above them in the
    plane, A and C on the given sides of the planes B-D-P."""
    L = dict(zip(BARS, lengths))
    x = np.zeros((5, 3))
    x[D] = [d1, 0.0, 0.0]
    pb, pd = L[(P, B)], L[(P, D)]
    px = (pb ** 2 - pd ** 2 + d1 ** 2) / (2 * d1)
    if pb ** 2 - px ** 2 < 0:
        return None
    x[P] = [px, np.sqrt(pb ** 2 - px ** 2), 0.0]
    a = _sphere3(x[B], L[(A, B)], x[D], L[(A, D)], x[P], L[(P, A)], sides[0])
    c = _sphere3(x[B], L[(B, C)], x[D], L[(C, D)], x[P], L[(P, C)], sides[1])
    if a is None or c is None:
        return None
    x[A], x[C] = a, c
    return x


@pytest.fixture(scope="module")
def sheet():
    d = fabkit.load_template(TEMPLATES / "origami_sheet.toml")
    # the rigid sheet: no paper thickness or crease give, so a build is its bars as cut
    spec = tolerance_spec(d, samples=40, paper_thickness=0.0, compliance_sigma=0.0)
    res = analyse_tolerance(d, spec, attribute=False)
    m = d.motion
    geo = process_geometry(d, res.spec, make_problem(d.network, m.drive, m.to),
                           res.behaviour.end_config)
    builds = sample_builds(geo, res.spec, np.random.default_rng(res.spec.seed))
    return d, res, builds


def test_the_threshold_is_a_quarter_of_the_way_between_the_states_in_fold_angle(sheet):
    d, res, _ = sheet
    end = res.behaviour.end_config
    designed = _folds(end)
    flat = _folds(d.network.nodes)
    assert np.allclose(flat, 0.0, atol=1e-9)
    # the folded crystal d1 = d2 = 2 - sqrt(2): PA and PC at 165.42°, PB and PD at 131.06°
    assert designed == pytest.approx([165.4207, 131.0604, 165.4207, 131.0604], abs=1e-3)
    apart = float(np.max(np.abs(designed - flat)))
    for name in ("crystals", "end state"):
        j = res.judged[name]
        assert j.unit == "°"
        assert j.limit_mm == pytest.approx(0.25 * apart, abs=1e-6) == pytest.approx(41.355,
                                                                                     abs=1e-3)
    folds = res.as_dict()["behaviour"]["folds"]
    assert folds["apart_deg"] == pytest.approx(apart, abs=1e-6) and folds["fraction"] == 0.25
    # the port-distance tolerance it replaces: a quarter of the travel, 21.967 mm
    assert res.behaviour.state_tol * res.spec.scale == pytest.approx(
        0.25 * (np.sqrt(2) - (2 - np.sqrt(2))) * 150 / np.sqrt(2), abs=1e-3)


def test_each_build_s_folded_state_is_judged_by_its_own_folds(sheet):
    d, res, builds = sheet
    end = res.behaviour.end_config
    designed = _folds(end)
    # the sides A and C fold to: those on which the design's own bars rebuild its end state
    d2 = 2 - np.sqrt(2)
    sides = [s for s in ((1, 1), (1, -1))
             if np.allclose(_folds(_sheet(d.network.edge_lengths, d2, s)), designed, atol=1e-6)]
    assert len(sides) == 1
    sides = sides[0]
    judged = res.judged["end state"].value_mm
    grid = np.linspace(2 - np.sqrt(2) - 0.2, 2 - np.sqrt(2) + 0.2, 1601)
    for k in range(builds.base.shape[0]):
        lengths = builds.base[k]

        def g(v):
            x = _sheet(lengths, v, sides)
            return np.nan if x is None else np.linalg.norm(x[A] - x[C]) - v

        gs = np.array([g(v) for v in grid])
        cross = np.flatnonzero(np.isfinite(gs[:-1]) & np.isfinite(gs[1:])
                               & (np.sign(gs[:-1]) != np.sign(gs[1:])))
        # the built crystal: the repelling fixed point nearest the designed one
        cross = [i for i in cross if abs((gs[i + 1] - gs[i]) / (grid[1] - grid[0]) + 1) > 1]
        i = min(cross, key=lambda i: abs(grid[i] - (2 - np.sqrt(2))))
        lo, hi = grid[i], grid[i + 1]
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if np.sign(g(mid)) == np.sign(g(lo)) else (lo, mid)
        off = float(np.max(np.abs(_folds(_sheet(lengths, lo, sides)) - designed)))
        assert judged[k] == pytest.approx(off, abs=1e-4), k
    # every one of these builds folds within 41.4° of the designed crystal: the sheet is ok
    assert np.all(judged <= res.judged["end state"].limit_mm) and not res.flagged


def test_the_flat_state_is_kept_where_the_sheet_locks_flat(sheet):
    _, res, _ = sheet
    # the flat crystal is where each built sheet, unfolded, locks: flat, every fold under 1°
    crystals = res.judged["crystals"]
    assert crystals.unit == "°" and crystals.ok.all() and np.max(crystals.value_mm) < 1.0
