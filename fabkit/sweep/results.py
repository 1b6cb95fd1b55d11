"""A finished sweep: its records as a table, columns, counts and summary."""

from __future__ import annotations

import csv
import io
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..status import Status
from .model import COLUMNS, HEAD_COLUMNS, MEASURES, TAIL_COLUMNS, SweepSpec

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
    damaged : tuple of (str, str)
        Chunks found damaged on resuming (file name, why): set aside as ``*.damaged``, their
        points computed again.
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
    damaged: tuple = ()

    @property
    def columns(self) -> tuple:
        """Names of the table's columns."""
        cols = list(HEAD_COLUMNS) + [a.key for a in self.spec.axes]
        for m in MEASURES:
            if m in self.spec.measures:
                cols.extend(COLUMNS[m])
        return tuple(cols) + TAIL_COLUMNS

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


