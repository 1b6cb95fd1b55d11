"""Exceptions raised by fabkit.

Every error derives from :class:`FabkitError`; ``str(error)`` is one line a user can act on. The
command line prints that line and exits with the error's :attr:`~FabkitError.exit_code`;
tracebacks appear only with ``--debug``. Each class has a stable :attr:`~FabkitError.code` (a
short identifier that reports and scripts may test) and keeps what failed in fields, so that no
caller ever has to read the message text to decide what to do.
"""

from __future__ import annotations

__all__ = [
    "FabkitError",
    "NetworkError",
    "TemplateError",
    "KinematicsError",
    "ConstructionError",
    "FlatStateError",
    "DesignError",
    "FabricationError",
    "PatternError",
    "ResourceError",
    "UsageError",
    "BoundsError",
    "SettingsError",
    "ArgumentError",
    "ArgumentTypeError",
    "ArgumentValueError",
    "InputFileError",
    "OutputError",
    "WriteError",
    "UnsafeNameError",
    "LockedError",
    "FolderChangedError",
    "MotionError",
    "SingularStartError",
    "UnavailableError",
    "Interrupted",
    "internal_error_line",
    "brief",
]


class FabkitError(Exception):
    """Base class of all errors that fabkit raises on purpose.

    Attributes
    ----------
    code : str
        Stable identifier of the kind of error (``"template"``, ``"usage"``, ...).
    exit_code : int
        Exit status of the command line for this error: 1 (a design or an input failed) unless a
        subclass says otherwise (2 for a usage error).
    """

    code = "error"
    exit_code = 1


class NetworkError(FabkitError, ValueError):
    """A network is malformed: bad coordinates, bad indices, duplicate or degenerate edges.

    Attributes
    ----------
    key : str
        What is at fault, as a key path inside a network description (``"edges[3]"``,
        ``"nodes[0]"``, ``"ports.d1"``), or ``""``.
    """

    code = "network"

    def __init__(self, message: str, key: str = ""):
        self.key = key
        super().__init__(message)


class TemplateError(FabkitError):
    """A template file cannot be read or fails validation.

    Parameters
    ----------
    path : str
        The template file.
    key : str
        Dotted key path inside the file (``"network.edges[3]"``), or ``""`` for the whole file.
    reason : str
        What is wrong and, where possible, how to fix it.
    """

    code = "template"

    def __init__(self, path, key: str, reason: str):
        self.path = str(path)
        self.key = key
        self.reason = reason
        where = f"{self.path}: {key}" if key else self.path
        super().__init__(f"{where}: {reason}")


class KinematicsError(FabkitError):
    """A motion cannot be traced as asked (wrong drive, no motion, unknown option)."""

    code = "kinematics"


class ConstructionError(KinematicsError):
    """The network has no construction order by circle/sphere intersections for the drive."""

    code = "construction"


class FlatStateError(ConstructionError):
    """The reference configuration is a flat state: a node lies on the line (2D) or plane (3D) of
    the nodes it would be placed from, so the side of the intersection, and with it the branch,
    is undetermined there.

    Attributes
    ----------
    node : int
    parents : tuple of int
    """

    code = "flat_state"

    def __init__(self, message: str, node: int = -1, parents: tuple = ()):
        self.node = int(node)
        self.parents = tuple(int(v) for v in parents)
        super().__init__(message)


class DesignError(FabkitError):
    """A module design specification cannot be met."""

    code = "design"


class FabricationError(FabkitError):
    """Fabrication settings or geometry that cannot be made; the message suggests a fix."""

    code = "fabrication"


class PatternError(FabricationError):
    """A crease pattern is malformed; ``part`` names what is wrong (``"vertices"``, ``"edges"``,
    ``"assignment"`` or ``"faces"``), so that a template error can point at the right key."""

    code = "pattern"

    def __init__(self, message: str, part: str):
        self.part = part
        super().__init__(message)


class ResourceError(FabkitError):
    """A computation would need more memory than the machine has (raised before allocating),
    or an exact search ran past its wall-clock safety net before its count of work (its answer
    must not depend on the machine's speed, so none is given)."""

    code = "resource"


class UsageError(FabkitError):
    """A command-line option has a value the command cannot use (exit status 2).

    Parameters
    ----------
    option : str
        The option as typed (``"--jobs"``).
    reason : str
        What is wrong with its value and what to give instead.
    """

    code = "usage"
    exit_code = 2

    def __init__(self, option: str, reason: str):
        self.option = option
        self.reason = reason
        super().__init__(f"{option}: {reason}" if option else reason)


class BoundsError(FabkitError):
    """A size asks for more work or memory than this machine can give in reasonable time.

    Checked before the work starts. Exit status 1 when the size comes from a template, 2 when it
    comes from a command-line option (``option`` is then set).

    Parameters
    ----------
    where : str
        The template path and key, or the option, that sets the size.
    quantity : str
        What is counted (``"modules"``, ``"Monte Carlo samples"``).
    value, limit : float
        The size asked for and the largest one accepted.
    override : str
        How to lift the limit (a flag or an environment variable), or ``""``.
    estimate : fabkit.io.workload.Estimate, optional
        The estimate of time and memory that was refused (``value`` and ``limit`` are then its
        description and the bound, as text).
    """

    code = "bounds"

    def __init__(self, where: str, quantity: str, value, limit, override: str = "",
                 option: bool = False, estimate=None):
        self.where = where
        self.quantity = quantity
        self.value = value
        self.limit = limit
        self.override = override
        self.estimate = estimate
        if option:
            self.exit_code = 2
        hint = f"; {override} lifts the limit" if override else ""
        if isinstance(value, str):
            text = f"{where}: {value} is over the limit of {limit}{hint}"
        else:
            text = f"{where}: {value:,} is over the limit of {limit:,} {quantity}{hint}"
        super().__init__(text)


class SettingsError(FabkitError, ValueError):
    """A setting that the declared schema (:mod:`fabkit.io.schema`) refuses: an unknown section or
    key, a value of the wrong type, a value out of range.

    Parameters
    ----------
    key : str
        The key path (``"fabrication.laser.min_web"``, ``"laser.kerf"``).
    reason : str
        Why, with the value given (``"must be >= 0, got -5"``).
    kind : str
        What is wrong, for code that must tell the cases apart (never the message's text):
        ``"unknown"`` (a key or section the schema does not declare), ``"missing"``, ``"type"``
        (a value of the wrong type: text for a number, 2.5 for a whole number) or ``"value"``
        (the right type, out of range or not allowed).
    """

    code = "settings"

    #: Values of :attr:`kind`.
    KINDS = ("unknown", "missing", "type", "value")

    def __init__(self, key: str, reason: str, kind: str = "value"):
        if kind not in self.KINDS:
            raise ValueError(f"SettingsError kind must be one of {self.KINDS}, got {kind!r}")
        self.key = key
        self.reason = reason
        self.kind = kind
        super().__init__(f"{key}: {reason}" if key else reason)


class ArgumentError(FabkitError):
    """An argument of a public function that fabkit cannot use; the message names it.

    Parameters
    ----------
    argument : str
        The argument's name (``"copies"``, ``"net"``).
    reason : str
        What is wrong, with the value given.
    """

    code = "argument"

    def __init__(self, argument: str, reason: str):
        self.argument = argument
        self.reason = reason
        super().__init__(f"{argument} {reason}")


class ArgumentTypeError(ArgumentError, TypeError):
    """An argument of the wrong type (a ``TypeError`` too)."""


class ArgumentValueError(ArgumentError, ValueError):
    """An argument of the right type with a value fabkit cannot use (a ``ValueError`` too)."""


class InputFileError(FabkitError):
    """An input path is not a readable regular file (a folder, a FIFO, a device, a loop).

    Parameters
    ----------
    path : str
    reason : str
    kind : str
        What is wrong, for code that must tell the cases apart (never the message's text):
        ``"missing"`` (no such file), ``"not_regular"`` (a folder, a FIFO, a device, a socket),
        ``"loop"`` (a symbolic-link loop), ``"unreadable"`` (anything else), ``"damaged"`` (the
        file's parser refused it: not its format, cut short, nested too deeply) or
        ``"bounds"`` (past one of the readers' bounds on depth, digits, counts or expansion,
        checked before the work). The last two exit with status 2, as a usage error: the
        file given cannot be used as it is.
    """

    code = "input_file"

    #: Values of :attr:`kind`.
    KINDS = ("missing", "not_regular", "loop", "unreadable", "damaged", "bounds")

    def __init__(self, path, reason: str, kind: str = "unreadable"):
        if kind not in self.KINDS:
            raise ValueError(f"InputFileError kind must be one of {self.KINDS}, got {kind!r}")
        self.path = str(path)
        self.reason = reason
        self.kind = kind
        if kind in ("damaged", "bounds"):
            self.exit_code = 2
        super().__init__(f"{self.path}: {reason}")


class OutputError(FabkitError):
    """An output folder or file cannot be created or written.

    Parameters
    ----------
    path : str
    reason : str
    """

    code = "output"

    def __init__(self, path, reason: str):
        self.path = str(path)
        self.reason = reason
        super().__init__(f"{self.path}: {reason}")


class WriteError(OutputError):
    """A file could not be written (a full disk, a quota, a file-size limit, permissions); no
    part of it, nor of the set of files it belonged to, was left behind.

    Parameters
    ----------
    path : str
        The file that could not be written.
    reason : str
        The system's reason (``"No space left on device"``).
    """

    code = "write"

    def __init__(self, path, reason: str):
        super().__init__(path, f"cannot write: {reason}; nothing of this output was written")
        self.reason = reason


def brief(value, limit: int = 60) -> str:
    """``repr(value)`` for a message, cut to about ``limit`` characters with the full length
    said: a 100 000-character name must not fill the terminal.

    Examples
    --------
    >>> brief("x" * 100_000)
    "'xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx'... (100000 characters)"
    """
    text = repr(value)
    if len(text) <= limit + 2:
        return text
    if isinstance(value, str):
        return f"{value[:limit]!r}... ({len(value)} characters)"
    return text[:limit] + "..."


class UnsafeNameError(OutputError, ValueError):
    """A name that fabkit would write under an output folder is not safe there: it would leave
    the folder (``..``, a separator, an absolute path), is empty, holds a control character or
    a character outside letters, digits and ``_ . + -``, or is reserved.

    Parameters
    ----------
    what : str
        What the name is (``"name"``, ``"file name"``, ``"template name"``).
    name : object
        The name as given.
    reason : str
        Why it is refused.
    """

    code = "unsafe_name"

    def __init__(self, what: str, name, reason: str):
        self.what = what
        self.name = name
        FabkitError.__init__(self, f"{what} {brief(name)} {reason}")
        self.path = str(name)
        self.reason = reason


class FolderChangedError(OutputError):
    """The output folder was removed, renamed, or replaced by a link or another folder while
    fabkit worked in it; fabkit stopped, wrote nothing more and nothing elsewhere.

    Parameters
    ----------
    path : str
        The output folder.
    """

    code = "output_changed"

    def __init__(self, path):
        super().__init__(path, "the output folder was moved, removed or replaced (by a link or "
                               "another folder) while fabkit worked in it; fabkit stopped and "
                               "wrote nothing more, nothing elsewhere: run the command again")

    def __reduce__(self):  # from a worker process to its parent, as it was
        return (FolderChangedError, (self.path,))


class LockedError(OutputError):
    """Another fabkit process is exporting into the same output folder.

    Parameters
    ----------
    path : str
        The output folder.
    pid : int or None
        The process that holds the lock, when known.
    """

    code = "locked"

    def __init__(self, path, pid=None):
        self.pid = pid
        who = f"process {pid}" if pid else "another process"
        super().__init__(path, f"{who} is exporting into this folder (lock file "
                               f".fabkit.lock); wait for it to finish, or use --wait")


class MotionError(TemplateError):
    """The template's motion does not reach its target (or cannot leave its start).

    Parameters
    ----------
    path, key, reason
        As for :class:`TemplateError`.
    status : str
        How the trace ended (a :class:`fabkit.status.Status` value of :data:`fabkit.status.TRACE`,
        or ``"refused"`` when the tracer raised before it started).
    """

    code = "motion"

    def __init__(self, path, key: str, reason: str, status: str = "failed"):
        self.status = str(status)
        super().__init__(path, key, reason)


class SingularStartError(MotionError):
    """The start configuration is a kinematic bifurcation (states of self-stress and more than one
    first-order motion), so the trace cannot choose a branch by itself; an exporter that chooses
    the branch (an origami crease assignment) may still resolve it."""

    code = "singular_start"


class UnavailableError(FabkitError):
    """An optional part (an exporter, a checker) cannot be imported.

    Parameters
    ----------
    what : str
        ``"export format 'stl'"``, ``"the .stl check"``.
    reason : str
    """

    code = "unavailable"

    def __init__(self, what: str, reason: str):
        self.what = what
        self.reason = reason
        super().__init__(f"{what} is not available: {reason}")


class Interrupted(BaseException):
    """Raised in the main process when SIGINT or SIGTERM arrives; carries the signal number so
    that the command line exits with 128 + signal, like a shell. A BaseException (as
    KeyboardInterrupt) so that no ``except Exception`` swallows it."""

    def __init__(self, signum: int):
        self.signum = int(signum)
        #: What the interrupted command adds to its one line (where to resume), or "".
        self.hint = ""
        super().__init__(f"interrupted by signal {self.signum}")


def internal_error_line(exc: BaseException) -> str:
    """One line for an unexpected exception: its type, where it was raised, how to report it."""
    import traceback
    from pathlib import Path

    if isinstance(getattr(exc, "internal_line", None), str):  # made where it happened (a child)
        return exc.internal_line
    frames = traceback.extract_tb(exc.__traceback__)
    where = f" at {Path(frames[-1].filename).name}:{frames[-1].lineno}" if frames else ""
    text = " ".join(str(exc).split())[:200]
    return (f"internal error{where}: {type(exc).__name__}: {text} -- this is a bug in fabkit; "
            "please report it with the output of the same command run with --debug")
