"""The batch engine behind ``fabkit export``: many templates in, one folder per design out.

Callable from Python::

    from fabkit.batch import export_many
    results = export_many(["templates/fourbar.toml"], outdir="out", jobs=2)
    results[0].outcome        # Outcome.OK / FAILED / CHECK_FAILED / INTERRUPTED
    results[0].formats["dxf"] # FormatResult(status=FormatStatus.EXPORTED, files=[...], ...)

What it guarantees:

- **Typed results.** Every design ends as a :class:`DesignResult` with an :class:`Outcome`; every
  format as a :class:`FormatResult` with a :class:`FormatStatus`. The command line, report.json and
  the tests read these fields; no decision anywhere reads the text of an error message.
- **Atomic folders.** A design is computed completely in memory, written to a hidden staging folder
  (each file through a temporary file and a rename), checked as built there, and swapped in place
  of the previous export by two renames. Files in the old folder that the export did not write
  (those of ``fabkit simulate``, ``map``, ``tolerance``, ``fold``) are carried over, so commands do
  not delete each other's outputs.
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
- **Progress.** One line per design and stage on stdout (``[3/30  41.2s] chaotic_chain: check
  (12.1 s in)``) whether or not it is a terminal: a design that takes more than two seconds
  announces each stage as it starts, and every design says how it ended.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
import threading
import time
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

from .errors import (BoundsError, FabkitError, Interrupted, LockedError, MotionError,
                     OutputError, SingularStartError, TemplateError, UnavailableError,
                     WriteError, internal_error_line)

__all__ = ["Outcome", "FormatStatus", "Stage", "CheckResult", "FormatResult", "DesignResult",
           "traced_motion", "build_outputs", "run_checks", "export_one", "export_many",
           "OutputLock", "Progress", "summary_table", "exit_code", "RESERVED", "MAX_SAMPLES"]

#: Files the batch writes itself into every design folder (besides the exporters' files).
RESERVED = ("report.json", "report.md", "report.html", "preview_motion.png", "preview_map.png",
            "preview_tolerance.png")

#: Largest number of Monte Carlo builds of the tolerance analysis without ``--allow-large``: each
#: build is one placement of the whole network, so 10 000 already take minutes for a chain.
MAX_SAMPLES = 10_000



def _safe(name: str) -> bool:
    """True when ``name`` can be a folder under the output folder (:mod:`fabkit.outputs`)."""
    from .errors import UnsafeNameError
    from .outputs import check_name

    try:
        check_name(name)
    except UnsafeNameError:
        return False
    return True

LOCK_NAME = ".fabkit.lock"


class Outcome(str, Enum):
    """How the export of one design ended."""

    OK = "ok"                      #: every file written and every as-built check passed
    FAILED = "failed"              #: nothing written: bad template, impossible motion, refusal
    CHECK_FAILED = "check failed"  #: files written, but an as-built check failed
    #: a format asked for (``--to``) cannot be produced: report.json names it ``refused`` with
    #: the reason; the formats that could be made are written
    REFUSED = "refused"
    INTERRUPTED = "interrupted"    #: stopped by a signal before it finished; nothing written

    def __str__(self) -> str:
        return self.value


class FormatStatus(str, Enum):
    """What happened to one format of one design."""

    EXPORTED = "exported"
    CHECK_FAILED = "check failed"
    DOES_NOT_APPLY = "does not apply"
    NOT_AVAILABLE = "not available"
    SKIPPED = "skipped by the template"
    #: asked for by name and cannot be produced (it does not apply, the template opts out, or
    #: it is not installed): the design fails with the reason in ``detail``
    REFUSED = "refused"

    def __str__(self) -> str:
        return self.value

    @property
    def produced(self) -> bool:
        """True when the format wrote files."""
        return self in (FormatStatus.EXPORTED, FormatStatus.CHECK_FAILED)


class Stage(str, Enum):
    """Stages of one design, in order (reported by the progress lines and in ``seconds``)."""

    LOAD = "load"
    MOTION = "motion"
    EXPORT = "export"
    PREVIEWS = "previews"
    TOLERANCE = "tolerance"
    WRITE = "write"
    CHECK = "check"

    def __str__(self) -> str:
        return self.value


@dataclass
class CheckResult:
    """The as-built check of one written file (``fabkit.check``)."""

    file: str
    ok: bool
    checks: list = field(default_factory=list)
    error: str = ""
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        out = {**self.extra, "file": self.file, "ok": self.ok, "checks": self.checks}
        if self.error:
            out["error"] = self.error
        return out


@dataclass
class FormatResult:
    """One format of one design: its status, files, exporter report and checks."""

    name: str
    status: FormatStatus
    files: list = field(default_factory=list)
    report: dict = field(default_factory=dict)
    detail: str = ""
    checks: list = field(default_factory=list)

    def as_dict(self) -> dict:
        out = {"status": self.status.value, "files": list(self.files)}
        if self.status.produced:
            out["report"] = self.report
        if self.detail:
            out["detail"] = self.detail
        if self.checks:
            out["checks"] = [c.as_dict() for c in self.checks]
        return out


@dataclass
class DesignResult:
    """The result of exporting one template.

    Attributes
    ----------
    path : str
        The template file.
    name : str
        The design's name (its folder), or the file's stem when it did not load.
    outcome : Outcome
    formats : dict of str to FormatResult
    files : int
        Files written into the folder (reports included).
    folder : str
        The design's folder, or ``""`` when nothing was written.
    error : str
        One line when the outcome is not OK, else ``""``.
    error_code : str
        The stable code of the error (:attr:`fabkit.errors.FabkitError.code`), ``"check"`` for a
        failed as-built check, ``"internal"`` for a bug, ``""`` when OK.
    seconds : float
        Wall time of the whole design.
    cpu_seconds : float
        CPU time of the process that exported it, over the same span (on a busy machine the
        wall time grows, this does not).
    stages : dict of str to float
        Wall time of each stage that ran.
    worker_exit : int or None
        When the worker process exporting the design died before it reported back: its exit
        status (negative: killed by that signal, as :attr:`multiprocessing.Process.exitcode`);
        ``error_code`` is then ``"worker"``. None otherwise.
    staged : str
        The complete staging folder not yet swapped in (``export_one(..., swap=False)``);
        ``""`` once swapped in, or when nothing was written.
    """

    path: str
    name: str
    outcome: Outcome = Outcome.FAILED
    formats: dict = field(default_factory=dict)
    files: int = 0
    folder: str = ""
    error: str = ""
    error_code: str = ""
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    stages: dict = field(default_factory=dict)
    worker_exit: int | None = None
    staged: str = ""

    @property
    def ok(self) -> bool:
        return self.outcome is Outcome.OK

    @property
    def exported_formats(self) -> list[str]:
        return [f for f, v in self.formats.items() if v.status.produced]

    def as_dict(self) -> dict:
        return {"path": self.path, "name": self.name, "outcome": self.outcome.value,
                "ok": self.ok, "formats": self.exported_formats, "files": self.files,
                "folder": self.folder, "error": self.error, "error_code": self.error_code,
                "seconds": self.seconds, "cpu_seconds": self.cpu_seconds,
                "stages": dict(self.stages), "worker_exit": self.worker_exit}


def exit_code(results) -> int:
    """0 when every design is OK, 1 when any failed (an interrupted run exits by its signal)."""
    return 0 if all(r.ok for r in results) else 1


# --- the motion ------------------------------------------------------------------------------

def _builder_key(design) -> str:
    from .templates import BUILDERS

    return next((k for k in BUILDERS if k in design.raw), "network")


def traced_motion(design, *, allow_singular_start=False, **overrides):
    """Trace a design's motion for export; every way it can fail is one :class:`MotionError`.

    Which template key the error names is decided from the network's structure (its mode count)
    and the trace's typed status, not from any message: no first-order motion → the builder
    section; a singular start (states of self-stress and more than one first-order motion) → the
    nodes; several motions without a singularity → the builder section; a turning or branch point
    before the target → ``motion.to``; any other failure → ``motion``.

    Parameters
    ----------
    design : Design
    allow_singular_start : bool
        Raise :class:`~fabkit.errors.SingularStartError` for a singular start, so that the caller
        may let an exporter that chooses the branch (an origami crease assignment) decide.
        Otherwise a singular start is a plain failure of the same class.
    **overrides
        Passed to :meth:`Design.trace` (``method``, ``to``, method options).

    Returns
    -------
    Trajectory or None
        None when the template gives no target (``motion.to``): a geometry-only design.

    Raises
    ------
    MotionError
        The motion is impossible, or its trace does not reach the target.
    """
    from .kinematics import Status
    from .rigidity import count_modes

    path = design.path or design.name
    target = overrides.get("to", design.motion.to)
    if target is None:
        return None
    builder = _builder_key(design)
    nodes_key = "network.nodes" if builder == "network" else builder
    singular = several = False
    if not design.motion.hold:
        modes = count_modes(design.network)
        if modes.conformational == 0:
            raise MotionError(path, builder,
                              f"the network is rigid: it has no conformational motion "
                              f"(modes: {modes.total} = {modes.rigid} rigid); remove an edge",
                              status="refused")
        singular = modes.self_stress > 0 and modes.conformational > 1
        several = modes.conformational > 1 and not singular
    try:
        traj = design.trace(**overrides)
    except TypeError as exc:  # an unknown method option
        raise MotionError(path, "motion.options", str(exc), status="refused") from None
    except FabkitError as exc:
        key = nodes_key if singular else builder if several else "motion"
        cls = SingularStartError if singular else MotionError
        raise cls(path, key, str(exc), status="refused") from None
    if traj.success:
        return traj
    at_start = traj.n_steps <= 1
    if singular and at_start:
        raise SingularStartError(path, nodes_key, f"target {design.motion.drive} = "
                                 f"{float(target):.10g} is not reached: {traj.message}",
                                 status=str(traj.status))
    key = "motion.to" if traj.status in (Status.TURNING_POINT, Status.BRANCH_POINT) else "motion"
    raise MotionError(path, key, f"target {design.motion.drive} = {float(target):.10g} is not "
                                 f"reached: {traj.message}", status=str(traj.status))


def _chain_port_names(net) -> list[str]:
    ports = [p for p in net.ports if re.fullmatch(r"d\d+", p)]
    return sorted(ports, key=lambda p: int(p[1:]))


def map_figure(traj, design):
    """The map picture of a design, or None when it has fewer than two ports d1, d2, ...

    A single module: its whole map d2 = f(d1) (:func:`fabkit.mapplots.map_figure`, fixed
    points and 2-cycles marked) with the traced stretch in red. A chain: the cobweb of the
    distances d_1, d_2, ... at the start and at the end of the motion, over the identity line.
    """
    import numpy as np

    from .viz import _mpl

    ports = _chain_port_names(traj.network)
    if len(ports) < 2:
        return None
    dist = np.stack([traj.distance(p) for p in ports], axis=1)  # (S, K)
    if len(ports) == 2:
        try:
            from .mapplots import map_figure as module_map_figure
            from .maps import module_map

            fig = module_map_figure(module_map(design.network), title=f"{design.name}: map")
        except (FabkitError, ImportError):
            fig = None
        if fig is not None:
            ax = fig.axes[0]
            ax.plot(dist[:, 0], dist[:, 1], "-", color="C3", lw=3, alpha=0.7,
                    label="traced motion")
            ax.legend(fontsize=7, loc="best")
            return fig
    plt = _mpl()
    fig, ax = plt.subplots(figsize=(5.6, 5.4))
    if len(ports) == 2:
        ax.plot(dist[:, 0], dist[:, 1], "-", color="C3", lw=2, label="d2 = f(d1), traced")
    else:
        for row, label, colour in ((0, "start", "C0"), (-1, "end", "C3")):
            d = dist[row]
            # cobweb: (d1, d1) → (d1, d2) → (d2, d2) → (d2, d3) → ...
            xs = np.repeat(d[:-1], 2)
            ys = np.empty_like(xs)
            ys[0::2] = np.concatenate([[d[0]], d[1:-1]])
            ys[1::2] = d[1:]
            ax.plot(xs, ys, "-", color=colour, lw=1.2, label=f"cobweb at the {label}")
            ax.plot(d[:-1], d[1:], "o", ms=3.5, color=colour)
    lo, hi = float(dist.min()), float(dist.max())
    pad = 0.05 * (hi - lo or 1.0)
    ax.plot([lo - pad, hi + pad], [lo - pad, hi + pad], ":", color="0.5", lw=1, label="identity")
    ax.set_xlabel("$d_k$")
    ax.set_ylabel("$d_{k+1}$")
    ax.set_title(f"{design.name}: map along the chain")
    ax.legend(loc="best", fontsize=8)
    ax.set_aspect("equal", adjustable="datalim")
    fig.tight_layout()
    return fig


def motion_report(traj) -> dict:
    """The motion facts of report.json (drive, start, target, method, status, distances)."""
    names = list(traj.network.ports)
    return {
        "drive": traj.network.ports and next((k for k, v in traj.network.ports.items()
                                              if tuple(v) == tuple(traj.drive_port)),
                                             str(traj.drive_port)),
        "start": float(traj.drive[0]),
        "to": float(traj.target),
        "method": traj.method,
        "status": str(traj.status),
        "message": traj.message,
        "steps": traj.n_steps,
        "max_edge_error": traj.max_edge_error,
        "start_distances": {n: float(traj.distance(n)[0]) for n in names},
        "final_distances": {n: float(traj.distance(n)[-1]) for n in names},
    }


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
    from .export import skip_reason

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
    from .tolerance import tolerance_spec

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
    from .export import EXPORTERS
    from .report import design_facts
    from .viz import figure_png, motion_figure

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
        from .tolerance import analyse_tolerance, tolerance_figure

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

    from .check import CHECKERS

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
    from .check import CHECKERS

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


# --- folders ---------------------------------------------------------------------------------

def _staging_names(outdir: Path, name: str) -> tuple[Path, Path]:
    # fixed names (no random part): paths that checkers quote stay the same from run to run
    return outdir / f".{name}.staging", outdir / f".{name}.old"


def check_replaceable(folder: Path) -> None:
    """Refuse to replace a folder that is not an earlier export or a folder of another fabkit
    command (:class:`~fabkit.errors.OutputError`)."""
    if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
        raise OutputError(folder, "exists and is not a folder; move it away or choose another "
                                  "output folder with -o")


def recover_folder(outdir: Path, name: str) -> None:
    """Undo what a run killed between its two renames left: the old folder put back when the
    new one never arrived, and the staging and old folders removed."""
    folder = outdir / name
    stage, old = _staging_names(outdir, name)
    if old.is_dir() and not folder.exists():
        os.replace(old, folder)
    for leftover in (stage, old):
        if leftover.is_dir():
            shutil.rmtree(leftover)


def _export_manifest(folder: Path) -> set | None:
    """Names the previous export wrote into ``folder`` (from its report.json), or None when the
    folder holds no export report."""
    import json

    try:
        old = json.loads((folder / "report.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(old, dict):
        return None
    names = set(old.get("files") or [])
    for v in (old.get("formats") or {}).values():
        if isinstance(v, dict):
            names.update(v.get("files") or [])
    names.update(old.get("previews") or [])
    names.update(("report.json", "report.md", "motion.png", "map.png", "tolerance.png")
                 if "files" not in old else ())
    return names


def carry_over(folder: Path, stage: Path) -> list[str]:
    """Hard-link (or copy) into ``stage`` what another command wrote into ``folder``: every
    entry the previous export did not write and the new one does not write either. Returns the
    names carried over."""
    if not folder.is_dir():
        return []
    mine = _export_manifest(folder) or set()
    kept = []
    for entry in sorted(folder.iterdir()):
        if entry.name in mine or entry.name.startswith(".") or (stage / entry.name).exists():
            continue
        target = stage / entry.name
        if entry.is_dir() and not entry.is_symlink():
            shutil.copytree(entry, target, symlinks=True, copy_function=_link_or_copy)
        else:
            _link_or_copy(entry, target)
        kept.append(entry.name)
    return kept


def _link_or_copy(src, dst):
    try:
        os.link(src, dst, follow_symlinks=False)
    except OSError:
        shutil.copy2(src, dst, follow_symlinks=False)
    return dst


def swap_in(stage: Path, folder: Path) -> None:
    """Replace ``folder`` by the complete ``stage`` folder with two renames; a reader sees the
    old export or the new one, never a mix."""
    if folder.exists():
        _, old = _staging_names(folder.parent, folder.name)
        os.replace(folder, old)
        os.replace(stage, folder)
        shutil.rmtree(old)
    else:
        os.replace(stage, folder)


class OutputLock:
    """An exclusive lock on an output folder: ``<out>/.fabkit.lock`` held with ``flock``.

    The kernel drops the lock when the holder dies, even by SIGKILL, so a stale lock file never
    blocks anyone; the file is removed on release.

    Parameters
    ----------
    outdir : path
    wait : bool
        Wait for the other export to finish instead of refusing.
    poll : float
        Seconds between attempts while waiting (short, so that a signal stops the wait).
    """

    def __init__(self, outdir, wait=False, poll=0.2):
        self.outdir = Path(outdir)
        self.wait = wait
        self.poll = poll
        self.fd = None

    def __enter__(self):
        import fcntl

        path = self.outdir / LOCK_NAME
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = _read_pid(fd)
                os.close(fd)
                if not self.wait:
                    raise LockedError(self.outdir, pid) from None
                time.sleep(self.poll)
                continue
            # the holder before us may have removed the file after we opened it: lock the file
            # that is at the path now
            try:
                same = os.fstat(fd).st_ino == os.stat(path).st_ino
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
            self.fd = fd
            return self

    def __exit__(self, *exc):
        if self.fd is not None:
            try:
                os.unlink(self.outdir / LOCK_NAME)
            except FileNotFoundError:
                pass
            os.close(self.fd)  # closing drops the flock
            self.fd = None
        return False


def _read_pid(fd) -> int | None:
    try:
        text = os.pread(fd, 32, 0).decode().strip()
        return int(text) if text else None
    except (OSError, ValueError):
        return None


def prepare_outdir(outdir) -> Path:
    """Create the output folder; :class:`OutputError` (one line) when that is impossible."""
    outdir = Path(outdir)
    try:
        if outdir.exists() and not outdir.is_dir():
            raise OutputError(outdir, "exists and is not a folder; choose another output "
                                      "folder with -o")
        outdir.mkdir(parents=True, exist_ok=True)
    except OutputError:
        raise
    except OSError as exc:
        raise OutputError(outdir, f"cannot create the output folder: "
                                  f"{exc.strerror or exc}") from None
    if not os.access(outdir, os.W_OK | os.X_OK):
        raise OutputError(outdir, "the output folder is not writable; choose another with -o")
    return outdir


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
    from .export import write_atomic, write_outputs
    from .errors import UnsafeNameError
    from .outputs import inside
    from .report import report_json, report_markdown
    from .report_html import write_design_report
    from .templates import load_template, with_settings

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
            raise TemplateError(path, "name", f"{design.name!r} {exc.reason}") from None
        check_replaceable(folder)
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
#: default; ``term``: SIGTERM; ``exit``: exit code 3 without cleaning up).
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
        else:
            os._exit(3)

    return hit


def _worker_main(parent_pid, conn, blas_threads: int) -> None:
    """A worker process: export the designs it is sent on ``conn`` until it gets None.

    ``blas_threads`` caps the BLAS/LAPACK threads of this worker so that the workers together
    use the machine's cores once: parallelism is across designs, and oversubscribed BLAS threads
    slow dense work down several times (a dense SVD of 882 coordinates: 0.15 s on one thread,
    seconds when threads contend).

    Everything goes back on the same pipe with blocking sends (no feeder thread), so what the
    parent reads was sent, and a design it has sent and not heard back about is known to be in
    the hands of this worker whatever the moment it dies.
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
    try:
        while True:
            try:
                task = conn.recv()
            except EOFError:  # the parent closed its end
                return
            if task is None:
                return
            index, name, args, kwargs = task
            hit = _fault_point(name)
            hit("taken")

            def progress(name, s, index=index, hit=hit):
                hit(s)
                conn.send(("stage", index, name, str(s)))

            res = export_one(*args, progress=progress, swap=False, **kwargs)
            hit("done")
            conn.send(("done", index, res))
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

    @property
    def pid(self) -> int:
        return self.proc.pid


class _Pool:
    """Worker processes, each fed one design at a time over its own pipe."""

    def __init__(self, jobs: int):
        import multiprocessing

        self.ctx = multiprocessing.get_context("spawn")  # fresh interpreters, no forked state
        self.blas_threads = max(1, (os.cpu_count() or 1) // jobs)
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
                                    args=(os.getpid(), theirs, self.blas_threads),
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


# --- many designs ----------------------------------------------------------------------------

class Progress:
    """Progress on stdout: one line per design and stage, terminal or not (stderr is kept for
    the one-line errors).

    Parameters
    ----------
    total : int
        Number of designs.
    stream : file, optional
        Default ``sys.stdout``.
    quiet : bool
        Print nothing.
    after : float
        A stage is shown once its design has run this many seconds (a design that is done
        sooner shows one line, when it ends).
    """

    def __init__(self, total: int, stream=None, quiet=False, after=2.0):
        self.stream = stream or sys.stdout
        self.total = total
        self.done = 0
        self.quiet = quiet
        self.after = after
        self.t0 = time.perf_counter()
        self.started: dict[str, float] = {}

    def _line(self, text: str) -> None:
        if self.quiet:
            return
        self.stream.write(f"[{self.done}/{self.total} {time.perf_counter() - self.t0:6.1f}s] "
                          f"{text}\n")
        self.stream.flush()

    def stage(self, name: str, stage) -> None:
        """A design starts a stage."""
        now = time.perf_counter()
        start = self.started.setdefault(name, now)
        if now - start >= self.after:
            self._line(f"{name}: {stage} ({now - start:.1f} s in)")

    def finished(self, result: DesignResult) -> None:
        """A design is done."""
        self.done += 1
        self._line(f"{result.name}: {result.outcome} in {result.seconds:.1f} s")

    def close(self) -> None:
        pass


def summary_table(results) -> str:
    """The table printed at the end: one line per design."""
    header = ("design", "status", "formats", "files", "time", "cpu", "output or error")
    body = [(r.name, r.outcome.value, ",".join(r.exported_formats) or "-", str(r.files),
             f"{r.seconds:.1f}s", f"{r.cpu_seconds:.1f}s", r.folder if r.ok else r.error)
            for r in results]
    widths = [max(len(x[i]) for x in [header, *body]) for i in range(6)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r[:6], widths)) + "  " + r[6]
             for r in [header, *body]]
    failed = sum(not r.ok for r in results)
    lines.append(f"{len(results) - failed} exported, {failed} failed")
    return "\n".join(lines)


def export_many(paths, formats=None, outdir="out", settings=None, *, jobs=1, check=True,
                tolerance_samples=None, progress=None, isolate=True, exporters=None,
                previews=True, debug=False, wait=False, allow_large=False) -> list[DesignResult]:
    """Export many templates; one :class:`DesignResult` per template, in input order.

    Parameters
    ----------
    paths : sequence of path
        Template files.
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
    progress : Progress, optional
    isolate : bool
        Export in fresh worker processes with a fixed hash seed (``PYTHONHASHSEED=0``), so that
        no library's set or dict ordering can make two runs differ; False with ``jobs=1`` runs
        in this process.
    exporters : dict of str to str, optional
        Format registry (default :data:`fabkit.export.EXPORTERS`, as it is now).
    previews : bool
        Draw the preview pictures.
    debug : bool
        Let internal errors raise with their traceback; implies one design at a time in this
        process.
    wait : bool
        Wait for another export into the same folder to finish, instead of refusing.
    allow_large : bool
        Lift the size bounds.

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
    from .export import EXPORTERS
    from .report_html import write_index
    from .templates import allow_large as large_allowed
    from .templates import load_template

    allow_large = allow_large or large_allowed()
    if tolerance_samples is not None and tolerance_samples > MAX_SAMPLES and not allow_large:
        raise BoundsError("--tolerance-samples", "Monte Carlo samples", int(tolerance_samples),
                          MAX_SAMPLES, "fabkit --allow-large", option=True)
    from .export import check_export_settings

    exporters = dict(EXPORTERS if exporters is None else exporters)
    # before any design: one bad key fails them all alike
    settings = check_export_settings(settings or {}, exporters)
    paths = [Path(p) for p in paths]
    results: list[DesignResult | None] = [None] * len(paths)
    owners: dict[str, Path] = {}
    names: dict[int, str] = {}
    todo = []

    def finished(i, res):
        results[i] = res
        if progress:
            progress.finished(res)

    cost = {}
    for i, p in enumerate(paths):
        try:
            design = load_template(p)
            name = design.name
            cost[i] = design.network.n_edges
        except FabkitError as exc:
            # a template that does not even load needs no worker: report it here
            finished(i, DesignResult(str(p), p.stem, error=str(exc), error_code=exc.code))
            continue
        if name in owners:
            finished(i, DesignResult(str(p), name, error_code="template",
                                     error=f"{p}: name: {name!r} is also the name of "
                                           f"{owners[name]}; each design needs its own name "
                                           "(its output folder)"))
            continue
        owners[name] = p
        names[i] = name
        todo.append(i)
    if not todo:
        return results  # type: ignore[return-value]
    outdir = prepare_outdir(outdir)
    kwargs = dict(check=check, tolerance_samples=tolerance_samples, exporters=exporters,
                  previews=previews, debug=debug, allow_large=allow_large)
    args = {i: (paths[i], formats, outdir, settings) for i in todo}
    with OutputLock(outdir, wait=wait):
        if (isolate or jobs > 1) and not debug:
            # largest designs first (edges as the measure of work): a long design started last
            # would run alone at the end while the other workers idle
            order = sorted(todo, key=lambda i: (-cost.get(i, 0), i))
            _run_pool(order, args, names, kwargs, jobs, outdir, progress, finished)
        else:
            stage_cb = progress.stage if progress else None
            for i in todo:
                finished(i, export_one(*args[i], progress=stage_cb, **kwargs))
        if any(r is not None and r.folder for r in results):
            write_index(outdir)  # index.html of every design folder in the output
    return results  # type: ignore[return-value]


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


def _run_pool(todo, args, names, kwargs, jobs, outdir, progress, finished) -> None:
    """Export the designs ``todo`` (in this order) in ``jobs`` worker processes.

    The parent hands a design to an idle worker and remembers it until the worker reports it
    done; the worker leaves its folder staged and the parent swaps it in. A worker that dies
    (killed by the system, out of memory, a crash), at whatever moment, fails the design it
    was handed with ``error_code = "worker"`` and its exit status, its staging folder is
    removed, and a new worker takes its place while designs remain.
    """
    from multiprocessing.connection import wait

    queue = list(todo)
    pending = set(todo)
    pool = _Pool(max(1, min(jobs, len(todo))))

    def dispatch(w):
        if not queue:
            return
        i = queue.pop(0)
        w.task = i  # handed over from here on, whatever happens to the send
        try:
            w.conn.send((i, names[i], args[i], kwargs))
        except OSError:
            pass  # the worker is gone: its death fails the design

    def receive(w) -> bool:
        """Handle every message waiting from ``w``; False when its pipe is closed."""
        try:
            while w.conn.poll():
                event = w.conn.recv()
                if event[0] == "stage":
                    if progress:
                        progress.stage(event[2], event[3])
                    continue
                _, i, res = event
                if i not in pending:  # pragma: no cover - every design is sent once
                    continue
                if res.staged:
                    try:
                        swap_in(Path(res.staged), Path(res.folder))
                    except OSError as exc:
                        recover_folder(outdir, names[i])
                        res.outcome, res.folder, res.files = Outcome.FAILED, "", 0
                        res.error = (f"{args[i][0]}: cannot write the export to {outdir}: "
                                     f"{exc.strerror or exc}")
                        res.error_code = "output"
                    res.staged = ""
                w.task = None
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
            if _safe(names[i]):
                try:  # its staging folder, whatever it holds
                    recover_folder(outdir, names[i])
                except OSError:  # pragma: no cover - the next run removes it
                    pass
            finished(i, DesignResult(str(args[i][0]), names[i], error_code="worker",
                                     error=_died_message(args[i][0], names[i],
                                                         w.proc.exitcode),
                                     worker_exit=w.proc.exitcode))
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
                open_ = receive(w) if w.conn in ready else True
                if w.proc.sentinel in ready or not open_ or not w.proc.is_alive():
                    receive(w)  # what it sent before it ended counts
                    if not open_ and w.proc.is_alive():
                        w.proc.kill()  # a broken pipe: this worker can no longer report
                    bury(w)
    except BaseException:
        pool.stop()
        # a worker killed between two writes leaves its staging folder: remove those of the
        # designs in flight, and put back an old folder caught between the two renames
        for i in pending:
            if _safe(names[i]):
                try:
                    recover_folder(outdir, names[i])
                except OSError:
                    pass
        raise
    finally:
        pool.close()
