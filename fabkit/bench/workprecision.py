"""Work-precision and scaling studies: what each tracing method costs for the accuracy it gives.

Every method traces the same chain of k copies of one of the paper's modules (the super-stable
module of Fig. 3e by default) over the same drive range, at several step sizes or tolerances. For
each run the study records the CPU time (median of repeats, single-threaded BLAS), the number of
configurations, the largest relative edge-length error, and the error of the chain's last
distance ``d_{k+1}`` against the exact reference: the module's map iterated k times
(:class:`fabkit.bench.ModuleMap`), evaluated at every drive value the trace visited.

Times are CPU seconds of the process that does the work (:func:`fabkit.bench.own_cpu_seconds`,
the figure of :func:`time.process_time`): what the work costs, the same on a quiet machine and
on a busy one, so that budgets, skips and targets do not pass or fail with the machine's load.
The wall time of the same work is recorded beside it (``wall_s``, ``wall_times``) for
information: what a user waited for that day.

Each run is made in a child process with a CPU budget, which the kernel enforces
(``RLIMIT_CPU``); a run that exceeds it is killed and marked ``"stopped at budget"``. Before a
run, its time is estimated from the smaller sizes (a power law through the last two); when the
estimate exceeds the budget the run is skipped and marked so (the dense ``rk4-nullspace`` grows
as about N^2.8 and would otherwise take hours).
"""

from __future__ import annotations

import math
import multiprocessing
import signal
import time
from dataclasses import dataclass, field

import numpy as np

from ..design.assemble import chain
from ..kinematics import trace
from ..kinematics.rk4_nullspace import conformational_velocity
from ..plots.viz import figure_kit
from . import ModuleMap, own_cpu_seconds, paper_module, single_thread_blas

__all__ = [
    "Setting",
    "FULL_SETTINGS",
    "QUICK_SETTINGS",
    "chain_problem",
    "collapsed_fixed_point",
    "run_budgeted",
    "timing",
    "measure",
    "work_precision",
    "fit_exponent",
    "scaling",
    "rk4_estimate",
    "lyapunov_protocol",
    "maps_lyapunov",
    "profile_method",
    "STOPPED",
    "SKIPPED",
    "BUDGET_SLACK",
    "WALL_FACTOR",
    "targets",
    "work_precision_figure",
    "scaling_figure",
]

STOPPED = "stopped at budget"
SKIPPED = "skipped: estimated over budget"
#: CPU seconds a run may use beyond its budget before the kernel stops it: the kernel's limit
#: (``RLIMIT_CPU``) counts whole seconds, so a run is stopped between ``budget + BUDGET_SLACK``
#: and one second more.
BUDGET_SLACK = 1.0
#: A run still going after this many times its CPU allowance (budget + :data:`BUDGET_SLACK`) in
#: wall time is stopped as well: it is waiting, not working (blocked, or starved on a machine
#: loaded more than this many times over), and no CPU limit would ever end it. Its message says
#: that the wall clock stopped it.
WALL_FACTOR = 10.0
# Exponent assumed for a method's first extrapolation, before two sizes are measured.
_PRIOR_EXPONENT = {"rk4-nullspace": 2.8}


#: The default target of the work-precision chain lies this far past the collapsed fixed point
#: D2* (as in templates/super_stable_chain.toml): the collapse crosses about 20 modules.
TARGET_PAST = 1e-12


@dataclass(frozen=True)
class Setting:
    """A method and its options (one point per chain size on the work-precision chart)."""

    method: str
    options: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        opts = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                         for k, v in sorted(self.options.items()))
        return f"{self.method} ({opts})" if opts else f"{self.method} (default)"


#: Settings of the full study, first one per method = the one used for the scaling chart.
FULL_SETTINGS = (
    Setting("map", {"samples": 101}),
    Setting("constructive", {"samples": 101}),
    Setting("constructive", {"samples": 11}),
    Setting("constructive", {"samples": 1001}),
    Setting("projected", {}),
    Setting("projected", {"max_step": 0.1}),
    Setting("projected", {"max_step": 0.02}),
    Setting("projected", {"tol": 1e-9}),
    Setting("rk4-nullspace", {"step": 0.05}),
    Setting("rk4-nullspace", {"step": 0.1}),
    Setting("rk4-nullspace", {"step": 0.02}),
    Setting("rk4-nullspace", {"step": 0.01}),
)

#: A subset for ``fabkit bench --quick``.
QUICK_SETTINGS = (
    Setting("map", {"samples": 101}),
    Setting("constructive", {"samples": 101}),
    Setting("constructive", {"samples": 11}),
    Setting("projected", {}),
    Setting("projected", {"max_step": 0.1}),
    Setting("rk4-nullspace", {"step": 0.05}),
    Setting("rk4-nullspace", {"step": 0.1}),
)


@dataclass
class ChainProblem:
    """A chain of ``k`` copies of a module, the drive range and the exact map reference."""

    module_name: str
    k: int
    network: object
    target: float
    fmap: ModuleMap

    @property
    def start(self) -> float:
        return float(self.network.port_distance("d1"))

    @property
    def last_port(self) -> str:
        return f"d{self.k + 1}"


def collapsed_fixed_point(module: str = "super_stable", bracket=(0.99, 1.2)) -> float:
    """The fixed point f(D) = D of a module's map inside ``bracket`` (bisection, to round-off).

    For the super-stable module this is its collapsed fixed point D2* = 1.00995049…, unstable
    (slope ≈ 4), where the chain's collapse ends.

    Examples
    --------
    >>> round(collapsed_fixed_point(), 10)
    1.0099504938
    """
    fmap = ModuleMap(paper_module(module))
    lo, hi = (float(v) for v in bracket)
    glo = float(fmap(np.array([lo]))[0]) - lo
    if not np.isfinite(glo) or glo * (float(fmap(np.array([hi]))[0]) - hi) > 0:
        raise ValueError(f"no single fixed point of {module} in {bracket}")
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        g = float(fmap(np.array([mid]))[0]) - mid
        if (g < 0) == (glo < 0):
            lo, glo = mid, g
        else:
            hi = mid
    return 0.5 * (lo + hi)


def chain_problem(k: int, module: str = "super_stable", target: float | None = None
                  ) -> ChainProblem:
    """Build the chain of ``k`` modules (ports d1 … d{k+1}) traced by the study.

    Parameters
    ----------
    k : int
        Number of modules.
    module : str
        A bundled module template name (default the super-stable module).
    target : float, optional
        Final value of the drive d1. Default for the super-stable module: 1e-12 above its
        collapsed fixed point D2* (:func:`collapsed_fixed_point`), so the collapse front runs
        through about 20 modules (the distance to D2* grows by the slope ≈ 4 per module): the
        whole soliton.
    """
    mod = paper_module(module)
    if target is None:
        if module != "super_stable":
            raise ValueError("give `target` for modules other than super_stable")
        target = default_chain_target()
    return ChainProblem(module, int(k), chain(mod, int(k)), float(target), ModuleMap(mod))


_TARGET_CACHE: list = []


def default_chain_target() -> float:
    """The drive's target of a super-stable chain: :data:`TARGET_PAST` above its collapsed
    fixed point (:func:`collapsed_fixed_point`, computed once per process).

    Returns
    -------
    float
    """
    if not _TARGET_CACHE:
        _TARGET_CACHE.append(collapsed_fixed_point() + TARGET_PAST)
    return _TARGET_CACHE[0]


# -- running with a CPU budget ------------------------------------------------------------------
def _timed_repeats(fn, budget: float, repeats: int):
    """``fn`` repeated: the CPU and wall seconds of each call, and the last result. Repeats
    stop at ``repeats`` or once one more would take the CPU time past half the budget. (The
    caller limits BLAS to one thread.)"""
    times, walls, result = [], [], None
    while True:
        c0, w0 = own_cpu_seconds(), time.perf_counter()
        result = fn()
        times.append(own_cpu_seconds() - c0)
        walls.append(time.perf_counter() - w0)
        if len(times) >= repeats or sum(times) + times[-1] > 0.5 * budget:
            break
    return times, walls, result


def _limit_cpu(seconds: float) -> None:
    """Let this process use ``seconds`` more CPU time (rounded up to whole seconds), then be
    ended by SIGXCPU from the kernel (even inside a C call)."""
    import resource

    used = resource.getrusage(resource.RUSAGE_SELF)  # the kernel's own count, which it limits
    soft = math.ceil(used.ru_utime + used.ru_stime + seconds)
    _, hard = resource.getrlimit(resource.RLIMIT_CPU)
    if hard != resource.RLIM_INFINITY:
        soft = min(soft, hard)
    try:
        resource.setrlimit(resource.RLIMIT_CPU, (soft, hard))
    except (ValueError, OSError):  # pragma: no cover - a limit this system will not take
        pass


def _child(conn, fn, evaluate, budget, repeats, grace):
    # Two messages: the times as soon as the timed work is done (the budget applies to it),
    # then the evaluation (allowed CPU seconds of its own).
    import resource

    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # terminate() must stop us even inside C code
    signal.signal(signal.SIGXCPU, signal.SIG_DFL)  # the CPU limit ends the child
    try:
        resource.setrlimit(resource.RLIMIT_CORE, (0, resource.getrlimit(resource.RLIMIT_CORE)[1]))
    except (ValueError, OSError):  # pragma: no cover - a stopped run may leave a core file
        pass
    try:
        with single_thread_blas():
            # the limit once BLAS is down to one thread: the threads it stops are accounted
            # for at the next reading of a CPU-limited process's clock (ms of CPU in no run)
            _limit_cpu(budget + BUDGET_SLACK)
            times, walls, result = _timed_repeats(fn, budget, repeats)
        conn.send(("timed", times, walls))
        _limit_cpu(grace + BUDGET_SLACK)
        conn.send(("ok", evaluate(result)))
    except Exception as exc:  # reported to the parent, which records it as the outcome
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def run_budgeted(fn, evaluate, budget: float, repeats: int = 3, grace: float = 30.0, *,
                 wall: float | None = None):
    """Run ``fn`` (timed, repeated) and ``evaluate(result)`` (untimed) in a child process that
    may use ``budget`` seconds of CPU time.

    Parameters
    ----------
    fn : callable
        The work to time; called up to ``repeats`` times while its CPU time stays within half the
        budget.
    evaluate : callable
        Turns the last result into a small picklable dict (errors, counts).
    budget : float
        CPU seconds of the timed work; a child that uses more (and :data:`BUDGET_SLACK`) is
        killed by the kernel and the outcome is :data:`STOPPED`.
    repeats : int
    grace : float
        CPU seconds allowed for ``evaluate`` after the timed work (computing the reference is
        not part of the measured work); past them the outcome is ``"error"``.
    wall : float, optional
        Wall seconds after which the timed work is stopped however little CPU time it used
        (default :data:`WALL_FACTOR` times the CPU allowance; the evaluation likewise from
        ``grace``): a run that waits instead of working.

    Returns
    -------
    outcome : str
        ``"ok"``, ``"error"`` or :data:`STOPPED`.
    times : list of float
        CPU time of each repeat, seconds (empty unless ``"ok"``).
    info : dict or str
        ``evaluate``'s result, or the error message. A dict result gets the wall time of each
        repeat, seconds, under ``"wall_times"`` (:func:`timing` makes the figures of both).

    Notes
    -----
    Uses the ``fork`` start method (the child inherits the chain already built). Where fork is
    not available the work runs in this process and cannot be stopped at the budget.
    """
    if "fork" not in multiprocessing.get_all_start_methods():
        try:
            with single_thread_blas():
                times, walls, result = _timed_repeats(fn, budget, repeats)
            return "ok", times, _with_walls(evaluate(result), walls)
        except Exception as exc:
            return "error", [], f"{type(exc).__name__}: {exc}"
    timed_wall = WALL_FACTOR * (budget + BUDGET_SLACK) if wall is None else float(wall)
    eval_wall = WALL_FACTOR * (grace + BUDGET_SLACK) if wall is None else float(wall)
    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, fn, evaluate, budget, repeats, grace),
                       daemon=True)
    proc.start()
    send.close()

    def receive(timeout):
        """The next message; None when none came within ``timeout`` wall seconds; "ended"
        when the child ended without one."""
        if not recv.poll(timeout):
            return None
        try:
            return recv.recv()
        except EOFError:
            proc.join(10.0)
            return "ended"

    def over_cpu():
        return proc.exitcode == -signal.SIGXCPU

    ended = "the child process ended without a result"
    times, walls = [], []
    try:
        msg = receive(timed_wall)
        if msg is None:
            outcome, info = STOPPED, (f"no result within {timed_wall:g} s of wall time (the CPU "
                                      f"budget is {budget:g} s): the run waited, not worked")
        elif msg == "ended":
            outcome, info = (STOPPED, f"ran past its CPU budget of {budget:g} s") if over_cpu() \
                else ("error", ended)
        elif msg[0] == "timed":
            _, cpu, walls = msg
            msg = receive(eval_wall)
            if msg is None:
                outcome, info = "error", (f"the evaluation took longer than {eval_wall:g} s of "
                                          "wall time")
            elif msg == "ended":
                outcome, info = "error", (f"the evaluation took longer than {grace:g} s of CPU "
                                          "time" if over_cpu() else ended)
            elif msg[0] == "ok":
                outcome, times, info = "ok", cpu, _with_walls(msg[1], walls)
            else:
                outcome, info = msg
        else:
            outcome, info = msg
    finally:  # also when this process is interrupted: never leave the child running
        if proc.is_alive():
            proc.terminate()
        proc.join(10.0)
        recv.close()
    return outcome, times, info


def _with_walls(info, walls):
    """``info`` with the wall seconds of the repeats under ``"wall_times"`` (a dict only)."""
    if isinstance(info, dict):
        return {**info, "wall_times": [float(w) for w in walls]}
    return info


def timing(times, info=None) -> dict:
    """The timing figures of a run of :func:`run_budgeted`.

    Parameters
    ----------
    times : list of float
        CPU seconds of each repeat (its second result).
    info : dict or str, optional
        Its third result (the wall seconds of each repeat under ``"wall_times"``).

    Returns
    -------
    dict
        ``times`` (CPU seconds of each repeat), ``time_s`` (their median: the figure budgets,
        skips and targets judge; None without a repeat), ``wall_times`` and ``wall_s`` (the same
        in wall-clock seconds, for information; None without them).

    Examples
    --------
    >>> timing([0.2, 0.1, 0.3], {"wall_times": [0.5, 0.4, 0.9]})["time_s"]
    0.2
    >>> timing([], "stopped")["wall_s"] is None
    True
    """
    walls = (info.get("wall_times") or []) if isinstance(info, dict) else []
    return {"times": [float(t) for t in times],
            "time_s": float(np.median(times)) if len(times) else None,
            "wall_times": [float(w) for w in walls],
            "wall_s": float(np.median(walls)) if len(walls) else None}


# -- one point of the chart ---------------------------------------------------------------------
def _trace_fn(problem: ChainProblem, setting: Setting):
    if setting.method == "map":
        samples = int(setting.options.get("samples", 101))
        values = np.linspace(problem.start, problem.target, samples)
        fmap = _library_map(problem.module_name) or problem.fmap
        return lambda: (values, fmap.iterate(values, problem.k)[-1])
    return lambda: trace(problem.network, "d1", to=problem.target, method=setting.method,
                         **setting.options)


def _library_map(module: str):
    """The module's map from :mod:`fabkit.maps` (what users iterate), or None without it."""
    try:
        from ..maps import module_map
    except ImportError:
        return None
    return module_map(paper_module(module))


def _evaluate_fn(problem: ChainProblem, setting: Setting):
    def evaluate(result) -> dict:
        if setting.method == "map":
            values, last = result
            ref = problem.fmap.iterate(values, problem.k)[-1]
            err = np.abs(last - ref)
            library = _library_map(problem.module_name) is not None
            return {"status": "finished", "configurations": int(values.size),
                    "max_edge_error": None,
                    "d_last_error": float(np.nanmax(err)) if np.isfinite(err).any() else None,
                    "d_last_final_error": float(err[-1]) if np.isfinite(err[-1]) else None,
                    "final_drive": float(values[-1]), "reference": not library,
                    "implementation": "fabkit.maps" if library else "fabkit.bench.ModuleMap",
                    "stats": {}}
        traj = result
        last = traj.distance(problem.last_port)
        ref = problem.fmap.iterate(traj.drive, problem.k)[-1]
        err = np.abs(last - ref)
        return {
            "status": str(traj.status),
            "message": traj.message,
            "configurations": int(traj.n_steps),
            "max_edge_error": float(traj.max_edge_error),
            "d_last_error": float(np.nanmax(err)) if np.isfinite(err).any() else None,
            "d_last_final_error": float(err[-1]) if np.isfinite(err[-1]) else None,
            "final_drive": float(traj.drive[-1]),
            "reference": False,
            "stats": {k: (v if isinstance(v, (int, float, str)) else str(v))
                      for k, v in traj.stats.items()},
        }

    return evaluate


def measure(problem: ChainProblem, setting: Setting, budget: float, repeats: int = 3) -> dict:
    """One point: time the setting on the chain and measure its errors.

    Returns
    -------
    dict
        ``method``, ``options``, ``label``, ``modules``, ``nodes``, ``coordinates``, ``outcome``
        (``"ok"``, ``"error"`` or :data:`STOPPED`), ``status`` (the trace's), ``time_s`` (median
        of ``times``, CPU seconds of each repeat), ``wall_s`` (median of ``wall_times``, the same
        in wall-clock seconds), ``configurations``, ``time_per_configuration_s`` (CPU),
        ``max_edge_error`` (relative), ``d_last_error`` (largest ``|d_{k+1} - f^k(d_1)|`` over the
        trace, design units), ``d_last_final_error`` (at the end), ``final_drive``, ``stats``.
    """
    net = problem.network
    point = {
        "method": setting.method,
        "options": dict(setting.options),
        "label": setting.label,
        "modules": problem.k,
        "nodes": int(net.n_nodes),
        "coordinates": int(net.n_nodes * net.dim),
        "module": problem.module_name,
        "drive": [problem.start, problem.target],
        "budget_s": budget,
    }
    outcome, times, info = run_budgeted(_trace_fn(problem, setting),
                                        _evaluate_fn(problem, setting), budget, repeats)
    point["outcome"] = outcome
    point["repeats"] = len(times)
    point.update(timing(times, info))
    if outcome == "ok":
        point.update(info)
        point["time_per_configuration_s"] = point["time_s"] / max(point["configurations"], 1)
    else:
        point.update(status=outcome if outcome == STOPPED else "error", message=info,
                     time_s=None, configurations=None, time_per_configuration_s=None,
                     max_edge_error=None, d_last_error=None, d_last_final_error=None)
    return point


def _estimate(history: list[tuple[int, float]], n: int, method: str) -> float | None:
    """Power-law extrapolation of a run's time to n nodes from the sizes measured so far."""
    if not history:
        return None
    if len(history) == 1:
        (n0, t0), = history
        return t0 * (n / n0) ** _PRIOR_EXPONENT.get(method, 1.2)
    (n0, t0), (n1, t1) = history[-2:]
    p = math.log(t1 / t0) / math.log(n1 / n0) if t0 > 0 and t1 > 0 and n1 != n0 else 1.0
    return t1 * (n / n1) ** max(p, 1.0)


def work_precision(sizes, settings=FULL_SETTINGS, *, budget: float = 30.0, repeats: int = 3,
                   module: str = "super_stable", target: float | None = None,
                   progress=None) -> list:
    """Measure every setting on chains of every size (small to large).

    Parameters
    ----------
    sizes : sequence of int
        Numbers of modules, e.g. ``(10, 100, 1000, 10000)``.
    settings : sequence of Setting
    budget : float
        CPU seconds allowed per run (all repeats of one setting at one size).
    repeats : int
        Largest number of repeats (fewer when one run takes more than a quarter of the budget).
    module, target
        See :func:`chain_problem`.
    progress : callable, optional
        Called with each finished point (for a progress line).

    Returns
    -------
    list of dict
        The points of :func:`measure`, plus skipped runs (``outcome`` :data:`SKIPPED`, with
        ``estimated_time_s``).

    Examples
    --------
    >>> pts = work_precision([3], [Setting("constructive", {"samples": 5})], budget=20)
    >>> pts[0]["status"], pts[0]["max_edge_error"] < 1e-12
    ('finished', True)
    """
    points = []
    history: dict[str, list[tuple[int, float]]] = {s.label: [] for s in settings}
    stopped: set[str] = set()
    for k in sorted(int(s) for s in sizes):
        problem = chain_problem(k, module, target)
        n = problem.network.n_nodes
        for s in settings:
            est = _estimate(history[s.label], n, s.method)
            if s.label in stopped or (est is not None and est > budget):
                why = ("a smaller chain already exceeded the budget" if s.label in stopped else
                       f"estimated {est:.3g} s from the smaller chains > budget {budget:g} s")
                pt = {"method": s.method, "options": dict(s.options), "label": s.label,
                      "modules": k, "nodes": n, "coordinates": n * problem.network.dim,
                      "module": module, "drive": [problem.start, problem.target],
                      "budget_s": budget,
                      "outcome": SKIPPED, "status": SKIPPED, "message": why,
                      "estimated_time_s": est, "time_s": None, "times": [], "repeats": 0,
                      "wall_s": None, "wall_times": [],
                      "configurations": None, "time_per_configuration_s": None,
                      "max_edge_error": None, "d_last_error": None, "d_last_final_error": None}
            else:
                pt = measure(problem, s, budget, repeats)
                if pt["outcome"] == STOPPED:
                    stopped.add(s.label)
                elif pt["outcome"] == "ok":
                    history[s.label].append((n, pt["time_s"]))
            points.append(pt)
            if progress is not None:
                progress(pt)
    return points


# -- scaling ------------------------------------------------------------------------------------
def fit_exponent(n, t) -> tuple[float, float] | None:
    """Least-squares fit ``t = c · n^p`` in log-log; returns ``(p, c)`` (None below 2 points).

    Examples
    --------
    >>> p, c = fit_exponent([10, 100, 1000], [2e-3, 2e-2, 2e-1])
    >>> round(p, 6), round(c, 9)
    (1.0, 0.0002)
    """
    n = np.asarray(n, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    ok = (n > 0) & (t > 0) & np.isfinite(t)
    if ok.sum() < 2 or np.unique(n[ok]).size < 2:
        return None
    p, logc = np.polyfit(np.log(n[ok]), np.log(t[ok]), 1)
    return float(p), float(math.exp(logc))


def scaling(points, settings=None) -> dict:
    """Fitted growth of the time per configuration (and of the total time) with the node count.

    Uses, per method, the first setting listed for it (the method's reference setting), and only
    runs that finished.

    Returns
    -------
    dict
        method → ``{"label", "nodes", "time_per_configuration_s", "time_s", "exponent" (fit over
        all sizes), "coefficient", "exponent_largest" (slope between the two largest sizes),
        "exponent_total" (of the total time), "over_budget_from_nodes"}`` (exponents None with
        fewer than two sizes).
    """
    first: dict[str, str] = {}
    for p in points:
        first.setdefault(p["method"], p["label"])
    out = {}
    for method, label in first.items():
        rows = [p for p in points if p["label"] == label and p["outcome"] == "ok"
                and p.get("status") == "finished"]
        rows.sort(key=lambda p: p["nodes"])
        n = [p["nodes"] for p in rows]
        tpc = [p["time_per_configuration_s"] for p in rows]
        tt = [p["time_s"] for p in rows]
        fit = fit_exponent(n, tpc)
        fit_total = fit_exponent(n, tt)
        # fixed costs dominate small chains: the slope between the two largest sizes is the
        # better estimate of the growth that matters
        last = fit_exponent(n[-2:], tpc[-2:]) if len(n) >= 2 else None
        beyond = sorted(p["nodes"] for p in points if p["label"] == label
                        and p["outcome"] in (STOPPED, SKIPPED))
        out[method] = {"label": label, "nodes": n, "time_per_configuration_s": tpc, "time_s": tt,
                       "exponent": fit[0] if fit else None,
                       "coefficient": fit[1] if fit else None,
                       "exponent_largest": last[0] if last else None,
                       "exponent_total": fit_total[0] if fit_total else None,
                       "over_budget_from_nodes": beyond[0] if beyond else None}
    return out


# -- the dense baseline where it is too slow to run ---------------------------------------------
def rk4_estimate(k: int, step: float, evaluations: int, *, module: str = "super_stable",
                 repeats: int = 1) -> dict:
    """Time of ``rk4-nullspace`` on a k-module chain from one measured evaluation.

    The method's cost is its number of evaluations (fixed by the step and the arclength, which
    for the super-stable chain does not grow with k) times the cost of one dense null-space
    evaluation; the latter is measured here at size k.

    Returns
    -------
    dict
        ``modules``, ``nodes``, ``step``, ``evaluations``, ``evaluation_s`` (median, CPU
        seconds), ``evaluation_wall_s`` (median, wall seconds), ``estimated_time_s`` (CPU).
    """
    problem = chain_problem(k, module)
    net = problem.network
    x = net.nodes.ravel()
    times, walls = [], []
    with single_thread_blas():
        for _ in range(max(int(repeats), 1)):
            c0, w0 = own_cpu_seconds(), time.perf_counter()
            conformational_velocity(net, x)
            times.append(own_cpu_seconds() - c0)
            walls.append(time.perf_counter() - w0)
    per = float(np.median(times))
    return {"modules": int(k), "nodes": int(net.n_nodes), "step": float(step),
            "evaluations": int(evaluations), "evaluation_s": per,
            "evaluation_wall_s": float(np.median(walls)),
            "estimated_time_s": per * int(evaluations)}


# -- the Lyapunov protocol ------------------------------------------------------------------------
def lyapunov_protocol(starts: int = 1000, transient: int = 5000, iterations: int = 20000,
                      module: str = "chaotic") -> dict:
    """The paper's Lyapunov protocol on the module's exact map (:meth:`fabkit.maps.Map1D.lyapunov`
    with ``method="exact"``), timed.

    ``starts`` initial distances evenly spaced over the map's invariant range, ``transient``
    iterations to settle on the attractor, then the mean of ``log |f'(d)|`` over ``iterations``
    further ones, with exact derivatives. All starts advance together.

    Returns
    -------
    dict
        ``exponent`` (mean over starts), ``exponent_spread`` (standard deviation), ``time_s``
        (CPU seconds), ``wall_s``, ``starts``, ``transient``, ``iterations``,
        ``finite_starts``, ``range``, ``time_per_map_evaluation_s`` (CPU).
    """
    from ..maps import module_map

    fmap = module_map(paper_module(module))
    lo, hi = fmap.invariant_range()
    with single_thread_blas():
        c0, w0 = own_cpu_seconds(), time.perf_counter()
        res = fmap.lyapunov(initial=int(starts), discard=int(transient), average=int(iterations),
                            method="exact")
        elapsed, wall = own_cpu_seconds() - c0, time.perf_counter() - w0
    evals = int(starts) * (int(transient) + int(iterations))
    return {"exponent": float(res.mean), "exponent_spread": float(res.std),
            "finite_starts": int(res.values.size) - int(res.escaped), "starts": int(starts),
            "transient": int(transient), "iterations": int(iterations), "time_s": elapsed,
            "wall_s": wall, "range": [float(lo), float(hi)],
            "time_per_map_evaluation_s": elapsed / max(evals, 1)}


def maps_lyapunov(starts: int = 1000, transient: int = 5000, iterations: int = 20000,
                  module: str = "chaotic", budget: float = 60.0) -> dict:
    """Time :meth:`fabkit.maps.Map1D.lyapunov` (the library's protocol) with a budget.

    Returns ``exponent``, ``std``,
    ``method`` (exact or table), ``time_s`` (median CPU seconds of up to 3 repeats within the
    budget), ``wall_s`` (the same in wall-clock seconds) and ``outcome`` (``"ok"``, ``"error"``
    or :data:`STOPPED`).
    """
    from ..maps import module_map

    fmap = module_map(paper_module(module))
    outcome, times, info = run_budgeted(
        lambda: fmap.lyapunov(initial=int(starts), discard=int(transient),
                              average=int(iterations)),
        lambda r: {"exponent": float(r.mean), "std": float(r.std), "method": str(r.method),
                   "escaped": int(r.escaped)},
        budget, repeats=3)
    out = {"starts": int(starts), "transient": int(transient), "iterations": int(iterations),
           "outcome": outcome, **timing(times, info)}
    if isinstance(info, dict):
        out.update(info)
    else:
        out["message"] = info
    return out


# -- profiling ------------------------------------------------------------------------------------
def profile_method(k: int, method: str = "projected", top: int = 25, **options) -> dict:
    """cProfile of one trace of a k-module chain; the functions with the most own time.

    Returns
    -------
    dict
        ``time_s`` (CPU seconds under the profiler), ``wall_s``, ``status``, ``stats`` (the
        trace's counters), ``text``
        (pstats listing sorted by internal time) and ``rows``: ``[function, calls, tottime,
        cumtime]`` for the top entries.
    """
    import cProfile
    import io
    import pstats

    problem = chain_problem(k)
    prof = cProfile.Profile()
    with single_thread_blas():
        c0, w0 = own_cpu_seconds(), time.perf_counter()
        prof.enable()
        traj = trace(problem.network, "d1", to=problem.target, method=method, **options)
        prof.disable()
        elapsed, wall = own_cpu_seconds() - c0, time.perf_counter() - w0
    buf = io.StringIO()
    st = pstats.Stats(prof, stream=buf).sort_stats("tottime")
    st.print_stats(top)
    rows = []
    for (fname, line, func), (cc, nc, tt, ct, _) in sorted(
            st.stats.items(), key=lambda kv: -kv[1][2])[:top]:
        rows.append([f"{fname.rsplit('/', 1)[-1]}:{line}({func})", int(nc), float(tt), float(ct)])
    return {"modules": int(k), "method": method, "time_s": elapsed, "wall_s": wall,
            "status": str(traj.status),
            "stats": {k2: str(v) for k2, v in traj.stats.items()}, "text": buf.getvalue(),
            "rows": rows}


# -- targets --------------------------------------------------------------------------------------
def targets(points, scal: dict, comparison: dict | None = None, lyapunov: dict | None = None,
            *, edge_target: float = 1e-12) -> dict:
    """The issue's targets, each with the measured figure and whether it is met.

    Times are judged in CPU seconds (``time_s``); the wall seconds of the same runs stand beside
    them (``wall_s``) for information.

    Parameters
    ----------
    points : list of dict
        Work-precision points.
    scal : dict
        :func:`scaling` result.
    comparison : dict, optional
        ``{"modules", "best": point, "rk4": point or estimate}`` at 300 modules.
    lyapunov : dict, optional
        :func:`lyapunov_protocol` result (``time_s``; ``extrapolated_time_s`` when scaled down).
    """
    out = {}
    done = [p for p in points if p["outcome"] == "ok" and p.get("status") == "finished"]
    kmax = max((p["modules"] for p in points), default=0)
    big = [p for p in done if p["modules"] == kmax and p["method"] != "map"
           and p["max_edge_error"] is not None and p["max_edge_error"] <= edge_target]
    best = min(big, key=lambda p: p["time_s"]) if big else None
    out["largest_chain"] = {
        "target": f"{kmax}-module chain, whole motion, edge error <= {edge_target:g}, in <= 1 s",
        "modules": kmax, "best": best["label"] if best else None,
        "time_s": best["time_s"] if best else None,
        "wall_s": best.get("wall_s") if best else None,
        "edge_error": best["max_edge_error"] if best else None,
        "met": bool(best and best["time_s"] <= 1.0 and kmax >= 10000),
    }
    for m in ("projected", "constructive"):
        e = scal.get(m, {}).get("exponent")
        e2 = scal.get(m, {}).get("exponent_largest")
        worst = max(v for v in (e, e2) if v is not None) if (e, e2) != (None, None) else None
        nodes = scal.get(m, {}).get("nodes") or [0]
        # fixed costs hide the growth on small chains: judge only a fit that reaches 1000 modules
        reach = max(nodes) >= 3000
        out[f"exponent_{m}"] = {"target": "time per configuration grows no faster than N^1.15 "
                                          "(fit reaching >= 3000 nodes)",
                                "exponent": e, "exponent_largest": e2, "largest_nodes": max(nodes),
                                "met": bool(worst is not None and worst <= 1.15 and reach)}
        if not reach:
            out[f"exponent_{m}"]["reason"] = "not judged: no finished run with >= 3000 nodes"
    # at every time budget, is some non-rk4 method at least as accurate as rk4?
    worse = []
    for r in (p for p in done if p["method"] == "rk4-nullspace"):
        rivals = [p for p in done if p["modules"] == r["modules"] and p["method"] not in
                  ("rk4-nullspace", "map") and p["time_s"] <= r["time_s"]
                  and p["max_edge_error"] <= r["max_edge_error"]
                  and (p["d_last_error"] or 0.0) <= (r["d_last_error"] or 0.0)]
        if not rivals:
            worse.append(r["label"] + f" at {r['modules']} modules")
    out["dominates_rk4"] = {"target": "best method at least as accurate as rk4-nullspace at every "
                                      "time budget", "exceptions": worse, "met": not worse}
    if comparison:
        b, r = comparison.get("best"), comparison.get("rk4")
        ratio = (r["time_s"] / b["time_s"]) if (b and r and b.get("time_s") and r.get("time_s"))\
            else None
        out["speedup_300"] = {
            "target": ">= 1000x faster than rk4-nullspace at 300 modules at equal or better "
                      "accuracy", "best": b.get("label") if b else None,
            "best_time_s": b.get("time_s") if b else None,
            "rk4_time_s": r.get("time_s") if r else None,
            "best_wall_s": b.get("wall_s") if b else None,
            "rk4_wall_s": r.get("wall_s") if r else None,
            "rk4_time_estimated": bool(r and r.get("estimated")),
            "ratio": ratio,
            "met": bool(ratio and ratio >= 1000 and b["max_edge_error"] <= (
                r.get("max_edge_error") or math.inf)),
        }
    if lyapunov:
        lib = lyapunov.get("library")
        if lib and lib.get("time_s") is not None:  # fabkit.maps: the implementation users get
            full = (lib["starts"], lib["transient"], lib["iterations"]) == (1000, 5000, 20000)
            scale = 1.0 if full else 25000 / (lib["transient"] + lib["iterations"])
            t = lib["time_s"] * scale
            wall = lib["wall_s"] * scale if lib.get("wall_s") is not None else None
            out["lyapunov"] = {"target": "Lyapunov protocol (1000 x 25000 map iterations) <= 1 s",
                               "implementation": "fabkit.maps Map1D.lyapunov "
                                                 f"({lib.get('method')})",
                               "time_s": t, "wall_s": wall, "extrapolated": not full,
                               "exponent": lib.get("exponent"),
                               "bench_map_time_s": lyapunov.get("extrapolated_time_s",
                                                                lyapunov.get("time_s")),
                               "met": bool(t <= 1.0)}
        else:
            t = lyapunov.get("extrapolated_time_s", lyapunov.get("time_s"))
            wall = lyapunov.get("extrapolated_wall_s", lyapunov.get("wall_s"))
            out["lyapunov"] = {"target": "Lyapunov protocol (1000 x 25000 map iterations) <= 1 s",
                               "implementation": "fabkit.bench ModuleMap (placement)",
                               "time_s": t, "wall_s": wall,
                               "extrapolated": "extrapolated_time_s" in lyapunov,
                               "exponent": lyapunov.get("exponent"),
                               "met": bool(t is not None and t <= 1.0)}
    return out


# -- figures ------------------------------------------------------------------------------------
_COLORS = {"map": "C1", "constructive": "C0", "projected": "C2", "rk4-nullspace": "C3"}
_MARKERS = ["o", "s", "^", "D", "v", "P"]


def work_precision_figure(points, *, floor: float = 1e-17):
    """Wall time against the largest edge error and against the d_{k+1} error, per method and
    chain size (marker); settings of one method at one size are joined by a line. Runs stopped
    at the budget or skipped are drawn as crosses at their budget on the top edge.

    Returns
    -------
    matplotlib.figure.Figure
    """

    fig, axes = figure_kit.subplots(1, 2, figsize=(13, 5.2))
    sizes = sorted({p["modules"] for p in points})
    mark = {k: _MARKERS[i % len(_MARKERS)] for i, k in enumerate(sizes)}
    keys = [("max_edge_error", "largest relative edge-length error"),
            ("d_last_error", "largest |d_{k+1} - f^k(d_1)| (design units)")]
    for ax, (key, label) in zip(axes, keys):
        for method in dict.fromkeys(p["method"] for p in points):
            col = _COLORS.get(method, "k")
            for k in sizes:
                rows = [p for p in points if p["method"] == method and p["modules"] == k
                        and p["outcome"] == "ok" and p.get(key) is not None]
                rows.sort(key=lambda p: p["time_s"])
                if rows:
                    t = [p["time_s"] for p in rows]
                    e = [max(p[key], floor) for p in rows]
                    ax.loglog(t, e, "-", color=col, lw=0.8, alpha=0.6)
                    hollow = [p.get("status") != "finished" for p in rows]
                    for ti, ei, h in zip(t, e, hollow):
                        ax.loglog(ti, ei, mark[k], color=col, ms=6,
                                  mfc="none" if h else col)
                cut = [p for p in points if p["method"] == method and p["modules"] == k
                       and p["outcome"] in (STOPPED, SKIPPED)]
                for p in cut:
                    ax.plot(p["budget_s"], 1.0, "x", color=col, ms=8, mew=2)
        ax.set_xlabel("CPU time, s (median of repeats, one BLAS thread)")
        ax.set_ylabel(label)
        ax.grid(True, which="major", alpha=0.3)
    handles = [figure_kit.Line2D([], [], color=_COLORS.get(m, "k"), lw=2, label=m)
               for m in dict.fromkeys(p["method"] for p in points)]
    handles += [figure_kit.Line2D([], [], color="0.3", ls="", marker=mark[k], label=f"{k} modules")
                for k in sizes]
    handles.append(figure_kit.Line2D([], [], color="0.3", ls="", marker="x", mew=2,
                              label="stopped at / skipped over budget (at the budget, top)"))
    axes[1].legend(handles=handles, fontsize=7, loc="upper left")
    axes[1].set_title("map: fabkit.maps iteration against the bench's own placement map; "
                      "errors of 0 drawn at the floor", fontsize=8)
    module = points[0]["module"] if points else ""
    fig.suptitle(f"work-precision: {module} chains", fontsize=10)
    fig.tight_layout()
    return fig


def scaling_figure(scal: dict, points=None, dense=None):
    """Time per configuration against the number of nodes (log-log) with fitted exponents.

    ``dense``: optional list of ``{"nodes", "evaluation_s"}`` (one dense null-space evaluation
    of ``rk4-nullspace`` timed at several sizes); drawn as the cost of one RK4 step (five
    evaluations: four stages and the check at the new point), where whole runs are over budget.
    """

    fig, ax = figure_kit.subplots(figsize=(7, 5))
    for method, s in scal.items():
        if not s["nodes"]:
            continue
        col = _COLORS.get(method, "k")
        n = np.asarray(s["nodes"], dtype=float)
        t = np.asarray(s["time_per_configuration_s"], dtype=float)
        lab = s["label"]
        if s["exponent"] is not None:
            lab += f": N^{s['exponent']:.2f}"
            if s.get("exponent_largest") is not None:
                lab += f" (largest sizes N^{s['exponent_largest']:.2f})"
        if s.get("over_budget_from_nodes"):
            lab += f"; over budget from N = {s['over_budget_from_nodes']}"
        ax.loglog(n, t, "o-", color=col, lw=0.6, label=lab)
        if s["exponent"] is not None:
            nn = np.geomspace(n.min(), n.max(), 20)
            ax.loglog(nn, s["coefficient"] * nn ** s["exponent"], "--", color=col, lw=1)
    if dense:
        n = np.array([e["nodes"] for e in dense], dtype=float)
        t = 5.0 * np.array([e["evaluation_s"] for e in dense], dtype=float)
        fit = fit_exponent(n, t)
        lab = "rk4-nullspace, 5 dense evaluations (one step)"
        if fit:
            lab += f": N^{fit[0]:.2f}"
        ax.loglog(n, t, "s-", color=_COLORS["rk4-nullspace"], mfc="none", lw=0.6, label=lab)
    ax.set_xlabel("nodes N")
    ax.set_ylabel("CPU time per configuration, s")
    ax.set_title("scaling: time per configuration (dashed: fit over all sizes)", fontsize=9)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
