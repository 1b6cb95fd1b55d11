"""The local executor (``fabkit.executor``): the same results as a serial run, whatever the
workers; a task past its time limit, a task that raises, a worker that dies or stops answering
end that task alone; a signal to the process that runs it leaves no worker behind.

The tasks are real work (chunks of a sweep) and functions of the standard library; the few
that must misbehave on purpose live in a module file the spawned workers import too.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from fabkit.errors import FabkitError
from fabkit.executor import (LocalExecutor, Task, TaskError, THREAD_VARIABLES,
                             blas_limits, user_thread_variables)
from fabkit.status import Status
from fabkit.sweep import make_spec
from fabkit.sweep.chunks import run_chunk

from conftest import TEMPLATES

MODULE = "fabkit_test_executor_tasks"

SOURCE = textwrap.dedent('''
    import os
    import signal

    from fabkit.executor import report
    from fabkit.stoppable import StepLimitError


    def die():
        os.kill(os.getpid(), signal.SIGKILL)


    def freeze():
        os.kill(os.getpid(), signal.SIGSTOP)


    def refuse_to_travel():
        # its __init__ takes two arguments, its args hold one: it cannot be rebuilt elsewhere
        raise StepLimitError("a step", "ran too long")


    def unpicklable():
        return lambda: None


    def announce(n):
        for k in range(n):
            report("step", k)
        return os.getpid()
''')


@pytest.fixture
def helpers(tmp_path, monkeypatch):
    """The misbehaving tasks, in a module file that the spawned workers import too."""
    mods = tmp_path / "mods"
    mods.mkdir()
    (mods / f"{MODULE}.py").write_text(SOURCE)
    monkeypatch.syspath_prepend(str(mods))
    monkeypatch.setenv("PYTHONPATH", str(mods) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    import importlib

    return importlib.import_module(MODULE)


def _alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie runs no code: dead for our purpose)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z"
    except (OSError, IndexError):  # reaped between the two looks, or no /proc
        return True


def _wait_dead(pids, seconds):
    deadline = time.monotonic() + seconds
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    return [p for p in pids if _alive(p)]


def _ends(pool, tasks):
    ends = list(pool.run(tasks))
    assert sorted(e.index for e in ends) == list(range(len(tasks)))  # one end per task
    return {e.index: e for e in ends}


def test_two_workers_give_the_serial_results():
    spec = make_spec(TEMPLATES / "period_two.toml", {"nodes[4].x": (-0.3, -0.1, 6)},
                     "fixed_points,slopes")
    payload = spec.as_dict()
    chunks = [[0, 1], [2, 3], [4], [5]]
    serial = [run_chunk(payload, c)["records"] for c in chunks]
    tasks = [Task(run_chunk, (payload, c)) for c in chunks]
    with LocalExecutor(2) as pool:
        ends = _ends(pool, tasks)
    assert [ends[i].status for i in range(4)] == [Status.DONE] * 4
    assert [ends[i].value["records"] for i in range(4)] == serial
    pids = {e.pid for e in ends.values()}
    assert len(pids) == 2 and os.getpid() not in pids  # two worker processes did the work
    assert _wait_dead(pids, 10) == []  # and ended with the block
    with LocalExecutor(2, in_process=True) as pool:
        here = _ends(pool, tasks)
    assert [here[i].value["records"] for i in range(4)] == serial
    assert {e.pid for e in here.values()} == {None}


def test_a_task_past_its_time_limit_is_stopped_and_its_worker_is_gone():
    # one worker: the stuck task's worker is killed and a new one runs the rest
    tasks = [Task(time.sleep, (60.0,), timeout=1.0)] + [Task(math.factorial, (n,))
                                                        for n in (3, 4, 5)]
    with LocalExecutor(1) as pool:
        ends = _ends(pool, tasks)
    stuck = ends[0]
    assert stuck.status is Status.TIMED_OUT and stuck.stopped
    assert stuck.limit == 1.0 and stuck.exitcode == -signal.SIGKILL and stuck.value is None
    assert not _alive(stuck.pid)
    assert [ends[i].value for i in (1, 2, 3)] == [6, 24, 120]
    assert {ends[i].pid for i in (1, 2, 3)} != {stuck.pid}


def test_an_exception_ends_its_task_only(helpers):
    tasks = [Task(math.factorial, (3,)), Task(math.sqrt, (-1.0,)),
             Task(helpers.refuse_to_travel), Task(helpers.unpicklable),
             Task(math.factorial, (4,))]
    with LocalExecutor(2) as pool:
        ends = _ends(pool, tasks)
    assert (ends[0].value, ends[4].value) == (6, 24)
    assert ends[1].status is Status.RAISED and isinstance(ends[1].value, ValueError)
    assert str(ends[1].value) == "math domain error"
    # an exception that cannot be rebuilt here, a result that cannot be sent: one line each
    for i, what in ((2, "StepLimitError: a step: ran too long"), (3, "pickle")):
        assert ends[i].status is Status.RAISED and isinstance(ends[i].value, TaskError)
        assert isinstance(ends[i].value, FabkitError) and what in str(ends[i].value)
        assert str(ends[i].value).startswith("internal error")
    # the same in this process: the exception itself
    with LocalExecutor(1, in_process=True) as pool:
        here = _ends(pool, tasks[:2])
    assert here[0].value == 6 and isinstance(here[1].value, ValueError)


def test_a_dead_or_silent_worker_ends_its_task_only(helpers):
    tasks = [Task(helpers.die), Task(helpers.freeze), Task(math.factorial, (5,)),
             Task(math.factorial, (6,))]
    with LocalExecutor(2, silence=3.0) as pool:
        ends = _ends(pool, tasks)
    assert ends[0].status is Status.DIED and ends[0].exitcode == -signal.SIGKILL
    assert not ends[0].stopped and ends[0].limit is None
    assert ends[1].status is Status.SILENT and ends[1].limit == 3.0 and ends[1].stopped
    assert ends[1].exitcode == -signal.SIGKILL and not _alive(ends[1].pid)
    assert (ends[2].value, ends[3].value) == (120, 720)


def test_reports_of_a_task_arrive_before_its_end(helpers):
    seen = []
    tasks = [Task(helpers.announce, (3,)), Task(helpers.announce, (2,))]
    with LocalExecutor(2, on_event=lambda i, payload: seen.append((i, payload))) as pool:
        for end in pool.run(tasks):
            # every report of this task came in before its end
            assert [p for i, p in seen if i == end.index] == [
                ("step", k) for k in range(3 - end.index)]
    with LocalExecutor(1, in_process=True, on_event=lambda i, p: seen.append((i, p))) as pool:
        seen.clear()
        assert [e.value for e in pool.run(tasks)] == [os.getpid()] * 2
    assert seen == [(0, ("step", 0)), (0, ("step", 1)), (0, ("step", 2)),
                    (1, ("step", 0)), (1, ("step", 1))]


def test_leaving_the_run_early_stops_the_workers():
    tasks = [Task(os.getpid)] + [Task(time.sleep, (60.0,))] * 3
    with LocalExecutor(2) as pool:
        for end in pool.run(tasks):
            workers = pool.pids
            break
    assert end.status is Status.DONE and end.value in workers and len(workers) == 2
    assert pool.pids == [] and _wait_dead(workers, 10) == []


def test_an_interrupt_held_back_while_a_worker_starts_stops_that_worker(monkeypatch):
    """A Ctrl-C that arrives while a worker starts is delivered as the signals are unblocked,
    after the start: the interrupt it raises must find the new worker among those it stops."""
    import contextlib

    import fabkit.executor as executor

    started = []

    @contextlib.contextmanager
    def delivered_at_the_end():
        yield
        started.extend(p.pid for p in __import__("multiprocessing").active_children())
        raise KeyboardInterrupt  # the held-back signal, delivered as the block ends

    stopped = []
    stop = LocalExecutor.stop

    def stop_and_tell(self, *args, **kwargs):
        stopped.extend(self.pids)
        stop(self, *args, **kwargs)

    monkeypatch.setattr(executor, "group_blocked", delivered_at_the_end)
    monkeypatch.setattr(LocalExecutor, "stop", stop_and_tell)
    with pytest.raises(KeyboardInterrupt):
        with LocalExecutor(1) as pool:
            list(pool.run([Task(time.sleep, (60.0,))]))
    assert len(started) == 1 and started[0] in stopped and pool.pids == []
    assert _wait_dead(started, 10) == []


def test_bad_jobs_are_refused():
    for jobs in (0, -1, True):
        with pytest.raises(ValueError, match="jobs must be a positive integer"):
            LocalExecutor(jobs)


# -- BLAS threads of the workers ----------------------------------------------------------------
#: Every thread variable a library reads (and the two that threadpoolctl never touches): none
#: may leak from the shell that runs the tests into a test that sets its own.
ALL_THREAD_VARIABLES = sorted({v for group in THREAD_VARIABLES.values() for v in group}
                              | {"VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS"})


def _worker_blas_threads(jobs: int, **kwargs) -> list[int]:
    """The thread counts threadpoolctl reports for the BLAS libraries inside a worker."""
    import threadpoolctl

    with LocalExecutor(jobs, **kwargs) as pool:
        (end,) = pool.run([Task(threadpoolctl.threadpool_info)])
    assert end.status is Status.DONE and end.pid not in (None, os.getpid()), end
    blas = [lib["num_threads"] for lib in end.value if lib["user_api"] == "blas"]
    assert blas, end.value  # numpy's BLAS is loaded in every worker (fabkit imports numpy)
    return blas


@pytest.mark.parametrize("variable", ["OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"])
def test_a_worker_keeps_the_users_blas_threads(monkeypatch, variable):
    # the worker's share would be 2 threads (given here so that it differs from the user's
    # 1 on any machine); the user's variable wins
    for name in ALL_THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv(variable, "1")
    assert set(_worker_blas_threads(1, blas_threads=2)) == {1}


def test_without_a_thread_variable_a_worker_takes_its_share_of_the_cores(monkeypatch):
    for name in ALL_THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    # a machine of 6 cores shared by 2 workers: 3 threads each (not what OpenBLAS would take
    # by itself here, all the cores)
    monkeypatch.setattr(os, "cpu_count", lambda: 6)
    assert set(_worker_blas_threads(2)) == {3}


def test_only_the_libraries_the_user_set_keep_their_threads():
    libs = [{"filepath": "/x/libopenblas.so", "internal_api": "openblas"},
            {"filepath": "/x/libmkl_rt.so", "internal_api": "mkl"},
            {"filepath": "/x/libgomp.so", "internal_api": "openmp"},
            {"filepath": "/x/libflexiblas.so", "internal_api": "flexiblas"}]
    assert blas_limits(2, libs, {}) == {lib["filepath"]: 2 for lib in libs}
    # MKL's own variable: MKL keeps it, and so does FlexiBLAS (whose backend may be MKL)
    assert blas_limits(2, libs, {"MKL_NUM_THREADS": "1"}) == {"/x/libopenblas.so": 2,
                                                              "/x/libgomp.so": 2}
    # OMP_NUM_THREADS is read by every one of them; an empty variable is not set
    assert blas_limits(2, libs, {"OMP_NUM_THREADS": "1"}) == {}
    assert blas_limits(2, libs, {"OMP_NUM_THREADS": " "}) == {lib["filepath"]: 2
                                                              for lib in libs}
    assert user_thread_variables("openblas", {"GOTO_NUM_THREADS": "3", "OMP_NUM_THREADS": "1"}) \
        == ["GOTO_NUM_THREADS", "OMP_NUM_THREADS"]


RUNNER = textwrap.dedent('''
    import os
    import signal
    import sys
    import time

    from fabkit.errors import Interrupted
    from fabkit.executor import LocalExecutor, Task


    def interrupted(signum, frame):
        raise Interrupted(signum)


    if __name__ == "__main__":
        if sys.argv[1] == "handled":  # as the command line does
            signal.signal(signal.SIGTERM, interrupted)
        tasks = [Task(os.getpid), Task(os.getpid)] + [Task(time.sleep, (3600.0,))] * 2
        try:
            with LocalExecutor(2) as pool:
                for end in pool.run(tasks):
                    print(end.value, flush=True)
        except (Interrupted, KeyboardInterrupt) as exc:
            print(f"stopped by {type(exc).__name__}", file=sys.stderr, flush=True)
            sys.exit(3)
''')


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs /proc (Linux)")
@pytest.mark.parametrize("how, signum, code, words", [
    ("default", signal.SIGTERM, -signal.SIGTERM, ""),  # no handler: the workers die with it
    ("handled", signal.SIGTERM, 3, "stopped by Interrupted"),
    ("default", signal.SIGINT, 3, "stopped by KeyboardInterrupt"),
])
def test_a_signal_to_the_process_leaves_no_worker(tmp_path, how, signum, code, words):
    script = tmp_path / "runner.py"
    script.write_text(RUNNER)
    proc = subprocess.Popen([sys.executable, str(script), how], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    workers = []
    try:
        workers = [int(proc.stdout.readline()) for _ in range(2)]
        assert len(set(workers)) == 2 and proc.pid not in workers
        assert all(_alive(p) for p in workers)
        time.sleep(0.5)  # the workers are in their hour-long tasks
        proc.send_signal(signum)
        assert proc.wait(timeout=60) == code
        # a worker ends within a second of the stop; a few seconds for a busy machine
        assert _wait_dead(workers, 10) == []
        # (read only now: a worker left alive would hold the pipe open)
        assert proc.stderr.read().strip() == words
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for pid in workers:  # a worker left behind by a failure here
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
