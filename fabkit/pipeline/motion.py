"""The design's motion for export: traced once, every way it fails typed; its pictures and facts."""

from __future__ import annotations


from ..errors import FabkitError
from ..motion import trace_motion
from ..status import Status
from ..plots.viz import figure_kit, set_margins
from ..model.network import chain_port_number, is_chain_port


# --- the motion ------------------------------------------------------------------------------

def traced_motion(design, *, allow_singular_start=False, **overrides):
    """Trace a design's motion for export; every way it can fail is one :class:`MotionError`.

    The Motion stage (:func:`fabkit.motion.trace_motion`) as a function that raises: which
    template key the error names is decided from the network's structure and the trace's typed
    status, never from a message.

    Parameters
    ----------
    design : Design
    allow_singular_start : bool
        Raise :class:`~fabkit.errors.SingularStartError` for a singular start, so that the caller
        may let an exporter that chooses the branch (an origami crease assignment) decide.
        Otherwise a singular start is a plain failure of the same class.
    **overrides
        Passed to :meth:`Design.trace` (``method``, ``to``, method options).

    Returns
    -------
    Trajectory or None
        None when the template gives no target (``motion.to``): a geometry-only design.

    Raises
    ------
    MotionError
        The motion is impossible, or its trace does not reach the target.
    """
    motion = trace_motion(design, judge=False, **overrides)
    if motion.status is Status.NO_TARGET:
        return None
    return motion.require()


def _chain_port_names(net) -> list[str]:
    ports = [p for p in net.ports if is_chain_port(p)]
    return sorted(ports, key=chain_port_number)


def map_figure(traj, design):
    """The map picture of a design, or None when it has fewer than two ports d1, d2, ...

    A single module: its whole map d2 = f(d1) (:func:`fabkit.plots.mapplots.map_figure`, fixed
    points and 2-cycles marked) with the traced stretch in red. A chain: the cobweb of the
    distances d_1, d_2, ... at the start and at the end of the motion, over the identity line.
    """
    import numpy as np

    ports = _chain_port_names(traj.network)
    if len(ports) < 2:
        return None
    dist = np.stack([traj.distance(p) for p in ports], axis=1)  # (S, K)
    if len(ports) == 2:
        try:
            from ..plots.mapplots import map_figure as module_map_figure
            from ..maps import module_map

            fig = module_map_figure(module_map(design.network), title=f"{design.name}: map")
        except (FabkitError, ImportError):
            fig = None
        if fig is not None:
            ax = fig.axes[0]
            ax.plot(dist[:, 0], dist[:, 1], "-", color="C3", lw=3, alpha=0.7,
                    label="traced motion")
            ax.legend(fontsize=7, loc="best")
            return fig
    fig, ax = figure_kit.subplots(figsize=(5.6, 5.4))
    if len(ports) == 2:
        ax.plot(dist[:, 0], dist[:, 1], "-", color="C3", lw=2, label="d2 = f(d1), traced")
    else:
        for row, label, colour in ((0, "start", "C0"), (-1, "end", "C3")):
            d = dist[row]
            # cobweb: (d1, d1) → (d1, d2) → (d2, d2) → (d2, d3) → ...
            xs = np.repeat(d[:-1], 2)
            ys = np.empty_like(xs)
            ys[0::2] = np.concatenate([[d[0]], d[1:-1]])
            ys[1::2] = d[1:]
            ax.plot(xs, ys, "-", color=colour, lw=1.2, label=f"cobweb at the {label}")
            ax.plot(d[:-1], d[1:], "o", ms=3.5, color=colour)
    lo, hi = float(dist.min()), float(dist.max())
    pad = 0.05 * (hi - lo or 1.0)
    ax.plot([lo - pad, hi + pad], [lo - pad, hi + pad], ":", color="0.5", lw=1, label="identity")
    ax.set_xlabel("dₖ")  # plain text: no math text parser
    ax.set_ylabel("dₖ₊₁")
    ax.set_title(f"{design.name}: map along the chain")
    ax.legend(loc="best", fontsize=8)
    ax.set_aspect("equal", adjustable="datalim")
    set_margins(fig, left=0.8, right=0.25, bottom=0.6, top=0.45)
    return fig


def motion_report(traj) -> dict:
    """The motion facts of report.json (drive, start, target, method, status, distances)."""
    names = list(traj.network.ports)
    return {
        "drive": traj.network.ports and next((k for k, v in traj.network.ports.items()
                                              if tuple(v) == tuple(traj.drive_port)),
                                             str(traj.drive_port)),
        "start": float(traj.drive[0]),
        "to": float(traj.target),
        "method": traj.method,
        "status": str(traj.status),
        "message": traj.message,
        "steps": traj.n_steps,
        "max_edge_error": traj.max_edge_error,
        "start_distances": {n: float(traj.distance(n)[0]) for n in names},
        "final_distances": {n: float(traj.distance(n)[-1]) for n in names},
    }
