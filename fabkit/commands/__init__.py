"""Subcommands of the ``fabkit`` command line, one per file (see :mod:`fabkit.cli`)."""

from __future__ import annotations

from pathlib import Path

from ..errors import FabkitError

__all__ = ["expand_templates", "check_output_folder", "check_count", "check_number"]


def expand_templates(paths) -> list[Path]:
    """Template files named by files, folders (their ``*.toml``), glob patterns and names of
    bundled templates (``fourbar``; a file of that name in the current folder wins, see
    :func:`fabkit.templates.resolve_template`), in order."""
    import glob

    from ..errors import InputFileError
    from ..templates import resolve_template

    out: list[Path] = []
    for raw in paths:
        p = resolve_template(raw)
        try:
            p.stat()
        except OSError as exc:
            import errno

            if exc.errno == errno.ELOOP:
                raise InputFileError(p, "symbolic-link loop: the link never reaches a "
                                        "file") from None
        if p.is_dir():
            found = sorted(p.glob("*.toml"))
            if not found:
                raise FabkitError(f"{p}: folder holds no *.toml templates")
            out.extend(found)
        elif set("*?[") & set(str(raw)):  # a glob pattern
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


def check_output_folder(path, option: str = "-o") -> Path:
    """Refuse an output folder that cannot be used, before any work (one line).

    The folder need not exist (it is created when the first file is written), but it must not be
    a file, and the nearest existing folder above it must be writable.

    Raises
    ------
    OutputError
    """
    import os

    from ..errors import OutputError

    p = Path(path)
    probe = p
    while not probe.exists() and not probe.is_symlink() and probe != probe.parent:
        probe = probe.parent
    if probe.is_symlink() and not probe.exists():
        raise OutputError(p, f"{option}: {probe} is a broken symbolic link")
    if not probe.is_dir():
        what = "exists and is not a folder" if probe == p else f"cannot be created: {probe} is " \
                                                              "not a folder"
        raise OutputError(p, f"{option}: {what}; choose another output folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        what = "is not writable" if probe == p else f"cannot be created: {probe} is not writable"
        raise OutputError(p, f"{option}: {what}; choose another output folder")
    return p


def check_count(option: str, value, minimum: int = 1, maximum: int | None = None,
                quantity: str = "") -> None:
    """A whole-number option within ``[minimum, maximum]``: UsageError below, BoundsError above
    (unless ``fabkit --allow-large``)."""
    from ..errors import BoundsError, UsageError
    from ..templates import allow_large

    if value is None:
        return
    if value < minimum:
        raise UsageError(option, f"must be at least {minimum}, got {value}")
    if maximum is not None and value > maximum and not allow_large():
        raise BoundsError(option, quantity or option.lstrip("-"), value, maximum,
                          "fabkit --allow-large", option=True)


def check_number(option: str, value, *, positive: bool = True) -> None:
    """A finite (and, by default, positive) number option; UsageError otherwise."""
    import math

    from ..errors import UsageError

    if value is None:
        return
    if not math.isfinite(value):
        raise UsageError(option, f"must be a finite number, got {value}")
    if positive and value <= 0:
        raise UsageError(option, f"must be positive, got {value}")
