"""Design reports: ``report.json`` (machine-readable) and ``report.md`` (for people), as bytes.

Both are pure functions of their input: no clock, no host name, no absolute path, keys sorted and
floats printed by ``repr``, so that the same design exported twice gives byte-identical reports.
:mod:`fabkit.batch` assembles the report dict from its typed results (``outcome`` is a
:class:`fabkit.batch.Outcome` value, each format's ``status`` a :class:`fabkit.batch.FormatStatus`
value); this module only turns it into bytes. The keys of report.json are listed in
docs/batch.md; readers should test ``outcome`` (and may fall back to ``ok`` for reports of
``report_version`` 1).
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np

__all__ = ["jsonable", "report_json", "report_markdown", "file_digest", "design_facts"]


def jsonable(value):
    """A copy of ``value`` that :func:`json.dumps` accepts and that prints the same every time.

    NumPy scalars and arrays become Python numbers and lists, tuples become lists, paths become
    strings, non-finite floats become ``None`` (JSON has no NaN), enums their value.

    Examples
    --------
    >>> jsonable({"a": np.float64(1.5), "b": (1, np.int64(2)), "c": float("nan")})
    {'a': 1.5, 'b': [1, 2], 'c': None}
    """
    from enum import Enum

    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, Enum):
        return jsonable(value.value)
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, Path):
        return value.as_posix()
    if value is None or isinstance(value, str):
        return value
    return str(value)


def report_json(report: dict) -> bytes:
    """``report.json`` bytes: sorted keys, two-space indent, trailing newline, UTF-8."""
    text = json.dumps(jsonable(report), indent=2, sort_keys=True, ensure_ascii=False,
                      allow_nan=False)
    return (text + "\n").encode("utf-8")


def file_digest(data: bytes) -> str:
    """SHA-256 of some bytes, hex (identifies a template or an output file in a report)."""
    return hashlib.sha256(data).hexdigest()


def design_facts(design) -> dict:
    """Name, description, template file name and digest, sizes and mode count of a design."""
    from .rigidity import count_modes

    net = design.network
    modes = count_modes(net)
    facts = {
        "name": design.name,
        "description": design.description,
        "figure": design.raw.get("figure", ""),
        "template": Path(design.path).name if design.path else "",
        "dim": net.dim,
        "nodes": net.n_nodes,
        "edges": net.n_edges,
        "ports": sorted(net.ports),
        "modes": {"total": modes.total, "rigid": modes.rigid,
                  "conformational": modes.conformational, "self_stress": modes.self_stress},
    }
    if design.path is not None and Path(design.path).is_file():
        facts["template_sha256"] = file_digest(Path(design.path).read_bytes())
    return facts


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if v is None:
        return "-"
    return str(v)


def _table(header, rows) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_fmt(c).replace("|", "\\|") for c in r) + " |" for r in rows]
    return lines


def _tolerance_markdown(tol) -> list[str]:
    """The tolerance section of report.md: the process's own error model, what the design is
    for, each criterion, the verdict and its margin."""
    from .tolerance.margin import margin_text

    if not tol:
        return []
    out = ["## Tolerance", ""]
    if tol.get("error"):
        return out + [f"Not analysed: {tol['error']}", ""]
    if tol.get("model"):
        out += [f"Monte Carlo, {tol.get('samples')} builds; error model of the process: "
                f"{tol['model']}.", ""]
    else:  # a report written before the error models were per process
        out += [f"Monte Carlo, {tol.get('samples')} builds: bar-length error σ "
                f"{_fmt(tol.get('length_sigma_mm'))} mm, hole clearance "
                f"{_fmt(tol.get('hole_clearance_mm'))} mm, sheet "
                f"{_fmt(tol.get('thickness_mm'))} ± {_fmt(tol.get('thickness_sigma_mm'))} mm "
                f"(scale {_fmt(tol.get('scale_mm'))} mm per unit).", ""]
    out += [f"**{tol.get('verdict', '')}**", ""]
    b = tol.get("behaviour") or {}
    if b:
        how = "stated in the template" if b.get("intent", "auto") != "auto" else \
            "inferred from its map and motion"
        parts = [f"{c['role']} crystal D* = {_fmt(c['value'])} ({c['kind']}"
                 + (", at a turning point)" if c.get("at_turning_point") else ")")
                 for c in b.get("crystals", [])]
        if b.get("end_lock"):
            parts.append(f"ends where its first module locks (d_in {_fmt(b['end_lock'][0])})")
        if b.get("order"):
            parts.append(f"the front runs {b['order']}")
        parts.append(f"judged at the end by its {b.get('end')} ({b.get('end_at')}, drive "
                     f"{_fmt(b.get('end_drive'))})")
        out += [f"What the design is for ({how}): " + "; ".join(parts) + ". A state is kept "
                f"within {_fmt(b.get('state_tolerance_mm'))} mm, a port distance within "
                f"{_fmt(b.get('limit_mm'))} mm.", ""]
        for note in b.get("notes", []):
            out += [f"- {note}"]
        if b.get("notes"):
            out.append("")
    rows = [(c["criterion"], f"{100 * c['kept_fraction']:.1f}%",
             c["p95_mm"] if c["criterion"] != "order" else "-",
             c["limit_mm"] if c["criterion"] != "order" else "-",
             c["missing"]) for c in tol.get("criteria", [])]
    if rows:
        out += _table(["criterion", "builds that keep it", "95% of builds (mm)", "allowed (mm)",
                       "no such state"], rows)
        out.append("")
    if tol.get("margin") is not None:
        alone = ", ".join(f"{n} {margin_text(v['value'], v['bound'])}"
                          for n, v in (tol.get("source_margins") or {}).items())
        out += [f"Margin {margin_text(tol['margin'], tol.get('margin_bound'))}: every error "
                "of the process may grow by this factor and the verdict stays the same"
                + (f"; each source alone: {alone}" if alone else "") + ". The chart (fraction "
                "of builds that keep the behaviour against the error scale) is in report.html "
                "and preview_tolerance.png.", ""]
    if tol.get("ports_judged", True):
        rows = [(p["port"], p["nominal"], p["mean"], p["std"], p["p95_abs_error_mm"],
                 p["limit_mm"]) for p in tol.get("ports", [])]
        if rows:
            out += _table(["port", "designed", "built (mean)", "std", "95% error (mm)",
                           "limit (mm)"], rows)
            out.append("")
    hz = tol.get("horizon")
    if hz and hz.get("modules") is not None:
        out += [f"Lyapunov exponent λ = {_fmt(hz.get('lyapunov'))} per module "
                f"({hz.get('source')}): predictability horizon about "
                f"{hz['modules']:.1f} modules; {hz.get('detail', '')}.", ""]
    elif hz:
        out += [f"Lyapunov exponent λ = {_fmt(hz.get('lyapunov'))} per module "
                f"({hz.get('source')}): {hz.get('detail', '')}.", ""]
    return out


def report_markdown(report: dict) -> bytes:
    """``report.md`` bytes: the design, its motion, each format with its checks, tolerance, and
    the preview images (relative links, so the folder can be moved).

    Parameters
    ----------
    report : dict
        As assembled by the export command: keys ``design``, ``motion``, ``formats``,
        ``tolerance``, ``previews``, ``ok``, ``errors`` (all optional but ``design``).

    Returns
    -------
    bytes
    """
    r = jsonable(report)
    d = r.get("design", {})
    out = [f"# {d.get('name', 'design')}", ""]
    if d.get("description"):
        out += [d["description"], ""]
    outcome = r.get("outcome") or ("ok" if r.get("ok") else "failed")
    status = "ok" if outcome == "ok" else outcome.upper()
    out += [f"- status: **{status}**",
            f"- template: `{d.get('template', '')}`"
            + (f" (sha256 {d['template_sha256'][:12]})" if d.get("template_sha256") else ""),
            ]
    if d.get("figure"):
        out.append(f"- paper figure: {d['figure']}")
    if "modes" in d:
        m = d["modes"]
        out.append(f"- network: {d.get('dim')}D, {d.get('nodes')} nodes, {d.get('edges')} edges; "
                   f"modes {m['total']} = {m['rigid']} rigid + {m['conformational']} "
                   f"conformational; {m['self_stress']} self-stress")
    out.append(f"- fabkit {r.get('fabkit_version', '')}")
    for err in r.get("errors", []):
        out.append(f"- error: {err}")
    out.append("")

    mo = r.get("motion")
    if mo and mo.get("status") == "singular start":
        out += ["## Motion", "",
                f"The template's motion cannot leave its singular start by itself "
                f"({mo.get('message', '')}). Exported by "
                f"{', '.join(mo.get('resolved_by', []))}, which choose the branch themselves "
                "(see their checks).", ""]
    elif mo:
        out += ["## Motion", "",
                f"{mo.get('drive')} from {_fmt(mo.get('start'))} to {_fmt(mo.get('to'))} by "
                f"`{mo.get('method')}`: {mo.get('status')} ({mo.get('message', '')}); "
                f"{mo.get('steps')} configurations, largest relative edge error "
                f"{_fmt(mo.get('max_edge_error'))}.", ""]
        fin = mo.get("final_distances") or {}
        if fin:
            out += _table(["port", "start", "end"],
                          [(k, (mo.get("start_distances") or {}).get(k), v)
                           for k, v in fin.items()])
            out.append("")

    fmts = r.get("formats") or {}
    skipped = {k: v for k, v in fmts.items() if v.get("status") in ("not available",
                                                                     "does not apply",
                                                                     "skipped by the template")}
    made = {k: v for k, v in fmts.items() if k not in skipped}
    if fmts:
        out += ["## Files", ""]
        if skipped:
            out += ["Not exported: " + ", ".join(
                f"{k} ({v['status']}" + (f": {v['detail']}" if v.get("detail") else "") + ")"
                for k, v in sorted(skipped.items())) + ".", ""]
        for name in sorted(made):
            f = made[name]
            out.append(f"### {name}: {f.get('status', '')}")
            out.append("")
            for fn in f.get("files", []):
                out.append(f"- [`{fn}`]({fn})")
            for chk in f.get("checks", []):
                rows = [(c.get("name"), "ok" if c.get("ok") else "FAIL", c.get("value"),
                         c.get("limit"), c.get("detail", "")) for c in chk.get("checks", [])]
                read = ", ".join(f"`{f}`" for f in chk.get("files") or []
                                 if isinstance(f, str) and f != chk.get("file"))
                out += ["", f"As-built check of `{chk.get('file')}`"
                            + (f" (with {read})" if read else "") + ": "
                            f"{'ok' if chk.get('ok') else 'FAILED'}"
                            + (f" ({chk['error']})" if chk.get("error") else "")
                            + (" — computed by the exporter from the same bytes as those written"
                               if chk.get("source") == "exporter" else ""), ""]
                if rows:
                    out += _table(["check", "result", "value", "limit", "detail"], rows)
            if f.get("error"):
                out.append(f"- error: {f['error']}")
            out.append("")

    out += _tolerance_markdown(r.get("tolerance"))

    pics = r.get("previews") or []
    if pics:
        out += ["## Previews", ""]
        for p in pics:
            out += [f"![{Path(p).stem}]({p})", ""]
    return ("\n".join(out).rstrip() + "\n").encode("utf-8")
