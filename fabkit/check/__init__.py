"""As-built checks: read exported files back, rebuild the network, re-simulate, compare.

One module per file format, each defining ``FORMAT``, ``SUFFIXES`` (file name endings it reads)
and ``check_file(path, design=None, settings=None, *, folder=None) -> dict``: a
JSON-serialisable report with at least ``"ok": bool`` and ``"checks"``. Every file a check
reads (the one named and the files of its export beside it) is listed, measured and read
through one :class:`fabkit.io.readback.ReadBack`: by path for a user's file, through the held
folder (``folder``, an :class:`~fabkit.io.folder.OutputFolder`) for the files an export has
just staged, which are then never looked up by path again.

Every check is one :class:`fabkit.check.items.Check` (its name, a status of
:data:`fabkit.status.CHECK`, the value measured, its limit and a one-sentence detail), made with
:func:`fabkit.check.items.check` and written into the report by
:func:`fabkit.check.items.finish` as ``{"name", "ok", "value", "limit", "detail"}``; ``ok`` of
the report is true when every check holds. A check that an earlier failure leaves without what
it needs is reported as not run (failed, its detail saying so and why), never left out; the
checks that need the design's template and were given none are named in the report's
``not_checked``, never reported ok.
"""

from __future__ import annotations

import importlib
from pathlib import Path

from ..errors import FabkitError
from ..io.readback import ReadBack
from ..io.workload import require

__all__ = ["CHECKERS", "checker_for", "check_file", "read_set", "require_files",
           "require_checked", "require_triangles", "MAX_TRIANGLES_PER_EDGE"]

#: Most triangles a printed file may hold per bar of the design it is checked against: the
#: bundled prints hold 30 (printed_planar) to 650 (physical_fourbar, round pin holes) a bar. A
#: file far past that is not this design's print, and its check would run for minutes.
MAX_TRIANGLES_PER_EDGE = 5000

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


def check_file(path, design=None, settings=None, *, motion=None, folder=None) -> dict:
    """Run the as-built check of an exported file (optionally against its design).

    The file must be a regular file, and its size goes through the work estimate before it is
    read (readers hold several bytes in memory per byte on disk).

    Parameters
    ----------
    path : str or path-like
    design : Design, optional
    settings : dict, optional
    motion : TracedMotion, optional
        The design's motion traced once by the pipeline.
    folder : OutputFolder, optional
        The held folder of fabkit's own that ``path`` lies in (an export's staging folder): the
        files are read through it, never by path (:class:`fabkit.io.readback.ReadBack`).

    Raises
    ------
    InputFileError
        Not a regular file (a folder, a FIFO, a device), or missing; a file given by path
        that its parser refuses (``kind="damaged"``).
    BoundsError
        Too large to read back within the bounds (``fabkit --allow-large`` lifts them).
    FabkitError
        No check for the file's suffix.
    """
    module = checker_for(path)
    source = ReadBack.of(folder)
    size = source.size(path)
    require(f"{path}", ("file byte", size))  # refused before the checker is loaded
    extra = {"folder": source} if folder is not None else {}
    if motion is not None:  # the design's motion traced once by the pipeline
        extra["motion"] = motion
    return module.check_file(path, design=design, settings=settings, **extra)


def require_checked(where: str, *parts):
    """Estimate the work of a check from counts read in the file, refuse it past the bounds,
    and hold the check to it (:func:`fabkit.stoppable.keep_to`); returns the estimate."""
    from ..stoppable import keep_to

    est = require(where, *parts)
    keep_to(est)
    return est


def require_triangles(path, triangles: int, design=None):
    """The check of ``triangles`` placed triangles within the estimate, and, against a
    design, within :data:`MAX_TRIANGLES_PER_EDGE` a bar of it, before any mesh is built.

    Raises
    ------
    InputFileError
        ``kind="bounds"``: far more triangles than the design's print holds.
    BoundsError
        Past the estimate.
    """
    from ..io.formats import refuse_count

    est = require_checked(f"{path}", ("placed triangle", triangles))
    net = getattr(design, "network", None)
    if net is not None:
        refuse_count(path, f"triangles for a design of {len(net.edges)} bars", triangles,
                     MAX_TRIANGLES_PER_EDGE * max(1, len(net.edges)),
                     f" ({MAX_TRIANGLES_PER_EDGE} a bar): not this design's print")
    return est


def require_files(paths, folder=None) -> None:
    """Estimate reading the files of one export back together (the beds of a print, the
    sheets of a kit) by their total size, before any of them is read: a sibling far larger
    than the file named is counted too. ``folder``: as for :func:`check_file`.

    Raises
    ------
    InputFileError
        A file that is not a regular file (a FIFO, a device, a folder), or missing.
    BoundsError
        Their total size is past the bounds.
    """
    source = ReadBack.of(folder)
    total = sum(source.size(p) for p in paths)
    paths = [Path(p) for p in paths]
    where = str(paths[0]) if len(paths) == 1 else (
        f"{paths[0]} with the files of its export beside it "
        f"({', '.join(p.name for p in paths[1:4])}{', ...' if len(paths) > 4 else ''})")
    require_checked(where, ("file byte", total))


def read_set(paths, folder=None) -> dict:
    """The bytes of the files of one export, path -> bytes, after :func:`require_files`.
    ``folder``: as for :func:`check_file`.

    Raises
    ------
    InputFileError, BoundsError
        As :func:`require_files`.
    """
    from ..io.workload import MAX_BYTES

    source = ReadBack.of(folder)
    require_files(paths, source)
    return {p: source.read(p, MAX_BYTES) for p in paths}
