"""The method contract: a method implements ``solve``; the base class owns the Trajectory.

Every registered method (and a user's own subclass) gets a Trajectory whose events are typed,
finite and placed at the configuration they name.
"""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from fabkit.kinematics import METHODS, EventKind, Mark, Method, Solved, Status
from fabkit.kinematics.trajectory import Event

from conftest import module_network

# One scenario per method that meets an event: the 4-bar driven into its flat state, and the flat
# origami sheet (a bifurcation) for the method that starts at singular states.
SCENARIOS = {"branch": ("origami_sheet", 1.0)}
DEFAULT = ("fourbar", 0.5)


@pytest.mark.parametrize("name", sorted(METHODS))
def test_every_method_returns_typed_events_at_their_configurations(name):
    module, to = SCENARIOS.get(name, DEFAULT)
    traj = fabkit.trace(module_network(module), drive="d1", to=to, method=name)
    assert traj.method.split("/")[0] == name
    assert isinstance(traj.status, Status)
    assert traj.events, f"{name} met no event"
    for ev in traj.events:
        assert isinstance(ev.kind, EventKind)
        assert 0 <= ev.index < traj.n_steps
        assert ev.drive == traj.drive[ev.index] and ev.arclength == traj.arclength[ev.index]
        assert np.isfinite(ev.drive) and np.isfinite(ev.arclength)
    if name != "branch":
        # the flat state of the antiparallelogram is at d1 = 2(sqrt(2) - 1)
        last = traj.events[-1]
        assert last.kind in (EventKind.TURNING_POINT, EventKind.BRANCH_POINT)
        assert last.drive == pytest.approx(2 * (np.sqrt(2) - 1), abs=2e-5)


class _ThreeSteps(Method):
    """A user's own method: three configurations of the 4-bar and a mark past the end."""

    name = "three-steps"
    options = {"offset": 0.0}

    def solve(self) -> Solved:
        x = self.problem.start
        moved = np.stack([x, x + 1.0 + self.opts["offset"], x + 2.0])  # rigid shifts
        return Solved(moved, Status.TURNING_POINT, "stopped on purpose",
                       (Mark(EventKind.TURNING_POINT, 99, "past the end"),), {"steps": 2})


def test_the_base_class_packages_a_users_method():
    net = module_network("fourbar")
    traj = fabkit.trace(net, drive="d1", to=3.0, method=_ThreeSteps)
    assert traj.method == "three-steps" and traj.status is Status.TURNING_POINT
    # aligned to the gauge: rigid shifts vanish, so every configuration is the start
    np.testing.assert_allclose(traj.positions, np.broadcast_to(net.nodes, traj.positions.shape),
                               atol=1e-12)
    (ev,) = traj.events
    assert ev.index == 2 and ev.drive == traj.drive[2] and ev.arclength == traj.arclength[2]
    assert traj.stats == {"steps": 2}
    with pytest.raises(TypeError, match="unknown option"):
        fabkit.trace(net, drive="d1", to=3.0, method=_ThreeSteps, ofset=1.0)


def test_a_method_without_solve_cannot_be_made():
    class Incomplete(Method):
        name = "incomplete"

    with pytest.raises(TypeError, match="solve"):
        fabkit.trace(module_network("fourbar"), drive="d1", to=3.0, method=Incomplete)


def test_events_refuse_unknown_kinds_and_nan():
    with pytest.raises(ValueError):
        Event("end_of_the_world", 0, 1.0, 0.0)
    with pytest.raises(ValueError, match="finite"):
        Event(EventKind.TURNING_POINT, 0, float("nan"), 0.0)
    assert Event("branch_point", 1, 2.0, 3.0).kind is EventKind.BRANCH_POINT
