"""Pictures of 1-D maps: the map with the identity line, cobweb diagrams, Lyapunov exponents,
and solution spaces of a module design (matplotlib figures; saving is the caller's job, e.g.
with :func:`fabkit.plots.viz.figure_png`)."""

from __future__ import annotations

import numpy as np

from ..maps import Map1D
from .viz import figure_kit, set_margins

__all__ = ["map_figure", "cobweb_figure", "lyapunov_figure", "solution_space_figure"]

# marker fill by stability: stable points filled, unstable hollow
_FILLED = {"stable": True, "super-stable": True, "neutral": True, "unstable": False,
           "super-unstable": False}


def _mark_points(ax, fmap: Map1D, fixed, cycles):
    for p in fixed:
        ax.plot([p.value], [p.value], "o", ms=8, color="C3",
                mfc="C3" if _FILLED[p.kind] else "white", zorder=5,
                label=f"D* = {p.value:.6g} (s = {p.slope:.3g}, {p.kind})")
    for k, c in enumerate(cycles):
        v = np.array(c.values + (c.values[0],))
        ax.plot(v[:-1], v[1:], "s", ms=7, color=f"C{4 + k % 5}",
                mfc=f"C{4 + k % 5}" if _FILLED[c.kind] else "white", zorder=5,
                label=f"{c.period}-cycle {', '.join(f'{x:.5g}' for x in c.values)} "
                      f"(s = {c.multiplier:.3g}, {c.kind})")


def map_figure(fmap: Map1D, *, fixed=None, cycles=None, title: str | None = None):
    """The map d_out = f(d_in): the whole motion's curve in grey, the branch used in blue, the
    identity line, fixed points (filled: stable, hollow: unstable) and cycles.

    Parameters
    ----------
    fmap : Map1D
    fixed, cycles : lists, optional
        Precomputed ``fmap.fixed_points()`` / ``fmap.cycles(m)`` (computed when omitted).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fixed = fmap.fixed_points() if fixed is None else fixed
    cycles = fmap.cycles(2) if cycles is None else cycles
    fig, ax = figure_kit.subplots(figsize=(6.2, 6.2))
    lo_all, hi_all = fmap.domain
    for br, d, f in fmap.curve():
        if br is not None and fmap.branch is not None and br.index == fmap.branch.index:
            continue
        ax.plot(d, f, "-", color="0.75", lw=1)
        lo_all, hi_all = min(lo_all, np.nanmin(d)), max(hi_all, np.nanmax(d))
    g = np.linspace(*fmap.domain, 800)
    ax.plot(g, fmap._values(g)[0], "-", color="C0", lw=2.2, label=f"branch used: {fmap.name}")
    ax.plot([lo_all, hi_all], [lo_all, hi_all], "--", color="0.4", lw=1, label="identity")
    _mark_points(ax, fmap, fixed, cycles)
    ax.set_xlabel("dₖ, input of module k (design units)")
    ax.set_ylabel("dₖ₊₁ = f(dₖ), its output (design units)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(title or "map and its whole motion (grey)")
    ax.legend(fontsize=7, loc="best")
    set_margins(fig, left=0.8, right=0.25, bottom=0.65, top=0.45)
    return fig


def cobweb_figure(fmap: Map1D, d1_values, steps: int = 16, *, title: str | None = None):
    """Cobweb diagrams of orbits from one or several initial d1 (the paper's Fig. 2c/f/i/l).

    Each orbit is drawn as vertical moves d_k -> d_{k+1} = f(d_k) and horizontal moves to the
    identity line; d_k are marked as squares. An orbit that leaves the map's domain stops there
    (the chain has no configuration beyond it), which the legend says.

    Parameters
    ----------
    fmap : Map1D
    d1_values : sequence of float
    steps : int
        Map iterations (modules in the chain).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = figure_kit.subplots(figsize=(6.2, 6.2), layout="constrained")
    g = np.linspace(*fmap.domain, 800)
    ax.plot(g, fmap._values(g)[0], "-", color="k", lw=1.5, label=fmap.name)
    ax.plot(fmap.domain, fmap.domain, "--", color="0.5", lw=1)
    cmap = figure_kit.get_cmap("Blues")
    vals = list(np.atleast_1d(d1_values))
    for n, d1 in enumerate(vals):
        color = cmap(0.9 - 0.6 * n / max(len(vals) - 1, 1))
        orbit = fmap.orbit(float(d1), steps)
        xs, ys = [orbit[0]], [orbit[0]]
        for a, b in zip(orbit[:-1], orbit[1:]):
            xs += [a, b]
            ys += [b, b]
        cut = "" if orbit.size == steps + 1 else f", leaves the domain after {orbit.size - 1}"
        ax.plot(xs, ys, "-", color=color, lw=1.2, label=f"$d_1$ = {d1:.6g}{cut}")
        ax.plot(orbit[:-1], orbit[1:], "s", ms=4, color=color)
    ax.set_xlabel("dₖ")
    ax.set_ylabel("dₖ₊₁")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(title or f"cobweb: {steps} iterations")
    ax.legend(fontsize=7, loc="best")
    return fig


def lyapunov_figure(result, *, title: str | None = None):
    """Lyapunov exponent of each orbit against its initial value, and their distribution.

    Parameters
    ----------
    result : LyapunovResult

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, (ax1, ax2) = figure_kit.subplots(1, 2, figsize=(10, 4), layout="constrained")
    ok = np.isfinite(result.values)
    ax1.plot(result.initial[ok], result.values[ok], ".", ms=2)
    ax1.axhline(result.mean, color="C3", lw=1)
    ax1.set_xlabel("initial $d_1$")
    ax1.set_ylabel("λ")
    ax2.hist(result.values[ok], bins=40, color="C0")
    ax2.axvline(result.mean, color="C3", lw=1, label=f"mean {result.mean:.4f} ± {result.std:.4f}")
    ax2.set_xlabel("λ")
    ax2.legend(fontsize=8)
    fig.suptitle(title or f"Lyapunov exponents ({ok.sum()} orbits, {result.discard} discarded, "
                          f"{result.average} averaged)")
    return fig


def solution_space_figure(spaces, *, variable=None, extent: float | None = None, title=None):
    """2D solution spaces as curves (zero level of their quadratic forms), designed nodes
    (with velocity arrows / final positions) and chosen variable nodes.

    Parameters
    ----------
    spaces : sequence of SolutionSpace
    variable : array_like, shape (m, 2), optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = figure_kit.subplots(figsize=(6, 6), layout="constrained")
    first = spaces[0]
    c = first.designed.mean(axis=0)
    R = extent or 3.0 * first.scale
    xs = np.linspace(c[0] - R, c[0] + R, 400)
    ys = np.linspace(c[1] - R, c[1] + R, 400)
    X, Y = np.meshgrid(xs, ys)
    pts = np.stack([X.ravel(), Y.ravel()], axis=1)
    colors = {"velocity": "C0", "displacement": "C2"}
    for s in spaces:
        Z = s.evaluate(pts).reshape(X.shape)
        ax.contour(X, Y, Z, levels=[0.0], colors=colors.get(s.kind, "C1"))
        ax.plot([], [], "-", color=colors.get(s.kind, "C1"), label=f"{s.kind} space")
        if s.kind == "velocity":
            ax.quiver(*s.designed.T, *s.target.T, color="C3", angles="xy", scale_units="xy",
                      scale=1, width=0.004)
        else:
            ax.plot(*s.target.T, "o", mfc="white", color="C3", label="final designed nodes")
    ax.plot(*first.designed.T, "o", color="C3", label="designed nodes")
    if variable is not None:
        v = np.asarray(variable)
        ax.plot(v[:, 0], v[:, 1], "o", color="C0", ms=8, label="variable nodes")
    ax.set_aspect("equal")
    ax.legend(fontsize=8, loc="best")
    ax.set_title(title or "solution spaces of a variable node")
    return fig
