"""Origami designs read from a template's ``[fabrication.origami]`` table, and their folding
through the flat state (branch choice, relay of the drive along a chain of sheets)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import FabricationError, KinematicsError, PatternError
from ...kinematics import trace
from ...kinematics.branching import analyze_bifurcation
from ...model.network import Network
from ...model.flat import flat_coords, point_diameter
from ...settings.origami import design_where, origami_settings, OrigamiSettings
from .pattern import ASSIGNMENTS, CreasePattern, fold_angles, network_from_pattern, planar_faces
from .tracing import ChainFold, fold_key, KEY as FOLD_KEY, SheetFold

# -- origami designs: a template's [fabrication.origami] table --------------------------------



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


def fold_trace(model: OrigamiModel, samples=None) -> tuple[type, dict]:
    """How the fold of a model traces its design's motion: the tracing method and its options
    (:mod:`fabkit.fab.creases.tracing`), for :func:`fabkit.trace` and the Motion stage alike.

    Parameters
    ----------
    model : OrigamiModel
    samples : int, optional
        Configurations of the fold (default: the model's ``samples`` setting).

    Returns
    -------
    (type, dict)
        :class:`~fabkit.fab.creases.tracing.SheetFold` for a flat start (the branch chosen by
        the assignment, or the one the settings name), else
        :class:`~fabkit.fab.creases.tracing.ChainFold`; and its options.
    """
    s = model.settings
    samples = int(samples or s.samples)
    if model.flat_start:
        branch = None if s.branch == "assignment" else int(s.branch)
        pattern = None if branch is not None else (model.assignment, model.edges, model.faces)
        return SheetFold, {"samples": samples, "branch": branch, "sign": s.sign,
                           "step_off": float(s.step_off), "pattern": pattern}
    return ChainFold, {"samples": samples, "spacing": s.spacing, "relay": s.relay,
                       "gauge": tuple(int(i) for i in model.faces[0][:3]), "name": model.name}


def traced_fold(trajectory, model: OrigamiModel, samples=None) -> bool:
    """Whether ``trajectory`` (the Motion stage's) is the trace the fold of ``model`` asks for
    (:func:`fold_trace`): of the model's own network, with the same method and options."""
    if trajectory is None or trajectory.network is not model.network:
        return False
    method, options = fold_trace(model, samples)
    return (trajectory.positions is not None
            and trajectory.stats.get(FOLD_KEY) == fold_key(method, options))


def fold_model(model: OrigamiModel, drive: str, to: float, samples=None, *,
               trajectory=None) -> FoldResult:
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
    trajectory : Trajectory, optional
        The design's motion as the Motion stage traced it. When it is the trace this fold asks
        for (:func:`traced_fold`: the Motion stage was asked for it,
        :func:`fabkit.fab.creases.plan.trace_needs`), the fold is made of it; else the fold
        traces the motion itself.

    A flat start is a bifurcation: the branches are enumerated by the second-order test
    (:mod:`fabkit.kinematics.branching`) and the one whose fold angles match the mountain/valley
    assignment (or the branch named in ``branch``) is followed. A regular start is placed
    constructively; with ``spacing = "geometric"`` the drive approaches its target geometrically
    (to resolve a sequential motion that speeds up towards the end), and ``relay`` hands the
    drive to the far end (:mod:`fabkit.fab.creases.tracing`).

    Returns
    -------
    FoldResult

    Raises
    ------
    FabricationError
        No target, or the motion cannot be traced (with the simulator's reason).
    """
    if to is None:
        raise FabricationError(f"{model.name}: motion.to (how far to fold) is not given")
    net = model.network
    try:
        if traced_fold(trajectory, model, samples):
            traj = trajectory
        else:
            method, options = fold_trace(model, samples)
            traj = trace(net, drive=drive, to=to, method=method, **options)
        if model.flat_start:
            bif = analyze_bifurcation(net)
            report, names = bif.summary(), [b.describe() for b in bif.branches]
            if not traj.success:
                raise FabricationError(f"{model.name}: folding stopped: {traj.message}")
        else:
            report, names = "", []
    except KinematicsError as exc:
        raise FabricationError(f"{model.name}: {exc}") from None
    pos = traj.positions
    chosen, sign = traj.stats.get("branch"), traj.stats.get("sign")
    ports = {k: net.port_distance(k, pos) for k in net.ports}
    angles = fold_angles(model.edges, model.faces, pos)
    # boundary and cut edges have no fold angle (where sheets are joined, two sheets' faces meet
    # at a boundary edge: that angle is not a crease's)
    angles[:, [a in ("B", "C") for a in model.assignment]] = 0.0
    return FoldResult(pos, net.port_distance(drive, pos), ports, angles, traj.method,
                      traj.message, chosen, sign, names, report,
                      float(np.max(net.edge_error(pos))))
