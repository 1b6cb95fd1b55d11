"""Output folders: staging, the swap into place, carrying other commands' files over, the lock."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from ..errors import LockedError, OutputError, UnsafeNameError
from ..io.outputs import LOCK_NAME, OutputLock, check_name, inside, own_entry


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

def staging_folders(outdir: Path, name: str) -> tuple[Path, Path]:
    """The staging and backup folders of design ``name``: missing, or folders of their own,
    never a symbolic link (:func:`fabkit.io.outputs.own_entry` refuses one in one line).

    Parameters
    ----------
    outdir : pathlib.Path
        The output folder.
    name : str
        The design's name (its folder under ``outdir``).

    Returns
    -------
    (pathlib.Path, pathlib.Path)
        ``outdir/.NAME.staging`` and ``outdir/.NAME.old``.
    """
    # fixed names (no random part): paths that checkers quote stay the same from run to run
    return (own_entry(outdir, f".{name}.staging"), own_entry(outdir, f".{name}.old"))


def check_replaceable(folder: Path) -> None:
    """Refuse to replace a folder that is not an earlier export or a folder of another fabkit
    command (:class:`~fabkit.errors.OutputError`)."""
    if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
        raise OutputError(folder, "exists and is not a folder; move it away or choose another "
                                  "output folder with -o")


def recover_folder(outdir: Path, name: str) -> None:
    """Undo what a run killed between its two renames left: the old folder put back when the
    new one never arrived, and the staging and old folders removed."""
    folder = inside(outdir, name)
    stage, old = staging_folders(outdir, name)
    if old.is_dir() and not os.path.lexists(folder):
        os.replace(old, folder)
    for leftover in (stage, old):
        if leftover.is_dir() and not leftover.is_symlink():
            shutil.rmtree(leftover)


def _export_manifest(folder: Path) -> set | None:
    """Names the previous export wrote into ``folder`` (from its report.json), or None when the
    folder holds no export report."""
    import json

    try:
        old = json.loads((folder / "report.json").read_text(encoding="utf-8"))
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


def carry_over(folder: Path, stage: Path, ours=None) -> list[str]:
    """Hard-link (or copy) into ``stage`` what another command wrote into ``folder``: every
    entry the previous exports did not write and the new one does not write either. Returns the
    names carried over.

    ``ours``: the names earlier exports wrote (from the folder's export record,
    :mod:`fabkit.pipeline.manifest`); None for a folder written before records were kept, whose
    report.json lists them."""
    import stat

    if folder.is_symlink() or not folder.is_dir():  # a link is never followed, nor moved in
        return []
    mine = set(ours) if ours is not None else (_export_manifest(folder) or set())
    kept = []
    for entry in sorted(folder.iterdir()):
        if entry.name in mine or entry.name.startswith(".") or os.path.lexists(
                stage / entry.name):
            continue
        target = stage / entry.name
        mode = entry.lstat().st_mode
        if stat.S_ISDIR(mode):
            shutil.copytree(entry, target, symlinks=True, copy_function=_link_or_copy)
        elif stat.S_ISREG(mode) or stat.S_ISLNK(mode):  # a link is carried as the link itself
            _link_or_copy(entry, target)
        else:
            continue  # a FIFO, a socket, a device: no fabkit command writes one
        kept.append(entry.name)
    return kept


def _link_or_copy(src, dst):
    try:
        os.link(src, dst, follow_symlinks=False)
    except OSError:
        shutil.copy2(src, dst, follow_symlinks=False)
    return dst


def swap_in(stage: Path, folder: Path, earlier_files=None) -> None:
    """Replace ``folder`` by the complete ``stage`` folder with two renames; a reader sees the
    old export or the new one, never a mix.

    What other commands wrote into ``folder`` is carried over first (:func:`carry_over`, with
    ``earlier_files`` as its ``ours``), under the folder's own lock: a library
    :func:`fabkit.writers.export` writing into it holds that lock, and the swap is then refused
    rather than made under it.

    Raises
    ------
    OutputError
        ``folder`` is not a folder, or another process holds its lock; nothing was swapped.
    """
    if not os.path.lexists(folder):
        os.replace(stage, folder)
        return
    check_replaceable(folder)
    _, old = staging_folders(folder.parent, folder.name)
    try:
        with OutputLock(folder):
            carry_over(folder, stage, earlier_files)
            os.replace(folder, old)  # the lock file goes with the old folder
            os.replace(stage, folder)
    except LockedError as exc:
        who = f"process {exc.pid}" if exc.pid else "another process"
        raise OutputError(folder, f"{who} is writing into this folder (it holds its "
                                  f"{LOCK_NAME}); nothing was swapped in: export the design "
                                  "again when it has finished") from None
    shutil.rmtree(old)


def prepare_outdir(outdir) -> Path:
    """Create the output folder; :class:`OutputError` (one line) when that is impossible."""
    outdir = Path(outdir)
    try:
        if outdir.exists() and not outdir.is_dir():
            raise OutputError(outdir, "exists and is not a folder; choose another output "
                                      "folder with -o")
        outdir.mkdir(parents=True, exist_ok=True)
    except OutputError:
        raise
    except OSError as exc:
        raise OutputError(outdir, f"cannot create the output folder: "
                                  f"{exc.strerror or exc}") from None
    if not os.access(outdir, os.W_OK | os.X_OK):
        raise OutputError(outdir, "the output folder is not writable; choose another with -o")
    return outdir
