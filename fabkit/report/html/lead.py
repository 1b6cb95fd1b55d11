"""The "Made for" section under the verdict: the process the design was made for, what to buy
and which file to start from, the other processes exported and the formats not written."""

from __future__ import annotations

from ..text import MADE_FOR
from .common import esc, exported, PROCESSES
from .folder import not_exported
from .laser import laser_lead
from .origami import origami_lead
from .printed import print_lead


def lead_section(report, files: dict) -> str:
    """The "Made for" section: the process's parts and the file to start from (or why nothing
    to build was written), the other processes exported, the formats not written."""
    process = report.process
    formats = report.formats
    why = not_exported(formats)
    if not exported(report, process):
        reasons = "; ".join(why) or "no export format applies to it"
        return (f'<section id=made-for class=lead><h2>Made for {esc(MADE_FOR[process])}: no '
                f'files</h2><p class="warn">Nothing to build was written: {esc(reasons)}.</p>'
                "</section>")
    if process == "laser":
        parts = laser_lead(formats, files)
    elif process == "origami":
        parts = origami_lead(formats)
    else:
        parts = print_lead(formats)
    others = [p for p in PROCESSES if p != process and exported(report, p)]
    if others:
        parts.append("<p>Also exported: " + ", ".join(
            f'<a href="#also-{p}">{esc(MADE_FOR[p])}</a>' for p in others) + " (folded below)."
                     "</p>")
    if why:
        parts.append(f"<p class=\"warn\">Not written: {esc('; '.join(why))}.</p>")
    return (f"<section id=made-for class=lead><h2>Made for {esc(MADE_FOR[process])}</h2>"
            + "".join(parts) + "</section>")
