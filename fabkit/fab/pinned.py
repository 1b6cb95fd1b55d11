"""Print-in-place bar linkages: every bar a body of its own, stacked in layers on printed pins.

A planar bar network prints as the laser kit is stacked (:mod:`fabkit.fab.layers`): the motion
is sampled, and :func:`~fabkit.fab.layers.plan_layers` gives every bar a layer so that no two
bars of one layer, and no bar and a pin's cap or collar, come closer than ``clearance`` anywhere
along the motion. Then, instead of acrylic and Chicago screws:

* a **bar** of layer ``L`` is a round-ended slab ``bar_width`` wide and ``bar_thickness`` tall,
  from ``z = L * pitch`` up (``pitch = bar_thickness + layer_gap``: stacked bars never touch);
* at each joint of two or more bars, the **pin** grows from the top of the joint's lowest bar
  (the pin's carrier, of whose body it is part) up through holes ``pin_clearance`` wider than
  the pin (radially) in the other bars, and ends in a **cap** one ``layer_gap`` above the top
  bar; a layer the pin passes without a bar gets a **collar** filling that layer's slot, so
  that every bar rests at its own height. Caps and collars have a 45-degree cone underneath
  (whole layers tall): they print without support;
* a joint of one bar only (a free end) gets a plain hole.

Nothing is fused: each body (one bar, with the pins it carries) is watertight on its own, and
is ``layer_gap`` above and ``pin_clearance`` around every other body. A chain too long for the
bed is cut between modules (:func:`fabkit.fab.printers.split_to_fit`); the joints of a cut get
plain holes in every bar and are joined by the maker (a bolt through the stack).

A bar that no printed pin joins (both its joints are cut, or free ends) has nothing to stand in
the stack for: it is taken out of its piece and **laid flat** on the bed, a piece of its own
(:attr:`PinnedPrint.flat`), lowered to z = 0 and arranged beside the others by the bed layout
(:func:`fabkit.fab.printers.bed_layout`). The bed layout keeps every part
:func:`fabkit.fab.slicer.placement_margin` from the bed's edges: the printer's margin plus what
the slicer prints around the parts.

Circles are regular polygons (:data:`CIRCLE_SEGMENTS`): pins, caps, collars and bar ends are
inscribed in their nominal circles and holes circumscribe theirs, so every clearance is at
least its nominal value. Volumes are exact for those polygons (:attr:`PinnedPrint.volumes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import FabricationError
from ..io.workload import require
from ..motion import motion_for, trace_motion
from .bars import stadium_polygon
from ..settings.fasteners import ScrewSpec
from .hinges import manifold3d
from ..settings.laser import LaserSettings
from .layers import plan_layers, sample_chain, sample_motion
from .printers import bed_layout, split_to_fit
from .slicer import placement_margin
from ..settings.printing import PrintSettings
from ..motion.window import motion_window

__all__ = ["CIRCLE_SEGMENTS", "PinnedPrint", "pinned_print", "printed_design", "stack_settings", "bar_body",
           "pin_profile", "polygon_area", "circle_polygon", "outline_of"]

#: Sides of the polygons standing for circles (pins, holes, caps, bar ends): a 3 mm pin loses
#: 0.007 mm to the chords.
CIRCLE_SEGMENTS = 32


def circle_polygon(centre, radius: float, *, outside: bool = False,
                   n: int = CIRCLE_SEGMENTS) -> np.ndarray:
    """A regular polygon for a circle, counter-clockwise: vertices on the circle, or (with
    ``outside``) edges touching it from outside (for holes: never smaller than the circle).

    Examples
    --------
    >>> p = circle_polygon([0.0, 0.0], 1.0, n=4, outside=True)
    >>> round(float(np.hypot(*p[0])), 6)
    1.414214
    """
    r = radius / math.cos(math.pi / n) if outside else radius
    t = 2.0 * math.pi * np.arange(n) / n
    return np.asarray(centre, dtype=np.float64) + r * np.stack([np.cos(t), np.sin(t)], axis=1)


def polygon_area(points) -> float:
    """Signed area (shoelace formula), positive for counter-clockwise."""
    p = np.asarray(points, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _regular_area(radius: float, n: int = CIRCLE_SEGMENTS) -> float:
    return 0.5 * n * radius * radius * math.sin(2.0 * math.pi / n)


def stack_settings(s: PrintSettings):
    """The stacking rules of :func:`~fabkit.fab.layers.plan_layers` for printed pins.

    The layer pitch plays the sheet thickness, the cap the screw head (one cap height plus the
    gap above the top bar), the collar the spacer ring; a printed pin has whatever length its
    stack needs, so every multiple of the pitch is a "post length".
    """
    pitch = s.layer_pitch
    pin = ScrewSpec(name="printed pin", barrel_diameter=s.pin_diameter,
                    hole_diameter=s.hole_diameter, head_diameter=s.cap_diameter,
                    head_height=s.bar_thickness + s.layer_gap,
                    lengths=tuple(pitch * k for k in range(1, s.max_layers + 1)), allowance=0.0)
    return LaserSettings(scale=s.scale, bar_width=s.bar_width, thickness=pitch,
                         thickness_tolerance=0.0, kerf=0.0, min_web=0.0,
                         clearance=s.clearance, screw=pin, spacer_diameter=s.cap_diameter,
                         max_layers=s.max_layers)


def pin_profile(z_start: float, stack: list[tuple[float, float]], s: PrintSettings) -> np.ndarray:
    """The half cross-section (radius, height) of a pin with its collars and cap.

    Parameters
    ----------
    z_start : float
        Where the pin starts, inside its carrier bar (mm).
    stack : list of (z_bottom, z_top)
        Collars then the cap, bottom to top: each a cone from the pin's radius at
        ``z_bottom`` out to the cap radius, then straight up to ``z_top``.
    s : PrintSettings

    Returns
    -------
    numpy.ndarray, shape (K, 2)
        Counter-clockwise in the (radius, z) plane, for :func:`manifold3d.Manifold.revolve`.
    """
    rp, rc, cone = 0.5 * s.pin_diameter, 0.5 * s.cap_diameter, s.cone_height
    pts = [(0.0, z_start), (rp, z_start)]
    for z0, z1 in stack[:-1]:  # collars: back to the pin's radius above each
        pts += [(rp, z0), (rc, z0 + cone), (rc, z1), (rp, z1)]
    z0, z1 = stack[-1]  # the cap ends flat on top
    pts += [(rp, z0), (rc, z0 + cone), (rc, z1), (0.0, z1)]
    return np.asarray(pts, dtype=np.float64)


def _profile_volume(profile: np.ndarray, n: int = CIRCLE_SEGMENTS) -> float:
    """Volume of a profile revolved into an n-gon solid: a sum of frusta of similar n-gons."""
    k = 0.5 * n * math.sin(2.0 * math.pi / n)
    r, z = profile[:, 0], profile[:, 1]
    r0, r1, dz = r[:-1], r[1:], z[1:] - z[:-1]
    # the profile runs up its outer side and back down the axis (r = 0): frusta from the
    # outer side, signed by the direction of travel
    return float(np.sum(k * dz * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0))


@dataclass(frozen=True, eq=False)
class PinnedPrint:
    """A print-in-place bar linkage, decided (mm, print frame: nodes centred on the origin).

    Attributes
    ----------
    settings : PrintSettings
    edges : numpy.ndarray of int, shape (E, 2)
    positions : numpy.ndarray, shape (N, 2)
        Joints in the printed (start) configuration.
    offset : numpy.ndarray, shape (2,)
        Scaled design coordinates minus print-frame coordinates.
    sweep : Sweep
        The sampled motion the stacking was planned over (positions in design mm).
    stacking : Stacking
    layer : numpy.ndarray of int, shape (E,)
    carrier : dict of int to int
        Joint -> the bar that carries its pin (the joint's lowest bar).
    incidence : dict of int to numpy.ndarray
        Joint -> its bars, lowest layer first.
    cut_joints : tuple of int
        Joints where the print is cut between pieces: plain holes, joined by the maker.
    pieces : list of dict
        ``bars`` (indices), ``nodes``, ``joined_at`` (port name or ``""``), ``flat`` (a bar no
        printed pin joins, laid flat on the bed alone).
    layout : list of Placement
        Where each piece goes on which bed (:func:`fabkit.fab.printers.bed_layout`).
    parts_margin : float
        How far (mm) the layout keeps the parts from the bed's edges
        (:func:`fabkit.fab.slicer.placement_margin`: the printer's margin and the slicer's reach).
    """

    settings: PrintSettings
    edges: np.ndarray
    positions: np.ndarray
    offset: np.ndarray
    sweep: object
    stacking: object
    layer: np.ndarray
    carrier: dict
    incidence: dict
    cut_joints: tuple
    pieces: list
    layout: list
    parts_margin: float = 0.0
    stats: dict = field(default_factory=dict)

    @property
    def n_bars(self) -> int:
        return int(self.edges.shape[0])

    @property
    def flat(self) -> list[int]:
        """The bars laid flat on the bed, each a piece of its own (no printed pin joins them)."""
        return [int(p["bars"][0]) for p in self.pieces if p.get("flat")]

    @property
    def beds(self) -> int:
        return 1 + max(p.bed for p in self.layout)

    def z(self, bar: int) -> float:
        """Height of a bar's underside (mm)."""
        return float(self.layer[bar]) * self.settings.layer_pitch

    def joint_bars(self, joint: int) -> np.ndarray:
        """The bars at a joint, lowest layer first."""
        return self.incidence.get(int(joint), np.zeros(0, dtype=np.int64))

    def pin_stack(self, joint: int) -> list[tuple[float, float]]:
        """Collars and cap of the pin at a joint, bottom to top: (z_bottom, z_top) in mm."""
        s = self.settings
        bars = self.joint_bars(joint)
        lo, hi = int(self.layer[bars].min()), int(self.layer[bars].max())
        taken = set(self.layer[bars].tolist())
        pitch = s.layer_pitch
        out = [(m * pitch, m * pitch + s.bar_thickness) for m in range(lo + 1, hi)
               if m not in taken]
        top = hi * pitch + s.bar_thickness + s.layer_gap
        out.append((top, top + s.bar_thickness))
        return out

    def bar_outline(self, bar: int) -> np.ndarray:
        """The bar's round-ended outline (counter-clockwise, mm, print frame)."""
        i, j = self.edges[bar]
        return stadium_polygon(self.positions[i], self.positions[j], 0.5 * self.settings.bar_width,
                               n=CIRCLE_SEGMENTS // 2 + 1)

    def holes(self, bar: int) -> list[int]:
        """The joints where the bar has a hole (those whose pin it does not carry)."""
        return [int(j) for j in self.edges[bar] if self.carrier.get(int(j)) != bar]

    def pins(self, bar: int) -> list[int]:
        """The joints whose pin the bar carries."""
        return [int(j) for j in self.edges[bar] if self.carrier.get(int(j)) == bar]

    @property
    def volumes(self) -> np.ndarray:
        """Exact volume of each bar's body (mm^3): the polygon slab less its holes, plus its
        pins with their collars and cap, less the part of each pin inside the bar."""
        s = self.settings
        hole = _regular_area(0.5 * s.hole_diameter / math.cos(math.pi / CIRCLE_SEGMENTS))
        pin_area = _regular_area(0.5 * s.pin_diameter)
        out = np.empty(self.n_bars)
        for k in range(self.n_bars):
            v = (polygon_area(self.bar_outline(k)) - hole * len(self.holes(k))) * s.bar_thickness
            for j in self.pins(k):
                z0 = self.z(k) + 0.5 * s.bar_thickness
                v += _profile_volume(pin_profile(z0, self.pin_stack(j), s))
                v -= pin_area * 0.5 * s.bar_thickness
            out[k] = v
        return out

    def piece_of_bar(self) -> np.ndarray:
        out = np.empty(self.n_bars, dtype=np.int64)
        for p, piece in enumerate(self.pieces):
            out[piece["bars"]] = p
        return out

    def placement_matrix(self, piece: int) -> np.ndarray:
        """4 x 4 map from the print frame to the piece's bed (turned, moved, dropped to z = 0)."""
        p = self.layout[piece]
        m = np.eye(4)
        m[:3, :] = p.matrix()
        m[2, 3] = -self.piece_floor(piece)
        return m

    def piece_floor(self, piece: int) -> float:
        """Height of the piece's lowest bar (mm): the piece is lowered by it onto the bed."""
        return float(self.layer[self.pieces[piece]["bars"]].min()) * self.settings.layer_pitch


def printed_design(design, s: PrintSettings):
    """The design as its printed linkage moves (``print.motion_from`` / ``motion_to``).

    Raises
    ------
    FabricationError
        See :func:`fabkit.motion.window.motion_window`.
    """
    return motion_window(design, s.motion_from, s.motion_to, "print")


def _sweep(design, s: PrintSettings, kit=None):
    """The linkage's motion sampled for its stacking: along the kit's traced motion (the
    design's, or its window's), traced here only when none is given."""
    kit = kit if kit is not None else trace_motion(design, judge=False)
    traj = kit.planning_trajectory()
    net = design.network
    step = 0.5 * s.clearance
    # from a start part way along the motion the module windows would count every module as
    # sweeping the union of the ranges (see the laser plan): such a linkage is sampled whole
    sweep = None if s.motion_from is not None else sample_chain(
        net, design.motion, s.scale, step, width=s.bar_width, clearance=s.clearance,
        column_radius=0.5 * s.cap_diameter, spacer_radius=0.5 * s.cap_diameter,
        floor_limit=s.clearance, trajectory=traj)
    if sweep is None:  # not a chain of modules: sample the whole motion
        sweep = sample_motion(net, design.motion, s.scale, step, floor_limit=s.clearance,
                              trajectory=traj)
    return sweep


def _check_bars(net, s: PrintSettings) -> None:
    """Refuse bars too short for a pin or hole at each end with a perimeter between them."""
    lengths = net.edge_lengths * s.scale
    need = s.cap_diameter + 2.0 * s.nozzle_width
    k = int(np.argmin(lengths))
    if lengths[k] < need:
        i, j = (int(v) for v in net.edges[k])
        raise FabricationError(
            f"bar {k} (joints {i}-{j}) is {lengths[k]:.2f} mm between its joints at print.scale "
            f"= {s.scale:g}: its two {s.cap_diameter:g} mm caps need >= {need:.2f} mm; raise "
            f"print.scale to >= {s.scale * need / lengths[k]:.4g} or use smaller pins and caps")


#: The last few plans, by everything they depend on: the export and the as-built checks of its
#: STL and 3MF, in one process, ask for the same plan (a pure function of the design and the
#: settings), and planning a chain's stacking takes seconds.
_PLANS: dict = {}
_PLANS_KEPT = 4


def _plan_key(design, s) -> tuple:
    net, m = design.network, design.motion
    return (design.name, str(design.path), net.nodes.tobytes(), net.edges.tobytes(),
            repr(sorted(net.ports.items())), repr((m.drive, m.to, m.method, m.hold, m.options)),
            s)


def pinned_print(design, s: PrintSettings, motion=None) -> PinnedPrint:
    """Decide layers, pins and pieces of a design's print-in-place linkage (no solids yet).

    The same design and settings give the same plan, computed once per process (the export and
    its as-built checks share it).

    Parameters
    ----------
    design : Design
        A planar bar network with a motion.
    s : PrintSettings
        ``linkage = "pins"`` settings (:func:`fabkit.settings.printing.design_print_settings`).
    motion : TracedMotion, optional
        The design's motion, traced once by the pipeline; its window (``motion_from`` /
        ``motion_to``) is asked of it. Traced here when not given.

    Returns
    -------
    PinnedPrint

    Raises
    ------
    FabricationError
        Not planar, bars too short for their pins, no collision-free stacking within
        ``max_layers``, a piece that fits the bed in no orientation.
    BoundsError
        More bars than the work estimate allows (``fabkit --allow-large`` lifts it).
    """
    key = _plan_key(design, s)
    if key not in _PLANS:
        while len(_PLANS) >= _PLANS_KEPT:
            _PLANS.pop(next(iter(_PLANS)))
        _PLANS[key] = _plan_print(design, s, motion)
    return _PLANS[key]


def outline_of(positions, edges, half: float) -> np.ndarray:
    """Every corner of the round-ended outlines of the bars ``edges`` (mm): what the bed layout
    turns and arranges."""
    return np.concatenate([stadium_polygon(positions[i], positions[j], half,
                                           n=CIRCLE_SEGMENTS // 2 + 1) for i, j in edges])


def _lay_flat(pieces: list, pinned: np.ndarray, edges: np.ndarray) -> list:
    """The pieces without the bars no printed pin joins, then each such bar a flat piece."""
    out, flat = [], []
    for piece in pieces:
        bars = np.asarray(piece["bars"], dtype=np.int64)
        keep = bars[pinned[bars]]
        if keep.size:
            out.append({**piece, "bars": keep, "nodes": np.unique(edges[keep])})
        flat += [{"bars": np.array([b]), "nodes": np.sort(edges[b]),
                  "joined_at": piece["joined_at"], "flat": True} for b in bars[~pinned[bars]]]
    return out + flat


def _plan_print(design, s: PrintSettings, motion=None) -> PinnedPrint:
    kit = None
    if motion is not None:  # the pipeline's motion: its window traced once for every process
        kit = motion_for(design, motion).window_motion(s.motion_from, s.motion_to, "print")
        design = kit.design
    else:
        design = printed_design(design, s)
    net = design.network
    if net.dim != 2:
        raise FabricationError(f"a printed bar linkage needs a 2D network; {design.name} is "
                               f"{net.dim}D")
    if design.motion.to is None:
        raise FabricationError("a print-in-place linkage is stacked over the design's motion; "
                               "the template has no [motion] to")
    _check_bars(net, s)

    require(f"{design.path or design.name}: print-in-place linkage", ("printed bar", net.n_edges))
    sweep = _sweep(design, s, kit)
    stacking = plan_layers(net.edges, sweep, stack_settings(s))
    layer = np.asarray(stacking.layer, dtype=np.int64)
    edges = np.asarray(net.edges, dtype=np.int64)
    xy = net.nodes * s.scale
    offset = 0.5 * (xy.min(axis=0) + xy.max(axis=0))
    positions = xy - offset
    half = 0.5 * s.bar_width

    def outline(nodes):
        keep = np.zeros(net.n_nodes, dtype=bool)
        keep[nodes] = True
        return outline_of(positions, edges[keep[edges].all(axis=1)], half)

    margin = placement_margin(s)
    split, layout = split_to_fit(net, outline, s.printer_profile(), margin=margin)
    pieces, owner = [], np.full(len(edges), -1)
    for p, (nodes, cut) in enumerate(split):
        keep = np.zeros(net.n_nodes, dtype=bool)
        keep[nodes] = True
        bars = np.flatnonzero(keep[edges].all(axis=1) & (owner < 0))
        owner[bars] = p
        pieces.append({"bars": bars, "nodes": np.asarray(nodes), "joined_at": cut,
                       "flat": False})
    cut_joints = sorted({int(v) for _, cut in split if cut for v in net.port(cut)})
    # the bars of every joint, lowest layer first (one sort, not a search per joint)
    ends = edges.ravel()
    bars_at = np.repeat(np.arange(len(edges)), 2)
    order = np.lexsort((layer[bars_at], ends))
    nodes, starts = np.unique(ends[order], return_index=True)
    incidence = dict(zip(nodes.tolist(), np.split(bars_at[order], starts[1:])))
    cut = set(cut_joints)
    carrier = {j: int(b[0]) for j, b in incidence.items() if len(b) >= 2 and j not in cut}
    pinned = np.isin(edges, list(carrier)).any(axis=1)
    if not pinned.all():  # bars no printed pin joins lie flat, each a piece of its own
        pieces = _lay_flat(pieces, pinned, edges)
        layout = bed_layout([outline_of(positions, edges[p["bars"]], half) for p in pieces],
                            s.printer_profile(), margin=margin)
    return PinnedPrint(settings=s, edges=edges, positions=positions, offset=offset, sweep=sweep,
                       stacking=stacking, layer=layer, carrier=carrier, incidence=incidence,
                       cut_joints=tuple(cut_joints), pieces=pieces, layout=layout,
                       parts_margin=margin, stats={"samples": int(sweep.n_samples), "layers": int(stacking.n_layers),
                              "proof": stacking.proof_text()})


def bar_body(plan: PinnedPrint, bar: int):
    """One bar's body as a manifold3d ``Manifold`` (mm, print frame): the slab with its holes,
    and the pins (with collars and cap) it carries.

    Raises
    ------
    FabricationError
        manifold3d is missing, or the body is not a valid manifold.
    """
    mf = manifold3d()
    s = plan.settings
    rings = [np.ascontiguousarray(plan.bar_outline(bar))]
    rings += [np.ascontiguousarray(circle_polygon(plan.positions[j], 0.5 * s.hole_diameter,
                                                  outside=True)[::-1])
              for j in plan.holes(bar)]
    slab = mf.Manifold.extrude(mf.CrossSection(rings, mf.FillRule.Positive), s.bar_thickness)
    body = slab.translate((0.0, 0.0, plan.z(bar)))
    for j in plan.pins(bar):
        profile = pin_profile(plan.z(bar) + 0.5 * s.bar_thickness, plan.pin_stack(j), s)
        pin = mf.Manifold.revolve(mf.CrossSection([np.ascontiguousarray(profile)]),
                                  CIRCLE_SEGMENTS)
        x, y = plan.positions[j]
        body = body + pin.translate((float(x), float(y), 0.0))
    status = body.status()
    if status != mf.Error.NoError:
        raise FabricationError(f"bar {bar}'s body could not be built (manifold3d: {status.name})")
    return body
