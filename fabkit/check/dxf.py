"""As-built check of laser-cut DXF sheets: read them back and prove the parts move as designed.

Steps (each a named entry of the report's ``checks``):

* ``units``: every sheet says ``$INSUNITS = 4`` (mm);
* ``audit``: ezdxf's structural audit finds no error;
* ``layers``: entities only on CUT, CUT_INNER, ENGRAVE and REFERENCE;
* ``parts``: every bar outline found once, with exactly two holes, on the layers it belongs to;
* ``holes_centred``: the round ends of each outline are centred on its holes (<= 1e-6 mm);
* ``width_after_kerf`` / ``hole_after_kerf``: drawn sizes with the kerf undone equal the
  designed bar width and hole (<= 1e-6 mm);
* ``lengths``: hole-centre distances equal the designed bar lengths (<= 1e-6 mm);
* ``topology``: the bars join the designed joints;
* ``modes``: the rebuilt network (joint positions fitted to the measured lengths, starting from
  the design) has exactly one conformational motion;
* ``module_map``: re-simulating the rebuilt network gives the design's port distances along
  the drive;
* ``screws_close``: the screw chosen for each joint's stack (layers read back) closes on the
  thickest sheets the thickness tolerance allows, with its washers;
* ``same_layer``: over the re-simulated motion, sampled more finely than the stacking was
  planned with (no node moves more than clearance / 4 between samples), no two bars of one
  layer come closer than clearance / 2 (the stacking's guarantee), and no bar or screw column
  enters another screw's layers nearby.

Without a design only the file-level checks run: the report's ``not_checked`` names the others.
A check that an earlier failure leaves without what it needs is reported as not run (failed).
"""

from __future__ import annotations

import io
import math
import re
from pathlib import Path
from typing import Optional

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from ..errors import FabricationError
from ..settings.fasteners import fit_fastener
from ..settings.design import design_settings
from ..io.formats import damaged, refuse_dxf_entities
from ..io.readback import ReadBack
from ..io.schema import describe_validation_error
from ..io.workload import MAX_BYTES
from ..model.network import Network
from ..model.rigidity import count_modes
from ..numerics import MM_SLACK, project_to_lengths
from . import require_files
from .clearance import fine_motion, same_layer_gaps
from .sheet_layout import least_gap, MIN_WEB_MM
from .items import Check, check, finish
from .motion import as_traced, compare_motion, design_window

__all__ = ["FORMAT", "SUFFIXES", "check_file", "check_documents", "read_sheet", "LENGTH_TOL",
           "parse_dxf"]

FORMAT = "dxf"
#: The sections of ``--set`` this check reads (any other has no effect on it).
READS = ("laser",)
SUFFIXES = (".dxf",)
#: Largest difference allowed between a read-back length and the design (mm).
LENGTH_TOL = 1e-6

#: Read-back lengths within this of the design's (mm) are the design's: the DXF stores coordinates
#: as round-trip floats, so read-back lengths differ from the design's only by round-off (~1e-13
#: mm on a 1 m sheet); 1e-9 mm leaves a wide margin and is far below any cutting error.
FILE_RESOLUTION_MM = 1e-9
#: Largest difference allowed between the re-simulated and designed port distances, relative
#: to the network size (design units): the map is compared away from exact flat states.
MAP_RTOL = 1e-6
_LAYERS = {"CUT", "CUT_INNER", "ENGRAVE", "REFERENCE"}
#: The checks of a kit's sheets from the file alone, in the order they run (``kerf`` runs too when
#: the user says which kerf the laser cuts).
FILE_CHECKS = ("units", "audit", "layers", "parts", "parts_apart", "holes_centred",
               "width_after_kerf", "hole_after_kerf")
#: The checks of a kit against its design, after :data:`FILE_CHECKS`.
DESIGN_CHECKS = ("lengths", "topology", "modes", "module_map", "screws_close", "same_layer")
#: The checks of the test coupon (``same_as_kit`` with a design).
COUPON_CHECKS = ("units", "audit", "layers", "parts", "width_after_kerf", "hole_after_kerf",
                 "ring_after_kerf", "spacing")
_APPID = "FABKIT"


#: Screw heads spanning a whole number of sheets to round-off take that many layers, not one more.
HEAD_LAYERS_SLACK = 1e-12


#: The fabkit part tags of an entity's xdata: id, kind, then whole numbers by kind (bar: its
#: index, its two joints, its layer; spacer: its joint and layer; reference: none).
PART_META = {"bar": 4, "spacer": 2, "reference": 0}
#: Whole numbers in part tags are indices: far below this in any kit fabkit can write.
MAX_INDEX = 10**7


class DxfHeader(BaseModel):
    """The FABKIT_* variables of a sheet's header (strings in the file, read as numbers)."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False)

    FABKIT_KERF: float = Field(ge=0, le=10, description="kerf the sheet was drawn for (mm)")
    FABKIT_BAR_WIDTH: float = Field(gt=0, le=1000, description="bar width (mm)")
    FABKIT_HOLE: float = Field(gt=0, le=1000, description="screw hole diameter (mm)")
    FABKIT_BARS: int = Field(ge=1, le=MAX_INDEX, description="bars in the kit")
    FABKIT_SCALE: float = Field(gt=0, le=1e6, description="mm per design unit")
    FABKIT_THICKNESS: Optional[float] = Field(None, gt=0, le=1000,
                                              description="sheet thickness (mm)")


def _mm(v: float) -> str:
    return "none" if math.isinf(v) else f"{v:.3f}"


def _bar_name(k, joints) -> str:
    return f"bar {int(k)} (joints {int(joints[0])}-{int(joints[1])})"


def _kerf_undone(drawn_outline_radius, drawn_hole_radius, kerf: float):
    """(width, hole diameter) of a part as it comes off the laser, from the radii drawn in the
    file and the kerf its header says it was drawn for: outlines were grown and holes shrunk
    by half the kerf, and the laser takes that half back on each side."""
    return (2.0 * np.asarray(drawn_outline_radius) - kerf,
            2.0 * np.asarray(drawn_hole_radius) + kerf)


def read_sheet(doc) -> dict:
    """Parts of one DXF document.

    Returns
    -------
    dict
        ``header`` (fabkit custom variables), ``insunits``, ``layers`` (layer names used),
        ``parts``: id -> {"kind", "meta" (list of ints), "arcs": [(centre, r)],
        "holes": [(centre, r)], "outer": [(centre, r)]}, ``untagged`` (CUT/CUT_INNER entities
        without a part id).
    """
    header = {k: v for k, v in doc.header.custom_vars}
    parts: dict[str, dict] = {}
    used_layers = set()
    untagged = 0
    problems: list[str] = []
    for e in doc.modelspace():
        layer = e.dxf.layer
        used_layers.add(layer)
        if not e.has_xdata(_APPID):
            if layer in ("CUT", "CUT_INNER"):
                untagged += 1
            continue
        tags = [t.value for t in e.get_xdata(_APPID)]
        tagged = _part_tags(tags)
        if isinstance(tagged, str):  # damaged: said in the parts check, never raised
            problems.append(f"a {e.dxftype()} on {layer}: {tagged}")
            continue
        pid, kind, meta = tagged
        part = parts.setdefault(pid, {"kind": kind, "meta": meta, "arcs": [], "holes": [],
                                      "outer": [], "layers": set()})
        part["layers"].add(layer)
        t = e.dxftype()
        if t == "CIRCLE":
            c = (float(e.dxf.center.x), float(e.dxf.center.y))
            (part["holes"] if layer == "CUT_INNER" else part["outer"]).append((c, float(e.dxf.radius)))
        elif t == "ARC":
            part["arcs"].append(((float(e.dxf.center.x), float(e.dxf.center.y)),
                                 float(e.dxf.radius)))
        elif t == "LWPOLYLINE":
            part["closed"] = bool(e.closed)
            for v in e.virtual_entities():
                if v.dxftype() == "ARC":
                    part["arcs"].append(((float(v.dxf.center.x), float(v.dxf.center.y)),
                                         float(v.dxf.radius)))
    return {"header": header, "insunits": doc.header.get("$INSUNITS", 0),
            "layers": used_layers, "parts": parts, "untagged": untagged, "problems": problems}


def _part_tags(tags: list):
    """(id, kind, meta) of a part's xdata, or why it cannot be read (a sentence)."""
    if len(tags) < 2 or not all(isinstance(t, str) for t in tags[:2]):
        return "its fabkit xdata lacks the part id and kind"
    pid, kind = tags[0], tags[1]
    if kind not in PART_META:
        return f"part {pid}: unknown kind {kind!r} (known: {', '.join(PART_META)})"
    meta = tags[2:]
    if len(meta) != PART_META[kind]:
        return f"part {pid}: a {kind} carries {PART_META[kind]} numbers, this one {len(meta)}"
    if not all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < MAX_INDEX
               for v in meta):
        return f"part {pid}: its numbers must be whole numbers from 0, got {meta}"
    return pid, kind, list(meta)


def _header_values(head: dict):
    """The FABKIT_* header variables as numbers, or why they cannot be read (a sentence)."""
    from pydantic import ValidationError

    if "FABKIT_BARS" not in head:
        return "the sheets carry no fabkit header (FABKIT_*): not written by fabkit"
    try:
        return DxfHeader.model_validate(head).model_dump()
    except ValidationError as exc:
        return "header " + describe_validation_error(exc, DxfHeader)


def check_documents(texts: dict, design=None, settings=None, *, motion=None) -> dict:
    """As-built check of a set of DXF sheets given as text.

    Parameters
    ----------
    texts : dict of str to str
        File name -> DXF text, every sheet of one export.
    design : Design, optional
        The design the sheets were made from (without it only file-level checks run).
    settings : dict, optional
        The laser overrides used for the export.
    motion : TracedMotion, optional
        The design's motion traced once by the pipeline: the kit's window and the design's
        trace to compare with are taken from it instead of being traced again.

    Returns
    -------
    dict
        ``ok``, ``checks`` (list of {"name", "ok", "value", "limit", "detail"}), ``bars``
        (read-back length per bar, mm) and ``files``.
    """
    import ezdxf

    docs = {}
    checks = []
    for name in sorted(texts):
        refuse_dxf_entities(texts[name], name)
        try:
            docs[name] = ezdxf.read(io.StringIO(texts[name]))
        except Exception as exc:  # ezdxf raises several types for malformed files
            checks.append(check("readable", False, name, None, f"{name}: {exc}"))
    if checks:
        return finish({"files": sorted(texts)}, checks, _expected(design),
                      "a sheet of the kit cannot be read")
    return _check_groups(docs, design, settings, motion)


def _check_groups(docs: dict, design, settings, motion=None) -> dict:
    """The kit's sheets, its uncompensated copy and its coupon are checked each on their own
    when given together; the first group's result carries the others' checks, prefixed."""
    groups: dict[str, dict] = {}
    for name, doc in docs.items():
        head = {k: v for k, v in doc.header.custom_vars}
        kind = "coupon" if "FABKIT_COUPON" in head else head.get("FABKIT_VARIANT", "")
        groups.setdefault(kind, {})[name] = doc
    if len(groups) <= 1:
        return _check_docs(docs, design, settings, motion)
    main, *rest = sorted(groups)   # the kit's own sheets ("") first
    out = _check_docs(groups[main], design, settings, motion)
    for kind in rest:
        other = _check_docs(groups[kind], design, settings, motion)
        out["checks"] = out["checks"] + [{**c, "name": f"{kind}: {c['name']}"}
                                         for c in other["checks"]]
        out["ok"] = bool(out["ok"] and other["ok"])
        out["files"] = sorted([*out["files"], *other["files"]])
    return out


def _audit(doc) -> tuple[int, str]:
    """(errors, why) of ezdxf's audit of a sheet. The audit follows block references by
    recursion: blocks nested thousands deep (fabkit writes no block) exhaust it, which is an
    error of the file, said as such."""
    try:
        return len(doc.audit().errors), ""
    except RecursionError:
        return 1, ("block references nested too deeply to audit (fabkit's sheets hold no "
                   "block)")


def _kerf_cut_with(settings, head: dict, kerf: float, checks: list) -> float:
    """The kerf the sheets were cut with: the one the user gives (``--set laser.kerf``, with a
    check that says when the file was drawn for another: its bars would come out the wrong
    size), else the header's."""
    given = settings.require("laser").kerf if settings.given("laser", "kerf") else None
    if given is None or head.get("FABKIT_VARIANT") == "uncompensated":
        return kerf
    same = abs(float(given) - kerf) <= MM_SLACK
    checks.append(check("kerf", same, float(given), kerf,
                        f"kerf of --set laser.kerf against the {kerf:g} mm the file was "
                        "drawn for" + ("" if same else "; re-export with the kerf of "
                                                       "your laser")))
    return float(given)


def _bars_read(sheets: dict, n_bars: int) -> tuple[dict, list]:
    """The bars of the sheets (by bar index: joints, layer, holes, round ends, sheet) and what
    is wrong with them: a bar twice, without two holes or a closed outline, an untagged cut
    entity, bars missing below the header's count or beyond it."""
    bars, problems = {}, [p for sh in sheets.values() for p in sh["problems"]]
    for name, sh in sheets.items():
        for pid, part in sh["parts"].items():
            if part["kind"] != "bar":
                continue
            k, i, j, layer = part["meta"]
            if k in bars:
                problems.append(f"bar {k} appears twice")
            holes = part["holes"]
            if len(holes) != 2:
                problems.append(f"bar {k} has {len(holes)} holes")
                continue
            if "CUT" not in part["layers"] or len(part["arcs"]) != 2:
                problems.append(f"bar {k} has no closed round-ended outline on CUT")
                continue
            bars[k] = {"joints": (i, j), "layer": layer, "holes": holes, "arcs": part["arcs"],
                       "sheet": name}
        problems += [f"{name}: {sh['untagged']} cut entities belong to no part"
                     for name, sh in sheets.items() if sh["untagged"]]
    # the header's count is read from the file, so it is checked, never trusted: no array is
    # sized by it, and bars beyond it are as wrong as bars missing below it
    if n_bars < 1:
        problems.append(f"the header says FABKIT_BARS = {n_bars}; a kit has at least one bar")
    extra = sorted(k for k in bars if not 0 <= k < n_bars)
    if extra:
        problems.append(f"bars {extra[:5]} are not among the {n_bars} of the header")
    elif len(bars) < n_bars:
        missing = [k for k in range(min(n_bars, len(bars) + 5)) if k not in bars][:5]
        problems.append(f"{n_bars - len(bars)} of the header's {n_bars} bars missing (first: "
                        f"{missing})")
    return bars, problems


def _check_docs(docs: dict, design, settings, motion=None) -> dict:
    settings = design_settings(design, settings)  # the pipeline's, resolved once; or a dict
    checks = []
    sheets = {name: read_sheet(doc) for name, doc in docs.items()}
    units = {name: sh["insunits"] for name, sh in sheets.items()}
    checks.append(check("units", all(u == 4 for u in units.values()),
                        sorted(set(units.values())), 4, "$INSUNITS of every sheet (4 = mm)"))
    audits = {name: _audit(doc) for name, doc in docs.items()}
    n_err = {name: n for name, (n, _) in audits.items()}
    why = "; ".join(f"{name}: {w}" for name, (_, w) in audits.items() if w)
    checks.append(check("audit", not any(n_err.values()), sum(n_err.values()), 0,
                        why or "errors found by ezdxf's audit"))
    used = set().union(*(sh["layers"] for sh in sheets.values())) if sheets else set()
    checks.append(check("layers", used <= _LAYERS, sorted(used), sorted(_LAYERS),
                        "layers that carry entities"))
    head = next(iter(sheets.values()))["header"] if sheets else {}
    if "FABKIT_COUPON" in head:
        return _check_coupon(sheets, head, checks, design, settings, sorted(docs))
    values = _header_values(head)
    if isinstance(values, str):
        checks.append(check("parts", False, None, None, values))
        return finish({"files": sorted(docs)}, checks, _expected(design))
    kerf, width, hole = values["FABKIT_KERF"], values["FABKIT_BAR_WIDTH"], values["FABKIT_HOLE"]
    n_bars, scale = values["FABKIT_BARS"], values["FABKIT_SCALE"]
    kerf = _kerf_cut_with(settings, head, kerf, checks)
    bars, problems = _bars_read(sheets, n_bars)
    checks.append(check("parts", not problems, len(bars), n_bars, "; ".join(problems[:3]) or
                        "every bar found once with two holes and a closed outline"))
    if problems:
        return finish({"files": sorted(docs)}, checks, _expected(design))
    checks.append(_parts_apart(sheets))
    ks = sorted(bars)
    hc = np.array([[bars[k]["holes"][0][0], bars[k]["holes"][1][0]] for k in ks])  # (E, 2, 2)
    hr = np.array([[bars[k]["holes"][0][1], bars[k]["holes"][1][1]] for k in ks])
    ac = np.array([[bars[k]["arcs"][0][0], bars[k]["arcs"][1][0]] for k in ks])
    ar = np.array([[bars[k]["arcs"][0][1], bars[k]["arcs"][1][1]] for k in ks])
    # match each arc to the nearer hole
    d_same = np.linalg.norm(ac - hc, axis=2).max(1)
    d_swap = np.linalg.norm(ac[:, ::-1] - hc, axis=2).max(1)
    off = np.minimum(d_same, d_swap)
    edges = np.array([bars[k]["joints"] for k in ks], dtype=np.int64)
    worst = int(np.argmax(off))
    checks.append(check("holes_centred", off.max() <= LENGTH_TOL, float(off.max()), LENGTH_TOL,
                        "largest distance (mm) from a hole centre to its round end's centre"
                        if off.max() <= LENGTH_TOL else
                        f"{_bar_name(ks[worst], edges[worst])}: a hole lies {off[worst]:.3f} mm "
                        "from the centre of its round end"))
    w_built, h_built = _kerf_undone(ar, hr, kerf)
    dw = float(np.abs(w_built - width).max())
    dh = float(np.abs(h_built - hole).max())
    checks.append(check("width_after_kerf", dw <= LENGTH_TOL, dw, LENGTH_TOL,
                        f"bar width with the {kerf:g} mm kerf of the header undone vs "
                        f"{width:g} mm"))
    checks.append(check("hole_after_kerf", dh <= LENGTH_TOL, dh, LENGTH_TOL,
                        f"hole diameter with the {kerf:g} mm kerf of the header undone vs "
                        f"{hole:g} mm"))
    lengths = np.linalg.norm(hc[:, 0] - hc[:, 1], axis=1)
    layer = np.array([bars[k]["layer"] for k in ks], dtype=np.int64)
    report = {"files": sorted(docs), "bars": [round(float(v), 9) for v in lengths],
              "scale": scale}
    if design is None:  # what the file alone cannot say is named, not passed
        report["not_checked"] = (f"no design given: {', '.join(DESIGN_CHECKS)} need the design's "
                                 "template")
        return finish(report, checks)
    net = design.network
    if len(lengths) != net.n_edges:  # another design's sheets: a failed check, not an error
        checks.append(check("topology", False, len(lengths), net.n_edges,
                            f"the file holds {len(lengths)} bars, the design {design.name} "
                            f"{net.n_edges} edges: not this design's file"))
        return finish(report, checks, _expected(design))
    want = net.edge_lengths * scale
    worst = int(np.argmax(np.abs(lengths - want)))
    dl = float(abs(lengths[worst] - want[worst]))
    checks.append(check("lengths", dl <= LENGTH_TOL, dl, LENGTH_TOL,
                        "largest |read-back - designed| bar length (mm)" if dl <= LENGTH_TOL else
                        f"{_bar_name(ks[worst], edges[worst])}: its holes are "
                        f"{lengths[worst]:.3f} mm apart, the design's bar {want[worst]:.3f} mm"))
    same_topology = np.array_equal(np.sort(edges, 1), np.sort(net.edges, 1))
    checks.append(check("topology", same_topology, None, None,
                        "bars join the designed joints" if same_topology else
                        "the bars read back join other joints than the design's"))
    if not same_topology:
        return finish(report, checks, _expected(design))
    spacers = [2.0 * r - kerf for sh in sheets.values() for part in sh["parts"].values()
               if part["kind"] == "spacer" for _, r in part["outer"]]
    measured = {"widths": w_built.max(axis=1), "thickness": values["FABKIT_THICKNESS"],
                "spacer": max(spacers) if spacers else None}
    checks += _motion_checks(design, edges, lengths, layer, scale, settings, report, measured,
                             motion)
    return finish(report, checks, _expected(design))


def _expected(design) -> tuple:
    """The checks of a kit's sheets: from the file alone, and with a design against it."""
    return FILE_CHECKS + (DESIGN_CHECKS if design is not None else ())


class CouponHeader(BaseModel):
    """The FABKIT_* variables of a test coupon's header."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False)

    FABKIT_KERF: float = Field(ge=0, le=10, description="kerf the coupon was drawn for (mm)")
    FABKIT_BAR_WIDTH: float = Field(gt=0, le=1000, description="bar width (mm)")
    FABKIT_HOLE: float = Field(gt=0, le=1000, description="screw hole diameter (mm)")
    FABKIT_SPACER: float = Field(gt=0, le=1000, description="spacer ring diameter (mm)")
    FABKIT_SPACING: float = Field(gt=0, le=1000, description="hole spacing of the bars (mm)")


def _parts_apart(sheets: dict):
    """The least gap between two parts' cut lines over the sheets (:mod:`.sheet_layout`)."""
    worst, where = float("inf"), None
    for name, sh in sheets.items():
        gap, pair = least_gap(sh["parts"])
        if gap < worst:
            worst, where = gap, (name, pair)
    if where is None or where[1] is None:
        return check("parts_apart", True, None, MIN_WEB_MM,
                     f"no two parts of a sheet within {4 * MIN_WEB_MM:g} mm of each other")
    name, (a, b) = where
    said = "overlap" if worst < 0 else f"are {worst:.2f} mm apart"
    return check("parts_apart", worst >= MIN_WEB_MM, round(worst, 6), MIN_WEB_MM,
                 f"least gap (mm) between the cut lines of two parts on a sheet: {a} and {b} "
                 f"on {name} {said}")


def _check_coupon(sheets, head, checks, design, settings, files) -> dict:
    """The kerf and fit test coupon: two bars and a ring drawn as the kit's parts, and (with a
    design) the same width, hole, ring and kerf as the kit those settings make."""
    from pydantic import ValidationError

    try:
        v = CouponHeader.model_validate(head).model_dump()
    except ValidationError as exc:
        checks.append(check("parts", False, None, None,
                            "coupon header " + describe_validation_error(exc, CouponHeader)))
        return finish({"files": files, "coupon": True}, checks, COUPON_CHECKS)
    parts = [p for sh in sheets.values() for p in sh["parts"].values()]
    bars = [p for p in parts if p["kind"] == "bar"]
    rings = [p for p in parts if p["kind"] == "spacer"]
    shaped = (len(bars) == 2 and len(rings) == 1
              and all(len(b["holes"]) == 2 and len(b["arcs"]) == 2 for b in bars)
              and len(rings[0]["holes"]) == 1 and len(rings[0]["outer"]) == 1)
    checks.append(check("parts", shaped, len(parts), 3,
                        "two bars with two holes and round ends, one spacer ring"))
    if not shaped:
        return finish({"files": files, "coupon": True}, checks, COUPON_CHECKS)
    kerf = v["FABKIT_KERF"]
    ar = np.array([[a[1] for a in b["arcs"]] for b in bars])
    hr = np.array([[h[1] for h in b["holes"]] for b in bars] + [[rings[0]["holes"][0][1]] * 2])
    w, h = _kerf_undone(ar, hr, kerf)
    ring_d, _ = _kerf_undone(np.array([rings[0]["outer"][0][1]]), np.zeros(1), kerf)
    spacing = np.array([np.linalg.norm(np.subtract(b["holes"][0][0], b["holes"][1][0]))
                        for b in bars])
    want = {"width_after_kerf": (w, v["FABKIT_BAR_WIDTH"]),
            "hole_after_kerf": (h, v["FABKIT_HOLE"]),
            "ring_after_kerf": (ring_d, v["FABKIT_SPACER"]),
            "spacing": (spacing, v["FABKIT_SPACING"])}
    for name, (got, expect) in want.items():
        d = float(np.abs(np.asarray(got) - expect).max())
        checks.append(check(name, d <= LENGTH_TOL, d, LENGTH_TOL,
                            f"drawn size with the {kerf:g} mm kerf undone vs {expect:g} mm"))
    if design is not None:
        s = settings.require("laser")
        kit = {"kerf": s.kerf, "bar width": s.bar_width, "hole": s.screw.hole_diameter,
               "ring": s.spacer_diameter}
        read = {"kerf": kerf, "bar width": v["FABKIT_BAR_WIDTH"], "hole": v["FABKIT_HOLE"],
                "ring": v["FABKIT_SPACER"]}
        off = [k for k in kit if abs(kit[k] - read[k]) > MM_SLACK]
        checks.append(check("same_as_kit", not off, off or None, None,
                            "kerf, bar width, hole and ring of the kit's settings"
                            + (f"; differ: {', '.join(off)}" if off else "")))
    return finish({"files": files, "coupon": True}, checks)


def _motion_checks(design, edges, lengths_mm, layer, scale, settings, report, measured,
                   motion=None) -> list[Check]:
    """Modes, the re-simulated motion, the screws and the clearances of the rebuilt kit.

    ``measured``: what the file says besides the bars' lengths: ``widths`` (each bar's width,
    kerf undone), ``thickness`` (the header's sheet) and ``spacer`` (the spacer rings'
    diameter, None when the kit has none). The template gives the clearance, the screw (a
    catalogue entry) and the window of the motion the kit follows; ``motion`` (the pipeline's
    :class:`fabkit.motion.TracedMotion`) gives that window's motion, traced once.
    """
    s = settings.require("laser")
    # the motion the kit follows (motion_from / _to), from the Motion stage: traced once
    design, reference = design_window(design, s.motion_from, s.motion_to, motion, "laser")
    net = design.network
    out = []
    # Joint positions with the read-back lengths. When the design's own joints already have them
    # to the file's resolution, they are kept: a refit would only add round-off, and a design
    # driven next to an unstable state (the super-stable chain ends 1e-12 above D2*) amplifies
    # 1e-13 of round-off into a visible change of its end state.
    x_mm = net.nodes * scale
    start_err = np.abs(np.linalg.norm(x_mm[edges[:, 0]] - x_mm[edges[:, 1]], axis=1) - lengths_mm)
    if start_err.max() > FILE_RESOLUTION_MM:
        x = project_to_lengths(edges, lengths_mm, x_mm).positions / scale
    else:  # the design's own joints, not a round trip through mm (a branch point would see it)
        x = net.nodes
    # the design's own network, bar for bar, is not traced again (:func:`.motion.as_traced`)
    built = as_traced(Network(x, edges, net.ports, net.labels), reference)
    err = float(np.abs(built.edge_lengths * scale - lengths_mm).max())
    modes = count_modes(built)
    # the design's own count: 1 for a mechanism, more for a design that starts at a branch
    # point on purpose (the AND gate: two infinitesimal motions and a state of self-stress)
    want = count_modes(net).conformational
    out.append(check("modes", modes.conformational == want and err <= LENGTH_TOL,
                     modes.conformational, want,
                     f"conformational motions of the rebuilt network (fit residual {err:.1e} mm, "
                     f"{modes.self_stress} states of self-stress) against the design's"))
    m = design.motion
    if m.to is None:
        out.append(check("module_map", False, None, None, "the design has no motion target"))
        return out
    cmp = compare_motion(design, built, MAP_RTOL, reference)
    out.append(check("module_map", cmp["ok"], cmp["worst"], cmp["limit"],
                     f"largest port-distance difference (design units, at {cmp['port']}) "
                     f"between the design's and the rebuilt network's motion; both "
                     f"{cmp['status']}"))
    thickness = measured["thickness"] or s.thickness
    out.append(_screws_close(edges, layer, s, thickness))
    # a chain past float64's drive resolution: steps up to the clearance are accepted there and
    # the gap required grows by the excess
    fine = fine_motion(built, m, scale, 0.25 * s.clearance, floor=s.clearance,
                       traced=cmp["trajectory"])
    head = int(math.ceil(s.screw.head_height / thickness - HEAD_LAYERS_SLACK))
    gaps = same_layer_gaps(edges, layer, fine.positions, measured["widths"],
                           columns=_columns(edges, layer, head, 0.5 * s.screw.head_diameter,
                                            0.5 * (measured["spacer"] or s.spacer_diameter)))
    need = 0.5 * s.clearance + max(0.0, fine.max_step - 0.25 * s.clearance)
    worst_gap = min(gaps["bar_gap"], gaps["joint_gap"], gaps["screw_gap"], gaps["column_gap"])
    report["motion"] = {"samples": fine.n_samples, "max_node_step_mm": fine.max_step,
                        **{k: (None if isinstance(v, float) and math.isinf(v) else v)
                           for k, v in gaps.items()}}
    out.append(check(
        "same_layer", worst_gap >= need, None if math.isinf(worst_gap) else round(worst_gap, 6),
        need, f"smallest gap (mm) between parts sharing a layer over {fine.n_samples} samples "
              f"(bar to bar {_mm(gaps['bar_gap'])}, two bars on one joint "
              f"{_mm(gaps['joint_gap'])}, bar to screw {_mm(gaps['screw_gap'])}, screw to screw "
              f"{_mm(gaps['column_gap'])})" + _closest(gaps, need)))
    return out


def _closest(gaps: dict, need: float) -> str:
    """Where the parts come too close, named (empty when nothing does)."""
    if gaps["joint_gap"] < need:
        return f"; bars {gaps['joint_pair'][0]} and {gaps['joint_pair'][1]} share a joint and " \
               "a layer: their round ends overlap"
    if gaps["bar_gap"] < need:
        return f"; bars {gaps['bar_pair'][0]} and {gaps['bar_pair'][1]} at sample " \
               f"{gaps['sample']}"
    if gaps["screw_gap"] < need:
        return f"; bar {gaps['screw_at'][0]} and the screw at joint {gaps['screw_at'][1]}"
    if gaps["column_gap"] < need:
        return f"; the screws at joints {gaps['column_pair'][0]} and {gaps['column_pair'][1]}"
    return ""


def _columns(edges, layer, head_slots: int, radius: float, ring_radius: float) -> dict:
    """The screw at every joint of two or more bars: its stack's layers, and its heads
    ``head_slots`` layers above and below (see :func:`fabkit.check.clearance.same_layer_gaps`)."""
    spans: dict[int, list[int]] = {}
    for b, (i, j) in enumerate(edges.tolist()):
        for v in (i, j):
            spans.setdefault(v, []).append(int(layer[b]))
    joints = sorted(j for j, zs in spans.items() if len(zs) >= 2)
    lo = np.array([min(spans[j]) for j in joints], dtype=np.int64)
    hi = np.array([max(spans[j]) for j in joints], dtype=np.int64)
    return {"joints": np.array(joints, dtype=np.int64), "low": lo - head_slots,
            "high": hi + head_slots, "inner_low": lo, "inner_high": hi, "radius": radius,
            "inner_radius": ring_radius}


def _screws_close(edges, layer, s, thickness: float) -> Check:
    """Every joint's stack (its layers read back) is closed by a fastener of the catalogue on
    the thickest sheets the thickness tolerance allows.

    The catalogue (:func:`fabkit.settings.fasteners.fit_fastener`: the posts, extensions and shims as
    sold) is asked afresh for the stack read back; the fasteners the writer chose are not
    consulted (the DXF holds none)."""
    spans: dict[int, list[int]] = {}
    for b, (i, j) in enumerate(edges.tolist()):
        for v in (i, j):
            spans.setdefault(v, []).append(int(layer[b]))
    worst, where, problem = math.inf, None, ""
    for joint, zs in sorted(spans.items()):
        if len(zs) < 2:
            continue
        n = max(zs) - min(zs) + 1
        try:
            fit = fit_fastener(s.screw, n, thickness, s.thickness_tolerance)
        except FabricationError as exc:
            problem = f"joint {joint}: {exc}"
            worst, where = -math.inf, joint
            break
        if fit.play_min < worst:
            worst, where = fit.play_min, joint
    ok = not problem and worst >= -MM_SLACK
    return check("screws_close", ok, None if math.isinf(worst) else round(worst, 6), 0.0,
                 problem or f"least axial play (mm) with washers on sheets of "
                 f"{thickness:g} + {s.thickness_tolerance:g} mm, at joint {where}")


def _sheet_set(path: Path, source: ReadBack) -> list[Path]:
    """The sheets of one export: ``laser_sheet<k>.dxf`` beside the given one (or the
    ``laser_sheet<k>_uncompensated.dxf`` set), else itself; listed through ``source``."""
    m = re.fullmatch(r"(.*sheet)(\d+)(_uncompensated)?\.dxf", path.name, flags=re.IGNORECASE)
    if not m:
        return [path]
    # only the numbered siblings: a stray laser_sheet_notes.dxf is not a sheet of the kit
    pattern = re.compile(re.escape(m.group(1)) + r"(\d+)" + re.escape(m.group(3) or "")
                         + r"\.dxf", flags=re.IGNORECASE)
    found = [(int(q.group(1)), p) for p in source.siblings(path)
             if (q := pattern.fullmatch(p.name))]
    return [p for _, p in sorted(found)] or [path]


#: The first bytes of a binary DXF file.
_BINARY_DXF = b"AutoCAD Binary DXF\r\n\x1a\x00"


def parse_dxf(data: bytes):
    """An ezdxf document from a DXF file's bytes (already read, and its entities counted).

    ezdxf's reader takes two thirds of the time of its recover mode on a well-formed file; a
    file it refuses (and a binary DXF) is read again by recover, which repairs what it can.

    Raises
    ------
    Exception
        Whatever ezdxf raises for a file that is not a DXF at all (several types).
    """
    import ezdxf
    from ezdxf import recover
    from ezdxf.filemanagement import dxf_stream_info

    if not data.startswith(_BINARY_DXF):
        try:
            encoding = dxf_stream_info(io.StringIO(data.decode("utf-8", "ignore"))).encoding
            return ezdxf.read(io.StringIO(data.decode(encoding, "surrogateescape")))
        except MemoryError:
            raise
        except Exception:  # noqa: BLE001 - ezdxf raises several types: recover tries next
            pass
    return recover.read(io.BytesIO(data))[0]


def check_file(path, design=None, settings=None, *, motion=None, folder=None) -> dict:
    """As-built check of a laser-cut DXF (and the other sheets of its export beside it).

    Parameters
    ----------
    path : str or pathlib.Path
        One ``laser_sheet<k>.dxf``; the sibling sheets are read too.
    design : Design, optional
    settings : dict, optional
    motion : TracedMotion, optional
        See :func:`check_documents`.
    folder : OutputFolder or ReadBack, optional
        Where the sheets are read from (:func:`fabkit.check.check_file`): through the held
        folder of an export that has just written them, or by path when None.

    Returns
    -------
    dict
        See :func:`check_documents`. A sheet of fabkit's own (read through ``folder``) that
        ezdxf cannot parse is a failed ``readable`` check.

    Raises
    ------
    InputFileError
        A missing sheet; ``kind="bounds"``: a sheet of more entities than
        :data:`fabkit.io.formats.MAX_DXF_ENTITIES` (counted before ezdxf reads it);
        ``kind="damaged"``: a sheet given by path (a user's file) that ezdxf cannot parse,
        named in one line.
    """
    source = ReadBack.of(folder)
    path = Path(path)
    source.size(path)  # the sheet named is there, whatever its siblings
    sheets = _sheet_set(path, source)
    require_files(sheets, source)  # every sibling sheet counted before any is read
    data = {p: source.read(p, MAX_BYTES) for p in sheets}
    for p, raw in data.items():  # and the entities of every sheet before ezdxf reads one
        refuse_dxf_entities(raw, p)
    docs, checks = {}, []
    for p, raw in data.items():
        try:
            docs[p.name] = parse_dxf(raw)
        except MemoryError:
            raise
        except Exception as exc:  # noqa: BLE001 - not a DXF at all
            why = " ".join((str(exc) or type(exc).__name__).split())[:200]
            if not source.own:  # a user's file: a damaged input, not a failed check
                raise damaged(p, f"not a DXF file ezdxf can read ({why})") from None
            checks.append(check("readable", False, p.name, None, f"{p.name}: {why}"))
    if checks:
        return finish({"files": [str(p) for p in sheets]}, checks, _expected(design),
                      "a sheet of the kit cannot be read")
    return _check_docs(docs, design, settings, motion)
