"""Origami designs read from a template's ``[fabrication.origami]`` table, and their folding
through the flat state (branch choice, relay of the drive along a chain of sheets)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import FabricationError, KinematicsError, PatternError
from ...kinematics import place, plan_construction
from ...kinematics.base import align_to_gauge
from ...kinematics.branching import analyze_bifurcation, fold_through
from ...model.network import Network
from ...model.flat import flat_coords, point_diameter
from ...numerics import TINY
from ...settings.origami import design_where, origami_settings, OrigamiSettings
from .pattern import (assignment_score, ASSIGNMENTS, CreasePattern, fold_angles,
                      network_from_pattern, planar_faces)

# -- origami designs: a template's [fabrication.origami] table --------------------------------



#: Geometric spacing runs from the start to this fraction of the way left to the target (the
#: last frames resolve the approach to a flat or folded state).
GEOMETRIC_END = 1e-12
#: The relay's share of its way is spaced in logit up to this fraction short of the target.
RELAY_END = 1e-6


@dataclass(frozen=True, eq=False)
class Sheet:
    """One sheet of paper of an origami design: its flat pattern and where its vertices went.

    Attributes
    ----------
    pattern : CreasePattern
        Flat pattern in the sheet's own coordinates.
    nodes : numpy.ndarray of int, shape (V,)
        Network node of each pattern vertex.
    """

    pattern: CreasePattern
    nodes: np.ndarray


@dataclass(frozen=True, eq=False)
class OrigamiModel:
    """An origami design ready to fold and export.

    Attributes
    ----------
    name : str
    network : Network
        Bar-and-joint network (pattern vertices first, then any apex nodes).
    n_vertices : int
        Number of paper vertices (network nodes that are not apex nodes).
    edges : numpy.ndarray, shape (E, 2)
        Paper edges (creases, boundary, facet diagonals) as network node pairs.
    assignment : tuple of str
        Assignment of each paper edge.
    faces : tuple of tuple of int
        Paper faces as network node cycles (counter-clockwise in their sheet's flat pattern).
    sheets : tuple of Sheet
    flat_start : bool
        The network's reference configuration is the flat sheet (a bifurcation).
    sheet_size : float
        Largest extent of one sheet's flat pattern, corner to corner (its diameter), mm.
    settings : OrigamiSettings
        The resolved [fabrication.origami] settings (with defaults and the sheet's scale).
    """

    name: str
    network: Network
    n_vertices: int
    edges: np.ndarray
    assignment: tuple
    faces: tuple
    sheets: tuple
    flat_start: bool
    sheet_size: float
    settings: OrigamiSettings

    @property
    def scale(self) -> float:
        """mm per design unit: ``sheet_size`` over the largest sheet's extent corner to corner
        (its flat pattern's diameter, the same however the sheet is drawn or turned); for the
        model as read, the same number as the settings' :attr:`OrigamiSettings.scale
        <fabkit.settings.origami.OrigamiSettings.scale>`."""
        return self.sheet_size / max(point_diameter(s.pattern.vertices) for s in self.sheets)

    def pattern(self) -> CreasePattern:
        """The flat pattern of a single-sheet design."""
        if len(self.sheets) != 1:
            raise FabricationError(f"{self.name} has {len(self.sheets)} sheets: use the layout")
        return self.sheets[0].pattern


def _err(where, key, reason):
    return FabricationError(f"{where}: fabrication.origami.{key}: {reason}")


def origami_model(design, settings: OrigamiSettings | None = None) -> OrigamiModel:
    """Read a design's [fabrication.origami] settings into an :class:`OrigamiModel`.

    Single sheet: the template's ``[network]`` is the flat sheet (3D, all nodes in one plane);
    ``assignment`` lists one of B/M/V/F/U/C per network edge; ``faces`` are found from the flat
    pattern when not given. Several sheets (a chain): ``sheet`` names the template of one sheet,
    ``sheets`` lists, per sheet, the network node of each of its vertices; assignment and faces
    come from the sheet template.

    Parameters
    ----------
    design : Design
    settings : OrigamiSettings, optional
        The design's resolved origami settings (:func:`fabkit.settings.origami.origami_settings`);
        resolved from the template alone when not given.

    Raises
    ------
    SettingsError
        A key of the wrong type or out of range (the schema).
    BoundsError
        More samples than can be folded in reasonable time and memory.
    FabricationError
        Missing keys, a sheet that is not flat, faces that are not polygons of edges; the
        message names the key.
    """
    s = origami_settings(design) if settings is None else settings
    net = design.network
    where = design_where(design)
    if s.chain:
        return _chain_model(design, s)
    assignment = s.assignment
    if assignment is None or len(assignment) != net.n_edges:
        raise _err(where, "assignment", f"must list one of {'/'.join(ASSIGNMENTS)} for each of "
                                        f"the {net.n_edges} network edges")
    flat = flat_coords(net.nodes, net.edges)  # flat: the settings' scale was measured on it
    faces = s.faces
    if faces is None:
        faces = planar_faces(flat, net.edges)
    try:
        cp = CreasePattern(flat, net.edges, tuple(assignment), faces, net.labels)
        full, info = network_from_pattern(cp, net.ports, net.labels)
    except PatternError as exc:
        raise _err(where, "faces" if exc.part == "faces" else "assignment", str(exc)) from None
    return OrigamiModel(design.name, full if info["apex"] else net, net.n_nodes, cp.edges,
                        cp.assignment, cp.faces, (Sheet(cp, np.arange(net.n_nodes)),), True,
                        float(s.sheet_size), s)


def _chain_model(design, s: OrigamiSettings) -> OrigamiModel:
    where = design_where(design)
    net = design.network
    # the settings checked that the sheet template is there
    one = origami_model(design.references["fabrication.origami.sheet"])
    if one.n_vertices != one.network.n_nodes:
        raise _err(where, "sheet", "chained sheets must have triangular panels")
    cp = one.pattern()
    maps = s.sheets
    if not maps:
        raise _err(where, "sheets", "must be a non-empty array of node lists")
    sheets, edge_set, faces = [], {}, []
    for k, m in enumerate(maps):
        if (len(m) != cp.n_vertices
                or any(isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < net.n_nodes
                       for i in m)):
            raise _err(where, f"sheets[{k}]", f"must list {cp.n_vertices} network nodes")
        nodes = np.array(m, dtype=np.int64)
        sheets.append(Sheet(cp, nodes))
        for (a, b), lab in zip(cp.edges.tolist(), cp.assignment):
            key = (int(nodes[a]), int(nodes[b]))
            if tuple(sorted(key)) not in {tuple(sorted(e)) for e in edge_set}:
                edge_set[key] = lab
        faces += [tuple(int(nodes[i]) for i in f) for f in cp.faces]
    net_keys = {tuple(sorted(e)) for e in net.edges.tolist()}
    pat_keys = {tuple(sorted(e)) for e in edge_set}
    if net_keys != pat_keys:
        extra = sorted(net_keys ^ pat_keys)[0]
        raise _err(where, "sheets", f"the sheets' edges and the network's edges differ "
                                   f"(e.g. nodes {extra[0]}-{extra[1]})")
    edges = np.array(list(edge_set), dtype=np.int64)
    return OrigamiModel(design.name, net, net.n_nodes, edges, tuple(edge_set.values()),
                        tuple(faces), tuple(sheets), False, float(s.sheet_size), s)


@dataclass(frozen=True, eq=False)
class FoldResult:
    """A simulated folding of an origami model.

    Attributes
    ----------
    positions : numpy.ndarray, shape (S, N, 3)
        Network node positions along the motion (design units).
    drive : numpy.ndarray, shape (S,)
    ports : dict of str to numpy.ndarray (S,)
        Every port distance along the motion.
    angles : numpy.ndarray, shape (S, E)
        Signed fold angle of every paper edge (degrees, valley positive).
    method : str
    message : str
    branch : int or None
        Branch taken out of the flat state (None when the start is regular).
    branches : list of str
        The branches found at the flat state.
    bifurcation : str
        The bifurcation report (empty when the start is regular).
    max_edge_error : float
    """

    positions: np.ndarray
    drive: np.ndarray
    ports: dict
    angles: np.ndarray
    method: str
    message: str
    branch: int | None
    sign: int | None
    branches: list
    bifurcation: str
    max_edge_error: float

    @property
    def target_angles(self) -> np.ndarray:
        """Per edge, the fold angle where it is folded most along the motion, shape (E,).

        The angles a person folds to: the end of a folding from flat, the start of an
        unfolding towards flat.
        """
        k = np.argmax(np.abs(self.angles), axis=0)
        return self.angles[k, np.arange(self.angles.shape[1])]


def folded_assignment(model: OrigamiModel, fold: FoldResult, rtol: float = 1e-6) -> tuple:
    """The assignment the simulated folding actually realises.

    Creases (M, V, U) become V or M by the sign of their target fold angle, or U where they stay
    flat along the motion (|angle| below ``rtol`` times the largest); B, C, F and J edges keep
    their labels. Equal to the design's assignment when the branch was chosen by it; files are
    written with this one, so that their colours and fold angles never contradict each other.

    Returns
    -------
    tuple of str
    """
    target = fold.target_angles
    big = float(np.abs(target).max()) if target.size else 0.0
    out = []
    for lab, ang in zip(model.assignment, target):
        if lab in ("M", "V", "U"):
            lab = "U" if abs(ang) <= rtol * big or big == 0.0 else ("V" if ang > 0 else "M")
        out.append(lab)
    return tuple(out)


def fold_model(model: OrigamiModel, drive: str, to: float, samples=None) -> FoldResult:
    """Fold an origami model along its design's motion.

    Parameters
    ----------
    model : OrigamiModel
    drive : str
        Port driven (the template's ``motion.drive``).
    to : float
        Target value of the drive (``motion.to``).
    samples : int, optional
        Number of configurations (default: the model's ``samples`` setting).

    A flat start is a bifurcation: the branches are enumerated by the second-order test
    (:mod:`fabkit.kinematics.branching`) and the one whose fold angles match the mountain/valley
    assignment (or the branch named in ``branch``) is followed. A regular start is traced
    directly; with ``spacing = "geometric"`` the drive approaches its target geometrically (to
    resolve a sequential motion that speeds up towards the end).

    Returns
    -------
    FoldResult

    Raises
    ------
    FabricationError
        No target, or the motion cannot be traced (with the simulator's reason).
    """
    s = model.settings
    if to is None:
        raise FabricationError(f"{model.name}: motion.to (how far to fold) is not given")
    samples = int(samples or s.samples)
    net = model.network
    branch = None if s.branch == "assignment" else int(s.branch)

    def score(x):
        return assignment_score(model.assignment, fold_angles(model.edges, model.faces, x))

    try:
        if model.flat_start:
            bif = analyze_bifurcation(net)
            traj = fold_through(net, drive, to, branch=branch, sign=s.sign,
                                score=score if branch is None else None,
                                step_off_size=float(s.step_off), method="auto",
                                samples=samples - 1)
            pos, method, message = traj.positions, traj.method, traj.message
            chosen, sign = traj.stats.get("branch"), traj.stats.get("sign")
            report, names = bif.summary(), [b.describe() for b in bif.branches]
            if str(traj.status) != "finished":
                raise FabricationError(f"{model.name}: folding stopped: {traj.message}")
        else:
            pair = net.port(drive)
            plan = plan_construction(net, pair)
            d0 = float(net.port_distance(drive))
            if s.spacing == "geometric":
                frac = 1.0 - np.geomspace(1.0, GEOMETRIC_END, samples)
                frac[0] = 0.0
            else:
                frac = np.linspace(0.0, 1.0, samples)
            values = d0 + frac * (float(to) - d0)
            pos, margin, _ = place(plan, values)
            if (margin[1:] < 0).any():
                k = int(np.argmax(margin[1:] < 0)) + 1
                raise FabricationError(f"{model.name}: the motion ends before {drive} = "
                                       f"{values[k]:.10g}")
            method, message = "constructive", f"reached {drive} = {float(to):.10g}"
            relay = s.relay
            if relay is not None:
                pos, message = _relay(model, pos, relay, float(to), samples)
                method = f"constructive ({drive}, then {relay})"
            gauge = tuple(int(i) for i in model.faces[0][:3])
            pos = align_to_gauge(pos, net.nodes, gauge)
            chosen = sign = None
            report, names = "", []
    except KinematicsError as exc:
        raise FabricationError(f"{model.name}: {exc}") from None
    ports = {k: net.port_distance(k, pos) for k in net.ports}
    angles = fold_angles(model.edges, model.faces, pos)
    # boundary and cut edges have no fold angle (where sheets are joined, two sheets' faces meet
    # at a boundary edge: that angle is not a crease's)
    angles[:, [a in ("B", "C") for a in model.assignment]] = 0.0
    return FoldResult(pos, net.port_distance(drive, pos), ports, angles, method, message, chosen,
                      sign, names, report, float(np.max(net.edge_error(pos))))


#: The relay port takes over the drive once it has moved by this fraction of its way.
RELAY_SWITCH = 1e-6


def _relay(model, pos, relay: str, to: float, samples: int):
    """Hand the drive over to another port part way (see ``relay`` in the docs).

    Driving one end of a chain whose map contracts towards that end resolves the start of the
    motion but not its end: the far end's distance is then the drive's error times the map's
    slope to the power k. Once the relay port (the far end) has moved by ``RELAY_SWITCH`` of its
    way, the remaining frames are placed from the relay port instead, where the map contracts
    the other way and the end of the motion is resolved to round-off.
    """
    net = model.network
    if relay not in net.ports:
        raise _err(model.name, "relay", f"unknown port {relay!r}")
    r = net.port_distance(relay, pos)
    moved = np.abs(r - r[0]) / max(abs(to - r[0]), TINY)
    hits = np.flatnonzero(moved >= RELAY_SWITCH)
    if hits.size == 0 or hits[0] >= samples - 1:
        return pos, f"reached {relay} = {r[-1]:.10g} without handing over"
    k = int(hits[0])
    plan = plan_construction(net, net.port(relay), pos[k])
    # the relay's share of its way, spaced evenly in logit from the handover to 1 - 1e-6 (small
    # first steps resolve the front leaving the middle), then the target itself
    start = min(float(moved[k]), 0.5)
    t = np.linspace(np.log(start / (1.0 - start)), np.log((1.0 - RELAY_END) / RELAY_END), samples - k - 1)
    values = np.append(r[0] + (to - r[0]) / (1.0 + np.exp(-t[1:])), to)
    more, margin, _ = place(plan, values)
    if (margin < 0).any():
        raise FabricationError(f"{model.name}: the relay port {relay} cannot reach {to:.10g}")
    # the relay's frames are in its own seed frame; the caller aligns every frame to the gauge
    out = np.concatenate([pos[: k + 1], more], axis=0)
    return out, f"handed the drive to {relay} at frame {k}; reached {relay} = {values[-1]:.10g}"
