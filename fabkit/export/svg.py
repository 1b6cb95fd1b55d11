"""SVG crease patterns in the conventions origami software reads (Origami Simulator).

Every crease or boundary segment is one ``<line>`` that is a direct child of ``<svg>`` (no
groups, no transforms), in mm. Stroke colour: black boundary, red (#ff0000) mountain, blue
(#0000ff) valley, green (#00ff00) cut, yellow (#ffff00) flat/facet, magenta (#ff00ff)
unassigned. ``stroke-opacity`` = |target fold angle| / 180° on mountain and valley creases (the
angle where the crease is folded most along the simulated motion), 1 elsewhere; ``opacity`` is never set (the
two multiply). The pattern is drawn as seen from the side its faces face (+z), y up.

A design of several sheets (a chain) gets a printable layout instead: every sheet drawn
separately in a grid, its corners labelled with the corners of the neighbouring sheets they are
joined to (``B=1A`` on sheet 2: corner B is glued onto corner A of sheet 1).

Settings (``[fabrication.origami]``, overridable as ``origami.<key>``): ``sheet_size`` (mm, the
larger side of one sheet's flat bounding box, default 150), ``samples``, ``branch``, ``sign``.
"""

from __future__ import annotations

from xml.sax.saxutils import escape

import numpy as np

from . import ExportResult

FORMAT = "svg"

#: Stroke colour of each FOLD assignment (Origami Simulator's import colours).
COLOURS = {"B": "#000000", "M": "#ff0000", "V": "#0000ff", "C": "#00ff00", "F": "#ffff00",
           "U": "#ff00ff", "J": "#ff00ff"}

_MARGIN = 10.0  # mm around each sheet


#: Why the format does not apply, when :func:`applies` says so (reported by ``--to svg``).
NOT_APPLICABLE = ("a crease pattern needs a [fabrication.origami] table (mountain/valley "
                  "assignment); this design has none: cut it (dxf) or print it (stl)")


def applies(design) -> bool:
    """True when the template has a ``[fabrication.origami]`` table."""
    fab = getattr(design, "fabrication", None)
    return isinstance(fab, dict) and isinstance(fab.get("origami"), dict)


def _fmt(v: float) -> str:
    return f"{v:.4f}".rstrip("0").rstrip(".")


def _lines(pattern, target, scale, dx, dy):
    """SVG <line> elements of one sheet placed with its bounding box at (dx, dy) (mm)."""
    v = pattern.vertices
    lo = v.min(axis=0)
    top = v[:, 1].max()
    out = []
    for k, (a, b) in enumerate(pattern.edges.tolist()):
        lab = pattern.assignment[k]
        p, q = v[a], v[b]
        x1, y1 = dx + (p[0] - lo[0]) * scale, dy + (top - p[1]) * scale
        x2, y2 = dx + (q[0] - lo[0]) * scale, dy + (top - q[1]) * scale
        op = min(abs(float(target[k])) / 180.0, 1.0) if lab in ("M", "V") else 1.0
        out.append(f'<line x1="{_fmt(x1)}" y1="{_fmt(y1)}" x2="{_fmt(x2)}" y2="{_fmt(y2)}" '
                   f'stroke="{COLOURS[lab]}" stroke-opacity="{_fmt(op)}" stroke-width="0.5" '
                   f'fill="none"/>')
    return out


def _document(width, height, body, title):
    head = ('<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{_fmt(width)}mm" '
            f'height="{_fmt(height)}mm" viewBox="0 0 {_fmt(width)} {_fmt(height)}">\n'
            f'<title>{escape(title)}</title>\n')
    return (head + "\n".join(body) + "\n</svg>\n").encode("utf-8")


def sheet_targets(model, fold) -> list[np.ndarray]:
    """Target fold angle of every edge of every sheet (degrees): where it is folded most."""
    final = fold.target_angles
    index = {tuple(sorted(map(int, e))): k for k, e in enumerate(model.edges.tolist())}
    out = []
    for sh in model.sheets:
        ks = [index[tuple(sorted((int(sh.nodes[a]), int(sh.nodes[b]))))]
              for a, b in sh.pattern.edges.tolist()]
        out.append(final[ks])
    return out


def join_marks(model) -> list[dict]:
    """For every sheet, the corners shared with other sheets: {local vertex: ["1A", ...]}."""
    owners: dict[int, list[tuple[int, int]]] = {}
    for k, sh in enumerate(model.sheets):
        for a, g in enumerate(sh.nodes.tolist()):
            owners.setdefault(int(g), []).append((k, a))
    marks = []
    for k, sh in enumerate(model.sheets):
        labels = sh.pattern.labels or tuple(str(i) for i in range(sh.pattern.n_vertices))
        here = {}
        for a, g in enumerate(sh.nodes.tolist()):
            others = [f"{j + 1}{(model.sheets[j].pattern.labels or labels)[b]}"
                      for j, b in owners[int(g)] if j != k]
            if others:
                here[a] = others
        marks.append(here)
    return marks


def render(model, fold) -> tuple[bytes, dict]:
    """The SVG of a model (one sheet, or a layout of all sheets) and a small report.

    Crease colours follow the folding the simulator did (:func:`folded_assignment`).
    """
    from dataclasses import replace

    from ..fab.creases import CreasePattern, folded_assignment

    realised = folded_assignment(model, fold)
    index = {tuple(sorted(map(int, e))): k for k, e in enumerate(model.edges.tolist())}
    sheets = []
    for sh in model.sheets:
        pat = sh.pattern
        labs = [realised[index[tuple(sorted((int(sh.nodes[a]), int(sh.nodes[b]))))]]
                for a, b in pat.edges.tolist()]
        sheets.append(replace(sh, pattern=CreasePattern(pat.vertices, pat.edges, labs, pat.faces,
                                                        pat.labels)))
    model = replace(model, sheets=tuple(sheets))
    scale = model.scale
    targets = sheet_targets(model, fold)
    if len(model.sheets) == 1:
        pat = model.sheets[0].pattern
        w, h = np.ptp(pat.vertices, axis=0) * scale
        body = _lines(pat, targets[0], scale, _MARGIN, _MARGIN)
        data = _document(w + 2 * _MARGIN, h + 2 * _MARGIN, body, model.name)
        return data, {"sheets": 1, "lines": len(body), "width_mm": float(w + 2 * _MARGIN),
                      "height_mm": float(h + 2 * _MARGIN)}
    marks = join_marks(model)
    n = len(model.sheets)
    cols = int(np.ceil(np.sqrt(n)))
    rows = int(np.ceil(n / cols))
    cell = model.sheet_size + 4 * _MARGIN
    body, n_lines = [], 0
    for k, sh in enumerate(model.sheets):
        pat = sh.pattern
        r, c = divmod(k, cols)
        dx, dy = c * cell + 2 * _MARGIN, r * cell + 2 * _MARGIN
        lines = _lines(pat, targets[k], scale, dx, dy)
        n_lines += len(lines)
        body += lines
        lo, top = pat.vertices.min(axis=0), pat.vertices[:, 1].max()
        centre = pat.vertices.mean(axis=0)
        cx, cy = dx + (centre[0] - lo[0]) * scale, dy + (top - centre[1]) * scale
        body.append(f'<text x="{_fmt(cx)}" y="{_fmt(cy + 12)}" font-size="6" '
                    f'text-anchor="middle" fill="#000000">sheet {k + 1}</text>')
        labels = pat.labels or tuple(str(i) for i in range(pat.n_vertices))
        for a, p in enumerate(pat.vertices):
            x = dx + (p[0] - lo[0]) * scale
            y = dy + (top - p[1]) * scale
            # put the mark outside the sheet, along the ray from its centre
            ray = p - centre
            nrm = np.linalg.norm(ray)
            ox, oy = (ray / nrm * 6.0) if nrm > 0 else (0.0, 0.0)
            text = labels[a] + ("=" + ",".join(marks[k][a]) if a in marks[k] else "")
            if a in marks[k]:
                body.append(f'<circle cx="{_fmt(x)}" cy="{_fmt(y)}" r="1.5" fill="#000000"/>')
            body.append(f'<text x="{_fmt(x + ox)}" y="{_fmt(y - oy + 2)}" font-size="4" '
                        f'text-anchor="middle" fill="#000000">{escape(text)}</text>')
    data = _document(cols * cell + 2 * _MARGIN, rows * cell + 2 * _MARGIN, body,
                     f"{model.name}: layout of {n} sheets")
    return data, {"sheets": n, "lines": n_lines, "joins": marks}


def export_design(design, settings: dict) -> ExportResult:
    """Crease pattern SVG (``<name>.svg``), or the layout of all sheets (``<name>_layout.svg``).

    Raises
    ------
    FabricationError
        No [fabrication.origami] table, bad settings, or a folding the simulator cannot do.
    """
    from ..fab.creases import fold_model, origami_model

    model = origami_model(design, (settings or {}).get("origami"))
    fold = fold_model(model, design.motion.drive, design.motion.to)
    data, report = render(model, fold)
    name = f"{design.name}.svg" if len(model.sheets) == 1 else f"{design.name}_layout.svg"
    report.update(format=FORMAT, sheet_size_mm=model.sheet_size, file=name)
    return ExportResult(files={name: data}, report=report)
