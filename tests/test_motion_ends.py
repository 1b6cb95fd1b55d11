"""A motion that reaches the drive's target is not yet the design happening: every designed end
([motion] ends, or the crystal a chain is designed to end at) is judged, and a port that missed
its end is named, with what it did and why, in the status, on the command line and in the
reports."""

from __future__ import annotations

import json

import pytest

from fabkit.cli import main
from fabkit.motion import trace_motion
from fabkit.status import Status
from fabkit.templates import load_template

from conftest import TEMPLATES

#: D1o and D2o of the chaotic module's unstable 2-cycle (templates/chaotic_chain.toml).
D1O, D2O = 0.8827949195901904, 1.819468

#: Three chaotic modules designed to end on the 2-cycle: d2, d4 at D2o and d3 at D1o. Driven to
#: D1o the chain gets there; driven past it to 0.76, d1 passes the peak of the module map
#: (d2 = 1.857 at d1 = 1.004), so d2 turns back, and every module after it with it.
TWO_CYCLE = """name = "two_cycle"
description = "three chaotic modules designed to end on the 2-cycle"

[chain]
module = "{module}"
copies = 3
mirror = "alternate"

[motion]
drive = "d1"
to = {to}
ends = {{ d2 = {d2o}, d3 = {d1o}, d4 = {d2o} }}
"""


def _two_cycle(tmp_path, to: float, ends: str | None = None):
    text = TWO_CYCLE.format(module=(TEMPLATES / "chaotic.toml").as_posix(), to=to, d1o=D1O,
                            d2o=D2O)
    if ends is not None:
        text = text.replace(f"ends = {{ d2 = {D2O}, d3 = {D1O}, d4 = {D2O} }}", ends)
    path = tmp_path / "two_cycle.toml"
    path.write_text(text)
    return path


def test_a_chain_driven_past_the_turning_point_of_its_map_names_the_modules_that_missed(tmp_path):
    motion = trace_motion(load_template(_two_cycle(tmp_path, 0.76)))
    assert motion.status is Status.ENDS_MISSED and motion.status is not Status.FINISHED
    assert motion.traced  # the trace reached d1 = 0.76: usable, but the design did not happen
    assert motion.require() is motion.trajectory
    ends = motion.ends
    assert ends.source == "stated" and not ends.reached
    assert ends.missed == ("d2", "d3", "d4")
    by_port = {p.port: p for p in ends.ports}
    # d2 went up to the peak of the map (1.857) and came back below its start (1.5)
    assert by_port["d2"].extreme == pytest.approx(1.857, abs=2e-3)
    assert by_port["d2"].end < 1.5 and by_port["d2"].motion == "turned back"
    assert {p.motion for p in ends.ports} == {"turned back"}
    line = motion.line()
    assert line.startswith("ends missed: reached d1 = 0.76, but d2–d4 (modules 1–3) did not "
                           "reach their designed end: d2–d4 turned back on the way; d2 turned "
                           "back at 1.857")
    assert "a turning point of module 1's map" in line
    assert "finished" not in line


def test_the_same_chain_driven_to_its_designed_end_reaches_every_end(tmp_path):
    motion = trace_motion(load_template(_two_cycle(tmp_path, D1O)))
    assert motion.status is Status.FINISHED and motion.ends.reached
    assert [round(p.end, 4) for p in motion.ends.ports] == [round(D2O, 4), round(D1O, 4),
                                                           round(D2O, 4)]
    assert motion.line() == ("reached d1 = 0.8827949196; every designed end reached (stated in "
                             "the template ([motion] ends))")


def test_modules_that_never_leave_their_start_are_named(tmp_path):
    # super-stable modules start at the top of their map (slope 0 at sqrt 3): driven up past
    # it, d2 moves but d3 only to second order and d4, d5 not at all
    path = tmp_path / "ss_up.toml"
    path.write_text(f"""name = "ss_up"
[chain]
module = "{(TEMPLATES / 'super_stable.toml').as_posix()}"
copies = 5
mirror = "alternate"
[motion]
drive = "d1"
to = 2.05
ends = {{ d2 = 1.5, d3 = 1.5, d4 = 1.5, d5 = 1.5 }}
""")
    motion = trace_motion(load_template(path))
    assert motion.status is Status.ENDS_MISSED
    assert motion.ends.missed == ("d2", "d3", "d4", "d5")
    assert [p.motion for p in motion.ends.ports] == ["short", "stayed", "stayed", "stayed"]
    assert ("d2–d5 (modules 1–4) did not reach their designed end: d2 ended away from it; "
            "d3–d5 never left their start") in motion.message
    # why d2 is short: on its branch, d1 would have to go on to about 2.094
    assert "its designed 1.5 needs d1 near 2.09" in motion.message


def test_a_chain_that_collapses_to_its_crystal_reaches_the_ends_it_implies():
    motion = trace_motion(load_template(TEMPLATES / "super_stable_chain8.toml"))
    assert motion.status is Status.FINISHED
    ends = motion.ends
    assert ends.source == "implied" and ends.reached and ends.judged_at == "lock"
    assert len(ends.ports) == 8  # every module's input port d1 ... d8 at D2*
    assert all(p.designed == pytest.approx(1.0099505, abs=1e-6) for p in ends.ports)


def test_simulate_and_export_say_it_in_one_line(tmp_path, capsys):
    path = _two_cycle(tmp_path, 0.76)
    assert main(["simulate", str(path), "-o", str(tmp_path / "sim")]) == 1
    said = capsys.readouterr()
    # the summary says the design did not happen before the error does, never "finished"
    assert "status        ends missed: the drive reached d1 = 0.76" in said.out
    assert "finished" not in said.out
    err = said.err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith(f"fabkit: error: {path}: motion.ends: target d1 = 0.76 is reached, "
                             "but d2–d4 (modules 1–3) did not reach their designed end")
    out = tmp_path / "out"
    assert main(["export", str(path), "--to", "dxf", "-o", str(out), "--no-check",
                 "--no-previews", "--tolerance-samples", "0", "-q"]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("two_cycle:")]
    assert len(lines) == 1
    assert lines[0].startswith("two_cycle: FLAG: the design does not happen: d2–d4 (modules 1–3) "
                               "did not reach their designed end")
    report = json.loads((out / "two_cycle" / "report.json").read_text())
    assert report["verdict"]["level"] == "FLAG"
    assert report["motion"]["status"] == "ends missed"
    assert report["motion"]["ends"]["missed"] == ["d2", "d3", "d4"]
    md = (out / "two_cycle" / "report.md").read_text()
    assert md.splitlines()[2].startswith("**FLAG**: the design does not happen: d2–d4")
    # at the target, and where the motion locks just past it (0.741), where it is judged
    assert "| port | start | end | designed end | where it locks | reached |" in md
    assert "| d3 | 1.5 | 1.35402 | 0.882795 | 1.60148 | no (turned back) |" in md


@pytest.mark.parametrize("ends, key, words", [
    ("ends = { d9 = 1.0 }", "motion.ends.d9", "is not a port of the network; ports: d1, d2, d3, d4"),
    ("ends = { d2 = -1.0 }", "motion.ends.d2", "must be > 0, got -1.0"),
    ("ends = { d2 = \"far\" }", "motion.ends.d2", "number"),
    ("ends = 1.5", "motion.ends", "must be a table of port = distance, got"),
    ("ends = {}", "motion.ends", "must name at least one port"),
])
def test_bad_designed_ends_are_refused_in_one_line(tmp_path, capsys, ends, key, words):
    path = _two_cycle(tmp_path, 0.76, ends)
    assert main(["simulate", str(path), "-o", str(tmp_path / "sim")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"fabkit: error: {path}: {key}: ")
    assert words in err[0]
    assert not (tmp_path / "sim").exists() or not any((tmp_path / "sim").iterdir())
