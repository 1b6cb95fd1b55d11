"""Pictures of designs made from wishes: a module with its map and wishes, a chain against the
curve it follows (matplotlib figures; saving is the caller's job)."""

from __future__ import annotations

import numpy as np

from ..numerics import apply_fit, rigid_fit
from .viz import draw_network, figure_kit

__all__ = ["module_design_figure", "curve_design_figure"]


def module_design_figure(result, title: str | None = None):
    """The designed module at its designed states, and its map with the wishes marked.

    Parameters
    ----------
    result : fabkit.design.MapDesign

    Returns
    -------
    matplotlib.figure.Figure
    """
    fmap, wish, net = result.map, result.wish, result.network
    fig, (ax, mx) = figure_kit.subplots(1, 2, figsize=(11, 5.2))
    states = [p.value for p in wish.fixed_points]
    if wish.cycle is not None:
        states = list(wish.cycle) + states
    shades = ["C0", "C1", "C2"]
    ref = net.nodes[[0, 1, 2]]
    for k, d in enumerate(states):
        x = fmap.configuration(d)
        # every state moved onto the reference triangle (node 1 up), so they overlay
        x = apply_fit(rigid_fit(x[[0, 1, 2]], ref), x)
        draw_network(ax, net, x, color=shades[k % 3], lw=2.0 if k == 0 else 1.2,
                     alpha=1.0 if k == 0 else 0.8)
        ax.plot(*x[[0, 1, 2]].T, ":", color=shades[k % 3], lw=0.8)
        if k == 0:
            for i, p in enumerate(x):
                ax.annotate(str(i), p, textcoords="offset points", xytext=(4, 4), fontsize=8)
        ax.plot([], [], "-", color=shades[k % 3], label=f"d1 = {d:.6g}")
    ax.set_title("module at its designed states (dotted: d1, d2 legs)")
    ax.legend(fontsize=8, loc="best")
    ax.set_axis_off()
    for br, d, f in fmap.curve():
        if fmap.branch is not None and br is not None and br.index == fmap.branch.index:
            continue
        mx.plot(d, f, "-", color="0.8", lw=1)
    g = np.linspace(*fmap.domain, 600)
    mx.plot(g, fmap._values(g)[0], "-", color="C0", lw=2, label="map on the designed branch")
    lo, hi = fmap.domain
    mx.plot([lo, hi], [lo, hi], "--", color="0.4", lw=1, label="d2 = d1")
    for p in wish.fixed_points:
        mx.plot([p.value], [p.value], "o", ms=9, mfc="none", mec="C3", mew=2)
        s = fmap.derivative(p.value)
        w = 0.08 * (hi - lo)
        mx.plot([p.value - w, p.value + w], [p.value - s * w, p.value + s * w], "-", color="C3",
                lw=1.5)
        label = f"fixed point {p.value:.6g}, slope {s:.3g}"
        mx.annotate(label, (p.value, p.value), textcoords="offset points", xytext=(8, -14),
                    fontsize=8, color="C3")
    if wish.cycle is not None:
        a, b = wish.cycle
        mx.plot([a, a, b, b, a], [a, b, b, a, a], "-", color="C2", lw=1)
        mx.plot([a, b], [b, a], "s", color="C2", ms=7, label=f"2-cycle {a:g} <-> {b:g}")
    mx.set_xlabel("$d_1$")
    mx.set_ylabel("$d_2 = f(d_1)$")
    mx.set_aspect("equal", adjustable="datalim")
    mx.legend(fontsize=8, loc="best")
    mx.set_title("map recomputed by fabkit.module_map (wishes in red)")
    fig.suptitle(title or f"fabkit design {wish.options()}", fontsize=10)
    fig.tight_layout()
    return fig


def curve_design_figure(result, title: str | None = None):
    """The chain's initial (straight) state above its traced final state over the curve.

    Parameters
    ----------
    result : fabkit.design.CurveDesign

    Returns
    -------
    matplotlib.figure.Figure
    """
    pts = result.curve.points
    fig, (top, ax) = figure_kit.subplots(2, 1, figsize=(8, 9),
                                         gridspec_kw={"height_ratios": [1, 3]})
    start = result.network.nodes * result.scale
    draw_network(top, result.network, start, color="C0", lw=0.8, nodes=False)
    top.set_title(f"initial state: straight ({len(result.names)} modules)")
    top.set_axis_off()
    ax.plot(*pts.T, "-", color="0.8", lw=8, zorder=1, label="drawn curve")
    draw_network(ax, result.network, result.final, color="C0", lw=0.8, nodes=False)
    ax.plot(*result.centerline.T, "-", color="C3", lw=1, label="chain's centre line")
    e = result.errors
    ax.set_title(f"traced final state over the curve (mm)\nmean distance {e['mean']:.2f} mm "
                 f"({100 * e['mean_fraction']:.2g} % of its size), max {e['max']:.2f} mm, "
                 f"ends {e['start']:.2f} / {e['end']:.2f} mm", fontsize=9)
    ax.legend(fontsize=8, loc="best")
    ax.set_aspect("equal")
    fig.suptitle(title or "fabkit design --curve", fontsize=10)
    fig.tight_layout()
    return fig
