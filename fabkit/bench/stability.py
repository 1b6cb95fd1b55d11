"""Stability study: what each tracing method does where methods fail.

Each :class:`Case` is a network, a drive and a target whose true outcome is known from
construction: either the motion reaches the target (``expect="finish"``) or no motion on the
start's branch does, and a correct method stops and says why (``expect="stop"``, at
``stop_drive`` when the place is known). Every method traces every case; :func:`classify` turns
the outcome and its evidence (largest relative edge error, largest distance to the constructive
reference, where it stopped) into one of :data:`CLASSES`.

The chaotic chain also gets a predictability horizon (:func:`predictability_horizon`): after how
many modules float64 map iteration, ``constructive`` and ``projected`` no longer agree with the
true distances, computed by constructive placement in 60-digit decimal arithmetic, compared with
the growth ``e^{λk}`` expected from the Lyapunov exponent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from decimal import Decimal, localcontext

import numpy as np

from ..design.assemble import branch, chain
from ..errors import FabkitError
from ..kinematics import align_to_gauge, METHODS, place, trace
from ..model.rigidity import count_modes
from ..plots.viz import figure_kit
from . import ModuleMap, paper_module
from .workprecision import collapsed_fixed_point
from ..model.network import is_chain_port

__all__ = [
    "CLASSES",
    "and_gate",
    "failure_figure",
    "Case",
    "classify",
    "stability_cases",
    "run_case",
    "stability_study",
    "study_methods",
    "stability_table",
    "predictability_horizon",
    "decimal_map",
]

FINISHED = "finished correctly"
STOPPED_OK = "stopped with a correct report"
WRONG_BRANCH = "wrong branch"
DIVERGED = "diverged"
INACCURATE = "silently inaccurate"
NO_CAUSE = "stopped without cause"
MISPLACED = "stopped at the wrong place"
CRASHED = "crashed"

#: Outcome classes, best first. The first five are the issue's; the last three name what else
#: was seen: a stop where the motion goes on, a stop far from the true end, and an exception that
#: is not a fabkit error (a bug).
CLASSES = (FINISHED, STOPPED_OK, WRONG_BRANCH, DIVERGED, INACCURATE, NO_CAUSE, MISPLACED, CRASHED)

#: Methods and options of the study (the paper's RK4 at a moderate step). Registered methods
#: not listed here are run with their defaults.
METHOD_OPTIONS = {
    "constructive": {},
    "projected": {},
    "rk4-nullspace": {"step": 0.02},
}


#: The super-stable chain is driven this far past D2* (the front then crosses ~10 modules).
SUPER_STABLE_PAST = 1e-6
#: The super-unstable 4-bars are driven this far past D1* = 1 (their flat state).
SUPER_UNSTABLE_PAST = 1e-9
#: The AND gate's branch is driven this far past D2*: the collapse would cross every module.
AND_GATE_PAST = 1e-12
#: The chaotic chain's d1 moves by this much: enough to cross ~30 modules' amplification.
CHAOTIC_MOVE = 1e-5
#: Step of the reference's central differences for the orbit's Lyapunov exponent (ModuleMap is
#: the independent reference, so it does not use the exact derivatives it checks).
REFERENCE_DIFF_STEP = 1e-7
#: Floors of log-scale plots (an exact zero has no logarithm): edge errors, and errors against
#: the 60-digit reference.
LOG_FLOOR = 1e-17
LOG_FLOOR_ERROR = 1e-18


def study_methods() -> dict:
    """Every registered tracing method with the options the study uses."""
    return {name: dict(METHOD_OPTIONS.get(name, {})) for name in METHODS}


@dataclass
class Case:
    """A situation where methods may fail, with its known true outcome.

    Attributes
    ----------
    name, title : str
    network : Network
    to : float
        Target of the drive d1.
    expect : str
        ``"finish"`` or ``"stop"``.
    stop_drive : float or None
        Where a correct stop happens (None: anywhere is correct, e.g. a singular start).
    fmap : ModuleMap or None
        Map of the module the network is a chain of (the reference), None when there is none.
    modules : int
        Number of modules (ports d1 … d{modules+1}).
    hold : tuple of str
    tol_ref : float
        Largest deviation from the reference (design units) of a correct trace.
    tol_stop : float
        Largest relative distance of a correct stop from ``stop_drive``.
    expect_by_method : dict
        Method name → expected outcome where it differs from ``expect`` (a method that switches
        branches at a bifurcation may correctly finish on the branch it names).
    note : str
        Why the case is hard and what the truth is.
    plot_port : str
        Port plotted against the drive in the failure-cases figure.
    """

    name: str
    title: str
    network: object
    to: float
    expect: str
    stop_drive: float | None = None
    fmap: ModuleMap | None = None
    modules: int = 1
    hold: tuple = ()
    tol_ref: float = 1e-9
    tol_stop: float = 1e-4
    expect_by_method: dict = field(default_factory=dict)
    note: str = ""
    plot_port: str = "d2"
    facts: dict = field(default_factory=dict)


def classify(expect: str, status: str, *, edge_error=None, ref_error=None, stop_error=None,
             tol_edge: float = 1e-9, tol_ref: float = 1e-9, tol_stop: float = 1e-4,
             diverge: float = 1e-3, branch: float = 1e-2) -> str:
    """Class of one outcome (one of :data:`CLASSES`).

    Parameters
    ----------
    expect : str
        ``"finish"`` or ``"stop"``: the true outcome.
    status : str
        The trace's status (``finished``, ``turning_point``, ``branch_point``, ``failed``),
        ``"raised"`` for a fabkit error raised instead of a result, ``"crashed"`` for any other
        exception.
    edge_error : float or None
        Largest relative edge-length error of the trace.
    ref_error : float or None
        Largest distance of the port distances from the constructive reference (design units).
    stop_error : float or None
        Distance of the stopping drive value from the true end of the motion (None when the
        place of the stop does not matter or is unknown).
    tol_edge, tol_ref, tol_stop : float
        What a correct trace keeps to.
    diverge : float
        Edge error beyond which the trace has diverged (bars broken).
    branch : float
        Reference deviation beyond which the trace is on another branch.

    Examples
    --------
    >>> classify("stop", "turning_point", edge_error=1e-15, stop_error=0.0)
    'stopped with a correct report'
    >>> classify("finish", "finished", edge_error=3e-7, ref_error=1e-10)
    'silently inaccurate'
    >>> classify("stop", "finished", edge_error=0.25)
    'diverged'
    """
    if status == "crashed":
        return CRASHED
    bad_edges = edge_error is not None and not (edge_error <= diverge)  # NaN counts as diverged
    if bad_edges:
        return DIVERGED
    far = ref_error is not None and not (ref_error <= branch)
    if status == "finished":
        if expect == "stop" or far:
            return WRONG_BRANCH
        if (edge_error is not None and edge_error > tol_edge) or (
                ref_error is not None and ref_error > tol_ref):
            return INACCURATE
        return FINISHED
    # stopped: a status other than finished, or a raised fabkit error
    if expect == "finish":
        return NO_CAUSE
    if far:
        return WRONG_BRANCH
    if stop_error is not None and not (stop_error <= tol_stop):
        return MISPLACED
    return STOPPED_OK


# -- the cases ----------------------------------------------------------------------------------
def _domain_end(fmap: ModuleMap, inside: float, outside: float, iterations: int = 200) -> float:
    """Drive value where the module's construction ends (bisection on the map being defined)."""
    lo, hi = float(inside), float(outside)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if np.isfinite(fmap(np.array([mid]))[0]):
            lo = mid
        else:
            hi = mid
    return lo


def _module_at(name: str, d1: float, nodes=None):
    """The module moved along its motion to d1 (same branch), as a new reference."""
    mod = paper_module(name, nodes)
    x, margin, _ = place(ModuleMap(mod).plan, [d1])
    if margin[0] < 0:
        raise ValueError(f"module {name} has no configuration with d1 = {d1}")

    x = align_to_gauge(x, mod.nodes, (0, 1))[0]
    return paper_module(name, x)


def _physical_fourbar_at(d1: float):
    """The 4-bar of Fig. 5c opened to d1 (node 0 above the line of nodes 2 and 1)."""
    x2, x1 = np.zeros(2), np.array([2.0, 0.0])
    phi = math.acos((5.0 - d1 * d1) / 4.0)  # |x0 - x2| = 1, |x1 - x2| = 2
    x0 = np.array([math.cos(phi), math.sin(phi)])
    dv = x1 - x0
    dd = float(np.linalg.norm(dv))
    along = (1.0 - 3.0 + dd * dd) / (2.0 * dd)  # |x3 - x0| = 1, |x3 - x1| = sqrt(3)
    h = math.sqrt(1.0 - along * along)
    x3 = x0 + along * dv / dd + h * np.array([-dv[1], dv[0]]) / dd
    return paper_module("physical_fourbar", [x0, x1, x2, x3])


def and_gate(modules: int = 6):
    """Two super-stable chains, the far end of the first joined to the middle of the second.

    Built by :func:`fabkit.design.assemble.branch` (the second chain is the trunk, the first the
    limb).
    Ports: ``d1`` (first branch's input), ``b1`` (second branch's input), ``out`` (the second
    branch's far end), ``joint`` (the shared pair). Of the four ways to join (mirror, swap), the
    one that keeps the limb's nodes farthest from the trunk's is taken.
    """
    ss = paper_module("super_stable")
    trunk = chain(ss, modules)
    limb = chain(ss, modules)
    end, mid = f"d{modules + 1}", f"d{modules // 2 + 1}"
    best = None
    for swap in (False, True):
        for mirror in (False, True):
            net = branch(trunk, limb, at=mid, end=end, mirror=mirror, swap=swap)
            own = net.nodes[trunk.n_nodes:]
            gap = float(np.min(np.linalg.norm(own[:, None] - trunk.nodes[None], axis=-1)))
            if best is None or gap > best[0]:
                best = (gap, net)
    net = best[1]
    return net.with_ports({"d1": net.port("d1_b"), "b1": net.port("d1"), "out": net.port(end),
                           "joint": net.port(mid)})


def stability_cases(*, chaotic_modules: int = 30, super_stable_modules: int = 20) -> list[Case]:
    """The cases of the study (see the module docstring and docs/bench.md)."""
    cases = []
    fb = paper_module("fourbar")
    fmap = ModuleMap(fb)
    flat = _domain_end(fmap, 2.0, 0.5)
    cases.append(Case(
        "fourbar_flat", "4-bar driven into its flat state", fb, 0.5, "stop", flat, fmap, 1,
        note=f"d1 is smallest ({flat:.12g} = 2√2 - 2) when all four nodes are collinear; there "
             "the antiparallelogram meets the parallelogram branch. Past it no configuration "
             "exists on this branch.",
        facts={"flat_d1": flat}))

    sheet = paper_module("origami_sheet")
    cases.append(Case(
        "origami_flat", "flat origami sheet (a kinematic bifurcation)", sheet, 1.2, "stop",
        float(sheet.port_distance("d1")), None, 1, expect_by_method={"branch": "finish"},
        note="at the flat sheet the rigidity matrix has a state of self-stress and two "
             "conformational motions (the paper's fold and the fold along the diagonal crease): "
             "the drive alone does not say which way to fold. Tracing methods must stop and say "
             "so; the 'branch' method, made to leave singular states, may finish on a branch it "
             "names (no reference: judged by its edges).",
        facts={"modes": str(_modes(sheet))}))

    cc = paper_module("curvature_contract")
    cmap = ModuleMap(cc)
    d0 = float(cc.port_distance("d1"))
    low = _domain_end(cmap, d0, d0 - 0.01)
    cases.append(Case(
        "turning_point", "turning point of the drive next to the start (driven into it)", cc,
        d0 - 0.01, "stop", low, cmap, 1, tol_stop=1e-7,
        note=f"the curvature-contract module starts {d0 - low:.2e} above its smallest d1 "
             f"({low:.12g}); driven down it must stop there, not step across (a stop counts "
             "as correct within 1e-7, far closer than the start).",
        facts={"smallest_d1": low, "start_d1": d0}))
    cases.append(Case(
        "turning_point_away", "turning point next to the start (driven away from it)", cc,
        d0 + 0.3, "finish", None, cmap, 1,
        note="driven up from the same start the motion is regular: a method must neither refuse "
             "the start nor step backwards across the turning point."))

    ss = paper_module("super_stable")
    k = int(super_stable_modules)

    d2star = collapsed_fixed_point()
    cases.append(Case(
        "super_stable", f"super-stable fixed point ({k}-module chain collapsing)",
        chain(ss, k), d2star + SUPER_STABLE_PAST, "finish", None, ModuleMap(ss), k, tol_ref=1e-8,
        plot_port="d2",
        note=f"slope 0 at D1* = √3: motion localises super-exponentially; far modules stay "
             f"frozen to round-off while the collapse front (driven to D2* + 1e-6, "
             f"D2* = {d2star:.12g}) runs through about 10 modules. Near the unstable D2* "
             "(slope ≈ 4) round-off grows 4× per module (~1e-10 after 10), so 1e-8 is "
             "accepted.",
        facts={"D2*": d2star}))

    pf = _physical_fourbar_at(1.5)
    cases.append(Case(
        "super_unstable", "super-unstable fixed point (8 4-bars driven to 1e-9 above D1*)",
        chain(pf, 8), 1.0 + SUPER_UNSTABLE_PAST, "finish", None, ModuleMap(pf), 8, tol_ref=1e-6,
        plot_port="d3",
        note="the 4-bar of Fig. 5c has slope ∞ at D1* = 1 (flat): d2 - 1 ~ √(d1 - 1). Round-off "
             "in d1 is amplified by the slopes, so up to ~1e-8 deviation is correct; the chain "
             "converges to the stable D2*."))

    gate = and_gate(6)
    cases.append(Case(
        "self_stress", "state of self-stress: the AND gate (6 + 6 super-stable modules)", gate,
        d2star + AND_GATE_PAST, "stop", float(gate.port_distance("d1")), None, 1, plot_port="joint",
        note="joining the far end of one super-stable chain to the middle of another makes a "
             "state of self-stress and two conformational motions at the start; driving one "
             "branch alone does not determine the motion.",
        facts={"modes": str(_modes(gate))}))
    cases.append(Case(
        "self_stress_held", "AND gate with the other branch held", gate, d2star + AND_GATE_PAST, "stop",
        None, None, 1, hold=("b1",), plot_port="joint",
        note="with the second branch's input held, the shared pair cannot move, so the first "
             "branch cannot collapse fully: f^6(d1) = √3 only at d1 = √3 (f has an extremum "
             "there). Numerically it moves until d7 of the first branch must change; reaching "
             "the target requires breaking bars."))

    ch = _module_at("chaotic", 0.9)
    kc = int(chaotic_modules)
    cmap2 = ModuleMap(ch)
    cases.append(Case(
        "chaotic", f"chaotic chain ({kc} modules, d1 moved by 1e-5)", chain(ch, kc),
        0.9 + CHAOTIC_MOVE, "finish", None, cmap2, kc, tol_ref=1e-9, plot_port=f"d{kc + 1}",
        note="λ ≈ 0.31: round-off (in building the chain as well as in tracing it) grows "
             "as e^{0.31 k}; at 30 modules deviations up to ~1e-10 are round-off, so 1e-9 is "
             "accepted."))
    return cases


def _modes(net):
    return count_modes(net)


# -- running ------------------------------------------------------------------------------------
def _reference_deviation(case: Case, traj) -> np.ndarray | None:
    """Largest |d_k - f^{k-1}(d1)| over the chain's ports at each configuration, shape (S,)."""
    if case.fmap is None:
        return None
    ref = case.fmap.iterate(traj.drive, case.modules)
    got = np.array([traj.distance(f"d{c + 1}") for c in range(case.modules + 1)])
    dev = np.abs(got - ref)
    dev[~np.isfinite(dev)] = -1.0  # no reference beyond the end of the motion
    out = dev.max(axis=0)
    out[out < 0] = np.nan
    return out


def run_case(case: Case, method: str, options=None, *, budget: float = 60.0) -> dict:
    """Trace one case with one method (in a child process, stopped at ``budget`` seconds of CPU
    time) and classify.

    Returns
    -------
    dict
        ``case``, ``method``, ``options``, ``status``, ``message``, ``time_s`` (CPU seconds),
        ``wall_s`` (wall seconds), ``edge_error``,
        ``ref_error``, ``stop_drive``, ``stop_error``, ``class``, and ``drive``/``port`` arrays
        (the plotted distance along the trace, as lists).
    """
    from .workprecision import STOPPED, run_budgeted, timing

    options = dict(METHOD_OPTIONS.get(method, {}) if options is None else options)

    def work():
        try:
            return trace(case.network, "d1", to=case.to, method=method, hold=case.hold,
                         **options)
        except FabkitError as exc:
            return ("raised", f"{type(exc).__name__}: {exc}")
        except Exception as exc:  # a bug in a method is an outcome of the study, not a stop
            return ("crashed", f"{type(exc).__name__}: {exc}")

    def evaluate(res) -> dict:
        if isinstance(res, tuple):
            return {"status": res[0], "message": res[1], "edge_error": None, "ref_error": None,
                    "stop_drive": None, "drive": [], "port": []}
        dev = _reference_deviation(case, res)
        ref_error = (float(np.nanmax(dev)) if dev is not None and np.isfinite(dev).any()
                     else None)
        return {"status": str(res.status), "message": res.message,
                "edge_error": float(res.max_edge_error), "ref_error": ref_error,
                "stop_drive": float(res.drive[-1]), "drive": res.drive.tolist(),
                "port": res.distance(case.plot_port).tolist(), "steps": int(res.n_steps),
                "edge_errors": res.edge_error.tolist(),
                "deviations": None if dev is None else dev.tolist()}

    outcome, times, info = run_budgeted(work, evaluate, budget, repeats=1)
    row = {"case": case.name, "method": method, "options": options, **timing(times, info)}
    if outcome == "ok":
        row.update(info)
    elif outcome == STOPPED:
        row.update(status="stopped at budget", message=info, edge_error=None, ref_error=None,
                   stop_drive=None, drive=[], port=[])
    else:
        row.update(status="crashed", message=info, edge_error=None, ref_error=None,
                   stop_drive=None, drive=[], port=[])
    expect = case.expect_by_method.get(method, case.expect)
    row["expect"] = expect
    stop_error = None
    if (expect == "stop" and case.stop_drive is not None and row["stop_drive"] is not None
            and row["status"] != "finished"):
        stop_error = abs(row["stop_drive"] - case.stop_drive) / max(abs(case.stop_drive), 1.0)
    row["stop_error"] = stop_error
    status = row["status"] if row["status"] != "stopped at budget" else "failed"
    row["class"] = classify(expect, status, edge_error=row["edge_error"],
                            ref_error=row["ref_error"], stop_error=stop_error,
                            tol_ref=case.tol_ref, tol_stop=case.tol_stop)
    return row


def stability_study(methods=None, *, budget: float = 60.0, cases=None, progress=None) -> dict:
    """Every method on every case.

    ``methods``: names (each with the study's options), a dict name → options, or None for
    every registered method (:func:`study_methods`).

    Returns
    -------
    dict
        ``cases``: [{name, title, expect, stop_drive, note, facts, reference (drive, port)
        arrays for the figure}], ``rows``: one :func:`run_case` dict per case and method.
    """
    methods = study_methods() if methods is None else (
        dict(methods) if isinstance(methods, dict) else {m: None for m in methods})
    cases = stability_cases() if cases is None else cases
    rows, meta = [], []
    for case in cases:
        ref = None
        port = case.plot_port
        if case.fmap is not None and is_chain_port(port):
            kk = int(case.plot_port[1:]) - 1
            d0 = float(case.network.port_distance("d1"))
            grid = np.linspace(d0, case.to, 400)
            ref = [grid.tolist(), case.fmap.iterate(grid, kk)[-1].tolist()]
        meta.append({"name": case.name, "title": case.title, "expect": case.expect,
                     "stop_drive": case.stop_drive, "note": case.note,
                     "facts": {k: (v if isinstance(v, (int, float, str)) else str(v))
                               for k, v in case.facts.items()},
                     "tol_ref": case.tol_ref, "plot_port": case.plot_port, "reference": ref,
                     "modules": case.modules, "to": case.to,
                     "start": float(case.network.port_distance("d1"))})
        for m, opts in methods.items():
            row = run_case(case, m, opts, budget=budget)
            rows.append(row)
            if progress is not None:
                progress(row)
    return {"cases": meta, "rows": rows}


def _fmt(v, spec=".1e"):
    return "–" if v is None else format(v, spec)


def stability_table(study: dict) -> str:
    """The study as a Markdown table: one row per case and method, with the evidence."""
    lines = ["| case | method | outcome | status | edge error | ref. deviation | stop at "
             "(true) | CPU s (wall s) |",
             "|---|---|---|---|---|---|---|---|"]
    by_name = {c["name"]: c for c in study["cases"]}
    for r in study["rows"]:
        c = by_name[r["case"]]
        expect = r.get("expect", c["expect"])
        true_stop = ("anywhere" if expect == "stop" and c["stop_drive"] is None else
                     _fmt(c["stop_drive"], ".10g") if expect == "stop" else "–")
        at = _fmt(r.get("stop_drive"), ".10g") if r["status"] != "finished" else "–"
        lines.append(
            f"| {c['name']} | {r['method']} | **{r['class']}** | {r['status']} | "
            f"{_fmt(r['edge_error'])} | {_fmt(r['ref_error'])} | {at} ({true_stop}) | "
            f"{_fmt(r['time_s'], '.3g')} ({_fmt(r.get('wall_s'), '.3g')}) |")
    lines.append("")
    lines.append("Messages:")
    lines.append("")
    for r in study["rows"]:
        msg = " ".join(str(r["message"]).split())
        lines.append(f"- {r['case']} / {r['method']}: {msg[:300]}")
    lines.append("")
    lines.append("Cases:")
    lines.append("")
    for c in study["cases"]:
        lines.append(f"- **{c['name']}** ({c['title']}; expected: {c['expect']}): {c['note']}")
    return "\n".join(lines) + "\n"


# -- predictability horizon of the chaotic chain -------------------------------------------------
def decimal_map(fmap: ModuleMap, d1, k: int, digits: int = 60) -> np.ndarray:
    """The distances d_1 … d_{k+1} of a chain by constructive placement in decimal arithmetic.

    The module's edge lengths (float64 numbers) are taken as exact; ``digits`` significant digits
    carry the round-off far below float64 for ``k`` up to several hundred modules of a map with
    λ ≈ 0.3. 2D modules only.

    Returns
    -------
    numpy.ndarray, shape (k + 1,)
        The true distances rounded to float64.
    """
    plan = fmap.plan
    if plan.dim != 2:
        raise ValueError("decimal_map handles 2D modules")
    ref = plan.reference
    a, b = plan.seed
    out_i, out_j = fmap.out
    with localcontext() as ctx:
        ctx.prec = int(digits)
        ua = [Decimal(float(v)) for v in ref[a]]
        ub = [Decimal(float(v)) for v in ref[b]]
        ux, uy = ub[0] - ua[0], ub[1] - ua[1]
        un = (ux * ux + uy * uy).sqrt()
        ux, uy = ux / un, uy / un
        radii = [[Decimal(float(r)) for r in row] for row in plan.radii]
        d = Decimal(float(d1))
        out = [float(d)]
        for _ in range(int(k)):
            pos = {a: (ua[0], ua[1]), b: (ua[0] + d * ux, ua[1] + d * uy)}
            for idx, v in enumerate(plan.order.tolist()):
                p, q = (int(w) for w in plan.parents[idx])
                r0, r1 = radii[idx]
                px, py = pos[p]
                dx, dy = pos[q][0] - px, pos[q][1] - py
                dist2 = dx * dx + dy * dy
                dist = dist2.sqrt()
                along = (r0 * r0 - r1 * r1 + dist2) / (2 * dist)
                h2 = r0 * r0 - along * along
                if h2 < 0:
                    return np.array(out + [math.nan] * (int(k) + 1 - len(out)))
                h = h2.sqrt() * int(plan.signs[idx])
                pos[v] = (px + along / dist * dx - h / dist * dy,
                          py + along / dist * dy + h / dist * dx)
            ex = pos[out_i][0] - pos[out_j][0]
            ey = pos[out_i][1] - pos[out_j][1]
            d = (ex * ex + ey * ey).sqrt()
            out.append(float(d))
    return np.array(out)


def predictability_horizon(k: int = 200, *, d1: float = 0.9, delta: float = 1e-8,
                           projected_modules: int = 60, threshold: float = 1e-2,
                           budget: float = 120.0) -> dict:
    """After how many modules float64 methods lose the chaotic chain.

    The chain of ``k`` chaotic modules is built at ``d1`` and driven to ``d1 + delta``. The true
    distances at the target come from :func:`decimal_map`. Map iteration and ``constructive``
    are evaluated on all k modules; ``projected`` traces a chain of ``projected_modules``
    (beyond about ``ln(1/delta)/λ`` modules the motion of the far end is too large to follow
    for any tracer), and its horizon is extrapolated from the fitted growth.

    Returns
    -------
    dict
        ``lyapunov_orbit`` (mean log-slope along the true orbit), per method ``error`` (list over
        modules), ``horizon`` (first module where the error exceeds ``threshold``, or the
        extrapolated one with ``extrapolated: true``), ``growth_rate`` (fitted slope of log
        error), and the pairwise disagreement horizons.
    """
    from .workprecision import run_budgeted

    module = _module_at("chaotic", d1)
    fmap = ModuleMap(module)
    target = d1 + delta
    truth = decimal_map(fmap, target, k)
    orbit = truth[:-1]
    hstep = REFERENCE_DIFF_STEP
    slope = (fmap(orbit + hstep) - fmap(orbit - hstep)) / (2 * hstep)
    lam = float(np.mean(np.log(np.abs(slope))))
    eps = np.finfo(float).eps

    series = {"map": fmap.iterate([target], k)[:, 0]}
    net = chain(module, k)
    outcome, _, info = run_budgeted(
        lambda: trace(net, "d1", to=target, method="constructive", samples=2),
        lambda tr: [float(v) for v in (tr.distance(f"d{c + 1}")[-1] for c in range(k + 1))],
        budget, repeats=1)
    if outcome == "ok":
        series["constructive"] = np.array(info)
    kp = int(projected_modules)
    net_p = chain(module, kp)
    outcome, _, info = run_budgeted(
        lambda: trace(net_p, "d1", to=target, method="projected"),
        lambda tr: ([float(v) for v in (tr.distance(f"d{c + 1}")[-1] for c in range(kp + 1))]
                    if tr.success else None),
        budget, repeats=1)
    if outcome == "ok" and info is not None:
        series["projected"] = np.array(info)

    result = {"modules": int(k), "d1": d1, "delta": delta, "threshold": threshold,
              "lyapunov_orbit": lam, "truth": truth.tolist(), "methods": {}}
    for name, vals in series.items():
        err = np.abs(vals - truth[:vals.size])
        result["methods"][name] = _horizon_of(err, lam, eps, threshold)
    names = list(series)
    pairs = {}
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            a, b = series[names[i]], series[names[j]]
            m = min(a.size, b.size)
            dis = np.abs(a[:m] - b[:m])
            pairs[f"{names[i]} vs {names[j]}"] = _horizon_of(dis, lam, eps, threshold)
    result["pairs"] = pairs
    result["expected_horizon"] = float(math.log(threshold / eps) / lam) if lam > 0 else None
    return result


def _horizon_of(err: np.ndarray, lam: float, eps: float, threshold: float) -> dict:
    """First module index where ``err`` exceeds the threshold; else extrapolate the fitted
    exponential growth of the error (fitted where it is above 100 ulp and below the threshold)."""
    err = np.asarray(err, dtype=np.float64)
    over = np.flatnonzero(~(err <= threshold))
    kk = np.arange(err.size)
    grow = (err > 100 * eps) & (err < threshold)
    rate = None
    if grow.sum() >= 5:
        rate, icpt = np.polyfit(kk[grow], np.log(err[grow]), 1)
        rate = float(rate)
    out = {"error": [float(v) for v in err], "growth_rate": rate, "extrapolated": False,
           "horizon": int(over[0]) if over.size else None}
    if out["horizon"] is None and rate is not None and rate > 0:
        out["horizon"] = float((math.log(threshold) - icpt) / rate)
        out["extrapolated"] = True
    return out


# -- figure ---------------------------------------------------------------------------------------
_COLORS = {"constructive": "C0", "projected": "C2", "rk4-nullspace": "C3", "map": "C1",
           "branch": "C4"}


def failure_figure(study: dict, horizon: dict | None = None):
    """One panel per case and one for the predictability horizon.

    A case's panel shows, against the drive, each method's largest deviation of the port
    distances from the iterated map (solid; cases with a reference) and its largest relative
    edge error (dotted); a cross marks where a method stopped; the legend gives its class.

    Returns
    -------
    matplotlib.figure.Figure
    """

    cases = study["cases"]
    n = len(cases) + (1 if horizon else 0)
    cols = 3
    rows = int(math.ceil(n / cols))
    fig, axes = figure_kit.subplots(rows, cols, figsize=(5.2 * cols, 3.6 * rows), squeeze=False)
    flat_axes = axes.ravel()
    floor = LOG_FLOOR
    for ax, c in zip(flat_axes, cases):
        for r in (r for r in study["rows"] if r["case"] == c["name"]):
            col = _COLORS.get(r["method"], "k")
            label = f"{r['method']}: {r['class']}"
            if r["drive"]:
                dev = r.get("deviations")
                if dev is not None:
                    y = np.maximum(np.asarray(dev, dtype=float), floor)
                    ax.semilogy(r["drive"], y, ".-", color=col, ms=3, lw=1, label=label)
                    ax.semilogy(r["drive"], np.maximum(r["edge_errors"], floor), ":", color=col,
                                lw=1)
                else:
                    y = np.maximum(np.asarray(r["edge_errors"], dtype=float), floor)
                    ax.semilogy(r["drive"], y, ":", marker=".", color=col, ms=3, lw=1,
                                label=label)
                if r["status"] != "finished":
                    ax.semilogy(r["drive"][-1], y[-1], "x", color=col, ms=9, mew=2)
            else:
                ax.semilogy([], [], "o", color=col, label=label + f" ({r['status']})")
        if c["expect"] == "stop" and c["stop_drive"] is not None:
            ax.axvline(c["stop_drive"], color="k", ls="--", lw=0.8, label="true end of motion")
        ax.set_title(c["title"], fontsize=9)
        ax.set_xlabel("d1 (drive)")
        ax.set_ylabel("deviation from map (solid), edge error (dotted)", fontsize=7)
        ax.set_ylim(floor / 2, 10)
        ax.legend(fontsize=6.5, loc="upper left")
    if horizon:
        ax = flat_axes[len(cases)]
        kk = np.arange(horizon["modules"] + 1)
        for name, h in horizon["methods"].items():
            err = np.maximum(np.asarray(h["error"], dtype=float), LOG_FLOOR_ERROR)
            hz = h["horizon"]
            tag = ("–" if hz is None else f"{hz:.0f}") + (" extrap." if h["extrapolated"] else "")
            ax.semilogy(kk[:err.size], err, ".", ms=3, color=_COLORS.get(name, "k"),
                        label=f"{name} vs exact (horizon {tag})")
        lam = horizon["lyapunov_orbit"]
        eps = np.finfo(float).eps
        ax.semilogy(kk, eps * np.exp(lam * kk), "k--", lw=1, label=f"ε·e^(λk), λ = {lam:.3f}")
        ax.axhline(horizon["threshold"], color="0.5", lw=0.8)
        ax.set_ylim(LOG_FLOOR_ERROR, 10)
        ax.set_xlabel("module k")
        ax.set_ylabel("|d_k - exact| (60-digit placement)")
        ax.set_title("chaotic chain: predictability horizon in float64", fontsize=9)
        ax.legend(fontsize=6.5, loc="lower right")
    for ax in flat_axes[n:]:
        ax.axis("off")
    fig.tight_layout()
    return fig
