"""One estimate of work before work: time and memory from the total size of what will be done.

Options bounded one by one multiply without bound (``--orbits`` × ``--average``, copies of a
chain of chains, builds × modules), so every command and API entry point that can be asked for
too much describes its work as counts of a few kinds of unit (:data:`UNITS`) and calls
:func:`require` before it starts. The estimate is the count times the unit's measured cost;
past :data:`MAX_SECONDS` or :data:`MAX_BYTES` it is refused with one line that gives the
estimate and the flag that accepts it (``fabkit --allow-large``, or ``FABKIT_ALLOW_LARGE=1`` for
the Python API).

Unit costs were measured on the 2-core reference machine (``python -m fabkit.io.workload``
lists them with what each measured) and rounded up: an estimate is an upper bound within a small
factor, meant to tell minutes from days, not seconds from seconds.

Examples
--------
>>> e = estimate(("map evaluation", 1000 * 25_000))
>>> round(e.seconds, 1), e.bytes
(2.5, 0.0)
>>> require("map --lyapunov", ("map evaluation", 100_000 * 10_000_000))
Traceback (most recent call last):
...
fabkit.errors.BoundsError: map --lyapunov: about 1.16 days (1e+12 map evaluations) is over the limit of 30 min of work; fabkit --allow-large lifts the limit
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from ..errors import BoundsError

__all__ = ["Unit", "UNITS", "Estimate", "estimate", "require", "allow_large", "MAX_SECONDS",
           "MAX_SWEEP_SECONDS", "MAX_BYTES", "describe_seconds", "describe_bytes"]

#: Work estimated above this many seconds is refused without ``--allow-large``.
MAX_SECONDS = 1800.0
#: Sweeps stream their points to disk and resume where they stopped: they may run this long.
MAX_SWEEP_SECONDS = 86400.0
#: Memory estimated above this many bytes is refused without ``--allow-large``.
MAX_BYTES = 2 * 2**30


@dataclass(frozen=True)
class Unit:
    """The cost of one unit of work: seconds and bytes held while the work runs."""

    seconds: float
    bytes: float
    doc: str


#: The kinds of work fabkit estimates, with their measured cost (rounded up).
UNITS: dict[str, Unit] = {
    "map evaluation": Unit(1e-7, 0.0, "one evaluation of a 1-D map inside a vectorised "
                                      "Lyapunov protocol (measured 6e-8 s)"),
    "orbit step": Unit(5e-5, 64.0, "one step of a cobweb orbit, evaluated alone (3e-5 s)"),
    "stored value": Unit(1e-9, 8.0, "one float64 kept in memory for the caller"),
    "node": Unit(2e-5, 400.0, "one node of a built network: coordinates, edges, ports and the "
                              "construction plan (chains of 10 000 modules: 0.44 s)"),
    "trace configuration node": Unit(5e-7, 24.0, "one node in one stored configuration of a "
                                                 "trace (constructive: 3e-7 s; 8 bytes a "
                                                 "coordinate)"),
    "build node": Unit(5e-5, 48.0, "one node of one simulated build in the Monte Carlo "
                                   "tolerance analysis (1.4e-5 to 2.4e-5 s)"),
    "origami sample node": Unit(5e-5, 48.0, "one node of one sample of a simulated folding"),
    "sweep point": Unit(0.5, 4e3, "one point of a design-space sweep (0.4 s on the bundled "
                                  "sweeps; its record is kept for sweep.csv)"),
    "printed bar": Unit(0.05, 4e5, "one bar of a print-in-place linkage: its body, files and "
                                   "their as-built checks (super_stable_chain, 144 bars: 0.012 s "
                                   "and 0.14 MB a bar to export)"),
    "file byte": Unit(2e-7, 8.0, "one byte of a file read back by the as-built check (ezdxf "
                                 "and trimesh hold about 5 bytes per byte read)"),
    "SVG byte": Unit(6e-6, 100.0, "one byte of a drawing read by svgelements into paths and "
                                  "sampled (a million segments, 7.8 MB: 35 s and 0.65 GB)"),
    "SVG close scan": Unit(3e-7, 0.0, "one segment svgelements walks back over to find where "
                                      "a closed subpath started (2e-7 s)"),
    "XML byte": Unit(5e-7, 16.0, "one byte of XML inflated from a 3MF package and parsed "
                                 "(ElementTree: 2.8e-7 s and 12 bytes a byte)"),
    "placed triangle": Unit(5e-5, 2.5e3, "one triangle of a printed file read back and checked "
                                         "as built: mesh, bodies, cross-sections, the rebuilt "
                                         "linkage (super_stable_chain's six beds, 74 000 "
                                         "triangles: 3.5e-5 s and 1.9 kB a triangle)"),
}


def allow_large() -> bool:
    """True when the bounds are lifted (``FABKIT_ALLOW_LARGE=1``, set by ``--allow-large``)."""
    return os.environ.get("FABKIT_ALLOW_LARGE", "") == "1"


@dataclass(frozen=True)
class Estimate:
    """Estimated time and memory of a piece of work.

    Attributes
    ----------
    seconds : float
    bytes : float
    parts : tuple of (str, float)
        The counts it was made from: (unit name, count).
    """

    seconds: float
    bytes: float
    parts: tuple

    def describe(self) -> str:
        """``"about 3 h, 12 GB (1e+09 sweep points)"``."""
        counts = ", ".join(f"{_count(n)} {u}s" for u, n in self.parts if n)
        size = f", {describe_bytes(self.bytes)}" if self.bytes >= 2**20 else ""
        return f"about {describe_seconds(self.seconds)}{size} ({counts})"


def estimate(*parts) -> Estimate:
    """The estimate of work made of ``(unit name, count)`` parts (see :data:`UNITS`).

    Raises
    ------
    KeyError
        An unknown unit (a bug in the caller).
    """
    seconds = total = 0.0
    clean = []
    for name, count in parts:
        unit = UNITS[name]
        count = float(count)
        seconds += unit.seconds * count
        total += unit.bytes * count
        clean.append((name, count))
    return Estimate(seconds, total, tuple(clean))


def require(where: str, *parts, option: bool = False,
            override: str = "fabkit --allow-large", max_seconds: float = MAX_SECONDS) -> Estimate:
    """Estimate the work and refuse it, before it starts, past the bounds.

    Parameters
    ----------
    where : str
        What asks for the work, for the message (``"map --lyapunov"``, ``"FILE: chain.copies"``).
    *parts : (str, number)
        The work as counts of units.
    option : bool
        The size comes from a command-line option (exit status 2) rather than an input (1).
    override : str
        How to lift the bounds, named in the message.
    max_seconds : float
        The time bound (:data:`MAX_SECONDS`; sweeps, which resume, use
        :data:`MAX_SWEEP_SECONDS`).

    Returns
    -------
    Estimate

    Raises
    ------
    BoundsError
        Over :data:`MAX_SECONDS` or :data:`MAX_BYTES`, unless the bounds are lifted.
    """
    est = estimate(*parts)
    if allow_large():
        return est
    if est.bytes > MAX_BYTES:
        raise BoundsError(where, "", est.describe(), f"{describe_bytes(MAX_BYTES)} of memory",
                          override, option=option, estimate=est)
    if est.seconds > max_seconds:
        raise BoundsError(where, "", est.describe(), f"{describe_seconds(max_seconds)} of work",
                          override, option=option, estimate=est)
    return est


def describe_seconds(s: float) -> str:
    """A duration a person reads at once: ``"40 s"``, ``"12 min"``, ``"3.5 h"``, ``"12 days"``."""
    if not math.isfinite(s):
        return "forever"
    for size, name in ((86400 * 365, "years"), (86400, "days"), (3600, "h"), (60, "min")):
        if s >= size:
            return f"{_figure(s / size)} {name}"
    return f"{_figure(s)} s"


def describe_bytes(b: float) -> str:
    """``"2 GB"``, ``"512 MB"``, ``"3 TB"`` (powers of 1024)."""
    for size, name in ((2**40, "TB"), (2**30, "GB"), (2**20, "MB"), (2**10, "kB")):
        if b >= size:
            return f"{b / size:.3g} {name}"
    return f"{b:.0f} bytes"


def _figure(v: float) -> str:
    return f"{v:.3g}" if v < 100 else f"{v:.0f}"


def _count(n: float) -> str:
    return f"{n:.0f}" if n < 1e6 else f"{n:.0e}"


if __name__ == "__main__":  # pragma: no cover - prints the measured unit costs of this machine
    for name, unit in UNITS.items():
        print(f"{name:<26} {unit.seconds:.1e} s  {unit.bytes:>9.0f} B   {unit.doc}")
