"""Chunks of points, the unit of work on processes and on a cluster, and their files on disk.

A chunk file is read back when a sweep resumes, so it is input like any other: every record is
validated against :class:`SweepRecord` (types, the status vocabulary, the point's own
parameters) before it is used. A chunk that fails is set aside as ``*.damaged`` and its points
are computed again; nothing of it reaches ``sweep.csv``.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Annotated, Literal, Optional, Sequence

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..errors import FabkitError, InputFileError, OutputError
from ..io.formats import load_json
from ..io.outputs import OutputFolder
from ..status import SWEEP_POINT
from .model import Axis, Protocol, SweepSpec, json_default
from .point import evaluate_point

_Real = Optional[float]
_Count = Optional[Annotated[int, Field(ge=0)]]


class SweepRecord(BaseModel):
    """One point's record as written to a chunk (:func:`fabkit.sweep.evaluate_point`).

    Its ``status`` is one of :data:`fabkit.status.SWEEP_POINT` (another status is refused):
    ``ok``, the map was evaluated and every measure computed; ``rigid``, the geometry has no
    conformational motion at all; ``flat``, the start is a flat state (a node collinear with the
    two it is built from: a turning point of d1, where the motion bifurcates), measured on the
    branch on the side of ``motion.to``; ``no_motion``, the network moves, but not in a way that
    d1 drives; ``escapes``, every orbit of the map leaves its domain (fixed points and cycles are
    still measured); ``failed``, anything else. ``reason`` (the CSV's and summary's column) is
    its one-sentence :attr:`message`.
    """

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)

    index: Annotated[int, Field(ge=0)]
    params: dict[str, float]
    status: Literal[tuple(sorted(s.value for s in SWEEP_POINT))]
    reason: str = ""
    domain_lo: _Real = None
    domain_hi: _Real = None
    reference: _Real = None
    modes_conformational: _Count = None
    modes_self_stress: _Count = None
    fixed_points: Optional[list[dict]] = None
    fixed_count: _Count = None
    fixed_value: _Real = None
    fixed_slope: _Real = None
    slope_reference: _Real = None
    cycles: Optional[list[dict]] = None
    cycle2_count: _Count = None
    cycle2_low: _Real = None
    cycle2_high: _Real = None
    cycle2_multiplier: _Real = None
    attractor_values: Optional[list[float]] = None
    attractor_period: Optional[int] = None
    attractor_min: _Real = None
    attractor_max: _Real = None
    lyapunov: _Real = None
    lyapunov_std: _Real = None

    @property
    def message(self) -> str:
        """Why the point ended as it did, in one sentence (its ``reason``)."""
        return self.reason


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


def split_chunks(indices: list, size: int) -> list:
    """Consecutive pieces of ``size`` indices (the last may be shorter).

    Parameters
    ----------
    indices : list of int
        The points to compute, in order.
    size : int
        Points per chunk.

    Returns
    -------
    list of list of int
    """
    return [indices[k:k + size] for k in range(0, len(indices), size)]


#: Largest chunk file read back when a sweep resumes (a larger one is set aside and its points
#: computed again): 32 points of a few kB each are what fabkit writes.
MAX_CHUNK_BYTES = 256 * 2**20


def write_chunk(chunks: OutputFolder, records: list) -> Path:
    """Write a chunk of records into the sweep's ``chunks/`` folder, through its handle.

    Parameters
    ----------
    chunks : OutputFolder
        The sweep's ``chunks/`` folder, held.
    records : list of dict
        The chunk's records, in index order (the file is named after the first and last).

    Returns
    -------
    pathlib.Path
        The chunk file written.
    """
    first, last = records[0]["index"], records[-1]["index"]
    text = json.dumps(records, default=json_default, allow_nan=False)
    return chunks.write(f"chunk-{first:07d}-{last:07d}.json", text.encode())


def read_chunks(folder: OutputFolder, spec: SweepSpec) -> tuple[dict, list]:
    """Records already on disk, by index, and the chunks that were damaged.

    A chunk cut off mid-write never exists (writes are atomic), but a chunk can still be
    damaged or edited: each must be JSON, a list of records that :class:`SweepRecord` accepts,
    for points of this grid with this grid's parameters. Chunks are read through the folder's
    handle, never through a link: a link (wherever it points), a FIFO or a device under a
    chunk's name is damaged too. A damaged chunk is renamed ``<name>.damaged`` (kept, never
    read again) and its points are computed again.

    Returns
    -------
    done : dict of int to dict
    damaged : list of (str, str)
        (file name, why) of every chunk set aside.
    """
    done, damaged = {}, []
    for name in folder.names():
        if not (name.startswith("chunk-") and name.endswith(".json")):
            continue
        why = None
        try:
            # a link, a FIFO or a device under a chunk's name is set aside, never read
            records = load_json(folder.read_bytes(name, MAX_CHUNK_BYTES), folder.path / name)
            if not isinstance(records, list) or not records:
                raise ValueError("not a list of records")
            for rec in records:
                SweepRecord.model_validate(rec)
                i = rec["index"]
                if i >= spec.size:
                    raise ValueError(f"point {i} is not on the grid of {spec.size} points")
                want = spec.point(i)
                if set(rec["params"]) != set(want) or any(
                        not math.isclose(rec["params"][k], v, rel_tol=0, abs_tol=0)
                        for k, v in want.items()):
                    raise ValueError(f"point {i} carries other parameter values than the grid")
        except ValidationError as exc:
            from ..io.schema import describe_validation_error

            why = describe_validation_error(exc, SweepRecord)
        except json.JSONDecodeError as exc:
            why = f"not JSON: {exc}"
        except (OSError, UnicodeDecodeError, ValueError, FabkitError) as exc:
            why = exc.reason if isinstance(exc, (InputFileError, OutputError)) else str(exc)
        if why is not None:
            folder.replace(name, name + ".damaged")  # the link itself, never its target
            damaged.append((name, why))
            continue
        for rec in records:
            done[rec["index"]] = rec
    return done, damaged


