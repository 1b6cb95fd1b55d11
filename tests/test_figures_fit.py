"""Pictures whose words can be read: no title or label cut off at the figure's edge, and axes
that do not read as inches."""

from __future__ import annotations

import fabkit
from fabkit.tolerance import analyse_tolerance, tolerance_figure, tolerance_spec
from fabkit.viz import _mpl, clipped_texts

from conftest import TEMPLATES


def test_clipped_texts_finds_a_title_cut_off_at_the_edge():
    plt = _mpl()
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.set_title("fits")
    assert clipped_texts(fig) == []
    fig.text(0.9, 0.5, "runs off the right edge")
    ax.set_xlabel("a label much too long for a figure four inches wide, so it is cut off")
    # (the axis with its label counts once as its ticks, and the label once as itself)
    long = "a label much too long for a figure four inches wide, so it is cut off"
    assert clipped_texts(fig) == ["x ticks of fits", long, "runs off the right edge"]
    plt.close(fig)


def test_the_tolerance_picture_keeps_a_long_verdict_inside():
    design = fabkit.load_template(TEMPLATES / "chaotic_chain.toml")
    result = analyse_tolerance(design, tolerance_spec(design, samples=30))
    assert len(result.verdict) > 300  # the verdict runs over several lines
    fig = tolerance_figure(result, title=design.name)
    assert clipped_texts(fig) == []
    assert fig._suptitle.get_text().count("\n") >= 2
    _mpl().close(fig)


def test_the_map_axes_say_input_and_output_not_inches():
    from fabkit.mapplots import map_figure

    design = fabkit.load_template(TEMPLATES / "super_stable.toml")
    fig = map_figure(fabkit.module_map(design.network, d_in="d1", d_out="d2"))
    ax = fig.axes[0]
    assert ax.get_xlabel() == "$d_k$, input of module k (design units)"
    assert ax.get_ylabel() == "$d_{k+1} = f(d_k)$, its output (design units)"
    assert clipped_texts(fig) == []
    _mpl().close(fig)
