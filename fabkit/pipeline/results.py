"""Typed results of the batch: how a design and each of its formats ended."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from ..status import EXPORT, FORMAT, Status, expect


class Stage(str, Enum):
    """Stages of one design, in order (reported by the progress lines and in ``seconds``)."""

    LOAD = "load"
    MOTION = "motion"
    EXPORT = "export"
    PREVIEWS = "previews"
    TOLERANCE = "tolerance"
    WRITE = "write"
    CHECK = "check"

    def __str__(self) -> str:
        return self.value


@dataclass
class CheckResult:
    """The as-built check of one written file (``fabkit.check``).

    Its :attr:`status` (one of :data:`fabkit.status.CHECK`) and :attr:`message` are read from
    ``ok`` and ``error``, the keys report.json gives it.
    """

    file: str
    ok: bool
    checks: list = field(default_factory=list)
    error: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def status(self) -> Status:
        """``ok`` when every check of the file passed, else ``failed``."""
        return Status.OK if self.ok else Status.FAILED

    @property
    def message(self) -> str:
        """Why the file could not be checked (``""`` when it could)."""
        return self.error

    def as_dict(self) -> dict:
        out = {**self.extra, "file": self.file, "ok": self.ok, "checks": self.checks}
        if self.error:
            out["error"] = self.error
        return out


@dataclass
class FormatResult:
    """One format of one design: its status, files, exporter report and checks.

    Attributes
    ----------
    name : str
    status : Status
        One of :data:`fabkit.status.FORMAT`.
    files : list of str
    report : dict
        The exporter's report (for a format that wrote files).
    message : str
        Why the format was not made, or what to know about it (report.json's ``detail``).
    checks : list of CheckResult
    """

    name: str
    status: Status
    files: list = field(default_factory=list)
    report: dict = field(default_factory=dict)
    message: str = ""
    checks: list = field(default_factory=list)

    def __post_init__(self):
        self.status = expect(self.status, FORMAT, "a format")

    def as_dict(self) -> dict:
        out = {"status": self.status.value, "files": list(self.files)}
        if self.status.produced:
            out["report"] = self.report
        if self.message:
            out["detail"] = self.message
        if self.checks:
            out["checks"] = [c.as_dict() for c in self.checks]
        return out


@dataclass
class DesignResult:
    """The result of exporting one template.

    Attributes
    ----------
    path : str
        The template file.
    name : str
        The design's name (its folder), or the file's stem when it did not load.
    status : Status
        How its export ended, one of :data:`fabkit.status.EXPORT` (``outcome`` in report.json
        and in :meth:`as_dict`).
    formats : dict of str to FormatResult
    files : int
        Files written into the folder (reports included).
    folder : str
        The design's folder, or ``""`` when nothing was written.
    message : str
        One line when the status is not OK, else ``""`` (``error`` in :meth:`as_dict`).
    error_code : str
        The stable code of the error (:attr:`fabkit.errors.FabkitError.code`), ``"check"`` for a
        failed as-built check, ``"internal"`` for a bug, ``""`` when OK.
    seconds : float
        Wall time of the whole design.
    cpu_seconds : float
        CPU time of the process that exported it, over the same span (on a busy machine the
        wall time grows, this does not).
    stages : dict of str to float
        Wall time of each stage that ran.
    worker_exit : int or None
        When the worker process exporting the design died before it reported back: its exit
        status (negative: killed by that signal, as :attr:`multiprocessing.Process.exitcode`);
        ``error_code`` is then ``"worker"``. None otherwise.
    staged : str
        The complete staging folder not yet swapped in (``export_one(..., swap=False)``);
        ``""`` once swapped in, or when nothing was written.
    earlier_files : tuple of str or None
        With ``staged``: the names earlier exports wrote into the design's folder, which the swap
        does not carry over (:func:`fabkit.pipeline.folders.swap_in`); None for a folder without
        an export record.
    card : IndexCard or None
        The design's card in index.html, made from its typed report (None when nothing was
        written).
    level : str
        The verdict's status (a :data:`fabkit.status.VERDICT` value: ``ok``, ``by design``,
        ``FLAG``, ``FAIL``), ``""`` when nothing was written.
    headline : str
        The verdict in one line (it heads report.md, report.html and the card).
    notes : list of str
        What happened to the formats earlier exports left in the folder: each kept or removed
        (stale) format in one line.
    """

    path: str
    name: str
    status: Status = Status.FAILED
    formats: dict = field(default_factory=dict)
    files: int = 0
    folder: str = ""
    message: str = ""
    error_code: str = ""
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    stages: dict = field(default_factory=dict)
    worker_exit: int | None = None
    staged: str = ""
    earlier_files: tuple | None = None
    card: object = None
    level: str = ""
    headline: str = ""
    notes: list = field(default_factory=list)

    def __post_init__(self):
        self.status = expect(self.status, EXPORT, "the export of a design")

    @property
    def ok(self) -> bool:
        return self.status is Status.OK

    @property
    def word(self) -> str:
        """The design in one word: the verdict's level when it exported (``ok``, ``by design``,
        ``FLAG``, ``FAIL``, as its reports head), else its status (``failed``, ...)."""
        return (self.level or self.status.value) if self.ok else self.status.value

    @property
    def checks(self) -> list:
        """Every as-built check of the written files (:class:`CheckResult`), format by format."""
        return [c for f in self.formats.values() for c in f.checks]

    @property
    def exported_formats(self) -> list[str]:
        return [f for f, v in self.formats.items() if v.status.produced]

    def as_dict(self) -> dict:
        return {"path": self.path, "name": self.name, "outcome": self.status.value,
                "ok": self.ok, "formats": self.exported_formats, "files": self.files,
                "folder": self.folder, "error": self.message, "error_code": self.error_code,
                "seconds": self.seconds, "cpu_seconds": self.cpu_seconds,
                "stages": dict(self.stages), "worker_exit": self.worker_exit,
                "level": self.level, "headline": self.headline, "notes": list(self.notes)}


def exit_code(results) -> int:
    """0 when every design is OK, 1 when any failed (an interrupted run exits by its signal)."""
    return 0 if all(r.ok for r in results) else 1
