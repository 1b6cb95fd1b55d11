"""Worker processes: one design at a time each, deaths and silences found, faults for the tests."""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

from ..errors import (Interrupted, OutputError)
from .design import export_one
from .folders import is_safe_name, recover_folder, swap_in
from .results import DesignResult, Outcome


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
#: Default time limit of one design in a worker process (``--timeout``); the work estimate
#: refuses designs expected to take more than half of it.
DESIGN_TIMEOUT = 3600.0


# --- worker processes -------------------------------------------------------------------------

def _die_with_parent(parent_pid: int) -> None:
    """Make this worker end when its parent does, however the parent ends (even SIGKILL).

    Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)``. Everywhere: a daemon thread that polls the
    parent's pid and exits at once when it changes (the worker was re-parented)."""
    import signal

    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:  # the parent died before the prctl took effect
        os._exit(1)

    def watch():
        while True:
            time.sleep(0.5)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, daemon=True, name="fabkit-parent-watch").start()


#: A fault to inject in the worker processes, for the tests of worker deaths only:
#: ``"NAME@MOMENT[:ACTION]"`` makes the worker exporting design NAME, at MOMENT (``taken``: as
#: it receives the design, before anything else; a :class:`Stage` value: as that stage starts;
#: ``done``: after the export, before it reports back), end by ACTION (``kill``: SIGKILL, the
#: default; ``term``: SIGTERM; ``exit``: exit code 3 without cleaning up) or stop answering
#: (``hang``: the export never returns while the worker lives on; ``stop``: SIGSTOP, the whole
#: worker stands still).
FAULT_ENV = "FABKIT_TEST_WORKER_FAULT"


def _fault_point(name: str):
    """The worker's fault injector for design ``name``: ``hit(moment)`` (a no-op without
    :data:`FAULT_ENV`)."""
    import signal

    spec = os.environ.get(FAULT_ENV, "")
    target, _, rest = spec.partition("@")
    moment, _, action = rest.partition(":")
    if not spec or target != name:
        return lambda moment: None

    def hit(now):
        if str(now) != moment:
            return
        if action in ("", "kill"):
            os.kill(os.getpid(), signal.SIGKILL)
        elif action == "term":
            os.kill(os.getpid(), signal.SIGTERM)
        elif action == "hang":
            while True:
                time.sleep(3600)
        elif action == "stop":
            os.kill(os.getpid(), signal.SIGSTOP)
        else:
            os._exit(3)

    return hit


def heartbeat_interval(silence: float) -> float:
    """Seconds between two "alive" messages of a worker under the silence limit ``silence``:
    :data:`HEARTBEAT`, or a sixth of the limit when that is shorter, so that a worker counts
    as silent only after several beats in a row went missing (one beat late on a busy machine
    is not a stopped worker).

    Examples
    --------
    >>> heartbeat_interval(120.0), heartbeat_interval(3.0)
    (1.0, 0.5)
    """
    return min(HEARTBEAT, silence / 6.0)


def _worker_main(parent_pid, conn, blas_threads: int, beat: float = HEARTBEAT) -> None:
    """A worker process: export the designs it is sent on ``conn`` until it gets None.

    ``blas_threads`` caps the BLAS/LAPACK threads of this worker so that the workers together
    use the machine's cores once: parallelism is across designs, and oversubscribed BLAS threads
    slow dense work down several times (a dense SVD of 882 coordinates: 0.15 s on one thread,
    seconds when threads contend).

    Everything goes back on the same pipe with blocking sends (no feeder thread), so what the
    parent reads was sent, and a design it has sent and not heard back about is known to be in
    the hands of this worker whatever the moment it dies. The heartbeat says "alive" as soon as
    the worker runs and then every ``beat`` seconds; a design is acknowledged with "taken" as it
    arrives, which starts its time limit.
    """
    import signal

    _die_with_parent(parent_pid)
    import threadpoolctl

    threadpoolctl.threadpool_limits(blas_threads)  # for the life of the worker
    # Ctrl-C in a terminal reaches the whole process group: the parent alone decides, and stops
    # the workers with SIGTERM, which unwinds the design in hand (its staging folder is removed)
    signal.signal(signal.SIGINT, signal.SIG_IGN)

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
                return
            if task is None:
                return
            index, name, args, kwargs = task
            send(("taken", index))
            hit = _fault_point(name)
            hit("taken")

            def progress(name, s, index=index, hit=hit):
                hit(s)
                send(("stage", index, name, str(s)))

            res = export_one(*args, progress=progress, swap=False, **kwargs)
            hit("done")
            send(("done", index, res))
    except Interrupted as exc:
        # the design in hand has been unwound; end by the signal itself, so that the parent
        # (when it did not send it) reports how this worker ended
        signal.signal(exc.signum, signal.SIG_DFL)
        os.kill(os.getpid(), exc.signum)


class _Worker:
    """One worker process, the parent's end of its pipe, and the design it was handed."""

    def __init__(self, proc, conn):
        self.proc = proc
        self.conn = conn
        self.task = None  # index of the design sent and not reported back
        self.born = time.monotonic()  # when it was started
        self.heard = None  # when the worker last said anything (None: starting, not a word yet)
        self.since = None  # when it took the design in hand (its "taken")
        self.stuck = ""  # why the parent stopped it (it stopped answering), or ""

    @property
    def pid(self) -> int:
        return self.proc.pid


class _Pool:
    """Worker processes, each fed one design at a time over its own pipe."""

    def __init__(self, jobs: int, beat: float = HEARTBEAT):
        import multiprocessing

        self.ctx = multiprocessing.get_context("spawn")  # fresh interpreters, no forked state
        self.blas_threads = max(1, (os.cpu_count() or 1) // jobs)
        self.beat = beat
        self.workers: list[_Worker] = []
        for _ in range(jobs):
            self.spawn()

    @property
    def procs(self):
        return [w.proc for w in self.workers]

    def spawn(self) -> _Worker:
        """Start one more worker."""
        saved = os.environ.get("PYTHONHASHSEED")
        os.environ["PYTHONHASHSEED"] = "0"  # read by each worker when it starts
        mine, theirs = self.ctx.Pipe(duplex=True)
        try:
            proc = self.ctx.Process(target=_worker_main, daemon=True,
                                    args=(os.getpid(), theirs, self.blas_threads, self.beat),
                                    name=f"fabkit-export-{len(self.workers)}")
            proc.start()
        finally:
            theirs.close()  # the worker's end lives in the worker: its death closes the pipe
            if saved is None:
                os.environ.pop("PYTHONHASHSEED", None)
            else:
                os.environ["PYTHONHASHSEED"] = saved
        worker = _Worker(proc, mine)
        self.workers.append(worker)
        return worker

    def stop(self, grace: float = 5.0) -> None:
        """SIGTERM every live worker, wait up to ``grace`` seconds, then SIGKILL."""
        for p in self.procs:
            if p.is_alive():
                p.terminate()
        deadline = time.monotonic() + grace
        for p in self.procs:
            p.join(max(0.0, deadline - time.monotonic()))
        for p in self.procs:
            if p.is_alive():
                p.kill()
                p.join(1.0)

    def close(self) -> None:
        for w in self.workers:
            try:
                w.conn.send(None)
            except OSError:  # it is gone already
                pass
        for p in self.procs:
            p.join(5.0)
        self.stop(grace=1.0)
        for w in self.workers:
            w.conn.close()


def _why_stuck(w: _Worker, now: float, name: str, *, silence: float, timeout: float | None,
               startup: float) -> str:
    """Why the worker ``w``, holding design ``name``, is to be stopped at time ``now``, or "".

    A worker that has not said a word yet is starting, allowed ``startup`` seconds from its
    start; one that has spoken may stay silent ``silence`` seconds; its design may run
    ``timeout`` seconds (None: no limit) from the moment the worker took it. Times are those of
    :func:`time.monotonic` (any clock, for the tests).
    """
    if w.heard is None:
        if now - w.born > startup:
            return (f"the worker did not start within {startup:g} s (it was to export {name}), "
                    "and was stopped")
        return ""
    if now - w.heard > silence:
        return (f"the worker stopped answering (no word for {silence:g} s) while exporting "
                f"{name}, and was stopped")
    if timeout is not None and w.since is not None and now - w.since > timeout:
        return (f"exporting {name} ran past the time limit of {timeout:g} s (--timeout), and "
                "was stopped")
    return ""


def _died_message(path, name: str, code) -> str:
    import signal

    if code is not None and code < 0:
        try:
            how = f"signal {-code}, {signal.Signals(-code).name}"
        except ValueError:
            how = f"signal {-code}"
    else:
        how = f"exit code {code}"
    return f"{path}: worker died ({how}) while exporting {name}; nothing of it was written"


def run_pool(todo, args, names, kwargs, jobs, outdir, progress, finished, *,
             timeout=None, silence=SILENCE) -> None:
    """Export the designs ``todo`` (in this order) in ``jobs`` worker processes.

    The parent hands a design to an idle worker and remembers it until the worker reports it
    done; the worker leaves its folder staged and the parent swaps it in. A worker that dies
    (killed by the system, out of memory, a crash), at whatever moment, fails the design it
    was handed with ``error_code = "worker"`` and its exit status, its staging folder is
    removed, and a new worker takes its place while designs remain.

    A worker that stops answering is found the same way: every worker says it is alive several
    times within the silence limit (:func:`heartbeat_interval`), so one that says nothing for
    ``silence`` seconds (stopped, or stuck where not even its heartbeat runs) is killed; and a
    design that runs past ``timeout`` seconds from the moment its worker took it (stuck in a
    loop while its heartbeat goes on) is stopped too. Either fails only that design, with the
    reason. The clocks measure the worker, not the machine: a worker's silence counts from its
    first word (until then it is starting, allowed :data:`STARTUP` seconds), and what a worker
    sent is read before it is judged silent (a parent that was itself kept waiting by a busy
    machine finds the heartbeats in the pipe).
    """
    from multiprocessing.connection import wait

    queue = list(todo)
    pending = set(todo)
    pool = _Pool(max(1, min(jobs, len(todo))), heartbeat_interval(silence))
    startup = max(silence, STARTUP)

    def dispatch(w):
        if not queue:
            return
        i = queue.pop(0)
        w.task = i  # handed over from here on, whatever happens to the send
        w.since = None  # its time limit starts when the worker takes it
        try:
            w.conn.send((i, names[i], args[i], kwargs))
        except OSError:
            pass  # the worker is gone: its death fails the design

    def receive(w) -> bool:
        """Handle every message waiting from ``w``; False when its pipe is closed."""
        try:
            while w.conn.poll():
                event = w.conn.recv()
                w.heard = time.monotonic()
                if event[0] == "alive":
                    continue
                if event[0] == "taken":
                    if event[1] == w.task:
                        w.since = w.heard
                    continue
                if event[0] == "stage":
                    if progress:
                        progress.stage(event[2], event[3])
                    continue
                _, i, res = event
                if i not in pending:  # pragma: no cover - every design is sent once
                    continue
                if res.staged:
                    try:
                        swap_in(Path(res.staged), Path(res.folder), res.earlier_files)
                    except (OSError, OutputError) as exc:
                        try:
                            recover_folder(outdir, names[i])
                        except (OSError, OutputError):
                            pass  # the guard's refusal is the error reported
                        res.outcome, res.folder, res.files = Outcome.FAILED, "", 0
                        why = exc.strerror if isinstance(exc, OSError) else exc.reason
                        res.error = (f"{args[i][0]}: cannot write the export to {outdir}: "
                                     f"{why or exc}")
                        res.error_code = "output"
                    res.staged = ""
                w.task, w.since = None, None
                pending.discard(i)
                finished(i, res)
        except (EOFError, OSError):  # closed, or cut off mid-message by the worker's death
            return False
        return True

    def bury(w):
        """The worker ``w`` has ended: fail the design it held, start another in its place."""
        w.proc.join()
        pool.workers.remove(w)
        w.conn.close()
        i = w.task
        if i is not None and i in pending:
            pending.discard(i)
            if is_safe_name(names[i]):
                try:  # its staging folder, whatever it holds
                    recover_folder(outdir, names[i])
                except (OSError, OutputError):  # pragma: no cover - the next run removes it
                    pass
            error = (f"{args[i][0]}: {w.stuck}; nothing of {names[i]} was written" if w.stuck
                     else _died_message(args[i][0], names[i], w.proc.exitcode))
            finished(i, DesignResult(str(args[i][0]), names[i],
                                     error_code="timeout" if w.stuck else "worker",
                                     error=error, worker_exit=w.proc.exitcode))
        if queue and len(pool.workers) < min(jobs, len(pending)):
            pool.spawn()

    try:
        while pending:
            for w in pool.workers:
                # only a worker seen alive gets a design (one that ended after finishing its
                # last design is buried below without one)
                if w.task is None and queue and w.proc.is_alive():
                    dispatch(w)
            ready = set(wait([w.conn for w in pool.workers] +
                             [w.proc.sentinel for w in pool.workers], timeout=1.0))
            for w in list(pool.workers):
                # every worker's pipe is read, ready or not: what arrived since the wait counts
                open_ = receive(w)
                now = time.monotonic()
                if w.task is not None and w.proc.is_alive() and not w.stuck:
                    w.stuck = _why_stuck(w, now, names[w.task], silence=silence,
                                         timeout=timeout, startup=startup)
                    if w.stuck:
                        w.proc.kill()
                        w.proc.join()
                if w.proc.sentinel in ready or not open_ or not w.proc.is_alive():
                    receive(w)  # what it sent before it ended counts
                    if not open_ and w.proc.is_alive():
                        w.proc.kill()  # a broken pipe: this worker can no longer report
                    bury(w)
    except BaseException:
        # half a second to unwind: a worker inside a C call never does, and the staging
        # folders are removed below whatever the workers did
        pool.stop(grace=0.5)
        # a worker killed between two writes leaves its staging folder: remove those of the
        # designs in flight, and put back an old folder caught between the two renames
        for i in pending:
            if is_safe_name(names[i]):
                try:
                    recover_folder(outdir, names[i])
                except (OSError, OutputError):
                    pass
        raise
    finally:
        pool.close()
