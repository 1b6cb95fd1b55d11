"""``fabkit export PATH... [--to dxf,svg,fold,stl] [-o DIR] [--jobs N] [--set KEY=VALUE ...]``.

Exports templates (files, folders of ``*.toml``, glob patterns) into one folder per design:
the files of every format that applies (or of the formats asked for), ``report.json``,
``report.md`` and preview PNGs (motion, map, tolerance, and any preview an exporter makes).

Each design is computed completely in memory first; nothing of a design is written when any
step of it raises. Its files (each through a temporary file and a rename) and its reports go to
a hidden staging folder, where the as-built check reads them back; two renames then put the
complete folder in place of the previous one, so a kill or a failed write at any moment leaves
the previous export untouched and no half-written file under a visible name. A design that fails
is reported and the others still export; the exit code is 1 when any failed. Identical input
gives identical bytes (no clock, no absolute path, fixed random seed, workers started with a
fixed hash seed).
"""

from __future__ import annotations

import re
import sys
import time
from pathlib import Path

NAME = "export"
HELP = "export templates (files, folders, globs) for fabrication, with reports and checks"

#: Files the export command writes itself into every design folder.
RESERVED = ("report.json", "report.md", "motion.png", "map.png", "tolerance.png")

_SAFE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")


def add_arguments(p):
    p.add_argument("paths", nargs="+", metavar="PATH",
                   help="template files, folders of *.toml templates, or glob patterns")
    p.add_argument("--to", default=None, metavar="FORMATS",
                   help="comma-separated formats (default: every format that applies to a design)")
    p.add_argument("-o", "--out", default="out", help="output folder (default: out)")
    p.add_argument("--jobs", "-j", type=int, default=1,
                   help="designs exported in parallel processes (default: 1)")
    p.add_argument("--set", dest="settings", action="append", default=[],
                   metavar="SECTION.KEY=VALUE",
                   help="override a fabrication setting, e.g. --set laser.kerf=0.2 (repeatable; "
                        "values are read as TOML: 0.2, true, \"text\", [1, 2])")
    p.add_argument("--no-check", action="store_true",
                   help="skip the as-built check of the written files")
    p.add_argument("--no-previews", action="store_true",
                   help="skip the preview pictures (motion, map, tolerance): faster batches")
    p.add_argument("--tolerance-samples", type=int, default=None, metavar="N",
                   help="Monte Carlo builds in the tolerance analysis (0: skip; default: the "
                        "template's [fabrication.tolerance] samples, else 200)")


# --- command-line values ---------------------------------------------------------------------

def parse_settings(items) -> dict:
    """``["laser.kerf=0.2", "laser.scale=10"]`` → ``{"laser": {"kerf": 0.2, "scale": 10}}``.

    Values are parsed as TOML values (numbers, booleans, quoted strings, arrays); anything that
    is not valid TOML is kept as a plain string.

    Raises
    ------
    FabkitError
        An item without ``=`` or without a dotted key, or a key given twice.
    """
    from ..errors import FabkitError
    from ..templates import tomllib

    out: dict = {}
    for item in items:
        key, eq, text = item.partition("=")
        key = key.strip()
        if not eq or not key:
            raise FabkitError(f"--set {item!r}: expected SECTION.KEY=VALUE, e.g. laser.kerf=0.2")
        parts = key.split(".")
        if len(parts) < 2 or not all(parts):
            raise FabkitError(f"--set {item!r}: the key must name a section and a key, "
                              "e.g. laser.kerf")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        node = out
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise FabkitError(f"--set {item!r}: {part!r} is already set to a value")
        if parts[-1] in node:
            raise FabkitError(f"--set {item!r}: {key} is given twice")
        node[parts[-1]] = value
    return out


def parse_formats(text: str | None) -> list[str] | None:
    """``"dxf,stl"`` → ``["dxf", "stl"]``; None stays None (every format that applies)."""
    from ..errors import FabkitError
    from ..export import EXPORTERS

    if text is None:
        return None
    names = [t.strip().lower() for t in text.split(",") if t.strip()]
    if not names:
        raise FabkitError("--to: give at least one format, e.g. --to dxf,stl")
    for n in names:
        if n not in EXPORTERS:
            raise FabkitError(f"--to: unknown format {n!r}; valid: {', '.join(EXPORTERS)}")
    return list(dict.fromkeys(names))


# --- one design --------------------------------------------------------------------------------

def _builder_key(design) -> str:
    from ..templates import BUILDERS

    return next((k for k in BUILDERS if k in design.raw), "network")


class SingularStart(Exception):
    """Internal: the motion cannot leave its start (a bifurcation such as a flat sheet) without a
    rule that chooses the branch; carries the one-line TemplateError to raise if no exporter
    supplies that rule."""

    def __init__(self, error):
        super().__init__(str(error))
        self.error = error


def _is_singular_start(message: str, steps: int = 1) -> bool:
    return steps <= 1 and ("singular" in message or "flat state" in message)


def traced_motion(design, *, allow_singular_start=False, **overrides):
    """Trace a design's motion for export; every way it can fail is a one-line TemplateError.

    Parameters
    ----------
    design : Design
    allow_singular_start : bool
        Raise :class:`SingularStart` (instead of the TemplateError) when the trace cannot leave a
        singular start: the caller may let an exporter that resolves the branch decide.
    **overrides
        Passed to :meth:`Design.trace` (``method``, ``to``, method options).

    Returns
    -------
    Trajectory or None
        None when the template gives no target (``motion.to``): a geometry-only design.

    Raises
    ------
    TemplateError
        The network has no conformational motion, or more than one (and no ``motion.hold``), the
        start state is singular (flat) for the chosen method, or the target is not reached
        (a turning point, a branch point, a failed trace); the key names the section to fix.
    """
    from ..errors import FabkitError, TemplateError
    from ..rigidity import count_modes

    path = design.path or design.name
    target = overrides.get("to", design.motion.to)
    if target is None:
        return None
    builder = _builder_key(design)
    nodes_key = "network.nodes" if builder == "network" else builder
    if not design.motion.hold:
        # no first-order motion at all means rigid; more than one first-order mode may be a
        # singular start of a one-motion network (a flat origami sheet), which the trace sorts out
        modes = count_modes(design.network)
        if modes.conformational == 0:
            raise TemplateError(path, builder,
                                f"the network is rigid: it has no conformational motion "
                                f"(modes: {modes.total} = {modes.rigid} rigid); remove an edge")
    try:
        traj = design.trace(**overrides)
    except FabkitError as exc:
        reason = str(exc)
        if "conformational motion" in reason:
            key = builder
        elif "flat" in reason or "start" in reason:
            key = nodes_key
        else:
            key = "motion"
        error = TemplateError(path, key, reason)
        if allow_singular_start and _is_singular_start(reason):
            raise SingularStart(error) from None
        raise error from None
    except TypeError as exc:  # an unknown method option
        raise TemplateError(path, "motion.options", str(exc)) from None
    if not traj.success:
        singular = _is_singular_start(traj.message, traj.n_steps)
        error = TemplateError(path, nodes_key if singular else "motion.to",
                              f"target {design.motion.drive} = {float(target):.10g} is not "
                              f"reached: {traj.message}")
        if allow_singular_start and singular:
            raise SingularStart(error)
        raise error
    return traj


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

    from ..errors import FabkitError
    from ..viz import _mpl

    ports = _chain_port_names(traj.network)
    if len(ports) < 2:
        return None
    dist = np.stack([traj.distance(p) for p in ports], axis=1)  # (S, K)
    if len(ports) == 2:
        try:
            from ..mapplots import map_figure as module_map_figure
            from ..maps import module_map

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


def _check_names(fmt, files, taken, path):
    from ..errors import FabkitError

    for name in files:
        p = Path(name)
        if p.is_absolute() or ".." in p.parts or not name or name.startswith("."):
            raise FabkitError(f"{path}: the {fmt} exporter produced a file named {name!r}, "
                              "which is not a plain name inside the design folder")
        if name in taken:
            raise FabkitError(f"{path}: the {fmt} exporter's file {name!r} clashes with "
                              f"{taken[name]}'s")
        taken[name] = fmt


def _load_exporter(fmt: str, exporters: dict):
    """The module of a format from a registry (name → module path); FabkitError if missing."""
    import importlib

    from ..errors import FabkitError

    if fmt not in exporters:
        raise FabkitError(f"unknown export format {fmt!r}; valid: {', '.join(exporters)}")
    try:
        return importlib.import_module(exporters[fmt])
    except ImportError as exc:
        raise FabkitError(f"export format {fmt!r} is not available: {exc}") from None


def build_outputs(design, formats, settings, tolerance_samples=None, exporters=None,
                  previews=True) -> tuple[dict, dict]:
    """Everything a design's folder will hold, computed in memory (nothing is written).

    Parameters
    ----------
    design : Design
    formats : list of str or None
        Formats to export; None: every format whose module says it ``applies(design)``.
    settings : dict
        Command-line overrides of the fabrication settings (nested dict).
    tolerance_samples : int or None
        Monte Carlo builds of the tolerance analysis (0 skips it; None: the template's setting).
    exporters : dict of str to str, optional
        Format registry (default :data:`fabkit.export.EXPORTERS`).
    previews : bool
        Draw motion.png, map.png and tolerance.png.

    Returns
    -------
    files : dict of str to bytes
        Every exporter's files plus the preview PNGs (reports excluded: they come after the check).
    report : dict
        Facts for report.json.

    Raises
    ------
    FabkitError
        Bad template content, impossible motion, or an exporter's refusal (one line).
    """
    import fabkit

    from ..errors import FabkitError
    from ..export import EXPORTERS, skip_reason
    from ..report import design_facts
    from ..viz import figure_png, motion_figure

    path = design.path or design.name
    report = {"design": design_facts(design), "fabkit_version": fabkit.__version__,
              "formats": {}, "previews": [], "errors": []}
    files: dict[str, bytes] = {}
    singular = None
    try:
        traj = traced_motion(design, allow_singular_start=True)
    except SingularStart as exc:
        # e.g. a flat origami sheet: an exporter that chooses the branch (by its mountain/valley
        # assignment) may still export it; with none, the design fails with this error
        traj, singular = None, exc.error
    spec = None
    if traj is not None and tolerance_samples != 0 and _has_tolerance():
        from ..tolerance import tolerance_spec

        # settings are checked before any heavy work: a bad value fails the design at once
        extra = {} if tolerance_samples is None else {"samples": tolerance_samples}
        spec = tolerance_spec(design, settings, **extra)

    exporters = dict(EXPORTERS if exporters is None else exporters)
    chosen = []
    for fmt in (formats if formats is not None else list(exporters)):
        try:
            module = _load_exporter(fmt, exporters)
        except FabkitError as exc:
            if formats is not None:
                raise
            report["formats"][fmt] = {"status": "not available", "detail": str(exc), "files": []}
            continue
        applies = getattr(module, "applies", None)
        if applies is not None and not applies(design):
            if formats is not None:
                report["formats"][fmt] = {"status": "does not apply", "files": []}
            continue
        reason = skip_reason(design, fmt)
        if reason is not None:  # the template opts out of this format and says why
            report["formats"][fmt] = {"status": "skipped by the template", "detail": reason,
                                      "files": []}
            continue
        chosen.append((fmt, module))

    taken = {name: "export" for name in RESERVED}
    for fmt, module in chosen:
        try:
            result = module.export_design(design, settings)
        except FabkitError as exc:
            if singular is not None:
                raise singular from None  # the root cause, not its consequence in this format
            msg = str(exc)
            if msg.startswith(str(path)):
                raise
            raise FabkitError(f"{path}: {fmt} export: {msg}") from None
        if not isinstance(result.files, dict) or not all(
                isinstance(v, (bytes, bytearray)) for v in result.files.values()):
            raise FabkitError(f"{path}: the {fmt} exporter returned no file bytes")
        _check_names(fmt, result.files, taken, path)
        files.update({k: bytes(v) for k, v in result.files.items()})
        report["formats"][fmt] = {"status": "exported", "files": sorted(result.files),
                                  "report": result.report}

    if singular is not None:
        if not any(v.get("status") == "exported" for v in report["formats"].values()):
            raise singular
        report["motion"] = {"status": "singular start", "message": singular.reason,
                            "resolved_by": sorted(f for f, v in report["formats"].items()
                                                  if v.get("status") == "exported")}
    # pictures after the exporters: a refused export fails fast
    if traj is not None:
        report["motion"] = motion_report(traj)
    if traj is not None and previews:
        files["motion.png"] = figure_png(motion_figure(traj, title=design.name))
        fig = map_figure(traj, design)
        if fig is not None:
            files["map.png"] = figure_png(fig)
    if spec is not None:
        from ..tolerance import analyse_tolerance, tolerance_figure

        tol = analyse_tolerance(design, spec, trajectory=traj)
        report["tolerance"] = tol.as_dict()
        if previews:
            files["tolerance.png"] = figure_png(tolerance_figure(tol, title=design.name))
    # pictures for report.md: ours, the exporters' PNGs, and SVGs (crease patterns, sheets)
    report["previews"] = sorted(n for n in files if n.endswith((".png", ".svg")))
    return files, report


def _has_tolerance() -> bool:
    import importlib.util

    return importlib.util.find_spec("fabkit.tolerance") is not None


def run_checks(paths, design, settings) -> tuple[list[dict], bool]:
    """As-built check of every written file that has a checker; returns (results, all ok)."""
    from ..check import CHECKERS, check_file
    from ..errors import FabkitError

    results, ok = [], True
    for p in paths:
        if p.suffix.lower().lstrip(".") not in CHECKERS:
            continue
        try:
            res = dict(check_file(p, design=design, settings=settings))
        except FabkitError as exc:
            if "is not available" in str(exc):
                continue  # that check is not installed: nothing to say about this file
            res = {"ok": False, "checks": [], "error": str(exc)}
        res["file"] = p.name
        ok &= bool(res.get("ok"))
        results.append(res)
    return results, ok


def _staging_names(outdir: Path, name: str) -> tuple[Path, Path]:
    # fixed names (no random part): paths that checkers quote stay the same from run to run
    return outdir / f".{name}.staging", outdir / f".{name}.old"


def check_replaceable(folder: Path) -> None:
    """Refuse to replace a folder that is not an earlier export (FabkitError)."""
    from ..errors import FabkitError

    if folder.exists() and not (folder.is_dir() and ((folder / "report.json").is_file()
                                                     or not any(folder.iterdir()))):
        raise FabkitError(f"{folder}: exists and is not a fabkit export folder (no report.json); "
                          "move it away or choose another output folder with -o")


def prepare_folder(outdir, name: str) -> tuple[Path, Path]:
    """The final and the staging folder of a design; removes what a killed run left behind.

    Raises
    ------
    FabkitError
        ``outdir/<name>`` exists but is not an export folder (no report.json and not empty):
        it is never replaced, whatever it holds.
    """
    import shutil

    outdir = Path(outdir)
    folder = outdir / name
    stage, old = _staging_names(outdir, name)
    check_replaceable(folder)
    for leftover in (stage, old):
        if leftover.is_dir():
            shutil.rmtree(leftover)
    stage.mkdir(parents=True)
    return folder, stage


def swap_in(stage: Path, folder: Path) -> None:
    """Replace ``folder`` by the complete ``stage`` folder with two renames; a reader sees the
    old export or the new one, never a mix."""
    import os
    import shutil

    if folder.exists():
        _, old = _staging_names(folder.parent, folder.name)
        os.replace(folder, old)
        os.replace(stage, folder)
        shutil.rmtree(old)
    else:
        os.replace(stage, folder)


def export_one(path, formats, outdir, settings, check=True, tolerance_samples=None,
               exporters=None, previews=True, debug=False) -> dict:
    """Export one template into ``outdir/<name>/``; never raises for a bad design.

    Everything is computed in memory first; the files (each written atomically) and the reports
    go to a hidden staging folder ``outdir/.<name>.staging``, which then replaces the design's
    folder. A failure or a kill at any point leaves the previous export untouched, and the next
    run removes the staging folder.

    Returns
    -------
    dict
        ``path``, ``name``, ``ok``, ``status`` ("ok", "failed", "check failed"), ``formats``,
        ``files`` (count written), ``folder``, ``error`` (one line or ""), ``seconds``.
    """
    import shutil

    from ..errors import FabkitError
    from ..export import write_atomic, write_outputs
    from ..report import report_json, report_markdown
    from ..templates import load_template

    t0 = time.perf_counter()
    row = {"path": str(path), "name": Path(path).stem, "ok": False, "status": "failed",
           "formats": [], "files": 0, "folder": "", "error": ""}
    stage = None
    try:
        design = load_template(path)
        row["name"] = design.name
        if not _SAFE_NAME.match(design.name):
            from ..errors import TemplateError

            raise TemplateError(path, "name", f"{design.name!r} cannot be a folder name; use "
                                              "letters, digits, '_', '-', '.' and '+'")
        check_replaceable(Path(outdir) / design.name)  # before the work, not after it
        files, report = build_outputs(design, formats, settings, tolerance_samples, exporters,
                                      previews)
        folder, stage = prepare_folder(outdir, design.name)
        written = write_outputs(files, stage)
        ok = True
        if check:
            results, ok = run_checks(written, design, settings)
            for res in results:
                fmt = next((f for f, v in report["formats"].items()
                            if res["file"] in v.get("files", [])), None)
                if fmt is not None:
                    report["formats"][fmt].setdefault("checks", []).append(res)
                    if not res.get("ok"):
                        report["formats"][fmt]["status"] = "check failed"
        report["ok"] = ok
        write_atomic(stage / "report.md", report_markdown(report))
        write_atomic(stage / "report.json", report_json(report))
        from ..report_html import write_design_report

        write_design_report(stage, design)  # report.html: from report.json and the files
        swap_in(stage, folder)
        stage = None
        row.update(ok=ok, status="ok" if ok else "check failed", folder=str(folder),
                   files=len(written) + 2,
                   formats=[f for f, v in report["formats"].items()
                            if v["status"] not in ("does not apply", "not available",
                                                   "skipped by the template")])
        if not ok:
            bad = [res["file"] for f in report["formats"].values() for res in f.get("checks", [])
                   if not res.get("ok")]
            row["error"] = (f"{path}: as-built check failed for {', '.join(bad)} "
                            f"(see {folder / 'report.md'})")
    except FabkitError as exc:
        row["error"] = str(exc)
    except OSError as exc:
        row["error"] = f"{path}: cannot write the export to {outdir}: {exc}"
    except Exception as exc:  # a bug must not stop the other designs; say where it happened
        import traceback

        if debug:
            raise
        where = traceback.extract_tb(exc.__traceback__)[-1]
        row["error"] = (f"{path}: internal error at {Path(where.filename).name}:{where.lineno}: "
                        f"{type(exc).__name__}: {exc}")
    finally:
        if stage is not None and stage.exists():
            shutil.rmtree(stage, ignore_errors=True)
    row["seconds"] = time.perf_counter() - t0
    return row


# --- many designs ----------------------------------------------------------------------------

class Progress:
    """A one-line progress bar on a terminal (stderr); silent otherwise."""

    def __init__(self, total: int, stream=None):
        self.stream = stream or sys.stderr
        self.total = total
        self.done = 0
        self.active = total > 0 and hasattr(self.stream, "isatty") and self.stream.isatty()

    def step(self, label: str) -> None:
        self.done += 1
        if not self.active:
            return
        width = 30
        fill = int(width * self.done / self.total)
        line = f"\r[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} {label}"
        self.stream.write(line[:100].ljust(100))
        self.stream.flush()

    def close(self) -> None:
        if self.active:
            self.stream.write("\r" + " " * 100 + "\r")
            self.stream.flush()


def summary_table(rows) -> str:
    """The table printed at the end: one line per design."""
    header = ("design", "status", "formats", "files", "time", "output or error")
    body = [(r["name"], r["status"], ",".join(r["formats"]) or "-", str(r["files"]),
             f"{r.get('seconds', 0.0):.1f}s", r["folder"] if r["ok"] else r["error"])
            for r in rows]
    widths = [max(len(x[i]) for x in [header, *body]) for i in range(5)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r[:5], widths)) + "  " + r[5]
             for r in [header, *body]]
    failed = sum(not r["ok"] for r in rows)
    lines.append(f"{len(rows) - failed} exported, {failed} failed")
    return "\n".join(lines)


def export_many(paths, formats=None, outdir="out", settings=None, *, jobs=1, check=True,
                tolerance_samples=None, progress=None, isolate=True, exporters=None,
                previews=True, debug=False) -> list[dict]:
    """Export many templates; one row per template (see :func:`export_one`), in input order.

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
        Monte Carlo builds (0: no tolerance analysis; None: the template's setting).
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
        Let internal errors (bugs, not bad designs) raise with their traceback; implies one
        design at a time in this process.

    Returns
    -------
    list of dict

    Notes
    -----
    Designs with the same name would share a folder: the later ones fail instead.
    """
    import os
    from concurrent.futures import ProcessPoolExecutor, as_completed

    from ..errors import FabkitError
    from ..export import EXPORTERS
    from ..templates import load_template

    settings = settings or {}
    exporters = dict(EXPORTERS if exporters is None else exporters)
    paths = [Path(p) for p in paths]
    rows: list[dict | None] = [None] * len(paths)
    owners: dict[str, Path] = {}
    todo = []
    for i, p in enumerate(paths):
        try:
            name = load_template(p).name
        except FabkitError as exc:
            # a template that does not even load needs no worker: report it here
            rows[i] = {"path": str(p), "name": p.stem, "ok": False, "status": "failed",
                       "formats": [], "files": 0, "folder": "", "seconds": 0.0,
                       "error": str(exc)}
            if progress:
                progress.step(p.stem)
            continue
        if name in owners:
            rows[i] = {"path": str(p), "name": name, "ok": False, "status": "failed",
                       "formats": [], "files": 0, "folder": "", "seconds": 0.0,
                       "error": f"{p}: name: {name!r} is also the name of {owners[name]}; "
                                "each design needs its own name (its output folder)"}
            if progress:
                progress.step(name)
            continue
        owners[name] = p
        todo.append(i)
    args = [(paths[i], formats, outdir, settings, check, tolerance_samples, exporters, previews,
             debug) for i in todo]
    if todo and (isolate or jobs > 1) and not debug:
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")  # fresh interpreters, no forked state
        saved = os.environ.get("PYTHONHASHSEED")
        os.environ["PYTHONHASHSEED"] = "0"  # read by each worker when it starts
        try:
            with ProcessPoolExecutor(max_workers=max(1, min(jobs, len(todo))),
                                     mp_context=ctx) as pool:
                futures = {pool.submit(export_one, *a): i for i, a in zip(todo, args)}
                for fut in as_completed(futures):
                    rows[futures[fut]] = fut.result()
                    if progress:
                        progress.step(rows[futures[fut]]["name"])
        finally:
            if saved is None:
                os.environ.pop("PYTHONHASHSEED", None)
            else:
                os.environ["PYTHONHASHSEED"] = saved
    else:
        for i, a in zip(todo, args):
            rows[i] = export_one(*a)
            if progress:
                progress.step(rows[i]["name"])
    return rows  # type: ignore[return-value]


def run(args) -> int:
    from ..errors import FabkitError
    from . import expand_templates

    if args.jobs < 1:
        raise FabkitError(f"--jobs must be at least 1, got {args.jobs}")
    if args.tolerance_samples is not None and args.tolerance_samples < 0:
        raise FabkitError(f"--tolerance-samples must be 0 or more, got {args.tolerance_samples}")
    formats = parse_formats(args.to)
    settings = parse_settings(args.settings)
    paths = expand_templates(args.paths)
    progress = Progress(len(paths))
    try:
        rows = export_many(paths, formats, args.out, settings, jobs=args.jobs,
                           check=not args.no_check, tolerance_samples=args.tolerance_samples,
                           progress=progress, previews=not args.no_previews,
                           debug=getattr(args, "debug", False))
    finally:
        progress.close()
    if any(r["folder"] for r in rows):
        from ..report_html import write_index

        write_index(args.out)  # index.html of every design folder in the output
    print(summary_table(rows))
    failed = [r for r in rows if not r["ok"]]
    for r in failed:
        print(f"fabkit: error: {r['error']}", file=sys.stderr)
    return 1 if failed else 0
