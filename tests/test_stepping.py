"""The stepping base owns the loop: configurations, max_steps, stops and their events, refusal of
non-finite steps; a method gives its start and one step at a time (here a toy method that moves
the paper's 4-bar by exact placement at fixed drive increments)."""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from fabkit.kinematics import (EventKind, Status, Step, StepMethod, Stop, make_problem, place,
                               plan_construction)


def fourbar():
    return fabkit.Network([[-1, -1], [-1, 1], [1, -1], [1, 1]],
                          [[0, 2], [0, 3], [1, 2], [1, 3]], ports={"d1": (0, 1), "d2": (2, 3)})


class Toy(StepMethod):
    """Fixed drive increments by exact placement; ``fault`` plants a stop or a bad step."""

    name = "toy"
    options = {"delta": 0.125, "max_steps": 1000, "fault": None, "at": 2}

    def _start(self, x0):
        p = self.problem
        self.plan = plan_construction(p.work, p.drive, p.start)
        self.value = p.start_drive
        self.calls = 0
        if self.opts["fault"] == "start":
            return Stop(Status.FINISHED, "nothing to do")
        return None

    def _at(self, value):
        return place(self.plan, [value])[0][0].ravel()

    def _step(self):
        p = self.problem
        self.calls += 1
        if self.calls == self.opts["at"]:
            if self.opts["fault"] == "nan":
                return Step(np.full(p.start.size, np.nan))
            if self.opts["fault"] == "turn":
                x = self._at(self.value + 0.5 * self.opts["delta"])
                return Stop(Status.TURNING_POINT, "planted turn", append=(x,),
                            event=EventKind.TURNING_POINT, detail="here")
        self.value += self.direction() * self.opts["delta"]
        if (self.value - p.target) * self.direction() >= 0:
            return Stop(Status.FINISHED, self.finished_message(), append=(self._at(p.target),))
        return Step(self._at(self.value))

    def _stats(self):
        return {"calls": self.calls}


def run(to=2.5, **options):
    net = fourbar()
    return Toy(make_problem(net, "d1", to), **options).run()


def test_the_loop_lands_on_the_target_with_monotone_arclength():
    tr = run(2.5)
    assert tr.status == Status.FINISHED and tr.method == "toy"
    assert tr.drive[-1] == pytest.approx(2.5, abs=1e-12)
    assert len(tr.positions) == 5  # three increments of 0.125, the fourth landing on 2.5
    assert np.all(np.diff(tr.arclength) > 0)
    assert tr.stats == {"steps": 4, "calls": 4}
    assert np.abs(tr.edge_error).max() < 1e-12


def test_max_steps_ends_with_a_failure_that_says_where():
    tr = run(2.6, max_steps=3)
    assert tr.status == Status.FAILED
    assert len(tr.positions) == 4 and tr.stats["steps"] == 3
    assert tr.message == f"no target after 3 steps (d1 = {tr.drive[-1]:.10g})"
    assert tr.drive[-1] == pytest.approx(2.375, abs=1e-12)


def test_a_typed_stop_appends_its_configuration_and_marks_it():
    tr = run(2.5, fault="turn")
    assert tr.status == Status.TURNING_POINT and tr.message == "planted turn"
    assert len(tr.positions) == 3  # start, one step, the planted point
    (ev,) = tr.events
    assert ev.kind == EventKind.TURNING_POINT and ev.index == 2 and ev.detail == "here"
    assert ev.drive == pytest.approx(2.1875, abs=1e-12)
    assert ev.arclength == pytest.approx(tr.arclength[-1])


def test_a_non_finite_step_is_a_failure_not_a_nan_in_the_trajectory():
    tr = run(2.5, fault="nan")
    assert tr.status == Status.FAILED
    assert "non-finite" in tr.message and "step 2 of 'toy'" in tr.message
    assert len(tr.positions) == 2 and np.isfinite(tr.positions).all()
    assert np.isfinite(tr.arclength).all() and not tr.events


def test_a_stop_at_the_start_leaves_the_start_alone():
    tr = run(2.5, fault="start")
    assert tr.status == Status.FINISHED and len(tr.positions) == 1 and tr.stats["steps"] == 0


def test_driving_down_steps_down():
    tr = run(1.8)
    assert tr.status == Status.FINISHED and tr.drive[-1] == pytest.approx(1.8, abs=1e-12)
    assert np.all(np.diff(tr.drive) < 0)
