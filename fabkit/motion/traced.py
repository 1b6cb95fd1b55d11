"""The Motion stage: a design's motion traced once, with one typed status every later stage reads.

:func:`trace_motion` traces a design's ``[motion]`` once and returns a :class:`TracedMotion`:
the trajectory (or None), a :class:`~fabkit.status.Status` (one of
:data:`fabkit.status.MOTION`), a one-line message, the typed error that the stages which need a
motion raise (:meth:`TracedMotion.require`), and whether the design happened
(:mod:`fabkit.motion.ends`). A kit that covers only part of the motion (``motion_from`` /
``motion_to``, :func:`fabkit.motion.window.motion_window`) asks for its window with
:meth:`TracedMotion.window`: each window is traced once and shared by every process and format
that uses it. Exporters, the as-built checks, the tolerance analysis and the reports take the
:class:`TracedMotion`; none of them traces the design's motion itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import ArgumentValueError, FabkitError, MotionError, SingularStartError
from .window import motion_window
from ..templates import BUILDERS
from ..status import MOTION, Status, expect
from ..model.rigidity import count_modes
from .spread import module_spread, shape_missed

__all__ = ["TracedMotion", "trace_motion", "motion_for"]


@dataclass(frozen=True, eq=False)
class TracedMotion:
    """A design's motion, traced once (the result of the Motion stage).

    Attributes
    ----------
    design : Design
        The design this motion moves (for a window: the kit's design, its reference moved to the
        window's start).
    status : Status
        One of :data:`fabkit.status.MOTION`.
    message : str
        One line: what happened (the trace's message, or which ports missed their end and why).
    trajectory : Trajectory or None
        The traced motion; also kept when the trace stopped short (a window's kit is sampled
        along what was traced). None when nothing was traced.
    error : MotionError or None
        The typed failure of a motion that did not reach its target (raised by
        :meth:`require`).
    ends : MotionEnds or None
        The designed end of every port that has one, judged (:func:`fabkit.motion.ends.judge_ends`).
    window : tuple or None
        ``(start, to)`` of a kit's window, None for the design's own motion.
    spread : ModuleSpread or None
        A driven chain: how far each module moved (:func:`fabkit.motion.spread.module_spread`).
    options : dict
        Trace options given beyond the template's ``[motion]`` (a laser kit's
        ``max_node_step``, :func:`fabkit.fab.plans.trace_needs`): a check that traces a rebuilt
        network again traces it with these too, so like is compared with like (a network that
        starts at a branch point, the AND gate, may leave it on another branch at another step).
    """

    design: object
    status: Status
    message: str = ""
    trajectory: object = None
    error: FabkitError | None = None
    ends: object = None
    window: tuple | None = None
    spread: object = None
    options: dict = field(default_factory=dict)
    _windows: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "status", expect(self.status, MOTION, "the Motion stage"))

    @property
    def traced(self) -> bool:
        return self.status.traced

    def require(self):
        """The trajectory of a motion that reached its target.

        Raises
        ------
        MotionError
            The typed failure (:class:`~fabkit.errors.SingularStartError` for a singular
            start), the same for every stage that asks.
        """
        if self.status.traced:
            return self.trajectory
        if self.error is not None:
            raise self.error
        path = self.design.path or self.design.name
        raise MotionError(path, "motion", self.message or "no [motion] with a target `to` is given",
                          status=str(self.status))

    def planning_trajectory(self):
        """The trajectory a kit is planned along (its stacking layers, its hinges): what was
        traced, even short of the target (the pipeline fails a design whose motion does not
        reach its target before any exporter runs; the Python API plans what was traced, as it
        always did). None for a design with no target (the planner says what it needs).

        Raises
        ------
        MotionError
            The motion could not be traced at all (its typed error).
        """
        if self.trajectory is None and self.status is not Status.NO_TARGET:
            self.require()
        return self.trajectory

    def line(self) -> str:
        """The motion in one line, as the command line and the reports say it."""
        local = f"; {self.spread.sentence()}" if self.spread is not None and \
            self.spread.localised and self.status is Status.FINISHED else ""
        if self.status is Status.FINISHED and self.ends is not None:
            return f"{self.message}{local}; every designed end reached ({self.ends.basis})"
        if local:
            return f"{self.message}{local}"
        if self.status is Status.ENDS_MISSED:
            return f"{self.status}: {self.message}"
        return self.message if self.status is Status.FINISHED else \
            f"{self.status}: {self.message}"

    def window_motion(self, start, to, process: str) -> "TracedMotion":
        """The motion of a kit that covers ``start`` to ``to`` of this one, traced once.

        Parameters
        ----------
        start, to : float or None
            ``[fabrication.<process>] motion_from`` / ``motion_to`` (None: this motion's start
            and target).
        process : str
            ``"laser"`` or ``"print"``, for the messages.

        Returns
        -------
        TracedMotion
            ``self`` when neither is given; else the window's motion, the same object for
            every caller that asks for the same window.

        Raises
        ------
        FabricationError
            See :func:`fabkit.motion.window.motion_window`.
        """
        if start is None and to is None:
            return self
        key = (None if start is None else float(start), None if to is None else float(to))
        if key not in self._windows:
            kit = motion_window(self.design, start, to, process)  # places the kit's start
            traj = kit.trace()
            status = Status.FINISHED if traj.success else Status.NOT_REACHED
            self._windows[key] = TracedMotion(kit, status, traj.message, traj, window=key)
        return self._windows[key]


def motion_for(design, motion):
    """The motion an exporter or a check uses: ``motion`` when given (it must be the motion of
    ``design``), else the design's motion traced once here (the Python API without a pipeline).

    Raises
    ------
    ArgumentValueError
        ``motion`` is the motion of another design.
    """
    if motion is None:
        return trace_motion(design)
    if not isinstance(motion, TracedMotion):
        raise ArgumentValueError("motion", "must be a fabkit TracedMotion (fabkit.motion."
                                           f"trace_motion), got {type(motion).__name__}")
    if motion.design is not design:
        raise ArgumentValueError("motion", f"is the motion of {motion.design.name!r}, not of "
                                           f"{design.name!r}")
    return motion


def _builder_key(design) -> str:
    return next((k for k in BUILDERS if k in design.raw), "network")


def trace_motion(design, *, judge: bool = True, **overrides) -> TracedMotion:
    """Trace a design's motion once; every way it can fail is a typed status and error.

    Which template key the error names is decided from the network's structure (its mode count)
    and the trace's typed status, not from any message: no first-order motion → the builder
    section; a singular start (states of self-stress and more than one first-order motion) → the
    nodes; several motions without a singularity → the builder section; a turning or branch
    point before the target → ``motion.to``; any other failure → ``motion``.

    Parameters
    ----------
    design : Design
    judge : bool
        Judge the designed ends (:func:`fabkit.motion.ends.judge_ends`) of a motion that reached
        its target.
    **overrides
        Passed to :meth:`Design.trace` (``method``, ``to``, method options).

    Returns
    -------
    TracedMotion
        Never raises for a motion that fails: its ``status`` and ``error`` say how.

    Raises
    ------
    TemplateError
        ``[motion] ends`` names a port the network does not have.
    """
    return _traced(design, judge=judge, **overrides)


def _traced(design, *, window=None, judge=True, **overrides) -> TracedMotion:  # noqa: C901

    path = design.path or design.name
    target = overrides.get("to", design.motion.to)
    if target is None:
        return TracedMotion(design, Status.NO_TARGET, "the template gives no target "
                                                            "(motion.to)", window=window)
    builder = _builder_key(design)
    nodes_key = "network.nodes" if builder == "network" else builder
    singular = several = False
    if not design.motion.hold:
        modes = count_modes(design.network)
        if modes.conformational == 0:
            error = MotionError(path, builder,
                                f"the network is rigid: it has no conformational motion "
                                f"(modes: {modes.total} = {modes.rigid} rigid); remove an edge",
                                status=Status.REFUSED.value)
            return TracedMotion(design, Status.REFUSED, error.reason, error=error,
                                window=window)
        singular = modes.self_stress > 0 and modes.conformational > 1
        several = modes.conformational > 1 and not singular
    options = {k: v for k, v in overrides.items() if k not in ("to", "method")}
    try:
        traj = design.trace(**overrides)
    except TypeError as exc:  # an unknown method option
        error = MotionError(path, "motion.options", str(exc), status=Status.REFUSED.value)
        return TracedMotion(design, Status.REFUSED, error.reason, error=error,
                            window=window)
    except FabkitError as exc:
        key = nodes_key if singular else builder if several else "motion"
        cls = SingularStartError if singular else MotionError
        error = cls(path, key, str(exc), status=Status.REFUSED.value)
        status = Status.SINGULAR_START if singular else Status.REFUSED
        return TracedMotion(design, status, error.reason, error=error, window=window)
    if traj.success:
        ends = spread = None
        if judge:
            from .ends import judge_ends

            ends = judge_ends(design, traj)
            spread = module_spread(design, traj)
        if ends is not None and not ends.reached:
            return TracedMotion(design, Status.ENDS_MISSED,
                                f"{traj.message}, but {ends.reason}", traj, ends=ends,
                                window=window, spread=spread, options=options)
        missed = shape_missed(design, spread)
        if missed:
            return TracedMotion(design, Status.ENDS_MISSED, f"{traj.message}, but {missed}",
                                traj, ends=ends, window=window, spread=spread,
                            options=options)
        return TracedMotion(design, Status.FINISHED, traj.message, traj, ends=ends,
                            window=window, spread=spread, options=options)
    at_start = traj.n_steps <= 1
    if singular and at_start:
        error = SingularStartError(path, nodes_key, f"target {design.motion.drive} = "
                                   f"{float(target):.10g} is not reached: {traj.message}",
                                   status=str(traj.status))
        return TracedMotion(design, Status.SINGULAR_START, error.reason, traj,
                            error=error, window=window, options=options)
    key = "motion.to" if traj.status in (Status.TURNING_POINT, Status.BRANCH_POINT) else "motion"
    error = MotionError(path, key, f"target {design.motion.drive} = {float(target):.10g} is not "
                                   f"reached: {traj.message}", status=str(traj.status))
    return TracedMotion(design, Status.NOT_REACHED, error.reason, traj, error=error,
                        window=window, options=options)
