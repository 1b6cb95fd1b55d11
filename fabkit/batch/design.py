"""One design, start to end: load, compute every file in memory, stage, check, report, swap in."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

from ..errors import (FabkitError, Interrupted, TemplateError, WriteError, internal_error_line)
from .folders import _staging_names, carry_over, check_replaceable, recover_folder, swap_in
from .formats import build_outputs, run_checks
from .results import DesignResult, FormatStatus, Outcome, Stage


# --- one design ------------------------------------------------------------------------------

def _report_dict(facts, formats, outcome, files) -> dict:
    import fabkit

    return {**facts, "fabkit_version": fabkit.__version__,
            "formats": {f: r.as_dict() for f, r in formats.items()},
            "errors": [], "ok": outcome is Outcome.OK, "outcome": outcome.value,
            "files": sorted(files), "report_version": 2}


def export_one(path, formats, outdir, settings, check=True, tolerance_samples=None,
               exporters=None, previews=True, debug=False, progress=None,
               allow_large=False, swap=True) -> DesignResult:
    """Export one template into ``outdir/<name>/``; never raises for a bad design.

    Parameters
    ----------
    path : path
        The template.
    formats, settings, tolerance_samples, exporters, previews, allow_large
        See :func:`build_outputs`.
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
    from ..export import write_atomic, write_outputs
    from ..errors import UnsafeNameError, brief
    from ..outputs import inside
    from ..report import report_json, report_markdown
    from ..report_html import write_design_report
    from ..templates import load_template, with_settings

    t0, cpu0 = time.perf_counter(), time.process_time()
    res = DesignResult(path=str(path), name=Path(path).stem)
    stage_dir = None
    current = [None, t0]

    def stage(s):
        now = time.perf_counter()
        if current[0] is not None:
            res.stages[str(current[0])] = res.stages.get(str(current[0]), 0.0) + now - current[1]
        current[:] = [s, now]
        if progress is not None and s is not None:
            progress(res.name, s)

    try:
        stage(Stage.LOAD)
        design = with_settings(load_template(path), settings)  # --set motion.to=...
        res.name = design.name
        outdir = Path(outdir)
        try:
            folder = inside(outdir, design.name)  # before the work, not after it
        except UnsafeNameError as exc:  # a Design made in code, not read from a template
            raise TemplateError(path, "name", f"{brief(design.name)} {exc.reason}") from None
        check_replaceable(folder)
        _staging_names(outdir, design.name)  # a link at .NAME.staging or .NAME.old: refused now
        files, fmts, facts = build_outputs(design, formats, settings, tolerance_samples,
                                           exporters, previews, stage=stage,
                                           allow_large=allow_large)
        stage(Stage.WRITE)
        recover_folder(outdir, design.name)
        stage_dir = _staging_names(outdir, design.name)[0]
        stage_dir.mkdir(parents=True)
        written = write_outputs(files, stage_dir)
        outcome = Outcome.OK
        if check:
            stage(Stage.CHECK)
            for chk in run_checks(written, design, settings):
                fmt = next((f for f, v in fmts.items() if chk.file in v.files), None)
                if fmt is None:
                    continue
                fmts[fmt].checks.append(chk)
                if not chk.ok:
                    fmts[fmt].status = FormatStatus.CHECK_FAILED
                    outcome = Outcome.CHECK_FAILED
        refused = [f"{f}: {v.detail}" for f, v in fmts.items()
                   if v.status is FormatStatus.REFUSED]
        if refused:  # asked for and not made: a failure with its reason, never "ok"
            outcome = Outcome.REFUSED
        names = [p.name for p in written] + ["report.json", "report.md", "report.html"]
        report = _report_dict(facts, fmts, outcome, names)
        report["errors"] = [f"{line} (format refused)" for line in refused]
        write_atomic(stage_dir / "report.md", report_markdown(report))
        write_atomic(stage_dir / "report.json", report_json(report))
        write_design_report(stage_dir, design)  # report.html: from report.json and the files
        carry_over(folder, stage_dir)
        if swap:
            swap_in(stage_dir, folder)
        else:
            res.staged = str(stage_dir)
        stage_dir = None
        res.outcome, res.formats, res.folder, res.files = outcome, fmts, str(folder), len(names)
        if outcome is Outcome.REFUSED:
            res.error = f"{path}: cannot produce {'; '.join(refused)}"
            res.error_code = "refused"
        elif outcome is Outcome.CHECK_FAILED:
            bad = [c.file for f in fmts.values() for c in f.checks if not c.ok]
            res.error = (f"{path}: as-built check failed for {', '.join(bad)} "
                         f"(see {folder / 'report.md'})")
            res.error_code = "check"
    except WriteError as exc:
        res.error = (f"{path}: cannot write the export to {outdir}: {exc.reason} "
                     f"({Path(exc.path).name}); nothing of it was written")
        res.error_code = "output"
    except FabkitError as exc:
        res.error, res.error_code = str(exc), exc.code
    except OSError as exc:
        res.error = f"{path}: cannot write the export to {outdir}: {exc.strerror or exc}"
        if getattr(exc, "filename", None):
            res.error += f" ({Path(exc.filename).name})"
        res.error_code = "output"
    except (Interrupted, KeyboardInterrupt):
        res.outcome, res.error, res.error_code = Outcome.INTERRUPTED, f"{path}: interrupted", \
            "interrupted"
        raise
    except Exception as exc:  # a bug must not stop the other designs; say where it happened
        if debug:
            raise
        res.error, res.error_code = f"{path}: {internal_error_line(exc)}", "internal"
    finally:
        if stage_dir is not None and stage_dir.exists():
            shutil.rmtree(stage_dir, ignore_errors=True)
        stage(None)
        res.seconds = time.perf_counter() - t0
        res.cpu_seconds = time.process_time() - cpu0
    return res
