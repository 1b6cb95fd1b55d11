"""The pictures of a tolerance analysis: how many builds keep the behaviour as errors grow, what
each criterion measured, and how it varies along the chain."""

from __future__ import annotations

import numpy as np

from ..plots.viz import figure_kit, plain_log_ticks, set_margins
from .result import ToleranceResult

__all__ = ["tolerance_figure", "keep_chart"]

#: Floor of the log-scale error plot (an exact zero has no logarithm).
LOG_FLOOR = 1e-12
#: Characters per line of the verdict over the three panels (8 pt on a 14 in figure).
TITLE_CHARS = 190


def _chart(ax, result: ToleranceResult) -> None:
    m = result.margin or {}
    curves = m.get("curves") or {}
    scales = np.asarray(curves.get("scales", []))
    if scales.size:
        for k, (name, y) in enumerate((n, v) for n, v in curves.items()
                                      if n not in ("scales", "all")):
            ax.semilogx(scales, 100 * np.asarray(y), "-", lw=1.2, color=f"C{k + 1}",
                        label=f"{name} alone")
        ax.semilogx(scales, 100 * np.asarray(curves["all"]), "-", lw=2.5, color="k",
                    label="all sources")
        plain_log_ticks(ax.xaxis)
    ax.axhline(100 * result.spec.min_reached, color="C3", ls="--", lw=1)
    ax.axvline(1.0, color="0.5", ls=":", lw=1)
    value, bound = m.get("value"), m.get("bound")
    if value is not None:
        label = {"at least": "≥ ", "below": "< "}.get(bound, "")
        ax.plot([value], [100 * result.spec.min_reached], "o", color="C3")
        ax.annotate(f"margin {label}{value:.2g}", (value, 100 * result.spec.min_reached),
                    textcoords="offset points", xytext=(6, -14), fontsize=8, color="C3")
    ax.set_xlim(0.1, 10.0)
    ax.set_ylim(-3, 103)
    ax.set_xlabel("error scale (× the process's own errors)")
    ax.set_ylabel("builds that keep the behaviour (%)")
    ax.set_title("how precise must the process be?", fontsize=10)
    ax.legend(fontsize=7, loc="lower left")


def keep_chart(result: ToleranceResult, *, title: str | None = None):
    """Fraction of builds that keep the design's behaviour against the error scale (0.1× to
    10× the process's errors): one curve per error source alone, one for all together, the
    margin where the latter meets ``min_reached``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = figure_kit.subplots(figsize=(6.4, 4.2))
    _chart(ax, result)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return fig


def tolerance_figure(result: ToleranceResult, *, title: str | None = None):
    """Three panels: the keep chart (:func:`keep_chart`), each criterion's number per build
    against what it allows, and the number along the chain (95% of builds).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import textwrap

    head = textwrap.wrap(f"{title + ': ' if title else ''}{result.verdict}", TITLE_CHARS)
    fig, axes = figure_kit.subplots(1, 3, figsize=(14, 4.2 + 0.16 * len(head)))
    _chart(axes[0], result)
    ax = axes[1]
    judged = [(n, j) for n, j in result.judged.items() if n != "order"]
    for k, (name, j) in enumerate(judged):
        v = np.asarray(j.value_mm, dtype=np.float64)
        lim = max(j.limit_mm, LOG_FLOOR)
        ratio = np.where(np.isfinite(v), v / lim, np.nan)
        missing = int(np.sum(~np.isfinite(v)))
        y = k + 0.3 * (np.random.default_rng(k).random(v.size) - 0.5)
        ax.plot(np.maximum(ratio, LOG_FLOOR), y, ".", ms=3, color=f"C{k}")
        text = f"{name}: {100 * j.ok.mean():.0f}% within {j.limit_mm:.3g}" + \
            (" mm" if j.unit == "mm" else j.unit)
        if missing:
            text += f" ({missing} with no such state)"
        ax.annotate(text, (0.02, k + 0.3), xycoords=("axes fraction", "data"), fontsize=8)
    ax.axvline(1.0, color="C3", ls="--", lw=1)
    ax.set_xscale("log")
    plain_log_ticks(ax.xaxis)
    ax.set_yticks([])
    ax.set_ylim(-0.6, max(len(judged), 1) - 0.2)
    ax.set_xlabel("measured / allowed (per build, worst part)")
    ax.set_title("what each build was judged on", fontsize=10)
    ax = axes[2]
    shown = False
    for k, (name, j) in enumerate(judged):
        per = getattr(j, "per_part", None)
        if per is None or per.ndim != 2 or per.shape[1] < 2:
            continue
        p95 = np.percentile(per, 95, axis=0, method="higher")
        x = np.arange(1, per.shape[1] + 1)
        ax.semilogy(x, np.maximum(p95, LOG_FLOOR), "o-", ms=3, color=f"C{k}",
                    label=f"{name} (95%)")
        ax.axhline(j.limit_mm, color=f"C{k}", ls="--", lw=0.8)
        shown = True
    if shown:
        plain_log_ticks(ax.yaxis)
        ax.legend(fontsize=8)
        ax.set_xlabel("module or port, along the chain")
        ax.set_ylabel("mm")
    else:
        ax.text(0.5, 0.5, "a single part", ha="center", va="center", transform=ax.transAxes)
    ax.set_title("along the chain", fontsize=10)
    fig.suptitle("\n".join(head), fontsize=8)
    # fixed margins (figure_png checks them on its drawing): a layout engine would lay the
    # figure out once more; the verdict's lines (8 pt) above the panels' titles
    set_margins(fig, left=0.75, right=0.2, bottom=0.6, top=0.42 + 0.16 * len(head), gap=0.85)
    return fig
