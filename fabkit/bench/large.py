"""Large networks: how mode counting and ``projected`` scale, and the targets for them.

- :func:`count_modes_scaling`: :func:`fabkit.count_modes` on chains of k super-stable modules
  (the geometry of ``templates/super_stable.toml``), as a user calls it (dense SVD up to
  ``SPARSE_FROM`` coordinates, the certified sparse path beyond) and with the dense SVD forced,
  where it fits the budget;
- :func:`fourbar_chain_points`: ``projected`` against ``constructive`` on chains of k 4-bars
  driven from d1 = 2 to 2.6, with the float64 floor of the edge error of each chain;
- :func:`lattice_points`: ``projected`` on a square lattice (:func:`fabkit.tessellate`) of the
  paper's 4-bar, a network without a construction order, driven from d1 = 2 to 2.5.

Every measurement runs in a child process with a time budget
(:func:`fabkit.bench.workprecision.run_budgeted`), single-threaded BLAS, median of repeats.
"""

from __future__ import annotations

import math

import numpy as np

from . import paper_module
from .workprecision import SKIPPED, STOPPED, fit_exponent, run_budgeted

__all__ = ["count_modes_scaling", "fourbar_chain_points", "lattice_points", "lattice",
           "edge_floor", "large_targets", "large_figure"]


def _skip(est, budget) -> bool:
    return est is not None and est > budget


def count_modes_scaling(sizes, *, budget: float = 30.0, repeats: int = 3,
                        progress=None) -> list[dict]:
    """Time :func:`fabkit.count_modes` on super-stable chains of each size.

    Returns
    -------
    list of dict
        One per size and path (``"auto"``: what a user gets; ``"dense"``: SVD forced, skipped
        where the N³ extrapolation from the last size exceeds the budget): ``modules``, ``nodes``,
        ``path``, ``outcome``, ``time_s``, ``times``, ``method`` (the path actually taken),
        ``counts`` (total, rigid, conformational, self-stress), ``gap``, ``smallest_nonzero``,
        ``ambiguous``.
    """
    from ..assemble import chain
    from ..rigidity import count_modes

    module = paper_module("super_stable")
    points, last_dense = [], None
    for k in sizes:
        net = chain(module, copies=int(k))
        for path in ("auto", "dense"):
            pt = {"modules": int(k), "nodes": net.n_nodes, "path": path, "budget_s": budget}
            if path == "dense" and last_dense is not None:
                n0, t0 = last_dense
                est = t0 * (net.n_nodes / n0) ** 3
                if _skip(est, budget):
                    pt.update(outcome=SKIPPED, time_s=None, times=[], estimate_s=est)
                    points.append(pt)
                    if progress:
                        progress(pt)
                    continue

            def evaluate(m):
                return {"method": m.method, "counts": [m.total, m.rigid, m.conformational,
                                                       m.self_stress],
                        "gap": m.gap, "smallest_nonzero": m.smallest_nonzero,
                        "ambiguous": m.ambiguous, "note": m.note}

            outcome, times, info = run_budgeted(
                lambda net=net, path=path: count_modes(net, method=path), evaluate, budget,
                repeats)
            pt.update(outcome=outcome, times=[float(t) for t in times],
                      time_s=float(np.median(times)) if times else None)
            if isinstance(info, dict):
                pt.update(info)
            else:
                pt["message"] = info
            if path == "dense":
                if outcome == "ok":
                    last_dense = (net.n_nodes, pt["time_s"])
                elif outcome == STOPPED:
                    last_dense = (net.n_nodes, math.inf)
            points.append(pt)
            if progress:
                progress(pt)
    return points


def edge_floor(net) -> float:
    """Float64 floor of the relative edge error of a network: machine epsilon × the extent of
    its configuration / its shortest bar (coordinates of size X carry an error of eps·X)."""
    extent = float(np.max(np.abs(net.nodes)))
    return float(np.finfo(float).eps * extent / np.min(net.edge_lengths))


def _trace_point(net, drive, to, method, budget, repeats, **options) -> dict:
    from ..kinematics import trace

    def evaluate(traj):
        return {"status": str(traj.status), "message": traj.message,
                "configurations": int(len(traj.positions)),
                "max_edge_error": float(traj.max_edge_error),
                "stats": {k: str(v) for k, v in traj.stats.items()}}

    outcome, times, info = run_budgeted(
        lambda: trace(net, drive, to=to, method=method, **options), evaluate, budget, repeats)
    pt = {"method": method, "nodes": net.n_nodes, "outcome": outcome, "budget_s": budget,
          "times": [float(t) for t in times],
          "time_s": float(np.median(times)) if times else None,
          "floor": edge_floor(net)}
    if isinstance(info, dict):
        pt.update(info)
        if pt["time_s"] is not None:
            pt["time_per_configuration_s"] = pt["time_s"] / max(pt["configurations"], 1)
    else:
        pt["message"] = info
    return pt


def fourbar_chain_points(sizes, *, budget: float = 30.0, repeats: int = 3, to: float = 2.6,
                         progress=None) -> list[dict]:
    """``constructive`` (101 samples) and ``projected`` (defaults) on k-module 4-bar chains
    driven from d1 = 2 to ``to``."""
    from ..assemble import chain

    points = []
    for k in sizes:
        net = chain(paper_module("fourbar"), copies=int(k))
        for method, opts in (("constructive", {"samples": 101}), ("projected", {})):
            pt = _trace_point(net, "d1", to, method, budget, repeats, **opts)
            pt["modules"] = int(k)
            points.append(pt)
            if progress:
                progress(pt)
    return points


def lattice(k: int):
    """A k × k square lattice of the paper's 4-bar (Fig. 2a), cells joined side to side and
    top to bottom: one conformational motion and (for k ≥ 3) states of self-stress."""
    from ..assemble import tessellate

    m = paper_module("fourbar")
    m = m.with_ports({**m.ports, "b": (0, 2), "t": (1, 3)})
    return tessellate(m, (int(k), int(k)), y_join=("t", "b"))


def lattice_points(sizes, *, budget: float = 30.0, repeats: int = 3, to: float = 2.5,
                   progress=None) -> list[dict]:
    """``projected`` on k × k 4-bar lattices, driving the first cell's d1 from 2 to ``to``."""
    points = []
    for k in sizes:
        net = lattice(k)
        pt = _trace_point(net, "d1_0_0", to, "projected", budget, repeats)
        pt["cells"] = int(k) ** 2
        pt["side"] = int(k)
        points.append(pt)
        if progress:
            progress(pt)
    return points


def large_targets(modes, chains) -> dict:
    """The targets for large networks, each with the measured figure and whether it is met."""
    out = {}
    auto = {p["modules"]: p for p in modes if p["path"] == "auto" and p["outcome"] == "ok"}
    p10 = auto.get(10000)
    out["count_modes_10000"] = {
        "target": "count_modes on the 10 000-module super-stable chain <= 1 s, exact counts",
        "time_s": p10["time_s"] if p10 else None,
        "counts": p10.get("counts") if p10 else None,
        "ambiguous": p10.get("ambiguous") if p10 else None,
        "met": bool(p10 and p10["time_s"] <= 1.0 and p10["counts"] == [4, 3, 1, 0]
                    and not p10["ambiguous"]),
    }
    fit = None
    if 1000 in auto and 10000 in auto:
        fit = fit_exponent([auto[1000]["nodes"], auto[10000]["nodes"]],
                           [auto[1000]["time_s"], auto[10000]["time_s"]])
    out["count_modes_exponent"] = {
        "target": "count_modes time grows no faster than N^1.2 between 1000 and 10 000 modules",
        "exponent": fit[0] if fit else None, "met": bool(fit and fit[0] <= 1.2)}
    done = {(p["method"], p["modules"]): p for p in chains
            if p["outcome"] == "ok" and p.get("status") == "finished"}
    pj = done.get(("projected", 10000))
    out["projected_10000"] = {
        "target": "projected: 10 000-module 4-bar chain, d1 2 -> 2.6, <= 2 s, edge error within "
                  "10x the float64 floor",
        "time_s": pj["time_s"] if pj else None,
        "edge_error": pj["max_edge_error"] if pj else None,
        "floor": pj["floor"] if pj else None,
        "met": bool(pj and pj["time_s"] <= 2.0 and pj["max_edge_error"] <= 10 * pj["floor"]),
    }
    a, b = done.get(("projected", 1000)), done.get(("constructive", 1000))
    ratio = a["time_s"] / b["time_s"] if a and b else None
    out["projected_vs_constructive_1000"] = {
        "target": "projected <= 3x the time of constructive on the 1000-module chain at the same "
                  "accuracy (both within 10x the float64 floor)",
        "ratio": ratio,
        "edge_errors": [a["max_edge_error"], b["max_edge_error"]] if a and b else None,
        "met": bool(ratio is not None and ratio <= 3.0
                    and max(a["max_edge_error"], b["max_edge_error"]) <= 10 * a["floor"]),
    }
    return out


def large_figure(modes, chains, lattice_pts):
    """Two panels: count_modes time against nodes (as called, and dense SVD forced); time per
    configuration of ``projected`` on 4-bar chains and on the 2D lattice (``constructive`` on the
    chains for reference), with fitted exponents."""
    from ..rigidity import SPARSE_FROM
    from . import pyplot

    plt = pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.2))

    def draw(ax, rows, key, style, color, label):
        rows = [p for p in rows if p["outcome"] == "ok" and p.get(key) is not None
                and p.get("status", "finished") == "finished"]
        if not rows:
            return
        n = np.array([p["nodes"] for p in rows], dtype=float)
        t = np.array([p[key] for p in rows], dtype=float)
        fit = fit_exponent(n, t)
        last = fit_exponent(n[-2:], t[-2:]) if n.size >= 2 else None
        if fit:
            label += f": N^{fit[0]:.2f}"
            if last:
                label += f" (largest sizes N^{last[0]:.2f})"
        ax.loglog(n, t, style, color=color, label=label)

    draw(ax1, [p for p in modes if p["path"] == "auto"], "time_s", "o-", "C2",
         f"count_modes (dense up to {SPARSE_FROM} coordinates, sparse beyond)")
    draw(ax1, [p for p in modes if p["path"] == "dense"], "time_s", "s--", "C3",
         "dense SVD forced")
    for p in modes:
        if p["outcome"] in (STOPPED, SKIPPED):
            ax1.plot(p["nodes"], p.get("estimate_s") or p["budget_s"], "x", color="C3", ms=8,
                     mew=2)
    ax1.set_xlabel("nodes N (super-stable chain)")
    ax1.set_ylabel("wall time, s")
    ax1.set_title("mode counting (crosses: dense SVD skipped, at its estimate)", fontsize=9)
    draw(ax2, [p for p in chains if p["method"] == "projected"], "time_per_configuration_s",
         "o-", "C2", "projected, 4-bar chain")
    draw(ax2, [p for p in chains if p["method"] == "constructive"],
         "time_per_configuration_s", "^-", "C0", "constructive, 4-bar chain")
    draw(ax2, lattice_pts, "time_per_configuration_s", "s-", "C4",
         "projected, k x k 4-bar lattice")
    for p in lattice_pts:
        if p["outcome"] != "ok" or p.get("status") != "finished":
            ax2.plot(p["nodes"], 1.0, "x", color="C4", ms=8, mew=2)
    ax2.set_xlabel("nodes N")
    ax2.set_ylabel("wall time per configuration, s")
    ax2.set_title("projected on chains and on a 2D lattice (crosses: did not finish)",
                  fontsize=9)
    for ax in (ax1, ax2):
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    return fig
