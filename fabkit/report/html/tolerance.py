"""The tolerance section: what the design is for, the builds that keep it, the chart of the
builds kept against the error scale with its margin, the ports and the predictability horizon."""

from __future__ import annotations

import numpy as np

from ..text import jsonable, MADE_FOR
from .common import esc, fmt_value, img, LAYER_COLOURS



def _unit(criterion: dict) -> str:
    """The unit after a criterion's number when it is not mm (an origami state's folds, °)."""
    unit = criterion.get("unit", "mm")
    return "" if unit == "mm" else unit

def keep_chart_svg(tol: dict) -> str:
    """Inline SVG: fraction of builds that keep the design's behaviour against the error scale
    (log axis, 0.1× to 10× the process's errors), a curve per error source alone and a thick one
    for all together, the line ``min_reached`` and the margin where the thick curve meets it.

    Parameters
    ----------
    tol : dict
        The ``tolerance`` part of report.json (``keep_curves``, ``margin``, ``min_reached``).

    Returns
    -------
    str
        ``""`` when the report has no curves.
    """
    curves = tol.get("keep_curves") or {}
    scales = curves.get("scales") or []
    if not scales or "all" not in curves:
        return ""
    w, h, left, bottom, top, right = 560, 300, 52, 40, 14, 150
    pw, ph = w - left - right, h - top - bottom

    def x(sv):
        return left + pw * (np.log10(sv) + 1.0) / 2.0

    def y(frac):
        return top + ph * (1.0 - frac)

    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}" width="{w}" '
             f'height="{h}" role="img" aria-label="builds that keep the behaviour against the '
             'error scale" font-size="11" font-family="sans-serif">',
             f'<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="#fff" '
             'stroke="#999"/>']
    for sv in (0.1, 0.2, 0.5, 1, 2, 5, 10):
        parts.append(f'<line x1="{x(sv):.1f}" y1="{top}" x2="{x(sv):.1f}" y2="{top + ph}" '
                     f'stroke="#eee"/><text x="{x(sv):.1f}" y="{top + ph + 14}" '
                     f'text-anchor="middle">{sv:g}×</text>')
    for fr in (0, 0.25, 0.5, 0.75, 1):
        parts.append(f'<text x="{left - 6}" y="{y(fr) + 4:.1f}" text-anchor="end">'
                     f'{100 * fr:.0f}%</text>')
    parts.append(f'<text x="{left + pw / 2:.0f}" y="{h - 6}" text-anchor="middle">error scale '
                 "(× the process's own errors)</text>")
    need = float(tol.get("min_reached", 0.95))
    parts.append(f'<line x1="{left}" y1="{y(need):.1f}" x2="{left + pw}" y2="{y(need):.1f}" '
                 'stroke="#d62728" stroke-dasharray="5 3"/>')
    parts.append(f'<line x1="{x(1):.1f}" y1="{top}" x2="{x(1):.1f}" y2="{top + ph}" '
                 'stroke="#888" stroke-dasharray="2 3"/>')
    names = [n for n in curves if n not in ("scales", "all")] + ["all"]
    for k, name in enumerate(names):
        pts = " ".join(f"{x(sv):.1f},{y(fr):.1f}" for sv, fr in zip(scales, curves[name]))
        colour = "#000" if name == "all" else LAYER_COLOURS[(k + 1) % len(LAYER_COLOURS)]
        width = 3 if name == "all" else 1.5
        label = "all sources" if name == "all" else f"{name} alone"
        parts.append(f'<polyline fill="none" stroke="{colour}" stroke-width="{width}" '
                     f'points="{pts}"><title>{esc(label)}</title></polyline>')
        ly = top + 14 + 16 * k
        parts.append(f'<line x1="{left + pw + 10}" y1="{ly - 4}" x2="{left + pw + 28}" '
                     f'y2="{ly - 4}" stroke="{colour}" stroke-width="{width}"/>'
                     f'<text x="{left + pw + 32}" y="{ly}">{esc(label)}</text>')
    value = tol.get("margin")
    if value is not None:
        from ...tolerance.margin import margin_text

        label = esc(margin_text(value, tol.get("margin_bound")))
        parts.append(f'<circle cx="{x(value):.1f}" cy="{y(need):.1f}" r="4" fill="#d62728">'
                     f'<title>margin {label}</title></circle>'
                     f'<text x="{x(value) + 6:.1f}" y="{y(need) + 14:.1f}" fill="#d62728">'
                     f'margin {label}</text>')
    parts.append("</svg>")
    return "".join(parts)


def tolerance_section(report, files: dict) -> str:
    """The Tolerance section (``""`` when the analysis did not run)."""
    if report.tolerance is None:
        return ""
    tol = jsonable(report.tolerance.as_dict())
    chaos = report.tolerance.flagged and (tol["behaviour"] or {}).get("chaos") is not None
    cls = "note" if chaos else ("bad" if tol["flagged"] else "ok")
    parts = [f"<p>Judged as {esc(MADE_FOR[tol['process']])}: {esc(tol['model'])}; "
             f"{tol['samples']} simulated builds.</p>",
             f"<p class=\"{cls}\">{esc(tol['verdict'])}</p>"]
    b = tol["behaviour"] or {}
    if b:
        how = "stated in the template" if b["intent"] != "auto" else \
            "inferred from its map and motion"
        bits = [f"{c['role']} crystal D* = {fmt_value(c['value'])} ({c['kind']})"
                for c in b["crystals"]]
        if b["order"]:
            bits.append(f"the front runs {b['order']}")
        bits.append(f"judged at the end by its {b['end']} ({b['end_at']})")
        parts.append(f"<p>What the design is for ({how}): {esc('; '.join(bits))}.</p>")
    rows = "".join(
        f"<tr><td>{esc(c['criterion'])}</td><td>{100 * c['kept_fraction']:.1f}%</td>"
        f"<td>{fmt_value(c['p95_mm']) + _unit(c) if c['criterion'] != 'order' else '–'}</td>"
        f"<td>{fmt_value(c['limit_mm']) + _unit(c) if c['criterion'] != 'order' else '–'}</td>"
        f"<td>{c['missing']}</td></tr>" for c in tol["criteria"])
    if rows:
        parts.append("<div class=\"scroll\"><table><tr><th>criterion</th><th>builds that keep "
                     "it</th><th>95% of builds (mm)</th><th>allowed (mm)</th><th>no such state"
                     "</th></tr>" + rows + "</table></div>")
    chart = keep_chart_svg(tol)
    if chart:
        from ...tolerance.margin import margin_text

        alone = ", ".join(f"{esc(n)} {esc(margin_text(v['value'], v['bound']))}"
                          for n, v in tol["source_margins"].items())
        parts.append(f"<p>Margin {esc(margin_text(tol['margin'], tol['margin_bound']))}"
                     ": every error of the process may grow by this factor and the verdict stays "
                     "the same" + (f"; each source alone: {alone}" if alone else "") + ".</p>"
                     f'<div class="inline-svg scroll">{chart}</div>')
    if tol["ports_judged"]:
        rows = "".join(f"<tr><td>{esc(p['port'])}</td><td>{fmt_value(p['nominal'])}</td>"
                       f"<td>{fmt_value(p['mean'])}</td><td>{fmt_value(p['p95_abs_error_mm'])}</td>"
                       f"<td>{fmt_value(p['limit_mm'])}</td></tr>" for p in tol["ports"])
        if rows:
            parts.append("<div class=\"scroll\"><table><tr><th>port</th><th>designed</th>"
                         "<th>built (mean)</th><th>95% error (mm)</th><th>limit (mm)</th></tr>"
                         + rows + "</table></div>")
    hz = tol["horizon"]
    if hz:
        parts.append(f"<p>Lyapunov exponent λ = {fmt_value(hz.get('lyapunov'))} per module "
                     f"({esc(hz.get('source'))}): {esc(hz.get('detail'))}.</p>")
    name = "preview_tolerance.png"
    if name in files:
        parts.append(img(name, files[name], "tolerance"))
    return "<section id=tolerance><h2>Tolerance</h2>" + "".join(parts) + "</section>"
