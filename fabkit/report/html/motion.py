"""The motion of a design as a scrubbable drawing (frames of projected node positions, its bars
coloured by laser layer, by crease assignment or grey for a print, the ports dashed), and the
sections that show it and the map."""

from __future__ import annotations

import json

import numpy as np

from .common import esc, exporter_report, img, LAYER_COLOURS


#: Most frames of a motion kept in a page (evenly spaced along the trace).
MAX_FRAMES = 61


MOTION_TAG = "fabkit-motion"


_ASSIGNMENT_COLOURS = {"M": "#e00000", "V": "#0040ff", "B": "#000000", "F": "#c0a000",
                       "C": "#00a000", "U": "#808080", "J": "#808080"}


def _project(x: np.ndarray) -> np.ndarray:
    """(..., N, d) → (..., N, 2) drawing coordinates, y down; 3D seen from above and the side."""
    if x.shape[-1] == 2:
        return np.stack([x[..., 0], -x[..., 1]], axis=-1)
    az, el = np.radians(-35.0), np.radians(35.0)
    rx = x[..., 0] * np.cos(az) - x[..., 1] * np.sin(az)
    ry = x[..., 0] * np.sin(az) + x[..., 1] * np.cos(az)
    return np.stack([rx, -(ry * np.sin(el) + x[..., 2] * np.cos(el))], axis=-1)


def _edge_colours(design, formats: dict) -> tuple[list, list]:
    """Colour of every edge and the legend (label, colour)."""
    net = design.network
    colours = ["#607d8b"] * net.n_edges
    legend = []
    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    bars = exporter_report(formats, "dxf").get("bars")
    assignment = (fab.get("origami") or {}).get("assignment") \
        if isinstance(fab.get("origami"), dict) else None
    if isinstance(assignment, list) and len(assignment) == net.n_edges:
        colours = [_ASSIGNMENT_COLOURS.get(a, "#808080") for a in assignment]
        names = {"M": "mountain", "V": "valley", "B": "boundary", "F": "flat", "C": "cut"}
        legend = [(names.get(a, a), _ASSIGNMENT_COLOURS.get(a, "#808080"))
                  for a in sorted(set(assignment))]
    elif isinstance(bars, list) and bars:
        lookup = {tuple(sorted(map(int, e))): k for k, e in enumerate(net.edges.tolist())}
        layers = set()
        for bar in bars:
            k = lookup.get(tuple(sorted(int(j) for j in bar["joints"][:2])))
            if k is not None and bar["layer"] is not None:
                colours[k] = LAYER_COLOURS[int(bar["layer"]) % len(LAYER_COLOURS)]
                layers.add(int(bar["layer"]))
        legend = [(f"laser layer {k}", LAYER_COLOURS[k % len(LAYER_COLOURS)])
                  for k in sorted(layers)]
    return colours, legend


#: The fill of the panels each process's plan names (``panels``: node cycles), in the order
#: they are looked for.
PANEL_FILLS = (("origami", "#fff3c4"), ("print", "#cfd8dc"))


def _faces(plans: dict) -> tuple[list, str]:
    """Filled polygons of the drawing, as the export's plans name them (``plan.panels``): the
    panels of an origami sheet, the rigid plates of a hinged print. None made: the bars alone
    show the motion (a report builds no model of its own)."""
    for process, fill in PANEL_FILLS:
        panels = getattr(plans.get(process), "panels", None)
        if panels:
            return [list(map(int, f)) for f in panels], fill
    return [], ""


def motion_frames(design, trajectory, formats: dict | None = None,
                  plans: dict | None = None) -> dict | None:
    """The motion as drawing data: frames of projected node positions, edges, ports, colours.

    Parameters
    ----------
    design : Design
    trajectory : Trajectory or None
        The design's traced motion (the pipeline's Motion stage); None: no drawing (a report
        never traces).
    formats : dict of str to FormatResult, optional
        The export's formats (a laser kit's layers colour the bars).
    plans : dict of str to plan, optional
        The plan of each process the export made files by (the Artefacts stage's ``plans``):
        an origami plan's panels and a hinged print's plates are drawn filled.

    Returns
    -------
    dict or None
        ``frames`` (F, N, 2), ``values`` (F,), ``edges``, ``ports`` ([name, i, j]),
        ``colours``, ``legend``, ``faces`` (node cycles drawn filled: a print's plates, an
        origami sheet's panels), ``fill``, ``viewbox``, ``drive``.
    """
    if trajectory is None:
        return None
    pos = np.asarray(trajectory.positions, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[0] < 2:
        return None
    keep = np.unique(np.linspace(0, pos.shape[0] - 1, min(MAX_FRAMES, pos.shape[0]))
                     .round().astype(int))
    xy = _project(pos[keep])
    lo, hi = xy.reshape(-1, 2).min(0), xy.reshape(-1, 2).max(0)
    span = float(max(hi - lo))
    scale = 1000.0 / span if span > 0 else 1.0
    xy = (xy - lo) * scale
    pad = 30.0
    net = design.network
    drive = design.motion.drive or "d1"
    try:
        a, b = net.port(drive)
        values = np.linalg.norm(pos[keep, a] - pos[keep, b], axis=-1)
    except Exception:  # a drive given as a node pair that is not a port: show the frame number
        values = np.arange(len(keep), dtype=float)
    colours, legend = _edge_colours(design, formats or {})
    faces, fill = _faces(plans or {})
    ports = [[p, int(i), int(j)] for p, (i, j) in sorted(net.ports.items())]
    w, h = (hi - lo) * scale
    return {"frames": np.round(xy, 2).tolist(), "values": values.tolist(),
            "edges": net.edges.tolist(), "ports": ports, "colours": colours, "legend": legend,
            "faces": faces, "fill": fill,
            "viewbox": [-pad, -pad, float(w) + 2 * pad, float(h) + 2 * pad], "drive": drive}


def motion_svg(data: dict, ident: str, *, autoplay=False, width=1.5) -> str:
    """An empty ``<svg>`` the page's player draws the motion ``data`` into, with the data
    beside it as JSON (``autoplay``: it loops on its own, as on a card)."""
    vb = " ".join(f"{v:.2f}" for v in data["viewbox"])
    extra = " data-autoplay" if autoplay else ""
    return (f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{vb}" data-motion="{ident}" '
            f'data-width="{width}" preserveAspectRatio="xMidYMid meet"{extra}></svg>'
            f'<script type="application/json" id="{ident}">'
            + json.dumps(data, separators=(",", ":")).replace("</", "<\\/") + "</script>")


def report_frames(report) -> dict | None:
    """The drawing data of a report's traced motion (None when it was not traced)."""
    motion = report.motion
    traj = motion.trajectory if motion is not None and motion.traced else None
    return motion_frames(report.design, traj, report.formats,
                         getattr(report.artefacts, "plans", None))


def motion_section(report, data: dict | None) -> str:
    """The Motion section: the traced motion's line and its drawing with a slider and a play
    button (``data``: :func:`motion_frames`), or the line alone; ``""`` when there is neither."""
    motion = report.motion
    line = motion.line() if motion is not None and motion.status.value != "no target" else ""
    if data is None:
        return f"<section id=motion><h2>Motion</h2><p>{esc(line)}</p></section>" if line else ""
    legend = "".join(f'<span><i style="background:{c}"></i>{esc(t)}</span>'
                     for t, c in data["legend"])
    return ("<section id=motion class=motion><h2>Motion</h2>"
            f"<p>{esc(line)}</p>"
            f'<div class="controls"><button data-play="{MOTION_TAG}">play</button>'
            f'<input type="range" min="0" max="{len(data["frames"]) - 1}" value="0" step="1" '
            f'id="frame" data-for="{MOTION_TAG}" aria-label="motion frame">'
            f'<output data-value-for="{MOTION_TAG}"></output></div>'
            + motion_svg(data, MOTION_TAG, width=2.5)
            + f'<p class="legend">{legend}<span><i style="background:#888"></i>ports (dashed)'
              "</span></p></section>")


def map_section(files: dict) -> str:
    """The map and cobweb pictures of the design, when the export drew them."""
    pics = [n for n in ("preview_motion.png", "preview_map.png") if n in files]
    if not pics:
        return ""
    return ("<section id=map><h2>Map and cobweb</h2>"
            + "".join(img(n, files[n], n) for n in pics) + "</section>")
