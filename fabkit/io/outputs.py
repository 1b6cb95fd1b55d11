"""One guard for every path fabkit writes, and one way to write a set of files.

A template travels: people share them, and a template's ``name`` becomes a folder name. Every
command and API function that writes therefore goes through this module:

- :func:`output_folder` checks the folder the user chose (``-o``) before any work;
- :func:`check_name` checks one name that fabkit puts under it (a design's folder, a file), so a
  name can never leave the folder: no ``..``, no separator, nothing absolute, no control
  character, no hidden or reserved name;
- :func:`inside` joins names under a folder with :func:`check_name` and refuses a path that a
  symbolic link would lead out of the folder;
- :func:`write_files` writes a set of files all-or-nothing: every file goes to a temporary file
  beside its target first, and only when all of them are complete are they renamed into place.
  A failure (a full disk included) removes the temporary files and names the file it could not
  write; nothing half-written is left.
- :func:`own_entry` and :func:`open_own_file` give the hidden entries fabkit keeps at the top of
  an output folder (the lock file, a design's staging and backup folders): never a symbolic
  link (followed or moved into place), never a FIFO or a device (opening one blocks), always a
  regular file or a folder of its own.

The batch engine (``fabkit export``) adds a staging folder swapped in whole on top of this.
"""

from __future__ import annotations

import os
import stat
import time
from pathlib import Path

from ..errors import LockedError, OutputError, UnsafeNameError
from .folder import OutputFolder
from .inputs import file_kind
from .names import (check_name, MAX_NAME_LENGTH, NAME_PATTERN, output_folder, OWN_PATTERN,
                    RESERVED_NAMES)

__all__ = ["NAME_PATTERN", "MAX_NAME_LENGTH", "RESERVED_NAMES", "OWN_PATTERN", "check_name",
           "output_folder", "OutputFolder", "inside", "own_entry", "open_own_file", "write_files", "write_atomic", "LOCK_NAME",
           "OutputLock"]

def inside(folder, *names: str, what: str = "name", replace_last: bool = False) -> Path:
    """``folder / name / ...`` with every name checked by :func:`check_name`.

    A name may be a relative POSIX path (``"chunks/chunk-0000000-0000099.json"``); each of its
    parts is checked. :data:`RESERVED_NAMES` are not refused here: fabkit writes them itself;
    names that come from a user (a template's ``name``) are checked with :func:`check_name`
    where they are read.

    ``replace_last``: the path is a file about to be replaced by a rename, which replaces a
    symbolic link in its place instead of writing through it, so a link there is allowed.

    Raises
    ------
    UnsafeNameError
        A name that is unsafe (see :func:`check_name`).
    OutputError
        An existing part of the path is a symbolic link that leads out of ``folder``.
    """
    root = Path(folder)
    path = root
    for name in names:
        parts = name.split("/") if isinstance(name, str) and name else (name,)
        for part in parts:
            check_name(part, what, reserved=False)
            path = path / part
    _refuse_escape(root, path.parent if replace_last and path != root else path)
    return path


def _refuse_escape(root: Path, path: Path) -> None:
    """A symbolic link met under ``root`` must not lead out of it."""
    try:
        base = root.resolve()
    except (OSError, RuntimeError):
        return  # the folder does not exist yet: nothing under it can be a link
    probe = root
    for part in path.relative_to(root).parts:
        probe = probe / part
        if probe.is_symlink():
            try:
                target = probe.resolve()
            except (OSError, RuntimeError):
                raise OutputError(probe, "is a symbolic link that leads nowhere; remove it or "
                                         "choose another output folder") from None
            if target != base and base not in target.parents:
                raise OutputError(probe, f"is a symbolic link to {target}, outside the output "
                                         f"folder {root}; fabkit does not write through it")


def own_entry(folder, name: str, kind: str = "folder") -> Path:
    """``folder / name`` for a hidden entry that fabkit itself keeps there, checked.

    The entry may be missing (fabkit creates it); when it exists it must be what fabkit would
    have made: a ``kind`` (``"folder"`` or ``"file"``) and never a symbolic link, wherever the
    link points (fabkit moves, removes and locks these entries, and a link would carry that
    onto its target). ``folder`` itself is checked as :func:`inside` checks a path.

    Raises
    ------
    UnsafeNameError
        ``name`` is not a hidden name of the form fabkit uses.
    OutputError
        The entry is a symbolic link, or not a ``kind``; the message names it.
    """
    if not isinstance(name, str) or not OWN_PATTERN.match(name) or len(name) > 255:
        raise UnsafeNameError("entry name", name, "is not a name fabkit keeps in an output "
                                                  "folder")
    path = Path(folder) / name
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return path
    except OSError as exc:
        raise OutputError(path, f"cannot be examined: {exc.strerror or exc}") from None
    if stat.S_ISLNK(st.st_mode):
        raise OutputError(path, "is a symbolic link where fabkit keeps its own "
                                f"{kind}; fabkit does not follow it: remove it")
    want = stat.S_ISDIR if kind == "folder" else stat.S_ISREG
    if not want(st.st_mode):
        raise OutputError(path, f"is {file_kind(st.st_mode)} where fabkit keeps its own "
                                f"{kind}; remove it")
    return path


def open_own_file(path) -> int:
    """Open (creating it) a file fabkit keeps and updates in place, such as a lock file.

    Opened without following a symbolic link and without blocking on a FIFO, then refused
    unless it is a regular file: nothing outside the output folder is truncated or written,
    and no special file is waited on.

    Returns
    -------
    int
        The file descriptor (read and write).

    Raises
    ------
    OutputError
        A link, a FIFO, a device or a folder at ``path``, or a file that cannot be opened.
    """
    path = Path(path)
    with OutputFolder.open(path.parent, "folder") as folder:  # the folder's fd closes after
        return folder.open_own(path.name)


def write_atomic(path, data: bytes) -> Path:
    """Write bytes to ``path`` through a temporary file in the same folder and ``os.replace``.

    The folder is held as an :class:`~fabkit.io.folder.OutputFolder` (given one, the file is
    written into it); a failure removes the temporary file and raises
    :class:`~fabkit.errors.OutputError` naming ``path``.
    """
    path = Path(path)
    with OutputFolder.open(path.parent, "folder") as folder:
        return folder.write(path.name, data)


def write_files(folder, files: dict, *, what: str = "file name") -> list[Path]:
    """Write every ``name → bytes`` of ``files`` under ``folder``, all or nothing.

    Names are checked with :func:`inside` before anything is written. Each file is written in
    full to a temporary file beside its target first (and synced), through the folder's handle
    (:class:`~fabkit.io.folder.OutputFolder`: no link is ever followed); only when every one
    of them is complete, and the folder is still the one held, are they renamed into place, so
    a failure leaves none of the new files and no temporary file. Renames do not need space, so
    a full disk can only stop the first phase.

    Parameters
    ----------
    folder : path or OutputFolder
        The folder to write into (created if needed); a handle is written through as it is.
    files : dict of str to bytes
        Name (a file name, or a relative POSIX path below ``folder``) → content.

    Returns
    -------
    list of pathlib.Path
        The paths written, in the order of the sorted names.

    Raises
    ------
    UnsafeNameError, OutputError
        A name that would leave ``folder``; a file that could not be written (the message
        names it and says why, e.g. "No space left on device"); the folder was replaced while
        fabkit worked (:class:`~fabkit.errors.FolderChangedError`).
    """
    if isinstance(folder, OutputFolder):
        return folder.write_files(files)
    for name in files:
        inside(folder, name, what=what, replace_last=True)
    with OutputFolder.open(folder, "folder") as handle:
        return handle.write_files(files)


# --- the lock of an output folder ----------------------------------------------------------

#: The lock file an export holds in its output folder while it writes.
LOCK_NAME = ".fabkit.lock"


class OutputLock:
    """An exclusive lock on an output folder: ``<out>/.fabkit.lock`` held with ``flock``.

    The kernel drops the lock when the holder dies, even by SIGKILL, so a stale lock file never
    blocks anyone; the file is removed on release. The lock file is opened, checked and removed
    through the folder's handle (:class:`~fabkit.io.folder.OutputFolder`), never through a link.

    Parameters
    ----------
    outdir : path or OutputFolder
    wait : bool
        Wait for the other export to finish instead of refusing.
    poll : float
        Seconds between attempts while waiting (short, so that a signal stops the wait).
    """

    def __init__(self, outdir, wait=False, poll=0.2):
        self.folder = outdir if isinstance(outdir, OutputFolder) else None
        self.outdir = Path(outdir)
        self.wait = wait
        self.poll = poll
        self.fd = None
        self._own = None  # a handle this lock opened itself

    def __enter__(self):
        import fcntl

        if self.folder is None:
            self.folder = self._own = OutputFolder.open(self.outdir, "folder")
        folder = self.folder
        while True:
            fd = folder.open_own(LOCK_NAME)  # never through a link, never blocked on a FIFO
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = _lock_holder(fd)
                os.close(fd)
                if not self.wait:
                    self._close_own()
                    raise LockedError(self.outdir, pid) from None
                time.sleep(self.poll)
                continue
            # the holder before us may have removed the file after we opened it: lock the file
            # that is at the path now
            st = folder.lstat(LOCK_NAME)
            if st is None or st.st_ino != os.fstat(fd).st_ino:
                os.close(fd)
                continue
            try:
                with folder.writing(LOCK_NAME):  # a full disk names the lock file
                    os.ftruncate(fd, 0)
                    os.write(fd, f"{os.getpid()}\n".encode())
            except BaseException:
                os.close(fd)
                self._close_own()
                raise
            self.fd = fd
            return self

    def __exit__(self, *exc):
        if self.fd is not None:
            try:  # only the file this lock holds: not a link or a file put there since
                st = self.folder.lstat(LOCK_NAME)
                if st is not None and st.st_ino == os.fstat(self.fd).st_ino:
                    self.folder.unlink(LOCK_NAME)
            except OSError:  # the folder went away under the lock: nothing to remove
                pass
            os.close(self.fd)  # closing drops the flock
            self.fd = None
        self._close_own()
        return False

    def _close_own(self) -> None:
        if self._own is not None:
            self._own.close()
            self.folder = self._own = None


def _lock_holder(fd) -> int | None:
    try:
        text = os.pread(fd, 32, 0).decode().strip()
        return int(text) if text else None
    except (OSError, ValueError):
        return None
