"""Tolerance analysis: how far a built network strays from its design.

A Monte Carlo over manufacturing errors of a laser-cut build (all in mm, turned into design units
by the fabrication scale):

- **bar length**: each bar's hole-to-hole length is off by ``N(0, length_sigma)`` (laser
  positioning, uneven kerf);
- **joint play**: each hole is ``hole_clearance`` wider than the screw barrel, plus the kerf error
  ``N(0, kerf_sigma)`` of that hole; the barrel sits anywhere in its hole (uniform over the disc
  of radius clearance / 2), which lengthens or shortens the bar along its axis;
- **sheet thickness**: ``N(thickness, thickness_sigma)`` per build; a bar can tilt in its holes
  by up to ``atan(clearance / thickness)``, which shortens its projected length by
  ``L (1 - cos θ)`` (thin sheets wobble more).

Each sampled build is then driven to the template's target ``motion.to`` (the input is set
exactly: the error is in the structure, not the actuation). Where a construction order exists the
builds are placed exactly by intersections, all drive values at once; otherwise each build's
lengths are realised by Gauss-Newton and traced by projected continuation. A build *reaches* the
target when every intersection exists all along the way.

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

from .errors import FabkitError, KinematicsError, TemplateError

__all__ = ["ToleranceSpec", "ToleranceResult", "tolerance_spec", "analyse_tolerance",
           "perturbed_lengths", "lyapunov_estimate", "tolerance_figure", "TOLERANCE_KEYS"]

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


@dataclass(frozen=True)
class ToleranceSpec:
    """Manufacturing errors and acceptance limits (lengths in mm).

    Attributes
    ----------
    scale : float
        mm per design unit (default: the laser settings' scale).
    length_sigma : float
        Standard deviation of each bar's hole-to-hole length (default 0.05 mm).
    kerf_sigma : float
        Standard deviation of the kerf, i.e. of each hole's diameter (default 0.03 mm).
    hole_clearance : float
        Hole diameter minus barrel diameter (default: from the screw, 4.2 - 4.0 = 0.2 mm).
    thickness, thickness_sigma : float
        Sheet thickness and its build-to-build standard deviation (default 3.0 and 0.15 mm).
    limit : float or None
        Allowed 95th-percentile error of every port distance at the target (mm); None: 1 % of
        the mean port distance.
    min_reached : float
        Fraction of builds that must reach the target (default 0.95).
    samples : int
        Number of simulated builds (default 200).
    seed : int
        Seed of the random numbers (same seed, same result).
    """

    scale: float = 50.0
    length_sigma: float = 0.05
    kerf_sigma: float = 0.03
    hole_clearance: float = 0.2
    thickness: float = 3.0
    thickness_sigma: float = 0.15
    limit: float | None = None
    min_reached: float = 0.95
    samples: int = 200
    seed: int = 0


TOLERANCE_KEYS = {f.name for f in fields(ToleranceSpec)}
_NON_NEGATIVE = ("length_sigma", "kerf_sigma", "hole_clearance", "thickness_sigma")
_POSITIVE = ("scale", "thickness", "limit")


def _laser_defaults(design, settings) -> dict:
    """Scale, thickness and hole clearance from the laser settings, when that stage exists."""
    from .errors import FabricationError

    try:
        from .fab.laser import laser_settings
    except ImportError:
        return {}
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


def tolerance_spec(design, settings=None, **overrides) -> ToleranceSpec:
    """The tolerance settings of a design: defaults < laser settings < the template's
    ``[fabrication.tolerance]`` table < ``settings["tolerance"]`` (command line) < ``overrides``.

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
        Unknown key, wrong type, or a negative or zero value, naming
        ``fabrication.tolerance.<key>``.
    TemplateError
        Invalid laser settings (they give the scale and the thickness), as
        ``fabrication.laser: <reason>``.

    Examples
    --------
    >>> from fabkit.templates import parse_template
    >>> d = parse_template('[network]\\nnodes=[[0,0],[1,0],[0,1],[1,1]]\\n'
    ...                    'edges=[[0,1],[0,2],[1,3],[2,3]]\\nports={d1=[0,3]}\\n'
    ...                    '[fabrication.tolerance]\\nscale=20\\nsamples=10')
    >>> tolerance_spec(d).scale, tolerance_spec(d, samples=5).samples
    (20.0, 5)
    """
    path = design.path or design.name
    values: dict = {}
    values.update(_laser_defaults(design, settings))
    table = design.fabrication.get("tolerance", {}) if isinstance(design.fabrication, dict) else {}
    cli = (settings or {}).get("tolerance", {})
    for where, source in (("fabrication.tolerance", table), ("--set tolerance", cli),
                          ("tolerance option", overrides)):
        if not isinstance(source, dict):
            raise TemplateError(path, where, "must be a table of tolerance settings")
        for key, value in source.items():
            full = f"{where}.{key}"
            if key not in TOLERANCE_KEYS:
                raise TemplateError(path, full, "unknown key; allowed keys here: "
                                                + ", ".join(sorted(TOLERANCE_KEYS)))
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
            if key == "min_reached" and not 0 <= value <= 1:
                raise TemplateError(path, full, f"must be a fraction in 0..1, got {value}")
            values[key] = float(value)
    return ToleranceSpec(**values)


def perturbed_lengths(lengths, spec: ToleranceSpec, rng) -> tuple[np.ndarray, np.ndarray]:
    """Sample the edge lengths of ``spec.samples`` builds.

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
    m, e = spec.samples, L.size
    L_mm = L * spec.scale
    t = np.maximum(spec.thickness + spec.thickness_sigma * rng.standard_normal(m),
                   0.1 * spec.thickness)
    length_err = spec.length_sigma * rng.standard_normal((m, e))
    clearance = np.maximum(spec.hole_clearance + spec.kerf_sigma * rng.standard_normal((m, e, 2)),
                           0.0)
    # barrel position in each hole: uniform over the disc of radius clearance / 2
    radius = 0.5 * clearance * np.sqrt(rng.random((m, e, 2)))
    along = radius * np.cos(2.0 * np.pi * rng.random((m, e, 2)))
    play = along[..., 1] - along[..., 0]
    # tilt in the holes, bounded by the tighter hole of the bar
    tilt = np.arctan(clearance.min(axis=2) / t[:, None]) * rng.random((m, e))
    shortening = L_mm[None, :] * (1.0 - np.cos(tilt))
    built = L[None, :] + (length_err + play - shortening) / spec.scale
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
        out = {
            "method": self.method,
            "samples": int(self.reached.size),
            "reached_fraction": self.reached_fraction,
            "length_rms_mm": self.length_rms,
            "ports": ports,
            "flagged": self.flagged,
            "verdict": self.verdict,
            "horizon": self.horizon,
            "end_nodes": list(self.end_nodes),
            "seed": self.spec.seed,
            "min_reached": self.spec.min_reached,
            "scale_mm": self.spec.scale,
            **{f"{k}_mm": getattr(self.spec, k) for k in ("length_sigma", "kerf_sigma",
                                                           "hole_clearance", "thickness",
                                                           "thickness_sigma", "limit")},
        }
        if self.end_offsets is not None and self.reached.any():
            r = np.linalg.norm(self.end_offsets[self.reached], axis=-1) * self.spec.scale
            out["end_position_p95_mm"] = float(np.percentile(r, 95))
            out["end_position_max_mm"] = float(r.max())
        out.update(self.extra)
        return out


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


def _realise(net, lengths, x0, iters=30) -> np.ndarray | None:
    """Node positions near ``x0`` with the given edge lengths (minimum-norm Gauss-Newton)."""
    from scipy.sparse.linalg import lsqr

    from .rigidity import rigidity_matrix

    x = np.array(x0, dtype=np.float64)
    i, j = net.edges[:, 0], net.edges[:, 1]
    for _ in range(iters):
        d = np.linalg.norm(x[i] - x[j], axis=1)
        res = d - lengths
        if np.max(np.abs(res) / lengths) < 1e-12:
            return x
        r = rigidity_matrix(net, x, normalized=True)
        step = lsqr(r, -res, atol=1e-14, btol=1e-14)[0]
        x = x + step.reshape(x.shape)
    d = np.linalg.norm(x[i] - x[j], axis=1)
    return x if np.max(np.abs(d - lengths) / lengths) < 1e-9 else None


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
    from .errors import ConstructionError
    from .kinematics import make_problem, place, plan_construction

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
        h = 1e-6 * to
        X, margin, _ = place(plan, [to - h, to + h])
        if (margin < 0).any():
            return None
        d = np.linalg.norm(X[:, pairs[:, 0]] - X[:, pairs[:, 1]], axis=-1)  # (2, K)
        gains = (d[1] - d[0]) / (2 * h)
        slopes = np.abs(gains[1:] / np.where(gains[:-1] == 0, np.finfo(float).tiny, gains[:-1]))
        logs = np.log(np.maximum(slopes, SLOPE_FLOOR))
        return {"lyapunov": float(np.mean(logs)), "source": "chain gains",
                "steps": int(logs.size), "local": logs.tolist()}
    # a single module: iterate d2 = f(d1) for a bundle of orbits started next to the target,
    # all at once; derivatives by central differences; the first steps are a transient
    d = to * (1.0 + 1e-3 * np.linspace(-1.0, 1.0, orbits))
    alive = np.ones(orbits, dtype=bool)
    logs = np.full((iterations, orbits), np.nan)
    steps = 0
    for it in range(iterations):
        h = 1e-7 * d
        X, margin, _ = place(plan, np.concatenate([d - h, d, d + h]))
        out = np.linalg.norm(X[:, pairs[1, 0]] - X[:, pairs[1, 1]], axis=-1).reshape(3, orbits)
        alive &= (margin.reshape(3, orbits) >= 0).all(axis=0)
        if not alive.any():
            break
        slope = np.abs(out[2] - out[0]) / (2 * h)
        # slopes below the finite-difference resolution count as that resolution (a
        # super-stable point would otherwise give log 0 = -inf)
        logs[it] = np.where(alive, np.log(np.maximum(slope, SLOPE_FLOOR)), np.nan)
        d = np.where(alive, out[1], d)
        steps = it + 1
    if steps == 0:
        return None
    skip = min(transient, steps // 2)
    kept = logs[skip:steps][:, alive] if alive.any() else logs[:steps]
    kept = kept[np.isfinite(kept)]
    return {"lyapunov": float(kept.mean()), "source": "iterated module map",
            "steps": int(steps), "orbits": int(alive.sum()), "transient": int(skip)}


def analyse_tolerance(design, spec: ToleranceSpec | None = None, *, trajectory=None,
                      grid: int = 41) -> ToleranceResult:
    """Monte Carlo of built copies of a design driven to its target (see the module docstring).

    Parameters
    ----------
    design : Design
        With ``motion.to`` set.
    spec : ToleranceSpec, optional
        Default: :func:`tolerance_spec` of the design.
    trajectory : Trajectory, optional
        The nominal motion (traced when not given); only its success is used.
    grid : int
        Drive values checked between the start and the target for every build.

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
    >>> d = load_template(Path(__file__).parents[1] / "templates" / "fourbar.toml")
    >>> res = analyse_tolerance(d, tolerance_spec(d, samples=50))
    >>> res.reached_fraction, res.flagged
    (1.0, False)
    """
    from .errors import ConstructionError
    from .kinematics import make_problem, place, plan_construction

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
    ref_dir = (problem.start[b] - problem.start[a])[:2]
    rng = np.random.default_rng(spec.seed)
    end_nodes = sorted(set(pairs[len([p for p in ports if re.fullmatch(r"d\d+", p)]) - 1].tolist()))

    try:
        plan = plan_construction(problem.work, problem.drive, problem.start)
    except ConstructionError:
        plan = None

    if plan is not None:
        method = "constructive"
        built, _ = perturbed_lengths(net.edge_lengths, spec, rng)
        n_virtual = problem.work.n_edges - net.n_edges
        work_lengths = np.concatenate(
            [built, np.broadcast_to(problem.work.edge_lengths[net.n_edges:],
                                    (spec.samples, n_virtual))], axis=1)
        eidx = _plan_edge_index(plan, problem.work)
        values = np.linspace(problem.start_drive, m.to, grid)
        nominal_x = place(plan, [m.to])[0][0]
        final = np.empty((spec.samples,) + nominal_x.shape)
        reached = np.empty(spec.samples, dtype=bool)
        radii_ok = eidx >= 0
        for s in range(spec.samples):  # builds differ in every radius: one placement each
            radii = np.where(radii_ok, work_lengths[s][np.maximum(eidx, 0)], 0.0)
            X, margin, _ = place(replace(plan, radii=radii), values)
            reached[s] = bool((margin[1:] >= 0).all())
            final[s] = X[-1]
        # redundant edges (self-stress) are not used by the construction: a build that cannot
        # close them does not assemble
        used = np.zeros(problem.work.n_edges, dtype=bool)
        used[eidx[radii_ok]] = True
        unused = np.flatnonzero(~used[:net.n_edges])
        moving = reached.copy()
        if unused.size:
            i, j = net.edges[unused, 0], net.edges[unused, 1]
            got = np.linalg.norm(final[:, i] - final[:, j], axis=-1)
            reached &= (np.abs(got - built[:, unused]).max(axis=1) * spec.scale
                        <= 2 * spec.hole_clearance + 1e-9)
        unclosed = int((moving & ~reached).sum())
        nominal = np.linalg.norm(nominal_x[pairs[:, 0]] - nominal_x[pairs[:, 1]], axis=-1)
        dist = np.linalg.norm(final[:, pairs[:, 0]] - final[:, pairs[:, 1]], axis=-1)
        dist[~reached] = np.nan
        framed = _to_drive_frame(final, a, b, ref_dir)
        nominal_framed = _to_drive_frame(nominal_x[None], a, b, ref_dir)[0]
        end_offsets = framed[:, end_nodes] - nominal_framed[None, end_nodes]
    else:
        from .kinematics import trace

        method = "projected"
        unclosed = 0
        spec = replace(spec, samples=min(spec.samples, PROJECTED_SAMPLES_CAP))
        built, _ = perturbed_lengths(net.edge_lengths, spec, rng)
        nominal_x = trajectory.final
        nominal = np.linalg.norm(nominal_x[pairs[:, 0]] - nominal_x[pairs[:, 1]], axis=-1)
        dist = np.full((spec.samples, len(ports)), np.nan)
        reached = np.zeros(spec.samples, dtype=bool)
        for s in range(spec.samples):
            x = _realise(net, built[s], net.nodes)
            if x is None:
                continue
            try:
                tr = trace(net.with_nodes(x), drive=m.drive, to=m.to, method="projected",
                           hold=m.hold)
            except (KinematicsError, FabkitError):
                continue
            if tr.success:
                reached[s] = True
                dist[s] = np.linalg.norm(tr.final[pairs[:, 0]] - tr.final[pairs[:, 1]], axis=-1)
        end_offsets = None

    length_rms = float(np.sqrt(np.mean((built - net.edge_lengths[None, :]) ** 2)) * spec.scale)
    size_mm = float(np.mean(nominal)) * spec.scale
    limit_mm = spec.limit if spec.limit is not None else 0.01 * size_mm
    limits = np.full(len(ports), limit_mm)

    # predictability horizon of chains: error e^{λk} reaches the module size
    horizon = None
    lyap = lyapunov_estimate(design, plan) if plan is not None else None
    if lyap is not None:
        lam = lyap["lyapunov"]
        eps = max(length_rms, 1e-12)
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

    res = ToleranceResult(spec=spec, method=method, ports=ports, nominal=nominal, distances=dist,
                          reached=reached, end_nodes=end_nodes, end_offsets=end_offsets,
                          length_rms=length_rms, limits=limits, horizon=horizon, flagged=False,
                          verdict="", extra={"drive": m.drive, "target": float(m.to),
                                             "unclosed": unclosed})
    err = res.port_errors_mm()
    p95 = np.percentile(err, 95, axis=0) if err.shape[0] else np.full(len(ports), np.inf)
    worst = int(np.argmax(p95 / limits))
    if res.reached_fraction < spec.min_reached:
        flagged = True
        stuck = int((~reached).sum()) - unclosed
        why = []
        if stuck:
            why.append(f"{stuck} stop at a turning point before the target")
        if unclosed:
            why.append(f"{unclosed} cannot close their redundant bars (states of self-stress) "
                       "within the joint play")
        verdict = (f"FLAG: only {100 * res.reached_fraction:.1f}% of builds reach "
                   f"{m.drive} = {m.to:.6g} (need {100 * spec.min_reached:.0f}%): "
                   + "; ".join(why))
    elif p95[worst] > limits[worst]:
        flagged = True
        verdict = (f"FLAG: {ports[worst]} is off by up to {p95[worst]:.3g} mm (95% of builds), "
                   f"more than the {limits[worst]:.3g} mm allowed")
    else:
        flagged = False
        verdict = (f"ok: {100 * res.reached_fraction:.1f}% of builds reach the target; every port "
                   f"within {limits[worst]:.3g} mm (worst {ports[worst]}: {p95[worst]:.3g} mm, "
                   "95% of builds)")
    return replace(res, flagged=flagged, verdict=verdict)


def tolerance_figure(result: ToleranceResult, *, title: str | None = None):
    """Three panels: error of the last chain port, error growth along the chain, end positions.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from .viz import _mpl

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
        p95 = np.maximum(np.percentile(err[:, along], 95, axis=0), 1e-12)
        ax.semilogy(k, p95, "o-", label="95% |error|")
        ax.semilogy(k, np.maximum(err[:, along].mean(axis=0), 1e-12), "s:", label="mean |error|")
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
