"""The exports a design folder holds: which formats came from which export, made how.

A later export into a design's folder adds its formats to those already there instead of
swapping the folder's contents (``fabkit export super_stable`` then ``--to stl`` leaves the laser
kit and the print side by side). Which earlier formats may stay is decided from a small typed
record written beside the files, ``exports.json`` (never from the reports, which are rendered
from typed results and never read back):

- each format's files, the export that made them (its number in this folder and its time), the
  digest of the design they were made from, the settings sections they read and the fabkit
  version;
- a format an export does not make again stays when all three are still the same, and its files
  are checked again as built; otherwise it is stale and removed, and the report says why.

A record that is not one (foreign JSON, another schema version, wrong types) is an error naming
the file: nothing is guessed about files whose origin is not known.
"""

from __future__ import annotations

import hashlib
import json
import stat
from dataclasses import dataclass, field
from pathlib import Path

from .. import __version__
from ..errors import FabkitError, InputFileError, OutputError
from ..io.formats import load_json
from ..io.outputs import OutputFolder
from ..report.text import jsonable
from ..writers import get_exporter

__all__ = ["MANIFEST", "SCHEMA", "SCHEMA_VERSION", "FormatOrigin", "Manifest", "read_manifest",
           "design_digest", "format_settings", "stale_reason", "sort_earlier", "new_manifest"]

#: The record's file name in a design folder.
MANIFEST = "exports.json"
#: What the record says it is, and the version of its layout.
SCHEMA = "fabkit.exports"
SCHEMA_VERSION = 1
#: Largest record read back (a record lists file names and exporter facts: kilobytes).
MAX_BYTES = 16 * 2**20
#: Largest file of an earlier export read back to stay in the folder (as ``fabkit check`` reads).
MAX_KEPT_BYTES = 256 * 2**20


@dataclass(frozen=True)
class FormatOrigin:
    """Where one format's files in a design folder came from.

    Attributes
    ----------
    format : str
    files : tuple of str
        The format's files in the folder.
    export : int
        Which export into this folder made them (1 for the first).
    when : str
        That export's time, UTC, ``YYYY-MM-DD HH:MM:SS``.
    design_digest : str
        SHA-256 of the design they were made from (:func:`design_digest`).
    settings : dict
        The ``--set`` sections the format reads, as given to that export.
    fabkit_version : str
    report : dict
        The exporter's facts (the ``report`` of :class:`~fabkit.pipeline.results.FormatResult`).
    """

    format: str
    files: tuple
    export: int
    when: str
    design_digest: str
    settings: dict = field(default_factory=dict)
    fabkit_version: str = ""
    report: dict = field(default_factory=dict)

    def same_making(self, other: "FormatOrigin") -> bool:
        """True when ``other`` made the same files the same way (design, settings, version)."""
        return (self.design_digest, _canonical(self.settings), self.fabkit_version) == (
            other.design_digest, _canonical(other.settings), other.fabkit_version)

    def line(self) -> str:
        """``"export 2 (2026-11-28 08:30:00 UTC), settings: the template's, --set
        laser.kerf=0.2"``."""
        said = ", ".join(f"{k}={json.dumps(v)}" for k, v in _flat(self.settings))
        return (f"export {self.export} ({self.when} UTC), settings: the template's"
                + (f", --set {said}" if said else ""))

    def as_dict(self) -> dict:
        return {"files": list(self.files), "export": self.export, "when": self.when,
                "design_digest": self.design_digest, "settings": self.settings,
                "fabkit_version": self.fabkit_version, "report": self.report}


@dataclass(frozen=True)
class Manifest:
    """The record of a design folder: every format it holds and where each came from."""

    design: str
    formats: dict

    @property
    def last_export(self) -> int:
        return max((o.export for o in self.formats.values()), default=0)

    def to_bytes(self) -> bytes:
        data = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION, "design": self.design,
                "formats": {f: o.as_dict() for f, o in sorted(self.formats.items())}}
        return (json.dumps(jsonable(data), indent=1, sort_keys=True) + "\n").encode("utf-8")


def _flat(settings: dict, prefix: str = ""):
    for k in sorted(settings):
        v = settings[k]
        if isinstance(v, dict):
            yield from _flat(v, f"{prefix}{k}.")
        else:
            yield f"{prefix}{k}", v


def _canonical(value) -> str:
    return json.dumps(jsonable(value), sort_keys=True)


def design_digest(design) -> str:
    """SHA-256 of what a design's files are made from: its template's bytes (when it has a file)
    and the built network, fabrication settings and motion (a chain's module file that changed
    changes the network, though not the chain's own file)."""
    import numpy as np

    h = hashlib.sha256()
    path = getattr(design, "path", None)
    if path:
        try:
            h.update(Path(path).read_bytes())
        except OSError:
            h.update(str(path).encode())
    net = design.network
    h.update(np.ascontiguousarray(np.asarray(net.nodes, dtype=float)).tobytes())
    h.update(_canonical([list(map(int, e)) for e in net.edges]).encode())
    h.update(_canonical(getattr(design, "fabrication", None) or {}).encode())
    h.update(_canonical(getattr(design, "motion", None)).encode())
    return h.hexdigest()


def format_settings(fmt: str, module, settings: dict) -> dict:
    """The ``--set`` sections a format's files depend on: its own, those it declares it reads
    (``READS``), and ``motion`` (the motion the files are made along)."""
    wanted = ("motion", fmt, *getattr(module, "READS", ()))
    return {k: settings[k] for k in sorted(set(wanted)) if k in (settings or {})}


def stale_reason(earlier: FormatOrigin, now: FormatOrigin) -> str | None:
    """Why files made as ``earlier`` no longer fit a folder made as ``now``, or None."""
    why = []
    if earlier.design_digest != now.design_digest:
        why.append("the design changed since")
    if _canonical(earlier.settings) != _canonical(now.settings):
        was = dict(_flat(earlier.settings))
        new = dict(_flat(now.settings))
        keys = sorted(k for k in set(was) | set(new) if was.get(k) != new.get(k))
        why.append("settings changed: " + ", ".join(
            f"{k} {json.dumps(was[k]) if k in was else 'default'} → "
            f"{json.dumps(new[k]) if k in new else 'default'}" for k in keys))
    if earlier.fabkit_version != now.fabkit_version:
        why.append(f"made by fabkit {earlier.fabkit_version}, this is {now.fabkit_version}")
    return "; ".join(why) or None


def _bad(path: Path, why: str) -> OutputError:
    return OutputError(path, f"{why}: not a fabkit export record ({SCHEMA} version "
                             f"{SCHEMA_VERSION}); remove it (or the folder) to export afresh")


def _field(path, data: dict, key: str, kind, where: str):
    value = data.get(key)
    if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise _bad(path, f"{where}{key}: expected {getattr(kind, '__name__', kind)}, got "
                         f"{type(value).__name__}")
    return value


def read_manifest(folder) -> Manifest | None:
    """The record of a design folder, or None when it holds none (a new folder, or one written
    before records were kept).

    Raises
    ------
    OutputError
        The record is not a regular file, not JSON, not this schema and version, or has a field
        of the wrong type; the message names the file.
    """
    if not isinstance(folder, OutputFolder):
        with OutputFolder.open(folder, "folder") as held:
            return read_manifest(held)
    path = folder.path / MANIFEST
    st = folder.lstat(MANIFEST)
    if st is None:
        return None
    if not stat.S_ISREG(st.st_mode):
        raise _bad(path, "not a regular file")
    try:
        data = load_json(folder.read_bytes(MANIFEST, MAX_BYTES), path)  # never through a link
    except InputFileError as exc:
        if exc.kind not in ("damaged", "bounds"):
            raise
        raise _bad(path, exc.reason) from None
    except OSError as exc:
        raise OutputError(path, f"cannot read the export record: {exc.strerror or exc}") from None
    if not isinstance(data, dict) or data.get("schema") != SCHEMA:
        raise _bad(path, "no schema")
    if data.get("schema_version") != SCHEMA_VERSION:
        raise _bad(path, f"schema version {data.get('schema_version')!r}")
    design = _field(path, data, "design", str, "")
    formats = {}
    for fmt, rec in _field(path, data, "formats", dict, "").items():
        where = f"formats.{fmt}."
        if not isinstance(rec, dict):
            raise _bad(path, f"formats.{fmt}: expected an object")
        files = _field(path, rec, "files", list, where)
        if not all(isinstance(f, str) and f and "/" not in f and "\\" not in f
                   and not f.startswith(".") for f in files):
            raise _bad(path, f"{where}files: expected plain file names")
        export = _field(path, rec, "export", int, where)
        if export < 1:
            raise _bad(path, f"{where}export: expected 1 or more, got {export}")
        formats[fmt] = FormatOrigin(
            fmt, tuple(files), export, _field(path, rec, "when", str, where),
            _field(path, rec, "design_digest", str, where),
            _field(path, rec, "settings", dict, where),
            _field(path, rec, "fabkit_version", str, where),
            _field(path, rec, "report", dict, where))
    return Manifest(design, formats)


def _origin_now(fmt, files, design, settings, exporters, digest) -> FormatOrigin:
    """How format ``fmt`` would be made by this export (its number and time not yet given)."""
    module = get_exporter(fmt, exporters)
    return FormatOrigin(fmt, tuple(files), 1, "", digest,
                        format_settings(fmt, module, settings), __version__)


def sort_earlier(folder, earlier: Manifest | None, design, settings, made, exporters,
                 digest: str) -> tuple[dict, tuple]:
    """Which formats of an earlier export stay in a design's folder.

    Parameters
    ----------
    folder : OutputFolder or None
        The design's folder (held; None when there is none).
    earlier : Manifest or None
    design : Design
    settings : dict
        This export's ``--set`` overrides.
    made : iterable of str
        The formats this export makes (they replace their earlier files).
    exporters : dict of str to str
        The format registry.
    digest : str
        :func:`design_digest` of ``design``.

    Returns
    -------
    kept : dict of str to FormatOrigin
        Formats that stay: made from the same design, with the same settings, by this version,
        and with every file still in the folder.
    removed : tuple of str
        One line per stale format: which, from which export, and why it goes.
    """
    kept, removed = {}, []
    if earlier is None:
        return kept, ()
    made = set(made)
    for fmt, old in sorted(earlier.formats.items()):
        if fmt in made:
            continue
        try:
            now = _origin_now(fmt, old.files, design, settings, exporters, digest)
            why = stale_reason(old, now)
        except FabkitError as exc:  # the format is no longer installed or known
            why = f"its exporter is not available: {exc}"
        if why is None:
            gone = [f for f in old.files if not _regular(folder, f)]
            if gone:
                why = f"its file{'s' if len(gone) > 1 else ''} {', '.join(gone)} went missing"
        if why is None:
            kept[fmt] = old
        else:
            removed.append(f"{fmt} ({', '.join(old.files)}) from export {old.export} removed: "
                           f"{why}")
    return kept, tuple(removed)


def _regular(folder: OutputFolder | None, name: str) -> bool:
    """True when ``name`` is a regular file in ``folder`` (not a link to one)."""
    st = folder.lstat(name) if folder is not None else None
    return st is not None and stat.S_ISREG(st.st_mode)


def new_manifest(name: str, earlier: Manifest | None, kept: dict, formats: dict, design,
                 settings, exporters, digest: str, when: str) -> Manifest:
    """The record after this export: the kept formats as they were, and every format made now;
    a format made again exactly as before keeps its earlier export number and time (identical
    input gives identical bytes, the record included).

    Parameters
    ----------
    name : str
        The design's name.
    earlier : Manifest or None
    kept : dict of str to FormatOrigin
    formats : dict of str to FormatResult
        This export's formats (those kept included).
    design, settings, exporters, digest
        As for :func:`sort_earlier`.
    when : str
        This export's time, UTC, ``YYYY-MM-DD HH:MM:SS``.
    """
    number = (earlier.last_export if earlier is not None else 0) + 1
    out = dict(kept)
    for fmt, res in formats.items():
        if fmt in kept or not res.status.produced:
            continue
        now = _origin_now(fmt, res.files, design, settings, exporters, digest)
        old = earlier.formats.get(fmt) if earlier is not None else None
        same = old is not None and old.same_making(now) and tuple(old.files) == now.files
        out[fmt] = FormatOrigin(fmt, now.files, old.export if same else number,
                                old.when if same else when, digest, now.settings,
                                now.fabkit_version, res.report)
    return Manifest(name, out)
