"""The formats of one design: which apply, their files and reports, the as-built checks."""

from __future__ import annotations

from pathlib import Path

from ..errors import (BoundsError, FabkitError, SingularStartError, TemplateError, UnavailableError)
from .motion import map_figure, motion_report, traced_motion
from .results import CheckResult, FormatResult, FormatStatus, Stage


#: Files the batch writes itself into every design folder (besides the exporters' files).
RESERVED = ("report.json", "report.md", "report.html", "preview_motion.png", "preview_map.png",
            "preview_tolerance.png")


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


def load_exporter(fmt: str, exporters: dict):
    """The module of a format from a registry (name → module path).

    Raises
    ------
    UnavailableError
        The module cannot be imported (a missing optional dependency).
    FabkitError
        The format is not in the registry.
    """
    import importlib

    if fmt not in exporters:
        raise FabkitError(f"unknown export format {fmt!r}; valid: {', '.join(exporters)}")
    try:
        return importlib.import_module(exporters[fmt])
    except ImportError as exc:
        raise UnavailableError(f"export format {fmt!r}", str(exc)) from None


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
    asked for by name that cannot be produced is :attr:`FormatStatus.REFUSED` with the reason;
    without ``formats`` those that do not apply are listed as such.
    """
    from ..export import skip_reason

    asked = formats is not None
    chosen, skipped = [], {}
    for fmt in (formats if asked else list(exporters)):
        try:
            module = load_exporter(fmt, exporters)
        except UnavailableError as exc:
            skipped[fmt] = FormatResult(fmt, FormatStatus.REFUSED if asked
                                        else FormatStatus.NOT_AVAILABLE, detail=str(exc))
            continue
        applies = getattr(module, "applies", None)
        if applies is not None and not applies(design):
            skipped[fmt] = (FormatResult(fmt, FormatStatus.REFUSED,
                                         detail=_not_applicable(fmt, module)) if asked
                            else FormatResult(fmt, FormatStatus.DOES_NOT_APPLY))
            continue
        reason = skip_reason(design, fmt)
        if reason is not None:  # the template opts out of this format and says why
            skipped[fmt] = FormatResult(fmt, FormatStatus.REFUSED if asked
                                        else FormatStatus.SKIPPED,
                                        detail=f"the template opts out: {reason}" if asked
                                        else reason)
            continue
        chosen.append((fmt, module))
    return chosen, skipped


def _tolerance_spec(design, settings, tolerance_samples, allow_large):
    from ..tolerance import tolerance_spec

    extra = {} if tolerance_samples is None else {"samples": tolerance_samples}
    spec = tolerance_spec(design, settings, **extra)
    if spec.samples > MAX_SAMPLES and not allow_large:
        where = (f"{design.path}: fabrication.tolerance.samples" if tolerance_samples is None
                 else "--tolerance-samples")
        raise BoundsError(where, "Monte Carlo samples", int(spec.samples), MAX_SAMPLES,
                          "fabkit --allow-large", option=tolerance_samples is not None)
    return spec


def build_outputs(design, formats, settings, tolerance_samples=None, exporters=None,
                  previews=True, *, stage=None, allow_large=False) -> tuple[dict, dict, dict]:
    """Everything a design's folder will hold, computed in memory (nothing is written).

    Parameters
    ----------
    design : Design
    formats : list of str or None
        Formats to export; None: every format whose module says it ``applies(design)``.
    settings : dict
        Command-line overrides of the fabrication settings (nested dict).
    tolerance_samples : int or None
        Monte Carlo builds of the tolerance analysis (0 skips it; None: the template's setting,
        else the analysis's default).
    exporters : dict of str to str, optional
        Format registry (default :data:`fabkit.export.EXPORTERS`).
    previews : bool
        Draw preview_motion.png, preview_map.png and preview_tolerance.png.
    stage : callable, optional
        Called with each :class:`Stage` as it starts (progress and timing).
    allow_large : bool
        Lift the bound on Monte Carlo samples.

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
    from ..export import EXPORTERS
    from ..report import design_facts
    from ..viz import figure_png, motion_figure

    stage = stage or (lambda s: None)
    path = design.path or design.name
    facts = {"design": design_facts(design), "previews": []}
    files: dict[str, bytes] = {}
    singular = None
    stage(Stage.MOTION)
    try:
        traj = traced_motion(design, allow_singular_start=True)
    except SingularStartError as exc:
        # e.g. a flat origami sheet: an exporter that chooses the branch (by its mountain/valley
        # assignment) may still export it; with none, the design fails with this error
        traj, singular = None, exc
    spec = None
    if traj is not None and tolerance_samples != 0:
        # settings and sizes are checked before any heavy work: a bad value fails at once
        spec = _tolerance_spec(design, settings, tolerance_samples, allow_large)

    exporters = dict(EXPORTERS if exporters is None else exporters)
    chosen, results = choose_formats(design, formats, exporters)
    taken = {name: "export" for name in RESERVED}
    stage(Stage.EXPORT)
    for fmt, module in chosen:
        try:
            result = module.export_design(design, settings)
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
        results[fmt] = FormatResult(fmt, FormatStatus.EXPORTED, sorted(result.files),
                                    result.report)

    if singular is not None:
        resolved = sorted(f for f, v in results.items() if v.status.produced)
        if not resolved:
            raise singular
        facts["motion"] = {"status": "singular start", "message": singular.reason,
                           "resolved_by": resolved}
    if traj is not None:
        facts["motion"] = motion_report(traj)
        if previews:
            stage(Stage.PREVIEWS)
            files["preview_motion.png"] = figure_png(motion_figure(traj, title=design.name))
            fig = map_figure(traj, design)
            if fig is not None:
                files["preview_map.png"] = figure_png(fig)
    if spec is not None:
        from ..tolerance import analyse_tolerance, tolerance_figure

        stage(Stage.TOLERANCE)
        # the traced sweep is reused (the nominal motion is exact to share); every build is
        # placed afresh inside the analysis
        tol = analyse_tolerance(design, spec, trajectory=traj)
        facts["tolerance"] = tol.as_dict()
        if previews:
            files["preview_tolerance.png"] = figure_png(tolerance_figure(tol, title=design.name))
    # pictures for report.md: ours, the exporters' PNGs, and SVGs (crease patterns, sheets)
    facts["previews"] = sorted(n for n in files if n.endswith((".png", ".svg")))
    return files, results, facts


def _load_checker(suffix: str):
    import importlib

    from ..check import CHECKERS

    try:
        return importlib.import_module(CHECKERS[suffix])
    except ImportError as exc:
        raise UnavailableError(f"the .{suffix} check", str(exc)) from None


def run_checks(paths, design, settings) -> list[CheckResult]:
    """As-built check of every written file that has a checker.

    The network is re-derived from the files (each checker reads them back); nothing of the
    export's in-memory plan is shared with the check. A checker whose result lists ``files``
    has read those too (the sheets of one laser export): they are not checked a second time.

    Parameters
    ----------
    paths : list of Path
        The written files.
    design : Design
    settings : dict

    Returns
    -------
    list of CheckResult
    """
    from ..check import CHECKERS

    results, covered = [], set()
    for p in paths:
        suffix = p.suffix.lower().lstrip(".")
        if suffix not in CHECKERS or p.name in covered:
            continue
        try:
            module = _load_checker(suffix)
        except UnavailableError:
            continue  # that check is not installed: nothing to say about this file
        try:
            res = dict(module.check_file(p, design=design, settings=settings))
        except FabkitError as exc:
            results.append(CheckResult(p.name, False, [], str(exc)))
            continue
        covered.update(Path(str(f)).name for f in res.get("files", []) or [])
        extra = {k: v for k, v in res.items() if k not in ("ok", "checks", "error", "file")}
        results.append(CheckResult(p.name, bool(res.get("ok")), list(res.get("checks", [])),
                                   str(res.get("error", "") or ""), extra))
    return results
