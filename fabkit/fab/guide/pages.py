"""The A4 pages of an assembly guide, drawn from its :class:`~.plan.GuidePlan`.

1. **Overview**: the whole kit at one scale, cut into rows, every module page outlined and
   numbered, the screws two pages share marked; the size as built and over the motion; how the
   pages join; the kit's contents from the bill of materials.
2. **How to build**: a side view of one screw (post up from below, bars bottom layer first, a
   spacer ring where a layer has no bar, washers on top under the screw head), how to handle
   a long chain page by page, and the page list.
3. **One page per two modules** (the whole network when it is not a chain): the bars coloured
   by layer with bar, layer and joint labels that never overlap, bars of other pages that a
   screw of this page takes drawn hatched with their page, joints closed on a later page
   marked with that page; the stack of every screw this page closes, bottom to top; the
   hardware for this page.
4. **Motion test**: which two joints to push, from what distance to what, what every port
   should read, and pictures of the collapse on its way.
"""

from __future__ import annotations

import io
import textwrap

import numpy as np

from .draw import (Labeller, best_rows, draw_bars, extent, label_bars, label_joints,
                   layer_colour, page_brackets, row_axes)
from .plan import MEASURABLE_MM, GuidePlan, frame_caption

__all__ = ["A4", "render_pages"]

#: A4 portrait, inches (matplotlib's unit).
A4 = (8.27, 11.69)
#: Left margin and usable width of a page (inches).
_LEFT, _WIDTH = 0.55, 7.17
#: Monospaced text: matplotlib's DejaVu Sans Mono on the page's picture, Courier in the PDF
#: (see :func:`_save_page`); both 0.6 em a character, so columns line up in either.
_MONO = "monospace"
#: Characters of the guide's words that the PDF's standard fonts (WinAnsi encoding) lack, and
#: what the PDF writes instead.
_PDF_PLAIN = str.maketrans({"→": "->", "−": "-", "≤": "<=", "≥": ">=", "≈": "~"})
#: How much of a bar of another page a page shows from the screw that takes it (mm).
GHOST_STUB_MM = 60.0


def _wrap(text: str, width: int) -> str:
    return "\n".join(textwrap.fill(p, width) if p else "" for p in text.split("\n"))


def _save_page(pdf, fig) -> bool:
    """Add a page to the PDF in the standard fonts of PDF readers (Helvetica, Courier) when
    every text of it can be written in them, else in the embedded DejaVu fonts; True for the
    former.

    The standard fonts are named, not embedded, and measured from their metric files: a page of
    the guide is written in a quarter of the time the embedded fonts take (each glyph laid out,
    traced and subset), and the PDF is smaller. Text the page's picture shows as ``→`` reads
    ``->`` in the PDF, and monospaced text is set in Courier Bold (plain Courier's hairline
    strokes fade at 7.5 pt); a page with a character beyond the standard fonts (a σ in a
    hardware catalogue's name) keeps the embedded fonts, so nothing is lost.
    """
    import logging

    import matplotlib
    from matplotlib.text import Text

    plain = []
    for t in fig.findobj(Text):
        written = t.get_text().translate(_PDF_PLAIN)
        try:
            written.encode("cp1252")
        except UnicodeEncodeError:
            pdf.savefig(fig)
            return False
        plain.append((t, written))
    changed = []  # (text, its words, its weight), restored after the page is written
    for t, written in plain:
        mono = t.get_fontfamily()[0] == _MONO
        if written != t.get_text() or mono:
            changed.append((t, t.get_text(), t.get_fontweight()))
            t.set_text(written)
            if mono:
                t.set_fontweight("bold")
    # the metric files call the regular weight "Medium", which matplotlib reports at each lookup
    fonts_log = logging.getLogger("matplotlib.font_manager")
    level = fonts_log.level
    fonts_log.setLevel(logging.ERROR)
    try:
        with matplotlib.rc_context({"pdf.use14corefonts": True}):
            pdf.savefig(fig)
    finally:
        fonts_log.setLevel(level)
        for t, text, weight in changed:
            t.set_text(text)
            t.set_fontweight(weight)
    return True


def _header(fig, title: str, sub: str | None = None):
    fig.text(0.5, 0.972, title, ha="center", va="center", fontsize=12.5, weight="bold")
    if sub:
        fig.text(_LEFT / A4[0], 0.948, _wrap(sub, 132), ha="left", va="top", fontsize=7.5)


def _page_extent(x, edges, bars, r):
    return extent(x[edges[np.asarray(bars)]], 3 * r)


def _mods(page) -> str:
    if not page.modules:
        return "the whole network"
    a, b = page.modules[0], page.modules[-1]
    return f"modules {a}-{b}" if b > a else f"module {a}"


def _bottom(fig, artist) -> float:
    """Figure fraction just below a drawn text."""
    box = artist.get_window_extent(fig.canvas.get_renderer())
    return box.y0 / fig.bbox.height - 0.012


def _page_spans(x, edges, pages, idx):
    out = []
    for i in idx:
        p = x[edges[np.asarray(pages[i].bars)]].reshape(-1, 2)
        out.append((f"p{pages[i].number}", float(p[:, 0].min()), float(p[:, 0].max())))
    return out


def _overview(fig, gp: GuidePlan, plan, x, edges, r, labellers):
    layers = plan.stacking.layer
    n = gp.n_pages
    size = (f"Built size {gp.size_mm[0]:.0f} × {gp.size_mm[1]:.0f} mm (bars and screw heads) "
            f"at the start; the motion test needs {gp.motion_size_mm[0]:.0f} × "
            f"{gp.motion_size_mm[1]:.0f} mm. ")
    if len(gp.pages) > 1:
        size += (f"Build on a flat table at least {gp.size_mm[0] + 100:.0f} mm long, or in "
                 "sections (page 2). The brackets name the page of this guide that draws each "
                 "part (p<page>); red rings mark the screws two pages share: the later page "
                 "closes them.")
    else:
        size += f"Page {gp.pages[0].number} draws every bar and lists every screw."
    _header(fig, f"{gp.name}: assembly guide, page 1 of {n}: overview", size)
    pages = gp.pages
    open_j = sorted({j for p in pages for j in p.open_joints})

    def row_ext(idx):
        bars = np.concatenate([np.asarray(pages[i].bars) for i in idx])
        return _page_extent(x, edges, bars, r)

    band = 0.42 if len(pages) > 1 else 0.0
    rows, ext, scale = best_rows(len(pages), row_ext, _WIDTH, 4.6, 0.15, max_scale=1 / 25.4,
                                 band_in=band)
    placed = row_axes(fig, ext, scale, _LEFT, 1.25, 0.15, _WIDTH, band_in=band)
    for row, (ax, strip) in zip(rows, placed):
        bars = np.concatenate([np.asarray(pages[i].bars) for i in row])
        draw_bars(ax, x, edges, bars, layers, r, alpha=0.4, lw=0.3)
        js = [j for j in open_j if j in edges[bars]]
        ax.plot(x[js, 0], x[js, 1], "o", ms=7, mfc="none", mec="#d00000", mew=1.3, zorder=6)
        if strip is not None:
            page_brackets(strip, _page_spans(x, edges, pages, row))
        for side in ax.spines.values():
            side.set_color("0.8")
    y = placed[-1][0].get_position().y0 - 0.02
    joins = []
    for p in pages:
        later = {}
        for j, q in sorted(p.open_joints.items()):
            later.setdefault(q, []).append(f"J{j}")
        how = "; ".join(f"leaves {', '.join(v)} loose for p{q}" for q, v in sorted(later.items()))
        joins.append(f"p{p.number}: {_mods(p)}" + (f"; {how}" if how else ""))
    head = fig.text(_LEFT / A4[0], y, "How the pages join" if len(pages) > 1 else "Pages",
                    fontsize=9.5, weight="bold", va="top")
    y = _bottom(fig, head)
    ncol = 2 if len(joins) > 8 else 1
    per = int(np.ceil(len(joins) / ncol))
    fs = 7.5 if per <= 16 else max(5.0, 7.5 * 16 / per)
    cols = [fig.text(_LEFT / A4[0] + 0.46 * c, y, "\n".join(joins[c * per:(c + 1) * per]),
                     fontsize=fs, va="top", family=_MONO) for c in range(ncol)]
    y = min(_bottom(fig, t) for t in cols) - 0.01
    head = fig.text(_LEFT / A4[0], y, "Kit contents (as laser_bom.md lists them)",
                    fontsize=9.5, weight="bold", va="top")
    rows_t = [f"{n:>4} × {name}" for name, n in gp.totals]
    fig.text(_LEFT / A4[0], _bottom(fig, head), "\n".join(rows_t), fontsize=7.5, va="top",
             family=_MONO)


def _stack_diagram(ax, plan):
    """Side view of one screw: post from below, bars, a spacer ring, washers, screw from above."""
    from matplotlib.patches import Rectangle

    s = plan.settings
    t, head, washer = 1.0, 0.6, 0.3
    parts = [("bar, layer 0 (bottom)", layer_colour(0)), ("bar, layer 1", layer_colour(1)),
             ("spacer ring where a layer has no bar (here layer 2)", "0.8"),
             ("bar, layer 3", layer_colour(3))]
    top = len(parts) * t
    ax.add_patch(Rectangle((-2.2, -head), 4.4, head, fc="0.45", ec="k"))
    ax.add_patch(Rectangle((-0.45, -head), 0.9, top + 2 * washer + head, fc="0.65", ec="k",
                           zorder=3))
    for k, (_, colour) in enumerate(parts):
        spacer = k == 2
        x0, x1 = (-1.6, 1.6) if spacer else (-4.5, 3.0)
        ax.add_patch(Rectangle((x0, k * t), x1 - x0, 0.96 * t, fc=colour, ec="k", alpha=0.6,
                               zorder=2))
    for k in range(2):
        ax.add_patch(Rectangle((-1.3, top + k * washer), 2.6, 0.9 * washer, fc="#d8d8d8",
                               ec="k"))
    screw = top + 2 * washer
    ax.add_patch(Rectangle((-2.2, screw), 4.4, head, fc="0.45", ec="k"))
    notes = [(-head / 2, 2.2, f"post (barrel, {s.screw.barrel_diameter:g} mm): up from below, "
                              "head down"),
             *[((k + 0.5) * t, 1.6 if k == 2 else 3.0, text)
               for k, (text, _) in enumerate(parts)],
             (top + washer, 1.3, "washers the page lists: on top, under the screw head"),
             (screw + head / 2, 2.2, "screw: in from above, into the post; snug, not tight")]
    ys = [notes[0][0]]
    for y, _, _ in notes[1:]:
        ys.append(max(y, ys[-1] + 0.75))
    for (y, x0, text), ly in zip(notes, ys):
        ax.plot([x0 + 0.2, 5.3], [y, ly], "-", color="0.5", lw=0.6)
        ax.text(5.5, ly, text, va="center", fontsize=8)
    ax.annotate("", (-5.6, screw + head), (-5.6, -head),
                arrowprops=dict(arrowstyle="->", color="0.3", lw=1.2))
    ax.text(-6.0, top / 2, "build upwards", rotation=90, va="center", ha="right", fontsize=8)
    ax.set_xlim(-7.5, 26)
    ax.set_ylim(-1.2, max(ys[-1], screw + head) + 0.6)
    ax.set_aspect("equal")
    ax.axis("off")


def _method(fig, gp: GuidePlan, plan):
    s = plan.settings
    _header(fig, f"{gp.name}: page 2 of {gp.n_pages}: how to build")
    ax = fig.add_axes([_LEFT / A4[0], 0.66, _WIDTH / A4[0], 0.29])
    _stack_diagram(ax, plan)
    first, last = gp.pages[0].number, gp.pages[-1].number
    motion = f" Page {gp.n_pages} is the motion test." if gp.motion is not None else ""
    if len(gp.pages) > 1:
        order = (f"Work from page {first} to page {last}, left to right. Each page closes the "
                 "screws it lists. A joint marked '→p<k>' belongs to a later page: leave the "
                 "bars that reach it loose (do not thread them) until page k, which draws them "
                 "hatched and threads them into its stack. Keep the finished part flat on the "
                 "table and slide it along as the chain grows; support any part that hangs over "
                 "the edge. Do not lift the chain by one end: the modules fold.")
    else:
        order = (f"Page {first} draws every bar and lists every screw: lay the bars out as "
                 "drawn, then close the screws one by one.")
    text = (
        "BEFORE YOU START\n"
        "Cut the sheets; check that the 100 mm reference square measures 100 mm. Peel the "
        "protective film. Every bar is engraved B<bar>·L<layer>: sort the bars by the page "
        "that draws them, and within a page by layer.\n\n"
        "EVERY SCREW\n"
        "Stand the post (the barrel) upright, head down. Thread the parts in the order the "
        "page lists them, bottom first: bars by layer, and a spacer ring (S<joint>.<layer>, "
        f"{s.spacer_diameter:g} mm, cut from the sheet) where the screw passes a layer with no "
        "bar. Put the washers the page lists on top, then screw the screw in from above until "
        "it is snug: the bars must still turn freely. Measure your sheet: on sheets thicker "
        "than nominal, drop washers where the screw does not reach.\n\n"
        f"{'A LONG CHAIN, PAGE BY PAGE' if len(gp.pages) > 1 else 'ORDER'}\n{order}\n\n"
        "CHECK AS YOU GO\n"
        "After each page, the part built should move freely by hand without forcing; a bar "
        "that rubs is usually a screw that is too tight or a bar on the wrong layer (check "
        f"its engraved L<layer>).{motion}")
    body = fig.text(_LEFT / A4[0], 0.64, _wrap(text, 112), fontsize=8, va="top",
                    linespacing=1.35)
    pages = [f"p{p.number}: {_mods(p)}, {len(p.bars)} bars, {len(p.closes)} screws"
             for p in gp.pages]
    ncol = 2 if len(pages) > 10 else 1
    per = int(np.ceil(len(pages) / ncol))
    head = fig.text(_LEFT / A4[0], _bottom(fig, body) - 0.01, "Pages", fontsize=9.5,
                    weight="bold", va="top")
    for c in range(ncol):
        fig.text(_LEFT / A4[0] + 0.46 * c, _bottom(fig, head),
                 "\n".join(pages[c * per:(c + 1) * per]), fontsize=7.5, va="top", family=_MONO)


def _module_page(fig, gp: GuidePlan, page, plan, x, edges, r, labellers):
    st, s = plan.stacking, plan.settings
    layers = st.layer
    by_joint = {js.joint: js for js in st.joints}
    own = np.asarray(page.bars)
    _header(fig, f"{gp.name}: page {page.number} of {gp.n_pages}, {_mods(page)}",
            "Bars coloured by layer (0 = bottom), labelled B<bar>·L<layer>; J<joint> = screw. "
            "Hatched bars belong to the page named on them (p<k>): this page threads them. "
            "'→p<k>': that screw is closed on page k; leave its bars loose here.")
    ax = fig.add_axes([_LEFT / A4[0], 0.42, _WIDTH / A4[0], 0.50])
    draw_bars(ax, x, edges, page.ghosts, layers, r, ghost=True)
    draw_bars(ax, x, edges, own, layers, r)
    joints = sorted({int(j) for j in edges[own].ravel() if int(j) in by_joint})
    ax.plot(x[joints, 0], x[joints, 1], "o", ms=3.5, color="k", zorder=5)
    near = {}
    for j in page.closes:
        for b in by_joint[j].bars:
            if b in page.ghosts:
                near[b] = j
    # the view: this page's bars, and a stub of each bar of another page (where its label goes)
    pts = [x[edges[own]].reshape(-1, 2)]
    for b, j in near.items():
        other = edges[b, 1] if edges[b, 0] == j else edges[b, 0]
        d = x[other] - x[j]
        pts.append((x[j] + d * min(1.0, GHOST_STUB_MM / max(float(np.linalg.norm(d)), r)))[None])
    pts = np.concatenate(pts)
    lo, hi = pts.min(0) - 3 * r, pts.max(0) + 3 * r
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    lab = Labeller(ax)
    texts = [f"J{j}" if j not in page.open_joints else f"J{j}→p{page.open_joints[j]}"
             for j in joints]
    label_joints(lab, x, joints, texts, 8, {j: "#c00000" for j in page.open_joints},
                 {j: "bold" for j in page.open_joints})
    label_bars(lab, x, edges, own, [f"B{k}·L{int(layers[k])}" for k in own], r)
    label_bars(lab, x, edges, page.ghosts,
               [f"B{k}·L{int(layers[k])} p{page.bar_page[k]}" for k in page.ghosts], r,
               colour="#444444", near=near)
    labellers.append(lab)
    from matplotlib.patches import Rectangle

    present = sorted({int(layers[k]) for k in (*page.bars, *page.ghosts)})
    handles = [Rectangle((0, 0), 1, 1, fc=layer_colour(z), alpha=0.45, ec="k", lw=0.5)
               for z in present]
    ax.legend(handles, [f"layer {z}" for z in present], fontsize=7, ncol=min(len(present), 8),
              loc="upper center", bbox_to_anchor=(0.5, -0.005), frameon=False)
    rows = []
    for j in page.closes:
        js = by_joint[j]
        at = dict(zip(js.layers, js.bars))
        seq = []
        for z in range(min(js.layers), max(js.layers) + 1):
            if z not in at:
                seq.append(f"S{j}.{z}")
            elif page.bar_page.get(at[z], page.number) != page.number:
                seq.append(f"B{at[z]}(L{z},p{page.bar_page[at[z]]})")
            else:
                seq.append(f"B{at[z]}(L{z})")
        fastener = (js.fastener.describe() if js.fastener is not None
                    else f"post {js.screw_length:g} mm")
        rows.append(f"J{j}: {' / '.join(seq)}  | {fastener}")
    head = fig.text(_LEFT / A4[0], 0.375, "Stack at each screw this page closes, bottom to "
                    f"top (S<joint>.<layer> = spacer ring, {s.spacer_diameter:g} mm):",
                    fontsize=8.5, weight="bold", va="top")
    fs = 7 if len(rows) <= 22 else max(4.5, 7 * 22 / len(rows))
    body = "\n".join(rows)
    if page.open_joints:
        later = ", ".join(f"J{j}→p{q}" for j, q in sorted(page.open_joints.items()))
        body += f"\n\nLeft loose on this page (closed later): {later}"
    stack = fig.text(_LEFT / A4[0], _bottom(fig, head), body, fontsize=fs, va="top",
                     family=_MONO)
    head = fig.text(_LEFT / A4[0], _bottom(fig, stack) - 0.01, "Hardware for this page:",
                    fontsize=8.5, weight="bold", va="top")
    fig.text(_LEFT / A4[0], _bottom(fig, head),
             "\n".join(f"{n:>4} × {name}" for name, n in page.hardware), fontsize=7.5,
             va="top", family=_MONO)


def _motion_page(fig, gp: GuidePlan, plan, edges, r):
    m = gp.motion
    s = plan.settings
    name = m.drive
    a, b = m.joints
    push = "Push" if m.end_mm < m.start_mm else "Pull"
    together = "together" if m.end_mm < m.start_mm else "apart"
    fol = m.followers
    order = {"forward": f"one after another, starting next to {name} and travelling away "
                        "from it",
             "backward": f"one after another, starting at the far end and travelling towards "
                         f"{name}",
             "together": "all together",
             "mixed": "not in order along the chain (see the table)",
             "none": "not at all: only the pushed part moves"}[m.order]
    moved = ", ".join(p[0] for p in fol) or "none"
    opening = {np.sign(p[2] - p[1]) for p in fol} - {0.0}
    if len(opening) > 1:
        order += "; some open while others close"
    text = (f"{push} joints J{a} and J{b} {together}: their centre-to-centre distance {name} "
            f"goes from {m.start_mm:.1f} mm to {m.end_mm:.1f} mm. Measure it between the "
            f"screw posts: the gap between the posts plus {s.screw.barrel_diameter:g} mm (the "
            f"post diameter). Hold J{a} in place and move J{b} along the line J{a}-J{b}.\n\n"
            "What you should see: "
            + (f"the ports that follow move {order}. " if len(fol) > 1 else "")
            + f"{len(fol)} of the {len(m.ports) - 1} other ports make at least half of their "
            f"change ({moved}); the table gives where each starts and ends. The pictures below "
            "show the kit on its way, to one scale, with the pushed pair in red.")
    if len(m.frames) > 2 and m.order in ("forward", "backward") and len(fol) > 1:
        away = abs(m.drive_mm[m.frames[len(m.frames) // 2]] - m.end_mm)
        if away < MEASURABLE_MM:
            text += (f" Half of them move while {name} is within {MEASURABLE_MM:g} mm of "
                     f"{m.end_mm:.1f} mm, closer than you can measure: push steadily to the end "
                     "and watch the collapse run along the chain as you arrive.")
        else:
            text += (f" Half of them have moved once {name} is within {away:.2f} mm of its end:"
                     " go slowly there.")
    _header(fig, f"{gp.name}: page {gp.n_pages} of {gp.n_pages}: motion test")
    body = fig.text(_LEFT / A4[0], 0.945, _wrap(text, 118), fontsize=8.3, va="top",
                    linespacing=1.35)
    rows = [f"{p[0]:>4}: {p[1]:7.1f} → {p[2]:7.1f} mm" + (" (pushed)" if p[0] == name else "")
            for p in m.ports]
    ncol = 1 if len(rows) <= 9 else (2 if len(rows) <= 20 else 3)
    per = int(np.ceil(len(rows) / ncol))
    head = fig.text(_LEFT / A4[0], _bottom(fig, body) - 0.005,
                    "Every port, start → end (centre to centre)", fontsize=9, weight="bold",
                    va="top")
    y = _bottom(fig, head)
    cols = [fig.text(_LEFT / A4[0] + 0.31 * c, y, "\n".join(rows[c * per:(c + 1) * per]),
                     fontsize=7.2, va="top", family=_MONO) for c in range(ncol)]
    top_in = (1 - min(_bottom(fig, t) for t in cols)) * A4[1] + 0.25
    frames = list(m.frames)
    pts = m.positions
    used = np.unique(edges)
    ext = [extent(pts[f][used], 2 * r) for f in frames]
    x0, x1 = min(e[0] for e in ext), max(e[2] for e in ext)
    ext = [(x0, e[1], x1, e[3]) for e in ext]  # one x range: the held joint stays in place
    title = 0.22
    height = A4[1] - top_in - 0.45 - title * len(frames)
    h = sum(e[3] - e[1] for e in ext)
    scale = min(_WIDTH / (x1 - x0), height / h, 1 / 25.4)
    placed = row_axes(fig, ext, scale, _LEFT, top_in + title, title + 0.02, _WIDTH)
    for f, (ax, _) in zip(frames, placed):
        draw_bars(ax, pts[f], edges, np.arange(edges.shape[0]), plan.stacking.layer, r,
                  alpha=0.5, lw=0.25)
        ax.plot(pts[f][[a, b], 0], pts[f][[a, b], 1], "-o", color="#d00000", lw=1.5, ms=3,
                zorder=6)
        ax.set_title(frame_caption(m, f), fontsize=7.5, loc="left", pad=2)
        for side in ax.spines.values():
            side.set_color("0.8")


def render_pages(gp: GuidePlan, plan, *, dpi: int = 100, pngs: bool = False,
                 check: bool = False):
    """Draw the pages of a guide plan.

    ``check``: also list every text that does not fit on its page (``stats["clipped"]``).

    Returns
    -------
    pdf : bytes
    images : list of bytes
        PNG of every page when ``pngs`` (else of the first page only).
    texts : list of list of str
        The text on each page.
    stats : dict
        ``pages``, ``labels`` placed, ``overlaps`` (pairs of label boxes that overlap, 0),
        ``shrunk``, ``dropped`` (labels with no free place) and ``dropped_on`` (the page of
        each), ``standard_fonts`` (pages written in the PDF's standard fonts, see
        :func:`_save_page`); with ``check``, ``clipped`` ((page, text) that does not fit on its
        page).
    """
    from matplotlib.backends.backend_pdf import PdfPages
    from matplotlib.text import Text

    from ...viz import _mpl, checked_png, clipped_texts

    plt = _mpl()
    s = plan.settings
    edges = np.asarray(plan.bars.edges)
    x = plan.design.network.nodes * s.scale
    r = 0.5 * s.bar_width
    stats = {"pages": 0, "labels": 0, "overlaps": 0, "shrunk": 0, "dropped": 0, "dropped_on": [],
             "clipped": [], "standard_fonts": 0}
    images, texts = [], []
    buf = io.BytesIO()
    drawers = [lambda fig, labs: _overview(fig, gp, plan, x, edges, r, labs),
               lambda fig, labs: _method(fig, gp, plan)]
    for page in gp.pages:
        drawers.append(lambda fig, labs, page=page: _module_page(fig, gp, page, plan, x, edges,
                                                                 r, labs))
    if gp.motion is not None:
        drawers.append(lambda fig, labs: _motion_page(fig, gp, plan, edges, r))
    with PdfPages(buf, metadata={"Creator": "fabkit", "CreationDate": None, "ModDate": None,
                                 "Producer": "fabkit"}) as pdf:
        for k, draw in enumerate(drawers):
            fig = plt.figure(figsize=A4)
            labellers: list = []
            draw(fig, labellers)
            for lab in labellers:
                stats["overlaps"] += lab.overlaps()
                for key in ("labels", "shrunk", "dropped"):
                    stats[key] += lab.stats[key]
                stats["dropped_on"] += [k + 1] * lab.stats["dropped"]
            texts.append([t.get_text() for t in fig.findobj(Text) if t.get_text()])
            stats["standard_fonts"] += _save_page(pdf, fig)
            if pngs or k == 0:  # one raster drawing gives the PNG and the clipping check
                png, clipped = checked_png(fig, dpi=dpi)
                images.append(png)
            else:
                clipped = clipped_texts(fig) if check else []
                plt.close(fig)
            if check:
                stats["clipped"] += [(k + 1, t) for t in clipped]
            stats["pages"] += 1
    return buf.getvalue(), images, texts, stats
