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

import errno
import os
import re
import stat
import tempfile
import time
from pathlib import Path

from ..errors import LockedError, OutputError, UnsafeNameError, WriteError
from .inputs import file_kind

__all__ = ["NAME_PATTERN", "MAX_NAME_LENGTH", "RESERVED_NAMES", "check_name", "output_folder",
           "inside", "own_entry", "open_own_file", "write_files", "write_atomic", "LOCK_NAME",
           "OutputLock"]

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


#: What the hidden entries fabkit keeps in an output folder look like: ``.fabkit.lock``,
#: ``.<design>.staging``, ``.<design>.old``.
_OWN_PATTERN = re.compile(r"^\.[A-Za-z0-9][A-Za-z0-9_.+-]*$")


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
    if not isinstance(name, str) or not _OWN_PATTERN.match(name) or len(name) > 255:
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
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as exc:
        if exc.errno == errno.ELOOP or path.is_symlink():
            raise OutputError(path, "is a symbolic link where fabkit keeps its own file; "
                                    "fabkit does not follow it: remove it") from None
        if exc.errno in (errno.ENXIO, errno.EISDIR):  # a FIFO without reader, a folder
            mode = os.lstat(path).st_mode
            raise OutputError(path, f"is {file_kind(mode)} where fabkit keeps its own file; "
                                    "remove it") from None
        raise OutputError(path, f"cannot be opened: {exc.strerror or exc}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise OutputError(path, f"is {file_kind(mode)} where fabkit keeps its own file; "
                                "remove it")
    return fd


def write_atomic(path, data: bytes) -> Path:
    """Write bytes to ``path`` through a temporary file in the same folder and ``os.replace``.

    The primitive under :func:`write_files`; a failure removes the temporary file and raises
    :class:`~fabkit.errors.OutputError` naming ``path``.
    """
    path = Path(path)
    tmp = _stage(path, data)
    try:
        os.replace(tmp, path)
    except BaseException:
        _unlink(tmp)
        raise
    return path


def write_files(folder, files: dict, *, what: str = "file name") -> list[Path]:
    """Write every ``name → bytes`` of ``files`` under ``folder``, all or nothing.

    Names are checked with :func:`inside` before anything is written. Each file is written in
    full to a temporary file beside its target (and synced); only when every one of them is
    complete are they renamed into place, so a failure leaves none of the new files and no
    temporary file. Renames do not need space, so a full disk can only stop the first phase.

    Parameters
    ----------
    folder : path
        The folder to write into (created if needed).
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
        names it and says why, e.g. "No space left on device").
    """
    targets = [(inside(folder, name, what=what, replace_last=True), data)
               for name, data in sorted(files.items())]
    staged: list[tuple[Path, Path]] = []
    created: list[Path] = []
    try:
        for path, data in targets:
            created += _new_folders(path.parent)
            staged.append((_stage(path, data), path))
        for tmp, path in staged:
            os.replace(tmp, path)
    except BaseException:
        for tmp, _ in staged:
            _unlink(tmp)
        for made in reversed(created):  # the folders this call created, deepest first
            try:
                made.rmdir()
            except OSError:
                pass
        raise
    return [path for path, _ in targets]


def _new_folders(folder: Path) -> list[Path]:
    """The folders that do not exist yet from the top down to ``folder``."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing[::-1]


def _stage(path: Path, data) -> Path:
    """Write ``data`` to a synced temporary file beside ``path``; returns its path."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise TypeError(f"{path.name}: file content must be bytes, got {type(data).__name__}")
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
        tmp = Path(name)
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600 files; use the usual permissions
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        if tmp is not None:
            _unlink(tmp)
        raise WriteError(path, exc.strerror or str(exc)) from None
    except BaseException:
        if tmp is not None:
            _unlink(tmp)
        raise
    return tmp


def _unlink(path: Path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# --- the lock of an output folder ----------------------------------------------------------

#: The lock file an export holds in its output folder while it writes.
LOCK_NAME = ".fabkit.lock"


class OutputLock:
    """An exclusive lock on an output folder: ``<out>/.fabkit.lock`` held with ``flock``.

    The kernel drops the lock when the holder dies, even by SIGKILL, so a stale lock file never
    blocks anyone; the file is removed on release.

    Parameters
    ----------
    outdir : path
    wait : bool
        Wait for the other export to finish instead of refusing.
    poll : float
        Seconds between attempts while waiting (short, so that a signal stops the wait).
    """

    def __init__(self, outdir, wait=False, poll=0.2):
        self.outdir = Path(outdir)
        self.wait = wait
        self.poll = poll
        self.fd = None

    def __enter__(self):
        import fcntl

        path = self.outdir / LOCK_NAME
        while True:
            fd = open_own_file(path)  # never through a link, never blocked on a FIFO
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = _lock_holder(fd)
                os.close(fd)
                if not self.wait:
                    raise LockedError(self.outdir, pid) from None
                time.sleep(self.poll)
                continue
            # the holder before us may have removed the file after we opened it: lock the file
            # that is at the path now
            try:
                same = os.fstat(fd).st_ino == os.lstat(path).st_ino
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
            self.fd = fd
            return self

    def __exit__(self, *exc):
        if self.fd is not None:
            path = self.outdir / LOCK_NAME
            try:  # only the file this lock holds: not a link or a file put there since
                if os.lstat(path).st_ino == os.fstat(self.fd).st_ino:
                    os.unlink(path)
            except FileNotFoundError:
                pass
            os.close(self.fd)  # closing drops the flock
            self.fd = None
        return False


def _lock_holder(fd) -> int | None:
    try:
        text = os.pread(fd, 32, 0).decode().strip()
        return int(text) if text else None
    except (OSError, ValueError):
        return None
