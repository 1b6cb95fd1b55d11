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
    """Run the as-built check of an exported file (optionally against its design)."""
    return checker_for(path).check_file(path, design=design, settings=settings)
