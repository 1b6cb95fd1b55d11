"""Output folders: staging, the swap into place, carrying other commands' files over, the lock."""

from __future__ import annotations

import os
import stat

from ..errors import LockedError, OutputError, UnsafeNameError
from ..io.outputs import check_name, LOCK_NAME, OutputFolder, OutputLock, own_entry


def is_safe_name(name: str) -> bool:
    """True when ``name`` can be a folder under the output folder (:mod:`fabkit.io.outputs`).

    Parameters
    ----------
    name : str
        A design's name.

    Returns
    -------
    bool
        False where :func:`fabkit.io.outputs.check_name` refuses it.
    """
    try:
        check_name(name)
    except UnsafeNameError:
        return False
    return True


# --- folders ---------------------------------------------------------------------------------

#: The mark fabkit leaves in the staging folder it makes for a design and in the design's
#: folder it is about to rename to the backup (``.NAME.old``); removed again once the new folder
#: is in place. A leftover staging or backup folder is removed or put back only when it holds
#: this mark, never a folder fabkit did not make.
MARK = ".fabkit-folder"
MARK_TEXT = b"made by fabkit export; fabkit may replace or remove this folder\n"


def staging_folders(outdir: OutputFolder, name: str) -> tuple[str, str]:
    """The names of the staging and backup folders of design ``name`` in ``outdir``: missing,
    or folders of their own, never a symbolic link, a file, or a folder without fabkit's
    :data:`MARK` (refused in one line).

    Parameters
    ----------
    outdir : OutputFolder
        The output folder.
    name : str
        The design's name (its folder under ``outdir``).

    Returns
    -------
    (str, str)
        ``.NAME.staging`` and ``.NAME.old``.

    Raises
    ------
    OutputError
    """
    # fixed names (no random part): paths that checkers quote stay the same from run to run
    names = (own_entry(outdir.path, f".{name}.staging").name,
             own_entry(outdir.path, f".{name}.old").name)
    for entry in names:
        st = outdir.lstat(entry)
        if st is None:
            continue
        if not stat.S_ISDIR(st.st_mode):  # a link or a file put there since own_entry looked
            raise OutputError(outdir.path / entry, "is no folder of fabkit's; fabkit does not "
                                                   "follow it: remove it")
        if not _marked(outdir, entry):
            raise OutputError(outdir.path / entry, "is in the way: a folder fabkit did not "
                                                   "make (it lacks fabkit's mark "
                                                   f"{MARK}); move it away")
    return names


def _marked(outdir: OutputFolder, entry: str) -> bool:
    """True when folder ``entry`` holds fabkit's :data:`MARK` (a regular file, not a link)."""
    try:
        sub = outdir.folder(entry, create=False)
    except OutputError:
        return False
    with sub:
        st = sub.lstat(MARK)
    return st is not None and stat.S_ISREG(st.st_mode)


def new_staging(outdir: OutputFolder, name: str) -> tuple[str, OutputFolder]:
    """Create the staging folder of design ``name`` (it must not exist), marked as fabkit's;
    returns its name and handle."""
    stage = staging_folders(outdir, name)[0]
    outdir.verify()  # the folder held is still the one its path names
    try:
        os.mkdir(stage, 0o777, dir_fd=outdir.fd)
    except OSError as exc:
        raise OutputError(outdir.path / stage, f"cannot be created: {exc.strerror or exc}"
                          ) from None
    handle = outdir.folder(stage, create=False)
    handle.write(MARK, MARK_TEXT)
    return stage, handle


def check_replaceable(outdir: OutputFolder, name: str) -> None:
    """Refuse to replace ``outdir/name`` when it is not a folder (a file, a link)
    (:class:`~fabkit.errors.OutputError`)."""
    st = outdir.lstat(name)
    if st is not None and not stat.S_ISDIR(st.st_mode):
        raise OutputError(outdir.path / name, "exists and is not a folder; move it away or "
                                              "choose another output folder with -o")


def recover_folder(outdir: OutputFolder, name: str) -> None:
    """Undo what a run killed between its two renames left: the old folder put back when the
    new one never arrived, and the staging and old folders removed; only folders that hold
    fabkit's :data:`MARK`, through the folder's handle (in the folder held, even if its path
    now names another)."""
    check_name(name)
    stage, old = staging_folders(outdir, name)
    if outdir.is_folder(old) and not outdir.exists(name):
        outdir.replace(old, name)
        with outdir.folder(name, create=False) as back:
            back.unlink(MARK)
    for leftover in (stage, old):
        if outdir.is_folder(leftover) and _marked(outdir, leftover):
            outdir.remove(leftover)


def _export_manifest(folder: OutputFolder) -> set | None:
    """Names the previous export wrote into ``folder`` (from its report.json), or None when the
    folder holds no export report."""
    import json

    try:
        old = json.loads(folder.read_bytes("report.json", MAX_REPORT_BYTES))
    except (OSError, ValueError):
        return None
    if not isinstance(old, dict):
        return None
    names = set(old.get("files") or [])
    for v in (old.get("formats") or {}).values():
        if isinstance(v, dict):
            names.update(v.get("files") or [])
    names.update(old.get("previews") or [])
    names.update(("report.json", "report.md", "motion.png", "map.png", "tolerance.png")
                 if "files" not in old else ())
    return names


#: Largest report.json of an export written before records were kept, read back to learn
#: which files it wrote.
MAX_REPORT_BYTES = 16 * 2**20


def carry_over(folder: OutputFolder, stage: OutputFolder, ours=None) -> list[str]:
    """Hard-link (or copy) into ``stage`` what another command wrote into ``folder``: every
    entry the previous exports did not write and the new one does not write either. Returns the
    names carried over. Links are carried as links, never followed; FIFOs, sockets and
    devices are not carried.

    ``ours``: the names earlier exports wrote (from the folder's export record,
    :mod:`fabkit.pipeline.manifest`); None for a folder written before records were kept, whose
    report.json lists them."""
    mine = set(ours) if ours is not None else (_export_manifest(folder) or set())
    kept = []
    for name in folder.names():
        if name in mine or name.startswith(".") or stage.exists(name):
            continue
        if _carry(folder, stage, name):
            kept.append(name)
    return kept


def _carry(src: OutputFolder, dst: OutputFolder, name: str) -> bool:
    """Entry ``name`` of ``src`` into ``dst`` (a folder entry by entry); False when it is no
    kind of file a command writes. A failure names the entry in ``dst`` (a WriteError)."""
    mode = src.lstat(name).st_mode
    if stat.S_ISDIR(mode):
        with dst.writing(name):
            os.mkdir(name, 0o777, dir_fd=dst.fd)
        with src.folder(name, create=False) as below, dst.folder(name, create=False) as to:
            for entry in below.names():
                _carry(below, to, entry)
    elif stat.S_ISLNK(mode):  # a link is carried as the link itself
        with dst.writing(name):
            os.symlink(os.readlink(name, dir_fd=src.fd), name, dir_fd=dst.fd)
    elif stat.S_ISREG(mode):
        try:
            os.link(name, name, src_dir_fd=src.fd, dst_dir_fd=dst.fd, follow_symlinks=False)
        except OSError:
            dst.write(name, src.read_bytes(name, MAX_CARRIED_BYTES))
    else:
        return False  # a FIFO, a socket, a device: no fabkit command writes one
    return True


#: Largest file of another command copied into a new export folder when it cannot be linked.
MAX_CARRIED_BYTES = 2**40


def swap_in(outdir: OutputFolder, stage: str, name: str, earlier_files=None) -> None:
    """Replace folder ``name`` of ``outdir`` by the complete ``stage`` folder with two renames;
    a reader sees the old export or the new one, never a mix. Both renames are commit points:
    the output folder must still be the one held (:meth:`OutputFolder.verify`).

    What other commands wrote into the folder is carried over first (:func:`carry_over`, with
    ``earlier_files`` as its ``ours``), under the folder's own lock: a library
    :func:`fabkit.writers.export` writing into it holds that lock, and the swap is then refused
    rather than made under it.

    Raises
    ------
    OutputError
        The folder is not a folder, or another process holds its lock; nothing was swapped.
    FolderChangedError
        The output folder was replaced while the export ran; nothing was swapped.
    """
    if not outdir.exists(name):
        with outdir.folder(stage, create=False) as staged:
            outdir.replace(stage, name)
            staged.unlink(MARK)  # a design's folder carries no mark (one left is harmless)
        return
    check_replaceable(outdir, name)
    _, old = staging_folders(outdir, name)
    folder = outdir.folder(name, create=False)
    # the folder about to become the backup is marked first: a run killed before its removal
    # leaves a backup that the next run knows as fabkit's
    folder.write(MARK, MARK_TEXT)
    try:
        with folder, OutputLock(folder), outdir.folder(stage, create=False) as staged:
            carry_over(folder, staged, earlier_files)
            try:
                outdir.replace(name, old)  # the lock file goes with the old folder
            except BaseException:
                folder.unlink(MARK)
                raise
            outdir.replace(stage, name)
            staged.unlink(MARK)
    except LockedError as exc:
        folder.unlink(MARK)
        who = f"process {exc.pid}" if exc.pid else "another process"
        raise OutputError(outdir.path / name, f"{who} is writing into this folder (it holds "
                                              f"its {LOCK_NAME}); nothing was swapped in: "
                                              "export the design again when it has finished"
                          ) from None
    outdir.remove(old)


def prepare_outdir(outdir) -> OutputFolder:
    """Create the output folder and hold it (:class:`~fabkit.io.folder.OutputFolder`);
    :class:`OutputError` (one line) when that is impossible."""
    handle = OutputFolder.open(outdir)
    handle.fd  # noqa: B018 - created and opened now: the folder held from here on
    if not os.access(handle.path, os.W_OK | os.X_OK):
        raise OutputError(handle.path, "the output folder is not writable; choose another with "
                                       "-o")
    return handle
