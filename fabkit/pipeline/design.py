"""One design, start to end, through the typed stages (:mod:`fabkit.pipeline.stages`): load, trace
the motion once, plan, compute every file in memory, stage, check, judge, report, swap in."""

from __future__ import annotations

import time
from pathlib import Path

from ..errors import (brief, FabkitError, FolderChangedError, internal_error_line, Interrupted,
                      TemplateError, UnsafeNameError, WriteError)
from ..io.outputs import check_name, OutputFolder
from ..report.html import design_html, index_card, motion_frames
from ..report.text import design_facts, report_json, report_markdown
from ..settings.design import design_settings
from ..templates import Design
from .folders import check_replaceable, new_staging, recover_folder, staging_folders, swap_in
from .formats import (choose_formats, make_artefacts, motion_facts, plan_design, RESERVED,
                      run_checks, traced_for)
from .manifest import (design_digest, MANIFEST, MAX_KEPT_BYTES, new_manifest, read_manifest,
                       sort_earlier)
from ..status import Status
from .results import DesignResult, FormatResult, Stage
from .stages import Artefacts, Checks, DesignReport, judge_design


def source_label(source):
    """What names a design in messages and results: its template file, or ``<name>`` for a
    design made in code that was never saved."""
    if isinstance(source, Design):
        return source.path if source.path is not None else f"<{source.name}>"
    return source


# --- one design ------------------------------------------------------------------------------

def report_dict(rep: DesignReport) -> dict:
    """report.json of a design: its typed results as data (keys listed in docs/batch.md)."""
    import fabkit

    out = {"design": rep.facts, "fabkit_version": fabkit.__version__,
           "formats": {f: r.as_dict() for f, r in rep.formats.items()},
           "errors": list(rep.errors), "ok": rep.outcome is Status.OK,
           "outcome": rep.outcome.value, "files": sorted(rep.names), "report_version": 4,
           "previews": list(rep.artefacts.previews), "process": rep.process,
           "verdict": rep.verdict.as_dict(),
           "exports": {f: {"export": o.export, "when": o.when, "settings": o.settings,
                           "fabkit_version": o.fabkit_version, "files": list(o.files),
                           "kept": f in rep.kept}
                       for f, o in sorted(rep.origins.items())},
           "removed": list(rep.removed)}
    mo = motion_facts(rep.motion, rep.formats) if rep.motion is not None else None
    if mo is not None:
        out["motion"] = mo
    if rep.tolerance is not None:
        out["tolerance"] = rep.tolerance.as_dict()
    return out


def keep_formats(art: Artefacts, folder: OutputFolder, kept: dict, order=()) -> Artefacts:
    """The Artefacts stage with the formats an earlier export left in ``folder`` added: their
    files as they are (read back as data, to be written again, checked again as built and shown
    in the report) and their results from the folder's record (:mod:`fabkit.pipeline.manifest`).
    A kept file that this export also makes is this export's. The formats follow ``order``
    (the registry's)."""
    files, formats = dict(art.files), dict(art.formats)
    for fmt, origin in sorted(kept.items()):
        for name in origin.files:
            if name not in files:
                files[name] = folder.read_bytes(name, MAX_KEPT_BYTES)  # never through a link
        formats[fmt] = FormatResult(fmt, Status.EXPORTED, sorted(origin.files),
                                    dict(origin.report), "")
    rank = {f: i for i, f in enumerate(order)}
    formats = {f: formats[f] for f in sorted(formats, key=lambda f: (rank.get(f, len(rank)), f))}
    shown = tuple(sorted(n for n in files if n.endswith((".png", ".svg"))))
    return Artefacts(files, formats, art.tolerance, shown, art.plans)


def export_one(path, formats, outdir, settings, check=True, tolerance_samples=None,
               exporters=None, previews=True, debug=False, progress=None,
               allow_large=False, swap=True) -> DesignResult:
    """Export one template into ``outdir/<name>/``; never raises for a bad design.

    Parameters
    ----------
    path : path or Design
        The template, or a design made in code (:meth:`fabkit.Design.from_network`).
    formats, settings, tolerance_samples, exporters, previews, allow_large
        See :func:`fabkit.pipeline.formats.build_outputs`.
    outdir : path
    check : bool
        Run the as-built checks.
    debug : bool
        Let internal errors raise with their traceback.
    progress : callable, optional
        ``progress(name, stage)`` as each stage starts.
    swap : bool
        Swap the finished staging folder in place of ``outdir/<name>``. False leaves it complete
        under the name in :attr:`DesignResult.staged` for the caller to swap in (a worker
        process does so: the parent swaps only what it has heard of, so a worker that dies
        at any moment leaves no new file).

    Returns
    -------
    DesignResult
    """
    t0, cpu0 = time.perf_counter(), time.process_time()
    res = DesignResult(path=str(source_label(path)),
                       name=path.name if isinstance(path, Design) else Path(path).stem)
    clock = _StageClock(res, progress, t0)
    staged = [None]  # the staging folder's name while it holds an unfinished export
    outdir = OutputFolder.open(outdir, "outdir")  # one handle on the folder from here on
    try:
        _export(path, formats, outdir, settings, res, clock, staged, check=check,
                tolerance_samples=tolerance_samples, exporters=exporters, previews=previews,
                allow_large=allow_large, swap=swap)
    except (Interrupted, KeyboardInterrupt, FolderChangedError) as exc:
        # a signal, or a folder swapped under the export: the whole run stops
        if not isinstance(exc, FolderChangedError):
            res.status, res.message, res.error_code = Status.INTERRUPTED, \
                f"{res.path}: interrupted", "interrupted"
        raise
    except Exception as exc:  # a bug must not stop the other designs; say where it happened
        if debug and not isinstance(exc, (FabkitError, OSError)):
            raise
        res.message, res.error_code = _failure(exc, res.path, outdir)
    finally:
        if staged[0] is not None:  # in the folder held, whatever its path names now
            try:
                outdir.remove(staged[0])
            except OSError:
                pass
        clock(None)
        res.seconds = time.perf_counter() - t0
        res.cpu_seconds = time.process_time() - cpu0
    return res


class _StageClock:
    """Times the stages of one design's export into ``res.stages`` and tells ``progress``."""

    def __init__(self, res: DesignResult, progress, t0: float):
        self.res, self.progress, self.current = res, progress, [None, t0]

    def __call__(self, s) -> None:
        now = time.perf_counter()
        name, since = self.current
        if name is not None:
            self.res.stages[str(name)] = self.res.stages.get(str(name), 0.0) + now - since
        self.current = [s, now]
        if self.progress is not None and s is not None:
            self.progress(self.res.name, s)


def _failure(exc: Exception, path, outdir) -> tuple[str, str]:
    """(error line, error code) of an export that stopped with ``exc``."""
    if isinstance(exc, WriteError):
        return (f"{path}: cannot write the export to {outdir}: {exc.reason} "
                f"({_destination(exc.path, outdir)}); nothing of it was written"), "output"
    if isinstance(exc, FabkitError):
        return str(exc), exc.code
    if isinstance(exc, OSError):
        line = f"{path}: cannot write the export to {outdir}: {exc.strerror or exc}"
        if getattr(exc, "filename", None):
            line += f" ({_destination(exc.filename, outdir)})"
        return line, "output"
    return f"{path}: {internal_error_line(exc)}", "internal"


def _destination(written, outdir) -> Path:
    """The path a file being written will have once in place: a file of the staging folder
    ``.NAME.staging/`` is named in the design's folder ``NAME/`` (the staging folder is removed
    with the failure), any other as it is."""
    written = Path(written)
    try:
        parts = written.relative_to(outdir.path).parts
    except ValueError:
        return written
    if parts and parts[0].startswith(".") and parts[0].endswith(".staging"):
        parts = (parts[0][1:-len(".staging")], *parts[1:])
    return outdir.path.joinpath(*parts)


def _load(path, settings, outdir, formats, exporters):
    """The Load stage: the design with ``--set`` applied, its folder, and what an earlier export
    left there (formats still current stay, stale ones go)."""
    from ..writers import EXPORTERS
    from ..templates import load_template, with_settings

    loaded = path if isinstance(path, Design) else load_template(path)
    # what the files are made from, as the template says (--set is compared on its own)
    digest = design_digest(loaded)
    design = with_settings(loaded, settings)  # --set motion.to=...
    try:
        check_name(design.name)  # before the work, not after it
    except UnsafeNameError as exc:  # a Design made in code, not read from a template
        raise TemplateError(source_label(path), "name",
                            f"{brief(design.name)} {exc.reason}") from None
    check_replaceable(outdir, design.name)
    staging_folders(outdir, design.name)  # a link at .NAME.staging or .NAME.old: refused now
    # a folder caught between the two renames of a killed run is put back first: its record
    # says what it holds
    recover_folder(outdir, design.name)
    folder = (outdir.folder(design.name, create=False) if outdir.is_folder(design.name)
              else None)
    earlier = read_manifest(folder) if folder is not None else None
    registry = dict(EXPORTERS if exporters is None else exporters)
    chosen = choose_formats(design, formats, registry)[0]
    kept, removed = sort_earlier(folder, earlier, design, settings, [f for f, _ in chosen],
                                 registry, digest)
    return design, digest, folder, earlier, registry, kept, removed, chosen


def _check_written(written, design, settings, motion, fmts, folder
                   ) -> tuple[Status, Checks]:
    """The Checks stage: every written file checked as built (read through ``folder``, the
    staging folder held), each result on its format."""
    outcome, by_format = Status.OK, {}
    for chk in run_checks(written, design, settings, motion, folder):
        fmt = next((f for f, v in fmts.items() if chk.file in v.files), None)
        if fmt is None:
            continue
        fmts[fmt].checks.append(chk)
        by_format.setdefault(fmt, []).append(chk)
        if not chk.ok:
            fmts[fmt].status = Status.CHECK_FAILED
            outcome = Status.CHECK_FAILED
    return outcome, Checks(by_format)


def carry_verdict(stage_dir: OutputFolder, plan, art: Artefacts, verdict) -> list[str]:
    """The report stage's one change to the files made: those that carry the verdict (a laser
    kit's guide and bill of materials, left empty by its writer: see
    :func:`fabkit.pipeline.formats.make_artefacts`) are made from their process's plan, now that
    the checks and the tolerance analysis have judged the design, and written over the staged
    ones. A format whose writer has no ``with_verdict`` keeps its files as made; a format kept
    from an earlier export (no plan made now) too. Returns the names written again.

    Parameters
    ----------
    stage_dir : OutputFolder
        The staging folder, held (the files are already written there).
    plan : Plan
        The Plan stage (the formats made and their writers).
    art : Artefacts
        Its files and format results are updated in place.
    verdict : Verdict

    Returns
    -------
    list of str
    """
    again = []
    for fmt, module in plan.chosen:
        hook = getattr(module, "with_verdict", None)
        made = art.plans.get(getattr(module, "PROCESS", None))
        result = art.formats.get(fmt)
        if hook is None or made is None or result is None or not result.status.produced:
            continue
        files, report = hook(made, list(result.files), verdict.as_dict())
        for name, data in files.items():
            stage_dir.write(name, data)
            art.files[name] = data
            again.append(name)
        more = report.pop("warnings", None)  # added to the writer's warnings, not over them
        result.report.update(report)
        if more:
            result.report["warnings"] = [*(result.report.get("warnings") or []), *more]
    return again


def _write_reports(stage_dir: OutputFolder, rep: DesignReport, art: Artefacts, written,
                   record, motion) -> dict:
    """report.md, report.json and report.html of a design into its staging folder, rendered
    from the typed results (none is read back); returns the design's card for index.html."""
    md, js = report_markdown(rep), report_json(report_dict(rep))
    stage_dir.write("report.md", md)
    stage_dir.write("report.json", js)
    traj = motion.trajectory if motion.traced else None
    frames = motion_frames(rep.design, traj, rep.formats, art.plans)
    listing = {p.name: len(art.files[p.name]) for p in written}
    listing.update({"report.md": len(md), "report.json": len(js),
                    MANIFEST: len(record.to_bytes())})
    stage_dir.write("report.html", design_html(rep, art.files, listing, frames))
    return index_card(rep, rep.design.name, frames)


def _export(path, formats, outdir, settings, res: DesignResult, clock, staged, *, check,
            tolerance_samples, exporters, previews, allow_large, swap) -> None:
    """The stages of :func:`export_one`, filling ``res``; raises what stops them."""
    from ..writers import write_outputs

    clock(Stage.LOAD)
    design, digest, folder, earlier, registry, kept, removed, chosen = _load(
        path, settings, outdir, formats, exporters)
    res.name = design.name
    clock(Stage.MOTION)
    # the settings resolved once, before the motion's trace asks what the plans need of it:
    # every later stage reads these (the raw overrides stay for the folder's record)
    resolved = design_settings(design, settings)
    motion = traced_for(design, chosen, resolved)  # once: every later stage reads this one
    plan = plan_design(design, formats, resolved, motion, tolerance_samples, exporters,
                       allow_large=allow_large, kept=kept)
    # the guide and bill of materials are drawn once, judged, by carry_verdict
    art = make_artefacts(design, plan, resolved, motion, previews, stage=clock, verdict_later=True)
    if kept:
        art = keep_formats(art, folder, kept, list(registry))
    fmts = art.formats
    clock(Stage.WRITE)
    staged[0], stage_dir = new_staging(outdir, design.name)
    written = write_outputs(art.files, stage_dir)
    outcome, checks = Status.OK, Checks({})
    if check:
        clock(Stage.CHECK)
        outcome, checks = _check_written(written, design, resolved, motion, fmts, stage_dir)
    refused = [f"{f}: {v.message}" for f, v in fmts.items() if v.status is Status.REFUSED]
    if refused:  # asked for and not made: a failure with its reason, never "ok"
        outcome = Status.REFUSED
    verdict = judge_design(outcome, fmts, checks, motion, art.tolerance, refused)
    carry_verdict(stage_dir, plan, art, verdict)  # before the record: it keeps the reports
    record = new_manifest(design.name, earlier, kept, fmts, design, settings, registry, digest,
                          time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()))
    stage_dir.write(MANIFEST, record.to_bytes())
    names = [p.name for p in written] + [MANIFEST, "report.json", "report.md", "report.html"]
    rep = DesignReport(design, design_facts(design), motion, plan, art, checks, verdict,
                       outcome, tuple(f"{line} (format refused)" for line in refused),
                       tuple(names), record.formats, removed)
    res.card = _write_reports(stage_dir, rep, art, written, record, motion)
    res.level, res.headline = str(verdict.status), verdict.headline
    # files of other commands stay; those of earlier exports are ours to keep or drop
    ours = None if earlier is None else (
        {f for o in earlier.formats.values() for f in o.files} | set(RESERVED) | {MANIFEST})
    stage_dir.close()
    if swap:
        swap_in(outdir, staged[0], design.name, ours)
    else:
        res.staged, res.earlier_files = str(stage_dir.path), (
            None if ours is None else tuple(sorted(ours)))
    staged[0] = None
    folder = outdir.path / design.name
    res.status, res.formats, res.folder, res.files = outcome, fmts, str(folder), len(names)
    res.notes = [f"{fmt} kept from {kept[fmt].line()}" for fmt in sorted(kept)] + list(removed)
    if outcome is Status.REFUSED:
        res.message, res.error_code = f"{res.path}: cannot produce {'; '.join(refused)}", "refused"
    elif outcome is Status.CHECK_FAILED:
        bad = [c.file for f in fmts.values() for c in f.checks if not c.ok]
        res.message = (f"{res.path}: as-built check failed for {', '.join(bad)} "
                     f"(see {folder / 'report.md'})")
        res.error_code = "check"
