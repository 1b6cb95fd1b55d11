"""The names fabkit writes under an output folder, and the check of the folder a user chose.

:func:`check_name` checks one name that fabkit puts under an output folder (a design's folder,
a file), so that a name can never leave the folder; :func:`output_folder` checks the folder the
user chose (``-o``) before any work; :data:`OWN_PATTERN` is what the hidden entries fabkit keeps
there look like.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from ..errors import OutputError, UnsafeNameError

__all__ = ["NAME_PATTERN", "MAX_NAME_LENGTH", "RESERVED_NAMES", "OWN_PATTERN", "check_name",
           "output_folder"]

#: What a name fabkit writes may look like: letters, digits and ``_ . + -``, starting with a
#: letter or digit (so never ``.``, ``..`` or a hidden file, and never an option like ``-x``).
NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")

#: Longest name accepted: file systems allow 255 bytes, and fabkit adds suffixes of its own
#: (``.staging``, ``.<random>.part``) to the names it stages.
MAX_NAME_LENGTH = 120

#: Names that fabkit itself writes at the top of an output folder (a design named like one of
#: them would overwrite it or be overwritten), and names that Windows reserves for devices (an
#: output folder shared with a Windows machine could not hold them). Compared without case and,
#: for the device names, without extension.
RESERVED_NAMES = frozenset({"index.html", "sweep.csv", "sweep.json", "chunks", "bench"})
_DEVICE_NAMES = frozenset({"con", "prn", "aux", "nul", *(f"com{i}" for i in range(10)),
                           *(f"lpt{i}" for i in range(10))})


def check_name(name, what: str = "name", *, reserved: bool = True) -> str:
    """Return ``name`` when it is safe as one file or folder name inside an output folder.

    Parameters
    ----------
    name : str
        The name (one path component).
    what : str
        What the name is, for the message (``"template name"``, ``"file name"``).
    reserved : bool
        Also refuse the names fabkit writes at the top of an output folder
        (:data:`RESERVED_NAMES`); device names are refused always.

    Raises
    ------
    UnsafeNameError
        Not a string, empty, too long, with a separator, ``..``, a control character or any
        character outside :data:`NAME_PATTERN`, or a reserved name. The message says why.

    Examples
    --------
    >>> check_name("super_stable_chain")
    'super_stable_chain'
    >>> check_name("../../escaped")
    Traceback (most recent call last):
    ...
    fabkit.errors.UnsafeNameError: name '../../escaped' would leave the output folder (it holds '/' or '..'); use letters, digits, '_', '-', '.' and '+'
    """
    if not isinstance(name, str):
        raise UnsafeNameError(what, name, f"must be a string, got {type(name).__name__}")
    if not name:
        raise UnsafeNameError(what, name, "is empty; every output needs a name of its own")
    if any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise UnsafeNameError(what, name, "holds a control character")
    if "/" in name or "\\" in name or name in (".", "..") or name.startswith(".."):
        raise UnsafeNameError(what, name, "would leave the output folder (it holds '/' or "
                                          "'..')" + _ALLOWED)
    if len(name) > MAX_NAME_LENGTH:
        raise UnsafeNameError(what, name, f"is {len(name)} characters long; at most "
                                          f"{MAX_NAME_LENGTH}")
    if not NAME_PATTERN.match(name):
        first = next((c for c in name if not re.match(r"[A-Za-z0-9_.+-]", c)), name[0])
        why = (f"may not start with {first!r}" if NAME_PATTERN.match("a" + name[1:])
               else f"holds {first!r}")
        raise UnsafeNameError(what, name, why + _ALLOWED)
    lower = name.lower()
    if lower.split(".", 1)[0] in _DEVICE_NAMES:
        raise UnsafeNameError(what, name, "is a device name that Windows reserves; choose "
                                          "another")
    if reserved and lower in RESERVED_NAMES:
        raise UnsafeNameError(what, name, "is a name fabkit writes itself at the top of an "
                                          "output folder; choose another")
    return name


_ALLOWED = "; use letters, digits, '_', '-', '.' and '+'"


def output_folder(path, option: str = "-o") -> Path:
    """Check an output folder the user chose, before any work (one line on refusal).

    The folder need not exist (it is created when the first file is written), but it must be
    given, it must not be a file, and the nearest existing folder above it must be writable.

    Parameters
    ----------
    path : str or path-like
    option : str
        The option that gave it, for the message.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    OutputError
    """
    text = os.fspath(path) if isinstance(path, os.PathLike) else path
    if not isinstance(text, str):
        raise OutputError(repr(path), f"{option}: must be a folder path, got "
                                      f"{type(path).__name__}")
    if not text.strip():
        raise OutputError(repr(text), f"{option}: is empty; give an output folder (e.g. "
                                      f"{option} out)")
    if any(ord(c) < 32 or ord(c) == 127 for c in text):
        raise OutputError(repr(text), f"{option}: holds a control character")
    p = Path(text)
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


#: What the hidden entries fabkit keeps in an output folder look like: ``.fabkit.lock``,
#: ``.<design>.staging``, ``.<design>.old``.
OWN_PATTERN = re.compile(r"^\.[A-Za-z0-9][A-Za-z0-9_.+-]*$")
