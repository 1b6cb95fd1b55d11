"""Subcommands of the ``fabkit`` command line, one per file (see :mod:`fabkit.cli`).

Options that mean the same in several commands are added here, so that they are spelt the same
everywhere: ``-o/--out-dir DIR`` (the output folder), ``-j/--jobs N`` (parallel processes),
``--set SECTION.KEY=VALUE`` (settings), ``-q/--quiet`` and ``--progress`` (progress lines, on
stderr: :mod:`fabkit.io.progress`). Each command's ``EXAMPLES`` end its ``--help``.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

from ..errors import BoundsError, FabkitError, InputFileError, UsageError
from ..io.outputs import output_folder, OutputFolder
from ..templates import allow_large, resolve_template
from ..io.progress import Progress

__all__ = ["expand_templates", "each_template", "check_output_folder", "out_folder", "check_count",
           "check_jobs", "check_number", "Example", "examples_epilog", "add_out_dir",
           "add_jobs", "add_settings", "add_progress_options", "progress_for",
           "short_list", "TOLERANCE_SAMPLES"]


# --- the help's examples ---------------------------------------------------------------------

@dataclass(frozen=True)
class Example:
    """One example at the end of a command's ``--help``.

    Attributes
    ----------
    command : str
        The command line, as typed (``fabkit export super_stable --to dxf``).
    says : str
        What it does, one short line.
    cheap : bool
        Quick enough for the test suite to run it (the others are parsed only).
    needs : tuple of str
        Command lines to run first, for the files this one reads.
    """

    command: str
    says: str
    cheap: bool = True
    needs: tuple = ()


def examples_epilog(examples) -> str:
    """The ``Examples:`` section that ends a command's ``--help``."""
    lines = ["Examples:"]
    for e in examples:
        lines += [f"  {e.command}", f"      {e.says}"]
    return "\n".join(lines)


# --- options spelt the same in every command -------------------------------------------------

#: Monte Carlo builds of the tolerance analysis when neither an option (``export
#: --tolerance-samples``, ``tolerance --samples``) nor the template sets them: the default of
#: :class:`fabkit.tolerance.spec.ToleranceSpec` (tests/test_cli_startup.py holds them equal),
#: stated here for the help, which must not import the tolerance analysis (and scipy with it).
TOLERANCE_SAMPLES = 200


def add_out_dir(p, default, help: str, *, ambiguous: str | None = None, **kwargs) -> None:
    """``-o/--out-dir DIR``: the output folder (``--out``, the older spelling, still works and
    is not shown). With ``ambiguous`` (a command with another ``--...-out`` option, such as
    ``map --d-out``), ``--out`` is refused with that text instead of naming a folder."""
    p.add_argument("-o", "--out-dir", dest="out_dir", default=default, metavar="DIR",
                   help=help, **kwargs)
    if ambiguous is not None:
        p.add_argument("--out", dest="out_dir", default=argparse.SUPPRESS, metavar="X",
                       help=argparse.SUPPRESS, action=_Refused, refusal=ambiguous)
        return
    p.add_argument("--out", dest="out_dir", default=argparse.SUPPRESS, metavar="DIR",
                   help=argparse.SUPPRESS, **kwargs)


class _Refused(argparse.Action):
    """An option refused with a one-line reason (a spelling that could mean two things)."""

    def __init__(self, *args, refusal: str, **kwargs):
        super().__init__(*args, **kwargs)
        self.refusal = refusal

    def __call__(self, parser, namespace, values, option_string=None):
        raise argparse.ArgumentError(self, self.refusal)


def add_jobs(p, default, help: str) -> None:
    """``-j/--jobs N``: work in parallel processes."""
    p.add_argument("-j", "--jobs", type=int, default=default, metavar="N", help=help)


def add_settings(p, help: str) -> None:
    """``--set SECTION.KEY=VALUE`` (repeatable): settings over the template's, read as TOML
    values (:func:`fabkit.commands.settings.parse_settings`)."""
    p.add_argument("--set", dest="settings", action="append", default=[],
                   metavar="SECTION.KEY=VALUE", help=help)


def add_progress_options(p) -> None:
    """``-q/--quiet`` and ``--progress``: progress lines on stderr, shown on a terminal."""
    group = p.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true",
                       help="no progress lines (they go to stderr, shown when it is a terminal)")
    group.add_argument("--progress", action="store_true",
                       help="progress lines on stderr even when it is not a terminal (a log, "
                            "a CI job)")


def progress_for(args, command: str):
    """The :class:`~fabkit.io.progress.Progress` of a command, as ``-q``/``--progress``
    ask."""
    quiet, forced = getattr(args, "quiet", False), getattr(args, "progress", False)
    return Progress(f"fabkit {command}", show=False if quiet else True if forced else None)


# --- templates -------------------------------------------------------------------------------


def expand_templates(paths) -> list[Path]:
    """Template files named by files, folders (their ``*.toml``), glob patterns and names of
    bundled templates (``fourbar``; a file of that name in the current folder wins, see
    :func:`fabkit.templates.resolve_template`), in order."""
    import glob

    out: list[Path] = []
    for raw in paths:
        p = resolve_template(raw)
        try:
            p.stat()
        except OSError as exc:
            import errno

            if exc.errno == errno.ELOOP:
                raise InputFileError(p, "symbolic-link loop: the link never reaches a "
                                        "file", kind="loop") from None
        if p.is_dir():
            found = sorted(p.glob("*.toml"))
            if not found:
                raise FabkitError(f"{p}: folder holds no *.toml templates")
            out.extend(found)
        elif set("*?[") & set(str(raw)) and not p.is_file():  # a glob pattern, not a file
            found = sorted(Path(g) for g in glob.glob(str(raw)))
            if not found:
                raise FabkitError(f"{raw}: no file matches")
            out.extend(found)
        else:
            out.append(p)
    seen, unique = set(), []
    for p in out:
        try:
            key = p.resolve()
        except (OSError, RuntimeError):  # a link loop inside a folder: load_template says so
            key = p.absolute()
        if key not in seen:
            seen.add(key)
            unique.append(p)
    return unique


def short_list(paths) -> str:
    """``"a.toml, b.toml, c.toml, ..."``: the first three file names, for a progress line."""
    return ", ".join(p.name for p in paths[:3]) + (", ..." if len(paths) > 3 else "")


def each_template(paths, work, *, debug: bool = False, progress=None) -> int:
    """Run ``work(path)`` for every template named by ``paths`` (see :func:`expand_templates`).

    A fabkit error of one template is printed as one line that names the template, and the
    others still run (as ``fabkit export`` does). ``work`` returns True when its template
    failed in a way it has already reported (a target not reached, a flagged design).
    With a :class:`~fabkit.io.progress.Progress`, the templates are its count (``work`` names
    its own stages with ``progress.stage(text)``).

    Returns
    -------
    int
        The exit code: 0 when every template succeeded, else the highest exit code of the
        failures (1, or 2 for a usage error).
    """
    import sys

    code = 0
    found = expand_templates(paths)
    if progress is not None:
        progress.stage(short_list(found), total=len(found), unit="templates")
    for path in found:
        ended, error = "done", None
        try:
            if work(path):
                code, ended = max(code, 1), "failed"
        except FabkitError as exc:
            ended = "failed"
            if debug:
                raise
            text = str(exc)
            named = str(path) in text or getattr(exc, "path", None) is not None
            error = f"fabkit: error: {text if named else f'{path}: {text}'}"
            code = max(code, int(exc.exit_code))
        if progress is not None:
            progress.advance(text=f"{path.name}: {ended}")
        if error is not None:  # after the progress line: the error is what a reader sees last
            print(error, file=sys.stderr)
    if progress is not None:
        progress.close()
    return code


def check_output_folder(path, option: str = "-o") -> Path:
    """Refuse an output folder that cannot be used, before any work (one line): the one guard
    of :func:`fabkit.io.outputs.output_folder`.

    Raises
    ------
    OutputError
    """
    return output_folder(path, option)


def out_folder(args, dest: str = "out_dir"):
    """The handle on the command's output folder (:class:`fabkit.io.folder.OutputFolder`):
    the one the command line opened before any work (``args.out_folder``), else one opened now
    on ``args.<dest>``; every file of the command is written through it.

    Returns
    -------
    OutputFolder
    """
    held = getattr(args, "out_folder", None)
    if held is None:
        held = args.out_folder = OutputFolder.open(getattr(args, dest))
    return held


def check_count(option: str, value, minimum: int = 1, maximum: int | None = None,
                quantity: str = "") -> None:
    """A whole-number option within ``[minimum, maximum]``: UsageError below, BoundsError above
    (unless ``fabkit --allow-large``)."""
    if value is None:
        return
    if value < minimum:
        raise UsageError(option, f"must be at least {minimum}, got {value}")
    if maximum is not None and value > maximum and not allow_large():
        raise BoundsError(option, quantity or option.lstrip("-"), value, maximum,
                          "fabkit --allow-large", option=True)


def check_jobs(option: str, value) -> None:
    """Worker processes: at least 1 and, unless ``fabkit --allow-large``, no more than the cores
    this process may run on (more only share them, each with its own memory)."""
    import os

    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        cores = os.cpu_count() or 1
    check_count(option, value, 1, cores, f"worker processes (this machine has {cores} "
                                         "cores)")


def check_number(option: str, value, *, positive: bool = True) -> None:
    """A finite (and, by default, positive) number option; UsageError otherwise."""
    import math

    if value is None:
        return
    if not math.isfinite(value):
        raise UsageError(option, f"must be a finite number, got {value}")
    if positive and value <= 0:
        raise UsageError(option, f"must be positive, got {value}")
