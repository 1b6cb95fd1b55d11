"""The result of a tolerance analysis and its JSON-ready summary."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .processes import NOT_KINEMATIC
from .spec import ToleranceSpec, model_summary


@dataclass(frozen=True, eq=False)
class ToleranceResult:
    """What :func:`analyse_tolerance` found.

    Attributes
    ----------
    spec : ToleranceSpec
    method : str
        ``"constructive"`` or ``"projected"`` (how the builds were placed).
    ports : list of str
        Port names, chain order (d1, d2, ...) first.
    nominal : numpy.ndarray, shape (P,)
        Designed port distances at the target (design units).
    distances : numpy.ndarray, shape (M, P)
        Port distances of every build at the target (NaN where the build does not reach it).
    reached : numpy.ndarray of bool, shape (M,)
    end_nodes : list of int
        Nodes of the last port (the far end of a chain).
    end_offsets : numpy.ndarray, shape (M, len(end_nodes), d) or None
        Displacement of those nodes from their designed target positions (design units, drive
        frame: the drive's first node fixed, its second on the designed drive direction).
    length_rms : float
        RMS effective bar-length error of the builds (mm).
    limits : numpy.ndarray, shape (P,)
        Allowed 95th-percentile error per port (mm).
    horizon : dict or None
        ``lyapunov``, ``source``, ``error``, ``module_size``, ``modules``, ``detail``.
    flagged : bool
        True when the intended final state is not reached within tolerance.
    verdict : str
        One sentence.
    """

    spec: ToleranceSpec
    method: str
    ports: list
    nominal: np.ndarray
    distances: np.ndarray
    reached: np.ndarray
    end_nodes: list
    end_offsets: np.ndarray | None
    length_rms: float
    limits: np.ndarray
    horizon: dict | None
    flagged: bool
    verdict: str
    extra: dict = field(default_factory=dict)

    @property
    def reached_fraction(self) -> float:
        return float(self.reached.mean()) if self.reached.size else 0.0

    def port_errors_mm(self) -> np.ndarray:
        """|built - designed| of every port for the builds that reach the target, (M', P) mm."""
        ok = self.distances[self.reached]
        return np.abs(ok - self.nominal[None, :]) * self.spec.scale

    def as_dict(self) -> dict:
        """JSON-ready summary (no per-build arrays)."""
        err = self.port_errors_mm()
        ok = self.distances[self.reached]
        ports = []
        for k, name in enumerate(self.ports):
            has = ok.shape[0] > 0
            ports.append({
                "port": name,
                "nominal": float(self.nominal[k]),
                "mean": float(ok[:, k].mean()) if has else None,
                "std": float(ok[:, k].std()) if has else None,
                "p95_abs_error": float(np.percentile(err[:, k], 95)) / self.spec.scale if has
                else None,
                "p95_abs_error_mm": float(np.percentile(err[:, k], 95)) if has else None,
                "limit_mm": float(self.limits[k]),
            })
        spec = self.spec
        out = {
            "process": spec.process,
            "method": self.method,
            "samples": int(self.reached.size),
            "reached_fraction": self.reached_fraction,
            "length_rms_mm": self.length_rms,
            "ports": ports,
            "flagged": self.flagged,
            "verdict": self.verdict,
            "horizon": self.horizon,
            "end_nodes": list(self.end_nodes),
            "seed": spec.seed,
            "min_reached": spec.min_reached,
            "scale_mm": spec.scale,
            "limit_mm": None if spec.limit is None else spec.limit,
            "limit_fraction": spec.limit_fraction,
            "errors": {k: getattr(spec, k) for k in spec.process_keys()},
            "model": model_summary(spec),
            "not_kinematic": NOT_KINEMATIC.get(spec.process, {}),
        }
        if spec.process == "laser":  # the laser's keys under their historical names
            out.update({f"{k}_mm": getattr(spec, k) for k in (
                "length_sigma", "kerf_sigma", "hole_clearance", "thickness", "thickness_sigma")})
        if self.end_offsets is not None and self.reached.any():
            r = np.linalg.norm(self.end_offsets[self.reached], axis=-1) * self.spec.scale
            out["end_position_p95_mm"] = float(np.percentile(r, 95))
            out["end_position_max_mm"] = float(r.max())
        out.update(self.extra)
        return out
