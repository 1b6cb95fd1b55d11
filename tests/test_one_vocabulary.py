"""One result vocabulary: every stage ends in a :class:`fabkit.status.Status` and a message.

There is one status enum in fabkit (:mod:`fabkit.status`); every stage's result carries a
``status`` from its stage's set and a one-sentence ``message``, and refuses a status outside that
set when it is made; report.json says the same string values it always did.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest

import fabkit
from fabkit import status as vocabulary
from fabkit.executor import TaskEnd
from fabkit.kinematics import Solved, Trajectory
from fabkit.motion import TracedMotion
from fabkit.pipeline import CheckResult, DesignResult, FormatResult, Verdict, export_many
from fabkit.status import Status
from fabkit.sweep.chunks import SweepRecord

from conftest import TEMPLATES

ROOT = Path(fabkit.__file__).parent

#: Enum classes of fabkit that are not a status, and why.
NOT_STATUSES = {
    "EventKind": "what a trace met on its way (an event at a configuration), not how it ended",
    "ExitCode": "the number the process exits with (documented per command), not a stage's end",
    "Stage": "the name of a stage of an export (progress lines, timings), not how it ended",
}

#: Name endings of a class that would be a second status vocabulary.
STATUS_LIKE = ("Status", "Outcome", "Level", "Ending")


def _enum_classes() -> list[tuple[str, str]]:
    """(file, class name) of every class in fabkit/ that derives from an Enum."""
    found = []
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.ClassDef):
                continue
            bases = [b.attr if isinstance(b, ast.Attribute) else getattr(b, "id", "")
                     for b in node.bases]
            if any(b.endswith(("Enum", "Flag")) for b in bases):
                found.append((str(path.relative_to(ROOT.parent)), node.name))
    return found


def test_the_walk_sees_every_enum():
    names = {name for _, name in _enum_classes()}
    assert {"Status", "EventKind", "ExitCode", "Stage"} <= names


def test_one_status_enum_in_fabkit():
    found = _enum_classes()
    status_like = [(f, n) for f, n in found if n.endswith(STATUS_LIKE)]
    assert status_like == [("fabkit/status.py", "Status")]
    others = sorted(n for f, n in found if f != "fabkit/status.py")
    assert others == sorted(NOT_STATUSES)


def _status_spelt_out(tree) -> list[int]:
    """Lines where a status is compared as text: ``str(x.status) == "finished"`` and the like
    (a status is compared as a member, ``x.status is Status.FINISHED``, or by ``x.success``)."""
    lines = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Compare):
            continue
        sides = [node.left, *node.comparators]
        spelt = any(isinstance(n, ast.Call) and getattr(n.func, "id", "") == "str" and n.args
                    and isinstance(n.args[0], ast.Attribute) and n.args[0].attr == "status"
                    for n in sides)
        if spelt:
            lines.append(node.lineno)
    return lines


def test_no_status_is_compared_as_text():
    found = {str(p.relative_to(ROOT.parent)): _status_spelt_out(ast.parse(p.read_text("utf-8")))
             for p in sorted(ROOT.rglob("*.py"))}
    assert {f: lines for f, lines in found.items() if lines} == {}
    # the walk sees the case it exists for
    assert _status_spelt_out(ast.parse('ok = str(t.status) == "finished"')) == [1]


def test_every_public_status_is_the_one_enum():
    import fabkit.kinematics
    import fabkit.pipeline
    import fabkit.sweep

    assert fabkit.kinematics.Status is Status
    assert fabkit.pipeline.Status is Status
    assert fabkit.sweep.Status is Status
    for name in ("MotionStatus", "FormatStatus", "Outcome", "Level", "Ending"):
        for module in (fabkit.kinematics, fabkit.pipeline, fabkit.sweep, fabkit.motion,
                       fabkit.executor):
            assert not hasattr(module, name), f"{module.__name__}.{name}"


def test_every_stage_set_is_of_the_one_enum_and_every_status_is_used():
    sets = [vocabulary.TRACE, vocabulary.MOTION, vocabulary.EXPORT, vocabulary.FORMAT,
            vocabulary.CHECK, vocabulary.VERDICT, vocabulary.TASK, vocabulary.SWEEP_POINT]
    assert all(isinstance(s, Status) for stage in sets for s in stage)
    assert set().union(*sets) == set(Status)
    assert [s.rank for s in vocabulary.VERDICT_ORDER] == [0, 1, 2, 3]


# --- every stage result: its status from its stage's set, and a message -----------------------

def _trajectory(status):
    net = fabkit.Network([[0, 0], [1, 0], [0, 1]], [[0, 1], [1, 2], [0, 2]],
                         ports={"d1": (1, 2)})
    one = np.zeros(1)
    return Trajectory(net, net.nodes[None], one, one, one, "toy", status, "a sentence", (1, 2),
                      1.0)


def _task(status):
    return TaskEnd(0, status, value=ValueError("boom"))


def _sweep_point(status):
    return SweepRecord(index=0, params={"motion.to": 1.0}, status=str(status),
                       reason="a sentence")


#: name → (make a result of a status, the stage's set, a status of another stage)
RESULTS = {
    "trajectory": (_trajectory, vocabulary.TRACE, Status.EXPORTED),
    "solved": (lambda s: Solved(None, s, "a sentence"), vocabulary.TRACE, Status.ENDS_MISSED),
    "motion": (lambda s: TracedMotion(None, s, "a sentence"), vocabulary.MOTION, Status.OK),
    "design": (lambda s: DesignResult("a.toml", "a", s, message="a sentence"),
               vocabulary.EXPORT, Status.FLAG),
    "format": (lambda s: FormatResult("dxf", s, message="a sentence"), vocabulary.FORMAT,
               Status.FINISHED),
    "verdict": (lambda s: Verdict(s, "a sentence"), vocabulary.VERDICT, Status.EXPORTED),
    "task": (_task, vocabulary.TASK, Status.FAILED),
    "sweep point": (_sweep_point, vocabulary.SWEEP_POINT, Status.FINISHED),
}


@pytest.mark.parametrize("name", sorted(RESULTS))
def test_a_stage_result_has_a_status_of_its_stage_and_a_message(name):
    make, allowed, _ = RESULTS[name]
    for status in sorted(allowed, key=lambda s: s.value):
        result = make(status)
        assert Status(result.status) is status
        assert isinstance(result.message, str) and result.message


@pytest.mark.parametrize("name", sorted(RESULTS))
def test_a_stage_result_refuses_a_status_of_another_stage(name):
    make, allowed, wrong = RESULTS[name]
    assert wrong not in allowed
    with pytest.raises(ValueError):
        make(wrong)
    with pytest.raises(ValueError):
        make("no such status")


def test_a_check_of_a_written_file_says_ok_or_failed():
    good, bad = CheckResult("a.dxf", True), CheckResult("b.dxf", False, error="cannot read it")
    assert (good.status, good.message) == (Status.OK, "")
    assert (bad.status, bad.message) == (Status.FAILED, "cannot read it")
    assert {good.status, bad.status} == vocabulary.CHECK


def test_a_task_says_how_it_ended_in_a_sentence():
    assert _task(Status.RAISED).message == "it raised ValueError: boom"
    stuck = TaskEnd(3, Status.TIMED_OUT, limit=2.5)
    assert stuck.stopped and stuck.message == ("it ran past its time limit of 2.5 s; its worker "
                                               "was killed")


def test_a_status_read_back_from_report_json_is_accepted_as_its_value():
    assert FormatResult("dxf", "exported").status is Status.EXPORTED
    assert DesignResult("a.toml", "a", "check failed").status is Status.CHECK_FAILED


# --- what report.json says --------------------------------------------------------------------

def test_report_json_says_the_documented_values(tmp_path):
    (res,) = export_many([str(TEMPLATES / "fourbar.toml")], ["dxf"], str(tmp_path),
                         isolate=False, tolerance_samples=0, previews=False)
    assert res.status is Status.OK and res.message == "" and res.word == "ok"
    report = json.loads((tmp_path / "fourbar" / "report.json").read_text(encoding="utf-8"))
    assert (report["outcome"], report["ok"]) == ("ok", True)
    assert report["verdict"]["level"] == "ok"
    assert report["verdict"]["text"].startswith("every as-built check passed")
    assert report["motion"]["status"] == "finished"
    assert report["formats"]["dxf"]["status"] == "exported"
    assert "detail" not in report["formats"]["dxf"]
    assert [c["ok"] for c in report["formats"]["dxf"]["checks"]] == [True, True]
    # the batch's own record: the same words under the documented keys
    row = res.as_dict()
    assert (row["outcome"], row["error"], row["level"]) == ("ok", "", "ok")
