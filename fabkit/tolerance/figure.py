"""The picture of a tolerance analysis."""

from __future__ import annotations

import re

import numpy as np

from .result import ToleranceResult

#: Floor of the log-scale error plot (an exact zero has no logarithm).
LOG_FLOOR = 1e-12


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
