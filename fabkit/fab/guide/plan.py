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

from ...numerics import MM_SLACK

__all__ = ["MODULES_PER_PAGE", "GuidePlan", "GuidePage", "MotionTest", "guide_plan",
           "screw_part", "page_groups", "frame_caption", "MEASURABLE_MM"]

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
    """

    number: int
    modules: tuple
    bars: tuple
    closes: tuple
    ghosts: tuple
    open_joints: dict
    bar_page: dict
    hardware: list


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
    """

    name: str
    pages: list
    first_module_page: int
    closing_page: dict
    size_mm: tuple
    motion_size_mm: tuple
    totals: list
    motion: MotionTest | None

    @property
    def n_pages(self) -> int:
        """Pages in the PDF: overview, method, module pages and the motion test."""
        return self.first_module_page - 1 + len(self.pages) + (self.motion is not None)


def page_groups(network, per_page: int = MODULES_PER_PAGE) -> list:
    """Bar index groups, one per page, and the modules of each.

    Returns
    -------
    list of (numpy.ndarray, tuple of int)
        Bars and 1-based module numbers of each page; one group of every bar (no modules)
        when the network is not a chain.
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
    return [(np.arange(n_e), ())]


def screw_part(bom: dict, length: float) -> str:
    """The name of the screw with post ``length`` as the bill of materials names it."""
    for entry in bom.get("screws", []):
        if abs(float(entry.get("post_length_mm", -1)) - float(length)) <= MM_SLACK:
            name = str(entry.get("name", "screw"))
            return name if f"{length:g}" in name else f"{name}, post {length:g} mm"
    return f"screw, post {length:g} mm"


def _washer_part(bom: dict) -> str:
    w = bom.get("washers") or {}
    if w.get("name"):
        return str(w["name"])
    return (f"washer {w.get('inner_diameter_mm', 0):g} mm hole, {w.get('thickness_mm', 0):g} mm"
            " thick")


def _spacer_part(bom: dict) -> str:
    sp = bom.get("spacer_rings") or {}
    return (f"spacer ring {sp.get('outer_diameter_mm', 0):g} mm (cut from the sheet, "
            f"{sp.get('thickness_mm', 0):g} mm)")


def fastener_part(bom: dict, row: dict) -> str:
    """The fastener of one BOM joint row as the bill of materials names it: the screw's name
    and its post (and extensions), or a clevis pin; shim washers are counted apart."""
    base = re.sub(r" \+ \d+ washers?$", "", str(row.get("fastener") or ""))
    if not base:
        return screw_part(bom, float(row["screw_length_mm"]))
    if row.get("fastener_kind") == "clevis pin":
        return base
    name = str(((bom.get("screws") or [{}])[0]).get("name", "Chicago screw"))
    return f"{name}, {base}"


def _hardware(bom: dict, joints) -> list:
    """Part name and count for a set of BOM joint rows."""
    fasteners: dict[str, int] = {}
    washers = spacers = 0
    for j in joints:
        part = fastener_part(bom, j)
        fasteners[part] = fasteners.get(part, 0) + 1
        washers += int(j.get("washers", 0))
        spacers += int(j.get("spacers", 0))
    out = sorted(fasteners.items())
    if washers:
        out.append((_washer_part(bom), washers))
    if spacers:
        out.append((_spacer_part(bom), spacers))
    return out


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
    if w.get("count"):
        out.append((_washer_part(bom), int(w["count"])))
    sp = bom.get("spacer_rings") or {}
    if sp.get("count"):
        out.append((_spacer_part(bom), int(sp["count"])))
    return out


def _port_key(name: str):
    m = re.fullmatch(r"([A-Za-z_]*)(\d+)", name)
    return (m.group(1), int(m.group(2)), "") if m else (name, -1, name)


def _dense_motion(plan):
    """Drive values (design units) and positions along the motion, spaced evenly and
    geometrically towards the target (a sequential collapse happens close to it), placed by
    construction; None when the network cannot be placed so or the placement leaves the traced
    motion (then the traced samples are used)."""
    from ...errors import FabkitError
    from ...kinematics import place, plan_construction

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
    for name in sorted(net.ports, key=_port_key):
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


def guide_plan(plan, bom: dict) -> GuidePlan:
    """Decide the pages of a laser kit's assembly guide.

    Parameters
    ----------
    plan : fabkit.export.dxf.LaserPlan
    bom : dict
        Its bill of materials (:func:`fabkit.export.dxf.bill_of_materials`): the hardware of
        every joint and the names of the parts.

    Returns
    -------
    GuidePlan
    """
    net = plan.design.network
    edges = np.asarray(plan.bars.edges)
    groups = page_groups(net)
    first = 3  # page 1: overview, page 2: how to build
    page_of_bar = np.empty(edges.shape[0], dtype=np.int64)
    for k, (bars, _) in enumerate(groups):
        page_of_bar[bars] = first + k
    stacks = {js.joint: js for js in plan.stacking.joints}
    closing = {j: int(max(page_of_bar[b] for b in js.bars)) for j, js in stacks.items()}
    bom_joint = {int(j["joint"]): j for j in bom.get("joints", [])}
    pages = []
    for k, (bars, modules) in enumerate(groups):
        number = first + k
        joints = sorted({int(j) for j in edges[bars].ravel() if int(j) in stacks})
        closes = tuple(j for j in joints if closing[j] == number)
        ghosts = tuple(sorted({int(b) for j in closes for b in stacks[j].bars
                               if page_of_bar[b] != number}))
        open_joints = {j: closing[j] for j in joints if closing[j] != number}
        bar_page = {int(b): number for b in bars}
        bar_page.update({b: int(page_of_bar[b]) for b in ghosts})
        hardware = _hardware(bom, [bom_joint[j] for j in closes if j in bom_joint])
        pages.append(GuidePage(number, modules, tuple(int(b) for b in bars), closes, ghosts,
                               open_joints, bar_page, hardware))
    s = plan.settings
    margin = 0.5 * max(s.bar_width, s.screw.head_diameter)
    x0 = net.nodes * s.scale
    motion = _motion_test(plan)
    moving = motion.positions if motion is not None else x0
    return GuidePlan(plan.design.name, pages, first, closing, _size(x0, edges, margin),
                     _size(moving, edges, margin), _totals(bom), motion)
