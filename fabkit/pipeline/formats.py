"""The formats of one design: which apply, their files and reports, the as-built checks."""

from __future__ import annotations

from pathlib import Path

from ..check import CHECKERS
from ..errors import BoundsError, FabkitError, TemplateError, UnavailableError
from ..writers import get_exporter, skip_reason
from ..fab.plans import make_plan, PLANNERS, trace_needs
from ..motion import trace_motion
from ..report.text import design_facts
from ..settings.design import design_settings
from ..plots.viz import figure_png, motion_figure
from ..tolerance import made_process, stated_process, tolerance_spec
from .motion import map_figure, motion_report
from ..status import Status
from .results import CheckResult, FormatResult, Stage
from .stages import Artefacts, Plan


#: Files the batch writes itself into every design folder (besides the exporters' files).
RESERVED = ("report.json", "report.md", "report.html", "preview_motion.png", "preview_map.png",
            "preview_tolerance.png", "exports.json")


#: Largest number of Monte Carlo builds of the tolerance analysis without ``--allow-large``: each
#: build is one placement of the whole network, so 10 000 already take minutes for a chain.
MAX_SAMPLES = 10_000




# --- formats ---------------------------------------------------------------------------------

def _check_names(fmt, files, taken, path):
    for name in files:
        p = Path(name)
        if (not name or p.is_absolute() or len(p.parts) != 1 or name.startswith(".")):
            raise FabkitError(f"{path}: the {fmt} exporter produced a file named {name!r}, "
                              "which is not a plain name inside the design folder")
        if name in taken:
            raise FabkitError(f"{path}: the {fmt} exporter's file {name!r} clashes with "
                              f"{taken[name]}'s")
        taken[name] = fmt


def _not_applicable(fmt: str, module) -> str:
    """Why a format does not apply: the exporter's ``NOT_APPLICABLE``, else its rule."""
    why = getattr(module, "NOT_APPLICABLE", None)
    if why:
        return str(why)
    rule = (getattr(module.applies, "__doc__", None) or "").strip().splitlines()
    return f"{fmt} does not apply to this design" + (
        f" (the exporter's rule: {rule[0].rstrip('.')})" if rule else "")


def choose_formats(design, formats, exporters) -> tuple[list, dict]:
    """The format modules to run for a design, and the FormatResults of those not run.

    The one place that decides which formats a design gets: asked for (``formats``) or every
    registered one that ``applies(design)`` and that the template does not opt out of. A format
    asked for by name that cannot be produced is :attr:`~fabkit.status.Status.REFUSED` with the
    reason; without ``formats`` those that do not apply are listed as such.
    """
    asked = formats is not None
    chosen, skipped = [], {}
    for fmt in (formats if asked else list(exporters)):
        try:
            module = get_exporter(fmt, exporters)
        except UnavailableError as exc:
            skipped[fmt] = FormatResult(fmt, Status.REFUSED if asked
                                        else Status.NOT_AVAILABLE, message=str(exc))
            continue
        applies = getattr(module, "applies", None)
        if applies is not None and not applies(design):
            skipped[fmt] = (FormatResult(fmt, Status.REFUSED,
                                         message=_not_applicable(fmt, module)) if asked
                            else FormatResult(fmt, Status.DOES_NOT_APPLY))
            continue
        reason = skip_reason(design, fmt)
        if reason is not None:  # the template opts out of this format and says why
            skipped[fmt] = FormatResult(fmt, Status.REFUSED if asked
                                        else Status.SKIPPED,
                                        message=f"the template opts out: {reason}" if asked
                                        else reason)
            continue
        chosen.append((fmt, module))
    return chosen, skipped


def _tolerance_spec(design, settings, tolerance_samples, allow_large, process=None):
    extra = {} if tolerance_samples is None else {"samples": tolerance_samples}
    if process is not None and stated_process(design, settings) is None:
        extra["process"] = process  # the process whose files are made judges them
    spec = tolerance_spec(design, settings, **extra)
    if spec.samples > MAX_SAMPLES and not allow_large:
        where = (f"{design.path}: fabrication.tolerance.samples" if tolerance_samples is None
                 else "--tolerance-samples")
        raise BoundsError(where, "Monte Carlo samples", int(spec.samples), MAX_SAMPLES,
                          "fabkit --allow-large", option=tolerance_samples is not None)
    return spec


def plan_design(design, formats, settings, motion, tolerance_samples=None, exporters=None, *,
                allow_large=False, kept=()) -> Plan:
    """The Plan stage: the formats a design gets, and the process its export is made by.

    Parameters
    ----------
    design : Design
    formats : list of str or None
        Formats to export; None: every format whose module says it ``applies(design)``.
    settings : DesignSettings
        The design's settings, resolved once before the Motion stage
        (:func:`fabkit.settings.design.design_settings`).
    motion : TracedMotion
        The Motion stage's result (no tolerance analysis without a traced motion).
    tolerance_samples : int or None
        Monte Carlo builds of the tolerance analysis (0 skips it; None: the template's setting,
        else the analysis's default).
    exporters : dict of str to str, optional
        Format registry (default :data:`fabkit.writers.EXPORTERS`).
    allow_large : bool
        Lift the bound on Monte Carlo samples.
    kept : iterable of str
        Formats an earlier export left in the design's folder that stay there: the folder's
        process is decided by them too (one report covers every format in the folder).

    Returns
    -------
    Plan

    Raises
    ------
    FabkitError
        Bad tolerance settings, too many samples.
    """
    from ..writers import EXPORTERS

    settings = design_settings(design, settings)  # resolved already: handed back as they are
    exporters = dict(EXPORTERS if exporters is None else exporters)
    chosen, skipped = choose_formats(design, formats, exporters)
    process = made_process(design, [f for f, _ in chosen] + list(kept), settings)
    spec = None
    if motion.traced and tolerance_samples != 0:
        # settings and sizes are checked before any heavy work: a bad value fails at once
        spec = _tolerance_spec(design, settings, tolerance_samples, allow_large, process)
    return Plan(tuple(chosen), skipped, process, spec)


def _accepts_motion(function, name: str = "motion") -> bool:
    """Whether an exporter or checker takes the traced motion (``motion=``, or the keyword
    ``name``): one of one's own written for ``(design, settings)`` is called that way, and
    traces what it needs itself."""
    import inspect

    try:
        params = inspect.signature(function).parameters
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is p.VAR_KEYWORD for p in params.values())


def _write_format(module, design, settings, motion, plans: dict, verdict_later: bool):
    """One format's files: a writer of a process's plan (``PROCESS`` and ``write``) gets the
    plan built once for every format of that process, from the resolved settings (and, when
    ``verdict_later`` and it has ``with_verdict``, ``verdict_pages=False``: the files that
    carry the verdict are made once, judged, by :func:`fabkit.pipeline.design.carry_verdict`);
    an exporter of one's own (``export_design``) gets the design, the overrides as a dict (its
    contract) and, when it takes it, the motion."""
    process = getattr(module, "PROCESS", None)
    if process in PLANNERS and callable(getattr(module, "write", None)):
        if process not in plans:
            plans[process] = make_plan(process, design, settings, motion)
        if verdict_later and callable(getattr(module, "with_verdict", None)):
            return module.write(plans[process], verdict_pages=False)
        return module.write(plans[process])
    overrides = settings.overrides_dict()
    if _accepts_motion(module.export_design):
        return module.export_design(design, overrides, motion=motion)
    return module.export_design(design, overrides)


def make_artefacts(design, plan: Plan, settings, motion, previews=True, *,
                   stage=None, verdict_later: bool = False) -> Artefacts:
    """The Artefacts stage: every file of the design's folder in memory (nothing is written).

    Every exporter, the previews and the tolerance analysis take the one traced motion; none
    traces it again.

    Parameters
    ----------
    design : Design
    plan : Plan
    settings : DesignSettings
    motion : TracedMotion
    previews : bool
        Draw preview_motion.png, preview_map.png and preview_tolerance.png.
    stage : callable, optional
        Called with each :class:`Stage` as it starts (progress and timing).
    verdict_later : bool
        The files that carry the verdict stand empty, to be made once the design is judged
        (:func:`fabkit.pipeline.design.carry_verdict`, which ``fabkit export`` runs); False:
        they are complete, headed "not judged".

    Returns
    -------
    Artefacts

    Raises
    ------
    FabkitError
        An exporter's refusal (one line), or the motion's typed failure.
    """
    stage = stage or (lambda s: None)
    settings = design_settings(design, settings)  # resolved already: handed back as they are
    path = design.path or design.name
    files: dict[str, bytes] = {}
    singular = motion.error if motion.status is Status.SINGULAR_START else None
    if not motion.traced and motion.status not in (Status.NO_TARGET,
                                                   Status.SINGULAR_START):
        motion.require()  # the one typed failure: nothing is exported
    results = dict(plan.skipped)
    taken = {name: "export" for name in RESERVED}
    stage(Stage.EXPORT)
    plans: dict = {}  # one plan per process, for all of its formats
    for fmt, module in plan.chosen:
        try:
            result = _write_format(module, design, settings, motion, plans, verdict_later)
        except FabkitError as exc:
            if singular is not None:
                raise singular from None  # the root cause, not its consequence in this format
            if isinstance(exc, TemplateError):
                raise  # already names the file and the key
            raise FabkitError(f"{path}: {fmt} export: {exc}") from None
        if not isinstance(result.files, dict) or not all(
                isinstance(v, (bytes, bytearray)) for v in result.files.values()):
            raise FabkitError(f"{path}: the {fmt} exporter returned no file bytes")
        _check_names(fmt, result.files, taken, path)
        files.update({k: bytes(v) for k, v in result.files.items()})
        results[fmt] = FormatResult(fmt, Status.EXPORTED, sorted(result.files),
                                    result.report)
    if singular is not None and not any(v.status.produced for v in results.values()):
        raise singular
    traj = motion.trajectory if motion.traced else None
    if traj is not None and previews:
        stage(Stage.PREVIEWS)
        files["preview_motion.png"] = figure_png(motion_figure(traj, title=design.name))
        fig = map_figure(traj, design)
        if fig is not None:
            files["preview_map.png"] = figure_png(fig)
    tol = None
    if plan.tolerance is not None:
        from ..tolerance import analyse_tolerance, tolerance_figure

        stage(Stage.TOLERANCE)
        # the traced sweep is reused (the nominal motion is exact to share); every build is
        # placed afresh inside the analysis
        tol = analyse_tolerance(design, plan.tolerance, trajectory=traj)
        if previews:
            files["preview_tolerance.png"] = figure_png(tolerance_figure(tol, title=design.name))
    # pictures for report.md: ours, the exporters' PNGs, and SVGs (crease patterns, sheets)
    shown = tuple(sorted(n for n in files if n.endswith((".png", ".svg"))))
    return Artefacts(files, results, tol, shown, plans)


def motion_facts(motion, formats) -> dict | None:
    """The ``motion`` part of report.json from the Motion stage's result."""
    if motion.status is Status.SINGULAR_START:
        return {"status": Status.SINGULAR_START.value, "message": motion.error.reason,
                "resolved_by": sorted(f for f, v in formats.items() if v.status.produced)}
    if not motion.traced:
        return None
    out = motion_report(motion.trajectory)
    if motion.spread is not None:
        out["spread"] = motion.spread.as_dict()
    if motion.ends is not None:
        out["status"] = str(motion.status)
        out["ends"] = motion.ends.as_dict()
        if motion.status is Status.ENDS_MISSED:
            out["message"] = motion.message
    return out


def build_outputs(design, formats, settings, tolerance_samples=None, exporters=None,
                  previews=True, *, stage=None, allow_large=False) -> tuple[dict, dict, dict]:
    """Everything a design's folder will hold, computed in memory (nothing is written): the
    Motion, Plan and Artefacts stages in one call.

    Parameters
    ----------
    design : Design
    formats, settings, tolerance_samples, exporters, allow_large
        See :func:`plan_design`.
    previews, stage
        See :func:`make_artefacts`.

    Returns
    -------
    files : dict of str to bytes
        Every exporter's files plus the preview PNGs (reports excluded: they come after the check).
    results : dict of str to FormatResult
    facts : dict
        The rest of report.json: ``design``, ``motion``, ``tolerance``, ``previews``.

    Raises
    ------
    FabkitError
        Bad template content, impossible motion, or an exporter's refusal (one line).
    """
    from ..writers import EXPORTERS

    stage = stage or (lambda s: None)
    stage(Stage.MOTION)
    settings = design_settings(design, settings)  # once: every later stage reads these
    registry = dict(EXPORTERS if exporters is None else exporters)
    motion = traced_for(design, choose_formats(design, formats, registry)[0], settings)
    plan = plan_design(design, formats, settings, motion, tolerance_samples, exporters,
                       allow_large=allow_large)
    art = make_artefacts(design, plan, settings, motion, previews, stage=stage)
    facts = {"design": design_facts(design), "previews": list(art.previews)}
    mo = motion_facts(motion, art.formats)
    if mo is not None:
        facts["motion"] = mo
    if art.tolerance is not None:
        facts["tolerance"] = art.tolerance.as_dict()
    return art.files, art.formats, facts


def traced_for(design, chosen, settings):
    """The Motion stage: the design's motion, traced once, as densely as the plans of the
    chosen formats need it (:func:`fabkit.fab.plans.trace_needs`), so no plan traces again."""
    needs = trace_needs({getattr(module, "PROCESS", None) for _, module in chosen}, design,
                        settings)
    return trace_motion(design, **needs)


def _load_checker(suffix: str):
    import importlib

    try:
        return importlib.import_module(CHECKERS[suffix])
    except ImportError as exc:
        raise UnavailableError(f"the .{suffix} check", str(exc)) from None


def run_checks(paths, design, settings, motion=None, folder=None) -> list[CheckResult]:
    """As-built check of every written file that has a checker.

    The network is re-derived from the files (each checker reads them back); nothing of the
    export's in-memory plan is shared with the check. A checker whose result lists ``files``
    has read those too (the sheets of one laser export): they are not checked a second time.

    Parameters
    ----------
    paths : list of Path
        The written files.
    design : Design
    settings : DesignSettings
        The design's settings, resolved once (a checker of one's own may be handed them too).
    motion : TracedMotion, optional
        The design's motion, traced once: handed to every checker that takes it (the design's
        side of the comparison is not traced again; the network rebuilt from the files is).
    folder : OutputFolder, optional
        The held folder the files were written into (the staging folder): every checker that
        takes it reads the files through it, never by a path looked up again.

    Returns
    -------
    list of CheckResult
    """
    results, covered = [], set()
    for p in paths:
        suffix = p.suffix.lower().lstrip(".")
        if suffix not in CHECKERS or p.name in covered:
            continue
        try:
            module = _load_checker(suffix)
        except UnavailableError:
            continue  # that check is not installed: nothing to say about this file
        extra = {}
        if motion is not None and _accepts_motion(module.check_file):
            extra["motion"] = motion
        if folder is not None and _accepts_motion(module.check_file, "folder"):
            extra["folder"] = folder
        try:
            res = dict(module.check_file(p, design=design, settings=settings, **extra))
        except FabkitError as exc:
            results.append(CheckResult(p.name, False, [], str(exc)))
            continue
        covered.update(Path(str(f)).name for f in res.get("files", []) or [])
        extra = {k: v for k, v in res.items() if k not in ("ok", "checks", "error", "file")}
        results.append(CheckResult(p.name, bool(res.get("ok")), list(res.get("checks", [])),
                                   str(res.get("error", "") or ""), extra))
    return results
