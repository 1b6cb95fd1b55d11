"""The typed stages of one design's export, and the verdict that heads its reports.

``fabkit export`` takes a design through explicit stages, each a typed result handed to the
next (as scipy's ``solve_ivp`` hands back one result with a status and a message)::

    Design ─► Motion ─► Plan ─► Artefacts ─► Checks ─► Verdict ─► Report

- **Motion** (:class:`fabkit.motion.TracedMotion`): the design's motion, traced once per
  window, with its status (did the drive reach its target, did every module reach its designed
  end?); every later stage reads it, none traces again.
- **Plan** (:class:`Plan`): the formats made, those not made and why, and the one process the
  export is made by and judged as (:func:`fabkit.tolerance.made_process`).
- **Artefacts** (:class:`Artefacts`): every file in memory, each format's result, the tolerance
  analysis of that process.
- **Checks** (:class:`Checks`): the as-built check of every written file.
- **Verdict** (:class:`Verdict`): the worst of the checks, the motion and the tolerance analysis,
  in one line that heads report.md, report.html and the design's card in index.html.
- **Report** (:class:`DesignReport`): everything the reports are rendered from, in memory; no
  report is made by reading another back.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from ..status import Status, VERDICT, expect

__all__ = ["Plan", "Artefacts", "Checks", "Finding", "Verdict", "DesignReport",
           "judge_design"]


@dataclass(frozen=True, eq=False)
class Plan:
    """The Plan stage: which formats a design gets, and the process it is made by.

    Attributes
    ----------
    chosen : tuple of (str, module)
        The formats to make, with their exporter modules.
    skipped : dict of str to FormatResult
        The formats not made, with their status and reason.
    process : str
        ``"laser"``, ``"print"`` or ``"origami"``: the process of the files made (its scale,
        error model and vocabulary head the report and judge the tolerance analysis).
    tolerance : ToleranceSpec or None
        The tolerance analysis to run (None: not run).
    """

    chosen: tuple
    skipped: dict
    process: str
    tolerance: object = None

    @property
    def formats(self) -> list[str]:
        return [f for f, _ in self.chosen]


@dataclass(frozen=True, eq=False)
class Artefacts:
    """The Artefacts stage: every file of the design's folder in memory (the reports excluded:
    they come after the checks), each format's result and the tolerance analysis.

    Attributes
    ----------
    files : dict of str to bytes
    formats : dict of str to FormatResult
    tolerance : ToleranceResult or None
    previews : tuple of str
        The pictures report.md shows (ours, the exporters' PNG and SVG files).
    plans : dict of str to plan
        The plan of each process whose writers made files (:func:`fabkit.fab.plans.make_plan`),
        made once: the reports draw from them (an origami sheet's panels, a print's plates).
    """

    files: dict
    formats: dict
    tolerance: object = None
    previews: tuple = ()
    plans: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Checks:
    """The Checks stage: the as-built check of every written file, by format."""

    by_format: dict = field(default_factory=dict)

    @property
    def results(self) -> list:
        return [c for checks in self.by_format.values() for c in checks]

    @property
    def failed(self) -> list:
        return [c for c in self.results if not c.ok]


@dataclass(frozen=True)
class Finding:
    """One thing the verdict weighs: its level (a :data:`fabkit.status.VERDICT` status), what it
    is about, and a sentence."""

    level: Status
    about: str
    text: str

    def __post_init__(self):
        object.__setattr__(self, "level", expect(self.level, VERDICT, "a finding"))


@dataclass(frozen=True)
class Verdict:
    """The Verdict stage: the worst of a design's checks, motion and tolerance analysis.

    Attributes
    ----------
    status : Status
        One of :data:`fabkit.status.VERDICT` (report.json's ``level``).
    message : str
        The finding that set the status, in words (shown beside its badge; report.json's
        ``text``).
    findings : tuple of Finding
        Every finding, worst first.
    """

    status: Status
    message: str
    findings: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "status", expect(self.status, VERDICT, "a verdict"))

    @property
    def headline(self) -> str:
        """One line: the status and the finding that set it (a design flagged by intent says so
        in words: its message starts "chaotic by design")."""
        return self.message if self.status is Status.BY_DESIGN else \
            f"{self.status}: {self.message}"

    def as_dict(self) -> dict:
        return {"level": self.status.value, "headline": self.headline, "text": self.message,
                "findings": [{"level": f.level.value, "about": f.about, "text": f.text}
                             for f in self.findings]}


#: Longest finding (characters) a verdict's line carries; the rest is in the report's
#: tolerance section.
FINDING_CHARS = 240
#: Said where a finding's clauses stop short of its whole text.
MORE = " (more in the report)"


def _first_clause(text: str, limit: int = FINDING_CHARS) -> str:
    """``text`` whole when it fits in ``limit`` characters, else its first clauses (cut at
    "; ", never inside a word) that fit, and :data:`MORE`; a first clause longer than
    the limit is cut at the last space that fits."""
    if len(text) <= limit:
        return text
    room = limit - len(MORE)
    cuts = [m.start() for m in re.finditer(r"; ", text) if m.start() <= room]
    if not cuts:
        cuts = [m.start() for m in re.finditer(r" ", text) if 0 < m.start() <= room]
    end = max(cuts) if cuts else len(text)
    return text[:end].rstrip(" ,;:") + (MORE if end < len(text) else "")


def _tolerance_finding(tolerance) -> Finding:
    """What a flagged tolerance analysis adds to the verdict: chaos by design, or a FLAG."""
    chaos = tolerance.behaviour.chaos if tolerance.behaviour is not None else None
    if chaos is not None:
        hz = tolerance.horizon or {}
        after = hz.get("limit_modules")
        return Finding(
            Status.BY_DESIGN, "tolerance",
            f"chaotic by design: its module map stretches errors by e^{chaos['lyapunov']:.2f} "
            "a module, so "
            + (f"a {hz['error_mm']:.3g} mm build error outgrows what is allowed after about "
               f"{after:.0f} modules and " if after is not None and "error_mm" in hz else "")
            + f"no build can keep the far end of its {chaos['modules']} modules where the "
            "design puts it; the tolerance analysis flags that, as the design intends")
    # "FLAG, margin 0.75; ..." said once: the level heads the line
    said = tolerance.verdict.removeprefix("FLAG, ")
    return Finding(Status.FLAG, "tolerance",
                   f"tolerance as {tolerance.spec.process} builds: {_first_clause(said)}")


def _passed(formats: dict, checks: Checks, motion, tolerance) -> list[str]:
    """The parts of an OK verdict's line: what was checked and passed."""
    parts = []
    n = len(checks.results)
    if n:
        parts.append(f"every as-built check passed ({n} file{'s' if n != 1 else ''} read back)")
    if tolerance is not None:  # "ok, margin 7.5" (the whole verdict is in its section)
        parts.append(f"tolerance as {tolerance.spec.process} builds: "
                     f"{tolerance.verdict.split(':')[0]}")
    if motion is not None and motion.ends is not None:
        parts.append("every designed end reached")
    if not parts:
        parts.append("nothing was checked" if not any(
            f.status.produced for f in formats.values()) else "no as-built check ran")
    return parts


def judge_design(outcome, formats: dict, checks: Checks, motion, tolerance,
                 refused: list) -> Verdict:
    """The Verdict stage: the worst of every check, the motion and the tolerance analysis.

    A failed as-built check or a format asked for and not made is a FAIL; a motion whose ports
    miss their designed end, and a tolerance analysis that flags the design, a FLAG; a design
    whose module map is chaotic (the tolerance analysis flags its far end, which no build can
    predict) is flagged *by design* and says so in words. A FLAG is never headed "ok".

    Parameters
    ----------
    outcome : Status
    formats : dict of str to FormatResult
    checks : Checks
    motion : TracedMotion or None
    tolerance : ToleranceResult or None
    refused : list of str
        ``"fmt: reason"`` of each format asked for and not made.

    Returns
    -------
    Verdict
    """
    found = []
    for line in refused:
        found.append(Finding(Status.FAIL, "format", f"cannot produce {line}"))
    for chk in checks.failed:
        bad = [c.get("name") for c in chk.checks if not c.get("ok")]
        found.append(Finding(Status.FAIL, "check", f"the as-built check of {chk.file} failed"
                             + (f" ({chk.error})" if chk.error else
                                f" ({', '.join(map(str, bad[:3]))})" if bad else "")))
    if not refused and not any(f.status.produced for f in formats.values()):
        why = "; ".join(f"{k}: {v.status}" + (f" – {v.message}" if v.message else "")
                        for k, v in sorted(formats.items()))
        found.append(Finding(Status.FLAG, "files", "nothing to build was written"
                             + (f" ({why})" if why else "")))
    if motion is not None and motion.status is Status.ENDS_MISSED:
        found.append(Finding(Status.FLAG, "motion", f"the design does not happen: "
                                                   f"{motion.ends.reason}"))
    if tolerance is not None and tolerance.flagged:
        found.append(_tolerance_finding(tolerance))
    found.sort(key=lambda f: -f.level.rank)
    if found:
        worst = found[0]
        others = sum(1 for f in found[1:] if f.level is not Status.OK)
        more = f" (and {others} more below)" if others else ""
        return Verdict(worst.level, worst.text + more, tuple(found))
    parts = _passed(formats, checks, motion, tolerance)
    return Verdict(Status.OK, "; ".join(parts))


@dataclass(frozen=True, eq=False)
class DesignReport:
    """The Report stage's input: everything report.json, report.md and report.html of one design
    say, as typed results in memory.

    Attributes
    ----------
    design : Design
    facts : dict
        Name, description, template and its digest, sizes, mode count
        (:func:`fabkit.report.text.design_facts`).
    motion : TracedMotion or None
    plan : Plan
    artefacts : Artefacts
    checks : Checks
    verdict : Verdict
    outcome : Status
    errors : list of str
    names : list of str
        Every file the export writes into the folder, the reports included.
    origins : dict of str to FormatOrigin
        Where each format in the folder came from: this export, or an earlier one whose files
        stay (:mod:`fabkit.pipeline.manifest`).
    removed : tuple of str
        The stale formats of earlier exports removed from the folder, one line each with why.
    """

    design: object
    facts: dict
    motion: object
    plan: Plan
    artefacts: Artefacts
    checks: Checks
    verdict: Verdict
    outcome: Status
    errors: tuple = ()
    names: tuple = ()
    origins: dict = field(default_factory=dict)
    removed: tuple = ()

    @property
    def process(self) -> str:
        return self.plan.process

    @property
    def formats(self) -> dict:
        return self.artefacts.formats

    @property
    def tolerance(self):
        return self.artefacts.tolerance

    @property
    def kept(self) -> set:
        """Formats an earlier export made whose files stay in the folder (this export did not
        make them again)."""
        return {f for f, o in self.origins.items()
                if f not in self.plan.formats and self.formats.get(f) is not None}

    def produced(self, fmt: str) -> bool:
        f = self.formats.get(fmt)
        return f is not None and f.status is Status.EXPORTED
