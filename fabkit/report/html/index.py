"""``index.html`` of a batch: a card per design (its moving picture, verdict and link), made
from the typed report in the process that exported it."""

from __future__ import annotations

import stat
from dataclasses import dataclass
from pathlib import Path

from ...io.outputs import OutputFolder
from ..text import MADE_FOR
from .common import esc, exported, level_span, PROCESSES
from .folder import not_exported
from .frame import CSS, JS
from .motion import motion_svg, report_frames


@dataclass(frozen=True)
class IndexCard:
    """A design's card in index.html, made from its typed report in the process that exported
    it and handed back with its result (the index reads no page back).

    Attributes
    ----------
    folder : str
        The design's folder name (its page is ``folder/report.html``).
    name, description : str
    level : str
        The verdict's status (a :data:`fabkit.status.VERDICT` value).
    text : str
        The verdict's finding in words, shown beside the level.
    process : str or None
    formats : tuple of str
        Formats written.
    checked : int
        Files read back by the as-built checks.
    why_not : str
        Why nothing (or nothing of its own process) was written, ``""`` otherwise.
    frames : dict or None
        The motion as drawing data (:func:`fabkit.report.html.motion_frames`).
    exports : tuple of str
        ``"dxf: export 1"`` for each format, when the folder holds more than one export's.
    """

    folder: str
    name: str
    description: str
    level: str
    text: str
    process: str | None
    formats: tuple
    checked: int
    why_not: str = ""
    frames: dict | None = None
    exports: tuple = ()


def index_card(report, folder: str, frames: dict | None = None):
    """A design's card in index.html, from its typed report (see :class:`IndexCard`).

    Parameters
    ----------
    report : fabkit.pipeline.stages.DesignReport
    folder : str
        The design's folder name.
    frames : dict, optional
        The motion as drawing data (made here when not given).

    Returns
    -------
    fabkit.pipeline.stages.IndexCard
    """
    made = tuple(sorted(f for f, v in report.formats.items() if v.status.produced))
    why = ""
    if not made:
        why = "; ".join(not_exported(report.formats)) or "no export format applies to it"
    elif not exported(report, report.process):
        why = "; ".join(w for w in not_exported(report.formats)
                        if w.split(":")[0] in PROCESSES[report.process])
    data = frames if frames is not None else report_frames(report)
    origins = getattr(report, "origins", {}) or {}
    exports = ()
    if len({o.export for o in origins.values()}) > 1:
        exports = tuple(f"{f}: export {o.export} ({o.when} UTC)"
                        for f, o in sorted(origins.items()))
    return IndexCard(folder, report.facts["name"], report.facts.get("description", ""),
                     str(report.verdict.status), report.verdict.message, report.process, made,
                     len(report.checks.results), why, data, exports)


def index_html(cards, earlier=()) -> bytes:
    """``index.html`` of a batch.

    Parameters
    ----------
    cards : iterable of IndexCard
        The designs of this export, in order.
    earlier : iterable of str
        Folders of designs exported into the same output by earlier runs (linked by name: no
        page is read back).

    Returns
    -------
    bytes
    """
    out = []
    for k, c in enumerate(cards):
        pic = motion_svg(c.frames, f"m{k}", autoplay=True) if c.frames else "<p>(no motion)</p>"
        lines = [f"<p>{esc(c.description)}</p>"]
        if c.level != "error":
            lines.insert(0, f'<p class="verdict-line">{level_span(c.level)}: {esc(c.text)}</p>')
        else:
            lines.append(f'<p class="bad">{esc(c.text)}</p>')
        if c.formats:
            lines.append(f"<p>made for {esc(MADE_FOR[c.process])} · formats: "
                         f"{esc(', '.join(c.formats))}" + (
                             f" · {c.checked} file{'s' if c.checked != 1 else ''} read back"
                             if c.checked else " · no as-built check ran") + "</p>")
            if c.exports:
                lines.append(f"<p>from more than one export: {esc('; '.join(c.exports))}</p>")
            if c.why_not:
                lines.append(f'<p class="warn">No {esc(c.process)} files: {esc(c.why_not)}'
                             "</p>")
        elif c.level != "error":
            lines.append(f'<p class="warn">No files to build: {esc(c.why_not)}</p>')
        link = (f'<a href="{esc(c.folder)}/report.html">{esc(c.name)}</a>' if c.folder
                else esc(c.name))
        out.append(f'<div class="card"><h3>{link}</h3>{pic}{"".join(lines)}</div>')
    older = list(earlier)
    more = ("<section><h2>Exported earlier into this folder</h2><p>"
            + ", ".join(f'<a href="{esc(f)}/report.html">{esc(f)}</a>' for f in older)
            + "</p></section>") if older else ""
    page = ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>fabkit batch</title><style>{CSS}</style></head><body><header><h1>fabkit "
            f"batch: {len(out)} designs</h1><p>Each picture moves through the design's "
            "motion; open a design for its slider, files, checks and tolerance.</p></header>"
            f'<main><div class="grid">{"".join(out)}</div>{more}</main><script>{JS}</script>'
            "</body></html>")
    return page.encode("utf-8")


def write_index(outdir, cards) -> Path:
    """Write ``outdir/index.html`` from the cards of this export; the other design folders
    of the output (exported by earlier runs) are linked by name.

    Returns
    -------
    pathlib.Path
    """
    cards = list(cards)
    mine = {c.folder for c in cards}
    with OutputFolder.held(outdir, "outdir") as held:  # never through a link
        earlier = sorted(name for name in held.names()
                         if not name.startswith(".") and name not in mine
                         and held.is_folder(name) and _has_report(held, name))
        return held.write("index.html", index_html(cards, earlier))


def _has_report(held, name: str) -> bool:
    """True when folder ``name`` holds a report.html (a regular file, not a link)."""
    with held.folder(name, create=False) as folder:
        st = folder.lstat("report.html")
    return st is not None and stat.S_ISREG(st.st_mode)
