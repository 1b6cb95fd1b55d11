"""What the laser kit makes of its settings: the window of the motion the kit follows, and
what a cutter is told about the kerf. The settings themselves are
:mod:`fabkit.settings.laser`."""

from __future__ import annotations

from ..settings.laser import LaserSettings
from ..motion.window import motion_window

__all__ = ["kit_design", "kerf_note"]


def kit_design(design, settings: LaserSettings):
    """The design as the kit moves: from ``motion_from`` to ``motion_to`` when they are set.

    See :func:`fabkit.motion.window.motion_window`.

    Parameters
    ----------
    design : Design
    settings : LaserSettings

    Returns
    -------
    Design
        ``design`` itself when neither setting is given.

    Raises
    ------
    FabricationError
        See :func:`fabkit.motion.window.motion_window`.
    """
    return motion_window(design, settings.motion_from, settings.motion_to, "laser")


def kerf_note(settings) -> str:
    """What a cutter must know about the kerf, in one sentence (DXF header, SVG, BOM)."""
    if settings.kerf == 0:
        return ("drawn at true size (kerf 0): let the laser or the cutting service compensate "
                "its kerf")
    return (f"kerf {settings.kerf:g} mm already applied: outlines grown and holes shrunk by "
            f"{0.5 * settings.kerf:g} mm; cut on the line, do not compensate kerf again")
