"""Tolerance analysis: how far a built network strays from its design, per fabrication process.

A Monte Carlo over the manufacturing errors of the process that builds the design (laser-cut
bars, a 3D print, a folded sheet; see :mod:`fabkit.tolerance.processes` for each error model and
docs/printing.md, docs/batch.md for the defaults and where they come from). Lengths are in mm and
become design units through the process's own scale (the laser settings' scale, the print's
``scale``, the origami sheet's ``sheet_size``), so every figure is in the maker's millimetres.

Each sampled build is driven to the template's target ``motion.to`` (the input is set exactly:
the error is in the structure, not the actuation). Where a construction order exists (from the
start, or from the folded target for a flat origami sheet) all builds and all drive values are
placed by intersections in one vectorised pass; otherwise each build's lengths are realised by
Gauss-Newton and traced by projected continuation. A build that locks at a turning point short of
the target ends there (the maker pulls until it stops): it *reaches* the target when it locks
within the limit of it, and its ports are measured where it locked.

A design is flagged only when the process's errors keep it from its target: fewer than
``min_reached`` of the builds reach it, or the 95th-percentile port error exceeds the limit
(default ``limit_fraction`` of the module size, the mean designed port distance). The verdict of
a flagged design names the error source that stops it (each source is simulated alone).

For chains of modules the analysis also estimates the Lyapunov exponent λ of the module map
(from the chain's own gains ∂d_{k+1}/∂d_k, or by iterating a single module's map) and the
predictability horizon k* = ln(module size / error) / λ: how many modules until a manufacturing
error grows, as e^{λk}, to the size of a module.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..errors import FabkitError, KinematicsError, TemplateError
from ..numerics import EDGE_RTOL, TINY, project_to_lengths
from .processes import NOT_KINEMATIC, PROCESSES, SOURCES, ProcessGeometry, sample_lengths

__all__ = ["ToleranceSpec", "ToleranceResult", "tolerance_spec", "analyse_tolerance",
           "perturbed_lengths", "lyapunov_estimate", "tolerance_figure", "TOLERANCE_KEYS",
           "PROCESSES", "SOURCES", "design_process"]

#: Builds whose lengths must be realised and traced one by one (no construction order) are
#: slow; their number is capped at this.
PROJECTED_SAMPLES_CAP = 40

#: |λ| below this (per module) counts as a neutral map: no exponential growth or decay.
NEUTRAL_LYAPUNOV = 1e-6

#: Map slopes below this are taken as this (the resolution of a central difference), so that a
#: super-stable point gives λ ≈ -27.6 instead of -inf.
SLOPE_FLOOR = 1e-12

#: Fewest map iterations from which a Lyapunov exponent is reported as a horizon.
MIN_MAP_STEPS = 3

#: Bisection steps that find where a build locks (a turning point short of the target).
LOCK_BISECTIONS = 26

#: Linear shrinkage after cooling, mean and standard deviation (fractions), by print material:
#: typical figures quoted by filament makers for parts that the slicer does not compensate.
SHRINKAGE = {"PLA": (0.003, 0.001), "PETG": (0.004, 0.0015), "TPU": (0.006, 0.002)}


#: Step of the central differences that read a chain's slopes off the traced plan (relative to
#: the target): the map is smooth there, and 1e-6 balances truncation and round-off.
SLOPE_STEP = 1e-6
#: A simulated build is projected onto its own bar lengths to this relative error (its bars
#: carry process errors of ~1e-3, so a tighter fit adds nothing).
BUILD_RTOL = 1e-9
#: Floor of the log-scale error plot (an exact zero has no logarithm).
LOG_FLOOR = 1e-12


@dataclass(frozen=True)
class ToleranceSpec:
    """Manufacturing errors of one process and the acceptance limits (lengths in mm).

    Attributes
    ----------
    process : str
        ``"laser"``, ``"print"`` or ``"origami"``: which error model applies (default: the
        design's fabrication table).
    scale : float
        mm per design unit (default: the process's own scale).
    length_sigma, kerf_sigma, hole_clearance, thickness, thickness_sigma : float
        Laser: bar-length σ (0.05 mm, laser positioning), hole-diameter σ from uneven kerf
        (0.03 mm), hole minus barrel diameter (the screw's 4.2 - 4.0 = 0.2 mm), sheet thickness
        and its build-to-build σ (3.0 ± 0.15 mm: extruded acrylic, ~5 %).
    xy_sigma, shrinkage, shrinkage_sigma, line_width_sigma, hinge_length : float
        Print: joint position σ per coordinate (0.1 mm, typical FDM accuracy), shrinkage
        fraction and its σ (by material, :data:`SHRINKAGE`), extrusion-width σ (0.03 mm), the
        hinges' free length (the print settings').
    crease_sigma, cut_sigma, paper_thickness, compliance_sigma : float
        Origami: crease-vertex position σ (0.5 mm, folding by hand on a printed line), boundary
        σ (0.2 mm, knife or cutter), paper thickness (0.1 mm, 80 g/m² copy paper), panel bowing
        σ (0.2 mm).
    limit : float or None
        Allowed 95th-percentile error of every port distance at the target (mm); None:
        ``limit_fraction`` of the module size.
    limit_fraction : float
        Default limit as a fraction of the mean designed port distance (0.02: a 2 % change of
        a module's shape is about what a maker sees by eye).
    min_reached : float
        Fraction of builds that must reach the target (default 0.95).
    samples : int
        Number of simulated builds (default 200).
    seed : int
        Seed of the random numbers (same seed, same result).
    """

    process: str = "laser"
    scale: float = 50.0
    length_sigma: float = 0.05
    kerf_sigma: float = 0.03
    hole_clearance: float = 0.2
    thickness: float = 3.0
    thickness_sigma: float = 0.15
    xy_sigma: float = 0.1
    shrinkage: float = 0.003
    shrinkage_sigma: float = 0.001
    line_width_sigma: float = 0.03
    hinge_length: float = 6.0
    crease_sigma: float = 0.5
    cut_sigma: float = 0.2
    paper_thickness: float = 0.1
    compliance_sigma: float = 0.2
    limit: float | None = None
    limit_fraction: float = 0.02
    min_reached: float = 0.95
    samples: int = 200
    seed: int = 0

    def process_keys(self) -> tuple[str, ...]:
        """The spec fields that belong to this process (its error sources' parameters)."""
        keys = [k for src in SOURCES[self.process].values() for k in src]
        if self.process == "laser":
            keys.insert(keys.index("thickness_sigma"), "thickness")
        return tuple(keys)


TOLERANCE_KEYS = {f.name for f in fields(ToleranceSpec)}
_COMMON = ("process", "scale", "limit", "limit_fraction", "min_reached", "samples", "seed")
_NON_NEGATIVE = ("length_sigma", "kerf_sigma", "hole_clearance", "thickness_sigma", "xy_sigma",
                 "shrinkage_sigma", "line_width_sigma", "hinge_length", "crease_sigma",
                 "cut_sigma", "paper_thickness", "compliance_sigma")
_POSITIVE = ("scale", "thickness", "limit", "limit_fraction")
_OWNER = {k: proc for proc in PROCESSES for src in SOURCES[proc].values() for k in src}
_OWNER["thickness"] = "laser"


def design_process(design) -> str:
    """The process a design is built by: its ``[fabrication.tolerance] process``, else the first
    of its origami / print / laser tables, else origami for 3D networks and laser for planar."""
    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    table = fab.get("tolerance")
    if isinstance(table, dict) and table.get("process") in PROCESSES:
        return table["process"]
    for proc, key in (("origami", "origami"), ("print", "print"), ("laser", "laser")):
        if key in fab:
            return proc
    return "origami" if design.network.dim == 3 else "laser"


def _laser_defaults(design, settings) -> dict:
    """Scale, thickness and hole clearance from the laser settings."""
    from ..errors import FabricationError
    from ..fab.laser import laser_settings

    laser = design.fabrication.get("laser") if isinstance(design.fabrication, dict) else None
    try:
        s = laser_settings(laser if isinstance(laser, dict) else {},
                           (settings or {}).get("laser") or {},
                           network_size=float(design.network.size))
    except FabricationError as exc:
        raise TemplateError(design.path or design.name, "fabrication.laser", str(exc)) from None
    out = {"scale": float(s.scale), "thickness": float(s.thickness)}
    screw = getattr(s, "screw", None)
    if screw is not None:
        out["hole_clearance"] = float(screw.hole_diameter - screw.barrel_diameter)
    return out


def _print_defaults(design, settings) -> dict:
    """Scale, hinge length and the material's shrinkage from the print settings."""
    from ..errors import FabricationError
    from ..fab.printing import design_print_settings

    try:
        s = design_print_settings(design, settings)
    except FabricationError as exc:
        raise TemplateError(design.path or design.name, "fabrication.print", str(exc)) from None
    mean, sd = SHRINKAGE.get(s.material, SHRINKAGE["PLA"])
    return {"scale": float(s.scale), "hinge_length": float(s.hinge_length), "shrinkage": mean,
            "shrinkage_sigma": sd}


def _origami_defaults(design, settings) -> dict:
    """Scale from the sheet size of the [fabrication.origami] table (150 mm when absent)."""
    from ..errors import FabricationError
    from ..fab.creases import origami_model

    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    if "origami" not in fab:
        return {"scale": 150.0 / max(float(design.network.size), TINY)}
    try:
        return {"scale": float(origami_model(design, (settings or {}).get("origami")).scale)}
    except FabricationError as exc:
        raise TemplateError(design.path or design.name, "fabrication.origami", str(exc)) from None


_DEFAULTS = {"laser": _laser_defaults, "print": _print_defaults, "origami": _origami_defaults}


def tolerance_spec(design, settings=None, **overrides) -> ToleranceSpec:
    """The tolerance settings of a design: defaults < the process's settings (scale, sheet,
    hinge, material) < the template's ``[fabrication.tolerance]`` table < ``settings
    ["tolerance"]`` (command line) < ``overrides``.

    Parameters
    ----------
    design : Design
    settings : dict, optional
        Command-line overrides, nested by section (``{"tolerance": {"samples": 50}}``).
    **overrides
        Final say on any field of :class:`ToleranceSpec`.

    Returns
    -------
    ToleranceSpec

    Raises
    ------
    TemplateError
        Unknown key, a key of another process, wrong type, or a negative or zero value, naming
        ``fabrication.tolerance.<key>``; invalid settings of the process (they give the scale).

    Examples
    --------
    >>> from fabkit.templates import parse_template
    >>> d = parse_template('[network]\\nnodes=[[0,0],[1,0],[0,1],[1,1]]\\n'
    ...                    'edges=[[0,1],[0,2],[1,3],[2,3]]\\nports={d1=[0,3]}\\n'
    ...                    '[fabrication.tolerance]\\nscale=20\\nsamples=10')
    >>> tolerance_spec(d).scale, tolerance_spec(d, samples=5).samples, tolerance_spec(d).process
    (20.0, 5, 'laser')
    """
    path = design.path or design.name
    table = design.fabrication.get("tolerance", {}) if isinstance(design.fabrication, dict) else {}
    cli = (settings or {}).get("tolerance", {})
    sources = (("fabrication.tolerance", table), ("--set tolerance", cli),
               ("tolerance option", overrides))
    process = design_process(design)
    for where, source in sources:
        if not isinstance(source, dict):
            raise TemplateError(path, where, "must be a table of tolerance settings")
        if "process" in source:
            if source["process"] not in PROCESSES:
                raise TemplateError(path, f"{where}.process", f"must be one of "
                                    f"{', '.join(PROCESSES)}, got {source['process']!r}")
            process = source["process"]
    values: dict = {"process": process}
    values.update(_DEFAULTS[process](design, settings))
    for where, source in sources:
        for key, value in source.items():
            full = f"{where}.{key}"
            if key == "process":
                continue
            if key not in TOLERANCE_KEYS:
                raise TemplateError(path, full, "unknown key; allowed keys for the "
                                    f"{process} process: "
                                    + ", ".join(sorted(set(_COMMON) | {
                                        k for k, p in _OWNER.items() if p == process})))
            if _OWNER.get(key, process) != process:
                raise TemplateError(path, full, f"is a {_OWNER[key]} error; this design is "
                                                f"analysed as {process} (set process = "
                                                f"\"{_OWNER[key]}\" to change that)")
            if value is None and key == "limit":
                values[key] = None
                continue
            if key in ("samples", "seed"):
                if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                    raise TemplateError(path, full, f"must be an integer, got {value!r}")
                if key == "samples" and value < 1:
                    raise TemplateError(path, full, f"must be at least 1, got {value}")
                values[key] = int(value)
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value):
                raise TemplateError(path, full, f"must be a finite number (mm), got {value!r}")
            if key in _NON_NEGATIVE and value < 0:
                raise TemplateError(path, full, f"must be >= 0 mm, got {value}")
            if key in _POSITIVE and value <= 0:
                raise TemplateError(path, full, f"must be > 0, got {value}")
            if key in ("min_reached", "shrinkage") and not 0 <= value <= 1:
                raise TemplateError(path, full, f"must be a fraction in 0..1, got {value}")
            values[key] = float(value)
    return ToleranceSpec(**values)


def perturbed_lengths(lengths, spec: ToleranceSpec, rng) -> tuple[np.ndarray, np.ndarray]:
    """Sample the edge lengths of ``spec.samples`` laser-cut builds (every laser error source).

    Parameters
    ----------
    lengths : array_like, shape (E,)
        Design lengths (design units).
    spec : ToleranceSpec
    rng : numpy.random.Generator

    Returns
    -------
    built : numpy.ndarray, shape (M, E)
        Effective lengths of every build (design units).
    thickness : numpy.ndarray, shape (M,)
        Sheet thickness of every build (mm).

    Examples
    --------
    >>> spec = ToleranceSpec(samples=4, length_sigma=0, kerf_sigma=0, hole_clearance=0)
    >>> built, t = perturbed_lengths([1.0, 2.0], spec, np.random.default_rng(0))
    >>> bool(np.allclose(built, [[1.0, 2.0]] * 4))
    True
    """
    L = np.asarray(lengths, dtype=np.float64)
    geo = ProcessGeometry(np.zeros((L.size + 1, 2)), np.zeros((L.size, 2), dtype=np.int64), L)
    state = rng.bit_generator.state
    built = sample_lengths(geo, replace(spec, process="laser"), rng)
    # the thickness is the first draw of the laser model: replay it
    rng2 = np.random.Generator(type(rng.bit_generator)())
    rng2.bit_generator.state = state
    t = np.maximum(spec.thickness + spec.thickness_sigma * rng2.standard_normal(spec.samples),
                   0.1 * spec.thickness)
    return built, t


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


def model_summary(spec: ToleranceSpec) -> str:
    """One sentence: the process's error sources with their values, in mm.

    Examples
    --------
    >>> model_summary(ToleranceSpec(process="origami", scale=100.0))[:40]
    'origami: crease position σ 0.5 mm, cut σ'
    """
    if spec.process == "laser":
        parts = [f"bar length σ {spec.length_sigma:g} mm", f"kerf σ {spec.kerf_sigma:g} mm",
                 f"hole play {spec.hole_clearance:g} mm",
                 f"sheet {spec.thickness:g} ± {spec.thickness_sigma:g} mm"]
    elif spec.process == "print":
        parts = [f"xy accuracy σ {spec.xy_sigma:g} mm",
                 f"shrinkage {100 * spec.shrinkage:g} ± {100 * spec.shrinkage_sigma:g} %",
                 f"line width σ {spec.line_width_sigma:g} mm",
                 f"hinge flexure over {spec.hinge_length:g} mm"]
    else:
        parts = [f"crease position σ {spec.crease_sigma:g} mm", f"cut σ {spec.cut_sigma:g} mm",
                 f"paper {spec.paper_thickness:g} mm thick",
                 f"crease compliance σ {spec.compliance_sigma:g} mm"]
    return f"{spec.process}: " + ", ".join(parts) + f" (scale {spec.scale:.4g} mm per unit)"


def _chain_ports(net) -> list[str]:
    """Ports named d1, d2, ... in order, followed by the other ports."""
    chain = sorted((p for p in net.ports if re.fullmatch(r"d\d+", p)), key=lambda p: int(p[1:]))
    return chain + sorted(p for p in net.ports if p not in chain)


def _plan_edge_index(plan, net) -> np.ndarray:
    """For every (placed node, parent) pair of a plan, the index of its edge in ``net``."""
    lookup = {(min(i, j), max(i, j)): k for k, (i, j) in enumerate(net.edges.tolist())}
    idx = np.full(plan.parents.shape, -1, dtype=np.int64)
    for row, (v, par) in enumerate(zip(plan.order.tolist(), plan.parents.tolist())):
        for c, p in enumerate(par):
            if p >= 0:
                idx[row, c] = lookup[(min(v, p), max(v, p))]
    return idx


def _to_drive_frame(x, a, b, ref_dir) -> np.ndarray:
    """Rigidly move configurations (..., N, 2) so node a is at the origin and a→b along ref_dir
    (2D only; 3D configurations are returned relative to node a)."""
    x = np.asarray(x) - np.asarray(x)[..., a:a + 1, :]
    if x.shape[-1] != 2:
        return x
    u = x[..., b, :] / np.linalg.norm(x[..., b, :], axis=-1, keepdims=True)
    ang = np.arctan2(ref_dir[1], ref_dir[0]) - np.arctan2(u[..., 1], u[..., 0])
    c, s = np.cos(ang)[..., None], np.sin(ang)[..., None]
    return np.stack([c * x[..., 0] - s * x[..., 1], s * x[..., 0] + c * x[..., 1]], axis=-1)


def lyapunov_estimate(design, plan=None, *, iterations: int = 400, orbits: int = 64,
                      transient: int = 50) -> dict | None:
    """Lyapunov exponent λ of the module map of a design, per module.

    Chains (ports d1, d2, d3, ...): λ is the mean of ``log |∂d_{k+1}/∂d_k|`` along the chain at
    the target, the gains measured by a central difference of the drive. A single module (ports
    d1 and d2): the map ``d2 = f(d1)`` is iterated from the target for up to ``iterations``
    steps while it stays in the module's range, λ = mean ``log |f'(d_k)|``.

    Parameters
    ----------
    design : Design
    plan : ConstructionPlan, optional
    iterations, orbits, transient : int

    Returns
    -------
    dict or None
        ``lyapunov`` (per module), ``source`` ("chain gains" / "iterated module map"),
        ``steps``; None when the design has no construction order or no d1/d2 ports.
    """
    from ..errors import ConstructionError, DesignError
    from ..kinematics import make_problem, place, plan_construction

    net = design.network
    chain = [p for p in _chain_ports(net) if re.fullmatch(r"d\d+", p)]
    if len(chain) < 2 or design.motion.drive != chain[0] or design.motion.to is None:
        return None
    problem = make_problem(net, design.motion.drive, design.motion.to, hold=design.motion.hold)
    if plan is None:
        try:
            plan = plan_construction(problem.work, problem.drive, problem.start)
        except ConstructionError:
            return None
    pairs = np.array([net.port(p) for p in chain])
    to = float(design.motion.to)
    if len(chain) >= 3:
        h = SLOPE_STEP * to
        X, margin, _ = place(plan, [to - h, to + h])
        if (margin < 0).any():
            return None
        d = np.linalg.norm(X[:, pairs[:, 0]] - X[:, pairs[:, 1]], axis=-1)  # (2, K)
        gains = (d[1] - d[0]) / (2 * h)
        slopes = np.abs(gains[1:] / np.where(gains[:-1] == 0, np.finfo(float).tiny, gains[:-1]))
        logs = np.log(np.maximum(slopes, SLOPE_FLOOR))
        return {"lyapunov": float(np.mean(logs)), "source": "chain gains",
                "steps": int(logs.size), "local": logs.tolist()}
    # a single module: the module's exact map (fabkit.maps), a bundle of orbits started next to
    # the target; orbits that leave the map's domain are dropped
    from ..maps import module_map

    try:
        fmap = module_map(net, chain[0], chain[1])
        d0 = np.clip(to * (1.0 + 1e-3 * np.linspace(-1.0, 1.0, orbits)), *fmap.domain)
        res = fmap.lyapunov(initial=d0, discard=transient, average=max(iterations - transient, 1),
                            method="exact")
    except (ConstructionError, KinematicsError, DesignError):
        return None
    vals = res.values[~np.isnan(res.values)]
    if not vals.size:
        return None
    # a super-stable orbit has log|f'| -> -inf; slopes below the floor count as the floor
    vals = np.maximum(vals, np.log(SLOPE_FLOOR))
    return {"lyapunov": float(vals.mean()), "source": "iterated module map",
            "steps": int(res.discard + res.average), "orbits": int(vals.size),
            "transient": int(res.discard)}


def _place_builds(plan, values, radii) -> tuple[np.ndarray, np.ndarray]:
    """Place every build at its own drive values in one pass of :func:`fabkit.kinematics.place`,
    one column per (build, drive value) carrying its build's radii.

    Parameters
    ----------
    plan : ConstructionPlan
    values : numpy.ndarray, shape (M, G)
        Drive values of each build.
    radii : numpy.ndarray, shape (M, K, dim)
        Each build's distances of every placed node to its parents.

    Returns
    -------
    positions : numpy.ndarray, shape (M, G, N, d)
    margin : numpy.ndarray, shape (M, G)
        Smallest ``h² / r²`` over the intersections; negative where one does not exist.
    """
    m, g = values.shape
    from ..kinematics import place

    x, margin, _ = place(plan, values.reshape(m * g), radii=np.repeat(radii, g, axis=0))
    return x.reshape((m, g) + x.shape[1:]), margin.reshape(m, g)


def _joint_turn(net, start, final) -> np.ndarray:
    """Largest turn (radians) between two bars at every joint from ``start`` to ``final`` (2D)."""
    i, j = net.edges[:, 0], net.edges[:, 1]
    if net.dim != 2:
        return np.zeros(net.n_nodes)
    ang = []
    for x in (start, final):
        dx = x[j] - x[i]
        ang.append(np.arctan2(dx[:, 1], dx[:, 0]))
    turn = np.angle(np.exp(1j * (ang[1] - ang[0])))  # each bar's own turn, wrapped
    hi = np.full(net.n_nodes, -np.inf)
    lo = np.full(net.n_nodes, np.inf)
    for ends in (i, j):
        np.maximum.at(hi, ends, turn)
        np.minimum.at(lo, ends, turn)
    return np.where(np.isfinite(hi), np.minimum(hi - lo, 2 * np.pi), 0.0)


def _process_geometry(design, spec, problem, final) -> ProcessGeometry:
    net = design.network
    turn = boundary = None
    if spec.process == "print" and final is not None:
        turn = _joint_turn(net, problem.start, final)
    if spec.process == "origami":
        fab = design.fabrication if isinstance(design.fabrication, dict) else {}
        assignment = (fab.get("origami") or {}).get("assignment") \
            if isinstance(fab.get("origami"), dict) else None
        if isinstance(assignment, list) and len(assignment) == net.n_edges:
            cut = net.edges[[a in ("B", "C") for a in assignment]]
            boundary = np.zeros(net.n_nodes, dtype=bool)
            boundary[cut.ravel()] = True
    return ProcessGeometry(net.nodes, net.edges, net.edge_lengths, turn, boundary)


@dataclass
class _Runs:
    """Results of one batch of simulated builds (constructive placement)."""

    dist: np.ndarray
    reached: np.ndarray
    final: np.ndarray
    stop: np.ndarray
    locked: int
    unclosed: int


def _simulate(plan, eidx, problem, net, built, values, pairs, limit_units, clearance_units):
    """Drive every build towards the target; a build that locks stops where it locks."""
    m = built.shape[0]
    n_virtual = problem.work.n_edges - net.n_edges
    work = np.concatenate([built, np.broadcast_to(problem.work.edge_lengths[net.n_edges:],
                                                  (m, n_virtual))], axis=1)
    mask = eidx >= 0
    radii = np.where(mask[None], work[:, np.maximum(eidx, 0)], 0.0)  # (M, K, dim)
    grid = np.broadcast_to(values, (m, values.size))
    X, margin = _place_builds(plan, grid, radii)
    bad = margin[:, 1:] < 0
    fails = bad.any(axis=1)
    final = X[:, -1].copy()
    stop = np.full(m, values[-1])
    if fails.any():
        f = np.flatnonzero(fails)
        first = np.argmax(bad[f], axis=1) + 1
        lo, hi = values[first - 1], values[first]
        for _ in range(LOCK_BISECTIONS):  # where each failing build locks
            mid = 0.5 * (lo + hi)
            _, mm = _place_builds(plan, mid[:, None], radii[f])
            ok = mm[:, 0] >= 0
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
        Xl, _ = _place_builds(plan, lo[:, None], radii[f])
        final[f] = Xl[:, 0]
        stop[f] = lo
    # a build that locks within the limit of the target has reached it (it stops there)
    reached = np.abs(stop - values[-1]) <= limit_units
    locked = int((~reached).sum())
    # redundant edges (self-stress) are not used by the construction: a build that cannot
    # close them does not assemble
    used = np.zeros(problem.work.n_edges, dtype=bool)
    used[eidx[mask]] = True
    unused = np.flatnonzero(~used[:net.n_edges])
    moving = reached.copy()
    if unused.size:
        i, j = net.edges[unused, 0], net.edges[unused, 1]
        got = np.linalg.norm(final[:, i] - final[:, j], axis=-1)
        reached &= np.abs(got - built[:, unused]).max(axis=1) <= clearance_units + EDGE_RTOL
    dist = np.linalg.norm(final[:, pairs[:, 0]] - final[:, pairs[:, 1]], axis=-1)
    dist[~reached] = np.nan
    return _Runs(dist, reached, final, stop, locked, int((moving & ~reached).sum()))


def _find_plan(problem, trajectory):
    """The cached construction plan from the start; from the target's sides when the start is a
    flat state (a flat origami sheet); None when there is no construction order."""
    from ..errors import ConstructionError
    from ..kinematics import plan_construction
    from ..kinematics.constructive import cached_plan

    try:
        return cached_plan(problem.work, problem.drive, problem.start)
    except ConstructionError:
        pass
    final = getattr(trajectory, "final", None)
    if final is None or np.shape(final) != problem.start.shape:
        return None
    try:
        return plan_construction(problem.work, problem.drive, final)
    except ConstructionError:
        return None


def analyse_tolerance(design, spec: ToleranceSpec | None = None, *, trajectory=None,
                      grid: int = 41, attribute: bool = True) -> ToleranceResult:
    """Monte Carlo of built copies of a design driven to its target (see the module docstring).

    Parameters
    ----------
    design : Design
        With ``motion.to`` set.
    spec : ToleranceSpec, optional
        Default: :func:`tolerance_spec` of the design.
    trajectory : Trajectory, optional
        The nominal motion (traced when not given).
    grid : int
        Drive values checked between the start and the target for every build.
    attribute : bool
        When the design is flagged, also simulate each error source alone (``extra
        ["sources"]``) and name in the verdict the one that stops the design.

    Returns
    -------
    ToleranceResult

    Raises
    ------
    TemplateError
        No target (``motion.to``) or a nominal motion that does not reach it.

    Examples
    --------
    >>> from fabkit.templates import load_template
    >>> from pathlib import Path
    >>> d = load_template(Path(__file__).parents[2] / "templates" / "fourbar.toml")
    >>> res = analyse_tolerance(d, tolerance_spec(d, samples=50))
    >>> res.reached_fraction, res.flagged
    (1.0, False)
    """
    from ..kinematics import make_problem, place

    path = design.path or design.name
    spec = spec or tolerance_spec(design)
    net = design.network
    m = design.motion
    if m.to is None:
        raise TemplateError(path, "motion.to", "the tolerance analysis needs a target value")
    if trajectory is None:
        trajectory = design.trace()
    if not trajectory.success:
        raise TemplateError(path, "motion.to", f"the designed motion does not reach the target: "
                                               f"{trajectory.message}")
    problem = make_problem(net, m.drive, m.to, hold=m.hold)
    ports = _chain_ports(net)
    pairs = np.array([net.port(p) for p in ports])
    a, b = problem.drive
    n_chain = len([p for p in ports if re.fullmatch(r"d\d+", p)])
    end_nodes = sorted(set(pairs[max(n_chain, 1) - 1].tolist()))
    plan = _find_plan(problem, trajectory)
    names = list(SOURCES[spec.process])

    def draw(sources=None):
        return sample_lengths(geo, spec, np.random.default_rng(spec.seed), sources)

    if plan is not None:
        method = "constructive"
        nominal_x = place(plan, [m.to])[0][0]
        geo = _process_geometry(design, spec, problem, nominal_x)
        nominal = np.linalg.norm(nominal_x[pairs[:, 0]] - nominal_x[pairs[:, 1]], axis=-1)
        size_mm = float(np.mean(nominal)) * spec.scale
        limit_mm = spec.limit if spec.limit is not None else spec.limit_fraction * size_mm
        eidx = _plan_edge_index(plan, problem.work)
        values = np.linspace(problem.start_drive, m.to, grid)
        clearance = (2 * spec.hole_clearance if spec.process == "laser" else limit_mm) / spec.scale

        def run(built):
            return _simulate(plan, eidx, problem, net, built, values, pairs,
                             limit_mm / spec.scale, clearance)

        built = draw()
        r = run(built)
        dist, reached, unclosed, locked = r.dist, r.reached, r.unclosed, r.locked
        ref_dir = (plan.reference[b] - plan.reference[a])[:2]
        framed = _to_drive_frame(r.final, a, b, ref_dir)
        nominal_framed = _to_drive_frame(nominal_x[None], a, b, ref_dir)[0]
        end_offsets = framed[:, end_nodes] - nominal_framed[None, end_nodes]
        stops = r.stop
    else:
        from ..kinematics import trace

        method = "projected"
        locked, unclosed = 0, 0
        spec = replace(spec, samples=min(spec.samples, PROJECTED_SAMPLES_CAP))
        nominal_x = trajectory.final
        geo = _process_geometry(design, spec, problem, nominal_x)
        nominal = np.linalg.norm(nominal_x[pairs[:, 0]] - nominal_x[pairs[:, 1]], axis=-1)
        size_mm = float(np.mean(nominal)) * spec.scale
        limit_mm = spec.limit if spec.limit is not None else spec.limit_fraction * size_mm

        def run(built):
            dist = np.full((built.shape[0], len(ports)), np.nan)
            reached = np.zeros(built.shape[0], dtype=bool)
            for s in range(built.shape[0]):
                proj = project_to_lengths(net.edges, built[s], net.nodes, rtol=BUILD_RTOL,
                                          max_iter=30)
                if not proj.converged:
                    continue
                x = proj.positions
                try:
                    tr = trace(net.with_nodes(x), drive=m.drive, to=m.to, method="projected",
                               hold=m.hold)
                except (KinematicsError, FabkitError):
                    continue
                if tr.success:
                    reached[s] = True
                    dist[s] = np.linalg.norm(tr.final[pairs[:, 0]] - tr.final[pairs[:, 1]],
                                             axis=-1)
            return _Runs(dist, reached, None, None, int((~reached).sum()), 0)

        built = draw()
        r = run(built)
        dist, reached, locked = r.dist, r.reached, r.locked
        end_offsets = stops = None

    length_rms = float(np.sqrt(np.mean((built - net.edge_lengths[None, :]) ** 2)) * spec.scale)
    limits = np.full(len(ports), limit_mm)

    def score(dist_, reached_):
        err = np.abs(dist_[reached_] - nominal[None, :]) * spec.scale
        p95 = np.percentile(err, 95, axis=0) if err.shape[0] else np.full(len(ports), np.inf)
        return float(reached_.mean()), p95

    frac, p95 = score(dist, reached)
    budget = {}
    worst = int(np.argmax(p95 / limits))
    if attribute and (frac < spec.min_reached or p95[worst] > limits[worst]):
        for name in names:
            rs = run(draw([name]))
            f_s, p_s = score(rs.dist, rs.reached)
            budget[name] = {"reached_fraction": f_s,
                            "p95_error_mm": float(np.max(p_s)) if np.isfinite(p_s).all()
                            else None}

    # predictability horizon of chains: error e^{λk} reaches the module size
    horizon = None
    lyap = lyapunov_estimate(design, plan) if plan is not None else None
    if lyap is not None:
        lam = lyap["lyapunov"]
        eps = max(length_rms, EDGE_RTOL)
        modules = None
        if lyap["steps"] < MIN_MAP_STEPS:
            detail = (f"the module map leaves the module's range after {lyap['steps']} step(s) "
                      "from the target: too short an orbit to estimate a horizon")
        elif abs(lam) < NEUTRAL_LYAPUNOV:
            detail = "neutral map (λ ≈ 0): errors neither grow nor shrink exponentially"
        elif lam < 0:
            detail = "errors shrink along the chain (λ < 0): no horizon"
        elif size_mm <= eps:
            detail = "the error is already as large as a module"
        else:
            modules = math.log(size_mm / eps) / lam
            detail = (f"a {eps:.3g} mm bar error grows to the {size_mm:.3g} mm module size after "
                      f"about {modules:.1f} modules")
        horizon = {**lyap, "error_mm": eps, "module_size_mm": size_mm, "modules": modules,
                   "detail": detail}
        ok = dist[reached]
        chain = [k for k, p in enumerate(ports) if re.fullmatch(r"d\d+", p)]
        if len(chain) >= 3 and ok.shape[0] >= 5:
            spread = ok[:, chain].std(axis=0)
            kk = np.arange(len(chain))
            good = spread > 0
            if good.sum() >= 3:
                horizon["monte_carlo_slope"] = float(np.polyfit(kk[good], np.log(spread[good]),
                                                                1)[0])
                horizon["monte_carlo_std"] = spread.tolist()

    extra = {"drive": m.drive, "target": float(m.to), "unclosed": unclosed, "locked": locked,
             "module_size_mm": size_mm, "sources": budget}
    if stops is not None:
        short = np.abs(stops - m.to) * spec.scale
        extra["lock_short_p95_mm"] = float(np.percentile(short, 95))
    unit = f"{spec.process} builds"
    if frac < spec.min_reached:
        flagged = True
        why = []
        if locked and method == "projected":
            why.append(f"{locked} stop before it (turning point or no assembly; traced one by "
                       "one)")
        elif locked:
            why.append(f"{locked} lock at a turning point more than {limit_mm:.3g} mm short of "
                       "it")
        if unclosed:
            why.append(f"{unclosed} cannot close their redundant bars (states of self-stress) "
                       "within the joint play")
        verdict = (f"FLAG: only {100 * frac:.1f}% of {unit} reach {m.drive} = {m.to:.6g} "
                   f"(need {100 * spec.min_reached:.0f}%): " + "; ".join(why)
                   + _cause(budget, "reached", spec))
    elif p95[worst] > limits[worst]:
        flagged = True
        verdict = (f"FLAG: {ports[worst]} is off by up to {p95[worst]:.3g} mm (95% of {unit}), "
                   f"more than the {limits[worst]:.3g} mm allowed"
                   + _cause(budget, "error", spec, limits[worst]))
    else:
        flagged = False
        verdict = (f"ok: {100 * frac:.1f}% of {unit} reach the target; every port within "
                   f"{limits[worst]:.3g} mm (worst {ports[worst]}: {p95[worst]:.3g} mm, 95% of "
                   "builds)")
    return ToleranceResult(spec=spec, method=method, ports=ports, nominal=nominal, distances=dist,
                           reached=reached, end_nodes=end_nodes, end_offsets=end_offsets,
                           length_rms=length_rms, limits=limits, horizon=horizon,
                           flagged=flagged, verdict=verdict, extra=extra)


def _cause(budget: dict, kind: str, spec: ToleranceSpec, limit: float | None = None) -> str:
    """``"; cause: <source> ..."``: the error sources that alone stop the design, else the one
    that hurts most alone."""
    if not budget:
        return ""
    if kind == "reached":
        alone = [n for n, v in budget.items() if v["reached_fraction"] < spec.min_reached]
        if alone:
            return "; stopped by " + ", ".join(
                f"{n} (alone {100 * budget[n]['reached_fraction']:.0f}% reach)" for n in alone)
        n = min(budget, key=lambda k: budget[k]["reached_fraction"])
        return (f"; no single source stops it, their sum does (worst alone: {n}, "
                f"{100 * budget[n]['reached_fraction']:.0f}% reach)")

    def err(k):
        e = budget[k]["p95_error_mm"]
        return math.inf if e is None else e

    alone = [n for n in budget if err(n) > limit]
    if alone:
        return "; stopped by " + ", ".join(f"{n} (alone {err(n):.3g} mm)" for n in alone)
    n = max(budget, key=err)
    return f"; no single source exceeds it, their sum does (largest alone: {n}, {err(n):.3g} mm)"


def tolerance_figure(result: ToleranceResult, *, title: str | None = None):
    """Three panels: error of the last chain port, error growth along the chain, end positions.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from ..viz import _mpl

    plt = _mpl()
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    err = result.port_errors_mm()
    chain = [k for k, p in enumerate(result.ports) if re.fullmatch(r"d\d+", p)] or \
        list(range(len(result.ports)))
    last = chain[-1]
    ax = axes[0]
    ok = result.distances[result.reached]
    if ok.shape[0]:
        ax.hist((ok[:, last] - result.nominal[last]) * result.spec.scale, bins=30, color="C0")
    for sgn in (-1, 1):
        ax.axvline(sgn * result.limits[last], color="C3", ls="--", lw=1)
    ax.set_xlabel(f"{result.ports[last]} built - designed (mm)")
    ax.set_ylabel("builds")
    ax.set_title(f"{result.ports[last]} at the target ({100 * result.reached_fraction:.0f}% "
                 "reach it)", fontsize=10)
    ax = axes[1]
    # the driven port is set exactly (no error): the curve starts at the next port
    along = [c for c in chain if result.ports[c] != result.extra.get("drive")] or chain
    if err.shape[0]:
        k = np.arange(1, len(along) + 1)
        p95 = np.maximum(np.percentile(err[:, along], 95, axis=0), LOG_FLOOR)
        ax.semilogy(k, p95, "o-", label="95% |error|")
        ax.semilogy(k, np.maximum(err[:, along].mean(axis=0), LOG_FLOOR), "s:", label="mean |error|")
        hz = result.horizon
        if hz and hz.get("lyapunov") is not None and len(along) >= 2:
            lam = hz["lyapunov"]
            ax.semilogy(k, p95[0] * np.exp(lam * (k - 1)), "--", color="0.5",
                        label=f"e^(λk), λ = {lam:.3g}")
        ax.axhline(result.limits[0], color="C3", ls="--", lw=1, label="limit")
        ax.set_xticks(k)
        ax.set_xticklabels([result.ports[c] for c in along], fontsize=8)
        ax.legend(fontsize=8)
    ax.set_ylabel("error (mm)")
    ax.set_title("error along the chain", fontsize=10)
    ax = axes[2]
    if result.end_offsets is not None and result.reached.any():
        off = result.end_offsets[result.reached] * result.spec.scale
        for c, node in enumerate(result.end_nodes):
            ax.plot(off[:, c, 0], off[:, c, 1], ".", ms=3, label=f"node {node}")
        ax.set_aspect("equal", adjustable="datalim")
        ax.legend(fontsize=8)
        ax.set_xlabel("x offset (mm)")
        ax.set_ylabel("y offset (mm)")
    else:
        ax.text(0.5, 0.5, "end positions not sampled\n(projected builds)", ha="center",
                va="center", transform=ax.transAxes)
    ax.set_title("far-end nodes: built - designed", fontsize=10)
    fig.suptitle(f"{title + ': ' if title else ''}{result.verdict}", fontsize=9)
    fig.tight_layout()
    return fig
