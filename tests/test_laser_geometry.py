"""Bar outlines with exact arcs, distances, stacking layers over the motion, nesting."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fabkit
from fabkit.fab.bars import bar_outline, bulge_primitives, hole_radius, outline_radius, undo_kerf
from fabkit.settings.laser import laser_settings
from fabkit.fab.layers import (Sweep, find_conflicts, plan_layers, point_segment_distance,
                               sample_motion, segment_distance, stacking_gaps)
from fabkit.fab.nest import REFERENCE_SIZE, make_parts, nest_parts
from fabkit.fab.bars import bar_set
from fabkit.templates import Motion

from conftest import TEMPLATES
from sheet_gaps import least_gap, SEPARATION_TOL


def test_outline_is_a_closed_stadium_with_half_circle_bulges():
    v = bar_outline(30.0, 14.0, kerf=0.2)
    assert v.tolist() == [[0.0, -7.1, 0.0], [30.0, -7.1, 1.0], [30.0, 7.1, 0.0], [0.0, 7.1, 1.0]]
    prims = bulge_primitives(v)
    kinds = [p[0] for p in prims]
    assert kinds == ["line", "arc", "line", "arc"]
    (_, c1, r1, a0, a1), (_, c2, r2, b0, b1) = prims[1], prims[3]
    assert c1 == pytest.approx((30.0, 0.0), abs=1e-12) and r1 == pytest.approx(7.1)
    assert (a0, a1) == pytest.approx((270.0, 90.0))       # right end: -90 deg to +90 deg, CCW
    assert c2 == pytest.approx((0.0, 0.0), abs=1e-12) and r2 == pytest.approx(7.1)
    assert (b0, b1) == pytest.approx((90.0, 270.0))
    # kerf: the outline grows and the hole shrinks by half the kerf; undo_kerf inverts it
    assert outline_radius(14.0, 0.2) == pytest.approx(7.1)
    assert hole_radius(4.2, 0.2) == pytest.approx(2.0)
    w, h = undo_kerf(7.1, 2.0, 0.2)
    assert (float(w), float(h)) == pytest.approx((14.0, 4.2))


def test_clockwise_bulge_becomes_a_counter_clockwise_dxf_arc():
    (_, centre, r, a0, a1), = [p for p in bulge_primitives([[1, 0, -1.0], [-1, 0, -1.0]])
                               if p[0] == "arc"][:1]
    assert centre == pytest.approx((0.0, 0.0), abs=1e-12) and r == pytest.approx(1.0)
    assert (a0, a1) == pytest.approx((180.0, 0.0))   # lower half from 1,0 clockwise to -1,0


def test_segment_distances():
    assert float(segment_distance([0, 0], [2, 0], [1, -1], [1, 1])) == 0.0
    assert float(segment_distance([0, 0], [1, 0], [3, 4], [3, 9])) == pytest.approx(math.hypot(2, 4))
    assert float(point_segment_distance([5, 5], [0, 0], [10, 0])) == 5.0
    # parallel overlapping segments 2 apart
    assert float(segment_distance([0, 0], [10, 0], [5, 2], [15, 2])) == pytest.approx(2.0)


def _crank_past_a_bar(h=3.5):
    """Ground 0-1 with a rigid triangle to node 4 above node 0, crank 0-2 swinging from 150 deg
    to 30 deg through the vertical, where it crosses bar 1-4; coupler 2-3 and rocker 3-1."""
    th = math.radians(150)
    nodes = [[0, 0], [10, 0], [3 * math.cos(th), 3 * math.sin(th)],
             [10 + 3 * math.cos(th), 3 * math.sin(th)], [0, h]]
    net = fabkit.Network(nodes, [[0, 1], [0, 4], [1, 4], [0, 2], [2, 3], [3, 1]],
                         ports={"d1": (1, 2)})
    to = math.hypot(10 - 3 * math.cos(math.radians(30)), 3 * math.sin(math.radians(30)))
    return net, Motion(drive="d1", to=to)


def test_bars_that_collide_mid_motion_get_different_layers():
    net, motion = _crank_past_a_bar()
    s = laser_settings({"scale": 20})
    sweep = sample_motion(net, motion, s.scale, s.sample_step)
    crank, brace = 3, 2                           # bars 0-2 and 1-4
    x = sweep.positions
    gap = segment_distance(x[:, 0], x[:, 2], x[:, 1], x[:, 4]) - s.bar_width
    assert gap[0] > 40 and gap[-1] > s.clearance       # apart at the start and at the end
    assert gap.min() < 0                               # overlapping in between
    assert 0 < int(np.argmin(gap)) < sweep.n_samples - 1
    ends_only = find_conflicts(net.edges, x[[0, -1]], width=s.bar_width, clearance=s.clearance,
                               column_radius=4.25)
    assert [brace, crank] not in ends_only.pairs.tolist()   # invisible from start and end
    stacking = plan_layers(net.edges, sweep, s)
    pairs = stacking.conflicts.pairs.tolist()
    k = pairs.index([brace, crank])
    assert stacking.conflicts.kind[k] == "sweep"
    assert 0 < stacking.conflicts.sample[k] < sweep.n_samples - 1
    assert stacking.layer[brace] != stacking.layer[crank]
    # the guarantee: steps bounded, and bars of one layer keep the clearance over the motion
    assert sweep.max_step <= s.sample_step
    gaps = stacking_gaps(net.edges, stacking.layer, x, width=s.bar_width)
    assert gaps["bar_gap"] >= s.clearance


def test_sampling_guarantee_holds_on_the_super_stable_collapse():
    design = fabkit.load_template(TEMPLATES / "super_stable.toml")
    s = laser_settings()
    sweep = sample_motion(design.network, design.motion, s.scale, s.sample_step)
    steps = np.linalg.norm(np.diff(sweep.positions, axis=0), axis=2).max(axis=1)
    assert steps.max() <= s.sample_step and sweep.max_step == pytest.approx(steps.max())
    # the samples lie on the motion: every edge keeps its length (mm)
    lengths = design.network.lengths_at(sweep.positions / s.scale) * s.scale
    assert np.abs(lengths - design.network.edge_lengths * s.scale).max() < 1e-9
    assert sweep.drive[0] == pytest.approx(math.sqrt(3)) and sweep.drive[-1] == pytest.approx(design.motion.to)


def test_fourbar_layers_are_optimal_and_screws_follow_the_stack():
    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    s = laser_settings()
    sweep = sample_motion(design.network, design.motion, s.scale, s.sample_step)
    st = plan_layers(design.network.edges, sweep, s)
    # bars 0-3 and 1-2 cross (antiparallelogram) and every other pair shares a joint: K4 minus
    # the pair 0-2 / 1-3, so three layers, which is the clique bound
    assert st.n_layers == 3 == st.lower_bound
    assert {tuple(p) for p, k in zip(st.conflicts.pairs.tolist(), st.conflicts.kind)
            if k == "sweep"} == {(1, 2)}
    for js in st.joints:
        span = max(js.layers) - min(js.layers) + 1
        assert js.stack_height == pytest.approx(span * s.thickness)
        assert js.screw_length >= js.stack_height + s.screw.allowance
        assert len(js.spacers) == span - len(js.bars)


def test_stacking_reorders_layers_to_keep_bars_off_screw_heads():
    # Two bars share joint 1; a third bar passes over joint 1's screw during the motion. With
    # one head layer above and below the stack it must sit outside layers [lo-1, hi+1].
    x = np.array([[[0, 0], [100, 0], [200, 0], [100, -60], [100, 60]],
                  [[0, 0], [100, 0], [200, 0], [90, -60], [90, 60]]], dtype=float)
    edges = [[0, 1], [1, 2], [3, 4]]
    sweep = Sweep(x, np.zeros(2), 0.5, 0.0, "given", "finished", "")
    st = plan_layers(edges, sweep, laser_settings())
    lo, hi = sorted(st.layer[:2])
    assert st.layer[2] < lo - 1 or st.layer[2] > hi + 1
    # bar 3-4 crosses both others (clique of 3), and the head needs one more layer: the
    # complete search finds that no 3-layer stacking exists, so the bound is 4
    assert st.n_layers == 4 and st.strategy == "propagation"
    assert st.stats["clique"] == 3 and st.lower_bound == 4 and st.stats["proven_minimal"]


def test_coinciding_joints_are_refused_with_a_fix():
    from fabkit.design.assemble import chain

    module = fabkit.load_template(TEMPLATES / "super_stable.toml")
    net = chain(module.network, 8, mirror="none")   # unmirrored: every third module lies on the first
    s = laser_settings()
    sweep = sample_motion(net, module.motion, s.scale, s.sample_step)
    with pytest.raises(fabkit.FabricationError) as info:
        plan_layers(net.edges, sweep, s)
    assert "mm apart at the start" in str(info.value) and 'mirror = "alternate"' in str(info.value)


def test_nesting_places_every_part_inside_sheets_without_overlap():
    s = laser_settings({"sheet_width": 260, "sheet_height": 130})
    lengths = np.tile([150.0, 120, 90, 200, 60, 45, 170, 110, 80, 220], 2)
    edges = np.stack([np.arange(20), np.arange(1, 21)], 1)
    bars = bar_set(lengths, edges, s)
    x = np.zeros((1, 21, 2))
    x[0, :, 0] = np.arange(21) * 1000.0   # far apart: no sweep conflicts
    st = plan_layers(edges, Sweep(x, np.zeros(1), 0.5, 0.0, "given", "finished", ""), s)
    parts = make_parts(bars, st, s)
    sheets = nest_parts(parts, s)
    assert len(sheets) >= 2
    placed = [p for sh in sheets for p in sh.parts]
    assert sorted(p.id for p in placed) == sorted(p.id for p in parts)
    ref = [sh.index for sh in sheets for p in sh.parts if p.id == "REF"]
    assert ref == [1]
    for sh in sheets:
        boxes = np.array([p.bbox for p in sh.parts])
        assert (boxes[:, :2] >= s.margin - 1e-9).all()
        assert (boxes[:, 2] <= s.sheet_width - s.margin + 1e-9).all()
        assert (boxes[:, 3] <= s.sheet_height - s.margin + 1e-9).all()
        for a in range(len(boxes)):
            for b in range(a + 1, len(boxes)):
                sep = max(boxes[b, 0] - boxes[a, 2], boxes[a, 0] - boxes[b, 2],
                          boxes[b, 1] - boxes[a, 3], boxes[a, 1] - boxes[b, 3])
                assert sep >= s.spacing - 1e-6
    # moving parts keeps hole spacing exact (quarter turns and shifts only)
    for p in placed:
        if p.kind == "bar":
            k = p.meta["bar"]
            assert np.linalg.norm(p.holes[1] - p.holes[0]) == pytest.approx(lengths[k], abs=1e-9)
            assert p.labels and p.labels[0].text.startswith(f"B{k} ")
    square = next(p for p in placed if p.id == "REF")
    side = np.ptp(square.outline[:, :2], axis=0)
    assert side.tolist() == pytest.approx([REFERENCE_SIZE, REFERENCE_SIZE])


def _overlap_free(sheets, s):
    # true shapes (stadiums round the holes, discs): a part of a last sheet may be moved into
    # the free space between round ends, where the packer's boxes would overlap
    for sh in sheets:
        assert least_gap(sh, s) >= s.spacing - SEPARATION_TOL


def test_large_kits_are_nested_in_groups_as_tightly_as_at_once(monkeypatch):
    import fabkit.fab.nest as nest

    s = laser_settings({"sheet_width": 260, "sheet_height": 130})
    rng = np.random.default_rng(3)
    lengths = rng.uniform(40.0, 220.0, 400)
    edges = np.stack([np.arange(400), np.arange(1, 401)], 1)
    bars = bar_set(lengths, edges, s)
    x = np.zeros((1, 401, 2))
    x[0, :, 0] = np.arange(401) * 1000.0
    st = plan_layers(edges, Sweep(x, np.zeros(1), 0.5, 0.0, "given", "finished", ""), s)
    parts = make_parts(bars, st, s)
    grouped = nest_parts(parts, s)
    free = (s.sheet_width - 2 * s.margin + s.spacing) * (s.sheet_height - 2 * s.margin + s.spacing)
    area = sum((p.bbox[2] - p.bbox[0] + s.spacing) * (p.bbox[3] - p.bbox[1] + s.spacing)
               for p in parts)
    assert area > nest.GROUP_SHEETS * free  # so the kit is packed in groups
    monkeypatch.setattr(nest, "GROUP_SHEETS", 10 ** 6)
    at_once = nest_parts(parts, s)
    assert len(grouped) <= len(at_once) + 1
    assert sorted(p.id for sh in grouped for p in sh.parts) == sorted(p.id for p in parts)
    assert [sh.index for sh in grouped] == list(range(1, len(grouped) + 1))
    _overlap_free(grouped, s)
    # the groups' emptier last sheets are re-packed with the next group: no tail of half-empty
    # sheets in the middle of the kit
    fill = [sum((p.bbox[2] - p.bbox[0]) * (p.bbox[3] - p.bbox[1]) for p in sh.parts) / free
            for sh in grouped]
    assert min(fill[:len(grouped) // 2]) > 0.6


def test_part_larger_than_the_sheet_is_refused():
    s = laser_settings({"sheet_width": 200, "sheet_height": 150})
    bars = bar_set([300.0], [[0, 1]], s)
    x = np.array([[[0, 0], [300, 0]]], dtype=float)
    st = plan_layers([[0, 1]], Sweep(x, np.zeros(1), 0.5, 0.0, "given", "finished", ""), s)
    with pytest.raises(fabkit.FabricationError, match="part B0 .* does not fit on a 200 x 150 mm"):
        nest_parts(make_parts(bars, st, s), s)


@pytest.mark.parametrize("method", ["projected", "rk4-nullspace"])
def test_sampling_bound_holds_for_the_other_methods(method):
    import dataclasses

    design = fabkit.load_template(TEMPLATES / "super_stable.toml")
    s = laser_settings()
    motion = dataclasses.replace(design.motion, method=method)
    sweep = sample_motion(design.network, motion, s.scale, s.sample_step)
    steps = np.linalg.norm(np.diff(sweep.positions, axis=0), axis=2).max(axis=1)
    assert sweep.method == method and steps.max() <= s.sample_step
    assert sweep.drive[-1] == pytest.approx(design.motion.to, abs=1e-9)


def _rules_broken(st, edges):
    """Every stacking rule checked from the stacking's own conflicts, independently of the
    planner's scoring: (pair on one layer, bar in a column, columns that meet)."""
    layer, head = st.layer, st.head_slots
    conf = st.conflicts
    span = {}
    for j in conf.screw_joints.tolist():
        zs = layer[[k for k, e in enumerate(edges.tolist()) if j in e]]
        span[j] = (int(zs.min()), int(zs.max()))
    broken = [("pair", a, b) for a, b in conf.pairs.tolist() if layer[a] == layer[b]]
    for rows, slack in ((conf.keepout, head), (conf.keepout_span, 0)):
        broken += [("column", b, j) for b, j in rows.tolist()
                   if span[j][0] - slack <= layer[b] <= span[j][1] + slack]
    broken += [("columns", i, j) for i, j in conf.joint_pairs.tolist()
               if span[i][0] - head <= span[j][1] + head and span[j][0] - head <= span[i][1] + head]
    return broken


def _chain_stacking(name):
    from fabkit.settings.laser import laser_overrides
    from fabkit.fab.layers import sample_chain

    design = fabkit.load_template(TEMPLATES / f"{name}.toml")
    net = design.network
    s = laser_settings(design.fabrication.get("laser", {}), laser_overrides({}),
                       network_size=net.size)
    sweep = sample_chain(net, design.motion, s.scale, s.sample_step, width=s.bar_width,
                         clearance=s.clearance, column_radius=0.5 * s.screw.head_diameter,
                         spacer_radius=0.5 * s.spacer_diameter, floor_limit=s.clearance)
    return net, s, sweep, plan_layers(net.edges, sweep, s)


def test_search_reaches_the_clique_bound_where_colourings_stop_one_layer_above():
    net, s, sweep, st = _chain_stacking("slope_one_and_a_half_chain")
    # every colouring that keeps bars off the screws needs 7 layers; six bars meet pairwise
    # (a clique of 6), and the layer search finds a 6-layer stacking: minimal, by the clique
    good = [c for c in st.stats["candidates"] if c[2] == 0]
    assert good and min(c[1] for c in good) == 7
    assert st.n_layers == 6 == st.lower_bound == st.stats["clique"]
    assert st.strategy == "backtracking" and st.proven_minimal and st.stats["proven_minimal"]
    assert st.proof_text() == "6 layers (proven minimal)"
    assert _rules_broken(st, np.asarray(net.edges)) == []
    assert set(st.layer.tolist()) == set(range(6))
    # the screws' total span after the descent (the search alone gives 90 layer steps)
    assert sum(max(js.layers) - min(js.layers) for js in st.joints) == 87
    gaps = stacking_gaps(net.edges, st.layer, sweep.positions, width=s.bar_width,
                         joints=st.joints, head_slots=st.head_slots,
                         column_radius=0.5 * s.screw.head_diameter,
                         spacer_radius=0.5 * s.spacer_diameter)
    assert min(gaps["bar_gap"], gaps["screw_gap"], gaps["column_gap"]) >= s.clearance


def test_shorter_screws_keep_every_rule_and_the_layer_count():
    from fabkit.fab.layers.search import _search_layers, _shorten_screws

    net, s, sweep, st = _chain_stacking("slope_one_and_a_half_chain")
    edges = np.asarray(net.edges)
    conf = st.conflicts
    inc = [np.flatnonzero((edges == j).any(axis=1)) for j in conf.screw_joints.tolist()]
    jpos = np.full(net.n_nodes, -1, dtype=np.int64)
    jpos[conf.screw_joints] = np.arange(conf.screw_joints.size)
    found = _search_layers(edges.shape[0], conf, inc, st.head_slots, range(6, 7))
    short = _shorten_screws(found, conf, inc, jpos, st.head_slots)

    def total(layer):
        return sum(int(layer[jb].max() - layer[jb].min()) for jb in inc)

    assert (total(found), total(short)) == (90, 87)
    assert short.max() + 1 <= 6
    fake = type("S", (), {"layer": short, "head_slots": st.head_slots, "conflicts": conf})
    assert _rules_broken(fake, edges) == []


def test_unproven_count_says_what_is_proven():
    from fabkit.fab.layers import Stacking

    _, _, _, st = _chain_stacking("slope_one_and_a_half_chain")
    unproven = Stacking(layer=st.layer, n_layers=7, joints=st.joints, conflicts=st.conflicts,
                        lower_bound=6, strategy="milp", head_slots=1)
    assert not unproven.proven_minimal
    assert unproven.proof_text() == "7 layers (at least 6 needed; fewer not ruled out)"


def _brute_gaps(edges, layer, x, width, joints, head, column_radius, spacer_radius):
    """stacking_gaps' three numbers by a plain loop over samples and pairs."""
    edges = np.asarray(edges)
    bar, screw, column = math.inf, math.inf, math.inf
    span = {st.joint: (min(st.layers) - head, max(st.layers) + head) for st in joints}
    for xs in x:
        for a in range(len(edges)):
            for b in range(a + 1, len(edges)):
                if layer[a] == layer[b] and not set(edges[a]) & set(edges[b]):
                    d = float(segment_distance(xs[edges[a, 0]], xs[edges[a, 1]],
                                               xs[edges[b, 0]], xs[edges[b, 1]]))
                    bar = min(bar, d - width)
            for st in joints:
                z0, z1 = span[st.joint]
                if z0 <= layer[a] <= z1 and st.joint not in edges[a]:
                    inner = z0 + head <= layer[a] <= z1 - head
                    r = max(column_radius, spacer_radius) if inner else column_radius
                    d = float(point_segment_distance(xs[st.joint], xs[edges[a, 0]],
                                                     xs[edges[a, 1]]))
                    screw = min(screw, d - 0.5 * width - r)
        for i, s1 in enumerate(joints):
            for s2 in joints[i + 1:]:
                (a0, a1), (b0, b1) = span[s1.joint], span[s2.joint]
                if a0 <= b1 and b0 <= a1:
                    d = float(np.linalg.norm(xs[s1.joint] - xs[s2.joint]))
                    column = min(column, d - 2 * column_radius)
    return bar, screw, column


def test_stacking_gaps_measure_the_true_minimum_between_coarse_samples():
    from fabkit.fab.layers import JointStack

    # bar 3-4 passes above bar 0-1 (one layer) and closest at sample 45 of 300, between the
    # coarse samples 32 and 64 of the pruning; bars 5-6 and 6-7 are far away and left out of
    # the full scan
    t = np.linspace(0, 1, 300)
    y = 20 + 60 * (t - 45 / 299) ** 2
    x = np.zeros((t.size, 8, 2))
    x[:, :3] = [[0, 0], [100, 0], [150, 40]]
    x[:, 3] = np.stack([20 + 10 * t, y], 1)
    x[:, 4] = np.stack([80 + 10 * t, y], 1)
    x[:, 5:] = [[1000, 0], [1100, 0], [1150, 40]]
    edges = np.array([[0, 1], [1, 2], [3, 4], [5, 6], [6, 7]])
    layer = np.array([0, 1, 0, 0, 1])
    joints = [JointStack(1, (0, 1), (0, 1), (), 0.0, 0.0, 0.0),
              JointStack(6, (3, 4), (0, 1), (), 0.0, 0.0, 0.0)]
    got = stacking_gaps(edges, layer, x, width=6.0, joints=joints, head_slots=1,
                        column_radius=4.0, spacer_radius=5.0)
    want = _brute_gaps(edges, layer, x, 6.0, joints, 1, 4.0, 5.0)
    assert (got["bar_gap"], got["screw_gap"], got["column_gap"]) == pytest.approx(want, abs=1e-12)
    assert got["bar_pair"] == [0, 2] and got["sample"] == 45
    assert got["bar_gap"] == pytest.approx(20 - 6.0, abs=1e-12)
    a, b = got["bar_pair"]
    k = got["sample"]
    xs = x[k]
    assert float(segment_distance(xs[edges[a, 0]], xs[edges[a, 1]], xs[edges[b, 0]],
                                  xs[edges[b, 1]])) - 6.0 == pytest.approx(got["bar_gap"])
    # the same without the pruning (no more samples than two strides): the same numbers
    few = stacking_gaps(edges, layer, x[::5], width=6.0, joints=joints, head_slots=1,
                        column_radius=4.0, spacer_radius=5.0)
    assert (few["bar_gap"], few["screw_gap"], few["column_gap"]) == pytest.approx(
        _brute_gaps(edges, layer, x[::5], 6.0, joints, 1, 4.0, 5.0), abs=1e-12)


def test_a_small_neighbourhood_proves_the_count_of_the_super_stable_chain():
    from fabkit.fab.layers.search import _colourings, _milp_layers, _neighbourhood

    net, s, sweep, st = _chain_stacking("super_stable_chain8")
    # the clique says 6, the column rules force a 7th: proven on 16 bars around the clique
    assert (st.n_layers, st.lower_bound, st.stats["clique"]) == (7, 7, 6)
    assert st.proven_minimal and st.proof_text() == "7 layers (proven minimal)"
    assert _rules_broken(st, np.asarray(net.edges)) == []
    edges = np.asarray(net.edges)
    conf = st.conflicts
    joint_bars = [np.flatnonzero((edges == j).any(axis=1)) for j in conf.screw_joints.tolist()]
    _, clique, members = _colourings(edges.shape[0], conf.pairs)
    sub = _neighbourhood(edges.shape[0], conf, joint_bars, members, 16)
    assert sub[0] == 16
    layer, bound, optimal = _milp_layers(*sub, st.head_slots, 6)
    assert layer is None and bound == 7 and optimal  # no 6-layer stacking of the 16 bars



def test_layer_search_budget_bounds_backtracking_not_length():
    """A long chain of conflicts: one pass places every bar, whatever the backtracking budget."""
    from types import SimpleNamespace

    from fabkit.fab.layers.search import _search_layers

    n = 5000
    none = np.zeros((0, 2), dtype=np.int64)
    conf = SimpleNamespace(screw_joints=np.zeros(0, dtype=np.int64),
                           pairs=np.stack([np.arange(n - 1), np.arange(1, n)], axis=1),
                           keepout=none, keepout_span=none, joint_pairs=none)
    layer = _search_layers(n, conf, [], 1, range(1, 4), node_limit=100)
    assert layer is not None and int(layer.max()) + 1 == 2  # one layer is refused, two suffice
    assert (layer[:-1] != layer[1:]).all()


def test_class_score_counts_as_the_full_score():
    """Scoring permutations of colour classes over distinct colour sets = scoring every bar."""
    from fabkit.fab.layers.search import _ClassScore, _score

    rng = np.random.default_rng(11)
    n_bars, k = 300, 5
    colours = rng.integers(0, k, n_bars)
    joints = np.arange(40)
    joint_bars = [np.unique(rng.choice(n_bars, size=rng.integers(1, 5), replace=False))
                  for _ in joints]
    jpos = np.arange(40)
    keepout = np.stack([rng.integers(0, n_bars, 60), rng.choice(joints, 60)], axis=1)
    span = np.stack([rng.integers(0, n_bars, 30), rng.choice(joints, 30)], axis=1)
    pairs = np.stack([rng.choice(joints, 25), rng.choice(joints, 25)], axis=1)
    perms = np.array([rng.permutation(k) for _ in range(50)])
    got = _ClassScore(colours, joint_bars, jpos, keepout, pairs, 1, span)(perms)
    want = _score(perms[:, colours], joint_bars, jpos, keepout, pairs, 1, span)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert want[0].max() > 0  # the rules are exercised


@pytest.mark.parametrize("text", ["B12·L3", "J45→p2", "100 mm", "S14.2"])
def test_label_outlines_set_glyph_by_glyph_match_ezdxf_drawing_the_whole_line(text):
    """Labels are drawn from glyphs cached one by one; the line they make is the one ezdxf's
    text2path draws for the whole text, centred (same polylines to 1e-12 mm)."""
    from ezdxf.addons import text2path
    from ezdxf.enums import TextEntityAlignment
    from ezdxf.fonts import fonts

    from fabkit.fab.nest import GLYPH_FLATNESS, Label, label_outlines

    paths = text2path.make_paths_from_str(text, fonts.FontFace(family="DejaVu Sans"), size=3.0,
                                          align=TextEntityAlignment.MIDDLE_CENTER)
    whole = [np.array([(v.x, v.y) for v in sub.flattening(distance=GLYPH_FLATNESS, segments=1)])
             for p in paths for sub in p.sub_paths()]
    whole = [w + (10.0, 20.0) for w in whole if w.shape[0] >= 3]
    ours = label_outlines(Label(text, (10.0, 20.0), 3.0, 0.0, "bar 0"))
    assert [o.shape for o in ours] == [w.shape for w in whole]
    assert max(float(np.abs(o - w).max()) for o, w in zip(ours, whole)) < 1e-12
