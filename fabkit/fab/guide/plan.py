"""What goes on which page of an assembly guide (pure data, nothing drawn).

A chain's modules are grouped two to a page; a network that is not a chain is one group. Every
screw (joint) is closed on exactly one page: the last page whose bars reach it. That page draws
and lists the whole stack, bars of earlier pages included (named with their page); every other
page that reaches the joint says which page closes it. Hardware is counted per page from the
bill of materials (the screws, washers and spacer rings of the joints the page closes), and
named as the bill of materials names it.

The motion test reads the drive's port (its two joints), where it starts and where the design
takes it, in mm, and what every other port does along the traced motion.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from ...errors import FabkitError, FabricationError
from ...kinematics import place, plan_construction
from ...numerics import MM_SLACK
from .flow import Block, block_height, flow
from .function import design_inputs, function_blocks, FunctionTest, function_test, port_key
from .verdict import verdict_rows

__all__ = ["MODULES_PER_PAGE", "GuidePlan", "GuidePage", "MotionTest", "Sheet", "guide_plan",
           "screw_part", "page_groups", "frame_caption", "MEASURABLE_MM", "bar_name",
           "stack_row", "ROOM_PT", "PICTURES_MIN_PT", "motion_sheets",
           "motion_words", "sheet_advice"]

#: Modules of a chain drawn on one page (two modules of the paper's chain are about 175 mm
#: wide: true size on A4).
MODULES_PER_PAGE = 2
#: A port counts as having followed the drive when it moved at least this share of the drive's
#: own change.
FOLLOW_SHARE = 0.5
#: Ports half way within this share of the motion's samples of each other move together.
TOGETHER_SHARE = 0.05
#: Ports whose half-way samples have at least this rank correlation with their order along the
#: chain follow one after another.
IN_ORDER_RHO = 0.8
#: The motion test's samples run geometrically to this fraction of the way left to the target
#: (a super-stable chain's front crosses a module each time the way left shrinks fourfold).
GEOMETRIC_END = 1e-12
#: A placement by construction stands for the traced motion when every port ends within this
#: fraction of the drive's start value of the traced end state.
AGREE_RTOL = 1e-6
#: Below this distance (mm) a maker cannot tell where the drive is (a caliper's resolution).
MEASURABLE_MM = 0.01
#: Height (points) for the text of each kind of page, from where its text begins (below the
#: overview's drawing, the method's screw diagram, a module page's drawing; below the title of
#: a page that continues one) to the bottom margin (0.45 in); :mod:`.pages` draws to these.
ROOM_PT = {"overview": 370.0, "method": 506.0, "module": 283.0, "motion": 763.0,
           "function": 763.0, "continued": 750.0}
#: Size of a module page's drawing (points: the page's width by half its height).
DRAWING_PT = (7.17 * 72.0, 0.5 * 11.69 * 72.0)
#: A page's drawing keeps at least this many points per mm: at 1.0 every 7 pt label of the
#: and-gate's parts finds a free place beside its bar (at 0.6, the whole gate on one page,
#: 124 of them found none).
MIN_PT_PER_MM = 1.0
#: The motion test's pictures need at least this height (points) below its text, else they
#: get a page of their own.
PICTURES_MIN_PT = 300.0


@dataclass(frozen=True)
class GuidePage:
    """One page of modules.

    Attributes
    ----------
    number : int
        Page number in the PDF.
    modules : tuple of int
        Modules drawn (1-based; empty when the network is not a chain).
    bars : tuple of int
        Bars of this page's modules.
    closes : tuple of int
        Joints whose screw is closed on this page (their whole stack is listed here).
    ghosts : tuple of int
        Bars of other pages threaded onto a joint this page closes.
    open_joints : dict
        Joint → the page that closes it, for joints of this page's bars closed elsewhere.
    bar_page : dict
        Bar → its page, for this page's bars and ghosts.
    hardware : list of (str, int)
        Part name and count for the joints this page closes.
    part : (int, int)
        Which part of a network that is not a chain this page draws, of how many.
    joins : dict
        Earlier page → the joints this page's bars share with it (where this page's part is
        joined to the part built so far).
    parent : int or None
        The page this one grows from in the build order (None for the first): the page
        before it, or, where the network branches, the page it branches from.
    previous : int or None
        The module page before this one (None for the first).
    """

    number: int
    modules: tuple
    bars: tuple
    closes: tuple
    ghosts: tuple
    open_joints: dict
    bar_page: dict
    hardware: list
    part: tuple = (1, 1)
    joins: dict = field(default_factory=dict)
    parent: int | None = None
    previous: int | None = None


@dataclass(frozen=True)
class Sheet:
    """One page of the PDF.

    Attributes
    ----------
    number : int
    kind : str
        ``"overview"``, ``"method"``, ``"module"``, ``"motion"`` or ``"pictures"`` (the motion
        test's pictures on a page of their own).
    blocks : tuple of Block
        The text the page sets (:mod:`.flow`).
    first : bool
        The first page of its kind (or of its module page); False for a page that continues
        the lists of the one before.
    page : GuidePage or None
        The module page it belongs to.
    pictures : bool
        The motion test's pictures are drawn on this page.
    """

    number: int
    kind: str
    blocks: tuple
    first: bool = True
    page: GuidePage | None = None
    pictures: bool = False


@dataclass(frozen=True)
class MotionTest:
    """The numbers and pictures of the motion test.

    Attributes
    ----------
    drive : str
        The port pushed (``d1``).
    joints : (int, int)
        Its two joints.
    start_mm, end_mm : float
        Centre-to-centre distance at the start and where the design takes it.
    ports : list of (str, float, float, int)
        Every port in order: name, start and end (mm), and the sample at which it has made half
        its change (-1 when it moves less than :data:`FOLLOW_SHARE` of the drive's change).
    order : str
        How the ports follow: ``"forward"`` (one after another from the drive's end: the
        samples at which they are half way rise along the chain, rank correlation at least
        :data:`IN_ORDER_RHO`), ``"backward"`` (from the far end), ``"together"`` (all within
        :data:`TOGETHER_SHARE` of the motion), ``"mixed"`` or ``"none"`` (no port follows).
    drive_mm : numpy.ndarray, shape (K,)
        The drive at each sample.
    positions : numpy.ndarray, shape (K, N, 2)
        Joint positions (mm) at each sample, the drive's first joint fixed.
    moved : numpy.ndarray of int, shape (K,)
        Ports other than the drive past half their change at each sample.
    frames : tuple of int
        Samples worth drawing: the start, the collapse a quarter, half and three quarters of
        the way, and the end.
    """

    drive: str
    joints: tuple
    start_mm: float
    end_mm: float
    ports: list
    order: str
    drive_mm: np.ndarray = field(repr=False)
    positions: np.ndarray = field(repr=False)
    moved: np.ndarray = field(repr=False)
    frames: tuple = ()

    @property
    def followers(self) -> list:
        """Ports other than the drive that moved at least :data:`FOLLOW_SHARE` of its change."""
        return [p for p in self.ports if p[0] != self.drive and p[3] >= 0]


@dataclass(frozen=True)
class GuidePlan:
    """Everything the guide says, page by page.

    Attributes
    ----------
    name : str
    pages : list of GuidePage
        The module pages in order.
    first_module_page : int
        PDF page number of the first module page (after the overview and the method).
    closing_page : dict
        Joint → the page that closes it.
    size_mm : (float, float)
        Width and height of the kit as built (bars, screw heads included) at the start.
    motion_size_mm : (float, float)
        The same over the whole motion (the space the test needs).
    totals : list of (str, int)
        Every part of the kit and how many (from the bill of materials).
    motion : MotionTest or None
    sheets : list of Sheet
        Every page of the PDF in order, with the text each sets.
    function : FunctionTest or None
        The functional test of a design with more than one input.
    verdict : dict or None
        The verdict the first page heads with (None: not judged).
    """

    name: str
    pages: list
    first_module_page: int
    closing_page: dict
    size_mm: tuple
    motion_size_mm: tuple
    totals: list
    motion: MotionTest | None
    sheets: list = field(default_factory=list)
    function: FunctionTest | None = None
    verdict: dict | None = None

    @property
    def n_pages(self) -> int:
        """Pages in the PDF: overview, method, module pages and the motion test, each with the
        pages that continue its lists."""
        return len(self.sheets)


def page_groups(network, per_page: int = MODULES_PER_PAGE, *, scale: float | None = None,
                radius: float = 0.0) -> list:
    """Bar index groups, one per page, and the modules of each.

    A chain's modules go ``per_page`` to a page. A network that is not a chain is one page
    when its drawing keeps at least :data:`MIN_PT_PER_MM` on the page (with ``scale``, mm per
    design unit, and ``radius``, half the bar width, given); else it is cut in two across its
    longer side, again and again, until every part does (a part of the network per page).

    Returns
    -------
    list of (numpy.ndarray, tuple of int)
        Bars and 1-based module numbers of each page (no modules for a network that is not a
        chain).
    """
    layout = network.assembly
    n_e = network.n_edges
    if layout is not None:
        counts = [m.n_edges for m, _, _ in layout.copies]
        if sum(counts) == n_e:
            offsets = np.concatenate([[0], np.cumsum(counts)])
            k = len(counts)
            return [(np.arange(offsets[c], offsets[min(c + per_page, k)]),
                     tuple(range(c + 1, min(c + per_page, k) + 1)))
                    for c in range(0, k, per_page)]
    if scale is None:
        return [(np.arange(n_e), ())]
    x = np.asarray(network.nodes, dtype=np.float64) * float(scale)
    edges = np.asarray(network.edges)
    mid = 0.5 * (x[edges[:, 0]] + x[edges[:, 1]])

    def legible(bars) -> bool:
        p = x[edges[bars]].reshape(-1, 2)
        span = p.max(axis=0) - p.min(axis=0) + 6 * radius
        return min(DRAWING_PT[0] / span[0], DRAWING_PT[1] / span[1]) >= MIN_PT_PER_MM

    def cut(bars) -> list:
        if len(bars) <= 2 or legible(bars):
            return [bars]
        p = mid[bars]
        axis = int(np.argmax(np.ptp(p, axis=0)))
        order = bars[np.argsort(p[:, axis], kind="stable")]
        half = len(order) // 2
        return cut(np.sort(order[:half])) + cut(np.sort(order[half:]))

    return [(g, ()) for g in cut(np.arange(n_e))]


def build_order(groups: list, edges: np.ndarray, joints, start: int) -> tuple:
    """The order in which the parts of a network are built, and the part each grows from.

    The parts (pages) are nodes of a graph whose links are the screws two parts share. The
    build walks it depth first from the part that holds ``start`` (the first input's joint):
    along one arm to its end (from a part, on to the neighbour whose bars are nearest in number:
    a chain numbers its bars module by module), then back to the nearest part with an arm not
    yet built (a branch), so every part is joined to a part already built. A chain's pages are
    already in that order.

    Parameters
    ----------
    groups : list of (numpy.ndarray, tuple)
        Bars and modules of each part (:func:`page_groups`).
    edges : numpy.ndarray, shape (E, 2)
    joints : set of int
        The joints that take a screw.
    start : int
        The joint the build starts from.

    Returns
    -------
    order : list of int
        Indices into ``groups`` in build order.
    parent : dict
        Index → the index of the part it grows from (absent for the first).
    """
    sets = [{int(j) for j in edges[bars].ravel() if int(j) in joints} for bars, _ in groups]
    mid = [float(np.median(bars)) if len(bars) else 0.0 for bars, _ in groups]
    first = next((k for k, js in enumerate(sets) if start in js), 0)
    order, parent, seen, stack = [], {}, set(), [(first, None)]
    while stack:
        k, up = stack.pop()
        if k in seen:
            continue
        seen.add(k)
        order.append(k)
        if up is not None:
            parent[k] = up
        # bars are numbered module by module along each chain: the neighbour whose bars are
        # nearest in number continues the same chain, and is taken next (pushed last)
        nxt = [m for m in range(len(groups)) if m not in seen and sets[k] & sets[m]]
        nxt.sort(key=lambda m: (abs(mid[m] - mid[k]), m), reverse=True)
        stack += [(m, k) for m in nxt]
    order += [k for k in range(len(groups)) if k not in seen]  # parts that share no screw
    return order, parent


def screw_part(bom: dict, length: float) -> str:
    """The name of the screw with post ``length`` as the bill of materials names it."""
    for entry in bom.get("screws", []):
        if abs(float(entry.get("post_length_mm", -1)) - float(length)) <= MM_SLACK:
            name = str(entry.get("description") or entry.get("name", "screw"))
            return f"{name}, post {length:g} mm"
    return f"screw, post {length:g} mm"


def _washer_part(bom: dict, name: str | None = None) -> str:
    """A shim or washer as the bill of materials names it (the thickest kind by default)."""
    w = bom.get("washers") or {}
    name = name or w.get("name")
    if name:
        return f"shim ring {name}" if str(name).startswith("DIN 988") else str(name)
    return (f"washer {w.get('inner_diameter_mm', 0):g} mm hole, {w.get('thickness_mm', 0):g} mm"
            " thick")


def _spacer_part(bom: dict) -> str:
    sp = bom.get("spacer_rings") or {}
    return (f"spacer ring {sp.get('outer_diameter_mm', 0):g} mm (cut from the sheet, "
            f"{sp.get('thickness_mm', 0):g} mm)")


def fastener_part(bom: dict, row: dict) -> str:
    """The fastener of one BOM joint row as the bill of materials names it: the screw's name
    and its post (and extensions), or a clevis pin; shim washers are counted apart."""
    base = re.sub(r" \+ [\d x.+ ]+ mm shims$| \+ \d+ washers?$", "",
                  str(row.get("fastener") or ""))
    if not base:
        return screw_part(bom, float(row["screw_length_mm"]))
    if row.get("fastener_kind") == "clevis pin":
        return base
    screw = (bom.get("screws") or [{}])[0]
    name = str(screw.get("description") or screw.get("name", "Chicago screw"))
    return f"{name}, {base}"


def _natural(text: str) -> tuple:
    """Sort key reading the numbers in a text as numbers ("post 7 mm" before "post 10 mm")."""
    return tuple((0, float(p), "") if re.fullmatch(r"\d+(\.\d+)?", p) else (1, 0.0, p)
                 for p in re.split(r"(\d+(?:\.\d+)?)", text) if p)


def _hardware(bom: dict, joints) -> list:
    """Part name and count for a set of BOM joint rows."""
    fasteners: dict[str, int] = {}
    shims: dict[str, int] = {}
    spacers = 0
    for j in joints:
        part = fastener_part(bom, j)
        fasteners[part] = fasteners.get(part, 0) + 1
        kinds = j.get("shims")
        if kinds is None and j.get("washers"):  # a bill of materials without shim kinds
            kinds = [[None, 0, int(j["washers"])]]
        for name, _, n in kinds or []:
            key = _washer_part(bom, name)
            shims[key] = shims.get(key, 0) + int(n)
        spacers += int(j.get("spacers", 0))
    out = sorted(fasteners.items(), key=lambda kv: _natural(kv[0]))
    out += [(name, n) for name, n in shims.items() if n]
    if spacers:
        out.append((_spacer_part(bom), spacers))
    return out


def sheet_advice(bom: dict) -> str:
    """What to change for sheet thinner or thicker than the kit was planned for."""
    st = bom.get("settings") or {}
    t, tol = float(st.get("thickness", 3.0)), float(st.get("thickness_tolerance", 0.0))
    w = bom.get("washers") or {}
    wt = float(w.get("thickness_mm", 0.5) or 0.5)
    name = _washer_part(bom)
    deepest = max((len(j.get("bottom_to_top", [])) for j in bom.get("joints", [])), default=1)
    play = float((bom.get("axial_play") or {}).get("nominal_max_mm", 0.5))
    return (f"The posts and shims are counted for {t:g} mm sheet: a stack of n layers is "
            f"n × {t:g} mm, and the shims leave at most {play:.1f} mm of play on it. Measure "
            "your sheet with calipers. Every 0.1 mm a sheet is thicker makes a stack of n "
            f"layers n × 0.1 mm taller (your deepest stack, {deepest} layers, "
            f"{0.1 * deepest:.1f} mm): take one {wt:g} mm shim ({name}) off for every {wt:g} "
            f"mm a stack grows; on thinner sheet put one more on for every {wt:g} mm it "
            f"shrinks (the spares are in the order). The posts close on sheets up to "
            f"{t + tol:g} mm; for thicker sheet, export again with laser.thickness set to "
            "what you measured.")


def _totals(bom: dict) -> list:
    out = [(f"{s['size_mm'][0]:g} × {s['size_mm'][1]:g} mm sheet, "
            f"{bom['settings']['thickness']:g} mm", 1) for s in bom.get("sheets", [])]
    merged: dict[str, int] = {}
    for name, n in out:
        merged[name] = merged.get(name, 0) + n
    out = [(f"acrylic {name}", n) for name, n in merged.items()]
    out.append(("bars (cut from the sheets)", len(bom.get("bars", []))))
    out += [(screw_part(bom, s["post_length_mm"]), int(s["count"])) for s in bom.get("screws", [])]
    w = bom.get("washers") or {}
    if w.get("kinds"):
        out += [(_washer_part(bom, k["name"]), int(k["count"])) for k in w["kinds"]]
    elif w.get("count"):
        out.append((_washer_part(bom), int(w["count"])))
    sp = bom.get("spacer_rings") or {}
    if sp.get("count"):
        out.append((_spacer_part(bom), int(sp["count"])))
    return out


def _dense_motion(plan):
    """Drive values (design units) and positions along the motion, spaced evenly and
    geometrically towards the target (a sequential collapse happens close to it), placed by
    construction; None when the network cannot be placed so or the placement leaves the traced
    motion (then the traced samples are used)."""
    net, motion = plan.design.network, plan.design.motion
    start, to = float(net.port_distance(motion.drive)), float(motion.to)
    q = np.unique(np.concatenate([np.linspace(0.0, 1.0, 41),
                                  np.geomspace(GEOMETRIC_END, 1.0, 97)]))[::-1]
    values = to + (start - to) * q
    try:
        x, margin, _ = place(plan_construction(net, net.port(motion.drive)), values)
    except (FabkitError, ValueError):
        return None
    if not np.all(margin > 0):
        return None
    traced = np.asarray(plan.sweep.positions)[-1] / plan.settings.scale
    for name in net.ports:  # the same end state as the traced motion
        if abs(float(net.port_distance(name, x[-1]) - net.port_distance(name, traced))) > \
                AGREE_RTOL * max(1.0, abs(start)):
            return None
    return values, x


def _order(halves: list, samples: int) -> str:
    """How ports that follow the drive do so, from the sample at which each is half way, in
    port order (see :attr:`MotionTest.order`)."""
    if not halves:
        return "none"
    h = np.asarray(halves, dtype=np.float64)
    if len(h) == 1:
        return "forward"
    if np.ptp(h) <= TOGETHER_SHARE * samples:
        return "together"
    rank = np.argsort(np.argsort(h, kind="stable"), kind="stable").astype(np.float64)
    rho = float(np.corrcoef(np.arange(len(h)), rank)[0, 1])
    return "forward" if rho >= IN_ORDER_RHO else ("backward" if rho <= -IN_ORDER_RHO
                                                  else "mixed")


def _motion_test(plan) -> MotionTest | None:
    net, motion = plan.design.network, plan.design.motion
    sweep = np.asarray(plan.sweep.positions, dtype=np.float64)
    if motion.to is None or sweep.ndim != 3 or sweep.shape[0] < 2 or motion.drive not in net.ports:
        return None
    scale = plan.settings.scale
    dense = _dense_motion(plan)
    x = dense[1] * scale if dense is not None else sweep
    a, b = net.port(motion.drive)
    drive = np.linalg.norm(x[:, a] - x[:, b], axis=1)
    change = abs(float(drive[-1] - drive[0]))
    ports, past = [], np.zeros(x.shape[0], dtype=np.int64)
    for name in sorted(net.ports, key=port_key):
        i, j = net.port(name)
        d = np.linalg.norm(x[:, i] - x[:, j], axis=1)
        moved = np.abs(d - d[0])
        total = float(moved[-1])
        half = -1
        if change > 0 and total >= FOLLOW_SHARE * change:
            half = int(np.argmax(moved >= 0.5 * total))
            if name != motion.drive:
                past += moved >= 0.5 * total
        ports.append((name, float(d[0]), float(d[-1]), half))
    order = _order([p[3] for p in ports if p[0] != motion.drive and p[3] >= 0], x.shape[0])
    last = x.shape[0] - 1
    frames = {0, last}
    if past[-1] >= 2:
        frames |= {int(np.argmax(past >= f * past[-1])) for f in (0.25, 0.5, 0.75)}
    else:  # nothing travels: even steps of the drive
        frames |= {int(np.argmin(np.abs(drive - (drive[0] + f * (drive[-1] - drive[0])))))
                   for f in (1 / 3, 2 / 3)}
    return MotionTest(motion.drive, (int(a), int(b)), float(drive[0]), float(motion.to) * scale,
                      ports, order, drive, x, past, tuple(sorted(frames)))


def frame_caption(m: MotionTest, f: int) -> str:
    """What a picture of the motion test at sample ``f`` shows, in words."""
    away = abs(float(m.drive_mm[f]) - m.end_mm)
    if f == 0:
        when = "start"
    elif f == m.drive_mm.shape[0] - 1:
        when = "end"
    elif away < MEASURABLE_MM:
        when = f"within {MEASURABLE_MM:g} mm of the end"
    else:
        when = f"{away:.2f} mm before the end"
    return (f"{m.drive} = {float(m.drive_mm[f]):.2f} mm ({when}): {int(m.moved[f])} of "
            f"{len(m.followers)} following ports past half way")


def _size(x: np.ndarray, edges: np.ndarray, margin: float) -> tuple:
    used = np.unique(edges)
    pts = x[..., used, :].reshape(-1, 2)
    span = pts.max(axis=0) - pts.min(axis=0) + 2 * margin
    return float(span[0]), float(span[1])


def bar_name(bar: int, layer: int) -> str:
    """A bar as it is engraved (the start of its engraving ``B<bar> L<layer> J<i>-<j>``)."""
    return f"B{bar} L{layer}"


def stack_row(js, page: GuidePage, fastener: str) -> str:
    """One screw's stack, bottom to top, as a builder reads it on the page that closes it:
    ``J2: B15 L0 / B5 L1 (p3) / S2.2 / B10 L3 | post 25 mm + 2 washers``."""
    at = dict(zip(js.layers, js.bars))
    seq = []
    for z in range(min(js.layers), max(js.layers) + 1):
        if z not in at:
            seq.append(f"S{js.joint}.{z}")
        elif page.bar_page.get(at[z], page.number) != page.number:
            seq.append(f"{bar_name(at[z], z)} (p{page.bar_page[at[z]]})")
        else:
            seq.append(bar_name(at[z], z))
    return f"J{js.joint}: {' / '.join(seq)}  | {fastener}"


def modules_text(page: GuidePage) -> str:
    """The modules a page builds, in words: ``"modules 3-7"``, ``"module 2"``, or the part of
    a network without modules.

    Parameters
    ----------
    page : GuidePage

    Returns
    -------
    str
    """
    if not page.modules:
        return ("the whole network" if page.part[1] <= 1 else
                f"part {page.part[0]} of {page.part[1]} of the network")
    a, b = page.modules[0], page.modules[-1]
    return f"modules {a}-{b}" if b > a else f"module {a}"


def build_words(page: GuidePage) -> str:
    """Where a page stands in the build order, in words: what it starts from, and at which
    screws its part joins the part built on earlier pages."""
    if page.parent is None and page.previous is None:
        return "Build order: start here; this page's part is the first."
    if page.parent is None:  # a part that shares no screw with another
        return "Build order: a part of its own: it shares no screw with the other pages."
    joins = "; ".join(f"p{q} at {', '.join(f'J{j}' for j in js)}"
                      for q, js in page.joins.items())
    how = (f"continue from page {page.parent}" if page.parent == page.previous else
           f"a branch: it grows from page {page.parent}, not from page {page.previous}")
    return f"Build order: {how}. Join this part to the part built so far: {joins}."


def _module_blocks(page: GuidePage, stacks: dict, settings) -> list:
    rows = []
    for j in page.closes:
        js = stacks[j]
        fastener = (js.fastener.describe() if js.fastener is not None
                    else f"post {js.screw_length:g} mm")
        rows.append(stack_row(js, page, fastener))
    blocks = [Block(None, (build_words(page),), style="body"),
              Block("Stacks of the screws this page closes, bottom to top", tuple(rows))]
    if page.open_joints:
        later = ", ".join(f"J{j}→p{q}" for j, q in sorted(page.open_joints.items()))
        blocks.append(Block(None, (f"Left loose on this page (closed later): {later}",),
                            style="body"))
    blocks.append(Block("Hardware for this page:",
                        tuple(f"{n:>4} × {name}" for name, n in page.hardware)))
    return blocks


def _overview_blocks(pages: list, totals: list, head: list) -> list:
    joins = []
    for p in pages:
        later: dict = {}
        for j, q in sorted(p.open_joints.items()):
            later.setdefault(q, []).append(f"J{j}")
        how = "; ".join(f"leaves {', '.join(v)} loose for p{q}" for q, v in sorted(later.items()))
        grows = (f"; grows from p{p.parent}" if p.parent is not None and p.parent != p.previous
                 else "")
        joins.append(f"p{p.number}: {modules_text(p)}{grows}" + (f"; {how}" if how else ""))
    return [Block("What this kit will do (the export's verdict)", tuple(head), style="body"),
            Block("How the pages join" if len(pages) > 1 else "Pages", tuple(joins),
                  columns=2 if len(joins) > 8 else 1),
            Block("Kit contents (as laser_bom.md lists them)",
                  tuple(f"{n:>4} × {name}" for name, n in totals))]


def _order_text(pages: list) -> str:
    """How to work through the module pages: their order follows the network (its arms, then
    its branches), each page saying what it joins."""
    first, last = pages[0].number, pages[-1].number
    branches = [p for p in pages if p.parent is not None and p.parent != p.previous]
    if branches:
        where = "; ".join(f"page {p.number} starts a branch from page {p.parent}"
                          for p in branches)
        route = (f"Work from page {first} to page {last} in page order: the order follows the "
                 f"network, one arm to its end, then back to where a branch leaves it ({where}). "
                 "Each page says, at its top, which earlier page its part joins and at which "
                 "screws.")
    else:
        route = (f"Work from page {first} to page {last} in page order: each page continues "
                 "the part of the page before it, and says at its top at which screws.")
    return (route + " Each page closes the screws it lists (a page with more screws than fit "
            "continues on the next). A joint marked '→p<k>' belongs to a later page: leave the "
            "bars that reach it loose (do not thread them) until page k, which draws them "
            "hatched and threads them into its stack. Keep the finished part flat on the table "
            "and slide it along as it grows; support any part that hangs over the edge. Do not "
            "lift it by one end: the modules fold.")


def _method_blocks(pages: list, settings, tests: dict, sheet_text: str) -> list:
    first = pages[0].number
    if len(pages) > 1:
        order = _order_text(pages)
    else:
        order = (f"Page {first} draws every bar and lists every screw: lay the bars out as "
                 "drawn, then close the screws one by one.")
    motion = f" Page {tests['motion']} is the motion test." if tests.get("motion") else ""
    if tests.get("function"):
        motion += f" Page {tests['function']} tests each input alone and all together."
    sections = [
        ("BEFORE YOU START",
         "Cut the test coupon first (laser_coupon.md). Cut the sheets; check that the 100 mm "
         "reference square measures 100 mm. Peel the protective film. Every bar is engraved "
         "B<bar> L<layer> J<joint>-<joint> (short bars B<bar> L<layer>), every spacer ring "
         "S<joint>.<layer>: sort the bars by the page that draws them, and within a page by "
         "layer."),
        ("EVERY SCREW",
         "Stand the post (the barrel) upright, head down. Thread the parts in the order the "
         "page lists them, bottom first: bars by layer, and a spacer ring (S<joint>.<layer>, "
         f"{settings.spacer_diameter:g} mm, cut from the sheet) where the screw passes a layer "
         "with no bar. Put the shims the page lists on top, then screw the screw in from "
         "above until it is snug: the bars must still turn freely."),
        ("YOUR SHEET", sheet_text),
        ("BUILD ORDER, PAGE BY PAGE" if len(pages) > 1 else "ORDER", order),
        ("CHECK AS YOU GO",
         "After each page, the part built should move freely by hand without forcing; a bar "
         "that rubs is usually a screw that is too tight or a bar on the wrong layer (check "
         f"its engraved L<layer>).{motion}"),
    ]
    blocks = [Block(head, (text,), style="body") for head, text in sections]
    rows = [f"p{p.number}: {modules_text(p)}, {len(p.bars)} bars, {len(p.closes)} screws"
            for p in pages]
    blocks.append(Block("Pages", tuple(rows), columns=2 if len(rows) > 10 else 1))
    return blocks


def motion_words(m: MotionTest, barrel: float) -> str:
    """What the motion test asks of the maker and what to expect, in words."""
    name = m.drive
    a, b = m.joints
    push = "Push" if m.end_mm < m.start_mm else "Pull"
    together = "together" if m.end_mm < m.start_mm else "apart"
    fol = m.followers
    order = {"forward": f"one after another, starting next to {name} and travelling away "
                        "from it",
             "backward": f"one after another, starting at the far end and travelling towards "
                         f"{name}",
             "together": "all together",
             "mixed": "in the order listed below (not one after another along the chain)",
             "none": "not at all: only the pushed part moves"}[m.order]
    names = [p[0] for p in fol]
    # a long chain's list is shortened: the table below gives every port
    moved = (", ".join(names) if len(names) <= 12 else
             ", ".join(names[:5]) + f", ... ({len(names) - 7} more) ..., " + ", ".join(names[-2:]))
    moved = moved or "none"
    opening = {np.sign(p[2] - p[1]) for p in fol} - {0.0}
    if len(opening) > 1:
        order += "; some open while others close"
    text = (f"{push} joints J{a} and J{b} {together}: their centre-to-centre distance {name} "
            f"goes from {m.start_mm:.1f} mm to {m.end_mm:.1f} mm. Measure it between the "
            f"screw posts: the gap between the posts plus {barrel:g} mm (the post diameter). "
            f"Hold J{a} in place and move J{b} along the line J{a}-J{b}. What you should see: "
            + (f"the ports that follow move {order}. " if len(fol) > 1 else "")
            + f"{len(fol)} of the {len(m.ports) - 1} other ports make at least half of their "
            f"change ({moved}); the table gives where each starts and ends. The pictures "
            "show the kit on its way, to one scale, with the pushed pair in red.")
    if len(fol) > 1 and m.order != "together":
        seq = [p[0] for p in sorted(fol, key=lambda p: p[3])]
        shown = (" → ".join(seq) if len(seq) <= 12 else
                 " → ".join(seq[:5]) + f" → ... ({len(seq) - 7} more) ... → " + " → ".join(seq[-2:]))
        text += f" The order in which they should move: {shown}."
    if len(m.frames) > 2 and m.order in ("forward", "backward") and len(fol) > 1:
        away = abs(m.drive_mm[m.frames[len(m.frames) // 2]] - m.end_mm)
        if away < MEASURABLE_MM:
            text += (f" Half of them move while {name} is within {MEASURABLE_MM:g} mm of "
                     f"{m.end_mm:.1f} mm, closer than you can measure: push steadily to the end "
                     "and watch the collapse run along the chain as you arrive.")
        else:
            text += (f" Half of them have moved once {name} is within {away:.2f} mm of its end:"
                     " go slowly there.")
    return text


def _motion_blocks(m: MotionTest, barrel: float) -> list:
    rows = [f"{p[0]:>4}: {p[1]:7.1f} → {p[2]:7.1f} mm" + (" (pushed)" if p[0] == m.drive else "")
            for p in m.ports]
    return [Block(None, (motion_words(m, barrel),), style="body"),
            Block("Every port, start → end (centre to centre)", tuple(rows),
                  columns=1 if len(rows) <= 9 else (2 if len(rows) <= 20 else 3))]


def motion_sheets(m: MotionTest, barrel: float, number: int) -> list:
    """The pages of the motion test from page ``number`` on: its words and the table of every
    port (continued as long as it runs), then its pictures below the table when at least
    :data:`PICTURES_MIN_PT` is left there, else on a page of their own.

    Parameters
    ----------
    m : MotionTest
    barrel : float
        The post's diameter (mm), to measure the drive between the posts.
    number : int
        Page number of the test's first page.

    Returns
    -------
    list of Sheet
    """
    parts = flow(_motion_blocks(m, barrel), ROOM_PT["motion"], ROOM_PT["continued"])
    room = ROOM_PT["motion"] if len(parts) == 1 else ROOM_PT["continued"]
    own = room - sum(block_height(b) for b in parts[-1]) < PICTURES_MIN_PT
    out = [Sheet(number + k, "motion", tuple(b), k == 0,
                 pictures=not own and k == len(parts) - 1) for k, b in enumerate(parts)]
    if own:
        out.append(Sheet(number + len(parts), "pictures", (), False, pictures=True))
    return out


def _make_pages(groups, parent: dict, starts, edges, stacks: dict, bom: dict) -> tuple:
    """The module pages, their numbers from ``starts`` (groups in build order), and the page
    that closes each joint."""
    bom_joint = {int(j["joint"]): j for j in bom.get("joints", [])}
    page_of_bar = np.empty(edges.shape[0], dtype=np.int64)
    for k, (bars, _) in enumerate(groups):
        page_of_bar[bars] = starts[k]
    closing = {j: int(max(page_of_bar[b] for b in js.bars)) for j, js in stacks.items()}
    pages = []
    for k, (bars, modules) in enumerate(groups):
        number = int(starts[k])
        joints = sorted({int(j) for j in edges[bars].ravel() if int(j) in stacks})
        closes = tuple(j for j in joints if closing[j] == number)
        ghosts = tuple(sorted({int(b) for j in closes for b in stacks[j].bars
                               if page_of_bar[b] != number}))
        open_joints = {j: closing[j] for j in joints if closing[j] != number}
        bar_page = {int(b): number for b in bars}
        bar_page.update({b: int(page_of_bar[b]) for b in ghosts})
        hardware = _hardware(bom, [bom_joint[j] for j in closes if j in bom_joint])
        joins: dict = {}
        for j in joints:  # where this page's part meets the part built on earlier pages
            for b in stacks[j].bars:
                q = int(page_of_bar[b])
                if q < number:
                    joins.setdefault(q, set()).add(j)
        pages.append(GuidePage(number, modules, tuple(int(b) for b in bars), closes,
                               ghosts, open_joints, bar_page, hardware, (k + 1, len(groups)),
                               {q: tuple(sorted(v)) for q, v in sorted(joins.items())},
                               int(starts[parent[k]]) if k in parent else None,
                               int(starts[k - 1]) if k else None))
    return pages, closing


def guide_plan(plan, bom: dict, verdict: dict | None = None) -> GuidePlan:
    """Decide the pages of a laser kit's assembly guide.

    Every list is cut into pages where it runs out of room (:func:`.flow.flow`), so the
    page numbers (a page's own, and those the pages give each other) are decided here,
    before anything is drawn: they are settled by laying the pages out again until they no
    longer change (a number's digits may move a line to the next page). The module pages
    follow the build order (:func:`build_order`); a design with more than one input ends with
    its functional test (:mod:`.function`).

    Parameters
    ----------
    plan : fabkit.fab.laser_plan.LaserPlan
    bom : dict
        Its bill of materials (:func:`fabkit.writers.dxf.bill_of_materials`): the hardware of
        every joint and the names of the parts.
    verdict : dict, optional
        The design's verdict (``level``, ``text``, ``findings``), set at the head of the first
        page (:func:`.verdict.verdict_rows`); None: the guide says it is not judged.

    Returns
    -------
    GuidePlan
    """
    net = plan.design.network
    s = plan.settings
    edges = np.asarray(plan.bars.edges)
    groups = page_groups(net, scale=s.scale, radius=0.5 * s.bar_width)
    stacks = {js.joint: js for js in plan.stacking.joints}
    inputs = design_inputs(plan.design) if plan.design.motion.drive in net.ports else ()
    start = int(net.port(inputs[0])[0]) if inputs else int(edges[0, 0])
    order, parent = build_order(groups, edges, set(stacks), start)
    groups = [groups[k] for k in order]
    parent = {order.index(k): order.index(v) for k, v in parent.items()}
    totals = _totals(bom)
    motion = _motion_test(plan)
    ft = function_test(plan.design, s.scale)
    barrel = s.screw.barrel_diameter
    n_motion = len(motion_sheets(motion, barrel, 0)) if motion is not None else 0
    fblocks = function_blocks(ft, net, barrel) if ft is not None else []
    head = verdict_rows(verdict, plan)
    sheet_text = sheet_advice(bom)
    # pages each part takes: start from one each and lay out until the numbers settle
    n_over, n_method, n_group = 1, 1, [1] * len(groups)
    for _ in range(8):
        first = 1 + n_over + n_method
        starts = np.concatenate([[first], first + np.cumsum(n_group)]).astype(int)
        pages, closing = _make_pages(groups, parent, starts, edges, stacks, bom)
        tests = {"motion": int(starts[-1]) if motion is not None else None,
                 "function": int(starts[-1]) + n_motion if ft is not None else None}
        laid = {"overview": flow(_overview_blocks(pages, totals, head), ROOM_PT["overview"],
                                 ROOM_PT["continued"]),
                "method": flow(_method_blocks(pages, s, tests, sheet_text),
                               ROOM_PT["method"], ROOM_PT["continued"]),
                "module": [flow(_module_blocks(p, stacks, s), ROOM_PT["module"],
                                ROOM_PT["continued"]) for p in pages]}
        counts = (len(laid["overview"]), len(laid["method"]), [len(m) for m in laid["module"]])
        if counts == (n_over, n_method, n_group):
            break
        n_over, n_method, n_group = counts
    else:  # pragma: no cover - numbers a digit longer move at most a few lines, once
        raise FabricationError(f"the pages of {plan.design.name}'s guide did not settle: "
                               "their numbers kept moving lines between pages")
    sheets: list = []

    def add(kind, blocks, first, page=None, pictures=False):
        sheets.append(Sheet(len(sheets) + 1, kind, tuple(blocks), first, page, pictures))

    for kind in ("overview", "method"):
        for k, b in enumerate(laid[kind]):
            add(kind, b, k == 0)
    for p, parts in zip(pages, laid["module"]):
        for k, b in enumerate(parts):
            add("module", b, k == 0, p)
    if motion is not None:
        sheets += motion_sheets(motion, barrel, len(sheets) + 1)
    for k, b in enumerate(flow(fblocks, ROOM_PT["function"], ROOM_PT["continued"])
                          if fblocks else []):
        add("function", b, k == 0)
    margin = 0.5 * max(s.bar_width, s.screw.head_diameter)
    x0 = net.nodes * s.scale
    moving = motion.positions if motion is not None else x0
    return GuidePlan(plan.design.name, pages, int(starts[0]), closing,
                     _size(x0, edges, margin), _size(moving, edges, margin), totals, motion,
                     sheets, ft, verdict)
