"""One way to read a file fabkit did not write itself in this run: a regular file, of bounded size.

Files that come back to fabkit (a resumed sweep's chunks, a sweep spec, a drawn curve, the
sibling sheets of a kit) are input like any template. A FIFO at such a path would block the
read forever, a device would never end, and a file may be far larger than its name suggests, so
every such read goes through :func:`read_regular`: the path is opened without blocking, refused
unless it is a regular file, and read only up to a bound.

Examples
--------
>>> import os, tempfile
>>> folder = tempfile.mkdtemp()
>>> os.mkfifo(os.path.join(folder, "spec.json"))
>>> read_regular(os.path.join(folder, "spec.json"), limit=100)  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
fabkit.errors.InputFileError: .../spec.json: is a FIFO (named pipe), not a regular file: refused
"""

from __future__ import annotations

import os
import stat

from ..errors import BoundsError, InputFileError

__all__ = ["read_regular", "file_kind"]


def file_kind(mode: int) -> str:
    """What a file's mode says it is, for a message (``"a FIFO (named pipe)"``)."""
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    return "a file"


def read_regular(path, limit: int, *, what: str = "bytes",
                 override: str = "fabkit --allow-large") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes.

    Parameters
    ----------
    path : str or path-like
    limit : int
        Largest size accepted (the bound is lifted by ``FABKIT_ALLOW_LARGE=1``).
    what : str
        What the limit counts, for the message.
    override : str
        How to lift the limit, for the message.

    Raises
    ------
    InputFileError
        Missing, unreadable, or not a regular file (a FIFO, a device, a folder, a socket):
        refused before reading, since such a read may never end.
    BoundsError
        Larger than ``limit``.
    """
    large = os.environ.get("FABKIT_ALLOW_LARGE", "") == "1"
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise InputFileError(path, "no such file", kind="missing") from None
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):  # before a file object is made of it: a folder's is refused
        os.close(fd)            # with a bare IsADirectoryError
        raise InputFileError(path, f"is {file_kind(mode)}, not a regular file: refused",
                             kind="not_regular")
    with os.fdopen(fd, "rb") as fh:
        size = os.fstat(fd).st_size
        if size > limit and not large:
            raise BoundsError(str(path), what, size, limit, override)
        cap = float("inf") if large else limit + 1
        try:  # the size it has now, and what it grows by meanwhile, up to the bound
            parts = [fh.read(int(min(size + 1, cap)))]
            total = len(parts[0])
            while total > size and total < cap and parts[-1]:
                parts.append(fh.read(int(min(2**24, cap - total))))
                total += len(parts[-1])
        except OSError as exc:
            raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
        data = parts[0] if len(parts) == 1 else b"".join(parts)
    if len(data) > limit and not large:
        raise BoundsError(str(path), what, len(data), limit, override)
    return data
