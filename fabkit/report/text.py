"""Design reports: ``report.json`` (machine-readable) and ``report.md`` (for people), as bytes.

Both are pure functions of their input: no clock, no host name, no absolute path, keys sorted and
floats printed by ``repr``, so that the same design exported twice gives byte-identical reports.
report.md is rendered from the typed results of the export (:class:`fabkit.pipeline.stages.
DesignReport`: the verdict, the traced motion, each format's result and checks, the tolerance
analysis), never from another report read back; report.json is the same results as data. The
keys of report.json are listed in docs/batch.md; readers should test ``outcome`` (and may fall
back to ``ok`` for reports of ``report_version`` 1).
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np

from ..model.rigidity import count_modes
from ..status import Status

__all__ = ["jsonable", "report_json", "report_markdown", "tolerance_markdown", "file_digest",
           "design_facts", "MADE_FOR"]


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


def _in_unit(value, criterion: dict):
    """A criterion's number, with its unit when it is not mm (an origami state's folds, °)."""
    unit = criterion.get("unit", "mm")
    return value if unit == "mm" or value is None else f"{_fmt(value)}{unit}"


def tolerance_markdown(result) -> list[str]:
    """The tolerance section of report.md: the process's own error model, what the design is
    for, each criterion, the verdict and its margin.

    Parameters
    ----------
    result : ToleranceResult or None
        The analysis (typed, in memory).

    Returns
    -------
    list of str
        Markdown lines (none without a result).
    """
    from ..tolerance.margin import margin_text

    if result is None:
        return []
    tol = jsonable(result.as_dict())
    out = ["## Tolerance", ""]
    out += [f"Monte Carlo, {tol['samples']} builds; error model of the process: "
            f"{tol['model']}.", ""]
    out += [f"**{tol['verdict']}**", ""]
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
        folds = b.get("folds")
        kept = (f"while every crease's fold angle stays within {_fmt(folds['limit_deg'])}° of "
                f"the designed state's ({_fmt(folds['fraction'])} of the "
                f"{_fmt(folds['apart_deg'])}° its states lie apart)" if folds else
                f"within {_fmt(b.get('state_tolerance_mm'))} mm")
        out += [f"What the design is for ({how}): " + "; ".join(parts) + ". A state is kept "
                f"{kept}, a port distance within {_fmt(b.get('limit_mm'))} mm.", ""]
        for note in b.get("notes", []):
            out += [f"- {note}"]
        if b.get("notes"):
            out.append("")
    rows = [(c["criterion"], f"{100 * c['kept_fraction']:.1f}%",
             _in_unit(c["p95_mm"], c) if c["criterion"] != "order" else "-",
             _in_unit(c["limit_mm"], c) if c["criterion"] != "order" else "-",
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


#: How each process is named in a report's lead: what it is made for.
MADE_FOR = {"laser": "laser-cut acrylic (Chicago screws)", "origami": "folded paper (origami)",
            "print": "a 3D print"}


def report_markdown(report) -> bytes:
    """``report.md`` bytes, rendered from the typed results of one design's export: its verdict
    first, then the design, its motion, each format with its checks, the tolerance analysis and
    the preview images (relative links, so the folder can be moved).

    Parameters
    ----------
    report : fabkit.pipeline.stages.DesignReport

    Returns
    -------
    bytes
    """
    d = jsonable(report.facts)
    verdict = report.verdict
    word = "flagged by design" if verdict.status is Status.BY_DESIGN else verdict.status.value
    out = [f"# {d['name']}", "", f"**{word}**: {verdict.message}", ""]
    if d.get("description"):
        out += [d["description"], ""]
    made = [f for f, v in report.formats.items() if v.status.produced]
    outcome = report.outcome
    out += [f"- export: **{'ok' if outcome is Status.OK else outcome.value.upper()}**"
            + (f"; made for {MADE_FOR[report.process]}" if made else "; no files to build"),
            f"- template: `{d['template']}`"
            + (f" (sha256 {d['template_sha256'][:12]})" if d.get("template_sha256") else "")]
    if d.get("figure"):
        out.append(f"- paper figure: {d['figure']}")
    m = d["modes"]
    out.append(f"- network: {d['dim']}D, {d['nodes']} nodes, {d['edges']} edges; "
               f"modes {m['total']} = {m['rigid']} rigid + {m['conformational']} "
               f"conformational; {m['self_stress']} self-stress")
    import fabkit

    out.append(f"- fabkit {fabkit.__version__}")
    for err in report.errors:
        out.append(f"- error: {err}")
    out.append("")
    out += _motion_markdown(report)
    out += _formats_markdown(report)
    out += tolerance_markdown(report.tolerance)
    pics = report.artefacts.previews
    if pics:
        out += ["## Previews", ""]
        for p in pics:
            out += [f"![{Path(p).stem}]({p})", ""]
    return ("\n".join(out).rstrip() + "\n").encode("utf-8")


def _motion_markdown(report) -> list[str]:
    motion = report.motion
    if motion is None or motion.status is Status.NO_TARGET:
        return []
    if motion.status is Status.SINGULAR_START:
        resolved = sorted(f for f, v in report.formats.items() if v.status.produced)
        return ["## Motion", "",
                f"The template's motion cannot leave its singular start by itself "
                f"({motion.error.reason}). Exported by {', '.join(resolved)}, which choose the "
                "branch themselves (see their checks).", ""]
    traj = motion.trajectory
    drive = motion.design.motion.drive
    out = ["## Motion", "",
           f"{drive} from {_fmt(float(traj.drive[0]))} to {_fmt(float(traj.target))} by "
           f"`{traj.method}`: {motion.line()}; {traj.n_steps} configurations, largest relative "
           f"edge error {_fmt(float(traj.max_edge_error))}.", ""]
    names = list(traj.network.ports)
    ends = {} if motion.ends is None else {pe.port: pe for pe in motion.ends.ports}
    at_lock = motion.ends is not None and motion.ends.judged_at == "lock"
    rows = []
    for n in names:
        row = [n, float(traj.distance(n)[0]), float(traj.distance(n)[-1])]
        if ends:
            pe = ends.get(n)
            row += [None] if pe is None else [pe.designed]
            if at_lock:  # judged where the motion, continued past the target, locks
                row += [None] if pe is None else [pe.end]
            row += [None] if pe is None else ["yes" if pe.reached else f"no ({pe.motion})"]
        rows.append(row)
    head = ["port", "start", "end"] + (
        ["designed end"] + (["where it locks"] if at_lock else []) + ["reached"] if ends else [])
    out += _table(head, rows)
    out.append("")
    if motion.ends is not None:
        out += [f"Designed ends {motion.ends.basis}; judged at the "
                f"{motion.ends.judged_at}, within {_fmt(motion.ends.tolerance)} (a quarter of "
                "the first module's travel).", ""]
    return out


def _formats_markdown(report) -> list[str]:
    fmts = report.formats
    quiet = (Status.NOT_AVAILABLE, Status.DOES_NOT_APPLY, Status.SKIPPED)
    skipped = {k: v for k, v in fmts.items() if v.status in quiet}
    made = {k: v for k, v in fmts.items() if k not in skipped}
    if not fmts:
        return []
    out = ["## Files", ""]
    numbers = sorted({o.export for o in report.origins.values()})
    if len(numbers) > 1:
        out += ["This folder holds the files of more than one export: "
                + "; ".join(f"export {n}: " + ", ".join(sorted(
                    f for f, o in report.origins.items() if o.export == n)) for n in numbers)
                + ".", ""]
    if report.removed:
        out += ["Removed from the folder (stale): " + "; ".join(report.removed) + ".", ""]
    if skipped:
        out += ["Not exported: " + ", ".join(
            f"{k} ({v.status}" + (f": {v.message}" if v.message else "") + ")"
            for k, v in sorted(skipped.items())) + ".", ""]
    for name in sorted(made):
        f = made[name]
        out.append(f"### {name}: {f.status}")
        if f.status.produced:
            out.append(f"Made by the {_process_of(name)} process.")
            origin = report.origins.get(name)
            if origin is not None:
                again = " and checked again as built" if f.checks else ""
                out.append(f"From {origin.line()}" + (
                    f"; kept from that export (same design, settings and fabkit version){again}."
                    if name in report.kept else "."))
        elif f.message:
            out.append(f"- {f.message}")
        out.append("")
        for fn in f.files:
            out.append(f"- [`{fn}`]({fn})")
        for chk in f.checks:
            c = jsonable(chk.as_dict())
            rows = [(x.get("name"), "ok" if x.get("ok") else "FAIL", x.get("value"),
                     x.get("limit"), x.get("detail", "")) for x in c["checks"]]
            read = ", ".join(f"`{Path(str(x)).name}`" for x in c.get("files") or []
                             if Path(str(x)).name != chk.file)
            out += ["", f"As-built check of `{chk.file}`"
                        + (f" (with {read})" if read else "") + ": "
                        f"{'ok' if chk.ok else 'FAILED'}"
                        + (f" ({chk.error})" if chk.error else ""), ""]
            if rows:
                out += _table(["check", "result", "value", "limit", "detail"], rows)
        out.append("")
    return out


def _process_of(fmt: str) -> str:
    from ..tolerance import PROCESS_FORMATS

    return next((p for p, fs in PROCESS_FORMATS.items() if fmt in fs), "its own")
