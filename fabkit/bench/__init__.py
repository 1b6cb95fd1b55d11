"""Speed against accuracy: the studies behind ``fabkit bench``.

- :mod:`fabkit.bench.workprecision`: CPU time against accuracy for every tracing method on chains
  of 10 to 10 000 modules, and how the time per configuration grows with the size;
- :mod:`fabkit.bench.stability`: what each method does where methods fail (flat states,
  bifurcations, turning points, super-stable and super-unstable fixed points, self-stress, chaos).

This module holds what both share: the paper's modules (loaded from the bundled templates), the
iterated map that serves as the exact reference, machine information, single-threaded BLAS
(the machines this runs on are small and shared; a fair comparison gives every method one core)
and the clocks. Every time the bench judges (budgets, skips, targets) is CPU time, which the
load of a shared machine barely changes; wall time is recorded beside it, for information.
"""

from __future__ import annotations

import contextlib
import os
import platform
import time

import numpy as np

from ..kinematics import place, plan_construction
from ..model.network import Network

__all__ = ["paper_module", "ModuleMap", "machine_info", "single_thread_blas",
           "finite", "own_cpu_seconds", "child_cpu_seconds", "cpu_seconds", "clock_text"]

def paper_module(name: str, nodes=None) -> Network:
    """One of the paper's modules, as its bundled template builds it (ports ``d1`` and ``d2``).

    Parameters
    ----------
    name : str
        A bundled template, e.g. ``"super_stable"`` (templates/super_stable.toml).
    nodes : array_like, shape (N, d), optional
        Other coordinates with the same topology (the module in another configuration).

    Raises
    ------
    KeyError
        Unknown name (the message lists the valid ones).

    Examples
    --------
    >>> net = paper_module("fourbar")
    >>> net.n_nodes, round(float(net.port_distance("d1")), 12)
    (4, 2.0)
    """
    from ..templates import bundled_template, load_template

    net = load_template(bundled_template(name)).network
    return net if nodes is None else net.with_nodes(np.asarray(nodes, dtype=np.float64))


class ModuleMap:
    """The 1-D map ``d2 = f(d1)`` of a module, evaluated by constructive placement.

    This is the bench's *reference*, and it stays independent of :mod:`fabkit.maps` on purpose:
    the methods (and :class:`fabkit.maps.Map1D`) are measured against it, so it must not share
    their branch walking. It only places the module on the reference configuration's side of
    every intersection; everything else (fixed points, Lyapunov exponents) uses fabkit.maps.

    The branch is that of the module's reference configuration (the side of every intersection),
    which is also the branch :func:`fabkit.chain` builds every copy on, so iterating this map
    gives the exact distances ``d_{k+1}`` of a chain: the reference the methods are measured
    against. Vectorised over drive values; one placement per module.

    Parameters
    ----------
    module : Network
        A module with ports ``d1`` and ``d2`` and a construction order from ``d1``.

    Examples
    --------
    >>> f = ModuleMap(paper_module("fourbar"))
    >>> [round(float(v), 12) for v in f([2.0, 1.0])]   # d1 * d2 = 4 for this 4-bar
    [2.0, 4.0]
    """

    def __init__(self, module: Network):
        self._place = place
        self.plan = plan_construction(module, module.port("d1"))
        self.out = module.port("d2")

    def __call__(self, d1) -> np.ndarray:
        """``f(d1)``, shape like ``d1``; NaN where the module has no configuration."""
        d = np.asarray(d1, dtype=np.float64)
        x, margin, _ = self._place(self.plan, d.ravel())
        i, j = self.out
        out = np.linalg.norm(x[:, i] - x[:, j], axis=-1)
        out[margin < 0] = np.nan
        return out.reshape(d.shape)

    def iterate(self, d1, k: int) -> np.ndarray:
        """The distances ``d_1 … d_{k+1}`` of a k-module chain, shape (k + 1, S).

        Examples
        --------
        >>> f = ModuleMap(paper_module("fourbar"))
        >>> f.iterate([1.0], 2)[:, 0].round(12).tolist()
        [1.0, 4.0, 1.0]
        """
        d = np.atleast_1d(np.asarray(d1, dtype=np.float64))
        out = np.empty((int(k) + 1, d.size))
        out[0] = d
        for c in range(int(k)):
            out[c + 1] = self(out[c])
        return out


def machine_info() -> dict:
    """What the timings were measured on (CPU, cores, load, library versions, BLAS threads)."""
    import scipy

    info = {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
    }
    with contextlib.suppress(OSError, ValueError):
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    info["cpu_model"] = line.split(":", 1)[1].strip()
                    break
    with contextlib.suppress(OSError, AttributeError):
        info["load_average"] = [round(v, 2) for v in os.getloadavg()]
    try:
        import threadpoolctl

        info["blas"] = [{"api": p.get("internal_api"), "threads": p.get("num_threads")}
                        for p in threadpoolctl.threadpool_info()]
    except ImportError:
        info["blas"] = "unknown (threadpoolctl not installed)"
    return info


@contextlib.contextmanager
def single_thread_blas():
    """Limit BLAS/LAPACK to one thread inside the block (no-op without threadpoolctl).

    On a shared two-core machine a multi-threaded dense SVD of a small matrix runs up to 20x
    slower than a single-threaded one (threads wait on each other), which would make the dense
    baseline look worse than it is. Every method is timed with one thread.
    """
    try:
        import threadpoolctl
    except ImportError:
        yield False
        return
    with threadpoolctl.threadpool_limits(1):
        yield True


def own_cpu_seconds() -> float:
    """CPU seconds (user and system, every thread) used so far by this process: the bench's
    clock for the work it measures.

    The figure of :func:`time.process_time`, read through ``getrusage(RUSAGE_SELF)``: a process
    under a CPU limit (``RLIMIT_CPU``, which the bench's measuring children run under) has Linux
    answer ``clock_gettime(CLOCK_PROCESS_CPUTIME_ID)`` from the group timer the scheduler updates
    at its ticks, which read 0 s for half a millisecond of work, while ``getrusage`` adds up
    every thread's exact run time. Where there is no ``resource`` module,
    :func:`time.process_time`.

    Returns
    -------
    float
    """
    try:
        import resource
    except ImportError:  # pragma: no cover - not POSIX
        return time.process_time()
    used = resource.getrusage(resource.RUSAGE_SELF)
    return used.ru_utime + used.ru_stime


def child_cpu_seconds() -> float:
    """CPU seconds (user and system) of this process's child processes that have ended and been
    waited for, and of their own children: ``resource.getrusage(RUSAGE_CHILDREN)``. The
    difference across a child's run is that child's CPU time (0 where there is no
    ``resource`` module).

    Returns
    -------
    float
    """
    try:
        import resource
    except ImportError:  # pragma: no cover - not POSIX
        return 0.0
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


def cpu_seconds() -> float:
    """CPU seconds used so far by this process (:func:`own_cpu_seconds`) and by its ended
    child processes (:func:`child_cpu_seconds`): the bench's clock for a whole run.

    Returns
    -------
    float
    """
    return own_cpu_seconds() + child_cpu_seconds()


def clock_text(point: dict, cpu: str = "time_s", wall: str = "wall_s", unit: str = "s") -> str:
    """A measured figure as a progress line shows it: CPU seconds, and the wall seconds beside
    them (``-`` when not measured).

    Parameters
    ----------
    point : dict
        A measured item (``time_s`` and ``wall_s``, or the keys given).
    cpu, wall : str
        The keys of its CPU and wall figures.
    unit : str
        What follows each number (``"s"``, ``"s/build"``).

    Returns
    -------
    str

    Examples
    --------
    >>> clock_text({"time_s": 0.0123, "wall_s": 0.04})
    '0.0123 s CPU (0.04 wall)'
    >>> clock_text({"time_s": None})
    '-'
    """
    t, w = point.get(cpu), point.get(wall)
    if t is None:
        return "-"
    return f"{t:.3g} {unit} CPU" + ("" if w is None else f" ({w:.3g} wall)")


def finite(doc):
    """A copy of a JSON-like document with NaN and infinities replaced by None (strict JSON).

    Examples
    --------
    >>> finite({"a": [1.0, float("nan")], "b": float("inf")})
    {'a': [1.0, None], 'b': None}
    """
    if isinstance(doc, dict):
        return {k: finite(v) for k, v in doc.items()}
    if isinstance(doc, (list, tuple)):
        return [finite(v) for v in doc]
    if isinstance(doc, (float, np.floating)) and not np.isfinite(doc):
        return None
    return doc
