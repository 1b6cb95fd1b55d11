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
    assert ax.get_xlabel() == "dₖ, input of module k (design units)"
    assert ax.get_ylabel() == "dₖ₊₁ = f(dₖ), its output (design units)"
    assert clipped_texts(fig) == []
    _mpl().close(fig)


def test_log_axes_are_labelled_as_matplotlib_labels_them_in_plain_text():
    """The log tick labels of the export's figures say what matplotlib's say (10⁻³, 6×10⁻¹⁶),
    at the same ticks, without math text."""
    from matplotlib.ticker import LogFormatterSciNotation

    from fabkit.viz import plain_log_ticks

    plt = _mpl()
    fig, ax = plt.subplots()
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
    _mpl().close(fig)
