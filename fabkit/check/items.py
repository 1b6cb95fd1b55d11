"""One item of an as-built check: what was checked, whether it holds, the size measured.

Every checker of :mod:`fabkit.check` reports its findings as :class:`Check` items, one per named
check, made by :func:`check` (or :func:`not_run` for a check that could not be run), and writes
them into its report with :func:`finish`, as the dicts report.json has always held:
``{"name", "ok", "value", "limit", "detail"}``.

A check ends in one of the statuses of :data:`fabkit.status.CHECK`: ``ok`` or ``failed``. A
check that could not be run (an earlier one found the file unusable for it) is failed, with a
detail that says so and why: a report never leaves out a check it did not run, and never says
``ok`` for one.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ..status import CHECK, expect, Status

__all__ = ["Check", "check", "not_run", "not_run_after", "all_passed", "finish"]

#: How the detail of a check that could not be run begins.
NOT_RUN = "not run"


@dataclass(frozen=True)
class Check:
    """One named check of a written file.

    Attributes
    ----------
    name : str
        What is checked ("lengths", "one closed body per bar").
    status : Status
        ``Status.OK`` or ``Status.FAILED`` (:data:`fabkit.status.CHECK`).
    value : object
        What was measured (a number, a list, None when nothing was).
    limit : object
        What it is held to (None when nothing is).
    detail : str
        One sentence: what the value is, or where and why the check failed.
    """

    name: str
    status: Status
    value: Any = None
    limit: Any = None
    detail: str = ""

    def __post_init__(self):
        object.__setattr__(self, "status", expect(self.status, CHECK, "a check of a file"))

    @property
    def passed(self) -> bool:
        """True when the check holds."""
        return self.status is Status.OK

    def as_dict(self) -> dict:
        """The item as report.json holds it: ``name``, ``ok`` (bool), ``value``, ``limit``,
        ``detail``."""
        return {"name": self.name, "ok": self.passed, "value": self.value, "limit": self.limit,
                "detail": self.detail}

    def named(self, prefix: str) -> Check:
        """The same item, its name prefixed (``"piece 2 on bed 1: lengths"``)."""
        return replace(self, name=f"{prefix}: {self.name}")


def check(name: str, ok, value=None, limit=None, detail: str = "") -> Check:
    """A check that holds when ``ok`` is true.

    Examples
    --------
    >>> check("lengths", 2e-7 <= 1e-6, 2e-7, 1e-6).as_dict()["ok"]
    True
    >>> check("lengths", False).status
    <Status.FAILED: 'failed'>
    """
    return Check(name, Status.OK if ok else Status.FAILED, value, limit, detail)


def not_run(name: str, why: str) -> Check:
    """A check that could not be run: failed, its detail saying why."""
    return Check(name, Status.FAILED, None, None, f"{NOT_RUN}: {why}")


def not_run_after(checks, names, why: str | None = None) -> list[Check]:
    """A :func:`not_run` item for every name of ``names`` that ``checks`` does not hold.

    ``why`` says what stopped them; by default the failed checks of ``checks`` are named.

    Examples
    --------
    >>> done = [check("parts", False, detail="2 bars missing")]
    >>> [c.detail for c in not_run_after(done, ["parts", "lengths"])]
    ["not run: stopped after 'parts' failed"]
    """
    have = {c.name for c in checks}
    if why is None:
        failed = [f"'{c.name}'" for c in checks if not c.passed]
        why = (f"stopped after {', '.join(failed[:4])}{' ...' if len(failed) > 4 else ''} "
               f"failed" if failed else "stopped early")
    return [not_run(n, why) for n in names if n not in have]


def all_passed(checks) -> bool:
    """True when every item holds (and there is at least one)."""
    checks = list(checks)
    return bool(checks) and all(c.passed for c in checks)


def finish(report: dict, checks, expected=(), why: str | None = None) -> dict:
    """Write ``checks`` into ``report`` (``ok`` and ``checks`` as report.json holds them), with a
    :func:`not_run` item for every name of ``expected`` they do not hold; returns the report."""
    checks = list(checks) + not_run_after(checks, expected, why)
    report.update(ok=all_passed(checks), checks=[c.as_dict() for c in checks])
    return report
