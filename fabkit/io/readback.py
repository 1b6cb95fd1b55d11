"""Where a check reads its files from: paths a user named, or a folder of fabkit's own, held.

An as-built check reads the file it is given and the files of the same export beside it (the
beds of a print, the sheets of a kit). A user's file (``fabkit check out/fourbar/x.dxf``) is an
input, read by path (:func:`fabkit.io.inputs.read_regular`). The files an export has just
staged are its own: they are read through the staging folder's handle
(:class:`~fabkit.io.folder.OutputFolder`), never by a path that is looked up again, so a folder
swapped or a link put in place of a staged file while the checks run is never read through.

:class:`ReadBack` is the one interface of both: a check lists, measures and reads its files
through it and never opens a path itself. :attr:`ReadBack.own` says where the files come from:
a file fabkit wrote that its parser refuses is a failed check of that export; a file a user
gave that its parser refuses is a damaged input (:class:`~fabkit.errors.InputFileError`).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path, PurePosixPath

from ..errors import InputFileError, OutputError
from .folder import OutputFolder
from .inputs import file_kind, read_regular

__all__ = ["ReadBack"]


class ReadBack:
    """The files of one check: by path (``folder`` None), or through a held folder.

    Parameters
    ----------
    folder : OutputFolder, optional
        The folder of fabkit's own the files are in (an export's staging folder); every path
        handed to the methods then lies below ``folder.path``.
    """

    def __init__(self, folder: OutputFolder | None = None):
        self.folder = folder

    @classmethod
    def of(cls, source) -> "ReadBack":
        """``source`` itself when it is a ReadBack, else one on the folder ``source`` (None:
        by path)."""
        return source if isinstance(source, ReadBack) else cls(source)

    @property
    def own(self) -> bool:
        """True when the files are fabkit's own (read through a held folder)."""
        return self.folder is not None

    def __repr__(self) -> str:
        return f"ReadBack({self.folder!r})"

    # --- through the folder -------------------------------------------------------------------

    def _place(self, path) -> tuple[OutputFolder, str]:
        """(handle of the folder holding ``path``, its name there)."""
        try:
            rel = PurePosixPath(Path(path).relative_to(self.folder.path).as_posix())
        except ValueError:
            raise OutputError(path, f"is not in the folder {self.folder.path} the check reads "
                                    "from") from None
        where = self.folder
        if len(rel.parts) > 1:
            where = self.folder.folder("/".join(rel.parts[:-1]), create=False)
        return where, rel.name

    # --- the interface ------------------------------------------------------------------------

    def size(self, path) -> int:
        """The size of the regular file ``path`` (a link there is not followed).

        Raises
        ------
        InputFileError
            Missing, or not a regular file (a link in a folder of fabkit's own, a FIFO, a
            device, a folder).
        """
        try:
            if self.folder is None:
                st = os.stat(path)
            else:
                where, name = self._place(path)
                st = where.lstat(name)
                if st is None:
                    raise FileNotFoundError
        except FileNotFoundError:
            raise InputFileError(path, "no such file", kind="missing") from None
        except OSError as exc:
            raise InputFileError(path, f"cannot read: {exc.strerror or exc}",
                                 kind="unreadable") from None
        if not stat.S_ISREG(st.st_mode):
            raise InputFileError(path, f"is {file_kind(st.st_mode)}, not a regular file: refused",
                                 kind="not_regular")
        return st.st_size

    def read(self, path, limit: int) -> bytes:
        """The bytes of ``path``, at most ``limit`` of them.

        Raises
        ------
        InputFileError, BoundsError
            By path: as :func:`fabkit.io.inputs.read_regular`.
        OutputError
            In a held folder: a link, not a regular file, or over ``limit``
            (:meth:`fabkit.io.folder.OutputFolder.read_bytes`).
        """
        if self.folder is None:
            return read_regular(path, limit)
        where, name = self._place(path)
        try:
            return where.read_bytes(name, limit)
        except FileNotFoundError:
            raise InputFileError(path, "no such file", kind="missing") from None

    def siblings(self, path) -> list[Path]:
        """The regular files in the folder of ``path`` (links excluded in a held folder)."""
        path = Path(path)
        if self.folder is None:
            return [p for p in path.parent.iterdir() if p.is_file()]
        where, _ = self._place(path)
        out = []
        for name in where.names():
            st = where.lstat(name)
            if st is not None and stat.S_ISREG(st.st_mode):
                out.append(path.parent / name)
        return out
