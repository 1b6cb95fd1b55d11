"""Assembly guide: A4 pages a person follows at the bench to stack and screw a laser-cut kit.

One page per group of modules (per two modules of a chain; the whole network when it is not
a chain). Each page draws the group's bars in the reference configuration, coloured by layer
and lowest layer first, with the bar id and layer on every bar and the joint id at every
screw, followed by the stack at each of the page's joints, bottom to top, with the screw
length and washers. Labels never overlap: each label tries positions along its bar (and beside
it) until its box, measured by the renderer, is free of the labels already placed; as a last
resort it shrinks.
"""

from __future__ import annotations

import io

import numpy as np
from ..numerics import MM_SLACK

__all__ = ["guide_pages", "A4"]

#: A4 portrait, inches (matplotlib's unit).
A4 = (8.27, 11.69)
_MODULES_PER_PAGE = 2


def _groups(plan):
    """Bar index groups, one per page (modules of a chain two at a time, else everything)."""
    net = plan.design.network
    layout = net.assembly
    n_e = net.n_edges
    if layout is None:
        return [np.arange(n_e)]
    counts = [m.n_edges for m, _, _ in layout.copies]
    if sum(counts) != n_e:
        return [np.arange(n_e)]
    offsets = np.concatenate([[0], np.cumsum(counts)])
    k = len(counts)
    return [np.arange(offsets[c], offsets[min(c + _MODULES_PER_PAGE, k)])
            for c in range(0, k, _MODULES_PER_PAGE)]


def _overlaps(box, boxes) -> bool:
    return any(box.overlaps(b) for b in boxes)


def guide_pages(plan, *, dpi: int = 100):
    """The assembly guide of a laser plan.

    Parameters
    ----------
    plan : fabkit.export.dxf.LaserPlan
    dpi : int
        Resolution of the PNG of the first page.

    Returns
    -------
    pdf : bytes
        All pages, A4 portrait.
    first_png : bytes
        The first page as PNG (for documentation).
    stats : dict
        ``pages``, ``labels`` (placed), ``overlaps`` (pairs of label boxes that overlap, 0),
        ``shrunk`` (labels set smaller to fit).
    """
    from matplotlib.backends.backend_pdf import PdfPages
    from matplotlib.collections import PolyCollection

    from .bars import stadium_polygon
    from ..viz import _mpl

    plt = _mpl()
    cmap = plt.get_cmap("tab10")
    st, s = plan.stacking, plan.settings
    edges = np.asarray(plan.bars.edges)
    x = plan.design.network.nodes * s.scale
    r = 0.5 * s.bar_width
    by_joint = {js.joint: js for js in st.joints}
    groups = _groups(plan)
    pdf_buf = io.BytesIO()
    first_png = b""
    stats = {"pages": 0, "labels": 0, "overlaps": 0, "shrunk": 0}
    with PdfPages(pdf_buf, metadata={"Creator": "fabkit", "CreationDate": None,
                                     "ModDate": None, "Producer": "fabkit"}) as pdf:
        for page, bars in enumerate(groups, start=1):
            fig = plt.figure(figsize=A4)
            ax = fig.add_axes([0.06, 0.40, 0.88, 0.53])
            order = bars[np.argsort(st.layer[bars], kind="stable")]
            polys = [stadium_polygon(x[edges[k, 0]], x[edges[k, 1]], r) for k in order]
            ax.add_collection(PolyCollection(
                polys, facecolors=[cmap(int(st.layer[k]) % 10) for k in order],
                edgecolors="k", linewidths=0.5, alpha=0.45))
            joints = sorted({int(j) for j in edges[bars].ravel() if int(j) in by_joint})
            ax.plot(x[joints, 0], x[joints, 1], "o", ms=3.5, color="k", zorder=5)
            ax.set_aspect("equal")
            ax.autoscale_view()
            lo, hi = x[edges[bars]].reshape(-1, 2).min(0) - 3 * r, \
                x[edges[bars]].reshape(-1, 2).max(0) + 3 * r
            ax.set_xlim(lo[0], hi[0])
            ax.set_ylim(lo[1], hi[1])
            ax.set_xticks([])
            ax.set_yticks([])
            fig.canvas.draw()
            renderer = fig.canvas.get_renderer()
            placed = []

            def put(text, candidates, size, colour):
                for fs in (size, 0.8 * size, 0.65 * size):
                    for pos in candidates:
                        t = ax.text(pos[0], pos[1], text, fontsize=fs, ha="center",
                                    va="center", color=colour, zorder=10,
                                    bbox=dict(boxstyle="square,pad=0.1", fc="white", ec="none",
                                              alpha=0.8))
                        box = t.get_window_extent(renderer).expanded(1.05, 1.1)
                        inside = ax.bbox.contains(box.x0, box.y0) and \
                            ax.bbox.contains(box.x1, box.y1)
                        if inside and not _overlaps(box, placed):
                            placed.append(box)
                            stats["labels"] += 1
                            stats["shrunk"] += fs < size
                            return True
                        t.remove()
                return False

            # screw (joint) labels first, just beside their joint
            px = (hi[0] - lo[0]) / (0.88 * A4[0] * 72)  # mm per point, roughly
            for j in joints:
                off = 9 * px
                cands = [x[j] + np.array(d) * off for d in
                         ((0, 1), (1, 1), (-1, 1), (1, 0), (-1, 0), (0, -1), (1, -1), (-1, -1),
                          (0, 2), (2, 0), (-2, 0), (0, -2))]
                put(f"J{j}", cands, 8, "black")
            for k in bars:
                a, b = x[edges[k, 0]], x[edges[k, 1]]
                normal = np.array([a[1] - b[1], b[0] - a[0]]) / max(np.linalg.norm(b - a), MM_SLACK)
                cands = [a + t * (b - a) + o * normal * r
                         for o in (0.0, 1.6, -1.6) for t in (0.5, 0.38, 0.62, 0.28, 0.72)]
                put(f"B{k}·L{int(st.layer[k])}", cands, 7, "#222222")
            # every label box, checked once more against all others
            for i in range(len(placed)):
                for j in range(i + 1, len(placed)):
                    stats["overlaps"] += placed[i].overlaps(placed[j])
            mods = ""
            layout = plan.design.network.assembly
            if layout is not None and len(groups) > 1:
                c0 = (page - 1) * _MODULES_PER_PAGE + 1
                c1 = min(c0 + _MODULES_PER_PAGE - 1, len(layout.copies))
                mods = f", modules {c0}-{c1}" if c1 > c0 else f", module {c0}"
            fig.suptitle(f"{plan.design.name}: assembly page {page} of {len(groups)}{mods}",
                         fontsize=12, y=0.975)
            fig.text(0.06, 0.945, "Bars coloured by layer (0 = bottom); label B<bar>·L<layer>; "
                     "J<joint> = screw. Lay every layer-0 bar, then layer 1, ... and close the "
                     "screws last.", fontsize=7.5)
            handles = [plt.Rectangle((0, 0), 1, 1, fc=cmap(z % 10), alpha=0.45, ec="k", lw=0.5)
                       for z in range(st.n_layers)]
            ax.legend(handles, [f"layer {z}" for z in range(st.n_layers)], fontsize=7,
                      ncol=min(st.n_layers, 7), loc="upper center",
                      bbox_to_anchor=(0.5, -0.005), frameon=False)
            rows = []
            for j in joints:
                js = by_joint[j]
                at = dict(zip(js.layers, js.bars))
                seq = " / ".join(f"B{at[z]}(L{z})" if z in at else f"S{j}.{z}"
                                 for z in range(min(js.layers), max(js.layers) + 1))
                rows.append(f"J{j}: {seq}   |  {js.fastener.describe()}")
            ncol = 2 if len(rows) > 18 else 1
            per = int(np.ceil(len(rows) / ncol)) if rows else 0
            fig.text(0.06, 0.335, "Stack at each screw, bottom to top (spacer = ring "
                     f"S<joint>.<layer>, {s.spacer_diameter:g} mm):", fontsize=8.5,
                     weight="bold")
            fs = 7 if per <= 30 else max(4.5, 7 * 30 / per)
            for c in range(ncol):
                fig.text(0.06 + 0.46 * c, 0.32, "\n".join(rows[c * per:(c + 1) * per]),
                         fontsize=fs, va="top", family="DejaVu Sans Mono")
            pdf.savefig(fig)
            if page == 1:
                buf = io.BytesIO()
                fig.savefig(buf, format="png", dpi=dpi)
                first_png = buf.getvalue()
            plt.close(fig)
            stats["pages"] += 1
    return pdf_buf.getvalue(), first_png, stats
