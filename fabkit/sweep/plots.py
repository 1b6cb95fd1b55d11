"""Pictures of a sweep: a bifurcation diagram for one varied key, heat maps for two.

Points whose status is not ``ok`` are drawn as such (a marker per status on the diagram, a
colour per status on the heat maps), never left blank without a legend.
"""

from __future__ import annotations

import numpy as np

from ..plots.viz import figure_kit
from .model import COLUMNS, MEASURES, key_path, lookup_number

__all__ = ["figures", "bifurcation_figure", "heatmap_figure", "STATUS_STYLE"]

#: Marker, colour and legend text of every status other than ``ok``.
STATUS_STYLE = {
    "flat": ("X", "#d62728", "flat state at the start"),
    "rigid": ("s", "#111111", "rigid (no motion)"),
    "no_motion": ("v", "#9467bd", "motion does not move d1"),
    "escapes": ("^", "#ff7f0e", "orbits leave the domain"),
    "failed": ("D", "#7f7f7f", "failed"),
}


def figures(result) -> dict:
    """``{file name: Figure}`` for a sweep: ``bifurcation.png`` (1-D) or one
    ``heatmap_<column>.png`` per scalar measure (2-D); nothing for more axes."""
    axes = result.spec.axes
    if len(axes) == 1:
        return {"bifurcation.png": bifurcation_figure(result)}
    if len(axes) == 2:
        out = {}
        for col in _heat_columns(result):
            out[f"heatmap_{col}.png"] = heatmap_figure(result, col)
        if not out:  # only statuses to show (e.g. a rigid family)
            out["heatmap_status.png"] = heatmap_figure(result, None)
        return out
    return {}


def _template_value(result, key):
    """The value the template itself has at a varied key (where its own module sits)."""
    raw = result.spec.raw
    return float(lookup_number(raw, key_path(key, raw), key))


def _template_name(result) -> str:
    raw = result.spec.raw
    name = raw.get("name")
    if isinstance(name, str):
        return name
    from pathlib import Path

    return Path(result.spec.template).stem


def bifurcation_figure(result, title: str | None = None):
    """Attractor values of the iterated map against the varied key, with the fixed points and
    2-cycles (stable: solid, unstable: hollow), the Lyapunov exponent below when measured, and
    every point that is not ``ok`` marked by its status.

    Returns
    -------
    matplotlib.figure.Figure
    """
    key = result.spec.axes[0].key
    x = np.array(result.spec.axes[0].values)
    recs = result.records
    has_ly = "lyapunov" in result.spec.measures
    if has_ly:
        fig, (ax, ax2) = figure_kit.subplots(2, 1, figsize=(11.5, 7.5), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 1.3]})
    else:
        fig, ax = figure_kit.subplots(figsize=(11.5, 5.5))
        ax2 = None
    # attractor: every value the settled orbits visit
    xs, ys = [], []
    for xi, r in zip(x, recs):
        v = r.get("attractor_values") or []
        xs.extend([xi] * len(v))
        ys.extend(v)
    if xs:
        ax.plot(xs, ys, ".", ms=1.2, color="k", alpha=0.5, rasterized=True)
        ax.plot([], [], "s", ms=3, color="k", label="attractor (settled orbits)")
    for kind_stable, style in ((True, dict(ms=2.5, mfc="C0", mec="C0")),
                               (False, dict(ms=2.5, mfc="none", mec="C0", mew=0.6))):
        fx = [(xi, p["value"]) for xi, r in zip(x, recs) for p in r.get("fixed_points") or []
              if (p["kind"] in ("stable", "super-stable")) == kind_stable]
        if fx:
            a = np.array(fx)
            ax.plot(a[:, 0], a[:, 1], "o", **style, zorder=3,
                    label="fixed point, " + ("stable" if kind_stable else "unstable"))
        cx = [(xi, v) for xi, r in zip(x, recs) for c in r.get("cycles") or []
              if (c["kind"] in ("stable", "super-stable")) == kind_stable for v in c["values"]]
        if cx:
            a = np.array(cx)
            st = dict(style, mfc="C2" if kind_stable else "none", mec="C2")
            ax.plot(a[:, 0], a[:, 1], "o", **st, zorder=3,
                    label="2-cycle, " + ("stable" if kind_stable else "unstable"))
    ax.set_ylabel("d (attractor values of d_{k+1} = f(d_k))")
    _status_strip(ax, x, recs)
    _mark_template(result, key, [ax] + ([ax2] if ax2 is not None else []))
    if ax2 is not None:
        ly = result.column("lyapunov")
        ax2.plot(x, ly, "-", color="C3", lw=1)
        ax2.axhline(0.0, color="0.5", lw=0.8)
        ax2.set_ylabel("Lyapunov exponent λ")
        ax2.set_xlabel(key)
        _status_strip(ax2, x, recs, legend=False)
    else:
        ax.set_xlabel(key)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    ax.set_title(title or f"{_template_name(result)}: bifurcation diagram over {key}")
    fig.tight_layout()
    return fig


def _status_strip(ax, x, recs, legend=True):
    """Points that are not ok: a shaded band and a marker on the axis' lower edge."""
    lo, hi = ax.get_ylim()
    dx = (x[1] - x[0]) if x.size > 1 else 1.0
    for status, (marker, colour, text) in STATUS_STYLE.items():
        sel = np.array([r["status"] == status for r in recs])
        if not sel.any():
            continue
        for xi in x[sel]:
            ax.axvspan(xi - dx / 2, xi + dx / 2, color=colour, alpha=0.12, lw=0)
        ax.plot(x[sel], np.full(sel.sum(), lo), marker, color=colour, ms=5, clip_on=False,
                zorder=4, label=f"{text} ({sel.sum()})" if legend else None)
    ax.set_ylim(lo, hi)


def _mark_template(result, key, axes):
    """A line where the template's own module sits, and what the sweep found there."""
    x0 = _template_value(result, key)
    values = np.array(result.spec.axes[0].values)
    if not values.min() <= x0 <= values.max():
        return
    name = _template_name(result)
    for k, ax in enumerate(axes):
        ax.axvline(x0, color="C6", lw=1.2, ls="--", zorder=1,
                   label=f"{name} (the template: {key} = {x0:g})" if k == 0 else None)
    rec = result.records[int(np.argmin(np.abs(values - x0)))]
    found = [f"{name}: {rec['status']}"]
    period, lam = rec.get("attractor_period"), rec.get("lyapunov")
    if period is not None and period > 0:
        found.append(f"period-{period} attractor")
    elif period == 0:  # chaos only when the exponent says so too
        found.append("no period, chaotic" if lam is not None and lam > 0 else "no period found")
    if lam is not None:
        found.append(f"λ = {lam:.3f}")
    axes[0].annotate(", ".join(found), xy=(x0, 1.0), xycoords=("data", "axes fraction"),
                     xytext=(4, -12), textcoords="offset points", fontsize=8, color="C6")


_LABELS = {
    "fixed_count": "number of fixed points",
    "fixed_value": "fixed point D* (nearest the start)",
    "fixed_slope": "slope f'(D*)",
    "slope_reference": "slope f'(d1) at the start",
    "cycle2_count": "number of 2-cycles",
    "cycle2_low": "2-cycle: lower value",
    "cycle2_high": "2-cycle: upper value",
    "cycle2_multiplier": "2-cycle multiplier",
    "lyapunov": "Lyapunov exponent λ",
    "lyapunov_std": "spread of λ over orbits",
    "modes_conformational": "conformational motions",
    "modes_self_stress": "states of self-stress",
    "attractor_period": "attractor period (0: none found, e.g. chaos)",
    "attractor_min": "attractor: smallest value",
    "attractor_max": "attractor: largest value",
}


# whole-number columns, drawn with one colour per value (and names for special values)
_DISCRETE = {
    "attractor_period": {0: "none found", -1: "escapes"},
    "fixed_count": {},
    "cycle2_count": {},
    "modes_conformational": {},
    "modes_self_stress": {},
}


def _heat_columns(result):
    return [c for m in MEASURES if m in result.spec.measures for c in COLUMNS[m]
            if np.isfinite(result.column(c)).any()]


def heatmap_figure(result, column: str | None, title: str | None = None):
    """One scalar column over a 2-D grid; points that are not ``ok`` in their status colour.

    Parameters
    ----------
    result : SweepResult
    column : str or None
        A column of the table (None: the statuses alone).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.colors import ListedColormap, TwoSlopeNorm
    from matplotlib.patches import Patch

    ax_, ay = result.spec.axes  # the first key along x
    xv, yv = np.array(ax_.values), np.array(ay.values)
    shape = result.spec.shape
    fig, ax = figure_kit.subplots(figsize=(7.5, 6))

    def edges(v):
        if v.size == 1:
            return np.array([v[0] - 0.5, v[0] + 0.5])
        mid = 0.5 * (v[1:] + v[:-1])
        return np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])

    # cells in ascending order of both keys, whatever order the values were given in
    ox, oy = np.argsort(xv, kind="stable"), np.argsort(yv, kind="stable")
    xv, yv = xv[ox], yv[oy]
    X, Y = edges(xv), edges(yv)
    # records run with the first key slowest: (n_x, n_y); a mesh wants rows along y
    status = np.array([r["status"] for r in result.records]).reshape(shape).T[np.ix_(oy, ox)]
    if column is not None:
        z = result.column(column).reshape(shape).T[np.ix_(oy, ox)]
        z = np.where(status == "ok", z, np.nan)
        finite = z[np.isfinite(z)]
        bad = (1, 1, 1, 0)
        if column in _DISCRETE and finite.size:
            # whole numbers (periods, counts): one colour per value found
            levels = np.unique(finite)
            cmap = ListedColormap(figure_kit.get_cmap("viridis")(np.linspace(0, 1, levels.size)))
            idx = np.where(np.isfinite(z), np.searchsorted(levels, np.nan_to_num(z)), np.nan)
            mesh = ax.pcolormesh(X, Y, np.ma.masked_invalid(idx),
                                 cmap=cmap.with_extremes(bad=bad), shading="flat",
                                 vmin=-0.5, vmax=levels.size - 0.5)
            bar = fig.colorbar(mesh, ax=ax, label=_LABELS.get(column, column),
                               ticks=np.arange(levels.size))
            names = _DISCRETE[column]
            bar.ax.set_yticklabels([names.get(int(v), f"{int(v)}") for v in levels])
        else:
            kw = {}
            cmap = figure_kit.get_cmap("viridis")
            if column == "lyapunov" and finite.size and finite.min() < 0 < finite.max():
                # λ = 0 is white: chaos red, cycles blue, each side on its own scale
                cmap = figure_kit.get_cmap("RdBu_r")
                kw = dict(norm=TwoSlopeNorm(0.0, float(finite.min()), float(finite.max())))
            mesh = ax.pcolormesh(X, Y, np.ma.masked_invalid(z), cmap=cmap.with_extremes(bad=bad),
                                 shading="flat", **kw)
            fig.colorbar(mesh, ax=ax, label=_LABELS.get(column, column))
    handles = []
    for s, (_, colour, text) in STATUS_STYLE.items():
        mask = status == s
        if not mask.any():
            continue
        ax.pcolormesh(X, Y, np.ma.masked_where(~mask, np.ones(mask.shape)),
                      cmap=ListedColormap([colour]), shading="flat")
        handles.append(Patch(color=colour, label=f"{text} ({int(mask.sum())})"))
    try:
        x0, y0 = _template_value(result, ax_.key), _template_value(result, ay.key)
        if xv.min() <= x0 <= xv.max() and yv.min() <= y0 <= yv.max():
            ax.plot([x0], [y0], "*", ms=14, mfc="w", mec="k", zorder=5)
            handles.append(figure_kit.Line2D([], [], ls="", marker="*", ms=10, mfc="w", mec="k",
                                      label=f"{_template_name(result)} (the template)"))
    except (KeyError, ValueError):
        pass
    if handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(0, -0.1), ncol=2,
                  fontsize=7, frameon=False)
    ax.set_xlabel(ax_.key)
    ax.set_ylabel(ay.key)
    what = _LABELS.get(column, column) if column else "status of every point"
    ax.set_title(title or f"{_template_name(result)}: {what}", fontsize=10)
    fig.tight_layout()
    return fig
