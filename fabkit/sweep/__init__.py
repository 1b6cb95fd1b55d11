"""Design-space sweeps: a module template evaluated on a grid of parameter values.

:func:`sweep` varies numeric keys of a template (node coordinates, or any number in it) on a
grid, evaluates every point with the cheapest adequate model — the module's map d2 = f(d1)
(:func:`fabkit.maps.module_map`) — and measures fixed points, slopes, cycles, the attractor of the
iterated map, its Lyapunov exponent and the mode count. Points are independent: they run in
chunks on local processes (:mod:`fabkit.executor`) or on a dask.distributed cluster (the
``cluster`` extra), every finished chunk is written to
disk at once (``DIR/chunks``), and a sweep that is interrupted and started again computes only
the points that are not on disk yet. Every point gets a typed :class:`Status`: a geometry that is
rigid, starts in a flat state, has a motion that does not move d1, or whose orbits all leave the
map's domain is recorded as such, never dropped.

The whole module is callable, so ``import fabkit.sweep; fabkit.sweep(template, vary=...)`` runs
:func:`sweep`.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import os
import sys
import time
import types
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from ..errors import FabkitError, InputFileError, Interrupted, OutputError
from ..executor import LocalExecutor, Task
from ..io.formats import load_json, load_toml
from .peer import guard_scheduler, probe_scheduler
from ..io.inputs import read_regular
from ..io.outputs import inside, OutputFolder, write_files
from ..templates import MAX_FILE_BYTES, resolve_template
from .chunks import read_chunks, run_chunk, split_chunks, write_chunk
from ..status import Status
from .model import (Axis, CHUNKS_FOLDER, json_default, key_path, lookup_number, MEASURES,
                    parse_vary, path_text, Protocol, require_points, SPEC_FILE, SweepError,
                    SweepSpec)
from .point import evaluate_point, failed_record
from .results import SweepResult


__all__ = [
    "MEASURES",
    "Axis",
    "Protocol",
    "Status",
    "SweepError",
    "SweepResult",
    "SweepFile",
    "SweepSpec",
    "evaluate_point",
    "make_spec",
    "read_sweep_file",
    "parse_vary",
    "sweep",
]

# --------------------------------------------------------------------------------------------
# The front function
# --------------------------------------------------------------------------------------------
def _axes_from(vary) -> tuple:
    if isinstance(vary, Axis):
        vary = [vary]
    if isinstance(vary, Mapping):
        items = []
        for key, v in vary.items():
            if isinstance(v, Axis):
                items.append(v)
            elif isinstance(v, tuple) and len(v) == 3 and isinstance(v[2], (int, np.integer)) \
                    and not isinstance(v[2], bool):
                items.append(Axis.linspace(str(key), float(v[0]), float(v[1]), int(v[2])))
            else:
                vals = np.asarray(v, dtype=np.float64).ravel()
                if vals.size == 0 or not np.all(np.isfinite(vals)):
                    raise SweepError(f"{key}: give (start, stop, n) or a non-empty list of "
                                     "finite values")
                if np.unique(vals).size != vals.size:
                    raise SweepError(f"{key}: a value is given twice")
                items.append(Axis(str(key), tuple(float(x) for x in vals)))
        vary = items
    if not isinstance(vary, (list, tuple)) or not all(isinstance(a, Axis) for a in vary):
        raise SweepError("vary must be an Axis, a list of them, or a mapping of key to "
                         f"(start, stop, n) or values; got {type(vary).__name__}")
    axes = tuple(vary)
    if not axes:
        raise SweepError("nothing to vary: give at least one key (--vary KEY=START:STOP:N)")
    keys = [a.key for a in axes]
    if len(set(keys)) != len(keys):
        raise SweepError(f"a key is varied twice: {', '.join(keys)}")
    return axes


#: Seconds a point of a sweep may run on a worker process before it counts as stopped
#: answering (the bundled sweeps take about 0.4 s a point).
POINT_TIMEOUT = 600.0
#: Largest ``chunks/spec.json`` read back (fabkit writes a few kB).
MAX_SPEC_BYTES = 16 * 2**20

def _measures_from(measure) -> tuple:
    if measure is None:
        return MEASURES
    if isinstance(measure, str):
        measure = [m for m in measure.split(",") if m.strip()]
    out = []
    for m in measure:
        m = m.strip()
        if m not in MEASURES:
            raise SweepError(f"unknown measure {m!r}; valid: {', '.join(MEASURES)}")
        if m not in out:
            out.append(m)
    if not out:
        raise SweepError(f"no measure given; valid: {', '.join(MEASURES)}")
    return tuple(m for m in MEASURES if m in out)


def make_spec(template, vary, measure=None, protocol: Protocol | None = None) -> SweepSpec:
    """Check a sweep request and return its :class:`SweepSpec` (nothing is computed).

    Raises
    ------
    TemplateError
        The template cannot be loaded.
    SweepError
        Unknown or non-numeric key, bad grid, unknown measure, unknown port.
    """
    from ..templates import Design, load_template

    design = template if isinstance(template, Design) else load_template(template)
    raw = design.raw
    axes = _axes_from(vary)
    seen = set()
    for ax in axes:
        tokens = key_path(ax.key, raw)
        canon = path_text(tokens)
        if canon in seen:
            raise SweepError(f"--vary key {ax.key!r} names {canon}, which is already varied")
        seen.add(canon)
        old = lookup_number(raw, tokens, ax.key)
        if isinstance(old, int) and any(v != round(v) for v in ax.values):
            raise SweepError(f"--vary key {ax.key!r}: {canon} is an integer; give values that "
                             "are whole numbers")
    require_points("sweep", int(np.prod([len(a.values) for a in axes], dtype=float)))
    protocol = protocol or Protocol()
    for port in (protocol.d_in, protocol.d_out):
        if port not in design.network.ports:
            known = ", ".join(sorted(design.network.ports)) or "none"
            raise SweepError(f"{design.path}: no port {port!r} to map (the network has: {known})")
    return SweepSpec(template=str(design.path or design.name), raw=copy.deepcopy(raw), axes=axes,
                     measures=_measures_from(measure), protocol=protocol)


@dataclass(frozen=True)
class SweepFile:
    """A sweep spec file: which template, what to vary and measure (see ``docs/sweep.md``).

    Attributes
    ----------
    path : pathlib.Path
    template : pathlib.Path
        Resolved relative to the spec file; a bare name found nowhere there (``"chaotic"``) is
        the bundled template of that name.
    axes : tuple of Axis
    measures : tuple of str or None
    protocol : Protocol
    """

    path: Path
    template: Path
    axes: tuple
    measures: tuple | None
    protocol: Protocol


_SPEC_KEYS = {"template", "vary", "measure", "protocol", "description"}


def read_sweep_file(path) -> SweepFile | None:
    """Read a sweep spec (a TOML file with a ``[sweep]`` table); None for any other file (a
    design template, which :func:`fabkit.load_template` reads).

    Raises
    ------
    SweepError
        A ``[sweep]`` table with a missing, unknown or malformed entry.
    """
    path = Path(path)
    try:  # a FIFO or a device given as the template is refused here, never waited on
        data = read_regular(path, MAX_FILE_BYTES)
    except InputFileError as exc:
        if exc.kind == "missing" or not os.path.exists(path):
            return None  # a bundled template's name: the template loader resolves it
        raise
    try:  # its depth, digits and values bounded before the parser runs
        raw = load_toml(data, path)
    except InputFileError as exc:
        if exc.kind == "bounds":
            raise
        return None  # not TOML: not ours; the template loader reports it properly
    sec = raw.get("sweep")
    if not isinstance(sec, dict):
        return None
    where = f"{path}: sweep"
    unknown = sorted(set(sec) - _SPEC_KEYS)
    if unknown:
        raise SweepError(f"{where}.{unknown[0]}: unknown key; allowed: "
                         f"{', '.join(sorted(_SPEC_KEYS))}")
    tpl = sec.get("template")
    if not isinstance(tpl, str):
        raise SweepError(f"{where}.template: must name the module template, "
                         "e.g. \"../chaotic.toml\"")
    vary = sec.get("vary", [])
    if not isinstance(vary, list) or not all(isinstance(v, str) for v in vary):
        raise SweepError(f"{where}.vary: must be an array of \"KEY=START:STOP:N\" strings")
    measure = sec.get("measure")
    if measure is not None and (not isinstance(measure, list)
                                or not all(isinstance(m, str) for m in measure)):
        raise SweepError(f"{where}.measure: must be an array of measure names")
    prot = sec.get("protocol", {})
    if not isinstance(prot, dict):
        raise SweepError(f"{where}.protocol: must be a table")
    fields = set(Protocol.__dataclass_fields__)
    bad = sorted(set(prot) - fields)
    if bad:
        raise SweepError(f"{where}.protocol.{bad[0]}: unknown key; allowed: "
                         f"{', '.join(sorted(fields))}")

    return SweepFile(path=path, template=resolve_template(tpl, base=path.parent),
                     axes=tuple(parse_vary(v) for v in vary),
                     measures=_measures_from(measure) if measure is not None else None,
                     protocol=Protocol(**prot))


#: The files a sweep writes at the top of its folder (plots besides, when asked for).
TOP_FILES = ("sweep.csv", "sweep.json")


def _refuse_in_the_way(held: OutputFolder, names) -> None:
    """A folder where the sweep writes a file, or a file where it keeps ``chunks/``, refused
    with its own name, before anything is written (none of the files is replaced)."""
    outdir = held.path
    if not os.path.lexists(outdir):  # made at the first write: nothing is in the way yet
        return
    for name in names:
        if held.is_folder(name):
            raise OutputError(outdir / name, "is a folder where the sweep writes its file; "
                                             "remove it or choose another -o")
    chunks = outdir / CHUNKS_FOLDER
    if os.path.lexists(chunks) and not os.path.islink(chunks) and not held.is_folder(
            CHUNKS_FOLDER):
        raise OutputError(chunks, "is a file where the sweep keeps its folder of finished "
                                  "chunks; remove it or choose another -o")


def _check_outdir(outdir, spec: SweepSpec) -> OutputFolder:
    """The sweep's output folder, held (:class:`~fabkit.io.folder.OutputFolder`), checked
    before any work: no folder in the way of its files, chunks/ never a link, and its spec
    this sweep's (a spec cut short or damaged is said to be so, not another sweep's)."""
    held = OutputFolder.open(outdir)
    outdir = held.path
    _refuse_in_the_way(held, TOP_FILES)
    # chunks/ and its spec: never through a link out of the folder (refused before any work)
    marker = inside(outdir, CHUNKS_FOLDER, SPEC_FILE, replace_last=True)
    if os.path.lexists(marker) and held.is_folder(CHUNKS_FOLDER):
        with held.folder(CHUNKS_FOLDER, create=False) as chunks:
            try:  # through the folder held: a link, a FIFO or a device there is refused
                old = load_json(chunks.read_bytes(SPEC_FILE, MAX_SPEC_BYTES), marker,
                                what="a sweep's spec")
            except InputFileError as exc:
                if exc.kind not in ("damaged", "bounds"):
                    raise
                raise InputFileError(marker, f"damaged ({exc.reason}); delete "
                                             f"{outdir / CHUNKS_FOLDER} to start the sweep "
                                             "again", kind="damaged") from None
        if not isinstance(old, dict) or not isinstance(old.get("fingerprint"), str):
            raise InputFileError(marker, "damaged (no fingerprint of a sweep in it); delete "
                                         f"{outdir / CHUNKS_FOLDER} to start the sweep again",
                                 kind="damaged")
        if old["fingerprint"] != spec.fingerprint():
            raise FabkitError(f"{outdir} holds the chunks of a different sweep (another template, "
                              "grid, measure or protocol); choose another -o or delete "
                              f"{outdir / CHUNKS_FOLDER}")
    return held


def _connect(scheduler, timeout: float):
    """A dask.distributed Client for an address (or the Client given), whether this sweep
    owns it, and the :class:`~fabkit.sweep.peer.PeerGuard` it talks through (None for a
    Client given or an address not ``tcp://``)."""
    try:
        from distributed import Client
    except ImportError:  # an optional dependency: local processes need nothing more
        raise FabkitError("running on a cluster (--scheduler) needs dask.distributed, which "
                          "this installation lacks: pip install 'fabkit[cluster]'") from None
    if isinstance(scheduler, Client):
        return scheduler, False, None
    # dask bounds the connection, not the messages after it: the scheduler's first message
    # is read here, within the timeout and a bound on its size, and every message after it by
    # the guard dask connects through
    probe_scheduler(str(scheduler), timeout)
    guard = guard_scheduler(str(scheduler), timeout)
    try:
        client = Client(guard.address if guard else str(scheduler), timeout=timeout)
    except (OSError, TimeoutError, ValueError) as exc:
        _refused_by(guard)
        raise FabkitError(f"cannot reach the dask scheduler at {scheduler}: "
                          f"{type(exc).__name__}") from None
    try:
        client.wait_for_workers(1, timeout=timeout)
    except (OSError, TimeoutError) as exc:
        client.close()
        _refused_by(guard)
        raise FabkitError(f"the dask scheduler at {scheduler} has no workers (waited "
                          f"{timeout:g} s: {type(exc).__name__}); start some with "
                          f"`dask worker {scheduler}`") from None
    return client, True, guard


def _refused_by(guard) -> None:
    """Close ``guard``; raise its one line when it cut the scheduler off."""
    if guard is None:
        return
    guard.close()
    if guard.failure is not None:
        raise FabkitError(f"{guard.failure} (check the address given to --scheduler)")


def sweep(template, vary, measure=None, *, outdir=None, scheduler=None, jobs: int | None = 1,
          chunk_size: int | None = None, protocol: Protocol | None = None, plots: bool = True,
          progress: Callable[[int, int], None] | None = None,
          connect_timeout: float = 10.0, point_timeout: float = POINT_TIMEOUT) -> SweepResult:
    """Evaluate a module template on a grid of parameter values.

    Parameters
    ----------
    template : str, pathlib.Path or Design
        A module template (its map d2 = f(d1) is what is measured).
    vary : mapping or sequence of Axis
        ``{key: (start, stop, n)}`` (n evenly spaced values, both ends included) or
        ``{key: [values]}``. Keys are paths into the template: ``"network.nodes[4][0]"``,
        ``"nodes[4].x"`` (the same), ``"motion.to"``, any number in the file. The grid is the
        outer product, the first key varying slowest.
    measure : sequence of str or str, optional
        Some of :data:`MEASURES` (default: all).
    outdir : str or pathlib.Path, optional
        Folder for ``sweep.csv``, ``sweep.json``, the plots and ``chunks/`` (each finished chunk
        of points, written as it arrives). A folder holding chunks of the same sweep resumes it.
        Without it nothing is written.
    scheduler : str or distributed.Client, optional
        A dask.distributed scheduler address (``tcp://host:8786``) or client: chunks run on its
        workers. Default: this machine.
    jobs : int or None
        Local processes when there is no scheduler (1: in this process; None: one per core).
        They are spawned (:class:`fabkit.executor.LocalExecutor`): a script that calls this
        with more than one needs the ``if __name__ == "__main__":`` guard.
    chunk_size : int, optional
        Points per task (default: about four tasks per worker, at most 32 points).
    protocol : Protocol, optional
    plots : bool
        Draw the bifurcation diagram (1-D) or heat maps (2-D) into ``outdir``.
    progress : callable(done, total), optional
        Called after every chunk (and once at the start with what was on disk).
    connect_timeout : float
        Seconds to wait for the scheduler.
    point_timeout : float
        Seconds a point may take on a worker process before it counts as stopped answering
        (a chunk gets this times its points, from the moment a worker takes it): its worker is
        killed, its points are recorded as ``failed`` with the reason, and the sweep goes on
        (so do the points of a chunk whose worker died). Points run in this process
        (``jobs=1``) cannot be stopped this way.

    Returns
    -------
    SweepResult

    Raises
    ------
    SweepError
        A request that cannot run (bad key, grid or measure).
    TemplateError
        The template cannot be loaded.
    FabkitError
        ``outdir`` is a file or holds another sweep; the scheduler cannot be reached.

    Examples
    --------
    >>> import fabkit.sweep
    >>> r = fabkit.sweep("templates/chaotic.toml", vary={"nodes[4].x": (-0.33, -0.33, 1)},
    ...                  measure="lyapunov")  # doctest: +SKIP
    >>> round(r.column("lyapunov")[0], 2)  # doctest: +SKIP
    0.31
    """
    spec = make_spec(template, vary, measure, protocol)
    # the output folder held from here on: every chunk, read or written, goes through it
    out = _check_outdir(outdir, spec) if outdir is not None else None
    if not (isinstance(point_timeout, (int, float)) and not isinstance(point_timeout, bool)
            and point_timeout > 0):
        raise SweepError(f"point_timeout must be a positive number of seconds, got "
                         f"{point_timeout!r}")
    if jobs is not None and (isinstance(jobs, bool) or int(jobs) < 1):
        raise SweepError(f"jobs must be a positive integer or None, got {jobs!r}")
    if chunk_size is not None and (isinstance(chunk_size, bool) or int(chunk_size) < 1):
        raise SweepError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    client, own_client, guard = (None, False, None)
    if scheduler is not None:
        client, own_client, guard = _connect(scheduler, connect_timeout)
    try:
        return _run(spec, out, client, jobs, chunk_size, plots, progress, point_timeout,
                    scheduler)
    except BaseException as exc:
        if guard is not None and guard.failure is not None and \
                not isinstance(exc, (KeyboardInterrupt, SystemExit, Interrupted)):
            # the guard cut the scheduler off: dask's own error (a closed connection, its
            # futures cancelled) says less than the guard's line
            _refused_by(guard)
        raise
    finally:
        if own_client:
            client.close()
        if guard is not None:
            guard.close()


def _run(spec, out, client, jobs, chunk_size, plots, progress, point_timeout,
         scheduler=None) -> SweepResult:
    done: dict = {}
    damaged: list = []
    folder = None
    if out is not None:
        marker = {"fingerprint": spec.fingerprint(), "spec": spec.as_dict()}
        write_files(out, {f"{CHUNKS_FOLDER}/{SPEC_FILE}": json.dumps(
            marker, indent=1, default=json_default).encode()})
        folder = out.folder(CHUNKS_FOLDER, create=False)
        done, damaged = read_chunks(folder, spec)
    todo = [i for i in range(spec.size) if i not in done]
    if client is not None:
        workers = max(1, sum(client.nthreads().values()))
        # the scheduler's own address, not the guard's dask connects to
        where = (client.scheduler.address if not isinstance(scheduler, str) else scheduler
                 if "://" in scheduler else f"tcp://{scheduler}")
    else:
        workers = (os.cpu_count() or 1) if jobs is None else int(jobs)
        workers = max(1, min(workers, len(todo) or 1))
        where = "in-process" if workers == 1 else "processes"
    size = int(chunk_size) if chunk_size else max(1, min(32, math.ceil(len(todo) / (4 * workers))))
    chunks = split_chunks(todo, size)
    payload = spec.as_dict()
    total = spec.size
    if progress:
        progress(len(done), total)

    cpu = [0.0]

    def arrived(chunk):
        records = chunk["records"]
        if folder is not None:
            write_chunk(folder, records)
        for r in records:
            done[r["index"]] = r
        cpu[0] += chunk["cpu"]
        if progress:
            progress(len(done), total)

    t0 = time.perf_counter()
    if chunks:
        if client is not None:
            _run_dask(client, payload, chunks, spec.fingerprint(), arrived)
        else:
            _run_processes(workers, payload, chunks, arrived, point_timeout)
    seconds = time.perf_counter() - t0
    records = [done[i] for i in range(spec.size)]
    result = SweepResult(spec=spec, records=records, outdir=out.path if out else None,
                         computed=len(todo),
                         damaged=tuple(damaged),
                         seconds=seconds, workers=workers, where=where, cpu_seconds=cpu[0])
    if out is None:
        return result
    return _write_outputs(result, plots, out)


def _run_processes(workers, payload, chunks, arrived, point_timeout) -> None:
    """Chunks on local worker processes (:class:`fabkit.executor.LocalExecutor`), or one after
    the other in this process for one worker. A chunk that runs past its time
    (``point_timeout`` per point, from the moment a worker takes it) has stopped answering: its
    worker is killed and its points are recorded as failed, and so are those of a chunk whose
    worker died; the other chunks go on."""
    tasks = [Task(run_chunk, (payload, c), timeout=point_timeout * len(c)) for c in chunks]
    # no silence limit: a chunk's time limit is the bound (a point may hold the interpreter
    # lock for long); the BLAS threads of the workers share the cores
    with LocalExecutor(workers, silence=None, name="fabkit-sweep",
                       in_process=workers == 1) as pool:
        for end in pool.run(tasks):
            if end.status is Status.DONE:
                arrived(end.value)
            elif end.status is Status.RAISED:
                raise end.value  # as it would have been raised in this process
            elif end.stopped:
                arrived(_stopped_chunk(payload, chunks[end.index],
                                       f"stopped answering: the worker ran past "
                                       f"{point_timeout:g} s a point and was stopped"))
            else:
                arrived(_stopped_chunk(payload, chunks[end.index],
                                       f"the worker process died ({_how(end.exitcode)}) "
                                       "while computing this point"))


def _how(exitcode) -> str:
    """How a process ended, from its exit code (negative: the signal)."""
    import signal

    if exitcode is not None and exitcode < 0:
        try:
            return f"signal {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"signal {-exitcode}"
    return f"exit code {exitcode}"


def _stopped_chunk(payload: dict, chunk, reason: str) -> dict:
    """The records of a chunk whose worker stopped answering or died: every point failed, with
    the reason."""
    spec = SweepSpec(template=payload["template"], raw=payload["raw"],
                     axes=tuple(Axis(a["key"], tuple(a["values"])) for a in payload["axes"]),
                     measures=tuple(payload["measures"]))
    records = []
    for i in chunk:
        rec = failed_record(int(i), spec.point(int(i)))
        rec["reason"] = reason
        records.append(rec)
    return {"records": records, "cpu": 0.0}


def _run_dask(client, payload, chunks, fingerprint, arrived) -> None:
    from distributed import as_completed

    import uuid

    (data,) = client.scatter([payload], broadcast=True)  # a list: a dict would scatter per key
    # a fresh token per run: a resumed sweep must not meet the cancelled tasks of the last one
    token = uuid.uuid4().hex[:8]
    futures = [client.submit(run_chunk, data, c, pure=False,
                             key=f"fabkit-sweep-{fingerprint[:12]}-{token}-{c[0]}")
               for c in chunks]
    try:
        for fut in as_completed(futures):
            arrived(fut.result())
    except BaseException:
        client.cancel(futures)
        raise


def _write_outputs(result: SweepResult, plots: bool, out: OutputFolder) -> SweepResult:
    files = {"sweep.csv": result.table_csv()}
    if plots:
        from ..plots.viz import figure_png
        from .plots import figures

        for name, fig in figures(result).items():
            files[name] = figure_png(fig)
    summary = result.summary()
    summary["files"] = sorted(files) + ["sweep.json"]
    files["sweep.json"] = (json.dumps(summary, indent=1, default=json_default, allow_nan=False)
                           + "\n").encode()
    _refuse_in_the_way(out, files)
    written = tuple(write_files(out, files))
    return dataclasses.replace(result, files=written)


class _CallableModule(types.ModuleType):
    """``fabkit.sweep(...)`` calls :func:`sweep` once the module is imported."""

    def __call__(self, *args, **kwargs):
        return sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
