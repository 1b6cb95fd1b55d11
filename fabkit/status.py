"""One vocabulary of results for every stage of fabkit.

Every stage ends in a value that carries a :class:`Status` and a one-sentence ``message``, as
:func:`scipy.integrate.solve_ivp`'s result does: a trace (:class:`fabkit.kinematics.Trajectory`),
the Motion stage (:class:`fabkit.motion.TracedMotion`), each format of an export, each check of a
written file, the design's export as a whole, its verdict, a task of the executor and a point of
a sweep. One enum holds every status a stage can end in, so a status read anywhere means the
same thing everywhere ("refused" is the same refusal in a trace, a format and an export) and is
written to report.json as its string value.

Which statuses a stage can end in is said by the stage's frozen set below (``TRACE``,
``MOTION``, ...); a result checks its status against it when it is made.
"""

from __future__ import annotations

from enum import Enum

__all__ = [
    "Status", "TRACE", "MOTION", "EXPORT", "FORMAT", "CHECK", "VERDICT", "VERDICT_ORDER", "TASK",
    "SWEEP_POINT", "expect",
]


class Status(str, Enum):
    """How a stage ended (the string value is what reports and report.json show)."""

    # -- shared by several stages -------------------------------------------------------------
    OK = "ok"                      #: done, and everything it checks holds
    FAILED = "failed"              #: it could not be done (the message says why)
    REFUSED = "refused"            #: asked for, and cannot be given as asked (the message says why)
    INTERRUPTED = "interrupted"    #: stopped by a signal before it finished; nothing written

    # -- a trace (kinematics) and the Motion stage --------------------------------------------
    FINISHED = "finished"            #: the drive reached its target (and every designed end)
    TURNING_POINT = "turning_point"  #: the drive reaches an extremum before the target
    BRANCH_POINT = "branch_point"    #: a bifurcation of the motion lies ahead; not crossed
    #: the drive reached its target, but ports did not reach their designed end: the trace is
    #: usable, the design did not happen (the message names them and why)
    ENDS_MISSED = "ends missed"
    #: the trace stopped before the target (a turning point, a branch point, a failure)
    NOT_REACHED = "target not reached"
    #: the start is a kinematic bifurcation: only an exporter that chooses the branch (an
    #: origami crease assignment) can leave it
    SINGULAR_START = "singular start"
    NO_TARGET = "no target"          #: the template gives no target: a geometry-only design

    # -- a format of an export, and the export of a design ------------------------------------
    EXPORTED = "exported"                  #: its files are written and pass their checks
    CHECK_FAILED = "check failed"          #: files written, but an as-built check failed
    DOES_NOT_APPLY = "does not apply"      #: the format does not fit the design's process
    NOT_AVAILABLE = "not available"        #: the format needs a package that is not installed
    SKIPPED = "skipped by the template"    #: the template opts out of the format

    # -- the verdict of a design (from best to worst, see :attr:`rank`) -----------------------
    #: flagged by what the design is for (a chaotic chain's far end cannot be predicted): said
    #: in words, not alarmed in red
    BY_DESIGN = "by design"
    FLAG = "FLAG"                  #: it may not work as built (the message says what to look at)
    FAIL = "FAIL"                  #: it will not work as built

    # -- a task of the executor ---------------------------------------------------------------
    DONE = "done"                  #: it returned
    RAISED = "raised"              #: it raised
    DIED = "died"                  #: its worker ended while it ran (killed, a crash)
    TIMED_OUT = "timed_out"        #: it ran past its time limit; its worker was killed
    SILENT = "silent"              #: its worker stopped answering; it was killed
    NOT_STARTED = "not_started"    #: its worker did not start in time; it was killed

    # -- a point of a sweep -------------------------------------------------------------------
    RIGID = "rigid"                #: the geometry has no conformational motion
    FLAT = "flat"                  #: the start is a flat state (a turning point of d1)
    NO_MOTION = "no_motion"        #: the network moves, but not in a way d1 drives
    ESCAPES = "escapes"            #: every orbit of the map leaves its domain

    def __str__(self) -> str:  # "finished", not "Status.FINISHED"
        return self.value

    @property
    def traced(self) -> bool:
        """True when there is a trajectory that reached the drive's target."""
        return self in (Status.FINISHED, Status.ENDS_MISSED)

    @property
    def produced(self) -> bool:
        """True when a format wrote files."""
        return self in (Status.EXPORTED, Status.CHECK_FAILED)

    @property
    def rank(self) -> int:
        """Place of a verdict from best (0, ``OK``) to worst (3, ``FAIL``)."""
        return VERDICT_ORDER.index(self)


#: how a trace of :mod:`fabkit.kinematics` ends
TRACE = frozenset({Status.FINISHED, Status.TURNING_POINT, Status.BRANCH_POINT, Status.FAILED})
#: how the Motion stage ends
MOTION = frozenset({Status.FINISHED, Status.ENDS_MISSED, Status.NOT_REACHED, Status.REFUSED,
                    Status.SINGULAR_START, Status.NO_TARGET})
#: how the export of one design ends
EXPORT = frozenset({Status.OK, Status.FAILED, Status.CHECK_FAILED, Status.REFUSED,
                    Status.INTERRUPTED})
#: what happened to one format of one design
FORMAT = frozenset({Status.EXPORTED, Status.CHECK_FAILED, Status.DOES_NOT_APPLY,
                    Status.NOT_AVAILABLE, Status.SKIPPED, Status.REFUSED})
#: how one check of a written file ends
CHECK = frozenset({Status.OK, Status.FAILED})
#: a design's verdict, from best to worst
VERDICT_ORDER = (Status.OK, Status.BY_DESIGN, Status.FLAG, Status.FAIL)
VERDICT = frozenset(VERDICT_ORDER)
#: how a task of the executor ends
TASK = frozenset({Status.DONE, Status.RAISED, Status.DIED, Status.TIMED_OUT, Status.SILENT,
                  Status.NOT_STARTED})
#: what happened at one point of a sweep
SWEEP_POINT = frozenset({Status.OK, Status.RIGID, Status.FLAT, Status.NO_MOTION, Status.ESCAPES,
                         Status.FAILED})


def expect(status: Status, allowed: frozenset, what: str) -> Status:
    """Return ``status`` if ``allowed`` holds it, else raise ValueError naming ``what``.

    Parameters
    ----------
    status : Status or str
        A status, or its string value (as read back from report.json).
    allowed : frozenset of Status
        The statuses the stage can end in (``TRACE``, ``MOTION``, ...).
    what : str
        The kind of result, for the message ("a trace", "a format").

    Examples
    --------
    >>> expect("finished", TRACE, "a trace")
    <Status.FINISHED: 'finished'>
    >>> expect(Status.EXPORTED, TRACE, "a trace")
    Traceback (most recent call last):
    ...
    ValueError: a trace cannot end 'exported' (it ends one of: branch_point, failed, finished, turning_point)
    """
    status = Status(status)
    if status not in allowed:
        names = ", ".join(sorted(s.value for s in allowed))
        raise ValueError(f"{what} cannot end {status.value!r} (it ends one of: {names})")
    return status
