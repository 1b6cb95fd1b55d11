"""Exceptions raised by fabkit.

Every error derives from :class:`FabkitError`; ``str(error)`` is one line a user can act on. The
command line prints that line and exits with a non-zero code; tracebacks appear only with
``--debug``.
"""

from __future__ import annotations

__all__ = [
    "FabkitError",
    "NetworkError",
    "TemplateError",
    "KinematicsError",
    "ConstructionError",
    "DesignError",
    "FabricationError",
    "ResourceError",
]


class FabkitError(Exception):
    """Base class of all errors that fabkit raises on purpose."""


class NetworkError(FabkitError, ValueError):
    """A network is malformed: bad coordinates, bad indices, duplicate or degenerate edges."""


class TemplateError(FabkitError):
    """A template file cannot be read or fails validation.

    Parameters
    ----------
    path : str
        The template file.
    key : str
        Dotted key path inside the file (``"network.edges[3]"``), or ``""`` for the whole file.
    reason : str
        What is wrong and, where possible, how to fix it.
    """

    def __init__(self, path, key: str, reason: str):
        self.path = str(path)
        self.key = key
        self.reason = reason
        where = f"{self.path}: {key}" if key else self.path
        super().__init__(f"{where}: {reason}")


class KinematicsError(FabkitError):
    """A motion cannot be traced as asked (wrong drive, no motion, unknown option)."""


class ConstructionError(KinematicsError):
    """The network has no construction order by circle/sphere intersections for the drive."""


class DesignError(FabkitError):
    """A module design specification cannot be met."""


class FabricationError(FabkitError):
    """Fabrication settings or geometry that cannot be made; the message suggests a fix."""


class ResourceError(FabkitError):
    """A computation would need more memory than the machine has (raised before allocating)."""
