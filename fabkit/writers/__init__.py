"""Writers: one module per file format behind one :func:`export` entry (like trimesh.exchange).

Each format module defines ``FORMAT`` (its name), ``PROCESS`` (the process whose plan it is
written from: ``"laser"``, ``"print"`` or ``"origami"``, :data:`fabkit.fab.plans.PLANNERS`) and
``write(plan) -> ExportResult``: pure, it turns the plan into the bytes of every file to write
and a report dict; it traces nothing, plans nothing and never opens a file. The batch engine
builds each process's plan once for all of that process's formats. ``export_design(design,
settings)`` is the one-call shortcut (plan, then write). An exporter of one's own registered in
:data:`EXPORTERS` may define ``export_design`` alone. Only :func:`write_outputs` writes, through
a temporary file in the target folder and ``os.replace`` (:mod:`fabkit.io.outputs`), so that no
half-written file is ever left behind.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ArgumentTypeError, FabkitError, OutputError, UnavailableError
from ..io.outputs import LOCK_NAME, OutputFolder, OutputLock, write_atomic, write_files
from ..templates import Design

__all__ = ["EXPORTERS", "ExportResult", "get_exporter", "format_process", "applies",
           "skip_reason", "write_atomic", "write_outputs", "export", "check_export_settings"]

#: Format name → module implementing it (imported only when the format is used, so a missing
#: optional dependency matters only to its own format).
EXPORTERS: dict[str, str] = {
    "dxf": "fabkit.writers.dxf",
    "svg": "fabkit.writers.svg",
    "fold": "fabkit.writers.fold",
    "stl": "fabkit.writers.stl",
    "cp": "fabkit.writers.cp",
}


@dataclass
class ExportResult:
    """What an exporter produces.

    Attributes
    ----------
    files : dict of str to bytes
        File name (relative to the design's output folder) → content.
    report : dict
        JSON-serialisable facts for report.json (checks, measurements, warnings).
    """

    files: dict[str, bytes] = field(default_factory=dict)
    report: dict = field(default_factory=dict)


def check_export_settings(settings, exporters: dict | None = None) -> dict:
    """Check overrides nested by section against :mod:`fabkit.io.schema`, with the sections that
    export formats of one's own declare (a module-level ``SETTINGS``, a
    :class:`fabkit.io.schema.Section` subclass). Returns the settings unchanged.

    Raises
    ------
    SettingsError
    """
    from ..io.schema import OVERRIDE_SECTIONS, check_settings

    registry = EXPORTERS if exporters is None else exporters
    extra = {}
    for key in settings or {}:
        if key not in OVERRIDE_SECTIONS and key in registry:
            model = getattr(importlib.import_module(registry[key]), "SETTINGS", None)
            if model is not None:
                extra[key] = model
    return check_settings(settings, sections=extra)


def get_exporter(fmt: str, exporters: dict | None = None):
    """The module that implements a format, from a registry (name → module path; default
    :data:`EXPORTERS`, as it is now). The one lookup of formats: the API, the batch engine and
    the commands use it.

    Raises
    ------
    FabkitError
        The format is not in the registry (the message lists the valid ones).
    UnavailableError
        Its module cannot be imported (a missing optional dependency).
    """
    registry = EXPORTERS if exporters is None else exporters
    try:
        name = registry[fmt]
    except (KeyError, TypeError):
        raise FabkitError(f"unknown export format {fmt!r}; valid: {', '.join(registry)}") from None
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        raise UnavailableError(f"export format {fmt!r}", str(exc)) from None


def format_process(fmt: str, exporters: dict | None = None) -> str | None:
    """The process (``PROCESS``) of a registered format's module, read without importing the
    module when it is not imported yet (``fabkit export --help`` names every format with its
    process, and must not load the DXF, mesh and plotting libraries the writers use).

    The module's source is parsed for a top-level ``PROCESS = "..."``; None when the format
    has none that can be read so (an exporter of one's own that computes it, or one without a
    source file), or is not registered.

    Examples
    --------
    >>> format_process("dxf"), format_process("stl"), format_process("png")
    ('laser', 'print', None)
    """
    import ast
    import importlib.util
    import sys

    name = (EXPORTERS if exporters is None else exporters).get(fmt)
    if name is None:
        return None
    if name in sys.modules:
        return getattr(sys.modules[name], "PROCESS", None)
    try:
        spec = importlib.util.find_spec(name)
        tree = ast.parse(Path(spec.origin).read_text(encoding="utf-8"))
    except (ImportError, ValueError, AttributeError, TypeError, OSError, SyntaxError):
        return None  # not found or not a source file: no process to name
    for node in tree.body:
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant) and any(
                isinstance(t, ast.Name) and t.id == "PROCESS" for t in node.targets):
            return node.value.value if isinstance(node.value.value, str) else None
    return None


def skip_reason(design, fmt: str) -> str | None:
    """Why a template opts out of a format (``[fabrication] skip = { dxf = "reason" }``), or None."""
    skip = (getattr(design, "fabrication", None) or {}).get("skip", {})
    if isinstance(skip, dict) and fmt in skip:
        return str(skip[fmt])
    return None


def applies(design, fmt: str, module=None) -> bool:
    """True when a format's exporter applies to a design and the template does not opt out."""
    module = module or get_exporter(fmt)
    check = getattr(module, "applies", None)
    return (check is None or bool(check(design))) and skip_reason(design, fmt) is None


def write_outputs(files: dict[str, bytes], outdir) -> list[Path]:
    """Write every file of an :class:`ExportResult`, all or nothing
    (:func:`fabkit.io.outputs.write_files`); returns the paths written."""
    return write_files(outdir, files)


def export(design, fmt: str, outdir, **settings) -> tuple[list[Path], dict]:
    """Export a design in one format into ``outdir``.

    All content is computed first; nothing is written when the exporter raises.

    Parameters
    ----------
    design : Design
    fmt : str
        A key of :data:`EXPORTERS`.
    outdir : path or OutputFolder
        The folder to write into: opened once, before the work, and held
        (:class:`~fabkit.io.folder.OutputFolder`); the files, the lock and the look for an
        export's report go through that handle, never through a path looked up again.
    **settings : dict
        Overrides nested by section, as ``--set`` gives them (``laser={"kerf": 0.2}``); every
        section and key is checked against :mod:`fabkit.io.schema`.

    Returns
    -------
    paths : list of pathlib.Path
    report : dict

    Raises
    ------
    SettingsError
        An unknown section or key, or a value of the wrong type or out of range.
    ArgumentTypeError
        ``design`` is not a Design.
    OutputError
        ``outdir`` is not a folder path, or cannot be created or written.
    FolderChangedError
        The folder was moved, removed or replaced while the files were computed.
    """
    check_export_settings(settings)  # a misspelt section (lazer=...) must not pass unnoticed
    if not isinstance(design, Design):
        raise ArgumentTypeError("design", "must be a fabkit Design (fabkit.load_template), got "
                                          f"{type(design).__name__}")
    module = get_exporter(fmt)
    with OutputFolder.held(outdir, "outdir") as held:  # one handle, opened before the work
        refuse_export_folder(held)
        result: ExportResult = module.export_design(design, settings)
        with export_locks(held):
            refuse_export_folder(held)  # it may have become one while we computed
            return write_outputs(result.files, held), result.report


def refuse_export_folder(outdir) -> None:
    """Refuse a folder that holds the kit and report of a ``fabkit export``.

    One format written there by hand would leave a folder whose report describes other files
    (a DXF cut with kerf 0.2 beside a report that says 0.15); such a folder is rewritten only
    by ``fabkit export``, which makes its report too.

    Raises
    ------
    OutputError
        ``outdir`` holds ``report.json``.
    """
    if isinstance(outdir, OutputFolder):  # the folder held: its entry, never through a link
        st = outdir.lstat("report.json") if outdir.identity is not None or \
            os.path.lexists(outdir.path) else None
        found = st is not None and stat.S_ISREG(st.st_mode)
    else:
        found = (Path(outdir) / "report.json").is_file()
    if found:
        raise OutputError(outdir, "holds the kit and report of a `fabkit export` (report.json): "
                                  "write into another folder, or export again with `fabkit "
                                  "export NAME --to FORMAT --set ...` so that the report "
                                  "says what the files are")


@contextlib.contextmanager
def export_locks(outdir):
    """Hold the lock of ``outdir`` (a path or a held :class:`~fabkit.io.folder.OutputFolder`;
    created if need be) and, when ``fabkit export`` may be writing into the folder above it
    (its lock file is there), that folder's lock too.

    Raises
    ------
    LockedError
        Another export holds either lock.
    """
    with contextlib.ExitStack() as stack:
        held = stack.enter_context(OutputFolder.held(outdir, "outdir"))
        parent = Path(os.path.abspath(held.path)).parent
        if os.path.lexists(parent / LOCK_NAME):
            stack.enter_context(OutputLock(parent))
        held.fd  # noqa: B018 - created (with its parents) and opened now
        stack.enter_context(OutputLock(held))
        yield
