"""Origami designs read from a template's ``[fabrication.origami]`` table, and their folding
through the flat state (branch choice, relay of the drive along a chain of sheets)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...errors import FabricationError, KinematicsError, PatternError, SettingsError
from ...io.schema import check_section
from ...io.workload import require
from ...kinematics import trace
from ...kinematics.branching import analyze_bifurcation
from ...model.network import Network
from ...numerics import canonical_frame, FLAT_SHEET_RTOL, TINY
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
    settings : dict
        The validated [fabrication.origami] table (with defaults).
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
    settings: dict = field(default_factory=dict)

    @property
    def scale(self) -> float:
        """mm per design unit: ``sheet_size`` over the largest sheet's extent corner to corner
        (its flat pattern's diameter, the same however the sheet is drawn or turned)."""
        return self.sheet_size / max(_diameter(s.pattern.vertices) for s in self.sheets)

    def pattern(self) -> CreasePattern:
        """The flat pattern of a single-sheet design."""
        if len(self.sheets) != 1:
            raise FabricationError(f"{self.name} has {len(self.sheets)} sheets: use the layout")
        return self.sheets[0].pattern


def _diameter(points) -> float:
    """Largest distance between two of the points (on their convex hull when there are many)."""
    p = np.asarray(points, dtype=np.float64)
    if p.shape[0] > 64:
        from scipy.spatial import ConvexHull, QhullError

        try:
            p = p[ConvexHull(p).vertices]
        except QhullError:  # all on one line
            pass
    diff = p[:, None, :] - p[None, :, :]
    return float(np.sqrt((diff * diff).sum(axis=-1)).max())


def _where(design) -> str:
    """The template file (or the design's name) for error messages."""
    return str(design.path) if getattr(design, "path", None) else design.name


def _err(where, key, reason):
    return FabricationError(f"{where}: fabrication.origami.{key}: {reason}")


def _table(design, overrides) -> dict:
    fab = design.fabrication.get("origami") if isinstance(design.fabrication, dict) else None
    if not isinstance(fab, dict):
        raise FabricationError(f"{_where(design)}: the template has no [fabrication.origami] table")
    merged = {**fab, **(overrides or {})}
    try:
        given = check_section("origami", merged).given()
    except SettingsError as exc:  # name the template, as the other origami errors do
        raise SettingsError(f"{_where(design)}: {exc.key}", exc.reason) from None
    out = {"sheet_size": 150.0, "samples": 41, "branch": "assignment", "sign": None,
           "spacing": "uniform", "step_off": 1e-3, **given}
    return out


def _flat_coords(x: np.ndarray, edges=None, tol: float = FLAT_SHEET_RTOL):
    """2D coordinates of a planar node set (in its own plane), or None when it is not planar.

    A sheet drawn in the xy plane keeps its coordinates and orientation; any other plane gets
    the frame of its own bars (:func:`fabkit.numerics.canonical_frame`: x along the first bar),
    so the pattern does not turn with the last bits of an eigenvector."""
    c = x - x.mean(axis=0)
    size = max(float(np.ptp(x, axis=0).max()), TINY)
    normal = np.linalg.svd(c, full_matrices=False)[2][2]
    if np.abs(c @ normal).max() > tol * size:
        return None
    if np.ptp(x[:, 2]) <= tol * size:
        return x[:, :2].copy()  # already in the xy plane: keep its coordinates and orientation
    frame = canonical_frame(x, edges if edges is not None else np.array([[0, 1]]))
    return c @ frame[:2].T


def origami_model(design, overrides=None) -> OrigamiModel:
    """Read a design's [fabrication.origami] table into an :class:`OrigamiModel`.

    Single sheet: the template's ``[network]`` is the flat sheet (3D, all nodes in one plane);
    ``assignment`` lists one of B/M/V/F/U/C per network edge; ``faces`` are found from the flat
    pattern when not given. Several sheets (a chain): ``sheet`` names the template of one sheet,
    ``sheets`` lists, per sheet, the network node of each of its vertices; assignment and faces
    come from the sheet template.

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
    s = _table(design, overrides)
    net = design.network
    name = design.name
    where = _where(design)
    # every sample of the folding is a configuration of the whole network
    require(f"{where}: fabrication.origami.samples", ("origami sample node",
                                                      s["samples"] * net.n_nodes))
    if net.dim != 3:
        raise FabricationError(f"{where}: origami needs a 3D network (nodes with x, y, z)")
    if "sheets" in s:
        return _chain_model(design, s)
    assignment = s.get("assignment")
    if not isinstance(assignment, list) or len(assignment) != net.n_edges:
        raise _err(where, "assignment", f"must list one of {'/'.join(ASSIGNMENTS)} for each of "
                                        f"the {net.n_edges} network edges")
    flat = _flat_coords(net.nodes, net.edges)
    if flat is None:
        raise FabricationError(f"{where}: the network of a single sheet must be given flat "
                               "(all nodes in one plane)")
    faces = s.get("faces")
    if faces is None:
        faces = planar_faces(flat, net.edges)
    try:
        cp = CreasePattern(flat, net.edges, tuple(assignment), faces, net.labels)
        full, info = network_from_pattern(cp, net.ports, net.labels)
    except PatternError as exc:
        raise _err(where, "faces" if exc.part == "faces" else "assignment", str(exc)) from None
    return OrigamiModel(name, full if info["apex"] else net, net.n_nodes, cp.edges, cp.assignment,
                        cp.faces, (Sheet(cp, np.arange(net.n_nodes)),), True,
                        float(s["sheet_size"]), s)


def _chain_model(design, s) -> OrigamiModel:
    name = design.name
    where = _where(design)
    net = design.network
    if "sheet" not in s or not isinstance(s["sheet"], str):
        raise _err(where, "sheet", "a design with `sheets` needs `sheet`: the template of one sheet")
    sheet_design = design.references.get("fabrication.origami.sheet")
    if sheet_design is None:
        raise _err(where, "sheet", "the sheet template was not loaded with the design (load the "
                                   "design with fabkit.load_template)")
    one = origami_model(sheet_design)
    if one.n_vertices != one.network.n_nodes:
        raise _err(where, "sheet", "chained sheets must have triangular panels")
    cp = one.pattern()
    maps = s["sheets"]
    if not isinstance(maps, list) or not maps:
        raise _err(where, "sheets", "must be a non-empty array of node lists")
    sheets, edge_set, faces = [], {}, []
    for k, m in enumerate(maps):
        if (not isinstance(m, list) or len(m) != cp.n_vertices
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
    return OrigamiModel(name, net, net.n_nodes, edges, tuple(edge_set.values()), tuple(faces),
                        tuple(sheets), False, float(s["sheet_size"]), s)


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
    samples = int(samples or s["samples"])
    if model.flat_start:
        branch = None if s["branch"] == "assignment" else int(s["branch"])
        pattern = None if branch is not None else (model.assignment, model.edges, model.faces)
        return SheetFold, {"samples": samples, "branch": branch, "sign": s["sign"],
                           "step_off": float(s["step_off"]), "pattern": pattern}
    return ChainFold, {"samples": samples, "spacing": s["spacing"], "relay": s.get("relay"),
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
            if str(traj.status) != "finished":
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
