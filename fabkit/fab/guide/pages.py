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
5. **Functional test** (a design with more than one input): each input pushed alone, then all
   of them, and every port that moves, start → end.

The first page heads with the design's verdict (:mod:`.verdict`) and each module page with its
place in the build order.

Lists longer than a page continue on the pages that follow (:mod:`.flow`, decided with the
page numbers in :func:`.plan.guide_plan`); every line is a text of its own at the pitch the
plan counted, never smaller than :data:`.flow.MIN_PT`. The PDF embeds its fonts (DejaVu, as
TrueType subsets), so every reader draws the words as they were measured.
"""

from __future__ import annotations

import io
import textwrap

import numpy as np

from ...plots.viz import checked_png, clipped_texts, figure_kit, figure_texts, frozen_heap
from .draw import (best_rows, draw_bars, extent, label_bars, label_joints, Labeller, layer_colour,
                   page_brackets, row_axes)
from .flow import column_lines, MIN_PT, STYLES
from .pdf_text import LAYER_GID, add_text_layer, off_page, text_runs
from .plan import bar_name, frame_caption, GuidePlan, modules_text, ROOM_PT

__all__ = ["A4", "render_pages", "BOTTOM_IN"]

#: A4 portrait, inches (matplotlib's unit).
A4 = (8.27, 11.69)
#: Left margin and usable width of a page (inches).
_LEFT, _WIDTH = 0.55, 7.17
#: Monospaced text (DejaVu Sans Mono, embedded in the PDF), so columns line up.
_MONO = "monospace"
#: Bottom margin of a page (inches): no text is set below it.
BOTTOM_IN = 0.45
#: How much of a bar of another page a page shows from the screw that takes it (mm).
GHOST_STUB_MM = 60.0


def _wrap(text: str, width: int) -> str:
    return "\n".join(textwrap.fill(p, width) if p else "" for p in text.split("\n"))


def _text_top(kind: str) -> float:
    """Where the text of a page of ``kind`` begins (inches from the top): the room the plan
    counted above the bottom margin."""
    return A4[1] - BOTTOM_IN - ROOM_PT[kind] / 72.0


def _draw_blocks(fig, blocks, top_in: float) -> float:
    """Set blocks from ``top_in`` (inches from the top) down, each line a text of its own at
    its style's pitch; returns where the text ends (inches from the top)."""
    H = A4[1]
    y = top_in
    for block in blocks:
        if block.title is not None:
            size, pitch, _, _ = STYLES["head"]
            fig.text(_LEFT / A4[0], 1 - y / H, block.title, fontsize=size, weight="bold",
                     va="top", gid=LAYER_GID)
            y += size * pitch / 72.0
        size, pitch, _, mono = STYLES[block.style]
        cols = column_lines(block)
        width = _WIDTH / len(cols) if cols else _WIDTH
        for c, lines in enumerate(cols):
            for k, line in enumerate(lines):
                if line:
                    fig.text((_LEFT + c * width) / A4[0], 1 - (y + k * size * pitch / 72.0) / H,
                             line, fontsize=size, va="top", family=_MONO if mono else None,
                             gid=LAYER_GID)
        y += max((len(c) for c in cols), default=0) * size * pitch / 72.0 + 6.0 / 72.0
    return y


def _header(fig, title: str, sub: str | None = None):
    fig.text(0.5, 0.972, title, ha="center", va="center", fontsize=12.5, weight="bold",
             gid=LAYER_GID)
    if sub:
        fig.text(_LEFT / A4[0], 0.948, _wrap(sub, 132), ha="left", va="top", fontsize=7.5,
                 gid=LAYER_GID)


def _page_extent(x, edges, bars, r):
    return extent(x[edges[np.asarray(bars)]], 3 * r)


def _page_spans(x, edges, pages, idx):
    out = []
    for i in idx:
        p = x[edges[np.asarray(pages[i].bars)]].reshape(-1, 2)
        out.append((f"p{pages[i].number}", float(p[:, 0].min()), float(p[:, 0].max())))
    return out


def _method_page(gp: GuidePlan) -> int:
    """The page that says how to build (after the overview and the pages that continue it)."""
    return next((s.number for s in gp.sheets if s.kind == "method"), 2)


def _title(gp: GuidePlan, sheet) -> str:
    what = {"overview": "overview", "method": "how to build", "motion": "motion test",
            "pictures": "motion test, pictures", "function": "functional test of the inputs"}
    if sheet.kind == "module":
        text = f"{gp.name}: page {sheet.number} of {gp.n_pages}, {modules_text(sheet.page)}"
    else:
        text = f"{gp.name}: page {sheet.number} of {gp.n_pages}: {what[sheet.kind]}"
    if not sheet.first:
        text += f" (continued from page {sheet.number - 1})"
    return text


def _overview(fig, gp: GuidePlan, sheet, plan, x, edges, r, labellers):
    layers = plan.stacking.layer
    pages = gp.pages
    size = (f"Built size {gp.size_mm[0]:.0f} × {gp.size_mm[1]:.0f} mm (bars and screw heads) "
            f"at the start; the motion test needs {gp.motion_size_mm[0]:.0f} × "
            f"{gp.motion_size_mm[1]:.0f} mm. ")
    if len(pages) > 1:
        where = ("The brackets name the page of this guide that draws each part (p<page>)"
                 if all(p.modules for p in pages) else
                 "p<page> marks the page of this guide that draws each part")
        size += (f"Build on a flat table at least {gp.size_mm[0] + 100:.0f} mm long, or in "
                 f"sections (page {_method_page(gp)}). {where}; red rings mark the screws two pages share: the "
                 "later page closes them.")
    else:
        size += f"Page {pages[0].number} draws every bar and lists every screw."
    _header(fig, _title(gp, sheet), size)
    open_j = sorted({j for p in pages for j in p.open_joints})

    def row_ext(idx):
        bars = np.concatenate([np.asarray(pages[i].bars) for i in idx])
        return _page_extent(x, edges, bars, r)

    chain = len(pages) > 1 and all(p.modules for p in pages)
    band = 0.42 if chain else 0.0
    # the drawing keeps above where the plan's text begins
    height = _text_top("overview") - 1.25 - 0.2
    rows, ext, scale = best_rows(len(pages), row_ext, _WIDTH, height, 0.15,
                                 max_scale=1 / 25.4, band_in=band)
    placed = row_axes(fig, ext, scale, _LEFT, 1.25, 0.15, _WIDTH, band_in=band)
    for row, (ax, strip) in zip(rows, placed):
        bars = np.concatenate([np.asarray(pages[i].bars) for i in row])
        draw_bars(ax, x, edges, bars, layers, r, alpha=0.4, lw=0.3)
        js = [j for j in open_j if j in edges[bars]]
        ax.plot(x[js, 0], x[js, 1], "o", ms=7, mfc="none", mec="#d00000", mew=1.3, zorder=6)
        if strip is not None:
            page_brackets(strip, _page_spans(x, edges, pages, row))
        elif len(pages) > 1:  # parts of a network: each page's name amid its bars
            for i in row:
                c = x[edges[np.asarray(pages[i].bars)]].reshape(-1, 2).mean(axis=0)
                ax.text(c[0], c[1], f"p{pages[i].number}", ha="center", va="center",
                        fontsize=9, weight="bold", zorder=8,
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="0.3", lw=0.6))
        for side in ax.spines.values():
            side.set_color("0.8")
    _draw_blocks(fig, sheet.blocks, _text_top("overview"))


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
             (top + washer, 1.3, "shims the page lists: on top, under the screw head"),
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


def _method(fig, gp: GuidePlan, sheet, plan):
    _header(fig, _title(gp, sheet))
    if sheet.first:
        ax = fig.add_axes([_LEFT / A4[0], 0.66, _WIDTH / A4[0], 0.29])
        _stack_diagram(ax, plan)
    _draw_blocks(fig, sheet.blocks, _text_top("method" if sheet.first else "continued"))


def _module_drawing(fig, gp: GuidePlan, page, plan, x, edges, r, labellers):
    st = plan.stacking
    layers = st.layer
    by_joint = {js.joint: js for js in st.joints}
    own = np.asarray(page.bars)
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
    lab = Labeller(ax, min_size=MIN_PT)
    texts = [f"J{j}" if j not in page.open_joints else f"J{j}→p{page.open_joints[j]}"
             for j in joints]
    label_joints(lab, x, joints, texts, 8, {j: "#c00000" for j in page.open_joints},
                 {j: "bold" for j in page.open_joints})
    label_bars(lab, x, edges, own, [bar_name(k, int(layers[k])) for k in own], r)
    label_bars(lab, x, edges, page.ghosts,
               [f"{bar_name(k, int(layers[k]))} p{page.bar_page[k]}" for k in page.ghosts], r,
               colour="#444444", near=near)
    labellers.append(lab)
    from matplotlib.patches import Rectangle

    present = sorted({int(layers[k]) for k in (*page.bars, *page.ghosts)})
    handles = [Rectangle((0, 0), 1, 1, fc=layer_colour(z), alpha=0.45, ec="k", lw=0.5)
               for z in present]
    ax.legend(handles, [f"layer {z}" for z in present], fontsize=7, ncol=min(len(present), 8),
              loc="upper center", bbox_to_anchor=(0.5, -0.005), frameon=False)


def _module_page(fig, gp: GuidePlan, sheet, plan, x, edges, r, labellers):
    page = sheet.page
    if sheet.first:
        _header(fig, _title(gp, sheet),
                "Bars coloured by layer (0 = bottom), labelled as engraved, B<bar> L<layer>; "
                "J<joint> = screw; S<joint>.<layer> = spacer ring "
                f"({plan.settings.spacer_diameter:g} mm, cut from the sheet). Hatched bars "
                "belong to the page named on them (p<k>): this page threads them. '→p<k>': that "
                "screw is closed on page k; leave its bars loose here.")
        _module_drawing(fig, gp, page, plan, x, edges, r, labellers)
        _draw_blocks(fig, sheet.blocks, _text_top("module"))
    else:
        _header(fig, _title(gp, sheet))
        _draw_blocks(fig, sheet.blocks, _text_top("continued"))


def _motion_pictures(fig, gp: GuidePlan, plan, edges, r, top_in: float):
    """The motion test's moments, one row each, from ``top_in`` to the bottom margin."""
    m = gp.motion
    a, b = m.joints
    frames = list(m.frames)
    pts = m.positions
    used = np.unique(edges)
    ext = [extent(pts[f][used], 2 * r) for f in frames]
    x0, x1 = min(e[0] for e in ext), max(e[2] for e in ext)
    ext = [(x0, e[1], x1, e[3]) for e in ext]  # one x range: the held joint stays in place
    title = 0.22
    height = A4[1] - top_in - BOTTOM_IN - title * len(frames)
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


def _motion_page(fig, gp: GuidePlan, sheet, plan, edges, r):
    _header(fig, _title(gp, sheet))
    top = _text_top("motion" if sheet.first else "continued")
    end = _draw_blocks(fig, sheet.blocks, top) if sheet.blocks else top
    if sheet.pictures:
        _motion_pictures(fig, gp, plan, edges, r, end + 0.1)


def render_pages(gp: GuidePlan, plan, *, dpi: int = 100, pngs: bool = False,
                 check: bool = False):
    """Draw the pages of a guide plan.

    ``check``: also list every text that does not fit on its page (``stats["clipped"]``); the
    texts of the PDF's text layer are measured on every page without it, and so are the texts
    of the pages drawn as PNG.

    Returns
    -------
    pdf : bytes
        Fonts embedded (TrueType subsets of DejaVu).
    images : list of bytes
        PNG of every page when ``pngs`` (else of the first page only).
    texts : list of list of str
        The text on each page.
    stats : dict
        ``pages``, ``labels`` placed, ``overlaps`` (pairs of label boxes that overlap, 0),
        ``shrunk``, ``dropped`` (labels with no free place) and ``dropped_on`` (the page of
        each), ``smallest_pt`` (the smallest text set on any page), ``clipped`` ((page,
        text) that does not fit on its page: which texts are measured, see ``check``).
    """
    import matplotlib
    from matplotlib.backends.backend_pdf import PdfPages

    s = plan.settings
    edges = np.asarray(plan.bars.edges)
    x = plan.design.network.nodes * s.scale
    r = 0.5 * s.bar_width
    stats = {"pages": 0, "labels": 0, "overlaps": 0, "shrunk": 0, "dropped": 0, "dropped_on": [],
             "clipped": [], "smallest_pt": float("inf")}
    images, texts, runs = [], [], []
    buf = io.BytesIO()

    def drawer(sheet):
        if sheet.kind == "overview":
            if sheet.first:
                return lambda fig, labs: _overview(fig, gp, sheet, plan, x, edges, r, labs)
            return lambda fig, labs: (_header(fig, _title(gp, sheet)),
                                      _draw_blocks(fig, sheet.blocks, _text_top("continued")))
        if sheet.kind == "method":
            return lambda fig, labs: _method(fig, gp, sheet, plan)
        if sheet.kind == "module":
            return lambda fig, labs: _module_page(fig, gp, sheet, plan, x, edges, r, labs)
        if sheet.kind == "function":
            top = _text_top("function" if sheet.first else "continued")
            return lambda fig, labs: (_header(fig, _title(gp, sheet)),
                                      _draw_blocks(fig, sheet.blocks, top))
        return lambda fig, labs: _motion_page(fig, gp, sheet, plan, edges, r)

    # TrueType (Type 42) subsets: every reader draws the glyphs measured here (a reader that
    # substitutes a font for an unembedded one sets "S tand" for "Stand"). matplotlib's PDF
    # writer sizes its font subsets by ``ps.fonttype``: at its default (3) every character past
    # the first 256 (→, ×, …) goes to a second subset of the same font, embedded again
    with frozen_heap(), matplotlib.rc_context({"pdf.fonttype": 42, "ps.fonttype": 42}), \
            PdfPages(buf, metadata={"Creator": "fabkit", "CreationDate": None, "ModDate": None,
                                    "Producer": "fabkit"}) as pdf:
        for k, sheet in enumerate(gp.sheets):
            fig = figure_kit.figure(figsize=A4)
            labellers: list = []
            drawer(sheet)(fig, labellers)
            for lab in labellers:
                stats["overlaps"] += lab.overlaps()
                for key in ("labels", "shrunk", "dropped"):
                    stats[key] += lab.stats[key]
                stats["dropped_on"] += [k + 1] * lab.stats["dropped"]
            shown = figure_texts(fig)
            texts.append([t.get_text() for t in shown])
            stats["smallest_pt"] = min([stats["smallest_pt"], *(t.get_fontsize() for t in shown)])
            # the headers, block lines and labels go to the PDF's text layer (.pdf_text), not
            # through matplotlib; the figure keeps them for the PNG and the clipping check
            layer = [t for t in shown if t.get_gid() == LAYER_GID]
            runs.append(text_runs(fig, layer))
            # every page's layer text is measured as set, at no cost: its clipping is known
            # for every page, not only for the pages drawn as PNG
            edge = off_page(runs[-1], *(72.0 * v for v in fig.get_size_inches()))
            for t in layer:
                t.set_visible(False)
            pdf.savefig(fig)
            for t in layer:
                t.set_visible(True)
            if pngs or k == 0:  # one raster drawing gives the PNG and the clipping check
                png, clipped = checked_png(fig, dpi=dpi)
                images.append(png)
            else:
                clipped = clipped_texts(fig) if check else []
            # what a drawing measured (the PNG pages, every page with ``check``) and the
            # layer's own measure, each text once
            stats["clipped"] += [(k + 1, t) for t in dict.fromkeys([*clipped, *edge])]
            stats["pages"] += 1
    return add_text_layer(buf.getvalue(), runs), images, texts, stats
