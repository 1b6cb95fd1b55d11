"""What a sweep is: the grid (axes and template key paths), the measures, the protocol."""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import asdict, dataclass, field

import numpy as np

from .. import __version__
from ..errors import FabkitError
from ..io.workload import MAX_SWEEP_SECONDS, require

#: What a sweep can measure at every point; all of them by default.
MEASURES = ("fixed_points", "slopes", "cycles", "lyapunov", "modes", "attractor")

#: Scalar columns of the table per measure (in this order after the common columns).
COLUMNS = {
    "fixed_points": ("fixed_count", "fixed_value"),
    "slopes": ("fixed_slope", "slope_reference"),
    "cycles": ("cycle2_count", "cycle2_low", "cycle2_high", "cycle2_multiplier"),
    "lyapunov": ("lyapunov", "lyapunov_std"),
    "modes": ("modes_conformational", "modes_self_stress"),
    "attractor": ("attractor_period", "attractor_min", "attractor_max"),
}
#: Columns of the table before the swept parameters.
HEAD_COLUMNS = ("index",)
#: Columns of the table after the measures.
TAIL_COLUMNS = ("status", "domain_lo", "domain_hi", "reference", "reason")

#: Folder of a sweep's output that holds its chunks of records (and the spec marker).
CHUNKS_FOLDER = "chunks"
#: The spec marker in :data:`CHUNKS_FOLDER`: the grid whose points the chunks hold.
SPEC_FILE = "spec.json"
#: A reference this close (relative to the module's size) to an end of its branch is a turning
#: point of d1: the start is a flat state.
FLAT_START_RTOL = 1e-9


#: A start that is flat gets this nudge (relative to the network, every node) to tell flatness
#: from a missing construction order.
FLAT_NUDGE = 1e-7
#: Settled orbit values within this (relative to the domain) are one point of the attractor.
ATTRACTOR_RTOL = 1e-7


class SweepError(FabkitError, ValueError):
    """A sweep request that cannot be run as given (bad --vary, unknown key or measure)."""


# --------------------------------------------------------------------------------------------
# What to vary
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Axis:
    """One varied key and its values.

    Attributes
    ----------
    key : str
        Key path into the template, e.g. ``"network.nodes[4][0]"`` (``"nodes[4].x"`` is the
        same), ``"motion.to"``.
    values : tuple of float
    """

    key: str
    values: tuple

    @classmethod
    def linspace(cls, key: str, start: float, stop: float, num: int) -> "Axis":
        """``num`` evenly spaced values from ``start`` to ``stop`` (both included).

        Raises
        ------
        SweepError
            ``num < 1``, non-finite ends, or ``start == stop`` with ``num > 1``.
        """
        if isinstance(num, bool) or int(num) != num or num < 1:
            raise SweepError(f"{key}: the number of values must be a positive integer, got {num}")
        if not (math.isfinite(start) and math.isfinite(stop)):
            raise SweepError(f"{key}: START and STOP must be finite numbers")
        if max(abs(start), abs(stop)) > MAX_VALUE:
            raise SweepError(f"{key}: START and STOP must lie within ±{MAX_VALUE:g} (no "
                             f"coordinate or length of a design is larger), got {start:g} and "
                             f"{stop:g}")
        if start == stop and num > 1:
            raise SweepError(f"{key}: START = STOP = {start:g} gives {num} equal values; give "
                             "different ends, or N = 1 for one value")
        require_points(f"--vary {key}", int(num))  # before the values are made
        return cls(key, tuple(float(v) for v in np.linspace(start, stop, int(num))))

    def as_dict(self) -> dict:
        return {"key": self.key, "values": list(self.values)}


def parse_vary(text: str) -> Axis:
    """``"KEY=START:STOP:N"`` → :class:`Axis`.

    Examples
    --------
    >>> parse_vary("nodes[4].x=-0.4:-0.2:3").values
    (-0.4, -0.30000000000000004, -0.2)
    """
    key, sep, rng = text.partition("=")
    key = key.strip()
    parts = rng.split(":")
    if not sep or not key or len(parts) != 3:
        raise SweepError(f"--vary {text!r}: expected KEY=START:STOP:N, "
                         "e.g. nodes[4].x=-0.45:-0.2:101")
    try:
        start, stop = float(parts[0]), float(parts[1])
    except ValueError:
        raise SweepError(f"--vary {text!r}: START and STOP must be numbers") from None
    try:
        num = int(parts[2])
    except ValueError:
        raise SweepError(f"--vary {text!r}: N must be an integer, got {parts[2]!r}") from None
    return Axis.linspace(key, start, stop, num)


_TOKEN = re.compile(r"([A-Za-z_][A-Za-z0-9_\-]*)|\[(\d+)\]|\.")
_XYZ = {"x": 0, "y": 1, "z": 2}


def key_path(key: str, raw: dict) -> list:
    """Tokens of a key path: ``"nodes[4].x"`` → ``["network", "nodes", 4, 0]``."""
    tokens: list = []
    pos = 0
    while pos < len(key):
        m = _TOKEN.match(key, pos)
        if not m or m.end() == pos:
            raise SweepError(f"--vary key {key!r}: cannot read it as a key path (e.g. "
                             "network.nodes[4][0], nodes[4].x, motion.to)")
        if m.group(1) is not None:
            name = m.group(1)
            # .x/.y/.z after an index: a coordinate
            tokens.append(_XYZ[name] if name in _XYZ and tokens and isinstance(tokens[-1], int)
                          else name)
        elif m.group(2) is not None:
            tokens.append(int(m.group(2)))
        pos = m.end()
    if not tokens or not isinstance(tokens[0], str):
        raise SweepError(f"--vary key {key!r}: must start with a name")
    if tokens[0] not in raw:
        owners = [s for s, v in raw.items() if isinstance(v, dict) and tokens[0] in v]
        if len(owners) == 1:  # nodes[4].x is network.nodes[4][0]
            tokens.insert(0, owners[0])
    return tokens


def lookup_number(raw: dict, tokens: list, key: str):
    """The number a key path points at in a template's raw tables.

    Parameters
    ----------
    raw : dict
        The template's tables as read.
    tokens : list of str or int
        The key path (:func:`key_path`).
    key : str
        The ``--vary`` key as the user wrote it, for the error message.

    Returns
    -------
    int or float

    Raises
    ------
    SweepError
        When the template has no such entry, or the entry is not a number (one line naming the
        path).
    """
    node = raw
    for k, t in enumerate(tokens):
        where = path_text(tokens[:k + 1])
        if isinstance(t, str):
            if not isinstance(node, dict) or t not in node:
                raise SweepError(f"--vary key {key!r}: the template has no {where}")
        else:
            if not isinstance(node, list) or not 0 <= t < len(node):
                size = len(node) if isinstance(node, list) else 0
                raise SweepError(f"--vary key {key!r}: the template has no {where} "
                                 f"({path_text(tokens[:k])} has {size} entries)")
        node = node[t]
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        raise SweepError(f"--vary key {key!r}: {path_text(tokens)} is not a number")
    return node


def path_text(tokens) -> str:
    """Tokens of a key path as text: ``["network", "nodes", 4, 0]`` → ``"network.nodes[4][0]"``."""
    out = ""
    for t in tokens:
        out += f"[{t}]" if isinstance(t, int) else (f".{t}" if out else t)
    return out


def assign_value(raw: dict, tokens: list, value) -> None:
    """Set the entry a key path points at (checked before by :func:`lookup_number`).

    Parameters
    ----------
    raw : dict
        The template's tables, changed in place.
    tokens : list of str or int
        The key path (:func:`key_path`).
    value
        The new value.
    """
    node = raw
    for t in tokens[:-1]:
        node = node[t]
    node[tokens[-1]] = value


# --------------------------------------------------------------------------------------------
# How to measure
# --------------------------------------------------------------------------------------------
#: Bounds of a sweep's protocol, checked when it is made (as ``map --orbits``, ``--discard``
#: and ``--average`` are): orbits, iterations, and Lyapunov map evaluations a point (1e-7 s
#: each: 100 s a point).
MAX_ORBITS = 100_000
MAX_ITERATIONS = 10_000_000
MAX_POINT_EVALUATIONS = 10**9
#: Largest magnitude of a value a sweep gives a key (the largest coordinate a network takes).
MAX_VALUE = 1e9


@dataclass(frozen=True)
class Protocol:
    """Numerical protocol of the measures (part of a sweep's identity).

    Attributes
    ----------
    d_in, d_out : str
        Ports of the map.
    orbits, discard, keep : int
        Attractor: orbits started evenly across the domain, iterations discarded, values kept
        per orbit.
    lyapunov_orbits, lyapunov_discard, lyapunov_average : int
        Lyapunov protocol (:meth:`fabkit.maps.Map1D.lyapunov`); the paper's is 1000, 5000, 20000,
        a sweep's default is lighter (the spread over orbits of a chaotic module is ~0.004).
    """

    d_in: str = "d1"
    d_out: str = "d2"
    orbits: int = 8
    discard: int = 2000
    keep: int = 64
    lyapunov_orbits: int = 32
    lyapunov_discard: int = 1000
    lyapunov_average: int = 4000

    def __post_init__(self):
        for name in ("orbits", "discard", "keep", "lyapunov_orbits", "lyapunov_discard",
                     "lyapunov_average"):
            v = getattr(self, name)
            low = 0 if name in ("discard", "lyapunov_discard") else 1
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                raise SweepError(f"protocol {name} must be an integer >= {low}, got {v!r}")
            top = MAX_ORBITS if "orbits" in name else MAX_ITERATIONS
            if v > top:
                raise SweepError(f"protocol {name} must be at most {top:,}, got {v:,}")
        evaluations = self.lyapunov_orbits * (self.lyapunov_discard + self.lyapunov_average)
        if evaluations > MAX_POINT_EVALUATIONS:
            raise SweepError(f"the Lyapunov protocol {self.lyapunov_orbits}:"
                             f"{self.lyapunov_discard}:{self.lyapunov_average} evaluates the "
                             f"map {evaluations:,} times a point, over the limit of "
                             f"{MAX_POINT_EVALUATIONS:,} (the paper's 1000:5000:20000 is "
                             "2.5e7)")


@dataclass(frozen=True)
class SweepSpec:
    """Everything that decides a sweep's numbers: the template, the grid, measures, protocol.

    Attributes
    ----------
    template : str
        Path of the template (for messages and relative references).
    raw : dict
        The parsed template.
    axes : tuple of Axis
        The grid is their outer product, the first axis varying slowest.
    measures : tuple of str
    protocol : Protocol
    """

    template: str
    raw: dict
    axes: tuple
    measures: tuple
    protocol: Protocol = field(default_factory=Protocol)

    @property
    def shape(self) -> tuple:
        return tuple(len(a.values) for a in self.axes)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    def point(self, index: int) -> dict:
        """The values of every varied key at point ``index``."""
        idx = np.unravel_index(int(index), self.shape)
        return {a.key: a.values[i] for a, i in zip(self.axes, idx)}

    def as_dict(self) -> dict:
        return {"template": self.template, "raw": self.raw,
                "axes": [a.as_dict() for a in self.axes], "measures": list(self.measures),
                "protocol": asdict(self.protocol)}

    def fingerprint(self) -> str:
        """Hash of what decides the numbers (not of the template's path)."""
        body = self.as_dict()
        body.pop("template")
        body["fabkit"] = __version__
        text = json.dumps(body, sort_keys=True, separators=(",", ":"), default=json_default)
        return hashlib.sha256(text.encode()).hexdigest()


def json_default(o):
    """``default`` of :func:`json.dumps` for a sweep's files: numpy scalars and arrays, dates.

    Parameters
    ----------
    o : object
        A value :mod:`json` cannot write itself.

    Returns
    -------
    int, float, list or str

    Raises
    ------
    TypeError
        For any other type (as :func:`json.dumps` expects).
    """
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if hasattr(o, "isoformat"):  # TOML dates
        return o.isoformat()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def require_points(where: str, points: int) -> None:
    """Refuse a grid whose points would take more than a day, before making it.

    Parameters
    ----------
    where : str
        What asks for the points (``"sweep"``, ``"--vary KEY"``), named in the refusal.
    points : int
        Number of grid points.

    Raises
    ------
    fabkit.io.workload.BoundsError
        When the points would take too long (:func:`fabkit.io.workload.require`).
    """
    require(where, ("sweep point", points), option=True, max_seconds=MAX_SWEEP_SECONDS)
