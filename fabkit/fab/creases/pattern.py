"""Flat crease patterns and their bar-and-joint networks: faces, panels, fold angles, flat
foldability (see the package docstring for the model)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import PatternError
from ...model.network import Network
from ...numerics import TINY

ASSIGNMENTS = ("B", "M", "V", "F", "U", "C", "J")


#: A face cycle encloses a face when its signed area is above this, relative to the pattern's
#: extent squared (the outer cycle is negative; a degenerate one is zero to round-off).
FACE_AREA_RTOL = 1e-12


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
            raise PatternError(f"crease pattern vertices must have shape (V, 2), got {v.shape}",
                               "vertices")
        if len(self.assignment) != e.shape[0]:
            raise PatternError(f"the crease pattern has {e.shape[0]} edges but "
                               f"{len(self.assignment)} assignments", "assignment")
        bad = [a for a in self.assignment if a not in ASSIGNMENTS]
        if bad:
            raise PatternError(f"unknown edge assignment {bad[0]!r}; valid: "
                               f"{', '.join(ASSIGNMENTS)}", "assignment")
        if e.size and (e.min() < 0 or e.max() >= v.shape[0]):
            raise PatternError("a crease names a vertex that does not exist", "edges")
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
                raise PatternError(f"face {f} {list(cyc)} uses the side {a}-{b}, "
                                   "which is not an edge of the pattern", "faces")
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
        if area > FACE_AREA_RTOL * max(float(np.ptp(v, axis=0).max()) ** 2, TINY):
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
            raise PatternError(f"face {list(cyc)} is not a simple counter-clockwise polygon",
                               "faces")
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
