"""Designs exported in worker processes (:class:`fabkit.executor.LocalExecutor`), one at a time
each: folders swapped in by the parent, deaths and silences reported per design, faults for the
tests."""

from __future__ import annotations

import os
import time
from pathlib import Path

from ..errors import FolderChangedError, internal_error_line, OutputError
from ..executor import SILENCE, LocalExecutor, Task, report
from .design import export_one, source_label
from .folders import is_safe_name, recover_folder, swap_in
from ..status import Status
from .results import DesignResult


#: Default time limit of one design in a worker process (``--timeout``); the work estimate
#: refuses designs expected to take more than half of it.
DESIGN_TIMEOUT = 3600.0


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


def _export_in_worker(name: str, args: tuple, kwargs: dict) -> DesignResult:
    """Export one design in a worker process: its folder is left staged for the parent to swap
    in, and every stage that starts is reported to the parent as it starts."""
    hit = _fault_point(name)
    hit("taken")

    def progress(name, s):
        hit(s)
        report(name, str(s))

    res = export_one(*args, progress=progress, swap=False, **kwargs)
    hit("done")
    return res


def _stuck_reason(ending: Status, limit: float, name: str) -> str:
    """Why the worker exporting design ``name`` was stopped, at the limit ``limit`` seconds."""
    if ending is Status.NOT_STARTED:
        return (f"the worker did not start within {limit:g} s (it was to export {name}), "
                "and was stopped")
    if ending is Status.SILENT:
        return (f"the worker stopped answering (no word for {limit:g} s) while exporting "
                f"{name}, and was stopped")
    return (f"exporting {name} ran past the time limit of {limit:g} s (--timeout), and was "
            "stopped")


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

    The executor hands a design to an idle worker; the worker leaves its folder staged and the
    parent swaps it in. A worker that dies (killed by the system, out of memory, a crash), at
    whatever moment, fails the design it was handed with ``error_code = "worker"`` and its exit
    status, its staging folder is removed, and a new worker takes its place while designs
    remain.

    A worker that stops answering for ``silence`` seconds (stopped, or stuck where not even its
    heartbeat runs), or whose design runs past ``timeout`` seconds from the moment it took it
    (stuck in a loop while its heartbeat goes on), is killed and fails only that design, with
    the reason (``error_code = "timeout"``). The clocks measure the worker, not the machine
    (:func:`fabkit.executor.overdue`).
    """
    tasks = [Task(_export_in_worker, (names[i], args[i], kwargs), timeout=timeout)
             for i in todo]
    pending = set(todo)
    on_stage = (lambda index, payload: progress.stage(*payload)) if progress else None
    try:
        with LocalExecutor(jobs, silence=silence, on_event=on_stage,
                           name="fabkit-export") as pool:
            for end in pool.run(tasks):
                i = todo[end.index]
                pending.discard(i)
                if end.status is Status.DONE:
                    finished(i, _swapped_in(end.value, source_label(args[i][0]), names[i],
                                            outdir))
                    continue
                if isinstance(end.value, FolderChangedError):  # in a worker: the run stops
                    raise end.value
                if is_safe_name(names[i]):
                    try:  # its staging folder, whatever it holds
                        recover_folder(outdir, names[i])
                    except (OSError, OutputError):  # pragma: no cover - the next run removes it
                        pass
                finished(i, _failed(end, source_label(args[i][0]), names[i]))
    except BaseException:
        # the executor has stopped the workers (half a second to unwind): a worker killed
        # between two writes leaves its staging folder, so remove those of the designs in
        # flight, and put back an old folder caught between the two renames
        for i in pending:
            if is_safe_name(names[i]):
                try:
                    recover_folder(outdir, names[i])
                except (OSError, OutputError):
                    pass
        raise


def _swapped_in(res: DesignResult, path, name: str, outdir) -> DesignResult:
    """The result of a design exported by a worker, its staged folder swapped in."""
    if res.staged:
        try:  # by name, in the folder this process holds: whatever the worker's paths said
            swap_in(outdir, Path(res.staged).name, name, res.earlier_files)
        except FolderChangedError:
            raise  # the whole run stops
        except (OSError, OutputError) as exc:
            try:
                recover_folder(outdir, name)
            except (OSError, OutputError):
                pass  # the guard's refusal is the error reported
            res.status, res.folder, res.files = Status.FAILED, "", 0
            why = exc.strerror if isinstance(exc, OSError) else exc.reason
            res.message = f"{path}: cannot write the export to {outdir}: {why or exc}"
            res.error_code = "output"
        res.staged = ""
    return res


def _failed(end, path, name: str) -> DesignResult:
    """The result of a design whose worker died, was stopped, or could not send it back."""
    if end.status is Status.RAISED:  # export_one reports its own errors: this is a bug
        return DesignResult(str(path), name, error_code="internal",
                            message=f"{path}: {internal_error_line(end.value)}")
    if end.stopped:
        return DesignResult(str(path), name, error_code="timeout", worker_exit=end.exitcode,
                            message=(f"{path}: {_stuck_reason(end.status, end.limit, name)}; "
                                   f"nothing of {name} was written"))
    return DesignResult(str(path), name, error_code="worker", worker_exit=end.exitcode,
                        message=_died_message(path, name, end.exitcode))
