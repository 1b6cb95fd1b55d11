"""Self-contained HTML reports: ``report.html`` per design and ``index.html`` for a batch.

A design's page is rendered from the typed results of its export
(:class:`fabkit.pipeline.stages.DesignReport`: the verdict, the traced motion, each format's result
and checks, the tolerance analysis, the files in memory), never from a report read back; its
traced motion becomes a scrubbable drawing: drag the slider (or
press play) and watch the network move, its bars coloured by laser layer, by crease assignment
(mountain red, valley blue, boundary black) or grey for a print, with the ports drawn dashed. The
page also shows the map and cobweb, the laser layers over the motion, the crease pattern, the
printed part and its bed layout, the bill of materials, the tolerance analysis and every check's
verdict. Pictures are inlined (data URIs, inline SVG): the page needs no network and no other file.

``index.html`` lists every design of a batch with its own moving picture, its verdict and a link to
its page, from the :class:`fabkit.pipeline.stages.IndexCard` each export hands back (designs
exported into the folder by earlier runs are linked by name).
"""

from __future__ import annotations

import base64
import html
import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FabkitError
from ..export import write_atomic
from .text import jsonable, MADE_FOR

__all__ = ["design_html", "index_html", "index_card", "write_index", "motion_frames",
           "keep_chart_svg", "describe_file", "not_exported", "image_size", "PROCESSES",
           "FILE_ROLES", "LEVEL_CLASS", "IndexCard"]

#: Most frames of a motion kept in a page (evenly spaced along the trace).
MAX_FRAMES = 61
#: CSS pixels per mm (96 per inch): an SVG drawn in mm shows at its true size.
PX_PER_MM = 96 / 25.4
#: Tables of a bill of materials longer than this are folded (the screws and sheets stay open,
#: the 144 bars of a long chain do not bury what follows).
FOLD_ROWS = 12

_MOTION_TAG = "fabkit-motion"
_LAYER_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
                  "#17becf", "#bcbd22", "#7f7f7f"]
_ASSIGNMENT_COLOURS = {"M": "#e00000", "V": "#0040ff", "B": "#000000", "F": "#c0a000",
                       "C": "#00a000", "U": "#808080", "J": "#808080"}

_CSS = """
body{font:15px/1.45 system-ui,-apple-system,"Segoe UI",sans-serif;margin:0;color:#222;
background:#fafafa}
header{background:#263238;color:#fff;padding:14px 24px}header h1{margin:0;font-size:22px}
header p{margin:4px 0 0;color:#cfd8dc}main{padding:12px 24px;max-width:1200px}
h1,h2,h3,p,td,th,li,figcaption,summary{overflow-wrap:anywhere}
section{background:#fff;border:1px solid #ddd;border-radius:6px;padding:12px 16px;margin:12px 0}
h2{font-size:18px;margin:4px 0 10px}table{border-collapse:collapse;margin:6px 0;font-size:13px}
td,th{border:1px solid #ddd;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#f0f0f0}.ok{color:#1b5e20;font-weight:600}.bad{color:#b71c1c;font-weight:600}
.warn{color:#e65100}.note{color:#5d4037;font-weight:600}.lead{border-left:5px solid #263238}
.strip i{display:inline-block;width:.7em;height:1.1em;margin-right:1px;border:1px solid;
vertical-align:middle}
.lead p{margin:4px 0}.verdict{border-left:5px solid #1b5e20}.verdict.FLAG,.verdict.FAIL{
border-left-color:#b71c1c}.verdict.by-design{border-left-color:#8d6e63}
.nowrap{white-space:nowrap}
.scroll{overflow-x:auto;max-width:100%}.pic{margin:8px 0}.pic img{max-width:none;display:block;
border:1px solid #eee}figcaption{font-size:13px;color:#555}
details{margin:8px 0}summary{cursor:pointer;font-weight:600}
.motion svg{width:100%;max-height:520px;background:#fff;border:1px solid #eee}
.controls{display:flex;gap:12px;align-items:center;margin:6px 0}
.controls input[type=range]{flex:1;min-width:0}.legend span{display:inline-block;margin-right:12px}
.legend i{display:inline-block;width:18px;height:4px;vertical-align:middle;margin-right:4px}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(min(330px,100%),1fr));gap:12px}
.card{background:#fff;border:1px solid #ddd;border-radius:6px;padding:10px;min-width:0}
.card svg{width:100%;height:220px;background:#fff}.card h3{margin:0 0 4px;font-size:16px}
.inline-svg svg{max-width:none;height:auto}
"""

# One player for a page: every <svg data-motion="ID"> is bound to the frames in the JSON block
# with that id; a range input with data-for="ID" scrubs it, a button with data-play="ID" plays.
# Thumbnails (data-autoplay) loop on their own.
_JS = """
(function(){
  function bind(svg){
    var data = JSON.parse(document.getElementById(svg.getAttribute('data-motion')).textContent);
    var ns = 'http://www.w3.org/2000/svg', lines = [], ports = [];
    var w = svg.getAttribute('data-width') || 1.5, polys = [];
    (data.faces || []).forEach(function(){
      var g = document.createElementNS(ns, 'polygon');
      g.setAttribute('fill', data.fill); g.setAttribute('fill-opacity', 0.7);
      g.setAttribute('stroke', 'none'); svg.appendChild(g); polys.push(g);
    });
    data.edges.forEach(function(e, k){
      var l = document.createElementNS(ns, 'line');
      l.setAttribute('stroke', data.colours[k]); l.setAttribute('stroke-width', w);
      l.setAttribute('stroke-linecap', 'round');
      l.setAttribute('vector-effect', 'non-scaling-stroke');
      svg.appendChild(l); lines.push(l);
    });
    data.ports.forEach(function(p){
      var l = document.createElementNS(ns, 'line');
      l.setAttribute('stroke', '#888'); l.setAttribute('stroke-width', 1);
      l.setAttribute('stroke-dasharray', '4 3');
      l.setAttribute('vector-effect', 'non-scaling-stroke');
      svg.insertBefore(l, svg.firstChild); ports.push(l);
    });
    function draw(f){
      var x = data.frames[f];
      (data.faces || []).forEach(function(face, k){
        polys[k].setAttribute('points', face.map(function(v){
          return x[v][0] + ',' + x[v][1]; }).join(' '));
      });
      data.edges.forEach(function(e, k){
        var l = lines[k];
        l.setAttribute('x1', x[e[0]][0]); l.setAttribute('y1', x[e[0]][1]);
        l.setAttribute('x2', x[e[1]][0]); l.setAttribute('y2', x[e[1]][1]);
      });
      data.ports.forEach(function(p, k){
        var l = ports[k];
        l.setAttribute('x1', x[p[1]][0]); l.setAttribute('y1', x[p[1]][1]);
        l.setAttribute('x2', x[p[2]][0]); l.setAttribute('y2', x[p[2]][1]);
      });
      svg.setAttribute('data-frame', f);
      var out = document.querySelector(
        '[data-value-for="' + svg.getAttribute('data-motion') + '"]');
      if (out) out.textContent = data.drive + ' = ' + data.values[f].toPrecision(6);
    }
    var id = svg.getAttribute('data-motion');
    var slider = document.querySelector('input[data-for="' + id + '"]');
    var button = document.querySelector('button[data-play="' + id + '"]');
    var timer = null, f = 0;
    function step(){ f = (f + 1) % data.frames.length; if (slider) slider.value = f; draw(f); }
    if (slider){ slider.max = data.frames.length - 1;
      slider.addEventListener('input', function(){ f = +slider.value; draw(f); }); }
    if (button) button.addEventListener('click', function(){
      if (timer){ clearInterval(timer); timer = null; button.textContent = 'play'; }
      else { timer = setInterval(step, 80); button.textContent = 'pause'; } });
    if (svg.hasAttribute('data-autoplay')) timer = setInterval(step, 90);
    draw(0);
  }
  document.querySelectorAll('svg[data-motion]').forEach(bind);
})();
"""


def _esc(x) -> str:
    return html.escape(str(x), quote=True)


def _fmt(v) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, tuple)):
        return ", ".join(_fmt(x) for x in v)
    return str(v)


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
    bars = _exporter(formats, "dxf").get("bars")
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
                colours[k] = _LAYER_COLOURS[int(bar["layer"]) % len(_LAYER_COLOURS)]
                layers.add(int(bar["layer"]))
        legend = [(f"laser layer {k}", _LAYER_COLOURS[k % len(_LAYER_COLOURS)])
                  for k in sorted(layers)]
    return colours, legend


def _faces(design) -> tuple[list, str]:
    """Filled polygons of the drawing: the rigid plates of a print, the panels of a sheet."""
    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    try:
        if "origami" in fab:
            from ..fab.creases import origami_model

            model = origami_model(design)
            n = design.network.n_nodes
            return [list(map(int, f)) for f in model.faces if max(f) < n], "#fff3c4"
        if "print" in fab:
            from ..fab.hinges import rigid_triangles

            given = (fab.get("print") or {}).get("rigid_triangles")
            return rigid_triangles(design.network, given).tolist(), "#cfd8dc"
    except FabkitError:  # no faces to draw: the bars alone still show the motion
        pass
    return [], ""


def motion_frames(design, trajectory, formats: dict | None = None) -> dict | None:
    """The motion as drawing data: frames of projected node positions, edges, ports, colours.

    Parameters
    ----------
    design : Design
    trajectory : Trajectory or None
        The design's traced motion (the pipeline's Motion stage); None: no drawing (a report
        never traces).
    formats : dict of str to FormatResult, optional
        The export's formats (a laser kit's layers colour the bars).

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
    faces, fill = _faces(design)
    ports = [[p, int(i), int(j)] for p, (i, j) in sorted(net.ports.items())]
    w, h = (hi - lo) * scale
    return {"frames": np.round(xy, 2).tolist(), "values": values.tolist(),
            "edges": net.edges.tolist(), "ports": ports, "colours": colours, "legend": legend,
            "faces": faces, "fill": fill,
            "viewbox": [-pad, -pad, float(w) + 2 * pad, float(h) + 2 * pad], "drive": drive}


def _motion_svg(data: dict, ident: str, *, autoplay=False, width=1.5) -> str:
    vb = " ".join(f"{v:.2f}" for v in data["viewbox"])
    extra = " data-autoplay" if autoplay else ""
    return (f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{vb}" data-motion="{ident}" '
            f'data-width="{width}" preserveAspectRatio="xMidYMid meet"{extra}></svg>'
            f'<script type="application/json" id="{ident}">'
            + json.dumps(data, separators=(",", ":")).replace("</", "<\\/") + "</script>")


def _data_uri(name: str, data: bytes) -> str:
    mime = {"png": "image/png", "svg": "image/svg+xml"}[name.rsplit(".", 1)[-1].lower()]
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


def image_size(name: str, data: bytes) -> tuple[int, int] | None:
    """Width and height (CSS pixels) at which a picture shows its text at its own size: a PNG's
    pixels, an SVG's ``width``/``height`` in mm at 96 px per inch; None when not known."""
    if name.lower().endswith(".png") and data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    if name.lower().endswith(".svg"):
        head = data[:2000].decode("utf-8", "replace")
        m = re.search(r'<svg[^>]*\bwidth="([\d.]+)mm"[^>]*\bheight="([\d.]+)mm"', head)
        if m:
            return (round(float(m.group(1)) * PX_PER_MM), round(float(m.group(2)) * PX_PER_MM))
    return None


def _img(name: str, data: bytes, alt: str, caption: str | None = None) -> str:
    """A picture at its own size (never scaled down: its box scrolls sideways instead)."""
    size = image_size(name, data)
    dims = f' width="{size[0]}" height="{size[1]}"' if size else ""
    return (f'<figure class="pic"><div class="scroll"><img src="{_data_uri(name, data)}" '
            f'alt="{_esc(alt)}"{dims}></div><figcaption>{_esc(caption or name)}</figcaption>'
            "</figure>")


def _blocks_html(blocks, fold_rows: int | None = None) -> str:
    """Blocks of text and tables (:func:`fabkit.export.dxf.bom_blocks`) as HTML; a table longer
    than ``fold_rows`` rows is folded under its heading (``<details>``)."""
    out, heading = [], ""
    for block in blocks:
        kind = block[0]
        if kind == "table":
            _, header, rows = block
            body = ("<tr>" + "".join(f"<th>{_esc(c)}</th>" for c in header) + "</tr>"
                    + "".join("<tr>" + "".join(f"<td>{_esc(c)}</td>" for c in row) + "</tr>"
                              for row in rows))
            table = f'<div class="scroll"><table>{body}</table></div>'
            if fold_rows is not None and len(rows) > fold_rows:
                table = (f"<details><summary>{_esc(heading or 'table')}: {len(rows)} rows"
                         f"</summary>{table}</details>")
            out.append(table)
        elif kind in ("title", "heading"):
            heading = block[1]
            level = 3 if kind == "title" else 4
            out.append(f"<h{level}>{_esc(block[1])}</h{level}>")
        elif kind == "strong":
            out.append(f"<p><b>{_esc(block[1])}</b></p>")
        elif kind == "item":
            out.append(f"<ul><li>{_esc(block[1])}</li></ul>")
        else:
            out.append(f"<p>{_esc(block[1])}</p>")
    return "\n".join(out)


#: The CSS class a verdict level is shown with: green ok, brown "by design" (said in words, not
#: alarmed), red FLAG and FAIL.
LEVEL_CLASS = {"ok": "ok", "by design": "note", "FLAG": "bad", "FAIL": "bad"}

#: The processes a design can be made for and the formats of each (one table, with the
#: tolerance analysis: :data:`fabkit.tolerance.PROCESS_FORMATS`).
PROCESSES = {"print": ("stl",), "origami": ("svg", "fold", "cp"), "laser": ("dxf",)}


def _exporter(formats: dict, fmt: str) -> dict:
    """The exporter's report of a format that wrote files (``{}`` when it wrote none)."""
    f = formats.get(fmt)
    return f.report if f is not None and f.status.produced else {}


def _pass(ok) -> str:
    return '<span class="ok">pass</span>' if ok else '<span class="bad">FAIL</span>'


def _spread_strip(spread) -> str:
    """The chain's modules as a strip of cells, each as dark as far as its output went (of
    the drive's travel; a module past the state tolerance is outlined)."""
    cells = []
    for k, (r, moved) in enumerate(zip(spread.reach.tolist(), spread.moved.tolist()), 1):
        light = 92 - 62 * min(max(r, 0.0), 1.0)
        edge = "#263238" if moved else "#cfd8dc"
        cells.append(f'<i style="background:hsl(210,60%,{light:.0f}%);border-color:{edge}" '
                     f'title="module {k}: {r:.2g} of the drive\'s travel"></i>')
    return f'<span class="strip">{"".join(cells)}</span>'


def _level(level) -> str:
    """A verdict level as a word in its colour."""
    word = "flagged by design" if str(level) == "by design" else str(level)
    return f'<span class="{LEVEL_CLASS[str(level)]}">{_esc(word)}</span>'


def _verdict_section(report) -> str:
    v = report.verdict
    cls = {"ok": "ok", "by design": "by-design"}.get(str(v.level), str(v.level))
    rows = "".join(f"<li>{_level(f.level)} {_esc(f.about)}: {_esc(f.text)}</li>"
                   for f in v.findings[1:])
    return (f'<section id=verdict class="verdict {cls}"><h2>Verdict: {_level(v.level)}</h2>'
            f"<p>{_esc(v.text)}</p>" + (f"<ul>{rows}</ul>" if rows else "")
            + "</section>")


def _checks_section(report) -> str:
    rows = []
    for fmt, f in sorted(report.formats.items()):
        rows.append(f"<tr><th colspan=5>{_esc(fmt)}: {_esc(f.status)}"
                    + (f" – {_esc(f.detail)}" if f.detail else "") + "</th></tr>")
        for res in f.checks:
            if res.error:
                rows.append(f"<tr><td>{_esc(res.file)}</td><td>{_pass(False)}</td>"
                            f"<td colspan=3>{_esc(res.error)}</td></tr>")
            for c in res.checks:
                rows.append(f"<tr><td>{_esc(res.file)}: {_esc(c['name'])}</td>"
                            f"<td>{_pass(c['ok'])}</td><td>{_esc(_fmt(c.get('value')))}"
                            f"</td><td>{_esc(_fmt(c.get('limit')))}</td>"
                            f"<td>{_esc(c.get('detail', ''))}</td></tr>")
        for w in (f.report.get("warnings") or [] if f.status.produced else []):
            rows.append(f'<tr><td colspan=5 class="warn">warning: {_esc(w)}</td></tr>')
    tol = report.tolerance
    if tol is not None:
        level = "by design" if tol.flagged and tol.behaviour is not None and \
            tol.behaviour.chaos is not None else ("FLAG" if tol.flagged else "ok")
        rows.append(f"<tr><th colspan=5>tolerance</th></tr><tr><td>as built</td>"
                    f"<td>{_level(level)}</td><td colspan=3>{_esc(tol.verdict)}</td></tr>")
    motion = report.motion
    spread = getattr(motion, "spread", None) if motion is not None else None
    if motion is not None and (motion.ends is not None or spread is not None):
        rows.append("<tr><th colspan=5>motion</th></tr>")
    if motion is not None and motion.ends is not None:
        rows.append(f"<tr><td>designed ends</td>"
                    f"<td>{_pass(motion.ends.reached)}</td>"
                    f"<td colspan=3>{_esc(motion.ends.reason or motion.ends.basis)}</td></tr>")
    if spread is not None:
        word = '<span class="note">localised</span>' if spread.localised else \
            '<span class="ok">spread</span>'
        rows.append(f"<tr><td>modules moved</td><td>{word}"
                    f"</td><td>{int(spread.moved.sum())} of {spread.modules}</td>"
                    f"<td>{_fmt(spread.tolerance)}</td><td>{_spread_strip(spread)} "
                    f"{_esc(spread.sentence())}</td></tr>")
    for e in report.errors:
        rows.append(f'<tr><td colspan=5 class="bad">{_esc(e)}</td></tr>')
    if not rows:
        return ""
    return ("<section id=checks><h2>Checks</h2><div class=\"scroll\"><table><tr><th>check</th>"
            "<th>result</th><th>value</th><th>limit</th><th>detail</th></tr>" + "".join(rows)
            + "</table></div></section>")


def keep_chart_svg(tol: dict) -> str:
    """Inline SVG: fraction of builds that keep the design's behaviour against the error scale
    (log axis, 0.1× to 10× the process's errors), a curve per error source alone and a thick one
    for all together, the line ``min_reached`` and the margin where the thick curve meets it.

    Parameters
    ----------
    tol : dict
        The ``tolerance`` part of report.json (``keep_curves``, ``margin``, ``min_reached``).

    Returns
    -------
    str
        ``""`` when the report has no curves.
    """
    curves = tol.get("keep_curves") or {}
    scales = curves.get("scales") or []
    if not scales or "all" not in curves:
        return ""
    w, h, left, bottom, top, right = 560, 300, 52, 40, 14, 150
    pw, ph = w - left - right, h - top - bottom

    def x(sv):
        return left + pw * (np.log10(sv) + 1.0) / 2.0

    def y(frac):
        return top + ph * (1.0 - frac)

    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}" width="{w}" '
             f'height="{h}" role="img" aria-label="builds that keep the behaviour against the '
             'error scale" font-size="11" font-family="sans-serif">',
             f'<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="#fff" '
             'stroke="#999"/>']
    for sv in (0.1, 0.2, 0.5, 1, 2, 5, 10):
        parts.append(f'<line x1="{x(sv):.1f}" y1="{top}" x2="{x(sv):.1f}" y2="{top + ph}" '
                     f'stroke="#eee"/><text x="{x(sv):.1f}" y="{top + ph + 14}" '
                     f'text-anchor="middle">{sv:g}×</text>')
    for fr in (0, 0.25, 0.5, 0.75, 1):
        parts.append(f'<text x="{left - 6}" y="{y(fr) + 4:.1f}" text-anchor="end">'
                     f'{100 * fr:.0f}%</text>')
    parts.append(f'<text x="{left + pw / 2:.0f}" y="{h - 6}" text-anchor="middle">error scale '
                 "(× the process's own errors)</text>")
    need = float(tol.get("min_reached", 0.95))
    parts.append(f'<line x1="{left}" y1="{y(need):.1f}" x2="{left + pw}" y2="{y(need):.1f}" '
                 'stroke="#d62728" stroke-dasharray="5 3"/>')
    parts.append(f'<line x1="{x(1):.1f}" y1="{top}" x2="{x(1):.1f}" y2="{top + ph}" '
                 'stroke="#888" stroke-dasharray="2 3"/>')
    names = [n for n in curves if n not in ("scales", "all")] + ["all"]
    for k, name in enumerate(names):
        pts = " ".join(f"{x(sv):.1f},{y(fr):.1f}" for sv, fr in zip(scales, curves[name]))
        colour = "#000" if name == "all" else _LAYER_COLOURS[(k + 1) % len(_LAYER_COLOURS)]
        width = 3 if name == "all" else 1.5
        label = "all sources" if name == "all" else f"{name} alone"
        parts.append(f'<polyline fill="none" stroke="{colour}" stroke-width="{width}" '
                     f'points="{pts}"><title>{_esc(label)}</title></polyline>')
        ly = top + 14 + 16 * k
        parts.append(f'<line x1="{left + pw + 10}" y1="{ly - 4}" x2="{left + pw + 28}" '
                     f'y2="{ly - 4}" stroke="{colour}" stroke-width="{width}"/>'
                     f'<text x="{left + pw + 32}" y="{ly}">{_esc(label)}</text>')
    value = tol.get("margin")
    if value is not None:
        from ..tolerance.margin import margin_text

        label = _esc(margin_text(value, tol.get("margin_bound")))
        parts.append(f'<circle cx="{x(value):.1f}" cy="{y(need):.1f}" r="4" fill="#d62728">'
                     f'<title>margin {label}</title></circle>'
                     f'<text x="{x(value) + 6:.1f}" y="{y(need) + 14:.1f}" fill="#d62728">'
                     f'margin {label}</text>')
    parts.append("</svg>")
    return "".join(parts)


def _tolerance_section(report, files: dict) -> str:
    if report.tolerance is None:
        return ""
    tol = jsonable(report.tolerance.as_dict())
    chaos = report.tolerance.flagged and (tol["behaviour"] or {}).get("chaos") is not None
    cls = "note" if chaos else ("bad" if tol["flagged"] else "ok")
    parts = [f"<p>Judged as {_esc(MADE_FOR[tol['process']])}: {_esc(tol['model'])}; "
             f"{tol['samples']} simulated builds.</p>",
             f"<p class=\"{cls}\">{_esc(tol['verdict'])}</p>"]
    b = tol["behaviour"] or {}
    if b:
        how = "stated in the template" if b["intent"] != "auto" else \
            "inferred from its map and motion"
        bits = [f"{c['role']} crystal D* = {_fmt(c['value'])} ({c['kind']})"
                for c in b["crystals"]]
        if b["order"]:
            bits.append(f"the front runs {b['order']}")
        bits.append(f"judged at the end by its {b['end']} ({b['end_at']})")
        parts.append(f"<p>What the design is for ({how}): {_esc('; '.join(bits))}.</p>")
    rows = "".join(
        f"<tr><td>{_esc(c['criterion'])}</td><td>{100 * c['kept_fraction']:.1f}%</td>"
        f"<td>{_fmt(c['p95_mm']) if c['criterion'] != 'order' else '–'}</td>"
        f"<td>{_fmt(c['limit_mm']) if c['criterion'] != 'order' else '–'}</td>"
        f"<td>{c['missing']}</td></tr>" for c in tol["criteria"])
    if rows:
        parts.append("<div class=\"scroll\"><table><tr><th>criterion</th><th>builds that keep "
                     "it</th><th>95% of builds (mm)</th><th>allowed (mm)</th><th>no such state"
                     "</th></tr>" + rows + "</table></div>")
    chart = keep_chart_svg(tol)
    if chart:
        from ..tolerance.margin import margin_text

        alone = ", ".join(f"{_esc(n)} {_esc(margin_text(v['value'], v['bound']))}"
                          for n, v in tol["source_margins"].items())
        parts.append(f"<p>Margin {_esc(margin_text(tol['margin'], tol['margin_bound']))}"
                     ": every error of the process may grow by this factor and the verdict stays "
                     "the same" + (f"; each source alone: {alone}" if alone else "") + ".</p>"
                     f'<div class="inline-svg scroll">{chart}</div>')
    if tol["ports_judged"]:
        rows = "".join(f"<tr><td>{_esc(p['port'])}</td><td>{_fmt(p['nominal'])}</td>"
                       f"<td>{_fmt(p['mean'])}</td><td>{_fmt(p['p95_abs_error_mm'])}</td>"
                       f"<td>{_fmt(p['limit_mm'])}</td></tr>" for p in tol["ports"])
        if rows:
            parts.append("<div class=\"scroll\"><table><tr><th>port</th><th>designed</th>"
                         "<th>built (mean)</th><th>95% error (mm)</th><th>limit (mm)</th></tr>"
                         + rows + "</table></div>")
    hz = tol["horizon"]
    if hz:
        parts.append(f"<p>Lyapunov exponent λ = {_fmt(hz.get('lyapunov'))} per module "
                     f"({_esc(hz.get('source'))}): {_esc(hz.get('detail'))}.</p>")
    name = "preview_tolerance.png"
    if name in files:
        parts.append(_img(name, files[name], "tolerance"))
    return "<section id=tolerance><h2>Tolerance</h2>" + "".join(parts) + "</section>"


#: What each file of a design folder is, by name (first match).
FILE_ROLES = (
    (r"laser_guide\.pdf", "assembly guide: A4 pages to print and follow at the bench"),
    (r"laser_guide_page1\.png", "the assembly guide's first page (overview)"),
    (r".*coupon.*", "test coupon: cut it first to check kerf and fit"),
    (r"laser_sheet(\d+)\.dxf", "sheet {0} to cut (DXF, mm)"),
    (r"laser_sheet(\d+)\.svg", "sheet {0} to cut (SVG for laser programs, mm)"),
    (r"laser_bom\.md", "bill of materials (to read)"),
    (r"laser_bom\.json", "bill of materials (data)"),
    (r"laser_assembly\.png", "picture: the kit by layer, in rows"),
    (r"laser_layers_motion\.png", "picture: the motion test with the layers"),
    (r".*_cut\.svg", "cut-ready sheet: perforated creases and the outline (laser or vinyl cutter)"),
    (r".*_layout\.svg", "crease patterns of every sheet and how they join (to print and fold)"),
    (r".*\.svg", "crease pattern (to print and fold; Origami Simulator reads it)"),
    (r".*\.fold", "FOLD file with the simulated folding"),
    (r".*\.cp", "ORIPA crease pattern"),
    (r".*\.3mf", "3D print with its settings (3MF)"),
    (r".*\.stl", "3D print (STL)"),
    (r".*_print\.png", "picture: the printed part"),
    (r"preview_motion\.png", "picture: the motion"),
    (r"preview_map\.png", "picture: the map and cobweb"),
    (r"preview_tolerance\.png", "picture: the tolerance analysis"),
    (r"report\.json", "this report as data"),
    (r"report\.md", "this report as text"),
    (r"exports\.json", "which export made each format's files, and how (read by the next export)"),
)


def describe_file(name: str) -> str:
    """What a file of a design folder is (``""`` when fabkit does not know the name)."""
    for pattern, text in FILE_ROLES:
        m = re.fullmatch(pattern, name)
        if m:
            return text.format(*m.groups())
    return ""


def _exported(report, proc: str) -> bool:
    return any(report.formats[f].status.produced for f in PROCESSES[proc]
               if f in report.formats)


def not_exported(formats: dict) -> list:
    """Why each format that was tried wrote nothing: ``["dxf: skipped by the template – …"]``.

    Parameters
    ----------
    formats : dict of str to FormatResult
    """
    out, never = [], []
    for fmt, f in sorted(formats.items()):
        if f.status.value == "does not apply":
            never.append(f"{fmt}: does not apply")  # said only when nothing else explains it
        elif not f.status.produced:
            out.append(f"{fmt}: {f.status}" + (f" – {f.detail}" if f.detail else ""))
    return out or never


def _link(name: str) -> str:
    return f'<a href="{_esc(name)}">{_esc(name)}</a>'


def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else (f"{n / 1e3:.0f} kB" if n >= 1e3 else f"{n} B")


def _lead_section(report, files: dict) -> str:
    process = report.process
    formats = report.formats
    why = not_exported(formats)
    if not _exported(report, process):
        reasons = "; ".join(why) or "no export format applies to it"
        return (f'<section id=made-for class=lead><h2>Made for {_esc(MADE_FOR[process])}: no '
                f'files</h2><p class="warn">Nothing to build was written: {_esc(reasons)}.</p>'
                "</section>")
    parts = []
    if process == "laser":
        b = _exporter(formats, "dxf")
        st = b["settings"]
        sheets = b["sheets"]
        sizes = sorted({f"{s['size_mm'][0]:g} × {s['size_mm'][1]:g} mm" for s in sheets})
        screws = sum(s["count"] for s in b["screws"])
        parts.append(f"<p>{len(sheets)} sheet{'s' if len(sheets) != 1 else ''} of "
                     f"{_esc(', '.join(sizes))}, {_fmt(st['thickness'])} mm acrylic, "
                     f"{_fmt(b['scale_mm_per_unit'])} mm a design unit; {len(b['bars'])} bars "
                     f"in {_esc(b['layers']['count'])} layers; {screws} screws, "
                     f"{b['washers']['count']} washers, {b['spacer_rings']['count']} spacer "
                     "rings (see the bill of materials).</p>")
        if "laser_guide.pdf" in files:
            parts.append(f"<p><b>Start here:</b> {_link('laser_guide.pdf')}, the assembly guide "
                         f"({b['guide_pages']} A4 pages: overview, how to build, a page per two "
                         "modules, the motion test).</p>")
    elif process == "origami":
        r = _exporter(formats, "svg")
        sheet = r.get("sheet") or {}
        if sheet.get("shape") == "square":
            paper = (f"a square of side {sheet['side_mm']:.2f} mm ({sheet['across_mm']:.2f} mm "
                     "corner to corner)")
        else:
            paper = f"{_esc(sheet.get('shape', 'a sheet'))} {_fmt(sheet.get('bbox_mm'))} mm"
        n = r.get("sheets", 1)
        parts.append(f"<p>One sheet of paper, {paper}.</p>" if n == 1 else
                     f"<p>{n} sheets of paper, each {paper}.</p>")
        if r.get("file"):
            parts.append(f"<p><b>Start here:</b> {_link(r['file'])} (print at 100 %, fold)"
                         + (f", or cut {_link(r['cut_file'])} on a laser or vinyl cutter"
                            if r.get("cut_file") else "") + ".</p>")
    else:
        r = _exporter(formats, "stl")
        st = r["settings"]
        size = " × ".join(_fmt(v) for v in r.get("size_mm") or [])
        if r["linkage"] == "pins":
            parts.append(f"<p>Printed in place: {_esc(r['bars'])} bars in "
                         f"{_esc(r['layers'])} layers on {_esc(r['printed_pins'])} "
                         f"printed pins ({_esc(st['material'])}), {_fmt(st['scale'])} mm a "
                         f"design unit, {_fmt(st['pin_clearance'])} mm pin clearance, "
                         f"{_fmt(st['clearance'])} mm between bars.</p>")
        else:
            parts.append(f"<p>{_esc(r['plates'])} plates joined by "
                         f"{_esc(r['hinges'])} hinges ({_esc(st['hinge_style'])}, "
                         f"{_esc(st['material'])}), {_esc(size)} mm.</p>")
        prints = sorted((n for n in formats["stl"].files if n.endswith((".3mf", ".stl"))),
                        key=lambda n: (not n.endswith(".3mf"), n))
        if prints:
            parts.append("<p><b>Start here:</b> " + ", ".join(_link(n) for n in prints) + ".</p>")
    others = [p for p in PROCESSES if p != process and _exported(report, p)]
    if others:
        parts.append("<p>Also exported: " + ", ".join(
            f'<a href="#also-{p}">{_esc(MADE_FOR[p])}</a>' for p in others) + " (folded below)."
                     "</p>")
    if why:
        parts.append(f"<p class=\"warn\">Not written: {_esc('; '.join(why))}.</p>")
    return (f"<section id=made-for class=lead><h2>Made for {_esc(MADE_FOR[process])}</h2>"
            + "".join(parts) + "</section>")


def _files_section(listing: dict, process: str | None) -> str:
    def rank(name):
        if name.startswith(("report.", "preview_")):
            return 3
        owner = ("laser" if name.startswith("laser_") else
                 "print" if name.endswith((".stl", ".3mf", "_print.png")) else "origami")
        return 0 if owner == process else (1 if name != "report.html" else 2)

    rows = "".join(f"<tr><td>{_link(n)}</td><td class=nowrap>{_size(listing[n])}</td>"
                   f"<td>{_esc(describe_file(n))}</td></tr>"
                   for n in sorted(listing, key=lambda n: (rank(n), n)) if n != "report.html")
    return ("<section id=files><h2>Files</h2><p>Every file written for this design, next to this "
            'page.</p><div class="scroll"><table><tr><th>file</th><th>size</th><th>what it is'
            "</th></tr>" + rows + "</table></div></section>")


def _kept_word(report, fmt: str) -> str:
    f = report.formats.get(fmt)
    return "kept, checked again" if f is not None and f.checks else "kept"


def _exports_section(report) -> str:
    """Which export made each format's files in the folder, when and with what settings, and
    the stale formats removed (:mod:`fabkit.pipeline.manifest`)."""
    if not report.origins and not report.removed:
        return ""
    kept = report.kept
    rows = "".join(
        f"<tr><td>{_esc(f)}</td><td>{o.export}</td><td class=nowrap>{_esc(o.when)} UTC</td>"
        f"<td>{_esc(o.line().split('settings: ', 1)[1])}</td>"
        f"<td>{_kept_word(report, f) if f in kept else 'made now'}</td></tr>"
        for f, o in sorted(report.origins.items()))
    gone = "".join(f"<li>{_esc(r)}</li>" for r in report.removed)
    return ("<section id=exports><h2>Exports in this folder</h2><p>A later export adds its "
            "formats to those already here; an earlier format stays while it was made from the "
            "same design, settings and fabkit version.</p><div class=\"scroll\"><table><tr>"
            "<th>format</th><th>export</th><th>when</th><th>settings</th><th>here</th></tr>"
            + rows + "</table></div>" + (f"<p>Removed (stale):</p><ul>{gone}</ul>" if gone
                                         else "") + "</section>")


def _laser_section(files: dict, ident: str = "laser") -> str:
    pics = [n for n in ("laser_assembly.png", "laser_layers_motion.png",
                        "laser_guide_page1.png") if n in files]
    pics += [n for n in sorted(files) if n.startswith("laser_") and n.endswith(".png")
             and n not in pics]
    sheets = [n for n in sorted(files) if n.startswith("laser_sheet") and n.endswith(".svg")]
    body = "".join(_img(n, files[n], n, f"{n}: {describe_file(n)}") for n in pics)
    if sheets:
        body += ("<details><summary>The cut sheets at true size (1 mm = 3.78 px)</summary>"
                 + "".join(_img(n, files[n], n) for n in sheets) + "</details>")
    return f"<section id={ident}><h2>Laser-cut kit</h2>{body}</section>"


def _laser_bom(report, ident: str = "bom") -> str:
    from ..export.dxf import bom_blocks

    bom = _exporter(report.formats, "dxf")
    if not bom:
        return ""
    return (f"<section id={ident}><h2>Bill of materials</h2>"
            + _blocks_html(bom_blocks(bom), FOLD_ROWS) + "</section>")


def _origami_section(report, files: dict, ident: str = "origami") -> str:
    r = _exporter(report.formats, "svg")
    svgs = [n for n in report.formats["svg"].files
            if n.endswith(".svg") and not n.endswith("_cut.svg") and n in files] if r else []
    body = "".join(_img(n, files[n], "crease pattern", f"{n}: {describe_file(n)}")
                   for n in svgs)
    creases = r.get("creases") or []
    if creases:
        rows = "".join(f"<tr><td>{_esc(c['crease'])}</td><td>{_esc(c['fold'])}</td>"
                       f"<td>{c['angle_deg']:.1f}°</td></tr>" for c in creases)
        body += ("<p>Fold every crease to its angle (0° flat, 180° folded flat), seen from the "
                 'printed side:</p><div class="scroll"><table><tr><th>crease</th><th>fold</th>'
                 f"<th>angle</th></tr>{rows}</table></div>")
    cut = r.get("cut") or {}
    if r.get("cut_file") in files:
        perf = cut.get("perforation") or {}
        body += (f"<details><summary>Cut-ready sheet {_esc(r['cut_file'])}: "
                 f"{_fmt(perf.get('dash_mm'))} mm cuts, {_fmt(perf.get('gap_mm'))} mm gaps, "
                 f"{_fmt(perf.get('stop_mm'))} mm whole at every vertex</summary>"
                 + _img(r["cut_file"], files[r["cut_file"]], "cut-ready sheet") + "</details>")
    return (f"<section id={ident}><h2>Crease pattern</h2><p>Valley folds blue and dashed, "
            "mountain folds red and dash-dot; the motion above shows the sheet folding.</p>"
            + body + "</section>")


def _origami_bom(report, ident: str = "bom") -> str:
    svg = _exporter(report.formats, "svg")
    if not svg:
        return ""
    sheet = svg.get("sheet") or {}
    size = (f"square, side {sheet['side_mm']:.2f} mm" if sheet.get("shape") == "square"
            else f"{_fmt(sheet.get('bbox_mm'))} mm")
    return (f"<section id={ident}><h2>Bill of materials</h2><table><tr><th>origami</th>"
            f"<th>quantity</th></tr><tr><td>paper sheets ({_esc(size)})</td>"
            f"<td>{_fmt(svg.get('sheets', 1))}</td></tr></table></section>")


def _print_section(report, files: dict, ident: str = "print") -> str:
    r = _exporter(report.formats, "stl")
    if not r:
        return ""
    pr = r.get("printer") or {}
    body = []
    s = r["settings"]
    if r["linkage"] == "pins":
        body.append(f"<p>Printed in place: {r['bars']} bars in {r['layers']} layers "
                    f"on {r['printed_pins']} printed pins ({_esc(s['material'])}), "
                    f"{_fmt(r['height_mm'])} mm tall, {_fmt(r['volume_mm3'])} mm³.</p>")
    else:
        body.append(f"<p>{r['plates']} plates, {r['hinges']} hinges "
                    f"({_esc(s['hinge_style'])}, {_esc(s['material'])}), "
                    f"{_esc(_fmt(r['size_mm']))} mm, {_fmt(r['volume_mm3'])} mm³.</p>")
    if pr:
        bed = pr.get("printer") or {}
        layout = "; ".join(f"piece {p['piece']} on bed {p['bed']} turned "
                           f"{p['angle_deg']:.0f}°" + (f", joined at {p['joined_at']}"
                                                      if p.get("joined_at") else "")
                           for p in pr.get("pieces", []))
        body.append(f"<p>Printer: {_esc(bed.get('description'))}. {_esc(layout)}. "
                    f"Files: {_esc(', '.join(pr.get('files', [])))}.</p>")
        if pr.get("note"):
            body.append(f"<p>{_esc(pr['note'])}</p>")
        if pr.get("join"):
            body.append(f"<p>Join: {_esc(pr['join'])}</p>")
        if pr.get("stl"):
            body.append(f"<p>The STL files: {_esc(pr['stl'])}.</p>")
    pics = [n for n in sorted(files) if n.endswith("_print.png")]
    body.append("".join(_img(n, files[n], "printed part") for n in pics))
    return f"<section id={ident}><h2>Printed part</h2>" + "".join(body) + "</section>"


def _print_bom(report, ident: str = "bom") -> str:
    stl = _exporter(report.formats, "stl")
    if not stl:
        return ""
    s = stl["settings"]
    return (f"<section id={ident}><h2>Bill of materials</h2>"
            "<table><tr><th>printed part</th><th>quantity</th></tr>"
            f"<tr><td>{_esc(s['material'])} filament</td>"
            f"<td>{_fmt((stl.get('volume_mm3') or 0) / 1000.0)} cm³</td></tr>"
            + (f"<tr><td>printed bars</td><td>{stl['bars']}</td></tr>"
               f"<tr><td>printed pins</td><td>{stl['printed_pins']}</td></tr>"
               if stl["linkage"] == "pins" else
               f"<tr><td>plates</td><td>{stl['plates']}</td></tr>"
               f"<tr><td>hinges</td><td>{stl['hinges']}</td></tr>") + "</table>"
            + _print_buy(stl) + "</section>")


def _print_buy(stl: dict) -> str:
    """The parts a print needs that are not printed (bolts where it is cut), with their size
    and count."""
    buy = (stl.get("print_bom") or {}).get("buy") or []
    if not buy:
        return ""
    rows = "".join(f"<tr><td>{_esc(b['part'])}</td><td>{_esc(b['standard'])}</td>"
                   f"<td>{_esc(b['size'])}</td><td>{b['count']}</td></tr>" for b in buy)
    return ("<table><tr><th>to buy (not printed)</th><th>standard</th><th>size</th>"
            f"<th>count</th></tr>{rows}</table>")


def _process_sections(proc: str, report, files: dict, primary: bool) -> str:
    """A process's pictures and bill of materials: open when the design was made for it,
    folded under "Also exported" otherwise."""
    if not _exported(report, proc):
        return ""
    suffix = "" if primary else f"-{proc}"
    if proc == "laser":
        body = _laser_section(files, "laser") + _laser_bom(report, "bom" + suffix)
    elif proc == "origami":
        body = _origami_section(report, files, "origami") + _origami_bom(report, "bom" + suffix)
    else:
        body = _print_section(report, files, "print") + _print_bom(report, "bom" + suffix)
    if primary:
        return body
    return (f'<details id="also-{proc}"><summary>Also exported: {_esc(MADE_FOR[proc])}'
            f"</summary>{body}</details>")


def _frames(report) -> dict | None:
    motion = report.motion
    traj = motion.trajectory if motion is not None and motion.traced else None
    return motion_frames(report.design, traj, report.formats)


def design_html(report, files: dict, listing: dict, frames: dict | None = None) -> bytes:
    """A design's ``report.html``, rendered from the typed results of its export.

    It opens with the verdict (the worst of the checks, the motion and the tolerance analysis),
    then the process the design was made for (what to buy, which file to start from) and a link
    to every file written for it; then the motion, that process's pictures and bill of
    materials, the map, any other process's files folded, the tolerance and every check.
    Pictures show at their own size (a wide one scrolls sideways in its box).

    Parameters
    ----------
    report : fabkit.pipeline.stages.DesignReport
    files : dict of str to bytes
        The files of the folder in memory (pictures are inlined from here).
    listing : dict of str to int
        Every file of the folder and its size in bytes, for the links.
    frames : dict, optional
        The motion as drawing data (:func:`motion_frames`; made here when not given).

    Returns
    -------
    bytes
        UTF-8 HTML that loads nothing from outside itself.
    """
    d = report.facts
    name = d["name"]
    v = report.verdict
    badge = {"ok": "#a5d6a7", "by design": "#d7ccc8"}.get(str(v.level), "#ef9a9a")
    word = "flagged by design" if str(v.level) == "by design" else str(v.level)
    head = (f"<header><h1>{_esc(name)} <span style=\"color:{badge}\">{_esc(word)}</span>"
            f"</h1><p>{_esc(d.get('description', ''))}"
            + (f" · {_esc(d['figure'])}" if d.get("figure") else "")
            + f" · fabkit {_esc(_version())}</p></header>")
    body = [_verdict_section(report), _lead_section(report, files),
            _files_section(listing, report.process), _exports_section(report)]
    data = frames if frames is not None else _frames(report)
    motion = report.motion
    line = motion.line() if motion is not None and motion.status.value != "no target" else ""
    if data is not None:
        legend = "".join(f'<span><i style="background:{c}"></i>{_esc(t)}</span>'
                         for t, c in data["legend"])
        body.append(
            "<section id=motion class=motion><h2>Motion</h2>"
            f"<p>{_esc(line)}</p>"
            f'<div class="controls"><button data-play="{_MOTION_TAG}">play</button>'
            f'<input type="range" min="0" max="{len(data["frames"]) - 1}" value="0" step="1" '
            f'id="frame" data-for="{_MOTION_TAG}" aria-label="motion frame">'
            f'<output data-value-for="{_MOTION_TAG}"></output></div>'
            + _motion_svg(data, _MOTION_TAG, width=2.5)
            + f'<p class="legend">{legend}<span><i style="background:#888"></i>ports (dashed)'
              "</span></p></section>")
    elif line:
        body.append(f"<section id=motion><h2>Motion</h2><p>{_esc(line)}</p></section>")
    body.append(_process_sections(report.process, report, files, True))
    pics = [n for n in ("preview_motion.png", "preview_map.png") if n in files]
    if pics:
        body.append("<section id=map><h2>Map and cobweb</h2>"
                    + "".join(_img(n, files[n], n) for n in pics) + "</section>")
    for proc in PROCESSES:
        if proc != report.process:
            body.append(_process_sections(proc, report, files, False))
    body.append(_tolerance_section(report, files))
    body.append(_checks_section(report))
    page = ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{_esc(name)} – fabkit report</title><style>{_CSS}</style></head><body>"
            + head + "<main>" + "".join(body) + f"</main><script>{_JS}</script></body></html>")
    return page.encode("utf-8")


def _version() -> str:
    import fabkit

    return fabkit.__version__


@dataclass(frozen=True)
class IndexCard:
    """A design's card in index.html, made from its typed report in the process that exported
    it and handed back with its result (the index reads no page back).

    Attributes
    ----------
    folder : str
        The design's folder name (its page is ``folder/report.html``).
    name, description : str
    level : str
        The verdict's level (:class:`fabkit.pipeline.stages.Level` value).
    text : str
        The verdict's finding in words, shown beside the level.
    process : str or None
    formats : tuple of str
        Formats written.
    checked : int
        Files read back by the as-built checks.
    why_not : str
        Why nothing (or nothing of its own process) was written, ``""`` otherwise.
    frames : dict or None
        The motion as drawing data (:func:`fabkit.report.html.motion_frames`).
    exports : tuple of str
        ``"dxf: export 1"`` for each format, when the folder holds more than one export's.
    """

    folder: str
    name: str
    description: str
    level: str
    text: str
    process: str | None
    formats: tuple
    checked: int
    why_not: str = ""
    frames: dict | None = None
    exports: tuple = ()


def index_card(report, folder: str, frames: dict | None = None):
    """A design's card in index.html, from its typed report (see :class:`IndexCard`).

    Parameters
    ----------
    report : fabkit.pipeline.stages.DesignReport
    folder : str
        The design's folder name.
    frames : dict, optional
        The motion as drawing data (made here when not given).

    Returns
    -------
    fabkit.pipeline.stages.IndexCard
    """
    made = tuple(sorted(f for f, v in report.formats.items() if v.status.produced))
    why = ""
    if not made:
        why = "; ".join(not_exported(report.formats)) or "no export format applies to it"
    elif not _exported(report, report.process):
        why = "; ".join(w for w in not_exported(report.formats)
                        if w.split(":")[0] in PROCESSES[report.process])
    data = frames if frames is not None else _frames(report)
    origins = getattr(report, "origins", {}) or {}
    exports = ()
    if len({o.export for o in origins.values()}) > 1:
        exports = tuple(f"{f}: export {o.export} ({o.when} UTC)"
                        for f, o in sorted(origins.items()))
    return IndexCard(folder, report.facts["name"], report.facts.get("description", ""),
                     str(report.verdict.level), report.verdict.text, report.process, made,
                     len(report.checks.results), why, data, exports)


def index_html(cards, earlier=()) -> bytes:
    """``index.html`` of a batch.

    Parameters
    ----------
    cards : iterable of IndexCard
        The designs of this export, in order.
    earlier : iterable of str
        Folders of designs exported into the same output by earlier runs (linked by name: no
        page is read back).

    Returns
    -------
    bytes
    """
    out = []
    for k, c in enumerate(cards):
        pic = _motion_svg(c.frames, f"m{k}", autoplay=True) if c.frames else "<p>(no motion)</p>"
        lines = [f"<p>{_esc(c.description)}</p>"]
        if c.level != "error":
            lines.insert(0, f'<p class="verdict-line">{_level(c.level)}: {_esc(c.text)}</p>')
        else:
            lines.append(f'<p class="bad">{_esc(c.text)}</p>')
        if c.formats:
            lines.append(f"<p>made for {_esc(MADE_FOR[c.process])} · formats: "
                         f"{_esc(', '.join(c.formats))}" + (
                             f" · {c.checked} file{'s' if c.checked != 1 else ''} read back"
                             if c.checked else " · no as-built check ran") + "</p>")
            if c.exports:
                lines.append(f"<p>from more than one export: {_esc('; '.join(c.exports))}</p>")
            if c.why_not:
                lines.append(f'<p class="warn">No {_esc(c.process)} files: {_esc(c.why_not)}'
                             "</p>")
        elif c.level != "error":
            lines.append(f'<p class="warn">No files to build: {_esc(c.why_not)}</p>')
        link = (f'<a href="{_esc(c.folder)}/report.html">{_esc(c.name)}</a>' if c.folder
                else _esc(c.name))
        out.append(f'<div class="card"><h3>{link}</h3>{pic}{"".join(lines)}</div>')
    older = list(earlier)
    more = ("<section><h2>Exported earlier into this folder</h2><p>"
            + ", ".join(f'<a href="{_esc(f)}/report.html">{_esc(f)}</a>' for f in older)
            + "</p></section>") if older else ""
    page = ("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>fabkit batch</title><style>{_CSS}</style></head><body><header><h1>fabkit "
            f"batch: {len(out)} designs</h1><p>Each picture moves through the design's "
            "motion; open a design for its slider, files, checks and tolerance.</p></header>"
            f'<main><div class="grid">{"".join(out)}</div>{more}</main><script>{_JS}</script>'
            "</body></html>")
    return page.encode("utf-8")


def write_index(outdir, cards) -> Path:
    """Write ``outdir/index.html`` from the cards of this export; the other design folders
    of the output (exported by earlier runs) are linked by name.

    Returns
    -------
    pathlib.Path
    """
    outdir = Path(outdir)
    cards = list(cards)
    mine = {c.folder for c in cards}
    earlier = sorted(p.name for p in outdir.iterdir()
                     if p.is_dir() and not p.name.startswith(".") and p.name not in mine
                     and (p / "report.html").is_file())
    write_atomic(outdir / "index.html", index_html(cards, earlier))
    return outdir / "index.html"
