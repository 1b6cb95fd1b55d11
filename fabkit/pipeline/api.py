"""The command line's work as Python functions: :func:`export` runs ``fabkit export`` on a design.

Imported on first use (``fabkit.export``), so that ``import fabkit`` stays light; it is part of
the batch engine (:mod:`fabkit.pipeline`), which does the work.
"""

from __future__ import annotations

from ..errors import ArgumentTypeError, ArgumentValueError
from ..io.suggest import did_you_mean
from ..templates import Design
from ..writers import EXPORTERS
from . import DesignResult, export_many

__all__ = ["export"]


def _formats(to) -> list[str] | None:
    """``"dxf,stl"``, ``["dxf", "stl"]`` or None (every format that applies), checked against
    the format registry."""
    if to is None:
        return None
    if isinstance(to, str):
        names = [t.strip().lower() for t in to.split(",") if t.strip()]
    elif isinstance(to, (list, tuple)) and all(isinstance(t, str) for t in to):
        names = [t.strip().lower() for t in to]
    else:
        raise ArgumentTypeError("to", f"must be a format name or a list of them, got "
                                      f"{type(to).__name__}")
    if not names:
        raise ArgumentValueError("to", "names no format; give at least one, e.g. to=\"dxf\"")
    for name in names:
        if name not in EXPORTERS:
            hint = did_you_mean(name, EXPORTERS)
            raise ArgumentValueError("to", f"names an unknown format {name!r}; "
                                     + (f"{hint} " if hint else "")
                                     + f"valid: {', '.join(EXPORTERS)}")
    return list(dict.fromkeys(names))


def export(design, to=None, out="out", *, settings: dict | None = None, check: bool = True,
           previews: bool = True, tolerance_samples: int | None = None, wait: bool = False,
           allow_large: bool = False) -> DesignResult:
    """Export a design for fabrication, as ``fabkit export`` does: plan, files, as-built checks,
    verdict and reports, into ``out/<name>/``.

    Parameters
    ----------
    design : Design, str or pathlib.Path
        A design (:func:`fabkit.load_template`, :meth:`fabkit.Design.from_network`, the design
        of :func:`fabkit.design_map`), a template file or a bundled template's name.
    to : str or list of str, optional
        Formats, ``"dxf"``, ``"stl"``, ``"dxf,stl"`` or ``["dxf", "stl"]`` (None: every format
        that applies to the design). ``dxf`` is the laser-cut kit, ``stl`` the 3D print (STL and
        3MF), ``svg``, ``fold`` and ``cp`` origami sheets.
    out : str or pathlib.Path
        Output folder; the design's files go to ``out/<name>/`` (with ``out/index.html``).
    settings : dict, optional
        Fabrication setting overrides nested by section, as ``--set`` gives them
        (``{"laser": {"kerf": 0.2}}``).
    check : bool
        Check the written files as built (``--no-check`` is False).
    previews : bool
        Draw the preview pictures (motion, map, tolerance).
    tolerance_samples : int, optional
        Monte Carlo builds of the tolerance analysis (0: none; None: the template's setting,
        else the analysis's default).
    wait : bool
        Wait for another export into the same folder to finish, instead of refusing.
    allow_large : bool
        Lift the size bounds (``fabkit --allow-large``).

    Returns
    -------
    DesignResult
        ``status`` (``Status.OK`` when every file was made and passed its checks), ``message``
        (one line when not), ``folder``, ``formats`` (each a ``FormatResult`` with its
        ``files`` and ``checks``), ``level`` and ``headline`` (the verdict of report.md).

    Raises
    ------
    ArgumentError
        A format that does not exist.
    SettingsError, UsageError
        A bad setting, or one that no format of this export reads.
    OutputError, LockedError
        The output folder cannot be written, or another export holds it.

    See Also
    --------
    fabkit.pipeline.export_many : many templates at once, in worker processes.

    Examples
    --------
    >>> import tempfile, fabkit
    >>> with tempfile.TemporaryDirectory() as out:
    ...     result = fabkit.export("fourbar", to="dxf", out=out, previews=False,
    ...                            tolerance_samples=0)
    ...     result.ok, result.exported_formats, all(c.ok for c in result.checks)
    (True, ['dxf'], True)
    """
    if not isinstance(design, Design) and not isinstance(design, str) \
            and not hasattr(design, "__fspath__"):
        raise ArgumentTypeError("design", f"must be a fabkit Design, a template file or a "
                                          f"bundled template's name, got "
                                          f"{type(design).__name__}")
    # one design in this process (no worker to hand a design made in code to)
    return export_many([design], _formats(to), out, settings, jobs=1, check=check,
                       tolerance_samples=tolerance_samples, isolate=False, previews=previews,
                       wait=wait, allow_large=allow_large)[0]
