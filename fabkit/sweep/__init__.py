"""Design-space sweeps: a module template evaluated on a grid of parameter values.

:func:`sweep` varies numeric keys of a template (node coordinates, or any number in it) on a
grid, evaluates every point with the cheapest adequate model — the module's map d2 = f(d1)
(:func:`fabkit.maps.module_map`) — and measures fixed points, slopes, cycles, the attractor of the
iterated map, its Lyapunov exponent and the mode count. Points are independent: they run in
chunks on local processes or on a dask.distributed cluster, every finished chunk is written to
disk at once (``DIR/chunks``), and a sweep that is interrupted and started again computes only
the points that are not on disk yet. Every point gets a typed :class:`Status`: a geometry that is
rigid, starts in a flat state, has a motion that does not move d1, or whose orbits all leave the
map's domain is recorded as such, never dropped.

The whole module is callable, so ``import fabkit.sweep; fabkit.sweep(template, vary=...)`` runs
:func:`sweep`.
"""

from __future__ import annotations

import copy
import dataclasses
import csv
import enum
import hashlib
import io
import json
import math
import os
import re
import sys
import time
import types
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from ..errors import ConstructionError, DesignError, FabkitError, KinematicsError

__all__ = [
    "MEASURES",
    "Axis",
    "Protocol",
    "Status",
    "SweepError",
    "SweepResult",
    "SweepFile",
    "SweepSpec",
    "evaluate_point",
    "make_spec",
    "read_sweep_file",
    "parse_vary",
    "sweep",
]

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
_COMMON = ("index",)
_TAIL = ("status", "domain_lo", "domain_hi", "reference", "reason")

_CHUNKS = "chunks"
_SPEC = "spec.json"
# A reference this close (relative to the module's size) to an end of its branch is a turning
# point of d1: the start is a flat state.
_FLAT_RTOL = 1e-9


#: A start that is flat gets this nudge (relative to the network, every node) to tell flatness
#: from a missing construction order.
FLAT_NUDGE = 1e-7
#: Settled orbit values within this (relative to the domain) are one point of the attractor.
ATTRACTOR_RTOL = 1e-7


class SweepError(FabkitError, ValueError):
    """A sweep request that cannot be run as given (bad --vary, unknown key or measure)."""


class Status(str, enum.Enum):
    """What happened at one point of a sweep.

    ``ok``: the map was evaluated and every measure computed. ``rigid``: the geometry has no
    conformational motion at all. ``flat``: the start configuration is a flat state (a node
    collinear with the two it is built from: a turning point of d1, where the motion
    bifurcates); the measures are those of the branch on the side of ``motion.to``. ``no_motion``:
    the network moves, but not in a way that d1 drives (no map d2 = f(d1) through the start).
    ``escapes``: the map exists but every orbit leaves its domain (no chain of many modules can
    be assembled); fixed points and cycles are still measured. ``failed``: anything else, with
    the reason.
    """

    OK = "ok"
    RIGID = "rigid"
    FLAT = "flat"
    NO_MOTION = "no_motion"
    ESCAPES = "escapes"
    FAILED = "failed"


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
        if start == stop and num > 1:
            raise SweepError(f"{key}: START = STOP = {start:g} gives {num} equal values; give "
                             "different ends, or N = 1 for one value")
        _require_points(f"--vary {key}", int(num))  # before the values are made
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


def _key_path(key: str, raw: dict) -> list:
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


def _lookup(raw: dict, tokens: list, key: str):
    node = raw
    for k, t in enumerate(tokens):
        where = _path_text(tokens[:k + 1])
        if isinstance(t, str):
            if not isinstance(node, dict) or t not in node:
                raise SweepError(f"--vary key {key!r}: the template has no {where}")
        else:
            if not isinstance(node, list) or not 0 <= t < len(node):
                size = len(node) if isinstance(node, list) else 0
                raise SweepError(f"--vary key {key!r}: the template has no {where} "
                                 f"({_path_text(tokens[:k])} has {size} entries)")
        node = node[t]
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        raise SweepError(f"--vary key {key!r}: {_path_text(tokens)} is not a number")
    return node


def _path_text(tokens) -> str:
    out = ""
    for t in tokens:
        out += f"[{t}]" if isinstance(t, int) else (f".{t}" if out else t)
    return out


def _assign(raw: dict, tokens: list, value) -> None:
    node = raw
    for t in tokens[:-1]:
        node = node[t]
    node[tokens[-1]] = value


# --------------------------------------------------------------------------------------------
# How to measure
# --------------------------------------------------------------------------------------------
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
        from .. import __version__

        body = self.as_dict()
        body.pop("template")
        body["fabkit"] = __version__
        text = json.dumps(body, sort_keys=True, separators=(",", ":"), default=_jsonable)
        return hashlib.sha256(text.encode()).hexdigest()


def _jsonable(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if hasattr(o, "isoformat"):  # TOML dates
        return o.isoformat()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


# --------------------------------------------------------------------------------------------
# One point
# --------------------------------------------------------------------------------------------
def _build(raw: dict, path: str):
    """Network of a (modified) parsed template, through the template's own builder."""
    import importlib

    from ..templates import BUILDERS, TemplateContext

    ctx = TemplateContext(path, raw)
    key = next(k for k in BUILDERS if k in raw)
    module_name, func_name = BUILDERS[key].split(":")
    builder = getattr(importlib.import_module(module_name), func_name)
    return builder(raw[key], ctx)


def _empty_record(index: int, params: dict) -> dict:
    return {"index": int(index), "params": params, "status": Status.FAILED.value, "reason": "",
            "domain_lo": None, "domain_hi": None, "reference": None}


def evaluate_point(spec: SweepSpec, index: int) -> dict:
    """Evaluate one point of a sweep.

    Parameters
    ----------
    spec : SweepSpec
    index : int
        Flat index into the grid (C order).

    Returns
    -------
    dict
        JSON-ready record: ``index``, ``params``, ``status`` (a :class:`Status` value),
        ``reason``, the map's domain and reference d1, and the requested measures (scalars
        under the names in ``COLUMNS``, full lists under ``fixed_points``, ``cycles``,
        ``attractor_values``). Never raises for a point that cannot be evaluated: its status
        and reason say why.
    """
    params = spec.point(index)
    rec = _empty_record(index, params)
    raw = copy.deepcopy(spec.raw)
    for key, value in params.items():
        tokens = _key_path(key, raw)
        old = _lookup(raw, tokens, key)
        _assign(raw, tokens, int(round(value)) if isinstance(old, int) else float(value))
    try:
        _measure(spec, raw, rec)
    except FabkitError as exc:  # the geometry at this point cannot be evaluated as asked
        rec["status"] = Status.FAILED.value
        rec["reason"] = str(exc)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        # numerics that broke down at this geometry: one failed point, not a failed sweep
        rec["status"] = Status.FAILED.value
        rec["reason"] = f"{type(exc).__name__}: {exc}"
    return _finite(rec)


def _finite(o):
    """The record with every non-finite float as None (an infinite slope at a turning point is
    still told by its ``kind``), so it is strict JSON."""
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, (float, np.floating)):
        v = float(o)
        return v if math.isfinite(v) else None
    if isinstance(o, np.integer):
        return int(o)
    return o


def _measure(spec: SweepSpec, raw: dict, rec: dict) -> None:
    from ..maps import map_from_trajectory, module_map
    from ..rigidity import count_modes

    p = spec.protocol
    want = set(spec.measures)
    net = _build(raw, spec.template)
    modes = count_modes(net)
    if "modes" in want:
        rec["modes_conformational"] = int(modes.conformational)
        rec["modes_self_stress"] = int(modes.self_stress)
    if modes.conformational == 0:
        rec["status"] = Status.RIGID.value
        rec["reason"] = "no conformational motion (the geometry is rigid)"
        return
    for port in (p.d_in, p.d_out):
        if port not in net.ports:
            known = ", ".join(sorted(net.ports)) or "none"
            raise SweepError(f"no port {port!r} (the network has: {known})")
    a, b = net.ports[p.d_in]
    d0 = float(np.linalg.norm(net.nodes[a] - net.nodes[b]))
    motion = raw.get("motion") if isinstance(raw.get("motion"), dict) else {}
    toward = motion.get("to")
    status = Status.OK
    try:
        try:
            fmap = module_map(net, p.d_in, p.d_out, toward=toward)
        except DesignError:  # `to` lies beyond the branch: the start's own branch
            fmap = module_map(net, p.d_in, p.d_out)
    except ConstructionError as exc:
        if _flat_start(net, (a, b)):
            rec["status"] = Status.FLAT.value
            rec["reason"] = f"the start is a flat state: {exc}"
            return
        # no construction order from d1: read the map off a traced motion instead
        if toward is None:
            rec["status"] = Status.NO_MOTION.value
            rec["reason"] = f"{exc}; and the template gives no motion.to to trace instead"
            return
        from ..kinematics import trace

        try:
            traj = trace(net, drive=p.d_in, to=float(toward), method="projected")
            fmap = map_from_trajectory(traj, p.d_in, p.d_out)
        except KinematicsError as exc2:
            rec["status"] = Status.NO_MOTION.value
            rec["reason"] = str(exc2)
            return
    lo, hi = fmap.domain
    rec["domain_lo"], rec["domain_hi"], rec["reference"] = float(lo), float(hi), d0
    size = max(float(net.size), d0)
    if min(abs(d0 - lo), abs(d0 - hi)) <= _FLAT_RTOL * size:
        status = Status.FLAT
        rec["reason"] = (f"the start d1 = {d0:.10g} is a turning point of d1 (a flat state); "
                         "measures are those of the branch toward motion.to")
    if want & {"fixed_points", "slopes"}:
        fps = fmap.fixed_points()
        near = min(fps, key=lambda q: abs(q.value - d0)) if fps else None
        rec["fixed_points"] = [q.as_dict() for q in fps]
        if "fixed_points" in want:
            rec["fixed_count"] = len(fps)
            rec["fixed_value"] = near.value if near else None
        if "slopes" in want:
            rec["fixed_slope"] = near.slope if near else None
            rec["slope_reference"] = (float(fmap.derivative(d0)) if lo <= d0 <= hi else None)
    if "cycles" in want:
        cyc = fmap.cycles(2)
        rec["cycles"] = [c.as_dict() for c in cyc]
        rec["cycle2_count"] = len(cyc)
        best = min(cyc, key=lambda c: abs(c.multiplier)) if cyc else None
        rec["cycle2_low"] = best.values[0] if best else None
        rec["cycle2_high"] = best.values[-1] if best else None
        rec["cycle2_multiplier"] = best.multiplier if best else None
    if "attractor" in want:
        values, period = _attractor(fmap, p)
        rec["attractor_values"] = values
        rec["attractor_period"] = period
        rec["attractor_min"] = min(values) if values else None
        rec["attractor_max"] = max(values) if values else None
        if not values:
            status = Status.ESCAPES if status is Status.OK else status
            rec["reason"] = rec["reason"] or (
                f"every orbit leaves the domain [{lo:.6g}, {hi:.6g}] within {p.discard} "
                "iterations: no long chain of this module can be assembled")
    if "lyapunov" in want:
        try:
            ly = fmap.lyapunov(initial=p.lyapunov_orbits, discard=p.lyapunov_discard,
                               average=p.lyapunov_average)
            rec["lyapunov"] = ly.mean if math.isfinite(ly.mean) else None
            rec["lyapunov_std"] = ly.std if math.isfinite(ly.std) else None
        except DesignError as exc:  # no invariant range: every orbit escapes
            rec["lyapunov"] = rec["lyapunov_std"] = None
            if status is Status.OK:
                status = Status.ESCAPES
                rec["reason"] = str(exc)
    rec["status"] = status.value


def _flat_start(net, pair) -> bool:
    """True when the start has no construction order only because it is flat: a slightly
    moved copy of it (1e-7 of the size, every node) has one."""
    from ..kinematics import plan_construction

    x = net.nodes
    rng = np.random.default_rng(0)
    nudged = x + FLAT_NUDGE * max(float(net.size), 1.0) * rng.standard_normal(x.shape)
    try:
        plan_construction(net, pair, nudged)
    except ConstructionError:
        return False
    return True


def _attractor(fmap, p: Protocol) -> tuple[list, int]:
    """Values the orbits settle on, and the period of the first surviving orbit (0: no period
    up to ``keep // 2``, e.g. chaos; -1: every orbit escapes)."""
    lo, hi = fmap.domain
    x0 = lo + (np.arange(p.orbits) + 0.5) / p.orbits * (hi - lo)
    orbits = fmap.iterate(x0, p.discard + p.keep - 1)[p.discard:]
    alive = np.all(np.isfinite(orbits), axis=0)
    if not alive.any():
        return [], -1
    tail = orbits[:, alive]
    scale = max(abs(lo), abs(hi), 1.0)
    tol = ATTRACTOR_RTOL * scale
    first = tail[:, 0]
    period = 0
    for m in range(1, p.keep // 2 + 1):
        if np.all(np.abs(first[m:] - first[:-m]) <= tol):
            period = m
            break
    # one value per cluster: a periodic attractor keeps its few values, a chaotic one many
    vals = np.sort(tail.ravel())
    keep = np.concatenate([[True], np.diff(vals) > tol])
    return [float(v) for v in vals[keep]], period


# --------------------------------------------------------------------------------------------
# Chunks of points (the unit of work on processes and on a cluster)
# --------------------------------------------------------------------------------------------
def run_chunk(spec_dict: dict, indices: Sequence[int]) -> dict:
    """Evaluate a chunk of points; takes and returns plain data so it ships to any worker.

    Returns
    -------
    dict
        ``records`` (one per index) and ``cpu``: CPU seconds of the thread that ran them (the
        cost of the points whatever else shares the machine; kept out of the records, whose
        numbers must not depend on where they ran).
    """
    t0 = time.thread_time()
    spec = _spec_from_dict(spec_dict)
    records = [evaluate_point(spec, int(i)) for i in indices]
    return {"records": records, "cpu": time.thread_time() - t0}


def _spec_from_dict(d: dict) -> SweepSpec:
    return SweepSpec(template=d["template"], raw=d["raw"],
                     axes=tuple(Axis(a["key"], tuple(a["values"])) for a in d["axes"]),
                     measures=tuple(d["measures"]), protocol=Protocol(**d["protocol"]))


def _chunks(indices: list, size: int) -> list:
    return [indices[k:k + size] for k in range(0, len(indices), size)]


def _write_chunk(folder: Path, records: list) -> Path:
    from ..outputs import write_atomic

    first, last = records[0]["index"], records[-1]["index"]
    text = json.dumps(records, default=_jsonable, allow_nan=False)
    return write_atomic(folder / f"chunk-{first:07d}-{last:07d}.json", text.encode())


def _read_chunks(folder: Path) -> dict:
    """Records already on disk, by index (a chunk cut off mid-write never exists: writes are
    atomic)."""
    done = {}
    for f in sorted(folder.glob("chunk-*.json")):
        for rec in json.loads(f.read_text()):
            done[int(rec["index"])] = rec
    return done


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class SweepResult:
    """A finished sweep.

    Attributes
    ----------
    spec : SweepSpec
    records : list of dict
        One per point, in grid order (see :func:`evaluate_point`).
    outdir : pathlib.Path or None
    files : tuple of pathlib.Path
        What was written (table, sweep.json, plots).
    computed : int
        Points computed by this call (the rest were read back from an earlier, interrupted run).
    seconds : float
        Wall time of the computation.
    workers : int
        Processes or cluster workers (cores) used.
    where : str
        ``"in-process"``, ``"processes"`` or the scheduler address.
    cpu_seconds : float
        CPU time the computed points took (summed over workers): ``computed / cpu_seconds`` is
        the throughput of one core however loaded the machine is.
    """

    spec: SweepSpec
    records: list
    outdir: Path | None = None
    files: tuple = ()
    computed: int = 0
    seconds: float = 0.0
    workers: int = 1
    where: str = "in-process"
    cpu_seconds: float = 0.0

    @property
    def columns(self) -> tuple:
        """Names of the table's columns."""
        cols = list(_COMMON) + [a.key for a in self.spec.axes]
        for m in MEASURES:
            if m in self.spec.measures:
                cols.extend(COLUMNS[m])
        return tuple(cols) + _TAIL

    def column(self, name: str) -> np.ndarray:
        """One column as an array (float with NaN for missing values; object for text).

        Raises
        ------
        KeyError
            For a name that is not a column.
        """
        if name not in self.columns:
            raise KeyError(f"no column {name!r}; columns: {', '.join(self.columns)}")
        vals = [_cell(r, name) for r in self.records]
        if name in ("status", "reason"):
            return np.array(vals, dtype=object)
        return np.array([np.nan if v is None else v for v in vals], dtype=np.float64)

    @property
    def status(self) -> np.ndarray:
        """:class:`Status` of every point, shape = the grid's shape."""
        return np.array([Status(r["status"]) for r in self.records],
                        dtype=object).reshape(self.spec.shape)

    def counts(self) -> dict:
        """Number of points per status value."""
        out: dict = {}
        for r in self.records:
            out[r["status"]] = out.get(r["status"], 0) + 1
        return out

    def table_csv(self) -> bytes:
        """The table as CSV text (floats written as the shortest exact repr)."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.columns)
        for r in self.records:
            w.writerow(["" if (v := _cell(r, c)) is None else (repr(v) if isinstance(v, float)
                        else v) for c in self.columns])
        return buf.getvalue().encode()

    def summary(self) -> dict:
        """JSON-ready: inputs, counts per status, timing, the records (with failures' reasons)."""
        rate = self.computed / self.seconds if self.seconds > 0 else None
        return {
            "template": self.spec.template,
            "fingerprint": self.spec.fingerprint(),
            "model": "map (constructive 1-D map of the module; a traced motion where the "
                     "network has no construction order)",
            "axes": [a.as_dict() for a in self.spec.axes],
            "shape": list(self.spec.shape),
            "measures": list(self.spec.measures),
            "protocol": asdict(self.spec.protocol),
            "columns": list(self.columns),
            "counts": self.counts(),
            "run": {"computed": self.computed, "resumed": len(self.records) - self.computed,
                    "seconds": self.seconds, "workers": self.workers, "where": self.where,
                    "points_per_second": rate,
                    "points_per_second_per_core": rate / self.workers if rate else None,
                    "cpu_seconds": self.cpu_seconds,
                    "points_per_cpu_second": (self.computed / self.cpu_seconds
                                              if self.cpu_seconds > 0 else None)},
            "points": self.records,
        }


def _cell(rec: dict, name: str):
    if name in rec["params"]:
        return rec["params"][name]
    return rec.get(name)


# --------------------------------------------------------------------------------------------
# The front function
# --------------------------------------------------------------------------------------------
def _require_points(where: str, points: int) -> None:
    """Refuse a grid whose points would take more than a day, before making it."""
    from ..workload import MAX_SWEEP_SECONDS, require

    require(where, ("sweep point", points), option=True, max_seconds=MAX_SWEEP_SECONDS)


def _axes_from(vary) -> tuple:
    if isinstance(vary, Axis):
        vary = [vary]
    if isinstance(vary, Mapping):
        items = []
        for key, v in vary.items():
            if isinstance(v, Axis):
                items.append(v)
            elif isinstance(v, tuple) and len(v) == 3 and isinstance(v[2], (int, np.integer)) \
                    and not isinstance(v[2], bool):
                items.append(Axis.linspace(str(key), float(v[0]), float(v[1]), int(v[2])))
            else:
                vals = np.asarray(v, dtype=np.float64).ravel()
                if vals.size == 0 or not np.all(np.isfinite(vals)):
                    raise SweepError(f"{key}: give (start, stop, n) or a non-empty list of "
                                     "finite values")
                if np.unique(vals).size != vals.size:
                    raise SweepError(f"{key}: a value is given twice")
                items.append(Axis(str(key), tuple(float(x) for x in vals)))
        vary = items
    if not isinstance(vary, (list, tuple)) or not all(isinstance(a, Axis) for a in vary):
        raise SweepError("vary must be an Axis, a list of them, or a mapping of key to "
                         f"(start, stop, n) or values; got {type(vary).__name__}")
    axes = tuple(vary)
    if not axes:
        raise SweepError("nothing to vary: give at least one key (--vary KEY=START:STOP:N)")
    keys = [a.key for a in axes]
    if len(set(keys)) != len(keys):
        raise SweepError(f"a key is varied twice: {', '.join(keys)}")
    return axes


def _measures_from(measure) -> tuple:
    if measure is None:
        return MEASURES
    if isinstance(measure, str):
        measure = [m for m in measure.split(",") if m.strip()]
    out = []
    for m in measure:
        m = m.strip()
        if m not in MEASURES:
            raise SweepError(f"unknown measure {m!r}; valid: {', '.join(MEASURES)}")
        if m not in out:
            out.append(m)
    if not out:
        raise SweepError(f"no measure given; valid: {', '.join(MEASURES)}")
    return tuple(m for m in MEASURES if m in out)


def make_spec(template, vary, measure=None, protocol: Protocol | None = None) -> SweepSpec:
    """Check a sweep request and return its :class:`SweepSpec` (nothing is computed).

    Raises
    ------
    TemplateError
        The template cannot be loaded.
    SweepError
        Unknown or non-numeric key, bad grid, unknown measure, unknown port.
    """
    from ..templates import Design, load_template

    design = template if isinstance(template, Design) else load_template(template)
    raw = design.raw
    axes = _axes_from(vary)
    seen = set()
    for ax in axes:
        tokens = _key_path(ax.key, raw)
        canon = _path_text(tokens)
        if canon in seen:
            raise SweepError(f"--vary key {ax.key!r} names {canon}, which is already varied")
        seen.add(canon)
        old = _lookup(raw, tokens, ax.key)
        if isinstance(old, int) and any(v != round(v) for v in ax.values):
            raise SweepError(f"--vary key {ax.key!r}: {canon} is an integer; give values that "
                             "are whole numbers")
    _require_points("sweep", int(np.prod([len(a.values) for a in axes], dtype=float)))
    protocol = protocol or Protocol()
    for port in (protocol.d_in, protocol.d_out):
        if port not in design.network.ports:
            known = ", ".join(sorted(design.network.ports)) or "none"
            raise SweepError(f"{design.path}: no port {port!r} to map (the network has: {known})")
    return SweepSpec(template=str(design.path or design.name), raw=copy.deepcopy(raw), axes=axes,
                     measures=_measures_from(measure), protocol=protocol)


@dataclass(frozen=True)
class SweepFile:
    """A sweep spec file: which template, what to vary and measure (see ``docs/sweep.md``).

    Attributes
    ----------
    path : pathlib.Path
    template : pathlib.Path
        Resolved relative to the spec file; a bare name found nowhere there (``"chaotic"``) is
        the bundled template of that name.
    axes : tuple of Axis
    measures : tuple of str or None
    protocol : Protocol
    """

    path: Path
    template: Path
    axes: tuple
    measures: tuple | None
    protocol: Protocol


_SPEC_KEYS = {"template", "vary", "measure", "protocol", "description"}


def read_sweep_file(path) -> SweepFile | None:
    """Read a sweep spec (a TOML file with a ``[sweep]`` table); None for any other file (a
    design template, which :func:`fabkit.load_template` reads).

    Raises
    ------
    SweepError
        A ``[sweep]`` table with a missing, unknown or malformed entry.
    """
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None  # not ours: the template loader reports it properly
    sec = raw.get("sweep")
    if not isinstance(sec, dict):
        return None
    where = f"{path}: sweep"
    unknown = sorted(set(sec) - _SPEC_KEYS)
    if unknown:
        raise SweepError(f"{where}.{unknown[0]}: unknown key; allowed: "
                         f"{', '.join(sorted(_SPEC_KEYS))}")
    tpl = sec.get("template")
    if not isinstance(tpl, str):
        raise SweepError(f"{where}.template: must name the module template, "
                         "e.g. \"../chaotic.toml\"")
    vary = sec.get("vary", [])
    if not isinstance(vary, list) or not all(isinstance(v, str) for v in vary):
        raise SweepError(f"{where}.vary: must be an array of \"KEY=START:STOP:N\" strings")
    measure = sec.get("measure")
    if measure is not None and (not isinstance(measure, list)
                                or not all(isinstance(m, str) for m in measure)):
        raise SweepError(f"{where}.measure: must be an array of measure names")
    prot = sec.get("protocol", {})
    if not isinstance(prot, dict):
        raise SweepError(f"{where}.protocol: must be a table")
    fields = set(Protocol.__dataclass_fields__)
    bad = sorted(set(prot) - fields)
    if bad:
        raise SweepError(f"{where}.protocol.{bad[0]}: unknown key; allowed: "
                         f"{', '.join(sorted(fields))}")
    from ..templates import resolve_template

    return SweepFile(path=path, template=resolve_template(tpl, base=path.parent),
                     axes=tuple(parse_vary(v) for v in vary),
                     measures=_measures_from(measure) if measure is not None else None,
                     protocol=Protocol(**prot))


def _check_outdir(outdir: Path, spec: SweepSpec) -> None:
    from ..outputs import output_folder

    output_folder(outdir)
    marker = outdir / _CHUNKS / _SPEC
    if marker.exists():
        try:
            old = json.loads(marker.read_text()).get("fingerprint")
        except (OSError, ValueError):
            old = None
        if old != spec.fingerprint():
            raise FabkitError(f"{outdir} holds the chunks of a different sweep (another template, "
                              "grid, measure or protocol); choose another -o or delete "
                              f"{outdir / _CHUNKS}")


def _connect(scheduler, timeout: float):
    """A dask.distributed Client for an address (or the Client given)."""
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - a declared dependency
        raise FabkitError("running on a cluster needs dask.distributed: pip install "
                          "'dask[distributed]'") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    try:
        client = Client(str(scheduler), timeout=timeout)
    except (OSError, TimeoutError, ValueError) as exc:
        raise FabkitError(f"cannot reach the dask scheduler at {scheduler}: "
                          f"{type(exc).__name__}") from None
    try:
        client.wait_for_workers(1, timeout=timeout)
    except (OSError, TimeoutError) as exc:
        client.close()
        raise FabkitError(f"the dask scheduler at {scheduler} has no workers (waited "
                          f"{timeout:g} s: {type(exc).__name__}); start some with "
                          f"`dask worker {scheduler}`") from None
    return client, True


def sweep(template, vary, measure=None, *, outdir=None, scheduler=None, jobs: int | None = 1,
          chunk_size: int | None = None, protocol: Protocol | None = None, plots: bool = True,
          progress: Callable[[int, int], None] | None = None,
          connect_timeout: float = 10.0) -> SweepResult:
    """Evaluate a module template on a grid of parameter values.

    Parameters
    ----------
    template : str, pathlib.Path or Design
        A module template (its map d2 = f(d1) is what is measured).
    vary : mapping or sequence of Axis
        ``{key: (start, stop, n)}`` (n evenly spaced values, both ends included) or
        ``{key: [values]}``. Keys are paths into the template: ``"network.nodes[4][0]"``,
        ``"nodes[4].x"`` (the same), ``"motion.to"``, any number in the file. The grid is the
        outer product, the first key varying slowest.
    measure : sequence of str or str, optional
        Some of :data:`MEASURES` (default: all).
    outdir : str or pathlib.Path, optional
        Folder for ``sweep.csv``, ``sweep.json``, the plots and ``chunks/`` (each finished chunk
        of points, written as it arrives). A folder holding chunks of the same sweep resumes it.
        Without it nothing is written.
    scheduler : str or distributed.Client, optional
        A dask.distributed scheduler address (``tcp://host:8786``) or client: chunks run on its
        workers. Default: this machine.
    jobs : int or None
        Local processes when there is no scheduler (1: in this process; None: one per core).
    chunk_size : int, optional
        Points per task (default: about four tasks per worker, at most 32 points).
    protocol : Protocol, optional
    plots : bool
        Draw the bifurcation diagram (1-D) or heat maps (2-D) into ``outdir``.
    progress : callable(done, total), optional
        Called after every chunk (and once at the start with what was on disk).
    connect_timeout : float
        Seconds to wait for the scheduler.

    Returns
    -------
    SweepResult

    Raises
    ------
    SweepError
        A request that cannot run (bad key, grid or measure).
    TemplateError
        The template cannot be loaded.
    FabkitError
        ``outdir`` is a file or holds another sweep; the scheduler cannot be reached.

    Examples
    --------
    >>> import fabkit.sweep
    >>> r = fabkit.sweep("templates/chaotic.toml", vary={"nodes[4].x": (-0.33, -0.33, 1)},
    ...                  measure="lyapunov")  # doctest: +SKIP
    >>> round(r.column("lyapunov")[0], 2)  # doctest: +SKIP
    0.31
    """
    spec = make_spec(template, vary, measure, protocol)
    out = Path(outdir) if outdir is not None else None
    if out is not None:
        _check_outdir(out, spec)
    if jobs is not None and (isinstance(jobs, bool) or int(jobs) < 1):
        raise SweepError(f"jobs must be a positive integer or None, got {jobs!r}")
    if chunk_size is not None and (isinstance(chunk_size, bool) or int(chunk_size) < 1):
        raise SweepError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    client, own_client = (None, False)
    if scheduler is not None:
        client, own_client = _connect(scheduler, connect_timeout)
    try:
        return _run(spec, out, client, jobs, chunk_size, plots, progress)
    finally:
        if own_client:
            client.close()


def _run(spec, out, client, jobs, chunk_size, plots, progress) -> SweepResult:
    done: dict = {}
    folder = None
    if out is not None:
        folder = out / _CHUNKS
        from ..outputs import write_atomic

        marker = {"fingerprint": spec.fingerprint(), "spec": spec.as_dict()}
        write_atomic(folder / _SPEC, json.dumps(marker, indent=1, default=_jsonable).encode())
        done = {i: r for i, r in _read_chunks(folder).items() if 0 <= i < spec.size}
    todo = [i for i in range(spec.size) if i not in done]
    if client is not None:
        workers = max(1, sum(client.nthreads().values()))
        where = str(client.scheduler.address)
    else:
        workers = (os.cpu_count() or 1) if jobs is None else int(jobs)
        workers = max(1, min(workers, len(todo) or 1))
        where = "in-process" if workers == 1 else "processes"
    size = int(chunk_size) if chunk_size else max(1, min(32, math.ceil(len(todo) / (4 * workers))))
    chunks = _chunks(todo, size)
    payload = spec.as_dict()
    total = spec.size
    if progress:
        progress(len(done), total)

    cpu = [0.0]

    def arrived(chunk):
        records = chunk["records"]
        if folder is not None:
            _write_chunk(folder, records)
        for r in records:
            done[r["index"]] = r
        cpu[0] += chunk["cpu"]
        if progress:
            progress(len(done), total)

    t0 = time.perf_counter()
    if chunks:
        if client is not None:
            _run_dask(client, payload, chunks, spec.fingerprint(), arrived)
        elif workers == 1:
            for c in chunks:
                arrived(run_chunk(payload, c))
        else:
            _run_processes(workers, payload, chunks, arrived)
    seconds = time.perf_counter() - t0
    records = [done[i] for i in range(spec.size)]
    result = SweepResult(spec=spec, records=records, outdir=out, computed=len(todo),
                         seconds=seconds, workers=workers, where=where, cpu_seconds=cpu[0])
    if out is None:
        return result
    return _write_outputs(result, plots)


def _run_processes(workers, payload, chunks, arrived) -> None:
    from concurrent.futures import ProcessPoolExecutor, as_completed

    pool = ProcessPoolExecutor(max_workers=workers)
    try:
        futures = [pool.submit(run_chunk, payload, c) for c in chunks]
        for fut in as_completed(futures):
            arrived(fut.result())
    except BaseException:
        # Ctrl-C or a failed write: drop what has not started, keep what is on disk
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()


def _run_dask(client, payload, chunks, fingerprint, arrived) -> None:
    from distributed import as_completed

    import uuid

    (data,) = client.scatter([payload], broadcast=True)  # a list: a dict would scatter per key
    # a fresh token per run: a resumed sweep must not meet the cancelled tasks of the last one
    token = uuid.uuid4().hex[:8]
    futures = [client.submit(run_chunk, data, c, pure=False,
                             key=f"fabkit-sweep-{fingerprint[:12]}-{token}-{c[0]}")
               for c in chunks]
    try:
        for fut in as_completed(futures):
            arrived(fut.result())
    except BaseException:
        client.cancel(futures)
        raise


def _write_outputs(result: SweepResult, plots: bool) -> SweepResult:
    from ..outputs import write_files

    out = result.outdir
    files = {"sweep.csv": result.table_csv()}
    if plots:
        from ..viz import figure_png
        from .plots import figures

        for name, fig in figures(result).items():
            files[name] = figure_png(fig)
    summary = result.summary()
    summary["files"] = sorted(files) + ["sweep.json"]
    files["sweep.json"] = (json.dumps(summary, indent=1, default=_jsonable, allow_nan=False)
                           + "\n").encode()
    written = tuple(write_files(out, files))
    return dataclasses.replace(result, files=written)


class _CallableModule(types.ModuleType):
    """``fabkit.sweep(...)`` calls :func:`sweep` once the module is imported."""

    def __call__(self, *args, **kwargs):
        return sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
