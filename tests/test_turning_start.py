"""Leaving a start where the drive turns (fabkit.kinematics.branching.turning_branches).

The physical 4-bar (bars 0-2 = 1, 1-2 = 2, 0-3 = 1, 1-3 = √3) starts flat, nodes 0, 1, 2 on one
line: d1 = 1 is the least d1 of its motion, and both ways along that motion open it, node 2
going to either side of the line 0–1. The reference is the 4-bar placed by hand: with d1 given,
nodes 2 and 3 are circle intersections on either side, and d2 follows.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import fabkit
from fabkit.cli import main
from fabkit.errors import KinematicsError
from fabkit.kinematics.branching import fold_through, turning_branches

from conftest import TEMPLATES


def _d2_by_hand(d1: float, same_side: bool) -> float:
    """d2 of the 4-bar at d1: node 0 at the origin, node 1 at (d1, 0), node 2 at distances 1
    and 2 from them, node 3 at 1 and √3, on the same side of the line 0–1 or on opposite ones."""
    def apex(r0, r1):
        x = (r0 ** 2 - r1 ** 2 + d1 ** 2) / (2 * d1)
        return np.array([x, math.sqrt(r0 ** 2 - x ** 2)])

    p2, p3 = apex(1.0, 2.0), apex(1.0, math.sqrt(3.0))
    if not same_side:
        p2 = p2 * [1.0, -1.0]
    return float(np.linalg.norm(p2 - p3))


@pytest.fixture(scope="module")
def flat():
    return fabkit.load_template("physical_fourbar").network


def test_the_flat_start_has_two_ways_out_and_they_are_mirror_images(flat):
    turn = turning_branches(flat, flat.nodes, flat.port("d1"))
    assert [b.index for b in turn.branches] == [1, 2]
    one, two = turn.branches
    assert np.allclose(one.tangent, -two.tangent)
    # d1 stands still to first order and grows to second order, the same on both
    assert abs(one.port_rates["d1"][0]) < 1e-9 and abs(two.port_rates["d1"][0]) < 1e-9
    assert one.port_rates["d1"][1] == pytest.approx(two.port_rates["d1"][1])
    assert one.port_rates["d1"][1] > 0
    assert one.words == "node 2 leaves the line 0–1 to its right (away from node 3)"
    assert two.words == "node 2 leaves the line 0–1 to its left (the side of node 3)"
    # d2 moves to first order (a regular drive there): not a turning point of d2
    assert turning_branches(flat, flat.nodes, flat.port("d2")) is None


@pytest.mark.parametrize("branch, same_side", [(None, False), (1, False), (2, True)])
def test_each_branch_is_the_fourbar_placed_by_hand(flat, branch, same_side):
    traj = fold_through(flat, "d1", 1.9, branch=branch)
    assert traj.success and traj.stats["turning_start"]
    assert traj.stats["branch"] == (branch or 1)
    for k in (20, 60, len(traj.drive) - 1):
        d1 = float(traj.distance("d1")[k])
        assert float(traj.distance("d2")[k]) == pytest.approx(_d2_by_hand(d1, same_side),
                                                              abs=1e-9)
    # on the branch away from node 3, d1 = 1.9 is next to the stable D2* = 1.90721 (slope
    # -0.537): d2 = 1.91105
    if not same_side:
        assert float(traj.distance("d2")[-1]) == pytest.approx(1.9110471, abs=1e-6)


def test_a_target_below_the_turning_point_is_on_no_branch(flat):
    with pytest.raises(KinematicsError, match="no branch through the singular state moves the "
                                              "drive towards the target"):
        fold_through(flat, "d1", 0.9)


def test_simulate_names_the_branch_and_takes_the_other(capsys, tmp_path):
    path = str(TEMPLATES / "physical_fourbar.toml")
    common = [path, "--set", "motion.drive=d1", "--to", "1.9", "-o", str(tmp_path)]
    assert main(["simulate", *common]) == 0
    out = capsys.readouterr().out
    assert "on branch 1 of 2 (node 2 leaves the line 0–1 to its right (away from node 3)); " \
           "branch 2 is its mirror image (node 2 leaves the line 0–1 to its left (the side of " \
           "node 3)); then reached d1 = 1.9" in out
    assert main(["simulate", *common, "--branch", "2"]) == 0
    assert "on branch 2 of 2 (node 2 leaves the line 0–1 to its left" in capsys.readouterr().out
    d2 = np.load(tmp_path / "physical_fourbar" / "trajectory.npz")
    assert d2["positions"].shape[0] > 2


@pytest.mark.parametrize("extra, code, words", [
    (["--branch", "3"], 1, "no branch 3: the start has 2 branch(es) (branch 1: node 2 leaves"),
    (["--branch", "0"], 2, "--branch: numbers branches from 1, got 0"),
    (["--branch", "1", "--method", "projected"], 2, "--method projected does not take it"),
])
def test_bad_branches_are_named(capsys, tmp_path, extra, code, words):
    path = str(TEMPLATES / "physical_fourbar.toml")
    assert main(["simulate", path, "--set", "motion.drive=d1", "--to", "1.9", "-o",
                 str(tmp_path), *extra]) == code
    assert words in capsys.readouterr().err
