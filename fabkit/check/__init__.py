"""As-built checks: read exported files back, rebuild the network, re-simulate, compare.

One module per file format, each defining ``FORMAT``, ``SUFFIXES`` (file name endings it reads)
and ``check_file(path, design=None, settings=None) -> dict`` (a JSON-serialisable report with at
least ``"ok": bool`` and ``"checks"``: a list of ``{"name", "ok", "value", "limit", "detail"}``).
"""

from __future__ import annotations

import importlib
from pathlib import Path

from ..errors import FabkitError

__all__ = ["CHECKERS", "checker_for", "check_file"]

#: Format name → module implementing its as-built check.
CHECKERS: dict[str, str] = {
    "dxf": "fabkit.check.dxf",
    "fold": "fabkit.check.fold",
    "stl": "fabkit.check.stl",
    "3mf": "fabkit.check.threemf",
}


def checker_for(path):
    """The checker module for a file, chosen by its suffix."""
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in CHECKERS:
        raise FabkitError(f"{path}: no as-built check for .{suffix} files; known: "
                          f"{', '.join('.' + k for k in CHECKERS)}")
    try:
        return importlib.import_module(CHECKERS[suffix])
    except ImportError as exc:
        raise FabkitError(f"the .{suffix} check is not available: {exc}") from None


def check_file(path, design=None, settings=None) -> dict:
    """Run the as-built check of an exported file (optionally against its design).

    The file must be a regular file, and its size goes through the work estimate before it is
    read (readers hold several bytes in memory per byte on disk).

    Raises
    ------
    InputFileError
        Not a regular file (a folder, a FIFO, a device), or missing.
    BoundsError
        Too large to read back within the bounds (``fabkit --allow-large`` lifts them).
    FabkitError
        No check for the file's suffix.
    """
    import os
    import stat

    from ..errors import InputFileError
    from ..workload import require

    module = checker_for(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputFileError(path, "no such file") from None
    except OSError as exc:
        raise InputFileError(path, exc.strerror or str(exc)) from None
    if not stat.S_ISREG(st.st_mode):
        raise InputFileError(path, "not a regular file (a folder, a FIFO or a device)")
    require(f"{path}", ("file byte", st.st_size))
    return module.check_file(path, design=design, settings=settings)
