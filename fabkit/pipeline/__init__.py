"""The batch engine behind ``fabkit export``: many templates in, one folder per design out.

Callable from Python: :func:`fabkit.export` exports one design (a template, or a design made in
code) in this process and returns its :class:`DesignResult`; many at once::

    from fabkit.pipeline import export_many
    results = export_many(["fourbar", "templates/fourbar_chain.toml"], outdir="out", jobs=2)
    results[0].status         # Status.OK / FAILED / CHECK_FAILED / REFUSED / INTERRUPTED
    results[0].message        # "" when OK, else one line: what went wrong
    results[0].formats["dxf"] # FormatResult(status=Status.EXPORTED, files=[...], ...)

What it guarantees:

- **Typed results.** Every design ends as a :class:`DesignResult`, every format as a
  :class:`FormatResult`, each with a :class:`~fabkit.status.Status` (one of
  :data:`fabkit.status.EXPORT`, :data:`fabkit.status.FORMAT`) and a one-line ``message``. The
  command line, report.json and the tests read these fields; no decision anywhere reads the text
  of an error message (the kind of an error is its ``error_code``).
- **Atomic folders.** A design is computed completely in memory, written to a hidden staging folder
  (each file through a temporary file and a rename), checked as built there, and swapped in place
  of the previous export by two renames. Files in the old folder that no export wrote (those of
  ``fabkit simulate``, ``map``, ``tolerance``, ``fold``) are carried over, so commands do not
  delete each other's outputs.
- **Formats added, not swapped.** The formats an earlier export left in the folder stay while
  they are current (same design, settings they read, fabkit version: ``exports.json``,
  :mod:`fabkit.pipeline.manifest`) and are checked again; stale ones are removed, saying why.
  The reports cover every format in the folder.
- **One export per folder.** A lock file ``<out>/.fabkit.lock`` (``flock``) makes a second export
  into the same folder refuse with :class:`~fabkit.errors.LockedError`, or wait with ``wait=True``.
- **Signals and processes.** Workers are spawned processes that die with their parent
  (``PR_SET_PDEATHSIG`` on Linux, and a watchdog thread that polls the parent's pid); SIGINT and
  SIGTERM in the parent stop every worker at once, and the staging folders of the designs in
  flight are removed, so no partial file is left under any name.
- **Workers that die.** Each worker gets one design at a time over its own pipe and leaves its
  folder staged; the parent swaps it in once the worker has reported. A worker that dies at any
  moment fails the design it was handed (``error_code = "worker"``, its exit status in
  :attr:`DesignResult.worker_exit`), leaves no file, and is replaced while designs remain.
- **Bounds before work.** Sizes that would not finish (Monte Carlo samples) are refused before any
  worker starts (:class:`~fabkit.errors.BoundsError`); template sizes are bounded when the template
  is loaded (:mod:`fabkit.templates`).
- **Progress.** :func:`export_many` tells a ``progress`` object (``stage(name, stage)`` as a
  design starts a stage, ``finished(result)`` as it ends, ``close()``) and says nothing itself;
  the command line's :class:`~fabkit.commands.export.DesignProgress` puts it into the one
  progress of every command (stderr, the designs done of all and the time left, ``-q``).
"""

from __future__ import annotations

from ..errors import BoundsError, FabkitError, UsageError
from ..writers import check_export_settings
from ..io.outputs import OutputLock
from ..io.schema import refuse_unused
from ..templates import allow_large as large_allowed, Design
from ..report.html import write_index
from ..tolerance import key_process, made_process
from .design import export_one, source_label
from .folders import prepare_outdir
from .formats import build_outputs, choose_formats, MAX_SAMPLES, RESERVED, run_checks
from .motion import traced_motion
from ..status import Status
from .results import CheckResult, DesignResult, exit_code, FormatResult, Stage
from .stages import Artefacts, Checks, DesignReport, judge_design, Plan, Verdict
from .workers import DESIGN_TIMEOUT, FAULT_ENV, run_pool, SILENCE

__all__ = ["Status", "Stage", "CheckResult", "FormatResult", "DesignResult",
           "Plan", "Artefacts", "Checks", "Verdict", "DesignReport", "judge_design",
           "traced_motion", "build_outputs", "run_checks", "export_one", "export_many",
           "OutputLock", "summary_table", "exit_code", "RESERVED", "MAX_SAMPLES",
           "DESIGN_TIMEOUT", "SILENCE", "FAULT_ENV"]


# --- many designs ----------------------------------------------------------------------------

def summary_table(results, messages: bool = True) -> str:
    """The table printed at the end: one line per design, its status that of its reports'
    verdict (:attr:`DesignResult.word`).

    Parameters
    ----------
    results : list of DesignResult
    messages : bool
        Give a failed design's error in its row. ``fabkit export`` says each error once, as a
        ``fabkit: error:`` line on stderr after the table, so its rows name the design's folder
        (where report.md says why) or ``(error below)`` instead.
    """
    header = ("design", "status", "formats", "files", "time", "cpu", "output or error")
    body = [(r.name, r.word, ",".join(r.exported_formats) or "-", str(r.files),
             f"{r.seconds:.1f}s", f"{r.cpu_seconds:.1f}s",
             r.folder if r.ok else r.message if messages else r.folder or "(error below)")
            for r in results]
    widths = [max(len(x[i]) for x in [header, *body]) for i in range(6)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r[:6], widths)) + "  " + r[6]
             for r in [header, *body]]
    failed = sum(not r.ok for r in results)
    lines.append(f"{len(results) - failed} exported, {failed} failed")
    return "\n".join(lines)


def _refuse_unused_settings(settings, designs, formats, exporters, tolerance_samples) -> None:
    """Refuse, before any work, ``--set`` sections that no design of this export reads: those
    of processes whose formats are not made (``print`` with ``--to dxf``) and whose tolerance
    analysis does not run (:func:`fabkit.io.schema.refuse_unused`)."""
    if not settings:
        return
    used, made, analysed = {"motion"}, set(), set()
    tol = settings.get("tolerance") if isinstance(settings.get("tolerance"), dict) else {}
    for design in designs:
        chosen, _ = choose_formats(design, formats, exporters)
        for fmt, module in chosen:
            made.add(fmt)
            used.update((fmt, *getattr(module, "READS", ())))
        if tolerance_samples != 0:  # as the export will judge it: the process it makes
            analysed.add(made_process(design, [f for f, _ in chosen], settings))
    used.update(analysed | ({"tolerance"} if analysed else set()))
    what = ", ".join(sorted(made)) or "no file"
    if analysed:
        what += f"; tolerance analysis as {'/'.join(sorted(analysed))}"
    refuse_unused(settings, used, f"this export ({what}) reads "
                                  f"{', '.join(sorted(used - {'motion'} - made))} settings only")
    for key in tol:
        owner = key_process(key)
        if owner is not None and owner not in analysed:
            raise UsageError("--set", f"tolerance.{key}: is a {owner} error; the designs here "
                                      f"are analysed as {'/'.join(sorted(analysed))} (set "
                                      f"tolerance.process = \"{owner}\" to change that)")


def _resolved(paths, settings, exporters, tolerance_samples, allow_large):
    """The templates' paths, the checked settings and the format registry, before any design:
    one bad key or size fails them all alike."""
    from ..writers import EXPORTERS
    from ..templates import resolve_template

    if tolerance_samples is not None and tolerance_samples > MAX_SAMPLES and not allow_large:
        raise BoundsError("--tolerance-samples", "Monte Carlo samples", int(tolerance_samples),
                          MAX_SAMPLES, "fabkit --allow-large", option=True)
    exporters = dict(EXPORTERS if exporters is None else exporters)
    settings = check_export_settings(settings or {}, exporters)
    # a bare name is a template of the current folder or a bundled one, as on the command line
    return ([p if isinstance(p, Design) else resolve_template(p) for p in paths], settings,
            exporters)


def _write_index(outdir, results) -> None:
    """index.html from the cards the exports handed back (no page is read back); the folders
    of earlier runs are linked by name."""
    cards = [r.card for r in results if r is not None and r.folder and r.card is not None]
    if cards:
        write_index(outdir, cards)


def _loaded(paths, finished):
    """Load every template once, before any work: one that does not load, or that shares its
    name (its output folder) with an earlier one, is finished here with its error. Returns the
    indices to export, their designs, names and costs (edges, the measure of work)."""
    from ..templates import load_template

    owners: dict[str, object] = {}
    todo, designs, names, cost = [], {}, {}, {}
    for i, p in enumerate(paths):
        try:
            design = designs[i] = p if isinstance(p, Design) else load_template(p)
            name = design.name
            cost[i] = design.network.n_edges
        except FabkitError as exc:
            # a template that does not even load needs no worker: report it here
            finished(i, DesignResult(str(p), p.stem, message=str(exc), error_code=exc.code))
            continue
        if name in owners:
            finished(i, DesignResult(str(source_label(p)), name, error_code="template",
                                     message=f"{source_label(p)}: name: {name!r} is also the "
                                             f"name of {source_label(owners[name])}; each "
                                             "design needs its own name (its output folder)"))
            continue
        owners[name] = p
        names[i] = name
        todo.append(i)
    return todo, designs, names, cost


def export_many(paths, formats=None, outdir="out", settings=None, *, jobs=1, check=True,
                tolerance_samples=None, progress=None, isolate=True, exporters=None,
                previews=True, debug=False, wait=False, allow_large=False,
                timeout: float | None = DESIGN_TIMEOUT,
                silence: float = SILENCE) -> list[DesignResult]:
    """Export many templates; one :class:`DesignResult` per template, in input order.

    Parameters
    ----------
    paths : sequence of path, str or Design
        Template files, or bare names (``"super_stable"``): a template of that name in the
        current folder, else the bundled one, as ``fabkit export NAME`` takes them; or designs
        made in code (:meth:`fabkit.Design.from_network`).
    formats : list of str or None
        Formats to export (None: every format that applies to each design).
    outdir : path
        Output folder; each design goes to ``outdir/<name>/``.
    settings : dict, optional
        Fabrication setting overrides, nested by section.
    jobs : int
        Worker processes.
    check : bool
        Run the as-built check of the written files.
    tolerance_samples : int or None
        Monte Carlo builds (0: no tolerance analysis; None: the template's setting, else the
        analysis's default).
    progress : object, optional
        Told ``stage(name, stage)`` as a design starts a stage and ``finished(result)`` as it
        ends (the command line passes a :class:`~fabkit.commands.export.DesignProgress`).
    isolate : bool
        Export in fresh worker processes with a fixed hash seed (``PYTHONHASHSEED=0``), so that
        no library's set or dict ordering can make two runs differ; False with ``jobs=1`` runs
        in this process.
    exporters : dict of str to str, optional
        Format registry (default :data:`fabkit.writers.EXPORTERS`, as it is now).
    previews : bool
        Draw the preview pictures.
    debug : bool
        Let internal errors raise with their traceback; implies one design at a time in this
        process.
    wait : bool
        Wait for another export into the same folder to finish, instead of refusing.
    allow_large : bool
        Lift the size bounds.
    timeout : float or None
        Seconds one design may take in a worker process before it is stopped and failed
        (None: no limit).
    silence : float
        Seconds a worker may say nothing (not even its heartbeat) before it counts as stopped
        answering.

    Returns
    -------
    list of DesignResult

    Raises
    ------
    OutputError, LockedError
        The output folder cannot be created or written, or another export holds it.
    BoundsError
        ``tolerance_samples`` above :data:`MAX_SAMPLES` without ``allow_large``.
    Interrupted
        SIGINT or SIGTERM: every worker is stopped and no partial file is left.

    Notes
    -----
    Designs with the same name would share a folder: the later ones fail instead.
    """
    allow_large = allow_large or large_allowed()
    paths, settings, exporters = _resolved(paths, settings, exporters, tolerance_samples,
                                           allow_large)
    results: list[DesignResult | None] = [None] * len(paths)

    def finished(i, res):
        results[i] = res
        if progress:
            progress.finished(res)

    todo, designs, names, cost = _loaded(paths, finished)
    if not todo:
        return results  # type: ignore[return-value]
    _refuse_unused_settings(settings, [designs[i] for i in todo], formats, exporters,
                            tolerance_samples)
    outdir = prepare_outdir(outdir)
    kwargs = dict(check=check, tolerance_samples=tolerance_samples, exporters=exporters,
                  previews=previews, debug=debug, allow_large=allow_large)
    args = {i: (paths[i], formats, outdir, settings) for i in todo}
    with outdir, OutputLock(outdir, wait=wait):  # the folder held, and locked, to the end
        if (isolate or jobs > 1) and not debug:
            # largest designs first (edges as the measure of work): a long design started last
            # would run alone at the end while the other workers idle
            order = sorted(todo, key=lambda i: (-cost.get(i, 0), i))
            run_pool(order, args, names, kwargs, jobs, outdir, progress, finished,
                     timeout=timeout, silence=silence)
        else:
            stage_cb = progress.stage if progress else None
            for i in todo:
                finished(i, export_one(*args[i], progress=stage_cb, **kwargs))
        _write_index(outdir, results)
    return results  # type: ignore[return-value]


