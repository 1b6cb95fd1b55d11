"""Typed results of the batch: how a design and each of its formats ended."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum



class Outcome(str, Enum):
    """How the export of one design ended."""

    OK = "ok"                      #: every file written and every as-built check passed
    FAILED = "failed"              #: nothing written: bad template, impossible motion, refusal
    CHECK_FAILED = "check failed"  #: files written, but an as-built check failed
    #: a format asked for (``--to``) cannot be produced: report.json names it ``refused`` with
    #: the reason; the formats that could be made are written
    REFUSED = "refused"
    INTERRUPTED = "interrupted"    #: stopped by a signal before it finished; nothing written

    def __str__(self) -> str:
        return self.value


class FormatStatus(str, Enum):
    """What happened to one format of one design."""

    EXPORTED = "exported"
    CHECK_FAILED = "check failed"
    DOES_NOT_APPLY = "does not apply"
    NOT_AVAILABLE = "not available"
    SKIPPED = "skipped by the template"
    #: asked for by name and cannot be produced (it does not apply, the template opts out, or
    #: it is not installed): the design fails with the reason in ``detail``
    REFUSED = "refused"

    def __str__(self) -> str:
        return self.value

    @property
    def produced(self) -> bool:
        """True when the format wrote files."""
        return self in (FormatStatus.EXPORTED, FormatStatus.CHECK_FAILED)


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
    """The as-built check of one written file (``fabkit.check``)."""

    file: str
    ok: bool
    checks: list = field(default_factory=list)
    error: str = ""
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        out = {**self.extra, "file": self.file, "ok": self.ok, "checks": self.checks}
        if self.error:
            out["error"] = self.error
        return out


@dataclass
class FormatResult:
    """One format of one design: its status, files, exporter report and checks."""

    name: str
    status: FormatStatus
    files: list = field(default_factory=list)
    report: dict = field(default_factory=dict)
    detail: str = ""
    checks: list = field(default_factory=list)

    def as_dict(self) -> dict:
        out = {"status": self.status.value, "files": list(self.files)}
        if self.status.produced:
            out["report"] = self.report
        if self.detail:
            out["detail"] = self.detail
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
    outcome : Outcome
    formats : dict of str to FormatResult
    files : int
        Files written into the folder (reports included).
    folder : str
        The design's folder, or ``""`` when nothing was written.
    error : str
        One line when the outcome is not OK, else ``""``.
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
        The verdict's level (:class:`fabkit.pipeline.stages.Level` value: ``ok``, ``by design``,
        ``FLAG``, ``FAIL``), ``""`` when nothing was written.
    headline : str
        The verdict in one line (it heads report.md, report.html and the card).
    notes : list of str
        What happened to the formats earlier exports left in the folder: each kept or removed
        (stale) format in one line.
    """

    path: str
    name: str
    outcome: Outcome = Outcome.FAILED
    formats: dict = field(default_factory=dict)
    files: int = 0
    folder: str = ""
    error: str = ""
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

    @property
    def ok(self) -> bool:
        return self.outcome is Outcome.OK

    @property
    def status(self) -> str:
        """The design in one word: the verdict's level when it exported (``ok``, ``by design``,
        ``FLAG``, ``FAIL``, as its reports head), else the outcome (``failed``, ...)."""
        return (self.level or self.outcome.value) if self.ok else self.outcome.value

    @property
    def exported_formats(self) -> list[str]:
        return [f for f, v in self.formats.items() if v.status.produced]

    def as_dict(self) -> dict:
        return {"path": self.path, "name": self.name, "outcome": self.outcome.value,
                "ok": self.ok, "formats": self.exported_formats, "files": self.files,
                "folder": self.folder, "error": self.error, "error_code": self.error_code,
                "seconds": self.seconds, "cpu_seconds": self.cpu_seconds,
                "stages": dict(self.stages), "worker_exit": self.worker_exit,
                "level": self.level, "headline": self.headline, "notes": list(self.notes)}


def exit_code(results) -> int:
    """0 when every design is OK, 1 when any failed (an interrupted run exits by its signal)."""
    return 0 if all(r.ok for r in results) else 1
