"""Progress of a long job, said the same way by every command: one line per event on stderr.

Every command that can run for more than a couple of seconds (``export``, ``sweep``, ``bench``,
``tolerance``, ``design``, ``map --lyapunov``, ``simulate``, ``letters``, ``check``, ``fold``,
``info`` of many templates) reports through one :class:`Progress`, from its start::

    fabkit sweep [0/40 points, 0.3 s] period_doubling: 40 points on 2 processes
    fabkit sweep [12/40 points, 9.8 s, about 23 s left] period_doubling: computing
    fabkit export [1/3 designs, 41 s, about 1 min 22 s left] super_stable_chain: tolerance

The stream is **stderr**, for every command: stdout carries what a command is for (the summary
table, the results a script reads, ``check --json``, ``templates | head``), so that
``fabkit export ... > summary.txt`` keeps a clean file while the progress still shows on the
terminal. Progress shows when stderr is a terminal; ``--progress`` shows it anyway (a log file,
a CI job), ``-q`` never. Errors stay one line (``fabkit: error: ...``) and come last.

Lines, never a status line redrawn in place: stdout and stderr share a terminal, and a line
redrawn with carriage returns would mix with the results printed meanwhile. Count updates are
thinned out (the first, one per tenth of the work or per :data:`EVERY` seconds, the last);
stages and named events always print.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

__all__ = ["Progress", "duration", "EVERY"]

#: Seconds between two count lines when the count moves on without a named event.
EVERY = 10.0

#: ``Progress.stage(total=...)`` left out: the count so far goes on.
_SAME = object()


def duration(seconds: float) -> str:
    """Seconds as a person reads them: ``"0.4 s"``, ``"42 s"``, ``"3 min 20 s"``,
    ``"2 h 05 min"``.

    Examples
    --------
    >>> duration(0.43), duration(42.2), duration(200), duration(7500)
    ('0.4 s', '42 s', '3 min 20 s', '2 h 05 min')
    """
    if not math.isfinite(seconds) or seconds < 0:
        return "?"
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 3600:
        m, s = divmod(int(round(seconds)), 60)
        if m >= 10:  # seconds no longer matter: the nearest minute
            return f"{int(round(seconds / 60))} min"
        return f"{m} min {s} s" if s else f"{m} min"
    h, m = divmod(int(round(seconds / 60)), 60)
    return f"{h} h {m:02d} min"


@dataclass
class _Count:
    """Work that can be counted: ``done`` of ``total`` ``unit``, counted since ``since`` from
    ``start`` (a resumed sweep starts with the points read back); the count last moved at
    ``at``."""

    total: int
    unit: str
    done: int
    since: float
    start: int
    at: float = 0.0

    def __str__(self) -> str:
        return f"{self.done}/{self.total}" + (f" {self.unit}" if self.unit else "")

    def move(self, done: int, now: float) -> None:
        if done != self.done:
            self.done, self.at = int(done), now

    def left(self, now: float) -> float | None:
        """Seconds left, at the time per unit of the units done so far, less the time already
        spent on the unit in hand (but never less than the units after it need); None before
        anything is done."""
        if self.done <= self.start or self.done >= self.total:
            return None
        each = max(self.at - self.since, 0.0) / (self.done - self.start)
        rest = self.total - self.done
        return max(each * rest - (now - self.at), each * (rest - 1))

    def tenth(self) -> int:
        return int(10 * self.done / self.total) if self.total else -1


class Progress:
    """Progress lines of one command: stage, count done of total, time left.

    A command has one count (the designs of an export, the points of a sweep, the templates of
    a ``tolerance`` run), and the item in hand may have its own (:meth:`within`: the steps of
    one template's analysis); the time left is that of the inner count while there is one.

    Parameters
    ----------
    command : str
        Said at the start of every line (``"fabkit export"``).
    show : bool or None
        True: always print (``--progress``); False: never (``-q``); None: when the stream is a
        terminal.
    stream : file, optional
        Default ``sys.stderr`` as it is when the object is made (a test's capture too).
    every : float
        Seconds between count lines without a named event.
    clock : callable, optional
        Seconds, monotonic (default :func:`time.monotonic`).

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> p = Progress("fabkit demo", show=True, stream=out, clock=iter([0, 0, 2, 3]).__next__)
    >>> p.stage("two things", total=2, unit="things")
    >>> p.advance(text="first done")
    >>> p.advance(text="second done")
    >>> print(out.getvalue(), end="")
    fabkit demo [0/2 things, 0.0 s] two things
    fabkit demo [1/2 things, 2.0 s, about 2.0 s left] first done
    fabkit demo [2/2 things, 3.0 s] second done
    """

    def __init__(self, command: str, *, show: bool | None = None, stream=None,
                 every: float = EVERY, clock=None):
        self.command = command
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock or time.monotonic
        self.every = every
        self.show = self._is_terminal() if show is None else bool(show)
        self.t0 = self.clock()
        self.text = ""
        self.count: _Count | None = None   # the command's count
        self.inner: _Count | None = None   # the count of the item in hand
        self._printed = (self.t0, -1, -1)  # time, count and tenth of the last line

    def _is_terminal(self) -> bool:
        try:
            return bool(self.stream.isatty())
        except (AttributeError, ValueError, OSError):  # closed, or not a file
            return False

    @property
    def done(self) -> int:
        """Units of the command's count done (0 without a count)."""
        return self.count.done if self.count else 0

    # --- what commands call ------------------------------------------------------------------

    def stage(self, text: str, *, total=_SAME, unit: str | None = None, done: int = 0) -> None:
        """A stage starts; always one line. With ``total``, a new count starts at ``done`` of
        ``total`` ``unit`` (``total=None``: a stage that is not counted); without, the count so
        far goes on (a design's next stage). Any count within the last item ends."""
        now = self.clock()
        self.text, self.inner = text, None
        if total is not _SAME:
            unit = unit if unit is not None else (self.count.unit if self.count else "")
            self.count = None if total is None else _Count(int(total), unit, int(done), now,
                                                           int(done), now)
        self._line(now)

    def update(self, done: int, total: int | None = None, text: str | None = None) -> None:
        """The command's count is now ``done`` (of ``total``, when it changed). With ``text``
        the line always prints (a named event: a design finished, a run measured); without,
        only the first, one per tenth of the work or per ``every`` seconds, and the last."""
        now = self.clock()
        if self.count is None:
            self.count = _Count(int(total or done), "", 0, self.t0, 0, self.t0)
        if total is not None:
            self.count.total = int(total)
        self.count.move(done, now)
        self.inner = None
        if text is not None:
            self.text = text
            self._line(now)
            return
        self._maybe_line(now, self.count)

    def advance(self, step: int = 1, text: str | None = None) -> None:
        """``step`` more units of the command's count done (see :meth:`update`)."""
        self.update(self.done + step, text=text)

    def within(self, done: int, total: int, unit: str, text: str | None = None) -> None:
        """The item in hand has ``done`` of ``total`` ``unit`` done (the steps of one
        template's analysis); a line with ``text``, else as for :meth:`update`."""
        now = self.clock()
        if self.inner is None or self.inner.unit != unit or self.inner.total != total \
                or done < self.inner.done:
            self.inner = _Count(int(total), unit, int(done), now, int(done), now)
        self.inner.move(done, now)
        if text is not None:
            self.text = text
            self._line(now)
        else:
            self._maybe_line(now, self.inner)

    def note(self, text: str) -> None:
        """A line that says something without moving the count (a finding, a warning)."""
        self.text = text
        self._line(self.clock())

    def close(self) -> None:
        """The job is done: nothing more to say (results follow on stdout)."""
        try:
            self.stream.flush()
        except (AttributeError, ValueError, OSError):
            pass

    # --- the line ----------------------------------------------------------------------------

    def left(self, now: float | None = None) -> float | None:
        """Seconds left: of the item in hand while it has a count, else of the command's
        count; None when the work is not countable or nothing of it is done yet."""
        now = self.clock() if now is None else now
        for count in (self.inner, self.count):
            if count is not None:
                left = count.left(now)
                if left is not None:
                    return left
        return None

    def prefix(self, now: float) -> str:
        """``[3/40 points, 12 s, about 1 min left]``."""
        parts = [str(c) for c in (self.count, self.inner) if c is not None]
        parts.append(duration(now - self.t0))
        left = self.left(now)
        if left is not None and left >= 0.05:  # "about 0.0 s left" would tell nothing
            many = self.inner is not None and self.count is not None \
                and self.count.done < self.count.total - 1
            parts.append(f"about {duration(left)} left" + (" in this one" if many else ""))
        return f"[{', '.join(parts)}]"

    def _maybe_line(self, now: float, count: _Count) -> None:
        last_time, last_done, last_tenth = self._printed
        if count.done == last_done:
            return
        if count.done >= count.total or last_done < 0 or count.tenth() > last_tenth or \
                now - last_time >= self.every:
            self._line(now, count)

    def _line(self, now: float, count: _Count | None = None) -> None:
        count = count or self.inner or self.count
        self._printed = (now, count.done, count.tenth()) if count else (now, -1, -1)
        if not self.show:
            return
        text = " ".join(str(self.text).splitlines()).strip()  # one line, whatever it held
        try:
            self.stream.write(f"{self.command} {self.prefix(now)} {text}".rstrip() + "\n")
            self.stream.flush()
        except (ValueError, OSError):  # the stream is closed or gone: progress is not worth an error
            self.show = False
