"""The levels of a build's model, speed against accuracy: the first-order test over the states
of self-stress (from the dense basis, or one sparse linear program), the nonlinear assembly with
joint play, and elastic relaxation without play.

Each case is a network with states of self-stress, built many times with bar-length errors
(σ ``sigma_mm``) and a little play (``room_mm`` a bar, 0.05 mm: small enough that some builds
close and some do not, on the AND gate and on lattices of 100 to 900 cells alike), the drive
port held. Per level and case: the CPU seconds a build takes (the wall seconds beside them),
and what the level says; the first-order verdicts are compared with the nonlinear assembly's
(the reference: the same question without linearisation), and the elastic level gives the
energy and the largest stress of a build forced together without play. The cases: the AND
gate (98 nodes, one state of self-stress) and k × k lattices of the paper's 4-bar
(:func:`fabkit.bench.large.lattice`, about k² states of self-stress; 10⁴ cells at k = 100).

Budgets are CPU seconds: each level stops taking builds once it has used its budget, and the
first-order levels, whose one linear program may alone run for minutes, solve their programs in
a child process that the kernel stops at the budget
(:func:`fabkit.bench.workprecision.run_budgeted`).
"""

from __future__ import annotations

import time

import numpy as np

from ..builds.assembly import assemble, bar_stress
from ..builds.closure import play_ratio, play_ratio_sparse, self_stress_basis
from ..builds.materials import bar_stiffness, MATERIALS
from ..templates import load_template
from ..plots.viz import figure_kit, set_margins
from . import clock_text, own_cpu_seconds
from .large import dense_svd_seconds, lattice
from .workprecision import run_budgeted, STOPPED

__all__ = ["level_cases", "levels_points", "levels_figure", "levels_line", "LEVELS"]

#: The levels, in order of cost.
LEVELS = ("first order (basis)", "first order (sparse LP)", "assembly with play",
          "elastic, no play")

#: mm per design unit of every case (the laser kit's default scale).
SCALE_MM = 100.0

#: A laser-cut acrylic bar: 14.5 mm wide, 3 mm thick.
SECTION_MM2 = 14.5 * 3.0


def level_cases(sizes) -> list[tuple[str, object, str]]:
    """(name, network, drive port) of the AND gate and of a k × k 4-bar lattice per size."""
    cases = [("AND gate", load_template("and_gate").network, "d1_b")]
    for k in sizes:
        cases.append((f"lattice {k}x{k}", lattice(int(k)), "d1_0_0"))
    return cases


def levels_points(cases, *, builds: int = 5, sigma_mm: float = 0.05, room_mm: float = 0.05,
                  budget: float = 30.0, seed: int = 0, progress=None) -> list[dict]:
    """Every level on every case: CPU seconds per build and what it says.

    Parameters
    ----------
    cases : list of (str, Network, str)
        From :func:`level_cases`.
    builds : int
        Builds per case (each level stops early once it has spent ``budget`` CPU seconds).
    sigma_mm, room_mm : float
        Bar-length error σ and each bar's play.
    budget : float
        CPU seconds per level and case; the dense basis is skipped where its SVD alone is
        estimated to take longer (:func:`fabkit.bench.large.dense_svd_seconds`), and a
        first-order level whose linear program passes it is stopped and marked skipped.
    seed : int
    progress : callable, optional
        ``progress(point)`` after each level of each case.

    Returns
    -------
    list of dict
        One per case and level: ``case``, ``level``, ``nodes``, ``edges``, ``self_stresses``
        (where known), ``builds`` (measured), ``seconds_per_build`` (CPU seconds; None:
        skipped), ``wall_seconds_per_build`` (the same in wall seconds) and the level's
        figures: ``closes`` (fraction), ``agrees`` (first order against the assembly),
        ``energy_mj`` and ``max_stress_mpa`` (elastic).
    """
    rng = np.random.default_rng(seed)
    acrylic = MATERIALS["acrylic"]
    points = []
    for name, net, drive in cases:
        rest0 = net.edge_lengths * SCALE_MM
        rests = rest0[None, :] + rng.normal(0.0, sigma_mm, (builds, rest0.size))
        gap = rests - rest0[None, :]
        x0 = net.nodes * SCALE_MM
        held = [net.port(drive)]
        base = {"case": name, "nodes": int(net.n_nodes), "edges": int(net.n_edges)}
        closes_ref = []

        def record(level, spent, done, **figures):
            """One point; ``spent``: (CPU, wall) seconds of its ``done`` builds, or None."""
            pt = {**base, "level": level, "builds": done,
                  "seconds_per_build": None if spent is None else spent[0] / max(done, 1),
                  "wall_seconds_per_build": None if spent is None else spent[1] / max(done, 1),
                  **figures}
            points.append(pt)
            if progress:
                progress(pt)
            return pt

        def first_order(level, before, ratio, why):
            """Play ratios build by build within the budget, judged against the assembly; the
            programs run in a child process that the kernel stops at the CPU budget.
            ``before``: (CPU, wall) seconds the level spent before its programs (the basis)."""

            def builds_within():
                c0, taus = own_cpu_seconds(), []
                for k in range(done):
                    taus.append(float(ratio(k)))
                    if before[0] + own_cpu_seconds() - c0 > budget:
                        break
                return taus

            outcome, times, info = run_budgeted(builds_within, lambda taus: {"taus": taus},
                                                budget, repeats=1)
            tau = np.array(info["taus"] if outcome == "ok" else [])
            if not tau.size:
                return record(level, None, 0, skipped=why if outcome in ("ok", STOPPED)
                              else f"{why}: {info}")
            spent = (before[0] + times[0], before[1] + info["wall_times"][0])
            return record(level, spent, tau.size,
                          closes=float(np.mean(tau <= 1.0)),
                          agrees=float(np.mean((tau <= 1.0) == ref[:tau.size])))

        # the nonlinear assembly first: the reference the first-order levels are judged by
        t0, done = _clock(), 0
        for k in range(builds):
            a = assemble(net.edges, rests[k], room_mm, x0,
                         stiffness=bar_stiffness(acrylic, SECTION_MM2, rests[k]), held=held)
            closes_ref.append(a.closes)
            done += 1
            if _since(t0)[0] > budget:
                break
        ref = np.array(closes_ref)
        record("assembly with play", _since(t0), done, closes=float(ref.mean()))

        est = dense_svd_seconds(net.n_edges, net.n_nodes * net.dim)
        if est > budget:
            record("first order (basis)", None, 0,
                   skipped=f"dense SVD estimated {est:.0f} s of CPU time")
        else:
            t0 = _clock()
            w = self_stress_basis(net, net.nodes)
            base["self_stresses"] = int(w.shape[1])
            points[-1]["self_stresses"] = base["self_stresses"]
            first_order("first order (basis)", _since(t0),
                        lambda k: play_ratio(w, gap[k], room_mm),
                        f"{w.shape[1]} states of self-stress: one build's LP over the basis "
                        f"passed the {budget:g} s CPU budget")

        first_order("first order (sparse LP)", (0.0, 0.0),
                    lambda k: play_ratio_sparse(net, gap[k], room_mm),
                    f"one build's LP passed the {budget:g} s CPU budget")

        t0, energy, stress, done_e = _clock(), [], [], 0
        for k in range(done):
            a = assemble(net.edges, rests[k], 0.0, x0,
                         stiffness=bar_stiffness(acrylic, SECTION_MM2, rests[k]), held=held)
            energy.append(a.energy)
            stress.append(float(np.abs(bar_stress(a, rests[k], acrylic.youngs_mpa)).max()))
            done_e += 1
            if _since(t0)[0] > budget:
                break
        record("elastic, no play", _since(t0), done_e,
               energy_mj=float(np.mean(energy)), max_stress_mpa=float(np.max(stress)))
    return points


def _clock() -> tuple[float, float]:
    """This process's CPU seconds and the wall clock, now."""
    return own_cpu_seconds(), time.perf_counter()


def _since(start: tuple[float, float]) -> tuple[float, float]:
    """CPU and wall seconds since ``start`` (from :func:`_clock`)."""
    cpu, wall = _clock()
    return cpu - start[0], wall - start[1]


def levels_line(p: dict) -> str:
    """One progress line for a measured point."""
    t = "skipped" if p["seconds_per_build"] is None else clock_text(
        p, "seconds_per_build", "wall_seconds_per_build", "s/build")
    if p.get("skipped"):
        return f"  {p['case']:<16} {p['level']:<24} {t:>30}  {p['skipped']}"
    says = ""
    if p.get("agrees") is not None:
        says = f"closes {100 * p['closes']:.0f}%, agrees with the assembly {100 * p['agrees']:.0f}%"
    elif p.get("closes") is not None:
        says = f"closes {100 * p['closes']:.0f}%"
    elif p.get("max_stress_mpa") is not None:
        says = f"forced: {p['energy_mj']:.3g} mJ, up to {p['max_stress_mpa']:.3g} MPa"
    return f"  {p['case']:<16} {p['level']:<24} {t:>30}  {says}"


def levels_figure(points):
    """CPU seconds per build against the network's edges, one line per level."""
    fig, ax = figure_kit.subplots(figsize=(7.5, 4.8))
    for k, level in enumerate(LEVELS):
        rows = [p for p in points if p["level"] == level and p["seconds_per_build"]]
        if rows:
            ax.loglog([p["edges"] for p in rows], [p["seconds_per_build"] for p in rows], "o-",
                      color=f"C{k}", label=level)
    ax.set_xlabel("bars (edges)")
    ax.set_ylabel("CPU seconds per build")
    ax.set_title("levels of model: AND gate and k x k 4-bar lattices")
    ax.legend(loc="upper left", fontsize=8)
    set_margins(fig, left=0.8, right=0.2, bottom=0.6, top=0.35)
    return fig
