"""Pictures of motion over time: an animated GIF of a trajectory and "sequence" plots that show
which module of a chain collapses when (the soliton, the AND gate).

Everything returns bytes or matplotlib figures; writing files is the caller's job.
"""

from __future__ import annotations

import io

import numpy as np

from ..errors import FabkitError
from .viz import figure_kit

__all__ = ["motion_gif", "collapse_profile", "collapse_order", "sequence_figure",
           "junction_figure"]


#: Smallest padding of the drawing's limits, so that a network that does not move in one
#: direction still gets a non-degenerate axis.
AXIS_PAD = 1e-9
#: Floor of the displacement drawn on a log scale (an exact zero has no logarithm).
LOG_FLOOR = 1e-17


def _frame_indices(traj, frames: int) -> np.ndarray:
    """Configurations evenly spaced in arclength (so slow and fast parts get fair time)."""
    s = traj.arclength
    if s[-1] <= 0:
        return np.zeros(1, dtype=int)
    wanted = np.linspace(0.0, s[-1], max(int(frames), 2))
    idx = np.searchsorted(s, wanted).clip(0, traj.n_steps - 1)
    return np.unique(idx)


def motion_gif(traj, *, frames: int = 40, fps: float = 12.0, size=(6.0, 4.0), dpi: int = 80,
               title: str | None = None) -> bytes:
    """Animated GIF of a traced motion (2D, or 3D projected on x-y), looping.

    Parameters
    ----------
    traj : Trajectory
    frames : int
        Number of frames, evenly spaced in arclength (the last configuration is always shown).
    fps : float
        Frames per second.
    size : (float, float)
        Figure size in inches.
    dpi : int
    title : str, optional

    Returns
    -------
    bytes
        GIF file contents.

    Raises
    ------
    FabkitError
        ``frames`` below 2 or ``fps`` not positive.

    Examples
    --------
    >>> import fabkit
    >>> net = fabkit.Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]],
    ...                      ports={"d1": (0, 1), "d2": (2, 3)})
    >>> motion_gif(fabkit.trace(net, "d1", to=3.0), frames=4)[:6]
    b'GIF89a'
    """
    if int(frames) < 2:
        raise FabkitError(f"`frames` must be at least 2, got {frames}")
    if not fps > 0:
        raise FabkitError(f"`fps` must be positive, got {fps}")
    from matplotlib.collections import LineCollection
    from PIL import Image

    idx = _frame_indices(traj, frames)
    if idx[-1] != traj.n_steps - 1:
        idx = np.append(idx, traj.n_steps - 1)
    pos = traj.positions[:, :, :2]
    lo, hi = pos.reshape(-1, 2).min(axis=0), pos.reshape(-1, 2).max(axis=0)
    pad = 0.05 * float(max(hi - lo)) + AXIS_PAD
    edges = traj.network.edges
    fig, ax = figure_kit.subplots(figsize=size)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_axis_off()
    lines = LineCollection(pos[0][edges], colors="C0", linewidths=1.2)
    ax.add_collection(lines)
    a, b = traj.drive_port
    (drive_line,) = ax.plot(*pos[0][[a, b]].T, "--", color="C3", lw=1.0)
    label = ax.set_title("")
    images = []
    for i in idx:
        lines.set_segments(pos[i][edges])
        drive_line.set_data(*pos[i][[a, b]].T)
        label.set_text(f"{title + ': ' if title else ''}drive = {traj.drive[i]:.6g}")
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[:, :, :3].copy()).convert("P", palette=Image.ADAPTIVE))
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:],
                   duration=int(round(1000.0 / fps)), loop=0)
    return buf.getvalue()


def collapse_profile(distances, start: float, end: float) -> np.ndarray:
    """How far each distance has gone from ``start`` towards ``end``: 0 at start, 1 at end.

    Parameters
    ----------
    distances : array_like, shape (K, S)
        K chain distances (d1 … dK) at S steps.
    start, end : float
        The two crystalline values (e.g. D1* and D2*).

    Returns
    -------
    numpy.ndarray, shape (K, S)
        ``(d - start) / (end - start)`` clipped to [0, 1].

    Raises
    ------
    FabkitError
        ``start == end`` or distances not 2-D.

    Examples
    --------
    >>> collapse_profile([[2.0, 1.5, 1.0]], 2.0, 1.0).tolist()
    [[0.0, 0.5, 1.0]]
    """
    d = np.asarray(distances, dtype=np.float64)
    if d.ndim != 2:
        raise FabkitError(f"`distances` must have shape (K, S), got {d.shape}")
    if start == end:
        raise FabkitError("`start` and `end` must differ")
    return np.clip((d - start) / (end - start), 0.0, 1.0) + 0.0  # + 0.0 turns -0.0 into 0.0


def collapse_order(profile, threshold: float = 0.5) -> np.ndarray:
    """Step at which each module first passes ``threshold`` of its collapse (-1: never).

    Parameters
    ----------
    profile : array_like, shape (K, S)
        From :func:`collapse_profile`.
    threshold : float

    Returns
    -------
    numpy.ndarray of int, shape (K,)

    Examples
    --------
    >>> collapse_order([[0.1, 0.6, 1.0], [0.0, 0.2, 0.7], [0.0, 0.0, 0.1]]).tolist()
    [1, 2, -1]
    """
    p = np.asarray(profile) > threshold
    return np.where(p.any(axis=1), p.argmax(axis=1), -1)


def sequence_figure(profile, x=None, *, xlabel: str = "step", title: str = "collapse sequence",
                    module_labels=None):
    """Heat map of the collapse of each module (rows) against the motion (columns).

    Parameters
    ----------
    profile : array_like, shape (K, S)
        From :func:`collapse_profile`.
    x : array_like, shape (S,), optional
        Abscissa of the steps (drive value, ``-log10(d1 - D2*)``, …); step index by default.
    xlabel, title : str
    module_labels : sequence of str, optional
        One per row (``d1 … dK`` by default).

    Returns
    -------
    matplotlib.figure.Figure
        Left: the heat map with the moment each module passes half of its collapse marked;
        right: that moment against the module index.
    """

    p = np.asarray(profile, dtype=np.float64)
    k, s = p.shape
    xs = np.arange(s, dtype=np.float64) if x is None else np.asarray(x, dtype=np.float64)
    if xs.shape != (s,):
        raise FabkitError(f"`x` must have {s} entries, got {xs.shape}")
    labels = list(module_labels) if module_labels is not None else [f"d{i + 1}" for i in range(k)]
    when = collapse_order(p)
    fig, (ax, ax2) = figure_kit.subplots(1, 2, figsize=(11, 4.5),
                                         gridspec_kw={"width_ratios": [3, 1]})
    order = np.argsort(xs)
    mesh = ax.pcolormesh(xs[order], np.arange(k), p[:, order], shading="nearest", cmap="Blues",
                         vmin=0, vmax=1)
    done = when >= 0
    ax.plot(xs[when[done]], np.flatnonzero(done), "o", color="C3", ms=3, label="half collapsed")
    ax.set_yticks(np.arange(k)[:: max(1, k // 12)])
    ax.set_yticklabels(labels[:: max(1, k // 12)])
    ax.set_xlabel(xlabel)
    ax.set_ylabel("distance along the chain")
    ax.set_title(title)
    ax.legend(loc="lower right", fontsize=8)
    fig.colorbar(mesh, ax=ax, label="collapsed fraction of the module")
    ax2.plot(np.flatnonzero(done), xs[when[done]], "o-", color="C3", ms=3)
    ax2.set_xlabel("module")
    ax2.set_ylabel(f"{xlabel} at half collapse")
    ax2.set_title("order of collapse")
    fig.tight_layout()
    return fig


def junction_figure(fraction, displacement, *, threshold: float = 1e-12,
                    title: str = "AND gate: junction displacement"):
    """Junction displacement (log scale) against the collapsed fraction of one branch.

    Parameters
    ----------
    fraction : array_like, shape (S,)
        Collapsed fraction of the branch (0 … 1).
    displacement : array_like, shape (S,)
        Junction displacement (design units); zeros are drawn at 1e-17.
    threshold : float
        Drawn as a horizontal line.

    Returns
    -------
    matplotlib.figure.Figure
    """

    f = np.asarray(fraction, dtype=np.float64)
    disp = np.maximum(np.abs(np.asarray(displacement, dtype=np.float64)), LOG_FLOOR)
    fig, ax = figure_kit.subplots(figsize=(6.5, 4.2))
    ax.semilogy(f, disp, ".-", color="C0", ms=3)
    ax.axhline(threshold, color="C3", lw=0.8, ls="--", label=f"{threshold:g}")
    ax.set_xlabel("collapsed fraction of the branch")
    ax.set_ylabel("junction displacement")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    return fig
