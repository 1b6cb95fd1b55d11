"""A design's ``report.html``: the page frame around its sections, in the order a maker reads
them."""

from __future__ import annotations

from ...status import Status
from ..text import MADE_FOR
from .checks import checks_section, verdict_section
from .common import esc, exported, PROCESSES
from .folder import exports_section, files_section
from .frame import CSS, JS
from .laser import laser_bom, laser_section
from .lead import lead_section
from .motion import map_section, motion_section, report_frames
from .origami import origami_bom, origami_section
from .printed import print_bom, print_section
from .tolerance import tolerance_section


def process_sections(proc: str, report, files: dict, primary: bool) -> str:
    """A process's pictures and bill of materials: open when the design was made for it,
    folded under "Also exported" otherwise."""
    if not exported(report, proc):
        return ""
    suffix = "" if primary else f"-{proc}"
    if proc == "laser":
        body = laser_section(files, "laser") + laser_bom(report, "bom" + suffix)
    elif proc == "origami":
        body = origami_section(report, files, "origami") + origami_bom(report, "bom" + suffix)
    else:
        body = print_section(report, files, "print") + print_bom(report, "bom" + suffix)
    if primary:
        return body
    return (f'<details id="also-{proc}"><summary>Also exported: {esc(MADE_FOR[proc])}'
            f"</summary>{body}</details>")


def design_html(report, files: dict, listing: dict, frames: dict | None = None) -> bytes:
    """A design's ``report.html``, rendered from the typed results of its export.

    It opens with the verdict (the worst of the checks, the motion and the tolerance analysis),
    then the process the design was made for (what to buy, which file to start from) and a link
    to every file written for it; then the motion, that process's pictures and bill of
    materials, the map, any other process's files folded, the tolerance and every check.
    Pictures show at their own size (a wide one scrolls sideways in its box).

    Parameters
    ----------
    report : fabkit.pipeline.stages.DesignReport
    files : dict of str to bytes
        The files of the folder in memory (pictures are inlined from here).
    listing : dict of str to int
        Every file of the folder and its size in bytes, for the links.
    frames : dict, optional
        The motion as drawing data (:func:`motion_frames`; made here when not given).

    Returns
    -------
    bytes
        UTF-8 HTML that loads nothing from outside itself.
    """
    d = report.facts
    name = d["name"]
    v = report.verdict
    badge = {"ok": "#a5d6a7", "by design": "#d7ccc8"}.get(str(v.status), "#ef9a9a")
    word = "flagged by design" if v.status is Status.BY_DESIGN else str(v.status)
    head = (f"<header><h1>{esc(name)} <span style=\"color:{badge}\">{esc(word)}</span>"
            f"</h1><p>{esc(d.get('description', ''))}"
            + (f" · {esc(d['figure'])}" if d.get("figure") else "")
            + f" · fabkit {esc(fabkit_version())}</p></header>")
    body = [verdict_section(report), lead_section(report, files),
            files_section(listing, report.process), exports_section(report)]
    body.append(motion_section(report, frames if frames is not None else report_frames(report)))
    body.append(process_sections(report.process, report, files, True))
    body.append(map_section(files))
    for proc in PROCESSES:
        if proc != report.process:
            body.append(process_sections(proc, report, files, False))
    body.append(tolerance_section(report, files))
    body.append(checks_section(report))
    page = ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{esc(name)} – fabkit report</title><style>{CSS}</style></head><body>"
            + head + "<main>" + "".join(body) + f"</main><script>{JS}</script></body></html>")
    return page.encode("utf-8")


def fabkit_version() -> str:
    """The version of fabkit that rendered the page (shown in its header)."""
    import fabkit

    return fabkit.__version__
