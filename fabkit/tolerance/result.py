"""The result of a tolerance analysis and its JSON-ready summary."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .processes import not_kinematic
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
        Designed port distances at the end of the motion (design units).
    distances : numpy.ndarray, shape (M, P)
        Port distances of every build at its end (NaN where it does not reach the end).
    reached : numpy.ndarray of bool, shape (M,)
        The build's motion ends within the limit of the design's end.
    keep : numpy.ndarray of bool, shape (M,)
        The build keeps the design's behaviour (every criterion).
    end_nodes : list of int
        Nodes of the last port (the far end of a chain).
    end_offsets : numpy.ndarray, shape (M, len(end_nodes), d) or None
        Displacement of those nodes from their designed end positions (design units, drive
        frame: the drive's first node fixed, its second on the designed drive direction).
    length_rms : float
        RMS effective bar-length error of the builds (mm).
    limits : numpy.ndarray, shape (P,)
        Allowed error per port (mm).
    horizon : dict or None
        ``lyapunov``, ``source``, ``error_mm``, ``module_size_mm``, ``modules``, ``detail``.
    flagged : bool
        True when fewer than ``min_reached`` of the builds keep the behaviour.
    verdict : str
        One sentence, with the margin.
    behaviour : Behaviour
        What the design is for (:mod:`fabkit.tolerance.behaviour`).
    judged : dict of str to Judged
        Every criterion over the builds.
    margin : dict
        ``value`` (the factor by which every error may grow with the verdict unchanged),
        ``bound`` ("at least", "below" or None), ``curves`` (fraction of builds that keep the
        behaviour against the error scale, all sources and each alone), ``sources`` (each
        source's own margin).
    critical : numpy.ndarray, shape (M,)
        Each build's critical error scale.
    """

    spec: ToleranceSpec
    method: str
    ports: list
    nominal: np.ndarray
    distances: np.ndarray
    reached: np.ndarray
    keep: np.ndarray
    end_nodes: list
    end_offsets: np.ndarray | None
    length_rms: float
    limits: np.ndarray
    horizon: dict | None
    flagged: bool
    verdict: str
    behaviour: object = None
    judged: dict = field(default_factory=dict)
    margin: dict = field(default_factory=dict)
    critical: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    @property
    def keep_fraction(self) -> float:
        """Fraction of the builds that keep the design's behaviour."""
        return float(self.keep.mean()) if self.keep.size else 0.0

    @property
    def reached_fraction(self) -> float:
        """Fraction of the builds whose motion ends within the limit of the design's end."""
        return float(self.reached.mean()) if self.reached.size else 0.0

    def port_errors_mm(self) -> np.ndarray:
        """|built - designed| of every port for the builds that reach the end, (M', P) mm."""
        ok = self.distances[self.reached]
        return np.abs(ok - self.nominal[None, :]) * self.spec.scale

    def criteria_dict(self) -> list[dict]:
        """Every criterion: builds that keep it, its number (95% of builds, worst; infinite
        where a build has no such state) and limit."""
        out = []
        for name, j in self.judged.items():
            v = j.value_mm
            fin = np.isfinite(v)
            out.append({
                "criterion": name,
                "kept_fraction": float(j.ok.mean()) if j.ok.size else 0.0,
                "p95_mm": float(np.percentile(v, 95, method="higher")) if v.size else None,
                "worst_mm": float(v.max()) if v.size else None,
                "missing": int((~fin).sum()),
                "limit_mm": float(j.limit_mm),
                "unit": j.unit,
                "detail": j.detail,
            })
        return out

    def as_dict(self) -> dict:
        """JSON-ready summary (no per-build arrays)."""
        err = self.port_errors_mm()
        ok = self.distances[self.reached]
        ports = []
        judged_ports = self.behaviour is None or self.behaviour.end == "ports"
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
        m = self.margin or {}
        out = {
            "process": spec.process,
            "method": self.method,
            "samples": int(self.keep.size),
            "keep_fraction": self.keep_fraction,
            "reached_fraction": self.reached_fraction,
            "length_rms_mm": self.length_rms,
            "behaviour": None if self.behaviour is None else self.behaviour.as_dict(),
            "criteria": self.criteria_dict(),
            "margin": m.get("value"),
            "margin_bound": m.get("bound"),
            "source_margins": m.get("sources", {}),
            "keep_curves": m.get("curves", {}),
            "source_samples": m.get("source_samples", 0),
            "ports": ports,
            "ports_judged": judged_ports,
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
            "not_kinematic": not_kinematic(spec),
        }
        if spec.process == "laser":  # the laser's keys under their historical names
            out.update({f"{k}_mm": getattr(spec, k) for k in (
                "length_sigma", "kerf_sigma", "hole_clearance", "thickness", "thickness_sigma")})
        if spec.process == "print":
            out["linkage"] = spec.linkage
        if self.end_offsets is not None and self.reached.any():
            r = np.linalg.norm(self.end_offsets[self.reached], axis=-1) * self.spec.scale
            out["end_position_p95_mm"] = float(np.percentile(r, 95))
            out["end_position_max_mm"] = float(r.max())
        out.update(self.extra)
        return out
