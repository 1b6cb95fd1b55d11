"""Crease patterns: a flat sheet with mountain/valley creases <-> the 3D bar-and-joint network.

The paper models creased paper as a linkage: every crease and boundary segment is a rigid edge,
every crease intersection or corner a node. A :class:`CreasePattern` holds the flat pattern
(vertices in the plane, edges with an assignment, faces); :func:`network_from_pattern` turns it
into the :class:`~fabkit.network.Network` the simulator folds; :func:`fold_angles` reads the
signed fold angle of every crease off folded node positions.

Rigid panels: a triangular panel is rigid by its three edges. A panel with n >= 4 vertices (a
face, or faces joined across facet diagonals "F") is triangulated in the plane (2n - 3 bars fix
its shape in the plane), and one **apex node** is added off the panel, above its centroid at a
height of half the square root of its area, joined by a bar to each of the n panel vertices.
Bars between coplanar points cannot stop the panel bending out of its plane to first order (a
flat quad with both diagonals is rigid but keeps a spurious infinitesimal flex), while the apex
bars can: panel plus apex is a triangulated pyramid, rigid and infinitesimally rigid. The count
is exact: the panel alone has 3n - (2n - 3) - 6 = n - 3 bending motions; the apex adds 3
coordinates and n bars, removing n - 3. So the network has exactly the motions of the rigid
origami, no spurious ones. Apex nodes are internal: they are not written to SVG or FOLD files.

Signed fold angles follow FOLD: in degrees, positive for a valley, negative for a mountain,
seen from the side the flat pattern's counter-clockwise faces face (+z).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FabricationError
from ..network import Network
from ..numerics import rigid_fit

__all__ = [
    "ASSIGNMENTS",
    "CreasePattern",
    "planar_faces",
    "network_from_pattern",
    "fold_angles",
    "assignment_score",
    "flat_foldability",
    "Sheet",
    "OrigamiModel",
    "origami_model",
    "FoldResult",
    "fold_model",
    "folded_assignment",
    "sheet_chain",
]

#: FOLD edge assignments: boundary, mountain, valley, flat (facet), unassigned, cut, join.
ASSIGNMENTS = ("B", "M", "V", "F", "U", "C", "J")


@dataclass(frozen=True, eq=False)
class CreasePattern:
    """A flat crease pattern.

    Attributes
    ----------
    vertices : numpy.ndarray, shape (V, 2)
        Flat coordinates (design units).
    edges : numpy.ndarray of int, shape (E, 2)
    assignment : tuple of str
        One of ``ASSIGNMENTS`` per edge.
    faces : tuple of tuple of int
        Counter-clockwise vertex cycles of the faces (the outer face excluded).
    labels : tuple of str or None
        Vertex labels (corners "A", "B", ...) for drawings.
    """

    vertices: np.ndarray
    edges: np.ndarray
    assignment: tuple
    faces: tuple
    labels: tuple | None = None

    def __post_init__(self):
        v = np.asarray(self.vertices, dtype=np.float64)
        e = np.asarray(self.edges, dtype=np.int64).reshape(-1, 2)
        if v.ndim != 2 or v.shape[1] != 2:
            raise FabricationError(f"crease pattern vertices must have shape (V, 2), got {v.shape}")
        if len(self.assignment) != e.shape[0]:
            raise FabricationError(f"the crease pattern has {e.shape[0]} edges but "
                                   f"{len(self.assignment)} assignments")
        bad = [a for a in self.assignment if a not in ASSIGNMENTS]
        if bad:
            raise FabricationError(f"unknown edge assignment {bad[0]!r}; valid: "
                                   f"{', '.join(ASSIGNMENTS)}")
        if e.size and (e.min() < 0 or e.max() >= v.shape[0]):
            raise FabricationError("a crease names a vertex that does not exist")
        faces = tuple(tuple(int(i) for i in f) for f in self.faces)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "edges", e)
        object.__setattr__(self, "assignment", tuple(self.assignment))
        object.__setattr__(self, "faces", faces)

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    def edge_faces(self) -> np.ndarray:
        """Left and right face of every edge, shape (E, 2); -1 where there is none.

        The left face of edge (u, v) is the one whose counter-clockwise cycle runs u -> v.
        """
        return edge_faces(self.edges, self.faces)


def edge_faces(edges: np.ndarray, faces) -> np.ndarray:
    """Left/right face of each edge (see :meth:`CreasePattern.edge_faces`)."""
    index = {(int(a), int(b)): k for k, (a, b) in enumerate(np.asarray(edges).tolist())}
    out = np.full((len(index), 2), -1, dtype=np.int64)
    for f, cyc in enumerate(faces):
        for a, b in zip(cyc, cyc[1:] + cyc[:1]):
            if (a, b) in index:
                out[index[(a, b)], 0] = f
            elif (b, a) in index:
                out[index[(b, a)], 1] = f
            else:
                raise FabricationError(f"face {f} {list(cyc)} uses the side {a}-{b}, "
                                       "which is not an edge of the pattern")
    return out


def planar_faces(vertices, edges) -> tuple:
    """Bounded faces of a planar straight-line graph, counter-clockwise.

    Parameters
    ----------
    vertices : array_like, shape (V, 2)
    edges : array_like of int, shape (E, 2)

    Returns
    -------
    tuple of tuple of int
        One vertex cycle per bounded face (the unbounded face, clockwise, is dropped).

    Examples
    --------
    >>> planar_faces([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]])
    ((0, 1, 2), (0, 2, 3))
    """
    v = np.asarray(vertices, dtype=np.float64)
    e = np.asarray(edges, dtype=np.int64)
    out_edges: dict[int, list[int]] = {i: [] for i in range(v.shape[0])}
    for a, b in e.tolist():
        out_edges[a].append(b)
        out_edges[b].append(a)
    # neighbours sorted counter-clockwise by angle
    order = {}
    for a, nb in out_edges.items():
        ang = [np.arctan2(*(v[b] - v[a])[::-1]) for b in nb]
        order[a] = [nb[k] for k in np.argsort(ang)]
    seen = set()
    faces = []
    for a, b in [(a, b) for a, b in e.tolist()] + [(b, a) for a, b in e.tolist()]:
        if (a, b) in seen:
            continue
        cyc = []
        u, w = a, b
        while (u, w) not in seen:
            seen.add((u, w))
            cyc.append(u)
            nb = order[w]
            k = nb.index(u)
            u, w = w, nb[(k - 1) % len(nb)]  # next edge: turn clockwise from the way back
        pts = v[cyc]
        area = 0.5 * float(np.sum(pts[:, 0] * np.roll(pts[:, 1], -1)
                                  - np.roll(pts[:, 0], -1) * pts[:, 1]))
        if area > 1e-12 * max(float(np.ptp(v, axis=0).max()) ** 2, 1e-300):
            k = cyc.index(min(cyc))
            faces.append(tuple(cyc[k:] + cyc[:k]))
    return tuple(sorted(faces))


def _panels(edges: np.ndarray, assignment, faces) -> list[list[int]]:
    """Groups of faces joined across facet diagonals (F edges): the rigid panels."""
    ef = edge_faces(edges, faces)
    parent = list(range(len(faces)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for k, a in enumerate(assignment):
        if a == "F" and ef[k, 0] >= 0 and ef[k, 1] >= 0:
            parent[root(ef[k, 0])] = root(ef[k, 1])
    groups: dict[int, list[int]] = {}
    for f in range(len(faces)):
        groups.setdefault(root(f), []).append(f)
    return list(groups.values())


def network_from_pattern(cp: CreasePattern, ports=None, labels=None) -> tuple[Network, dict]:
    """The 3D bar-and-joint network of a flat crease pattern (flat state, z = 0).

    Parameters
    ----------
    cp : CreasePattern
    ports : mapping of str to (int, int), optional
        Named vertex pairs (d1, d2, ...).
    labels : sequence of str, optional

    Returns
    -------
    network : Network
        Nodes 0..V-1 are the pattern's vertices at z = 0; then one apex node per panel with four
        or more vertices (see the module docstring). Edges: every pattern edge except cuts, then
        fan diagonals of untriangulated panels, then the apex bars.
    info : dict
        ``"apex"``: list of (apex node, panel vertices); ``"diagonals"``: added (i, j) pairs;
        ``"pattern_edges"``: indices (into the network's edges) of the pattern's edges, in
        pattern order (-1 for cuts).

    Raises
    ------
    FabricationError
        A face that is not a simple polygon of pattern edges.
    """
    v = cp.vertices
    nodes = [np.column_stack([v, np.zeros(len(v))])]
    keep = [k for k, a in enumerate(cp.assignment) if a != "C"]
    edges = [tuple(cp.edges[k]) for k in keep]
    pattern_edges = np.full(len(cp.assignment), -1, dtype=np.int64)
    pattern_edges[keep] = np.arange(len(keep))
    present = {tuple(sorted(e)) for e in edges}
    apex_info, diagonals = [], []
    n_next = len(v)
    for group in _panels(cp.edges, cp.assignment, cp.faces):
        verts = sorted({i for f in group for i in cp.faces[f]})
        if len(verts) <= 3:
            continue
        for f in group:  # fan-triangulate faces that are not triangles
            cyc = cp.faces[f]
            if len(cyc) > 3:
                for t in _ear_diagonals(v, cyc):
                    key = tuple(sorted(t))
                    if key not in present:
                        present.add(key)
                        edges.append(key)
                        diagonals.append(key)
        pts = v[verts]
        poly = [v[list(cp.faces[f])] for f in group]
        area = sum(0.5 * abs(float(np.sum(p[:, 0] * np.roll(p[:, 1], -1)
                                          - np.roll(p[:, 0], -1) * p[:, 1]))) for p in poly)
        apex = np.append(pts.mean(axis=0), 0.5 * np.sqrt(area))
        nodes.append(apex[None])
        for i in verts:
            edges.append((i, n_next))
        apex_info.append((n_next, verts))
        n_next += 1
    net = Network(np.vstack(nodes), np.array(edges, dtype=np.int64), ports or {},
                  None if labels is None else list(labels) + [f"apex{k}" for k in
                                                              range(len(apex_info))])
    return net, {"apex": apex_info, "diagonals": diagonals, "pattern_edges": pattern_edges}


def _ear_diagonals(v: np.ndarray, cyc) -> list[tuple[int, int]]:
    """Diagonals of an ear-clipping triangulation of a simple counter-clockwise polygon."""
    idx = list(cyc)
    out = []
    guard = 0
    while len(idx) > 3 and guard < 10 * len(cyc):
        guard += 1
        for k in range(len(idx)):
            a, b, c = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            pa, pb, pc = v[a], v[b], v[c]
            cross = (pb[0] - pa[0]) * (pc[1] - pa[1]) - (pb[1] - pa[1]) * (pc[0] - pa[0])
            if cross <= 0:
                continue
            inside = False
            for o in idx:
                if o in (a, b, c):
                    continue
                p = v[o]
                d1 = (pb[0] - pa[0]) * (p[1] - pa[1]) - (pb[1] - pa[1]) * (p[0] - pa[0])
                d2 = (pc[0] - pb[0]) * (p[1] - pb[1]) - (pc[1] - pb[1]) * (p[0] - pb[0])
                d3 = (pa[0] - pc[0]) * (p[1] - pc[1]) - (pa[1] - pc[1]) * (p[0] - pc[0])
                if d1 >= 0 and d2 >= 0 and d3 >= 0:
                    inside = True
                    break
            if not inside:
                out.append((a, c))
                idx.pop(k)
                break
        else:
            raise FabricationError(f"face {list(cyc)} is not a simple counter-clockwise polygon")
    return out


def _normals(positions: np.ndarray, faces) -> np.ndarray:
    """Unit normals of faces (Newell's method), shape (S, F, 3)."""
    x = np.asarray(positions, dtype=np.float64)
    out = np.zeros(x.shape[:-2] + (len(faces), 3))
    sizes = np.array([len(f) for f in faces])
    for n in np.unique(sizes):  # one vectorised pass per polygon size (all triangles: one pass)
        which = np.flatnonzero(sizes == n)
        cyc = np.array([faces[f] for f in which], dtype=np.int64)  # (F_n, n)
        p = x[..., cyc, :]  # (..., F_n, n, 3)
        out[..., which, :] = np.cross(p, np.roll(p, -1, axis=-2)).sum(axis=-2)
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def fold_angles(edges, faces, positions) -> np.ndarray:
    """Signed fold angle of every edge in folded configurations.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    faces : sequence of vertex cycles, counter-clockwise in the flat pattern
    positions : array_like, shape (V, 3) or (S, V, 3)
        Folded positions of (at least) the pattern's vertices.

    Returns
    -------
    numpy.ndarray, shape (E,) or (S, E)
        Degrees in [-180, 180]: positive valley, negative mountain, 0 on edges with fewer than
        two faces.

    Examples
    --------
    Two triangles hinged on the x axis, both lifted by 45°: a 90° valley.

    >>> c = np.sqrt(0.5)
    >>> x = [[0, 0, 0], [1, 0, 0], [0.5, c, c], [0.5, -c, c]]
    >>> e = [[0, 1], [1, 2], [2, 0], [0, 3], [3, 1]]
    >>> np.round(fold_angles(e, [(0, 1, 2), (0, 3, 1)], x), 6).tolist()
    [90.0, 0.0, 0.0, 0.0, 0.0]
    """
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    x = np.asarray(positions, dtype=np.float64)
    ef = edge_faces(e, faces)
    nrm = _normals(x, faces)
    inner = (ef >= 0).all(axis=1)
    out = np.zeros(x.shape[:-2] + (e.shape[0],))
    if inner.any():
        k = np.flatnonzero(inner)
        nl = nrm[..., ef[k, 0], :]
        nr = nrm[..., ef[k, 1], :]
        axis = x[..., e[k, 1], :] - x[..., e[k, 0], :]
        axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
        s = -np.einsum("...i,...i->...", np.cross(nl, nr), axis)
        c = np.einsum("...i,...i->...", nl, nr)
        out[..., k] = np.degrees(np.arctan2(s, c))
    return out


def assignment_score(assignment, angles, rtol: float = 1e-3) -> float:
    """How well signed fold angles agree with a mountain/valley assignment.

    +1 for every M (V) edge folded as a mountain (valley), -1 for every M/V edge folded the
    other way or not folded (|angle| below ``rtol`` times the largest); other edges are ignored.

    Parameters
    ----------
    assignment : sequence of str, length E
    angles : array_like, shape (E,)

    Returns
    -------
    float
    """
    a = np.asarray(angles, dtype=np.float64)
    big = float(np.abs(a).max()) if a.size else 0.0
    score = 0.0
    for k, lab in enumerate(assignment):
        if lab not in ("M", "V"):
            continue
        if abs(a[k]) <= rtol * big or big == 0.0:
            score -= 1.0
        elif (a[k] > 0) == (lab == "V"):
            score += 1.0
        else:
            score -= 1.0
    return score


def flat_foldability(cp: CreasePattern, tol_deg: float = 1e-6) -> list[dict]:
    """Maekawa and Kawasaki at every interior vertex of a pattern meant to fold flat.

    A vertex is interior when it lies on no boundary (B) or cut edge. Its creases are the M, V
    and U edges at it (F edges are flat and do not count). Maekawa: ``|#M - #V| = 2``;
    Kawasaki: the alternating sum of the sector angles between consecutive creases is 0.

    Returns
    -------
    list of dict
        One per interior vertex: ``vertex``, ``degree``, ``mountains``, ``valleys``,
        ``unassigned``, ``maekawa`` (bool; False while a crease is unassigned),
        ``kawasaki_deg`` (the alternating sum, degrees), ``kawasaki`` (bool).
    """
    v = cp.vertices
    on_boundary = set()
    for k, a in enumerate(cp.assignment):
        if a in ("B", "C"):
            on_boundary.update(int(i) for i in cp.edges[k])
    out = []
    for vert in range(cp.n_vertices):
        if vert in on_boundary:
            continue
        inc = [k for k in range(len(cp.assignment))
               if vert in cp.edges[k] and cp.assignment[k] in ("M", "V", "U")]
        if not inc:
            continue
        others = [int(cp.edges[k][1] if cp.edges[k][0] == vert else cp.edges[k][0]) for k in inc]
        ang = np.array([np.arctan2(*(v[o] - v[vert])[::-1]) for o in others])
        order = np.argsort(ang)
        ang = ang[order]
        sectors = np.diff(np.append(ang, ang[0] + 2 * np.pi))
        alt = float(np.degrees(np.sum(sectors[0::2]) - np.sum(sectors[1::2])))
        labs = [cp.assignment[inc[k]] for k in order]
        m, vv, u = labs.count("M"), labs.count("V"), labs.count("U")
        out.append({
            "vertex": vert,
            "degree": len(inc),
            "mountains": m,
            "valleys": vv,
            "unassigned": u,
            "maekawa": u == 0 and abs(m - vv) == 2,
            "kawasaki_deg": alt,
            "kawasaki": len(inc) % 2 == 0 and abs(alt) <= tol_deg,
        })
    return out


# -- origami designs: a template's [fabrication.origami] table --------------------------------

_ORIGAMI_KEYS = {"assignment", "faces", "sheet_size", "samples", "branch", "sign", "sheet",
                 "sheets", "spacing", "step_off", "relay"}


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
        Larger side of one sheet's flat bounding box, mm.
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
        """mm per design unit."""
        ext = max(float(np.ptp(s.pattern.vertices, axis=0).max()) for s in self.sheets)
        return self.sheet_size / ext

    def pattern(self) -> CreasePattern:
        """The flat pattern of a single-sheet design."""
        if len(self.sheets) != 1:
            raise FabricationError(f"{self.name} has {len(self.sheets)} sheets: use the layout")
        return self.sheets[0].pattern


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
    unknown = sorted(set(merged) - _ORIGAMI_KEYS)
    if unknown:
        raise _err(_where(design), unknown[0], f"unknown key; allowed: {', '.join(sorted(_ORIGAMI_KEYS))}")
    out = {"sheet_size": 150.0, "samples": 41, "branch": "assignment", "sign": None,
           "spacing": "uniform", "step_off": 1e-3, **merged}
    size = out["sheet_size"]
    if isinstance(size, bool) or not isinstance(size, (int, float)) or not size > 0:
        raise _err(_where(design), "sheet_size", f"must be a positive size in mm, got {size!r}")
    n = out["samples"]
    if isinstance(n, bool) or not isinstance(n, int) or n < 2:
        raise _err(_where(design), "samples", f"must be an integer >= 2, got {n!r}")
    if out["spacing"] not in ("uniform", "geometric"):
        raise _err(_where(design), "spacing", f"must be 'uniform' or 'geometric', got {out['spacing']!r}")
    b = out["branch"]
    if not (b == "assignment" or (isinstance(b, int) and not isinstance(b, bool) and b >= 1)):
        raise _err(_where(design), "branch", f"must be 'assignment' or a branch number >= 1, got {b!r}")
    if out["sign"] not in (None, 1, -1) or isinstance(out["sign"], bool):
        raise _err(_where(design), "sign", f"must be 1 or -1, got {out['sign']!r}")
    st = out["step_off"]
    if isinstance(st, bool) or not isinstance(st, (int, float)) or not 0 < st <= 0.1:
        raise _err(_where(design), "step_off", f"must be a number in (0, 0.1], got {st!r}")
    if "relay" in out and not isinstance(out["relay"], str):
        raise _err(_where(design), "relay", f"must be a port name, got {out['relay']!r}")
    return out


def _flat_coords(x: np.ndarray, tol: float = 1e-12):
    """2D coordinates of a planar node set (in its own plane), or None when it is not planar."""
    c = x - x.mean(axis=0)
    u, s, vt = np.linalg.svd(c, full_matrices=False)
    scale = max(float(s[0]), 1e-300)
    if s[2] > tol * scale:
        return None
    if np.ptp(x[:, 2]) <= tol * scale:
        return x[:, :2].copy()  # already in the xy plane: keep its coordinates and orientation
    return c @ vt[:2].T


def origami_model(design, overrides=None) -> OrigamiModel:
    """Read a design's [fabrication.origami] table into an :class:`OrigamiModel`.

    Single sheet: the template's ``[network]`` is the flat sheet (3D, all nodes in one plane);
    ``assignment`` lists one of B/M/V/F/U/C per network edge; ``faces`` are found from the flat
    pattern when not given. Several sheets (a chain): ``sheet`` names the template of one sheet,
    ``sheets`` lists, per sheet, the network node of each of its vertices; assignment and faces
    come from the sheet template.

    Raises
    ------
    FabricationError
        Missing or malformed keys, a sheet that is not flat, faces that are not polygons of
        edges; the message names the key.
    """
    s = _table(design, overrides)
    net = design.network
    name = design.name
    where = _where(design)
    if net.dim != 3:
        raise FabricationError(f"{where}: origami needs a 3D network (nodes with x, y, z)")
    if "sheets" in s:
        return _chain_model(design, s)
    assignment = s.get("assignment")
    if not isinstance(assignment, list) or len(assignment) != net.n_edges:
        raise _err(where, "assignment", f"must list one of {'/'.join(ASSIGNMENTS)} for each of "
                                        f"the {net.n_edges} network edges")
    flat = _flat_coords(net.nodes)
    if flat is None:
        raise FabricationError(f"{where}: the network of a single sheet must be given flat "
                               "(all nodes in one plane)")
    faces = s.get("faces")
    if faces is None:
        faces = planar_faces(flat, net.edges)
    try:
        cp = CreasePattern(flat, net.edges, tuple(assignment), faces, net.labels)
        full, info = network_from_pattern(cp, net.ports, net.labels)
    except FabricationError as exc:
        raise _err(where, "faces" if "face" in str(exc) else "assignment", str(exc)) from None
    return OrigamiModel(name, full if info["apex"] else net, net.n_nodes, cp.edges, cp.assignment,
                        cp.faces, (Sheet(cp, np.arange(net.n_nodes)),), True,
                        float(s["sheet_size"]), s)


def _chain_model(design, s) -> OrigamiModel:
    name = design.name
    where = _where(design)
    net = design.network
    if "sheet" not in s or not isinstance(s["sheet"], str):
        raise _err(where, "sheet", "a design with `sheets` needs `sheet`: the template of one sheet")
    from ..templates import load_template

    base = Path(design.path).parent if design.path else Path(".")
    sheet_design = load_template(base / s["sheet"])
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
    from ..errors import KinematicsError
    from ..kinematics import plan_construction, place
    from ..kinematics.base import align_to_gauge
    from ..kinematics.branching import analyze_bifurcation, fold_through

    s = model.settings
    if to is None:
        raise FabricationError(f"{model.name}: motion.to (how far to fold) is not given")
    samples = int(samples or s["samples"])
    net = model.network
    branch = None if s["branch"] == "assignment" else int(s["branch"])

    def score(x):
        return assignment_score(model.assignment, fold_angles(model.edges, model.faces, x))

    try:
        if model.flat_start:
            bif = analyze_bifurcation(net)
            traj = fold_through(net, drive, to, branch=branch, sign=s["sign"],
                                score=score if branch is None else None,
                                step_off_size=float(s["step_off"]), method="auto",
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
            if s["spacing"] == "geometric":
                frac = 1.0 - np.geomspace(1.0, 1e-12, samples)
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
            relay = s.get("relay")
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
    from ..kinematics import place, plan_construction

    net = model.network
    if relay not in net.ports:
        raise _err(model.name, "relay", f"unknown port {relay!r}")
    r = net.port_distance(relay, pos)
    moved = np.abs(r - r[0]) / max(abs(to - r[0]), 1e-300)
    hits = np.flatnonzero(moved >= RELAY_SWITCH)
    if hits.size == 0 or hits[0] >= samples - 1:
        return pos, f"reached {relay} = {r[-1]:.10g} without handing over"
    k = int(hits[0])
    plan = plan_construction(net, net.port(relay), pos[k])
    # the relay's share of its way, spaced evenly in logit from the handover to 1 - 1e-6 (small
    # first steps resolve the front leaving the middle), then the target itself
    start = min(float(moved[k]), 0.5)
    t = np.linspace(np.log(start / (1.0 - start)), np.log((1.0 - 1e-6) / 1e-6), samples - k - 1)
    values = np.append(r[0] + (to - r[0]) / (1.0 + np.exp(-t[1:])), to)
    more, margin, _ = place(plan, values)
    if (margin < 0).any():
        raise FabricationError(f"{model.name}: the relay port {relay} cannot reach {to:.10g}")
    # the relay's frames are in its own seed frame; the caller aligns every frame to the gauge
    out = np.concatenate([pos[: k + 1], more], axis=0)
    return out, f"handed the drive to {relay} at frame {k}; reached {relay} = {values[-1]:.10g}"


# -- chains of sheets ----------------------------------------------------------------------------

#: Local vertices of the next sheet (A', C', B') merged onto (B, D, C) of the previous sheet.
CHAIN_JOIN = {"next": (0, 2, 1), "prev": (1, 3, 2)}


def sheet_chain(sheet: Network, copies: int, at: float, *, reference=None) -> tuple[Network, list]:
    """Sheets of the paper's origami module joined corner to corner, three corners per join.

    Sheet k+1's corners A', C' are merged onto sheet k's corners B, D (its d2 pair onto the
    previous sheet's d1 pair) and its corner B' onto sheet k's corner C. Two boundary edges
    coincide (A'B' = BC and B'C' = CD, both sides of the square), so the third node adds exactly
    one constraint per join: the one that stops sheet k+1 hinging about the line BD. Two shared
    corners alone leave that hinge (k sheets, k motions); with the third the chain keeps one
    conformational motion for any number of sheets (3N - E = 3(2k + 3) - (6k + 2) = 7). Every
    corner is shared by at most three consecutive sheets. (Merging B' onto A instead also keeps
    one motion, but then every sheet shares the edge AB of sheet 1, like the pages of a book.)
    Chain ports: ``d1`` = sheet 1's (A, C), ``d{k+1}`` = sheet k's (B, D): the chain iterates
    the inverse of the sheet's map, ``d_k = f(d_{k+1})``.

    Parameters
    ----------
    sheet : Network
        One sheet with nodes A, B, C, D, P (0..4) and ports d1 = (B, D), d2 = (A, C).
    copies : int
        Number of sheets.
    at : float
        The sheet's d1 value of the crystalline state to build (every sheet alike): a fixed
        point of the map, d1 = d2.
    reference : array_like, shape (5, 3), optional
        A configuration of the sheet on the wanted branch (off the flat state) that decides the
        side of every intersection.

    Returns
    -------
    network : Network
        3 + 2·copies nodes, 2 + 6·copies edges.
    sheets : list of list of int
        Network node of each sheet's vertices A, B, C, D, P.

    Raises
    ------
    FabricationError
        ``at`` is not a fixed point of the sheet's map, or the sheets do not fit.
    """
    from ..kinematics import place, plan_construction

    ref = sheet.nodes if reference is None else np.asarray(reference, dtype=np.float64)
    plan = plan_construction(sheet, sheet.port("d1"), ref)
    x, margin, _ = place(plan, [at])
    x = x[0]
    if margin[0] < 0:
        raise FabricationError(f"the sheet has no configuration with d1 = {at}")
    d2 = float(np.linalg.norm(x[0] - x[2]))
    if abs(d2 - at) > 1e-9 * at:
        raise FabricationError(f"d1 = {at} is not a fixed point of the sheet's map (d2 = {d2:.12g})")
    nodes = [x]
    maps = [list(range(5))]
    edges = [tuple(e) for e in sheet.edges.tolist()]
    n = 5
    nxt, prv = CHAIN_JOIN["next"], CHAIN_JOIN["prev"]
    for k in range(1, int(copies)):
        last = maps[-1]
        allx = np.vstack(nodes)
        dst = allx[[last[i] for i in prv]]
        fit = rigid_fit(x[list(nxt)], dst)
        rot, shift, rms = fit.rotation, fit.shift, float(fit.rms)
        if rms > 1e-9:
            raise FabricationError(f"sheet {k + 1} does not fit onto sheet {k} (rms {rms:.1e})")
        y = x @ rot.T + shift
        local = [-1] * 5
        for a, b in zip(nxt, prv):
            local[a] = last[b]
        for a in range(5):
            if local[a] < 0:
                local[a] = n
                nodes.append(y[a][None])
                n += 1
        maps.append(local)
        present = {tuple(sorted(e)) for e in edges}
        for a, b in sheet.edges.tolist():
            key = (local[a], local[b])
            if tuple(sorted(key)) not in present:
                edges.append(key)
    ports = {"d1": (maps[0][0], maps[0][2])}
    for k, m in enumerate(maps):
        ports[f"d{k + 2}"] = (m[1], m[3])
    labels = [f"{'ABCDP'[a]}{k + 1}" for k, m in enumerate(maps) for a in range(5)
              if m[a] >= 0 and (k == 0 or a not in nxt)]
    net = Network(np.vstack(nodes), np.array(edges, dtype=np.int64), ports, labels)
    return net, maps
