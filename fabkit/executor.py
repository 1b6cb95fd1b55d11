"""Local parallel work: picklable tasks in spawned worker processes that a signal or a time
limit stops, and that never outlive this process.

:class:`LocalExecutor` is the one way fabkit runs work on local processes (``fabkit export
--jobs``, ``fabkit sweep --jobs``; a dask cluster is the way to other machines). It hands the
tasks out in the order given, one at a time to each idle worker, and yields each task's
:class:`TaskEnd` as it arrives, so that the caller can show progress and write results at once.
What it guarantees:

- a task that raises is reported as raised (its exception), and the other tasks go on;
- a task that runs past its time limit (counted from the moment its worker took it) has its
  worker killed, is reported as timed out, and a new worker takes the dead one's place while
  tasks remain; so does a worker that stops answering (every worker says it is alive several
  times within the silence limit, from a thread of its own) or dies (killed by the system, a
  crash);
- a terminating signal (:data:`TERMINATING`, as :class:`~fabkit.errors.Interrupted` or
  KeyboardInterrupt in this process), or any exception while the tasks run, stops every worker within a second (SIGTERM,
  which unwinds the task in hand, then SIGKILL) before it propagates; and a worker ends with
  this process however that ends, SIGKILL included (Linux: ``PR_SET_PDEATHSIG``; elsewhere a
  thread that watches the parent).

Workers are fresh interpreters (the ``spawn`` start method: no state inherited from a parent
that may hold locks or threads), started with ``PYTHONHASHSEED=0`` so that their results do
not depend on the run. Each caps the threads of its BLAS and OpenMP libraries to its share of
the cores (``cpu_count // jobs``, at least one), so that the workers together use the machine's
cores once, except a library whose threads the user set in the environment
(:data:`THREAD_VARIABLES`, :func:`blas_limits`): that one keeps the user's count. A script that
runs tasks needs the ``if __name__ == "__main__":`` guard, since each worker imports it.

Examples
--------
>>> import math
>>> tasks = [Task(math.factorial, (n,)) for n in (3, 4, 5)]
>>> with LocalExecutor(jobs=1, in_process=True) as pool:
...     sorted((end.index, end.value) for end in pool.run(tasks))
[(0, 6), (1, 24), (2, 120)]
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Iterator

from .errors import FabkitError, Interrupted, internal_error_line
from .status import Status, TASK, expect

__all__ = ["Task", "TaskEnd", "TaskError", "LocalExecutor", "report", "overdue",
           "TERMINATING", "GROUP", "install_signals", "restore_signals", "group_blocked",
           "worker_ignores", "default_in_child",
           "heartbeat_interval", "die_with_parent", "blas_limits", "user_thread_variables",
           "HEARTBEAT", "SILENCE", "STARTUP", "GRACE", "THREAD_VARIABLES"]

#: Longest interval between two "alive" messages of a worker process; shorter silence limits
#: get a faster heartbeat (:func:`heartbeat_interval`).
HEARTBEAT = 1.0
#: A worker silent for this long has stopped answering (it is stopped, or stuck somewhere not
#: even its heartbeat thread runs): longer than the longest call that holds the interpreter
#: lock (the layer solver's time limit is 20 s).
SILENCE = 120.0
#: A new worker must say its first word within this many seconds (or the silence limit, when
#: that is longer). Until then it is starting, not silent: a fresh interpreter importing numpy,
#: scipy and fabkit takes about a second on a quiet 2-core machine and several beside four busy
#: processes, more than a short silence limit.
STARTUP = 120.0
#: Seconds the workers have to unwind after SIGTERM when the run is stopped, before SIGKILL (a
#: worker inside a C call never does).
GRACE = 0.5
#: Longest wait of the parent between two looks at its workers (seconds): the time limits are
#: judged at least this often.
POLL = 1.0
#: The environment variables through which a user sets the threads of each library a worker
#: would cap, by threadpoolctl's name of the library (``internal_api``); each library reads them
#: once, as it loads. OpenBLAS reads OPENBLAS_NUM_THREADS, then GOTO_NUM_THREADS, then
#: OMP_NUM_THREADS (numpy's and scipy's wheels bundle OpenBLAS); MKL reads MKL_NUM_THREADS (and
#: MKL_DOMAIN_NUM_THREADS) before OMP_NUM_THREADS; BLIS reads BLIS_NUM_THREADS before
#: OMP_NUM_THREADS; an OpenMP runtime reads OMP_NUM_THREADS. A library not listed here
#: (FlexiBLAS hands the count to the backend it loads) counts as set by any of them. Accelerate
#: (VECLIB_MAXIMUM_THREADS) and numexpr (NUMEXPR_NUM_THREADS) are not among them: threadpoolctl
#: does not limit them, so a worker never changes what their variables say.
THREAD_VARIABLES = {
    "openblas": ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS"),
    "mkl": ("MKL_NUM_THREADS", "MKL_DOMAIN_NUM_THREADS", "OMP_NUM_THREADS"),
    "blis": ("BLIS_NUM_THREADS", "OMP_NUM_THREADS"),
    "openmp": ("OMP_NUM_THREADS",),
}


# --- the signals that end a command ---------------------------------------------------------
#
# Every terminating signal (TERMINATING: TERM, INT, HUP, QUIT, USR1, USR2) raises Interrupted in
# the main thread (install_signals): the command unwinds as for an error (workers stopped,
# staging folders and temporary files removed, the lock released), prints one line and exits
# with 128 + the signal. SIGPIPE stays with Python: a closed pipe is a BrokenPipeError (141).
# The first signal starts the clean-up; any later one (a second Ctrl-C) is ignored to the end of
# the process, so it can neither cut the clean-up short nor print a traceback; the clean-up is
# bounded (GRACE seconds, then SIGKILL). A terminal sends INT, QUIT and HUP to its whole
# process group (GROUP): workers have them blocked while they start (group_blocked) and ignore
# them from then on (worker_ignores); the parent alone decides, and stops them with SIGTERM.

#: The signals that end a command the same way (those this platform has).
TERMINATING = tuple(getattr(signal, name) for name in
                    ("SIGTERM", "SIGINT", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGUSR2")
                    if hasattr(signal, name))
#: The signals a terminal sends to a whole process group.
GROUP = tuple(getattr(signal, name) for name in ("SIGINT", "SIGQUIT", "SIGHUP")
              if hasattr(signal, name))


#: The signal that is ending the command, once one came (:func:`restore_signals` then leaves the
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


def install_signals() -> dict:
    """Make every signal of :data:`TERMINATING` raise :class:`~fabkit.errors.Interrupted` in the
    main thread; returns the previous handlers for :func:`restore_signals` (nothing outside the main
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


def restore_signals(previous: dict) -> None:
    """Put back the handlers :func:`install_signals` returned, unless a signal is ending the command:
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


@dataclass(frozen=True)
class Task:
    """``func(*args, **kwargs)``, to run in a worker; every part must pickle (``func`` by its
    module-level name).

    Attributes
    ----------
    timeout : float or None
        Seconds the task may run, from the moment a worker takes it (None: no limit).
    """

    func: Callable
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)
    timeout: float | None = None


@dataclass
class TaskEnd:
    """The end of one task, as :meth:`LocalExecutor.run` reports it.

    Attributes
    ----------
    index : int
        The task's position in the list given to :meth:`LocalExecutor.run`.
    status : Status
        How it ended, one of :data:`fabkit.status.TASK`: ``DONE`` (it returned), ``RAISED``,
        ``DIED`` (its worker ended while it ran), ``TIMED_OUT`` (past its time limit),
        ``SILENT`` (its worker stopped answering), ``NOT_STARTED`` (its worker did not start in
        time); the executor killed the worker of the last three.
    value : object
        What the task returned (``DONE``) or the exception it raised (``RAISED``); else None.
    exitcode : int or None
        How the worker ended when the task ended with it (negative: the signal), else None.
    limit : float or None
        The limit that stopped it, in seconds (``TIMED_OUT``, ``SILENT``, ``NOT_STARTED``).
    pid : int or None
        The worker process that ran the task (None: run in this process).
    """

    index: int
    status: Status
    value: Any = None
    exitcode: int | None = None
    limit: float | None = None
    pid: int | None = None

    def __post_init__(self):
        self.status = expect(self.status, TASK, "a task")

    @property
    def stopped(self) -> bool:
        """True when the executor killed the worker for a limit."""
        return self.status in (Status.TIMED_OUT, Status.SILENT, Status.NOT_STARTED)

    @property
    def message(self) -> str:
        """How the task ended, in one sentence."""
        limit = "" if self.limit is None else f" of {self.limit:g} s"
        return {
            Status.DONE: "it returned",
            Status.RAISED: f"it raised {type(self.value).__name__}: {self.value}",
            Status.DIED: f"its worker ended while it ran (exit status {self.exitcode})",
            Status.TIMED_OUT: f"it ran past its time limit{limit}; its worker was killed",
            Status.SILENT: f"its worker stopped answering (limit{limit}); it was killed",
            Status.NOT_STARTED: f"its worker did not start in time (limit{limit}); it was killed",
        }[self.status]


class TaskError(FabkitError):
    """A task's exception that cannot travel back from its worker, carried as its one line."""

    code = "internal"

    def __init__(self, line: str):
        self.internal_line = line
        super().__init__(line)

    def __reduce__(self):
        return (type(self), (self.internal_line,))


def heartbeat_interval(silence: float | None) -> float:
    """Seconds between two "alive" messages of a worker under the silence limit ``silence``:
    :data:`HEARTBEAT`, or a sixth of the limit when that is shorter, so that a worker counts
    as silent only after several beats in a row went missing (one beat late on a busy machine
    is not a stopped worker).

    Examples
    --------
    >>> heartbeat_interval(120.0), heartbeat_interval(3.0), heartbeat_interval(None)
    (1.0, 0.5, 1.0)
    """
    return HEARTBEAT if silence is None else min(HEARTBEAT, silence / 6.0)


def overdue(now: float, *, born: float, heard: float | None, since: float | None,
            silence: float | None, timeout: float | None,
            startup: float) -> tuple[Status, float] | None:
    """Whether a worker holding a task is to be stopped at time ``now``, and why.

    A worker that has not said a word yet (``heard`` None) is starting, allowed ``startup``
    seconds from its start ``born``; one that has spoken may stay silent ``silence`` seconds
    (None: for ever); its task may run ``timeout`` seconds (None: no limit) from the moment
    ``since`` the worker took it. Times are those of :func:`time.monotonic` (any clock, for the
    tests).

    Returns
    -------
    (Status, float) or None
        The ending (``NOT_STARTED``, ``SILENT`` or ``TIMED_OUT``) and the limit passed, or None
        while the worker is within its limits.
    """
    if heard is None:
        return (Status.NOT_STARTED, startup) if now - born > startup else None
    if silence is not None and now - heard > silence:
        return Status.SILENT, silence
    if timeout is not None and since is not None and now - since > timeout:
        return Status.TIMED_OUT, timeout
    return None


# --- in the worker ----------------------------------------------------------------------------

#: In a worker: sends one message to the parent, tagged with the task in hand (else None).
_to_parent: Callable | None = None


def report(*payload) -> None:
    """Send ``payload`` (picklable) from the task running in a worker to the ``on_event`` of
    its :class:`LocalExecutor`, at once; in any other process, or in a task run in process,
    hand it to ``on_event`` directly (or do nothing without one)."""
    if _to_parent is not None:
        _to_parent(payload)


def die_with_parent(parent_pid: int) -> None:
    """Make this process end when its parent ``parent_pid`` does, however the parent ends (even
    SIGKILL).

    Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)``. Everywhere: a daemon thread that polls the
    parent's pid and exits at once when it changes (the process was re-parented)."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):  # pragma: no cover - a libc without prctl
            pass
    if os.getppid() != parent_pid:  # the parent died before the prctl took effect
        os._exit(1)

    def watch():
        while True:
            time.sleep(0.5)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, daemon=True, name="fabkit-parent-watch").start()


def user_thread_variables(internal_api: str, environ=None) -> list[str]:
    """The thread variables of one library that the user set (not empty) in ``environ``.

    Parameters
    ----------
    internal_api : str
        The library as threadpoolctl names it (``"openblas"``, ``"mkl"``, ``"blis"``,
        ``"openmp"``, ...); one not in :data:`THREAD_VARIABLES` counts as set by any of
        their variables.
    environ : mapping, optional
        The environment (default: this process's).

    Returns
    -------
    list of str
        The names set, in the order of :data:`THREAD_VARIABLES` (empty: the user left the
        library's threads alone).

    Examples
    --------
    >>> user_thread_variables("openblas", {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "2"})
    ['OMP_NUM_THREADS']
    >>> user_thread_variables("mkl", {"OPENBLAS_NUM_THREADS": "1"})
    []
    """
    environ = os.environ if environ is None else environ
    names = THREAD_VARIABLES.get(internal_api)
    if names is None:
        names = tuple(dict.fromkeys(v for group in THREAD_VARIABLES.values() for v in group))
    return [v for v in names if environ.get(v, "").strip()]


def blas_limits(threads: int, info: list[dict], environ=None) -> dict[str, int]:
    """The thread limits a worker sets: ``threads`` for every library in ``info`` whose threads
    the user did not set in the environment (:func:`user_thread_variables`).

    A library whose variable is set has read it when it loaded and runs with the user's count;
    the worker leaves it so. The others get ``threads``, the worker's share of the cores.

    Parameters
    ----------
    threads : int
        The worker's share of the cores.
    info : list of dict
        ``threadpoolctl.threadpool_info()`` (each with ``filepath`` and ``internal_api``).
    environ : mapping, optional
        The environment (default: this process's).

    Returns
    -------
    dict
        ``{filepath: threads}``, for ``threadpoolctl.threadpool_limits``; empty when the user
        set every library's threads.

    Examples
    --------
    >>> libs = [{"filepath": "/a/libopenblas.so", "internal_api": "openblas"},
    ...         {"filepath": "/b/libgomp.so", "internal_api": "openmp"}]
    >>> blas_limits(2, libs, {"OPENBLAS_NUM_THREADS": "1"})
    {'/b/libgomp.so': 2}
    >>> blas_limits(2, libs, {"OMP_NUM_THREADS": "1"})
    {}
    """
    return {lib["filepath"]: int(threads) for lib in info
            if not user_thread_variables(lib.get("internal_api", ""), environ)}


def _travelling(exc: BaseException) -> BaseException:
    """``exc`` if it survives the trip to the parent (pickled and rebuilt), else its one line."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001 - any exception class may refuse to be rebuilt
        return TaskError(internal_error_line(exc))


def _worker_main(parent_pid: int, conn, blas_threads: int | None, beat: float) -> None:
    """A worker process: run the tasks it is sent on ``conn`` until it gets None, then end
    (:func:`_end_worker`).

    Everything goes back on the same pipe with blocking sends (no feeder thread), so what the
    parent reads was sent, and a task it has sent and not heard back about is known to be in
    the hands of this worker whatever the moment it dies. The heartbeat says "alive" as soon as
    the worker runs and then every ``beat`` seconds; a task is acknowledged with "taken" as it
    arrives, which starts its time limit.
    """
    global _to_parent

    die_with_parent(parent_pid)
    if blas_threads is not None:
        import threadpoolctl

        # parallelism is across tasks: oversubscribed BLAS threads slow dense work down several
        # times (a dense SVD of 882 coordinates: 0.15 s on one thread, seconds when they contend);
        # but a library whose threads the user set (OPENBLAS_NUM_THREADS=1, ...) keeps them
        limits = blas_limits(blas_threads, threadpoolctl.threadpool_info())
        if limits:
            threadpoolctl.threadpool_limits(limits)  # for the life of the worker
    # Ctrl-C, Ctrl-\ and a hang-up reach the whole process group: the parent alone decides,
    # and stops the workers with SIGTERM, which unwinds the task in hand (its finally blocks run)
    worker_ignores()

    def on_term(signum, frame):
        raise Interrupted(signum)

    signal.signal(signal.SIGTERM, on_term)
    lock = threading.Lock()

    def send(message):
        with lock:  # the heartbeat thread writes to the same pipe
            conn.send(message)

    def heartbeat():
        while True:
            try:
                send(("alive",))
            except (OSError, ValueError):  # the parent is gone or the pipe is closed
                return
            time.sleep(beat)

    threading.Thread(target=heartbeat, daemon=True, name="fabkit-heartbeat").start()
    try:
        while True:
            try:
                task = conn.recv()
            except EOFError:  # the parent closed its end
                _end_worker()
            if task is None:
                _end_worker()
            index, func, args, kwargs = task
            send(("taken", index))
            _to_parent = lambda payload, index=index: send(("event", index, payload))  # noqa: E731
            try:
                message = ("done", index, func(*args, **kwargs))
            except Exception as exc:  # noqa: BLE001 - reported as this task's ending
                message = ("raised", index, _travelling(exc))
            finally:
                _to_parent = None
            try:
                send(message)
            except Exception as exc:  # noqa: BLE001 - a result that does not pickle
                send(("raised", index, TaskError(internal_error_line(exc))))
    except Interrupted as exc:
        # the task in hand has been unwound; end by the signal itself, so that the parent
        # (when it did not send it) reports how this worker ended
        signal.signal(exc.signum, signal.SIG_DFL)
        os.kill(os.getpid(), exc.signum)


def _end_worker() -> None:
    """End a worker whose tasks are done, without the interpreter's teardown.

    Every result has gone back on the pipe and every file a task wrote is closed (the tasks
    write atomically and close what they open); the teardown would only free the heap of a
    whole export, module by module: 0.3-0.6 s of CPU after ``printed_planar_chain10``, a twentieth
    of its export, with the parent waiting on it. Buffered output is flushed first."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(0)


# --- in the parent ----------------------------------------------------------------------------

class _Worker:
    """One worker process, the parent's end of its pipe, and the task it was handed."""

    def __init__(self, proc, conn):
        self.proc = proc
        self.conn = conn
        self.task: int | None = None  # index of the task sent and not reported back
        self.born = time.monotonic()  # when it was started
        self.heard: float | None = None  # when it last said anything (None: not a word yet)
        self.since: float | None = None  # when it took the task in hand (its "taken")
        self.stopped: tuple[Status, float] | None = None  # why the parent killed it


class LocalExecutor:
    """Run :class:`Task` lists in ``jobs`` spawned worker processes (see the module's text).

    Use it as a context manager: leaving the block by an exception stops the workers at once
    (:data:`GRACE`), leaving it otherwise ends them in order.

    Parameters
    ----------
    jobs : int
        Worker processes at most (never more than tasks remain).
    silence : float or None
        Seconds a worker may say nothing before it counts as stopped (None: no limit; the
        tasks' time limits still hold).
    startup : float
        Seconds a new worker has to say its first word (at least ``silence``).
    on_event : callable, optional
        ``on_event(index, payload)`` in this process for every :func:`report` of task
        ``index``, as it arrives.
    blas_threads : int or None, optional
        BLAS and OpenMP threads of each worker (default: the machine's cores shared among the
        workers, ``cpu_count // jobs`` and at least one). A library whose threads the user set
        in the environment (:data:`THREAD_VARIABLES`) keeps the user's count either way.
    name : str
        Prefix of the workers' process names.
    in_process : bool
        Run the tasks one after the other in this process instead (no time limits: a task
        cannot be stopped here); ``jobs`` is then ignored.
    """

    def __init__(self, jobs: int, *, silence: float | None = SILENCE, startup: float = STARTUP,
                 on_event: Callable | None = None, blas_threads: int | None = None,
                 name: str = "fabkit-worker", in_process: bool = False):
        if isinstance(jobs, bool) or int(jobs) < 1:
            raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
        self.jobs = int(jobs)
        self.silence = silence
        self.startup = max(startup, silence or 0.0)
        self.on_event = on_event
        self.blas_threads = blas_threads
        self.name = name
        self.in_process = in_process
        self.workers: list[_Worker] = []
        self._ctx = None
        self._started = 0

    def __enter__(self) -> "LocalExecutor":
        return self

    def __exit__(self, kind, exc, tb) -> None:
        if kind is not None:
            self.stop()
        self.close()

    @property
    def pids(self) -> list[int]:
        """The worker processes running now."""
        return [w.proc.pid for w in self.workers]

    # --- the run ---------------------------------------------------------------------------

    def run(self, tasks: Iterable[Task]) -> Iterator[TaskEnd]:
        """Run ``tasks`` (handed out in this order) and yield each one's end as it arrives.

        Every task gets exactly one :class:`TaskEnd`. Stopping the iteration early, or any
        exception while it runs, stops the workers.
        """
        tasks = list(tasks)
        if not tasks:
            return
        if self.in_process:
            yield from self._run_here(tasks)
            return
        from multiprocessing.connection import wait

        queue = list(range(len(tasks)))
        pending = set(queue)
        wanted = max(1, min(self.jobs, len(tasks)))
        try:
            while len(self.workers) < wanted:
                self._spawn()
            while pending:
                for w in self.workers:
                    # only a worker seen alive gets a task (one that ended after finishing its
                    # last task is buried below without one)
                    if w.task is None and queue and w.proc.is_alive():
                        self._dispatch(w, queue.pop(0), tasks)
                ready = set(wait([w.conn for w in self.workers] +
                                 [w.proc.sentinel for w in self.workers], timeout=POLL))
                ends: list[TaskEnd] = []
                for w in list(self.workers):
                    # every worker's pipe is read, ready or not: what arrived since the wait
                    # counts, and a worker is judged silent only after its pipe was read
                    open_ = self._receive(w, ends)
                    if w.task is not None and w.proc.is_alive() and not w.stopped:
                        w.stopped = overdue(time.monotonic(), born=w.born, heard=w.heard,
                                            since=w.since, silence=self.silence,
                                            timeout=tasks[w.task].timeout,
                                            startup=self.startup)
                        if w.stopped:
                            w.proc.kill()
                            w.proc.join()
                    if w.proc.sentinel in ready or not open_ or not w.proc.is_alive():
                        self._receive(w, ends)  # what it sent before it ended counts
                        if not open_ and w.proc.is_alive():
                            w.proc.kill()  # a broken pipe: this worker can no longer report
                        end = self._bury(w)
                        if end is not None:
                            ends.append(end)
                        pending.difference_update(e.index for e in ends)
                        if queue and len(self.workers) < min(self.jobs, len(pending)):
                            self._spawn()  # in the dead one's place
                pending.difference_update(e.index for e in ends)
                for end in ends:
                    yield end
        except BaseException:  # an interrupt, an error of the caller, or the run left early
            self.stop()
            raise

    def _run_here(self, tasks: list) -> Iterator[TaskEnd]:
        global _to_parent

        for i, t in enumerate(tasks):
            if self.on_event is not None:
                _to_parent = lambda payload, i=i: self.on_event(i, payload)  # noqa: E731
            try:
                end = TaskEnd(i, Status.DONE, t.func(*t.args, **t.kwargs))
            except Exception as exc:  # noqa: BLE001 - reported as this task's ending
                end = TaskEnd(i, Status.RAISED, exc)
            finally:
                _to_parent = None
            yield end

    def _spawn(self) -> _Worker:
        """Start one more worker."""
        import multiprocessing

        if self._ctx is None:
            self._ctx = multiprocessing.get_context("spawn")  # fresh interpreters
        blas = self.blas_threads
        if blas is None:
            blas = max(1, (os.cpu_count() or 1) // self.jobs)
        saved = os.environ.get("PYTHONHASHSEED")
        os.environ["PYTHONHASHSEED"] = "0"  # read by each worker when it starts
        mine, theirs = self._ctx.Pipe(duplex=True)
        try:
            proc = self._ctx.Process(target=_worker_main, daemon=True,
                                     args=(os.getpid(), theirs, blas,
                                           heartbeat_interval(self.silence)),
                                     name=f"{self.name}-{self._started}")
            with group_blocked():  # no Ctrl-C traceback from a worker that is still starting
                proc.start()
                # known before a signal held back meanwhile is delivered (as the block ends):
                # the interrupt it raises must find this worker among those it stops
                worker = _Worker(proc, mine)
                self.workers.append(worker)
                self._started += 1
        finally:
            theirs.close()  # the worker's end lives in the worker: its death closes the pipe
            if saved is None:
                os.environ.pop("PYTHONHASHSEED", None)
            else:
                os.environ["PYTHONHASHSEED"] = saved
        return worker

    @staticmethod
    def _dispatch(w: _Worker, i: int, tasks: list) -> None:
        t = tasks[i]
        w.task = i  # handed over from here on, whatever happens to the send
        w.since = None  # its time limit starts when the worker takes it
        try:
            w.conn.send((i, t.func, t.args, t.kwargs))
        except OSError:
            pass  # the worker is gone: its death ends the task

    def _receive(self, w: _Worker, ends: list) -> bool:
        """Handle every message waiting from ``w``; False when its pipe is closed."""
        try:
            while w.conn.poll():
                event = w.conn.recv()
                w.heard = time.monotonic()
                kind = event[0]
                if kind == "alive":
                    continue
                if kind == "taken":
                    if event[1] == w.task:
                        w.since = w.heard
                    continue
                if kind == "event":
                    if self.on_event is not None:
                        self.on_event(event[1], event[2])
                    continue
                _, i, value = event
                if i != w.task:  # pragma: no cover - every task is sent once
                    continue
                w.task, w.since = None, None
                ending = Status.DONE if kind == "done" else Status.RAISED
                ends.append(TaskEnd(i, ending, value, pid=w.proc.pid))
        except (EOFError, OSError):  # closed, or cut off mid-message by the worker's death
            return False
        return True

    def _bury(self, w: _Worker) -> TaskEnd | None:
        """The worker ``w`` has ended: the end of the task it held, if any."""
        w.proc.join()
        self.workers.remove(w)
        w.conn.close()
        if w.task is None:
            return None
        if w.stopped:
            ending, limit = w.stopped
            return TaskEnd(w.task, ending, exitcode=w.proc.exitcode, limit=limit,
                           pid=w.proc.pid)
        return TaskEnd(w.task, Status.DIED, exitcode=w.proc.exitcode, pid=w.proc.pid)

    # --- the end ---------------------------------------------------------------------------

    def stop(self, grace: float = GRACE) -> None:
        """SIGTERM every live worker, wait up to ``grace`` seconds, then SIGKILL."""
        procs = [w.proc for w in self.workers]
        for p in procs:
            if p.is_alive():
                p.terminate()
        deadline = time.monotonic() + grace
        for p in procs:
            p.join(max(0.0, deadline - time.monotonic()))
        for p in procs:
            if p.is_alive():
                p.kill()
                p.join(1.0)

    def close(self) -> None:
        """Tell every worker to end, wait for them, and stop those that do not."""
        for w in self.workers:
            try:
                w.conn.send(None)
            except OSError:  # it is gone already
                pass
        for w in self.workers:
            w.proc.join(5.0)
        self.stop(grace=1.0)
        for w in self.workers:
            w.conn.close()
        self.workers = []
