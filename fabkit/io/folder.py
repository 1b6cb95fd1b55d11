"""One handle on an output folder: every file fabkit makes, renames, removes or reads back in it.

A path is looked up by name at every step; a folder handle is not. :class:`OutputFolder` opens
the folder the user chose (``-o``) once, as a directory file descriptor (a real folder, owned
by the user running fabkit, never a symbolic link), and does everything relative to it with
links never followed: ``os.open(name, O_NOFOLLOW, dir_fd=)``, ``os.mkdir(name, dir_fd=)``,
``os.replace(src, dst, src_dir_fd=, dst_dir_fd=)``, ``shutil.rmtree(name, dir_fd=)``. A folder
below it (a design's folder, ``chunks/``, a staging folder) is a handle of its own, opened
relative to its parent the same way.

Whoever removes the folder, renames it or puts a link or another folder in its place while
fabkit works cannot make it write elsewhere: writes go to the folder that was opened. Before a
set of files is renamed into place (the commit points) the handle also compares the folder it
holds with what the path names now (``st_dev``, ``st_ino``, of the folder and of each parent
handle); when they differ the run stops with :class:`~fabkit.errors.FolderChangedError`, one
line, and nothing more is written.

A handle pickles as its path and identity: a worker process that unpickles one opens the path
again and refuses it (:class:`~fabkit.errors.FolderChangedError`) unless it is the same folder.
A folder that does not exist yet is created (with its missing parents) when first used, and
removed again if the first set of files written into it fails.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
import stat
from pathlib import Path

from ..errors import FolderChangedError, OutputError, WriteError
from .inputs import file_kind
from .names import check_name, output_folder, OWN_PATTERN

__all__ = ["OutputFolder", "MAX_READ_BACK"]

#: Flags of a folder opened as a handle: never through a link at its own name.
_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)
#: Flags of a file of fabkit's own read back: never through a link, never blocked on a FIFO.
_READ_FLAGS = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
#: Largest file of its own fabkit reads back unless told otherwise (chunk files, records).
MAX_READ_BACK = 256 * 2**20


class OutputFolder:
    """A folder fabkit writes into, held open (see the module's text).

    Use :meth:`open` for the folder a user chose and :meth:`folder` for one below it.

    Attributes
    ----------
    path : pathlib.Path
        The folder's path, for messages (and to compare with at the commit points).
    """

    def __init__(self, path, identity=None, fd=None, parent=None, name=None, option="-o"):
        self.path = Path(path)
        self.identity = identity
        self.parent = parent
        self.name = name
        self.option = option
        self._fd = fd
        self._created: list[Path] = []  # folders made by the first use, for a failed first write

    # --- opening ----------------------------------------------------------------------------

    @classmethod
    def open(cls, path, option: str = "-o") -> "OutputFolder":
        """The handle on the output folder ``path`` (the user's ``-o``), checked before work.

        The folder is opened now when it exists, and created when first used otherwise.

        Raises
        ------
        OutputError
            As :func:`fabkit.io.outputs.output_folder`; or ``path`` is a symbolic link, not a
            folder, or a folder of another user.
        """
        if isinstance(path, OutputFolder):
            return path
        p = output_folder(path, option)
        handle = cls(p, option=option)
        if os.path.lexists(p):
            handle.fd  # noqa: B018 - opened now: the folder it names now is the one held
        return handle

    @classmethod
    @contextlib.contextmanager
    def held(cls, folder, option: str = "-o"):
        """``with OutputFolder.held(x) as handle``: ``x`` itself when it is a handle (left
        open), else a handle opened on the path ``x`` for the block (closed after it)."""
        if isinstance(folder, OutputFolder):
            yield folder
            return
        with cls.open(folder, option) as handle:
            yield handle

    @property
    def fd(self) -> int:
        """The folder's file descriptor (opened, or created and opened, on first use)."""
        if self._fd is None:
            self._fd = self._open_fd()
        return self._fd

    def _open_fd(self) -> int:
        if self.parent is not None:
            fd = self._open_dir(self.name, self.parent.fd)
        else:
            if self.identity is None and not os.path.lexists(self.path):
                self._create_path()
            fd = self._open_dir(str(self.path), None)
        st = os.fstat(fd)
        if self.identity is not None and (st.st_dev, st.st_ino) != self.identity:
            os.close(fd)
            raise self._changed()
        if self.parent is None and st.st_uid != os.geteuid():
            os.close(fd)
            raise OutputError(self.path, f"{self.option}: belongs to another user (uid "
                                         f"{st.st_uid}); fabkit writes only into folders of "
                                         "the user it runs as: choose another output folder")
        self.identity = (st.st_dev, st.st_ino)
        return fd

    def _create_path(self) -> None:
        missing = []
        probe = self.path
        while not os.path.lexists(probe) and probe != probe.parent:
            missing.append(probe)
            probe = probe.parent
        for folder in reversed(missing):
            try:
                os.mkdir(folder)
            except FileExistsError:
                continue
            except OSError as exc:
                raise OutputError(folder, f"cannot create the output folder: "
                                          f"{exc.strerror or exc}") from None
            self._created.append(folder)

    def _open_dir(self, name: str, dir_fd) -> int:
        where = self.path
        try:
            return os.open(name, _DIR_FLAGS, dir_fd=dir_fd)
        except OSError as exc:
            if self.identity is not None:  # held before: what is there now is another thing
                raise self._changed() from None
            try:
                mode = os.stat(name, dir_fd=dir_fd, follow_symlinks=False).st_mode
            except OSError:
                mode = None
            if mode is not None and stat.S_ISLNK(mode):
                raise OutputError(where, "is a symbolic link; fabkit does not write through "
                                         "it: remove it or choose another output folder"
                                  ) from None
            if mode is not None and not stat.S_ISDIR(mode):
                raise OutputError(where, f"is {file_kind(mode)}, not a folder; move it away "
                                         "or choose another output folder") from None
            raise OutputError(where, f"cannot be opened: {exc.strerror or exc}") from None

    def folder(self, name: str, create: bool = True) -> "OutputFolder":
        """The handle on folder ``name`` below this one (a relative POSIX path of checked
        names), created when missing if ``create``; never a link.

        Raises
        ------
        UnsafeNameError, OutputError
        """
        handle = self
        for part in name.split("/"):
            _check_part(part)
            if create:
                try:
                    os.mkdir(part, 0o777, dir_fd=handle.fd)
                except FileExistsError:
                    pass
                except OSError as exc:
                    raise WriteError(handle.path / part, exc.strerror or str(exc)) from None
            handle = OutputFolder(handle.path / part, parent=handle, name=part,
                                  option=self.option)
            handle.fd  # noqa: B018 - opened now, relative to its parent, never through a link
        return handle

    def close(self) -> None:
        """Close the folder's descriptor (a later use opens the same folder again, or fails)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> "OutputFolder":
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False

    def __del__(self):
        try:
            self.close()
        except (OSError, AttributeError, TypeError):  # the interpreter is going away
            pass

    def __getstate__(self):
        return {"path": str(self.path), "identity": self.identity, "parent": self.parent,
                "name": self.name, "option": self.option}

    def __setstate__(self, state):
        self.__init__(state["path"], state["identity"], None, state["parent"], state["name"],
                      state["option"])

    def __repr__(self) -> str:
        return f"OutputFolder({str(self.path)!r})"

    def __str__(self) -> str:
        return str(self.path)

    def __fspath__(self) -> str:
        return str(self.path)

    # --- the commit points ------------------------------------------------------------------

    def _changed(self) -> FolderChangedError:
        top = self
        while top.parent is not None:
            top = top.parent
        return FolderChangedError(top.path)

    def verify(self) -> None:
        """Refuse to go on when the path no longer names the folder held (nor, for a folder
        below another, its parent's).

        Raises
        ------
        FolderChangedError
        """
        if self._fd is None and self.identity is None:
            return  # not created yet: nothing to compare
        fd = self.fd
        try:
            if self.parent is None:
                st = os.lstat(self.path)
            else:
                st = os.stat(self.name, dir_fd=self.parent.fd, follow_symlinks=False)
            held = os.fstat(fd)
        except OSError:
            raise self._changed() from None
        if ((st.st_dev, st.st_ino) != self.identity or not stat.S_ISDIR(st.st_mode)
                or held.st_nlink == 0):
            raise self._changed()
        if self.parent is not None:
            self.parent.verify()

    # --- entries ----------------------------------------------------------------------------

    def lstat(self, name: str):
        """The entry ``name``'s own status (a link's, not its target's), or None."""
        try:
            return os.stat(name, dir_fd=self.fd, follow_symlinks=False)
        except FileNotFoundError:
            return None

    def exists(self, name: str) -> bool:
        """True when an entry ``name`` (of any kind, a link included) is here."""
        return self.lstat(name) is not None

    def is_folder(self, name: str) -> bool:
        """True when ``name`` is a folder here (not a link to one)."""
        st = self.lstat(name)
        return st is not None and stat.S_ISDIR(st.st_mode)

    def names(self) -> list[str]:
        """The names of the entries here, sorted."""
        return sorted(os.listdir(self.fd))

    @contextlib.contextmanager
    def writing(self, name: str):
        """``with folder.writing(name):`` around making entry ``name`` here: an OSError met
        (a full disk, a file-size limit, a quota) becomes a :class:`~fabkit.errors.WriteError`
        that names the entry's whole path. An error of a call relative to the folder's
        descriptor (``dir_fd=``) names the bare entry at most, and a write to a descriptor
        names nothing at all; this is where every write fabkit makes in an output folder gets
        the name the one-line message shows.

        Raises
        ------
        WriteError
        """
        try:
            yield self.path / name
        except OSError as exc:
            raise WriteError(self.path / name, exc.strerror or str(exc)) from None

    def replace(self, src: str, dst: str, into: "OutputFolder | None" = None) -> None:
        """Rename entry ``src`` here to ``dst`` here (or in ``into``), replacing what is at
        ``dst`` (a link there is replaced, never followed); a commit point.

        Raises
        ------
        FolderChangedError, WriteError
        """
        target = into if into is not None else self
        self.verify()
        target.verify()
        with target.writing(dst):
            os.replace(src, dst, src_dir_fd=self.fd, dst_dir_fd=target.fd)

    def remove(self, name: str) -> None:
        """Remove entry ``name`` (a folder with all it holds, or a file or link itself); a
        link met anywhere below is removed, never followed."""
        st = self.lstat(name)
        if st is None:
            return
        if stat.S_ISDIR(st.st_mode):
            shutil.rmtree(name, dir_fd=self.fd)
        else:
            os.unlink(name, dir_fd=self.fd)

    def unlink(self, name: str) -> None:
        """Remove the file (or link) ``name`` when it is there."""
        try:
            os.unlink(name, dir_fd=self.fd)
        except FileNotFoundError:
            pass

    def read_bytes(self, name: str, limit: int = MAX_READ_BACK) -> bytes:
        """The bytes of ``name``, a regular file of fabkit's own here, read without following
        a link and without blocking on a FIFO.

        Raises
        ------
        OutputError
            A link, a folder, a FIFO or a device at ``name``, or a file over ``limit`` bytes;
            the message names it.
        FileNotFoundError
            Nothing at ``name``.
        """
        path = self.path / name
        try:
            fd = os.open(name, _READ_FLAGS, dir_fd=self.fd)
        except OSError as exc:
            if exc.errno == errno.ENOENT:
                raise
            st = self.lstat(name)
            if st is not None and stat.S_ISLNK(st.st_mode):
                raise OutputError(path, "is a symbolic link, not a regular file: refused "
                                        "(fabkit reads its own files back, never through a "
                                        "link)") from None
            if st is not None and not stat.S_ISREG(st.st_mode):
                raise OutputError(path, f"is {file_kind(st.st_mode)}, not a regular file: "
                                        "refused") from None
            raise OutputError(path, f"cannot be read: {exc.strerror or exc}") from None
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode):
                raise OutputError(path, f"is {file_kind(st.st_mode)}, not a regular file: "
                                        "refused")
            if st.st_size > limit:
                raise OutputError(path, f"holds {st.st_size} bytes, more than the {limit} "
                                        "fabkit writes there; remove it")
            chunks, size = [], 0
            while size <= limit:
                block = os.read(fd, min(1 << 20, limit + 1 - size))
                if not block:
                    break
                chunks.append(block)
                size += len(block)
            if size > limit:
                raise OutputError(path, f"grew past {limit} bytes while read; remove it")
            return b"".join(chunks)
        finally:
            os.close(fd)

    def open_own(self, name: str) -> int:
        """Open (creating it) a file fabkit keeps and updates in place here (a lock file):
        never through a link, never blocked on a FIFO, refused unless a regular file.

        Returns
        -------
        int
            The file descriptor (read and write).
        """
        path = self.path / name
        flags = (os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK
                 | getattr(os, "O_CLOEXEC", 0))
        try:
            fd = os.open(name, flags, 0o644, dir_fd=self.fd)
        except OSError as exc:
            st = self.lstat(name)
            if exc.errno == errno.ELOOP or st is not None and stat.S_ISLNK(st.st_mode):
                raise OutputError(path, "is a symbolic link where fabkit keeps its own file; "
                                        "fabkit does not follow it: remove it") from None
            if st is not None and exc.errno in (errno.ENXIO, errno.EISDIR):
                raise OutputError(path, f"is {file_kind(st.st_mode)} where fabkit keeps its "
                                        "own file; remove it") from None
            raise OutputError(path, f"cannot be opened: {exc.strerror or exc}") from None
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            os.close(fd)
            raise OutputError(path, f"is {file_kind(mode)} where fabkit keeps its own file; "
                                    "remove it")
        return fd

    # --- writing ----------------------------------------------------------------------------

    def write_files(self, files: dict) -> list[Path]:
        """Write every ``name → bytes`` of ``files`` here, all or nothing
        (:func:`fabkit.io.outputs.write_files` says how); names may be relative POSIX paths.

        Returns
        -------
        list of pathlib.Path
            The paths written, in the order of the sorted names.

        Raises
        ------
        UnsafeNameError, WriteError, OutputError, FolderChangedError
        """
        plan = []
        for name, data in sorted(files.items()):
            parts = name.split("/") if isinstance(name, str) and name else [name]
            for part in parts:
                _check_part(part)
            if not isinstance(data, (bytes, bytearray, memoryview)):
                raise TypeError(f"{parts[-1]}: file content must be bytes, got "
                                f"{type(data).__name__}")
            plan.append(("/".join(parts[:-1]), parts[-1], data))
        first = self.parent is None and self._fd is None
        self.verify()  # a commit point before the first byte, and again before the renames
        made: list[tuple[OutputFolder, str]] = []  # folders this call created
        staged: list[tuple[OutputFolder, str, str]] = []
        try:
            folders = {"": self}
            for sub, _, _ in plan:
                if sub not in folders:
                    folders[sub] = self._folder_made(sub, made)
            for sub, leaf, data in plan:
                staged.append((folders[sub], folders[sub]._stage(leaf, data), leaf))
            self.verify()
            for where, tmp, leaf in staged:
                where.replace(tmp, leaf)
            staged = []
        except BaseException:
            for where, tmp, _ in staged:
                where.unlink(tmp)
            for where, name in reversed(made):
                try:
                    os.rmdir(name, dir_fd=where.fd)
                except OSError:
                    pass
            if first:
                self._undo_creation()
            raise
        return [self.path / (f"{sub}/{leaf}" if sub else leaf) for sub, leaf, _ in plan]

    def write(self, name: str, data: bytes) -> Path:
        """Write one file (see :meth:`write_files`)."""
        return self.write_files({name: data})[0]

    def _folder_made(self, sub: str, made: list) -> "OutputFolder":
        handle = self
        for part in sub.split("/"):
            if not handle.exists(part):
                try:
                    os.mkdir(part, 0o777, dir_fd=handle.fd)
                    made.append((handle, part))
                except FileExistsError:
                    pass
                except OSError as exc:
                    raise WriteError(handle.path / part, exc.strerror or str(exc)) from None
            handle = handle.folder(part, create=False)
        return handle

    def _stage(self, leaf: str, data) -> str:
        """Write ``data`` to a synced temporary file here; returns its name."""
        tmp = f".{leaf}.{secrets.token_hex(4)}.part"
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)
        fd = None
        try:
            fd = os.open(tmp, flags, 0o666, dir_fd=self.fd)  # the umask applies
            with os.fdopen(fd, "wb") as fh:
                fd = None
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            if fd is not None:
                os.close(fd)
            self.unlink(tmp)
            raise WriteError(self.path / leaf, exc.strerror or str(exc)) from None
        except BaseException:
            self.unlink(tmp)
            raise
        return tmp

    def _undo_creation(self) -> None:
        """Remove the folders the first use created, when they are still empty."""
        self.close()
        for folder in reversed(self._created):
            try:
                os.rmdir(folder)
            except OSError:
                pass
        self._created = []
        self.identity = None


def _check_part(part) -> None:
    """A name fabkit writes (checked), or a hidden entry of its own (``.NAME.staging``)."""
    if isinstance(part, str) and part.startswith(".") and OWN_PATTERN.match(part) \
            and len(part) <= 255:
        return
    check_name(part, "file name", reserved=False)
