"""Error models of the three ways fabkit builds a network: laser-cut bars, a 3D print, folded paper.

Every model turns the design's rest geometry into the effective rest lengths of ``M`` simulated
builds (design units), drawing its random numbers in a fixed order so that switching an error
source off (to find which one stops a build) leaves the others' draws unchanged. Lengths in the
parameters are millimetres; ``scale`` (mm per design unit) converts.

Laser (acrylic bars and Chicago screws; defaults from docs/fabrication notes)
    ``bar length``: hole-to-hole length ``N(0, length_sigma)`` per bar (laser positioning);
    ``kerf``: each hole's diameter ``N(0, kerf_sigma)`` off (uneven kerf), which widens or
    tightens its play. The play itself is a freedom, not an error (:mod:`fabkit.builds`): a
    barrel sits where the assembly pushes it in a hole ``hole_clearance`` wider than it, so the
    distance between a bar's two pins may be anything within ``room`` of its own length, the
    sum of its two holes' radial clearances (:attr:`BuildLengths.room`). The sheet's thickness
    only lets a bar tilt within that same play, and sets the stack and the screw lengths.

Print, ``linkage = "hinges"``
    Triangle plates joined by flexure hinges, printed flat in one piece.
    ``xy accuracy``: every joint printed ``N(0, xy_sigma)`` off per in-plane coordinate (typical
    FDM dimensional accuracy 0.1-0.2 mm); ``shrinkage``: the part shrinks by a fraction
    ``N(shrinkage, shrinkage_sigma)`` per build as it cools (material default; 0 if the slicer
    compensates); ``line width``: extrusion ``N(0, line_width_sigma)`` wider than the nozzle
    width per build, which grows every plate by half of it on each side and so shortens each
    hinge's free length by it; ``hinge flexure``: a hinge of free length ``ℓ`` turned by ``θ``
    bends into an arc whose chord is ``ℓ sin(θ/2) / (θ/2)``, so every bar loses
    ``ℓ/2 (1 - sin(θ/2)/(θ/2))`` at each of its joints (``θ``: that joint's largest turn from
    the printed state to the state the build is in; straight, as printed, it loses nothing).
    Layer height and hinge thickness (a whole number of layers) set the hinges' stiffness and
    strain, not the joint-to-joint geometry: they are checked by the print export's strain
    check, not here.

Print, ``linkage = "pins"`` (bars printed in place on pins, :mod:`fabkit.fab.pinned`)
    ``xy accuracy`` and ``shrinkage`` as above: a pin and the holes round it are printed at one
    place of the bed, in one print, so they err together; ``line width``: extrusion
    ``N(0, line_width_sigma)`` wider than the nozzle makes every pin that much thicker and
    every hole that much narrower, so each hole's radial play shrinks by it. The play is a
    freedom, as a laser kit's is: a bar end that turns on a pin (every end but the one whose
    body carries the pin, :attr:`ProcessGeometry.play_ends`) may sit anywhere within
    ``pin_clearance`` of it, so a bar's pin distance may take any value within ``room``, the
    sum of its ends' radial play. No flexure bends: no hinge flexure source.

Origami
    Sheets of paper, the paper's bar-and-joint idealisation: creases and boundary edges are
    rigid bars, crease intersections are joints. A sheet is made flat: its vertex errors lie in
    its flat pattern, so that every build can lie flat, as paper does.
    ``crease position``: every crease vertex folded ``N(0, crease_sigma)`` off its drawn place
    per in-plane coordinate of its sheet's pattern (hand folding along a printed line);
    ``cut``: boundary corners ``N(0, cut_sigma)`` off (knife or cutter); a bar two glued sheets
    share takes the mean of their two lengths. What only a fold brings grows with it (the
    sheet's largest crease angle over π: zero flat, one folded flat on itself):
    ``paper thickness``: a sheet of thickness ``t`` folds about its inner surface, so the hinge
    line sits up to ``t`` (uniformly, any direction) from the mid-surface line the bars
    idealise; ``crease compliance``: panels bow between their corners under the fold, which
    shortens each bar by a half-normal of ``compliance_sigma`` (bars never stretch). Without a
    ``[fabrication.origami]`` table of sheets the vertices of the network's rest configuration
    move in 3D and every error applies in every state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..numerics import TINY
from .canonical import canonical_frame, canonical_order, canonical_scalars, canonical_vectors

__all__ = ["PROCESSES", "SOURCES", "NOT_KINEMATIC", "PROCESS_EXTRA_KEYS", "ProcessGeometry", "Sheet", "BuildLengths",
           "sample_lengths", "sample_builds", "hinge_shortening", "state_profile",
           "joint_turns", "PROFILE_SAMPLES", "interp_rows", "spec_sources", "not_kinematic",
           "nominal_room_mm", "bar_play_ends", "PIN_SOURCES_LEFT_OUT"]

#: The processes and, for each, its error sources (names used in verdicts) with the spec keys
#: each one reads.
SOURCES: dict[str, dict[str, tuple[str, ...]]] = {
    "laser": {"bar length": ("length_sigma",), "kerf": ("kerf_sigma",)},
    "print": {"xy accuracy": ("xy_sigma",), "shrinkage": ("shrinkage", "shrinkage_sigma"),
              "line width": ("line_width_sigma",), "hinge flexure": ("hinge_length",)},
    "origami": {"crease position": ("crease_sigma",), "cut": ("cut_sigma",),
                "paper thickness": ("paper_thickness",),
                "crease compliance": ("compliance_sigma",)},
}
PROCESSES = tuple(SOURCES)

#: Quantities of a process that do not move a joint in the rigid-bar model, and why.
NOT_KINEMATIC = {
    "laser": {"hole play": "a freedom, not an error: the barrel sits where the assembly pushes "
                           "it, so each bar's pin distance may take any value within its room "
                           "(the assembly with play, fabkit.builds); it is what lets an "
                           "over-constrained kit go together, and what gives the ports their slop",
              "sheet thickness": "sets the stack height and the screw lengths (the BOM); a bar's "
                                 "tilt in its holes uses the same play, not more"},
    "print": {"layer height": "sets the hinge thickness (whole layers): stiffness and strain, "
                              "checked by the print export, not the joint positions",
              "hinge thickness": "stiffness and bending strain only (print export's check)"},
}

#: What a pin-jointed print's play and bars are (its joints are not flexures).
NOT_KINEMATIC_PINS = {
    "pin play": "a freedom, not an error: a bar end turning on a printed pin sits where the "
                "assembly pushes it within the pin's clearance, so each bar's pin distance may "
                "take any value within its room; it gives the ports their slop",
    "layer height": "sets the bars' and gaps' heights (whole layers), not the joint positions"}

#: Error sources of the hinge print that a print-in-place bar linkage does not have.
PIN_SOURCES_LEFT_OUT = ("hinge flexure",)

#: Spec keys of a process that belong to no error source (the freedoms and the section).
PROCESS_EXTRA_KEYS = {"laser": ("hole_clearance", "thickness", "thickness_sigma", "bar_width")}

#: The same for a pin-jointed print (set in its ``[fabrication.print]`` table, not here).
PIN_EXTRA_KEYS = ("pin_clearance", "bar_width", "bar_thickness")


def _pins(spec) -> bool:
    return spec.process == "print" and getattr(spec, "linkage", "hinges") == "pins"


def spec_sources(spec) -> dict[str, tuple[str, ...]]:
    """The error sources of the process a spec analyses, with the keys each reads: those of
    :data:`SOURCES`, less a flexure hinge's where a print's joints are pins.

    Examples
    --------
    >>> from fabkit.tolerance import ToleranceSpec
    >>> list(spec_sources(ToleranceSpec(process="print", linkage="pins")))
    ['xy accuracy', 'shrinkage', 'line width']
    """
    out = dict(SOURCES[spec.process])
    if _pins(spec):
        for name in PIN_SOURCES_LEFT_OUT:
            out.pop(name)
    return out


def not_kinematic(spec) -> dict[str, str]:
    """Quantities of the spec's process that move no joint of the rigid-bar model, and why."""
    return dict(NOT_KINEMATIC_PINS) if _pins(spec) else dict(NOT_KINEMATIC.get(spec.process, {}))


def nominal_room_mm(spec, n_edges: int, play_ends=None) -> np.ndarray | None:
    """Every bar's axial room (mm) with nominal clearances: the sum of its ends' radial play.

    Parameters
    ----------
    spec : ToleranceSpec
    n_edges : int
    play_ends : array_like, shape (E,), optional
        A pin-jointed print: per bar, its ends that turn on a pin (:mod:`fabkit.tolerance.pins`);
        two where not given.

    Returns
    -------
    numpy.ndarray, shape (E,) or None
        Laser: ``hole_clearance`` (two holes, each half of it radially); a pin-jointed print:
        ``pin_clearance`` times the bar's ends that turn on a pin; None for joints without play
        (flexure hinges, creases) or a clearance of zero.

    Examples
    --------
    >>> from fabkit.tolerance import ToleranceSpec
    >>> spec = ToleranceSpec(process="print", linkage="pins", pin_clearance=0.3)
    >>> nominal_room_mm(spec, 3, [1, 2, 0]).tolist()
    [0.3, 0.6, 0.0]
    """
    if spec.process == "laser" and spec.hole_clearance > 0:
        return np.full(n_edges, float(spec.hole_clearance))
    if _pins(spec) and spec.pin_clearance > 0:
        return bar_play_ends(play_ends, n_edges) * float(spec.pin_clearance)
    return None


def bar_play_ends(play_ends, n_edges: int) -> np.ndarray:
    """Per bar, its ends that turn on a pin with play, as floats, shape (E,): ``play_ends``,
    or two per bar where it is None."""
    if play_ends is None:
        return np.full(n_edges, 2.0)
    ends = np.asarray(play_ends, dtype=np.float64)
    if ends.shape != (n_edges,):
        raise ValueError(f"play_ends must hold one count per bar ({n_edges}), got shape "
                         f"{ends.shape}")
    return ends


#: Below this half-angle (radians) sin(x)/x is 1 to round-off (its error is x²/6).
SINC_SMALL = 1e-9


@dataclass(frozen=True)
class ProcessGeometry:
    """What the error models need of a design besides its rest lengths.

    Attributes
    ----------
    nodes : numpy.ndarray, shape (N, d)
        Rest positions (design units): the flat pattern / printed layout.
    edges : numpy.ndarray of int, shape (E, 2)
    lengths : numpy.ndarray, shape (E,)
        Design rest lengths (design units); position errors are added to these.
    joint_turn : numpy.ndarray, shape (N,) or None
        Largest turn (radians) between two bars at each joint from the start to the target.
    boundary : numpy.ndarray of bool, shape (N,) or None
        Origami: nodes on the sheet's cut boundary.
    sheets : tuple of Sheet or None
        Origami: every sheet of paper with its flat pattern (the state it is made in).
    play_ends : numpy.ndarray, shape (E,) or None
        A pin-jointed print: per bar, its ends that turn on a pin with play
        (:mod:`fabkit.tolerance.pins`); None: two per bar.
    """

    nodes: np.ndarray
    edges: np.ndarray
    lengths: np.ndarray
    joint_turn: np.ndarray | None = None
    boundary: np.ndarray | None = None
    sheets: tuple | None = None
    play_ends: np.ndarray | None = None


@dataclass(frozen=True)
class Sheet:
    """One sheet of paper: its flat pattern and where it sits in the network.

    Attributes
    ----------
    nodes : numpy.ndarray of int, shape (V,)
        Network node of each pattern vertex.
    flat : numpy.ndarray, shape (V, 2)
        The flat pattern (design units).
    edges : numpy.ndarray of int, shape (F, 2)
        Paper edges as pattern vertex pairs.
    boundary : numpy.ndarray of bool, shape (V,)
        Vertices on the cut boundary.
    creases : numpy.ndarray of int, shape (C, 4)
        Per crease (a folded edge): its two vertices and the third vertex of each of its two
        faces (counter-clockwise in the pattern), for its fold angle.
    """

    nodes: np.ndarray
    flat: np.ndarray
    edges: np.ndarray
    boundary: np.ndarray
    creases: np.ndarray


def _active(spec, sources) -> set:
    names = set(spec_sources(spec))
    return names if sources is None else names & set(sources)


def _moved(geo: ProcessGeometry, pos) -> np.ndarray:
    """Rest lengths plus the change that moving the nodes to ``pos`` (M, N, d) makes."""
    i, j = geo.edges[:, 0], geo.edges[:, 1]
    nominal = np.linalg.norm(geo.nodes[i] - geo.nodes[j], axis=-1)
    return geo.lengths[None, :] + np.linalg.norm(pos[:, i] - pos[:, j], axis=-1) - nominal


def _gain(gain, m: int) -> np.ndarray:
    """Per-build factor on every error parameter, shape (M,)."""
    if gain is None:
        return np.ones(m)
    g = np.broadcast_to(np.asarray(gain, dtype=np.float64), (m,))
    if not np.all(np.isfinite(g)) or np.any(g < 0):
        raise ValueError("gain must be finite and >= 0")
    return np.array(g)


def _laser(geo: ProcessGeometry, spec, rng, on: set, g):
    L = np.asarray(geo.lengths, dtype=np.float64)
    m, e = spec.samples, L.size
    # the sheet's thickness is drawn first (perturbed_lengths replays it), then the errors
    rng.standard_normal(m)
    length_err = g[:, None] * spec.length_sigma * rng.standard_normal((m, e))
    kerf = g[:, None, None] * spec.kerf_sigma * rng.standard_normal((m, e, 2))
    out = length_err if "bar length" in on else np.zeros((m, e))
    # each hole's diametral clearance over its barrel; a bar's pins may be that much apart
    # over both its holes' radial clearances together
    clear = np.maximum(spec.hole_clearance + (kerf if "kerf" in on else np.zeros_like(kerf)),
                       0.0)
    room = 0.5 * clear.sum(axis=2)
    return L[None, :] + out / spec.scale, np.zeros((m, e)), room / spec.scale


def _printed(geo: ProcessGeometry, spec, rng, on: set, g):
    """What every print draws: its lengths (mm) with the joints' errors and the shrinkage, and
    each build's extra line width (mm)."""
    x = geo.nodes * spec.scale
    m = spec.samples
    # each joint's error attached to the design (canonical order and frame): the same builds
    # for the design renumbered or drawn turned
    xy = g[:, None, None] * spec.xy_sigma * canonical_vectors(rng, m, x, geo.edges)
    shrink = g * (spec.shrinkage + spec.shrinkage_sigma * rng.standard_normal(m))
    width = g * spec.line_width_sigma * rng.standard_normal(m)
    pos = x[None] + (xy if "xy accuracy" in on else np.zeros_like(xy))
    L = _moved(geo, pos / spec.scale) * spec.scale
    if "shrinkage" in on:
        L = L * (1.0 - shrink[:, None])
    return L, width if "line width" in on else np.zeros(m)


def _print(geo: ProcessGeometry, spec, rng, on: set, g):
    if _pins(spec):
        return _print_pins(geo, spec, rng, on, g)
    m = spec.samples
    L, width = _printed(geo, spec, rng, on, g)
    # the plates grow by half the extra width on each side: a shorter free hinge length; a hinge
    # bent by θ then shortens each bar at it by half its free length times (1 - sinc(θ/2))
    hinge = g * spec.hinge_length if "hinge flexure" in on else np.full(m, spec.hinge_length)
    ell = np.maximum(hinge - width, 0.0)
    if "hinge flexure" in on:
        bend = 0.5 * ell
    elif "line width" in on:
        bend = 0.5 * (ell - spec.hinge_length)  # the line width's share only
    else:
        bend = np.zeros(m)
    return L / spec.scale, np.repeat((bend / spec.scale)[:, None], geo.edges.shape[0], axis=1), None


def _print_pins(geo: ProcessGeometry, spec, rng, on: set, g):
    """A print-in-place bar linkage: the hinge print's joint errors and shrinkage (the same
    draws), no flexure; the extra line width narrows every pin's play."""
    e = geo.edges.shape[0]
    L, width = _printed(geo, spec, rng, on, g)
    # a pin w thicker and its hole w narrower (each by w/2 a side): w less radial play
    play = np.maximum(spec.pin_clearance - width, 0.0)
    room = play[:, None] * bar_play_ends(geo.play_ends, e)[None, :]
    return L / spec.scale, np.zeros((spec.samples, e)), room / spec.scale


def _origami(geo: ProcessGeometry, spec, rng, on: set, gain):
    if geo.sheets:
        return _origami_sheets(geo, spec, rng, on, gain)
    x = geo.nodes * spec.scale
    m, n = spec.samples, x.shape[0]
    i = geo.edges[:, 0]
    g = gain[:, None, None]
    boundary = geo.boundary if geo.boundary is not None else np.zeros(n, dtype=bool)
    z = canonical_vectors(rng, m, x, geo.edges)
    direction = canonical_vectors(rng, m, x, geo.edges)
    reach = canonical_scalars(rng.random((m, n)), geo.edges, n)
    bow = np.abs(rng.standard_normal((m, i.size)))
    sigma = np.where(boundary, spec.cut_sigma if "cut" in on else 0.0,
                     spec.crease_sigma if "crease position" in on else 0.0)
    pos = x[None] + g * sigma[None, :, None] * z
    if "paper thickness" in on:
        # the hinge line of a crease vertex sits up to t from the drawn (mid-surface) line
        u = direction / np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), TINY)
        pos = pos + g * np.where(boundary, 0.0, spec.paper_thickness * reach)[..., None] * u
    L = _moved(geo, pos / spec.scale) * spec.scale
    if "crease compliance" in on:
        L = L - gain[:, None] * spec.compliance_sigma * bow
    return L / spec.scale, np.zeros((m, i.size)), None


def _origami_sheets(geo: ProcessGeometry, spec, rng, on: set, gain):
    """Sheets made flat: vertex errors lie in each sheet's flat pattern (its lengths stay those
    of a flat sheet), and what only a fold brings (the hinge line's offset by the paper's
    thickness, panels bowing) grows with the fold, zero in the flat state."""
    m, e = spec.samples, geo.edges.shape[0]
    lookup = {(min(i, j), max(i, j)): k for k, (i, j) in enumerate(geo.edges.tolist())}
    g = gain[:, None, None]
    change = np.zeros((m, e))
    count = np.zeros(e)
    fold = np.zeros((m, e))
    bow = np.abs(rng.standard_normal((m, e)))
    # vertex errors attached to each sheet (its own order and in-plane frame), the directions
    # of the hinge lines' offsets to the design's frame
    frame3 = canonical_frame(geo.nodes, geo.edges)
    for sh in geo.sheets:
        v = sh.flat.shape[0]
        z = canonical_vectors(rng, m, sh.flat, sh.edges)
        order = canonical_order(sh.edges, v)
        direction = np.empty((m, v, 3))
        direction[:, order] = rng.standard_normal((m, v, 3)) @ frame3
        reach = canonical_scalars(rng.random((m, v)), sh.edges, v)
        sigma = np.where(sh.boundary, spec.cut_sigma if "cut" in on else 0.0,
                         spec.crease_sigma if "crease position" in on else 0.0)
        p = sh.flat * spec.scale
        pos = p[None] + g * sigma[None, :, None] * z
        a, b = sh.edges[:, 0], sh.edges[:, 1]
        ids = np.array([lookup[(min(int(sh.nodes[i]), int(sh.nodes[j])),
                                max(int(sh.nodes[i]), int(sh.nodes[j])))]
                        for i, j in sh.edges.tolist()])
        nominal = np.linalg.norm(p[a] - p[b], axis=-1)
        np.add.at(change.T, ids, (np.linalg.norm(pos[:, a] - pos[:, b], axis=-1) - nominal).T)
        np.add.at(count, ids, 1.0)
        if "paper thickness" in on:
            # folded, the hinge line of a crease vertex sits up to t from the drawn line
            u = direction / np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), TINY)
            off = g * np.where(sh.boundary, 0.0, spec.paper_thickness * reach)[..., None] * u
            rest = geo.nodes[sh.nodes] * spec.scale
            moved = np.linalg.norm((rest[a] + off[:, a]) - (rest[b] + off[:, b]), axis=-1) \
                - np.linalg.norm(rest[a] - rest[b], axis=-1)
            np.add.at(fold.T, ids, moved.T)
    change = change / np.maximum(count, 1.0)  # a bar of two glued sheets: their mean
    L = geo.lengths[None, :] * spec.scale + (change if on & {"cut", "crease position"}
                                             else np.zeros((m, e)))
    shortening = -fold / np.maximum(count, 1.0)
    if "crease compliance" in on:
        shortening = shortening + gain[:, None] * spec.compliance_sigma * bow
    return L / spec.scale, shortening / spec.scale, None


_MODELS = {"laser": _laser, "print": _print, "origami": _origami}


@dataclass(frozen=True)
class BuildLengths:
    """Effective rest lengths of ``M`` builds, in two parts.

    Attributes
    ----------
    base : numpy.ndarray, shape (M, E)
        Every length error of the state the build is made in (design units).
    bend : numpy.ndarray, shape (M, E)
        What a state's :func:`state_profile` (zero in the made state) takes off each bar, per
        unit of profile (design units): half the free hinge length of a print (a hinge bent by
        θ shortens each bar at it by ``bend * (1 - sinc(θ/2))``), the bowing of a folded sheet's
        panels less the offset of its hinge lines; zero for laser-cut bars.
    room : numpy.ndarray, shape (M, E) or None
        Each bar's axial room (design units): its pin distance may be anything within this of
        its length at no force (laser: the sum of its two holes' radial clearances; a
        pin-jointed print: of its ends' radial play on their pins). None where joints have no
        play (flexure hinges, creases).
    """

    base: np.ndarray
    bend: np.ndarray
    room: np.ndarray | None = None

    def at(self, shortening=None) -> np.ndarray:
        """Lengths in one state per build.

        Parameters
        ----------
        shortening : numpy.ndarray, shape (E,) or (M, E), optional
            :func:`state_profile` of the state; None: the state the builds are made in.

        Returns
        -------
        numpy.ndarray, shape (M, E)
        """
        if shortening is None:
            return self.base
        return self.base - self.bend * np.asarray(shortening, dtype=np.float64)

    def over(self, shortening) -> np.ndarray:
        """Lengths in many states (columns) per build.

        Parameters
        ----------
        shortening : numpy.ndarray, shape (C, E) or (M, C, E)

        Returns
        -------
        numpy.ndarray, shape (M, C, E)
        """
        s = np.asarray(shortening, dtype=np.float64)
        if s.ndim == 2:
            s = s[None]
        return self.base[:, None, :] - self.bend[:, None, :] * s

    def select(self, rows) -> "BuildLengths":
        """The builds ``rows`` only."""
        return BuildLengths(self.base[rows], self.bend[rows],
                            None if self.room is None else self.room[rows])


def hinge_shortening(edges, turn) -> np.ndarray:
    """Per bar, the sum over its two joints of ``1 - sinc(θ/2)`` (θ: the joint's largest turn).

    Parameters
    ----------
    edges : numpy.ndarray of int, shape (E, 2)
    turn : numpy.ndarray, shape (..., N)
        Radians.

    Returns
    -------
    numpy.ndarray, shape (..., E)

    Examples
    --------
    >>> hinge_shortening(np.array([[0, 1]]), np.array([np.pi, 0.0])).round(4).tolist()
    [0.3634]
    """
    half = 0.5 * np.asarray(turn, dtype=np.float64)
    safe = np.where(half > SINC_SMALL, half, 1.0)
    h = 1.0 - np.where(half > SINC_SMALL, np.sin(half) / safe, 1.0)
    return h[..., edges[:, 0]] + h[..., edges[:, 1]]


def joint_turns(edges, rest, configs) -> np.ndarray:
    """Largest turn between two bars at every joint from the rest layout (2D), many states.

    Parameters
    ----------
    edges : numpy.ndarray of int, shape (E, 2)
    rest : numpy.ndarray, shape (N, 2)
    configs : numpy.ndarray, shape (C, N, 2)

    Returns
    -------
    numpy.ndarray, shape (C, N)
        Radians; zero in 3D (folded sheets have no flexure hinges) and where a state is NaN.
    """
    configs = np.asarray(configs, dtype=np.float64)
    c, n = configs.shape[0], rest.shape[0]
    if rest.shape[1] != 2:
        return np.zeros((c, n))
    i, j = edges[:, 0], edges[:, 1]
    d0 = rest[j] - rest[i]
    d = configs[:, j] - configs[:, i]
    turn = np.angle(np.exp(1j * (np.arctan2(d[..., 1], d[..., 0])
                                 - np.arctan2(d0[:, 1], d0[:, 0]))))  # (C, E)
    turn = np.nan_to_num(turn)
    hi = np.full((n, c), -np.inf)
    lo = np.full((n, c), np.inf)
    for ends in (i, j):
        np.maximum.at(hi, ends, turn.T)
        np.minimum.at(lo, ends, turn.T)
    out = np.where(np.isfinite(hi), np.minimum(hi - lo, 2 * np.pi), 0.0)
    return out.T


def _fold_fractions(sheet: Sheet, x) -> np.ndarray:
    """Largest fold angle of a sheet's creases over π, in every state ``x`` (C, V, 3) -> (C,)."""
    if sheet.creases.size == 0:
        return np.zeros(x.shape[0])
    i, j, k, l_ = sheet.creases.T
    n1 = np.cross(x[:, j] - x[:, i], x[:, k] - x[:, i])
    n2 = np.cross(x[:, l_] - x[:, i], x[:, j] - x[:, i])
    cos = np.sum(n1 * n2, axis=-1) / np.maximum(
        np.linalg.norm(n1, axis=-1) * np.linalg.norm(n2, axis=-1), TINY)
    return np.nan_to_num(np.arccos(np.clip(cos, -1.0, 1.0)) / np.pi).max(axis=1)


#: Samples of a module's nominal branch at which the state profile (bent hinges, folds) is
#: tabulated; it is smooth along the branch and interpolated between them.
PROFILE_SAMPLES = 257


def interp_rows(values, grid, table) -> np.ndarray:
    """Linear interpolation of every column of ``table`` (G, K) at ``values`` (Q,), clamped.

    Parameters
    ----------
    values : numpy.ndarray, shape (Q,)
    grid : numpy.ndarray, shape (G,)
        Increasing sample positions.
    table : numpy.ndarray, shape (G, K)

    Returns
    -------
    numpy.ndarray, shape (Q, K)
    """
    v = np.clip(values, grid[0], grid[-1])
    i = np.clip(np.searchsorted(grid, v) - 1, 0, grid.size - 2)
    t = ((v - grid[i]) / (grid[i + 1] - grid[i]))[:, None]
    return (1.0 - t) * table[i] + t * table[i + 1]


def state_profile(geo: ProcessGeometry, process: str, configs, nodes, edge_ids):
    """How far each bar is from the state its build was made in, per unit of
    :attr:`BuildLengths.bend`: a print's :func:`hinge_shortening`, a sheet's fold fraction
    (its largest crease angle over π); None for laser-cut bars (no such state).

    Parameters
    ----------
    geo : ProcessGeometry
    process : str
    configs : numpy.ndarray, shape (C, n, d)
        States of the nodes ``nodes`` (the whole network, or one module).
    nodes : numpy.ndarray of int, shape (n,)
    edge_ids : numpy.ndarray of int, shape (K,)
        Bars (both ends among ``nodes``) whose profile is wanted.

    Returns
    -------
    numpy.ndarray, shape (C, K) or None
    """
    configs = np.asarray(configs, dtype=np.float64)
    local = {int(v): i for i, v in enumerate(np.asarray(nodes).tolist())}
    pairs = np.array([[local[int(a)], local[int(b)]] for a, b in geo.edges[edge_ids].tolist()],
                     dtype=np.int64).reshape(-1, 2)
    if process == "print":
        turns = joint_turns(pairs, geo.nodes[np.asarray(nodes)], configs)
        return hinge_shortening(pairs, turns)
    if process != "origami" or not geo.sheets:
        return None
    out = np.zeros((configs.shape[0], len(edge_ids)))
    lookup = {(min(a, b), max(a, b)): k for k, (a, b) in enumerate(geo.edges[edge_ids].tolist())}
    for sh in geo.sheets:
        if not all(int(v) in local for v in sh.nodes.tolist()):
            continue
        w = _fold_fractions(sh, configs[:, [local[int(v)] for v in sh.nodes.tolist()]])
        for i, j in sh.edges.tolist():
            key = (min(int(sh.nodes[i]), int(sh.nodes[j])), max(int(sh.nodes[i]), int(sh.nodes[j])))
            if key in lookup:
                out[:, lookup[key]] = np.maximum(out[:, lookup[key]], w)
    return out


def sample_builds(geo: ProcessGeometry, spec, rng, sources=None, gain=None) -> BuildLengths:
    """Effective rest lengths of ``spec.samples`` builds, with the hinges' bending kept apart.

    Parameters
    ----------
    geo : ProcessGeometry
    spec : ToleranceSpec
    rng : numpy.random.Generator
    sources : iterable of str, optional
        Only these error sources; None: all of them.
    gain : float or array_like, shape (M,), optional
        Factor on every error parameter of each build (the same random draws, scaled): the
        margin of a design is found by varying it.

    Returns
    -------
    BuildLengths
    """
    g = _gain(gain, spec.samples)
    base, bend, room = _MODELS[spec.process](geo, spec, rng, _active(spec, sources), g)
    return BuildLengths(base, bend, room)


def sample_lengths(geo: ProcessGeometry, spec, rng, sources=None) -> np.ndarray:
    """Effective rest lengths of ``spec.samples`` builds under the process's errors.

    Parameters
    ----------
    geo : ProcessGeometry
    spec : ToleranceSpec
        Its ``process`` picks the model.
    rng : numpy.random.Generator
    sources : iterable of str, optional
        Only these error sources (names of :data:`SOURCES`); None: all of them.

    Returns
    -------
    numpy.ndarray, shape (M, E)
        Design units.

    Examples
    --------
    >>> from fabkit.tolerance import ToleranceSpec
    >>> geo = ProcessGeometry(np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[0, 1]]),
    ...                       np.array([1.0]))
    >>> spec = ToleranceSpec(process="print", scale=10.0, samples=3)
    >>> sample_lengths(geo, spec, np.random.default_rng(0), sources=()).tolist()
    [[1.0], [1.0], [1.0]]
    """
    builds = sample_builds(geo, spec, rng, sources)
    if geo.joint_turn is None or spec.process != "print":
        return builds.base
    return builds.at(hinge_shortening(geo.edges, geo.joint_turn))
