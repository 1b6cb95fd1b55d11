"""The verdict that heads a design's page, and the table of every check: each format's
as-built checks and warnings, the tolerance analysis, the motion's designed ends and spread."""

from __future__ import annotations

from .common import esc, fmt_value, level_span, pass_span


def _spread_strip(spread) -> str:
    """The chain's modules as a strip of cells, each as dark as far as its output went (of
    the drive's travel; a module past the state tolerance is outlined)."""
    cells = []
    for k, (r, moved) in enumerate(zip(spread.reach.tolist(), spread.moved.tolist()), 1):
        light = 92 - 62 * min(max(r, 0.0), 1.0)
        edge = "#263238" if moved else "#cfd8dc"
        cells.append(f'<i style="background:hsl(210,60%,{light:.0f}%);border-color:{edge}" '
                     f'title="module {k}: {r:.2g} of the drive\'s travel"></i>')
    return f'<span class="strip">{"".join(cells)}</span>'


def verdict_section(report) -> str:
    """The Verdict section that opens the page: the level, the finding that set it, and the
    other findings."""
    v = report.verdict
    cls = {"ok": "ok", "by design": "by-design"}.get(str(v.status), str(v.status))
    rows = "".join(f"<li>{level_span(f.level)} {esc(f.about)}: {esc(f.text)}</li>"
                   for f in v.findings[1:])
    return (f'<section id=verdict class="verdict {cls}"><h2>Verdict: {level_span(v.status)}</h2>'
            f"<p>{esc(v.message)}</p>" + (f"<ul>{rows}</ul>" if rows else "")
            + "</section>")


def checks_section(report) -> str:
    """The Checks section: a row per check of every format, the tolerance analysis, the
    motion's designed ends and spread, and every error; ``""`` when there is none."""
    rows = [row for fmt, f in sorted(report.formats.items()) for row in _format_rows(fmt, f)]
    rows += _tolerance_rows(report.tolerance) + _motion_rows(report.motion)
    for e in report.errors:
        rows.append(f'<tr><td colspan=5 class="bad">{esc(e)}</td></tr>')
    if not rows:
        return ""
    return ("<section id=checks><h2>Checks</h2><div class=\"scroll\"><table><tr><th>check</th>"
            "<th>result</th><th>value</th><th>limit</th><th>detail</th></tr>" + "".join(rows)
            + "</table></div></section>")


def _format_rows(fmt: str, f) -> list[str]:
    """One format: its status, each as-built check of each file read back, its warnings."""
    rows = [f"<tr><th colspan=5>{esc(fmt)}: {esc(f.status)}"
            + (f" – {esc(f.message)}" if f.message else "") + "</th></tr>"]
    for res in f.checks:
        if res.error:
            rows.append(f"<tr><td>{esc(res.file)}</td><td>{pass_span(False)}</td>"
                        f"<td colspan=3>{esc(res.error)}</td></tr>")
        for c in res.checks:
            rows.append(f"<tr><td>{esc(res.file)}: {esc(c['name'])}</td>"
                        f"<td>{pass_span(c['ok'])}</td><td>{esc(fmt_value(c.get('value')))}"
                        f"</td><td>{esc(fmt_value(c.get('limit')))}</td>"
                        f"<td>{esc(c.get('detail', ''))}</td></tr>")
    for w in (f.report.get("warnings") or [] if f.status.produced else []):
        rows.append(f'<tr><td colspan=5 class="warn">warning: {esc(w)}</td></tr>')
    return rows


def _tolerance_rows(tol) -> list[str]:
    """The tolerance analysis as one check: ok, FLAG, or flagged by design (chaos)."""
    if tol is None:
        return []
    level = "by design" if tol.flagged and tol.behaviour is not None and \
        tol.behaviour.chaos is not None else ("FLAG" if tol.flagged else "ok")
    return [f"<tr><th colspan=5>tolerance</th></tr><tr><td>as built</td>"
            f"<td>{level_span(level)}</td><td colspan=3>{esc(tol.verdict)}</td></tr>"]


def _motion_rows(motion) -> list[str]:
    """The motion's designed ends and how far along a chain it spread, when judged."""
    spread = getattr(motion, "spread", None) if motion is not None else None
    ends = motion.ends if motion is not None else None
    if ends is None and spread is None:
        return []
    rows = ["<tr><th colspan=5>motion</th></tr>"]
    if ends is not None:
        rows.append(f"<tr><td>designed ends</td>"
                    f"<td>{pass_span(ends.reached)}</td>"
                    f"<td colspan=3>{esc(ends.reason or ends.basis)}</td></tr>")
    if spread is not None:
        word = '<span class="note">localised</span>' if spread.localised else \
            '<span class="ok">spread</span>'
        rows.append(f"<tr><td>modules moved</td><td>{word}"
                    f"</td><td>{int(spread.moved.sum())} of {spread.modules}</td>"
                    f"<td>{fmt_value(spread.tolerance)}</td><td>{_spread_strip(spread)} "
                    f"{esc(spread.sentence())}</td></tr>")
    return rows
