"""The loop of step-by-step tracing methods, owned once (as ``solve_ivp`` owns its solvers' loop).

A step-based method (``projected``, ``rk4-nullspace``) subclasses :class:`StepMethod` and
implements two things: :meth:`StepMethod._start`, which sets the method up at the start
configuration, and :meth:`StepMethod._step`, which takes one accepted step from the last
configuration (controlling its own step size, rejecting and retrying inside). Each returns a
typed result: :class:`Step` (the next configuration) or :class:`Stop` (a status, a message, the
configurations that end the trace — the landing on the target, the point found at a turning or
branch point — and the event at the last of them). The base keeps the configurations, counts
steps against ``max_steps``, refuses a non-finite configuration, turns the stop into events at the
right index, and returns the :class:`~.base.Solved`; :meth:`~.base.Method.run` then builds the
Trajectory. Control flows on these types, never on message text.

A method that declares an ``until`` option lets its caller end the trace early: ``until(x)`` is
asked after every accepted step (x of shape (N, d), in the method's frame) and the trace stops,
``failed`` with a message that says so, after the first configuration it holds for (a build judged only up to
where its loops run out of play need not be traced beyond it).
"""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import dataclass

import numpy as np

from .base import Mark, Method, Solved
from .record import Recorder
from ..status import Status
from .trajectory import EventKind

__all__ = ["Step", "Stop", "StepMethod"]


@dataclass(frozen=True, eq=False)
class Step:
    """One accepted step: the next configuration, flat (d·N,)."""

    x: np.ndarray


@dataclass(frozen=True, eq=False)
class Stop:
    """The end of a trace.

    Attributes
    ----------
    status : Status
    message : str
        One sentence: where and why the trace ended.
    append : tuple of numpy.ndarray
        Configurations (flat) that end the trace, appended in order (e.g. the landing on the
        target, or the point found at a turning point).
    event : EventKind or None
        An event at the last configuration once ``append`` is appended.
    detail : str
        The event's sentence.
    """

    status: Status
    message: str
    append: tuple = ()
    event: EventKind | None = None
    detail: str = ""


class StepMethod(Method):
    """Base class of methods that trace step by step (see the module docstring).

    Subclasses declare ``options`` with a ``max_steps`` entry, and implement :meth:`_start`,
    :meth:`_step` and, for their counters, :meth:`_stats`. The configurations accepted so far are
    ``self.positions`` (flat arrays; the last one is where the next step starts).
    """

    #: True when the configurations are already in the gauge frame (the method fixes the gauge).
    aligned = False

    @abstractmethod
    def _start(self, x0: np.ndarray) -> Stop | None:
        """Set up at the start configuration ``x0`` (flat); a Stop ends the trace there."""

    @abstractmethod
    def _step(self) -> Step | Stop:
        """One accepted step from ``self.positions[-1]``, or the end of the trace."""

    def _stats(self) -> dict:
        """The method's own counters (steps are counted by the base)."""
        return {}

    def _exhausted(self) -> Stop:
        """The stop when ``max_steps`` steps did not reach the target."""
        p = self.problem
        x = self.positions[-1].reshape(p.start.shape)
        drive = float(p.drive_of(x[None])[0])
        return Stop(Status.FAILED, f"no target after {self.opts['max_steps']} steps "
                                   f"({p.drive_name} = {drive:.10g})")

    def _until_stop(self, step: int) -> Stop:
        """The stop when the caller's ``until`` holds at the configuration of step ``step``."""
        p = self.problem
        x = self.positions[-1].reshape(p.start.shape)
        drive = float(p.drive_of(x[None])[0])
        return Stop(Status.FAILED, f"stopped at step {step} by the caller's until "
                                   f"({p.drive_name} = {drive:.10g})")

    def solve(self) -> Solved:
        p = self.problem
        x0 = p.start.ravel().copy()
        self.positions = [x0]
        # with keep other than "all", configurations go to the recorder as soon as the next one
        # is accepted, and only the last stays in self.positions (where the next step starts)
        recorder = None if p.keep == "all" else Recorder(p, aligned=self.aligned)
        count = 1
        stop = self._start(x0)
        limit = int(self.opts["max_steps"])
        until = self.opts.get("until")

        def accept(x):
            nonlocal count
            self.positions.append(x)
            count += 1
            if recorder is not None:  # in the gauge frame unless the method moved its gauge
                recorder.add(self.positions.pop(0), aligned=self.aligned)

        while stop is None:
            if count > limit:
                stop = self._exhausted()
                break
            result = self._step()
            if isinstance(result, Stop):
                stop = result
                break
            x = np.asarray(result.x, dtype=np.float64)
            if x.shape != x0.shape or not np.isfinite(x).all():
                stop = Stop(Status.FAILED,
                            f"step {count} of '{self.name}' gave a configuration "
                            "with non-finite coordinates; the trace stops before it")
                break
            accept(x)
            if until is not None and until(x.reshape(p.start.shape)):
                stop = self._until_stop(count - 1)
        for x in stop.append:
            x = np.asarray(x, dtype=np.float64)
            if x.shape == x0.shape and np.isfinite(x).all():
                accept(x)
        marks = ()
        if stop.event is not None:
            marks = (Mark(stop.event, count - 1, stop.detail),)
        stats = {"steps": count - 1, **self._stats()}
        stats["steps"] = count - 1
        if recorder is not None:
            for x in self.positions:
                recorder.add(x, aligned=self.aligned)
            return Solved(None, stop.status, stop.message, marks, stats,
                           record=recorder.finish())
        X = np.array(self.positions).reshape((len(self.positions),) + p.start.shape)
        return Solved(X, stop.status, stop.message, marks, stats, aligned=self.aligned)
