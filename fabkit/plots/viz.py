"""Pictures of networks and motions (matplotlib figures; saving is the caller's job)."""

from __future__ import annotations

import gc
from contextlib import contextmanager

import numpy as np

from ..model.network import Network

__all__ = ["draw_network", "motion_figure", "elastic_figure", "figure_png", "checked_png", "clipped_texts",
           "figure_texts", "layout_faults", "frozen_heap", "set_margins", "plain_log_ticks", "figure_kit"]


#: Floor of edge errors drawn on a log scale (an exact zero has no logarithm).
LOG_FLOOR = 1e-17


class Figures:
    """pyplot's figure-making calls, on :class:`matplotlib.figure.Figure` objects of their own.

    fabkit renders its pictures to bytes: each figure gets its own Agg canvas, and neither
    pyplot's list of open figures nor the session's backend is touched, so a notebook's or an
    application's matplotlib stays as its user set it (``matplotlib.use`` is never called).
    A figure is freed when its caller drops it; there is nothing to close.
    """

    @staticmethod
    def figure(**kwargs):
        """A new figure on its own Agg canvas (keywords as :class:`matplotlib.figure.Figure`)."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(**kwargs)
        FigureCanvasAgg(fig)
        return fig

    def subplots(self, nrows: int = 1, ncols: int = 1, *, sharex=False, sharey=False,
                 squeeze: bool = True, width_ratios=None, height_ratios=None, subplot_kw=None,
                 gridspec_kw=None, **fig_kw):
        """A figure and its grid of axes, as :func:`matplotlib.pyplot.subplots` returns them."""
        fig = self.figure(**fig_kw)
        axes = fig.subplots(nrows, ncols, sharex=sharex, sharey=sharey, squeeze=squeeze,
                            width_ratios=width_ratios, height_ratios=height_ratios,
                            subplot_kw=subplot_kw, gridspec_kw=gridspec_kw)
        return fig, axes

    @staticmethod
    def get_cmap(name: str, lut: int | None = None):
        """A registered colormap, resampled to ``lut`` colours when given."""
        import matplotlib

        cmap = matplotlib.colormaps[name]
        return cmap.resampled(lut) if lut is not None else cmap

    @property
    def Line2D(self):  # noqa: N802 - the matplotlib class, by its own name
        from matplotlib.lines import Line2D

        return Line2D

    @property
    def Rectangle(self):  # noqa: N802
        from matplotlib.patches import Rectangle

        return Rectangle

    @property
    def Circle(self):  # noqa: N802
        from matplotlib.patches import Circle

        return Circle


#: The figure factory every fabkit picture is made with (see :class:`Figures`).
figure_kit = Figures()


_SUPERSCRIPT = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")


def _log_formatter(**kwargs):
    """matplotlib's log-axis tick formatter, its labels written as plain text (``10⁻³``,
    ``6×10⁻¹⁶``) instead of math text: the same labels at the same ticks, without the math
    text parser (1.55 s of CPU in the figures of the first 8 bundled designs' export)."""
    from matplotlib.ticker import LogFormatterSciNotation

    class PlainLogFormatter(LogFormatterSciNotation):
        def __call__(self, x, pos=None):
            label = super().__call__(x, pos)
            if not label.startswith("$\\mathdefault{"):
                return label
            body = label[len("$\\mathdefault{"):-len("}$")].replace("\\times", "×")
            base, _, exponent = body.partition("^{")
            base = base.replace("-", "−")
            return base + exponent.rstrip("}").translate(_SUPERSCRIPT) if exponent else base

    return PlainLogFormatter(**kwargs)


def plain_log_ticks(axis) -> None:
    """Label a log-scale axis (``ax.xaxis`` or ``ax.yaxis``) in plain text, as matplotlib's own
    log labels but without math text (see :func:`_log_formatter`)."""
    axis.set_major_formatter(_log_formatter())
    axis.set_minor_formatter(_log_formatter(labelOnlyBase=False))


def draw_network(ax, net, positions=None, *, color="C0", alpha=1.0, lw=1.5, nodes=True,
                 ports=False, zorder=2):
    """Draw a 2D network (3D: projected on x-y) into a matplotlib axis."""
    from matplotlib.collections import LineCollection

    x = net.nodes if positions is None else np.asarray(positions)
    seg = x[net.edges][:, :, :2]
    ax.add_collection(LineCollection(seg, colors=color, linewidths=lw, alpha=alpha, zorder=zorder))
    if nodes and net.n_nodes <= 5000:
        ax.plot(x[:, 0], x[:, 1], "o", ms=3 if net.n_nodes > 50 else 4, color=color, alpha=alpha,
                zorder=zorder + 1)
    if ports:
        for name, (i, j) in net.ports.items():
            ax.plot(x[[i, j], 0], x[[i, j], 1], ":", color="0.4", lw=0.8, zorder=zorder - 1)
    ax.set_aspect("equal")
    ax.autoscale_view()


def motion_figure(traj, *, frames: int = 3, title: str | None = None):
    """Initial, intermediate and final geometry overlaid, plus the drive along the path.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, (ax, ax2) = figure_kit.subplots(1, 2, figsize=(11, 4.8),
                                         gridspec_kw={"width_ratios": [2, 1]})
    s = traj.n_steps
    idx = sorted(set(np.linspace(0, s - 1, max(frames, 2)).round().astype(int).tolist()))
    cmap = figure_kit.get_cmap("Blues")
    for k, i in enumerate(idx):
        shade = 0.9 - 0.6 * k / max(len(idx) - 1, 1)
        draw_network(ax, traj.network, traj.positions[i], color=cmap(shade),
                     lw=1.8 if i in (0, s - 1) else 1.0)
    a, b = traj.drive_port
    ax.plot(*traj.positions[-1][[a, b], :2].T, "--", color="C3", lw=1, label="drive (final)")
    ax.set_title(title or "motion: dark = start, light = end")
    ax.legend(loc="best", fontsize=8)
    ax2.plot(traj.arclength, traj.drive, "-", color="C0", label="drive")
    ax2.set_xlabel("arclength")
    ax2.set_ylabel("drive distance")
    ax2.set_title(f"{traj.method}: {traj.status}")
    ax2b = ax2.twinx()
    err = np.maximum(traj.edge_error, LOG_FLOOR)
    ax2b.semilogy(traj.arclength, err, ".", color="C3", ms=3)
    plain_log_ticks(ax2b.yaxis)
    ax2b.set_ylabel("max relative edge error", color="C3")
    set_margins(fig, left=0.55, right=1.2, bottom=0.55, top=0.35, gap=0.85)
    return fig


def elastic_figure(run, *, title: str | None = None):
    """A build driven with elastic bars: its start and end, and the elastic energy and the
    largest bar stress (against the material's allowable) along the drive.

    Parameters
    ----------
    run : fabkit.tolerance.elastic.ElasticRun

    Returns
    -------
    matplotlib.figure.Figure
    """
    m = run.motion
    fig, (ax, ax2) = figure_kit.subplots(1, 2, figsize=(11, 4.8),
                                         gridspec_kw={"width_ratios": [2, 1]})
    net = Network(m.positions[0], run.edges)
    draw_network(ax, net, m.positions[0], color="0.6", lw=1.0)
    peak = m.peak_stress
    draw_network(ax, net, m.positions[-1], color="C3" if peak[-1] > run.material.allowable_mpa
                 else "C0", lw=1.6)
    ax.set_title(title or "driven with elastic bars: grey = start, coloured = end")
    ax2.plot(m.drive, peak, "-", color="C3", label="largest stress")
    ax2.axhline(run.material.allowable_mpa, color="C3", ls="--", lw=0.8,
                label=f"{run.material.name} allows")
    ax2.set_xlabel(f"{run.drive} (mm)")
    ax2.set_ylabel("largest |stress| (MPa)", color="C3")
    ax2.legend(loc="upper left", fontsize=8)
    ax2b = ax2.twinx()
    ax2b.plot(m.drive, m.energy, ".", color="C0", ms=3)
    ax2b.set_ylabel("elastic energy (mJ)", color="C0")
    if m.drive[-1] < m.drive[0]:
        ax2.invert_xaxis()  # the drive's own direction, start on the left
    ax2.set_title("quasi-static steps")
    set_margins(fig, left=0.55, right=1.2, bottom=0.55, top=0.35, gap=0.85)
    return fig


@contextmanager
def frozen_heap():
    """Draw with the objects that exist before the drawing left out of the garbage collector's
    full passes (:func:`gc.freeze`, undone on leaving).

    A drawing makes many objects, and each full pass of the collector it sets off walks every
    object of the process as well (a design's export holds some 200 000): a tenth of the time
    of drawing a kit's guide. The objects the drawing makes are collected as always. Nothing is
    frozen when the caller has frozen objects itself or turned the collector off.
    """
    if not gc.isenabled() or gc.get_freeze_count():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


#: zlib level of the PNGs: 1 writes them in 80 % of the time of level 4 (0.62 against 0.75 s for
#: the 30 pictures of five bundled designs) for files 7 % larger (6.2 against 5.8 MB).
PNG_COMPRESSION = 1


def _canvas_png(fig, dpi: int) -> bytes:
    """The figure's drawn canvas as PNG bytes: RGB when every pixel is opaque (a figure's
    white background), else RGBA; no metadata but the resolution."""
    import io

    from PIL import Image

    rgba = np.asarray(fig.canvas.buffer_rgba())  # (height, width, 4), no copy
    image = Image.frombuffer("RGBA", (rgba.shape[1], rgba.shape[0]), rgba, "raw", "RGBA", 0, 1)
    if image.getextrema()[3][0] == 255:  # PIL's conversion: a third cheaper than NumPy's copy
        image = image.convert("RGB")
    buf = io.BytesIO()
    image.save(buf, format="png", compress_level=PNG_COMPRESSION, dpi=(dpi, dpi))
    return buf.getvalue()


def figure_png(fig, dpi: int = 110) -> bytes:
    """Render a figure to PNG bytes (deterministic metadata).

    The canvas is drawn once (``savefig`` draws a figure laid out by ``tight_layout`` twice). A
    figure placed by :func:`set_margins` (no layout engine) is checked on that drawing and laid
    out by ``tight_layout`` and drawn again only when :func:`layout_faults` finds a text cut off
    or running into another axes.
    """
    fig.set_dpi(dpi)
    _draw_fitted(fig)
    return _canvas_png(fig, dpi)


def _draw_fitted(fig) -> None:
    """Draw a figure on its canvas; one without a layout engine (fixed margins) whose drawing
    shows :func:`layout_faults` is laid out by ``tight_layout`` and drawn again."""
    fig.canvas.draw()
    if fig.get_layout_engine() is None and layout_faults(fig):
        fig.tight_layout()
        fig.canvas.draw()


def set_margins(fig, *, left: float, right: float, bottom: float, top: float,
                gap: float = 0.0) -> None:
    """Place a figure's grid of subplots by fixed margins, in inches.

    A layout engine lays a figure out once more before it is drawn (``tight_layout`` took as
    long as the drawing itself, 62 ms a figure in an export); fixed margins cost nothing, and
    :func:`figure_png` falls back to ``tight_layout`` when the drawing shows they do not fit.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Its axes on one grid (``figure_kit.subplots``); twin axes share their parent's place.
    left, right, bottom, top : float
        Inches from each edge of the figure to the outer axes.
    gap : float
        Inches between neighbouring columns and rows of the grid.
    """
    w, h = fig.get_size_inches()
    grid = fig.axes[0].get_subplotspec().get_gridspec()
    inner_w, inner_h = w - left - right, h - top - bottom
    ncols, nrows = grid.ncols, grid.nrows
    # matplotlib's spaces are fractions of the mean axes width (height)
    wspace = gap * ncols / (inner_w - (ncols - 1) * gap) if ncols > 1 else None
    hspace = gap * nrows / (inner_h - (nrows - 1) * gap) if nrows > 1 else None
    fig.subplots_adjust(left=left / w, right=1 - right / w, bottom=bottom / h, top=1 - top / h,
                        wspace=wspace, hspace=hspace)


def checked_png(fig, dpi: int = 110) -> tuple[bytes, list]:
    """Render a figure once: its PNG bytes (as :func:`figure_png`) and its
    :func:`clipped_texts`.

    The check measures the drawing the PNG is made of, so a picture is drawn once, not twice.
    """
    fig.set_dpi(dpi)
    clipped = clipped_texts(fig, render=True)  # draws the canvas at ``dpi``
    return _canvas_png(fig, dpi), clipped


def clipped_texts(fig, *, render: bool = False) -> list:
    """The visible texts of a figure that do not fit inside it (a title cut off at the edge).

    Tick labels count as one text per axis (``"x ticks of <axes title>"``), and only those
    drawn (within the axis' limits).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    render : bool
        Rasterise the figure on its canvas as well (for a caller that wants its pixels); else
        only lay it out (legends, titles and aspect placed as a draw places them), which
        gives the same text boxes for a fraction of the time.

    Returns
    -------
    list of str
    """
    if render:
        fig.canvas.draw()
    else:
        fig.draw_without_rendering()
    return _faults(fig, fig.canvas.get_renderer(), overlaps=False)


def layout_faults(fig) -> list:
    """What does not fit in a figure as last drawn on its canvas: the texts cut off at its
    edge (as :func:`clipped_texts`), and axes whose ticks, labels or title run into another
    axes or into the figure's title (``"<title> runs into <title>"``; twin axes count as one).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Drawn (``fig.canvas.draw()``); the text sizes of that drawing are reused.

    Returns
    -------
    list of str
    """
    return _faults(fig, fig.canvas.get_renderer(), overlaps=True)


def _axis_extent(axis, renderer):
    """The box of an axis' drawn tick labels, its label and offset text, as placed by the last
    draw (``Axis.get_tightbbox`` without placing the label again: a third of its time)."""
    from matplotlib.transforms import Bbox

    boxes = [label.get_window_extent(renderer)
             for tick in axis._update_ticks()  # the ticks inside the view, as drawn
             for label in (tick.label1, tick.label2) if label.get_visible()]
    boxes += [t.get_window_extent(renderer) for t in (axis.label, axis.offsetText)
              if t.get_visible() and t.get_text()]
    boxes = [b for b in boxes if b._is_finite()]
    return Bbox.union(boxes) if boxes else None


def _all_texts(fig) -> list:
    """Every :class:`~matplotlib.text.Text` of a figure but its tick labels, in the order of
    ``fig.findobj(Text)``.

    ``findobj`` walks an axis' ticks through ``Axis.get_children``, which makes the ticks of an
    axis that has none yet (one turned off, one never drawn): a third of the time of checking
    a picture of many axes went into making ticks only to leave them out.
    """
    from matplotlib.axis import Axis
    from matplotlib.text import Text

    out: list = []

    def walk(artist) -> None:
        children = ((artist.label, artist.offsetText) if isinstance(artist, Axis)
                    else artist.get_children())
        for child in children:
            walk(child)
        if isinstance(artist, Text):
            out.append(artist)

    walk(fig)
    return out


def figure_texts(fig) -> list:
    """The texts a figure shows (visible, not empty), tick labels left out, in the order of
    ``fig.findobj(Text)``; the ticks of an axis are not made to find them (see
    :func:`_all_texts`).

    Parameters
    ----------
    fig : matplotlib.figure.Figure

    Returns
    -------
    list of matplotlib.text.Text
    """
    return [t for t in _all_texts(fig) if t.get_visible() and t.get_text()]


def _faults(fig, renderer, *, overlaps: bool) -> list:
    from matplotlib.transforms import Bbox

    box = fig.bbox

    def outside(e) -> bool:
        return e is not None and (e.x0 < box.x0 - 0.5 or e.y0 < box.y0 - 0.5
                                  or e.x1 > box.x1 + 0.5 or e.y1 > box.y1 + 0.5)

    out = []
    places: dict = {}  # axes position -> (name, boxes of the axes and its decorations)
    for ax in fig.axes:
        name = ax.get_title() or "an axes"
        key = tuple(round(v, 4) for v in ax.get_position().bounds)
        place = places.setdefault(key, (name, [ax.bbox]))
        for title in (ax.title, ax._left_title, ax._right_title):
            if title.get_visible() and title.get_text().strip():
                place[1].append(title.get_window_extent(renderer))
        if not ax.axison:  # ax.axis("off"): its axes are not drawn, nor their ticks
            continue
        for axis_name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            if not axis.get_visible():
                continue
            extent = _axis_extent(axis, renderer)
            if outside(extent):
                out.append(f"{axis_name} ticks of {name}")
            if extent is not None:
                place[1].append(extent)
    for t in _all_texts(fig):  # tick labels are counted per axis above
        if not t.get_visible() or not t.get_text().strip():
            continue
        if outside(t.get_window_extent(renderer)):
            out.append(t.get_text())
    if not overlaps:
        return out

    def meet(a, b) -> bool:
        return (a.x0 < b.x1 - 0.5 and b.x0 < a.x1 - 0.5
                and a.y0 < b.y1 - 0.5 and b.y0 < a.y1 - 0.5)

    regions = [(name, Bbox.union(boxes)) for name, boxes in places.values()]
    for i, (name_a, a) in enumerate(regions):
        for name_b, b in regions[i + 1:]:
            if meet(a, b):
                out.append(f"{name_a} runs into {name_b}")
    for t in [fig._suptitle, *fig.texts]:
        if t is None or not t.get_visible() or not t.get_text().strip():
            continue
        e = t.get_window_extent(renderer)
        out += [f"{t.get_text()} runs into {name}" for name, r in regions if meet(e, r)]
    return out
