"""fabkit.io.progress: the one way long commands say how far they are (stage, count done of
total, time left), on stderr, shown on a terminal, forced with --progress, silenced with -q."""

from __future__ import annotations

import io
import os

import pytest

from fabkit.io.progress import Progress, duration


class Clock:
    """A clock the test moves by hand (seconds)."""

    def __init__(self, now: float = 100.0):
        self.now = now

    def __call__(self) -> float:
        return self.now


def _progress(clock, **kwargs):
    out = io.StringIO()
    return Progress("fabkit job", show=True, stream=out, clock=clock, **kwargs), out


def _lines(out) -> list[str]:
    return out.getvalue().splitlines()


@pytest.mark.parametrize("seconds, text", [
    (0.0, "0.0 s"), (0.04, "0.0 s"), (9.94, "9.9 s"), (10.2, "10 s"), (89.4, "89 s"),
    (90, "1 min 30 s"), (599, "9 min 59 s"), (600, "10 min"), (659, "11 min"), (3599, "60 min"),
    (3600, "1 h 00 min"), (7500, "2 h 05 min"),
    (-1, "?"), (float("nan"), "?"), (float("inf"), "?"),
])
def test_durations_read_as_a_person_reads_them(seconds, text):
    assert duration(seconds) == text


def test_a_stage_and_its_count_with_the_time_left_at_the_rate_so_far():
    clock = Clock()
    p, out = _progress(clock)
    p.stage("tracing", total=4, unit="points")
    clock.now += 3.0
    p.update(1)  # 3 s for the first point: 9 s for the three others
    clock.now += 1.0
    p.update(2)  # 4 s for two: 2 s each, 4 s for the two others
    clock.now += 4.0
    p.update(4)
    assert _lines(out) == [
        "fabkit job [0/4 points, 0.0 s] tracing",
        "fabkit job [1/4 points, 3.0 s, about 9.0 s left] tracing",
        "fabkit job [2/4 points, 4.0 s, about 4.0 s left] tracing",
        "fabkit job [4/4 points, 8.0 s] tracing",  # done: no time left to guess
    ]


def test_count_lines_are_thinned_named_events_are_not():
    clock = Clock()
    p, out = _progress(clock, every=10.0)
    p.stage("many", total=1000, unit="points")
    for done in range(1, 1001):
        clock.now += 0.001  # quick points: a line per tenth only
        p.update(done)
    counts = [line.split("[", 1)[1].split(" ", 1)[0] for line in _lines(out)]
    assert counts == ["0/1000", *(f"{k}/1000" for k in range(100, 1001, 100))]
    out.seek(0), out.truncate()
    p.stage("slow", total=1000, unit="points")
    for done in range(1, 4):
        clock.now += 11.0  # slower than `every`: each move of the count prints
        p.update(done)
    p.update(3)  # no move, no line
    p.update(3, text="a named event")  # always a line
    assert [line.split(",")[0] for line in _lines(out)] == [
        "fabkit job [0/1000 points", "fabkit job [1/1000 points", "fabkit job [2/1000 points",
        "fabkit job [3/1000 points", "fabkit job [3/1000 points"]
    assert _lines(out)[-1].endswith("] a named event")


def test_the_item_in_hand_has_its_own_count_and_the_time_left_is_its_own():
    clock = Clock()
    p, out = _progress(clock)
    p.stage("a.toml, b.toml", total=2, unit="templates")
    p.within(0, 4, "steps", "a: builds")
    clock.now += 2.0
    p.within(1, 4, "steps", "a: margin")
    clock.now += 2.0
    p.advance(text="a.toml: done")
    p.stage("b: loading")  # the count goes on; the inner count ends
    assert _lines(out) == [
        "fabkit job [0/2 templates, 0.0 s] a.toml, b.toml",
        "fabkit job [0/2 templates, 0/4 steps, 0.0 s] a: builds",
        "fabkit job [0/2 templates, 1/4 steps, 2.0 s, about 6.0 s left in this one] a: margin",
        "fabkit job [1/2 templates, 4.0 s, about 4.0 s left] a.toml: done",
        "fabkit job [1/2 templates, 4.0 s, about 4.0 s left] b: loading",
    ]


def test_a_time_left_too_short_to_read_is_left_out():
    clock = Clock()
    p, out = _progress(clock)
    p.stage("quick", total=3, unit="steps")
    clock.now += 0.01
    p.update(1, text="one")  # 0.02 s left: "0.0 s" would tell nothing
    clock.now += 0.5
    p.update(2, text="two")  # 0.26 s a step
    assert _lines(out)[1:] == ["fabkit job [1/3 steps, 0.0 s] one",
                               "fabkit job [2/3 steps, 0.5 s, about 0.3 s left] two"]


def test_a_resumed_count_times_only_the_work_of_this_run():
    clock = Clock()
    p, out = _progress(clock)
    p.stage("computing, 60 read back", total=100, unit="points", done=60)
    clock.now += 10.0
    p.update(70, text="computing")  # 1 s a point in this run: 30 s for the 30 left
    assert _lines(out)[-1] == "fabkit job [70/100 points, 10 s, about 30 s left] computing"


def test_quiet_prints_nothing_and_a_stream_that_is_gone_is_not_an_error():
    clock = Clock()
    out = io.StringIO()
    p = Progress("fabkit job", show=False, stream=out, clock=clock)
    p.stage("x", total=3, unit="runs")
    p.advance(text="one")
    p.note("a finding")
    p.close()
    assert out.getvalue() == "" and p.done == 1
    gone = io.StringIO()
    p = Progress("fabkit job", show=True, stream=gone, clock=clock)
    gone.close()
    p.stage("x")  # a closed stream: progress stops, the job goes on
    p.note("y")
    p.close()
    assert p.show is False


def test_a_multi_line_text_stays_one_line():
    p, out = _progress(Clock())
    p.note("first\nsecond  \n")
    assert _lines(out) == ["fabkit job [0.0 s] first second"]


def test_shown_on_a_terminal_and_not_on_a_pipe_or_a_file(tmp_path):
    master, slave = os.openpty()
    try:
        with open(slave, "w", closefd=False) as tty:
            p = Progress("fabkit job", stream=tty)  # show=None: decided by the stream
            assert p.show is True
            p.stage("on a terminal")
        text = os.read(master, 4096).decode()
        assert text.startswith("fabkit job [") and "] on a terminal" in text
    finally:
        os.close(master)
        os.close(slave)
    with open(tmp_path / "log.txt", "w") as log:
        p = Progress("fabkit job", stream=log)
        assert p.show is False
        p.stage("in a file")
    assert (tmp_path / "log.txt").read_text() == ""
    assert Progress("fabkit job", stream=io.StringIO()).show is False
