"""Pictures whose words can be read: no title or label cut off at the figure's edge, and axes
that do not read as inches."""

from __future__ import annotations

import pytest

import fabkit
from fabkit.tolerance import analyse_tolerance, tolerance_figure, tolerance_spec
from fabkit.plots.viz import clipped_texts, figure_kit

from conftest import TEMPLATES


def test_clipped_texts_finds_a_title_cut_off_at_the_edge():
    fig, ax = figure_kit.subplots(figsize=(4, 3))
    ax.set_title("fits")
    assert clipped_texts(fig) == []
    fig.text(0.9, 0.5, "runs off the right edge")
    ax.set_xlabel("a label much too long for a figure four inches wide, so it is cut off")
    # (the axis with its label counts once as its ticks, and the label once as itself)
    long = "a label much too long for a figure four inches wide, so it is cut off"
    assert clipped_texts(fig) == ["x ticks of fits", long, "runs off the right edge"]


def test_the_tolerance_picture_keeps_a_long_verdict_inside():
    design = fabkit.load_template(TEMPLATES / "chaotic_chain.toml")
    result = analyse_tolerance(design, tolerance_spec(design, samples=30))
    assert len(result.verdict) > 300  # the verdict runs over several lines
    fig = tolerance_figure(result, title=design.name)
    assert clipped_texts(fig) == []
    assert fig._suptitle.get_text().count("\n") >= 2


def test_the_map_axes_say_input_and_output_not_inches():
    from fabkit.plots.mapplots import map_figure

    design = fabkit.load_template(TEMPLATES / "super_stable.toml")
    fig = map_figure(fabkit.module_map(design.network, d_in="d1", d_out="d2"))
    ax = fig.axes[0]
    assert ax.get_xlabel() == "dₖ, input of module k (design units)"
    assert ax.get_ylabel() == "dₖ₊₁ = f(dₖ), its output (design units)"
    assert clipped_texts(fig) == []


def test_log_axes_are_labelled_as_matplotlib_labels_them_in_plain_text():
    """The log tick labels of the export's figures say what matplotlib's say (10⁻³, 6×10⁻¹⁶),
    at the same ticks, without math text."""
    from matplotlib.ticker import LogFormatterSciNotation

    from fabkit.plots.viz import plain_log_ticks

    fig, ax = figure_kit.subplots()
    ax.semilogy([0, 1], [6e-16, 3e-15])
    ours = ax.yaxis
    plain_log_ticks(ours)
    fig.canvas.draw()
    theirs = {}
    for minor, fmt in ((False, LogFormatterSciNotation()),
                       (True, LogFormatterSciNotation(labelOnlyBase=False))):
        ticks = ours.get_minorticklocs() if minor else ours.get_majorticklocs()
        fmt.set_axis(ours)
        theirs[minor] = fmt.format_ticks(ticks)
    plain = [t.get_text() for t in ours.get_majorticklabels()]
    assert not any("$" in t for t in plain + [t.get_text() for t in ours.get_minorticklabels()])
    as_math = [t.replace("$\\mathdefault{", "").replace("}$", "").replace("\\times", "×")
               .replace("10^{", "10^").replace("}", "") for t in theirs[False]]
    sup = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹⁻", "0123456789-")
    assert [t.replace("−", "-").replace("10", "10^", 1).translate(sup) if "10" in t else t
            for t in plain] == as_math
    minor_labels = [t.get_text() for t in ours.get_minorticklabels() if t.get_text()]
    assert "6×10⁻¹⁶" in minor_labels and len(minor_labels) == sum(bool(t) for t in theirs[True])


def test_layout_faults_finds_labels_cut_off_and_axes_that_run_into_each_other():
    from fabkit.plots.viz import _draw_fitted, layout_faults, set_margins

    fig, (a, b) = figure_kit.subplots(1, 2, figsize=(6, 3))
    a.set_title("left")
    b.set_title("right")
    for ax in (a, b):
        ax.plot([0, 1], [1e5, 2e5])
        ax.set_ylabel("a y label")
    set_margins(fig, left=0.05, right=0.1, bottom=0.6, top=0.4, gap=0.05)
    fig.canvas.draw()
    faults = layout_faults(fig)
    assert "y ticks of left" in faults          # off the left edge
    assert "left runs into right" in faults     # the right axes' ticks and label in the gap
    params = (fig.subplotpars.left, fig.subplotpars.wspace)
    _draw_fitted(fig)  # the fallback: tight_layout, drawn again
    assert layout_faults(fig) == []
    assert fig.subplotpars.left > params[0] and fig.subplotpars.wspace > params[1]
    # margins that fit are kept as they are
    fig2, ax = figure_kit.subplots(figsize=(6, 3))
    ax.plot([0, 1], [0, 1])
    set_margins(fig2, left=0.6, right=0.2, bottom=0.5, top=0.3)
    _draw_fitted(fig2)
    assert layout_faults(fig2) == []
    assert abs(fig2.subplotpars.left - 0.1) < 1e-12 and abs(fig2.subplotpars.top - 0.9) < 1e-12


def test_set_margins_gives_the_gaps_in_inches():
    from fabkit.plots.viz import set_margins

    fig, axes = figure_kit.subplots(2, 3, figsize=(10, 6))
    set_margins(fig, left=0.7, right=0.3, bottom=0.5, top=0.4, gap=0.8)
    (x0, y0), (x1, y1) = [axes[1, 0].get_position().get_points()[k] for k in (0, 1)]
    nx0 = axes[1, 1].get_position().x0
    top = axes[0, 0].get_position().y0
    assert abs(x0 * 10 - 0.7) < 1e-9 and abs(y0 * 6 - 0.5) < 1e-9
    assert abs((nx0 - x1) * 10 - 0.8) < 1e-9 and abs((top - y1) * 6 - 0.8) < 1e-9
    assert abs(axes[0, 2].get_position().x1 * 10 - 9.7) < 1e-9


def test_the_export_figures_fit_their_fixed_margins_without_a_second_layout():
    """The motion, map and tolerance pictures of the export are placed by fixed margins; on
    designs with long titles, log axes and multi-line verdicts nothing is cut off or overlaps,
    so figure_png draws each once."""
    from fabkit.pipeline.motion import map_figure, traced_motion
    from fabkit.plots.viz import layout_faults, motion_figure

    for name in ("super_stable_chain", "fourbar", "period_two_chain16"):
        design = fabkit.load_template(TEMPLATES / f"{name}.toml")
        traj = traced_motion(design, allow_singular_start=True)
        figs = [motion_figure(traj, title=design.name), map_figure(traj, design)]
        result = analyse_tolerance(design, tolerance_spec(design, samples=30), trajectory=traj)
        figs.append(tolerance_figure(result, title=design.name))
        for fig in figs:
            assert fig.get_layout_engine() is None
            fig.set_dpi(110)
            fig.canvas.draw()
            assert layout_faults(fig) == [], (name, fig.get_size_inches())


def test_figure_png_is_opaque_rgb_with_the_pixels_of_the_canvas():
    """A figure on its white background becomes an RGB PNG (a transparent one stays RGBA) with
    exactly the pixels matplotlib drew, at the resolution asked."""
    import io

    import numpy as np
    from PIL import Image

    from fabkit.plots.viz import figure_png, set_margins

    fig, ax = figure_kit.subplots(figsize=(3, 2))
    ax.plot([0, 1], [0, 1], color="C3")
    set_margins(fig, left=0.5, right=0.2, bottom=0.4, top=0.2)  # fits: drawn once
    fig.set_dpi(100)
    fig.canvas.draw()
    drawn = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    im = Image.open(io.BytesIO(figure_png(fig, dpi=100)))
    assert im.mode == "RGB" and im.size == (300, 200)
    assert round(im.info["dpi"][0]) == 100
    assert np.array_equal(np.asarray(im), drawn)
    clear = figure_kit.figure(figsize=(2, 2))
    clear.patch.set_alpha(0.0)
    im = Image.open(io.BytesIO(figure_png(clear, dpi=50)))
    assert im.mode == "RGBA" and im.size == (100, 100) and np.asarray(im)[..., 3].min() == 0


@pytest.mark.parametrize("n_layers", [1, 8, 9, 14, 24])
def test_the_layer_legend_of_a_kit_picture_fits_under_its_drawing(n_layers):
    """The AND gate's 14 layers ran its pictures' legend off both edges ("layer 0", "layer 1"
    and "layer 13" cut off): the legend keeps to rows of LEGEND_COLUMNS, every entry inside the
    picture, and the bottom margin grows with its rows so that it stays under the drawing (a
    kit stacks at most 24 layers by default)."""
    from fabkit.fab.guide.pictures import (bottom_margin, layer_legend, LEGEND_COLUMNS,
                                           PICTURE_WIDTH)

    top, drawing = 0.75, 2.0
    bottom = bottom_margin(n_layers)
    fig = figure_kit.figure(figsize=(PICTURE_WIDTH, top + drawing + bottom), dpi=100)
    ax = fig.add_axes([0.3 / PICTURE_WIDTH, bottom / (top + drawing + bottom),
                       (PICTURE_WIDTH - 0.6) / PICTURE_WIDTH, drawing / (top + drawing + bottom)])
    ax.axis("off")  # as the pictures draw their rows
    layer_legend(fig, n_layers)
    assert clipped_texts(fig) == []
    legend = fig.legends[0]
    box = legend.get_window_extent(fig.canvas.get_renderer())
    assert box.y1 <= ax.get_window_extent().y0 + 0.5  # under the drawing, not over it
    assert 0 <= box.x0 and box.x1 <= PICTURE_WIDTH * 100
    rows = {round(t.get_window_extent().y0) for t in legend.get_texts()}
    assert len(rows) == -(-n_layers // LEGEND_COLUMNS)


def test_a_kit_picture_that_cuts_a_text_off_is_a_warning_of_the_export(monkeypatch):
    """The pictures measure their texts on the drawing their PNG is made of; a text cut off at
    the edge is said in the laser format's report (its ``warnings``), not shipped unnoticed.
    Drawn 3 inches wide, the four-bar's pictures cut off their titles."""
    from fabkit.fab.guide import pictures
    from fabkit.writers.dxf import export_design

    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    assert "warnings" not in export_design(design).report  # as drawn: every text inside
    monkeypatch.setattr(pictures, "PICTURE_WIDTH", 3.0)
    warnings = export_design(design).report["warnings"]
    assert [w.split(":")[0] for w in warnings] == ["laser_assembly.png",
                                                    "laser_layers_motion.png"]
    assert all("text cut off at the picture's edge: " in w for w in warnings)
    assert "fourbar: assembly, 3 layers" in warnings[0]
