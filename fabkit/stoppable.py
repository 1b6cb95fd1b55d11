"""Steps that a signal stops at once, even inside a C extension, and that keep to their estimate.

Python runs a signal handler only between two bytecodes of its main thread, so SIGINT or
SIGTERM waits while a C extension computes: GEOS polygonising the cross-section of a hostile
mesh, trimesh splitting a million triangles into bodies, for minutes. The work estimate
(:mod:`fabkit.io.workload`) bounds a file by its counts, but the cost of degenerate geometry
(thousands of coincident copies of one body) is not in any count.

:func:`run_stoppable` therefore runs such a step in a forked child process. The parent only
waits, so a signal reaches it at once: it kills the child and raises
:class:`~fabkit.errors.Interrupted`. (A fork, not a worker of :mod:`fabkit.executor`: the step's
function and arguments, closures and meshes among them, need not pickle, and the child starts in
milliseconds with everything already imported; it dies with its parent as the workers do.)
Inside the child, :func:`keep_to` turns each estimate into limits the kernel enforces: CPU
seconds (``RLIMIT_CPU``) and address space (``RLIMIT_AS``), a few times the estimate. A step
that runs past them is stopped and reported in one line, never left running. Called outside
such a child (the Python API), :func:`keep_to` does nothing.

Examples
--------
>>> run_stoppable(sum, [1, 2, 3], what="a sum")
6
"""

from __future__ import annotations

import os
import resource
import signal
import sys

from .errors import FabkitError
from .executor import default_in_child, die_with_parent
from .io.workload import describe_bytes, estimate as combine

__all__ = ["run_stoppable", "keep_to", "TIME_FACTOR", "MIN_SECONDS", "MEMORY_FACTOR",
           "MIN_BYTES", "StepLimitError"]

#: A step may use this many times the CPU seconds of its estimate, and at least MIN_SECONDS.
TIME_FACTOR = 4.0
MIN_SECONDS = 60.0
#: A step may add this many times the bytes of its estimate to the address space it started
#: with, and at least MIN_BYTES (libraries map more than they touch).
MEMORY_FACTOR = 4.0
MIN_BYTES = 2 * 2**30

#: The pipe to the parent, in the child process only: :func:`keep_to` applies limits there.
_to_parent = None
#: In the child: CPU seconds and address space when the first estimate came, and every
#: estimate's parts since.
_held = {"cpu": 0.0, "space": 0, "parts": []}


class StepLimitError(FabkitError):
    """A step ran past the CPU time or the memory its work estimate allowed, and was stopped.

    Attributes
    ----------
    what : str
        The step (``"check of big.3mf"``).
    """

    code = "bounds"

    def __init__(self, what: str, reason: str):
        self.what = what
        self.reason = reason
        super().__init__(f"{what}: {reason}")


class _ChildInternalError(Exception):
    """An unexpected exception in the child, carried as the one line the child made of it."""

    def __init__(self, line: str):
        self.internal_line = line
        super().__init__(line)


def keep_to(estimate) -> None:
    """Hold the step running in this child process to its estimates, this one included.

    The estimates a step makes add up (a file's bytes, then the triangles its items place);
    from the first one on, the step may use :data:`TIME_FACTOR` times their seconds of CPU
    time (at least :data:`MIN_SECONDS`) and :data:`MEMORY_FACTOR` times their bytes of
    address space more than it held (at least :data:`MIN_BYTES`). Outside a child of
    :func:`run_stoppable`, or with the bounds lifted, nothing is limited.

    Parameters
    ----------
    estimate : fabkit.io.workload.Estimate
        The work about to be done.
    """
    if _to_parent is None or os.environ.get("FABKIT_ALLOW_LARGE", "") == "1":
        return

    if not _held["parts"]:
        used = resource.getrusage(resource.RUSAGE_SELF)
        _held.update(cpu=used.ru_utime + used.ru_stime, space=_address_space())
    _held["parts"] += list(estimate.parts)
    total = combine(*_held["parts"])
    allowed = max(MIN_SECONDS, TIME_FACTOR * total.seconds)
    _set_soft(resource.RLIMIT_CPU, int(_held["cpu"] + allowed) + 1)
    _set_soft(resource.RLIMIT_AS, int(_held["space"] + max(MIN_BYTES,
                                                           MEMORY_FACTOR * total.bytes)))
    # the parent words the message if the kernel stops this process at the limit
    _to_parent.send(("limits", (total.describe(), allowed)))


def _set_soft(which: int, value: int) -> None:
    _, hard = resource.getrlimit(which)
    if hard != resource.RLIM_INFINITY:
        value = min(value, hard)
    try:
        resource.setrlimit(which, (value, hard))
    except (ValueError, OSError):  # pragma: no cover - a limit this system will not take
        pass


def _address_space() -> int:
    """Bytes of address space this process holds now."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):  # not Linux: the resident size, in kB or bytes
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return rss if sys.platform == "darwin" else rss * 1024


def run_stoppable(func, *args, what: str, **kwargs):
    """``func(*args, **kwargs)`` in a forked child process that a signal stops at once.

    The parent waits without computing: SIGINT or SIGTERM ends the child at once and raises
    :class:`~fabkit.errors.Interrupted` here. Inside the child, :func:`keep_to` limits CPU time
    and memory to a few times each estimate the step makes.

    Parameters
    ----------
    func : callable
        The step; its result must pickle.
    what : str
        What the step is, for messages (``"check of x.stl"``).

    Returns
    -------
    Whatever ``func`` returns.

    Raises
    ------
    FabkitError
        What ``func`` raised (as a FabkitError with the same message, code and exit code).
    StepLimitError
        The step ran past its CPU time or memory, or its process died.
    Exception
        An unexpected exception of ``func``: one line saying where (as the command line shows
        internal errors).
    """
    if not hasattr(os, "fork"):
        return func(*args, **kwargs)  # pragma: no cover - no fork here: in this process
    from multiprocessing.connection import Connection, wait

    parent = os.getpid()
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: never returns into the caller's code
        try:
            os.close(read_end)
            _child_main(Connection(write_end, readable=False), parent, func, args, kwargs)
        finally:
            os._exit(0)
    os.close(write_end)
    receive = Connection(read_end, writable=False)
    ended = _pidfd(pid)
    limits, message, status = None, None, None
    try:
        while message is None and status is None:
            ready = wait([receive] + ([ended] if ended is not None else []),
                         timeout=None if ended is not None else 0.2)
            if receive in ready:
                try:
                    message = receive.recv()
                except EOFError:  # it ended without a word
                    status = os.waitpid(pid, 0)[1]
                    break
                if message[0] == "limits":
                    limits, message = message[1], None
            elif ended is not None and ended in ready:
                if receive.poll():
                    continue  # what it sent before it ended counts
                status = os.waitpid(pid, 0)[1]
            elif ended is None:
                done, code = os.waitpid(pid, os.WNOHANG)
                if done:
                    status = code
                    if receive.poll():  # what it sent before it ended counts
                        message = receive.recv()
                        while message[0] == "limits" and receive.poll():
                            limits, message = message[1], receive.recv()
                        if message[0] == "limits":
                            limits, message = message[1], None
        if status is None:
            status = os.waitpid(pid, 0)[1]
    except BaseException:
        # a signal (or any error here): the child ends at once; the kernel frees its memory
        # while this process goes on, and a thread reaps it
        os.kill(pid, signal.SIGKILL)
        import threading

        threading.Thread(target=_reap, args=(pid,), daemon=True).start()
        raise
    finally:
        receive.close()
        if ended is not None:
            os.close(ended)
    exitcode = -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)
    if message is None:
        raise _died(what, exitcode, limits)
    kind, payload = message
    if kind == "ok":
        return payload
    if kind == "error":
        text, code, exit_code = payload
        exc = FabkitError(text)
        exc.code, exc.exit_code = code, exit_code
        raise exc
    if kind == "memory":
        raise StepLimitError(what, f"needed more memory than its size allows ({payload}); "
                                   "fabkit --allow-large lifts the limit")
    raise _ChildInternalError(payload)


def _pidfd(pid: int):
    """A descriptor that becomes readable when process ``pid`` ends (Linux), else None."""
    try:
        return os.pidfd_open(pid)
    except (AttributeError, OSError):
        return None


def _reap(pid: int) -> None:
    try:
        os.waitpid(pid, 0)
    except ChildProcessError:
        pass


def _died(what: str, exitcode, limits) -> StepLimitError:
    """The error for a child that ended without a result (``limits``: the last estimate it
    kept to, as (description, CPU seconds allowed))."""
    if exitcode == -signal.SIGXCPU and limits:
        from .io.workload import describe_seconds

        estimate, allowed = limits
        return StepLimitError(what, f"ran past the {describe_seconds(allowed)} of CPU time "
                                    f"allowed for work estimated at {estimate}, and was "
                                    "stopped: it costs far more than its counts say (such as "
                                    "thousands of coincident copies of one body); fabkit "
                                    "--allow-large lifts the limit")
    how = (f"signal {signal.Signals(-exitcode).name}" if exitcode and exitcode < 0
           else f"exit code {exitcode}")
    return StepLimitError(what, f"its process died ({how}) before it finished")


def _child_main(conn, parent_pid, func, args, kwargs) -> None:
    """The child: die with the parent, compute, send the result or the error, exit."""
    global _to_parent
    _to_parent = conn
    default_in_child()  # the parent decides; the child just ends
    die_with_parent(parent_pid)
    try:
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # a stopped step leaves no core file
    except (ValueError, OSError):  # pragma: no cover
        pass
    try:
        result = ("ok", func(*args, **kwargs))
    except FabkitError as exc:
        result = ("error", (str(exc), exc.code, exc.exit_code))
    except MemoryError:
        result = ("memory", f"over {_describe_limit()} of address space")
    except Exception as exc:  # noqa: BLE001 - reported as the internal error it is
        from .errors import internal_error_line

        result = ("internal", internal_error_line(exc))
    try:
        conn.send(result)
    except Exception as exc:  # noqa: BLE001 - a result that does not pickle is a bug
        from .errors import internal_error_line

        conn.send(("internal", internal_error_line(exc)))
    conn.close()


def _describe_limit() -> str:
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    return describe_bytes(soft) if soft != resource.RLIM_INFINITY else "the machine's memory"
