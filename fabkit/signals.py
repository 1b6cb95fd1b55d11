"""The signals that end a command, and the one way each of them ends it.

Every terminating signal a user or a system sends (:data:`TERMINATING`: SIGTERM, SIGINT, SIGHUP,
SIGQUIT, SIGUSR1, SIGUSR2) raises :class:`~fabkit.errors.Interrupted` in the main thread
(:func:`install`): the command unwinds as it does for an error, so workers are stopped, staging
folders and temporary files removed and the output folder's lock released, and the command line
prints one line and exits with 128 + the signal's number. SIGPIPE is left to Python (ignored,
so that a closed pipe shows as :class:`BrokenPipeError`, which ends the command with 141).

The first signal starts the clean-up; any later one (a second Ctrl-C 0.2 s after the first) is
ignored from then on, to the end of the process, so that it can never cut the clean-up short nor print a
traceback. The clean-up is bounded: workers have :data:`fabkit.executor.GRACE` seconds before
SIGKILL.

A terminal sends SIGINT (Ctrl-C), SIGQUIT (Ctrl-\\) and SIGHUP (a hang-up) to its whole process
group (:data:`GROUP`), workers included: workers ignore them from the moment they exist
(:func:`group_blocked` keeps them blocked while a worker starts, :func:`worker_ignores` ignores
them inside it), and the parent alone decides, stopping them with SIGTERM.
"""

from __future__ import annotations

import contextlib
import signal
import threading

from .errors import Interrupted

__all__ = ["TERMINATING", "GROUP", "install", "restore", "group_blocked", "worker_ignores",
           "default_in_child"]

#: The signals that end a command the same way (those this platform has).
TERMINATING = tuple(getattr(signal, name) for name in
                    ("SIGTERM", "SIGINT", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGUSR2")
                    if hasattr(signal, name))
#: The signals a terminal sends to a whole process group.
GROUP = tuple(getattr(signal, name) for name in ("SIGINT", "SIGQUIT", "SIGHUP")
              if hasattr(signal, name))


#: The signal that is ending the command, once one came (:func:`restore` then leaves the
#: signals ignored: the process is on its way out).
_ending = {"signum": None}


def _raise_interrupted(signum, frame):
    # the clean-up this starts must not be cut short by a second signal (a second Ctrl-C)
    _ending["signum"] = signum
    for sig in TERMINATING:
        try:
            signal.signal(sig, signal.SIG_IGN)
        except (ValueError, OSError):  # pragma: no cover - not settable here
            pass
    raise Interrupted(signum)


def install() -> dict:
    """Make every signal of :data:`TERMINATING` raise :class:`~fabkit.errors.Interrupted` in the
    main thread; returns the previous handlers for :func:`restore` (nothing outside the main
    thread, where handlers cannot be set).

    Returns
    -------
    dict
        Signal number → previous handler.
    """
    if threading.current_thread() is not threading.main_thread():
        return {}
    previous = {}
    _ending["signum"] = None
    for sig in TERMINATING:
        try:
            previous[sig] = signal.signal(sig, _raise_interrupted)
        except (ValueError, OSError):  # not settable here (embedded interpreter)
            pass
    return previous


def restore(previous: dict) -> None:
    """Put back the handlers :func:`install` returned, unless a signal is ending the command:
    then they stay ignored, so that a second Ctrl-C between the end of the clean-up and the
    end of the process (the interpreter's teardown) cannot print a traceback either."""
    if _ending["signum"] is not None:
        return
    for sig, handler in previous.items():
        signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


@contextlib.contextmanager
def group_blocked():
    """Block :data:`GROUP` in this thread while a worker process starts: the worker inherits
    the mask and so cannot die of a Ctrl-C while it imports (a traceback from its bootstrap),
    before :func:`worker_ignores` runs. A signal that arrives meanwhile is delivered here when
    the block ends."""
    if not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - not POSIX
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, set(GROUP))
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def worker_ignores() -> None:
    """In a worker: ignore :data:`GROUP` (the parent decides and stops it with SIGTERM), then
    unblock them (:func:`group_blocked`); one that arrived meanwhile is discarded."""
    for sig in GROUP:
        signal.signal(sig, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, set(GROUP))


def default_in_child() -> None:
    """In a forked child that its parent kills: every signal of :data:`TERMINATING` ends it at
    once (the parent's handlers are not for it)."""
    for sig in TERMINATING:
        signal.signal(sig, signal.SIG_DFL)
