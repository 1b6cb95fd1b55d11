"""The bar-and-joint network of a FOLD file, rebuilt by the check from the file's own data.

The check does not ask the writer how it turned its crease pattern into a linkage: it rebuilds
the linkage from what the file says (vertices, edges with their assignment, faces) and folds it
with the shared simulator (:mod:`fabkit.kinematics`).

Every edge but a cut (C) is a bar. A panel is a face, or faces joined across facet diagonals
(F edges). A panel of n >= 4 vertices is made rigid: each of its faces with more than three
vertices gets the n - 3 diagonals of an ear-clipping triangulation (rigid in its plane), and
the panel gets one node off its plane joined to every panel vertex (rigid out of it: bars
between coplanar points alone leave a flat panel an infinitesimal bend). A triangle is rigid by
its own three edges.

A fold angle is signed as FOLD signs it: positive for a valley, negative for a mountain, seen
from the side the counter-clockwise faces of the flat pattern face.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import FabricationError, KinematicsError
from ..kinematics import place, plan_construction
from ..kinematics.branching import analyze_bifurcation, fold_through
from ..model.network import Network
from ..numerics import TINY

__all__ = ["RebuiltFold", "Refold", "rebuild", "fold_angles", "refold"]

#: An ear of a face is cut off only when its corner turns left by more than this, relative to
#: the face's extent squared (a corner on a straight side would give a triangle of no area,
#: which holds nothing in place).
EAR_AREA_RTOL = 1e-9
#: A crease folded less than this fraction of the most folded one counts as not folded when a
#: branch out of the flat sheet is scored against the assignment (every crease of the branch
#: moves at first order, so a real fold is far above it just off the flat state).
UNFOLDED_RTOL = 1e-3
#: Geometric spacing of the drive ends this fraction of its way short of the target (then the
#: target itself), as the file's ``spacing = "geometric"`` asks.
GEOMETRIC_END = 1e-12


@dataclass(frozen=True, eq=False)
class RebuiltFold:
    """A FOLD file's linkage, rebuilt.

    Attributes
    ----------
    network : Network
        File vertices first (design units), then one node per panel of four or more vertices.
    n_vertices : int
    edges : numpy.ndarray of int, shape (E, 2)
        The file's edges.
    assignment : tuple of str
    faces : tuple of tuple of int
    flat_start : bool
        The file's root frame is a flat crease pattern (2D vertices): folding starts at a
        bifurcation.
    samples : int
    spacing : str
    step_off : float
        The file's ``fabkit:motion`` settings.
    """

    network: Network
    n_vertices: int
    edges: np.ndarray
    assignment: tuple
    faces: tuple
    flat_start: bool
    samples: int
    spacing: str
    step_off: float


@dataclass(frozen=True, eq=False)
class Refold:
    """The rebuilt linkage folded again: positions (S, N, 3) from the start, and the branch
    taken out of the flat state with the names of all branches found there (None and [] for a
    start that is not flat)."""

    positions: np.ndarray
    branch: int | None
    branches: list


def _face_sides(edges: np.ndarray, faces) -> np.ndarray:
    """Per edge, the face its (u, v) direction runs along counter-clockwise and the face on the
    other side, shape (E, 2), -1 where there is none."""
    where = {}
    for k, (u, v) in enumerate(edges.tolist()):
        where[(u, v)] = (k, 0)
        where[(v, u)] = (k, 1)
    sides = np.full((len(edges), 2), -1, dtype=np.int64)
    for f, cyc in enumerate(faces):
        for a, b in zip(cyc, np.roll(cyc, -1).tolist()):
            if (a, b) not in where:
                raise FabricationError(f"face {f} {list(cyc)} runs along {a}-{b}, which is not "
                                       "an edge of the file")
            sides[where[(a, b)]] = f
    return sides


def _panels(sides: np.ndarray, assignment, n_faces: int) -> list[list[int]]:
    """Faces grouped into panels: connected across F edges."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    joined = sides[[k for k, a in enumerate(assignment) if a == "F"]].reshape(-1, 2)
    joined = joined[(joined >= 0).all(axis=1)]
    graph = coo_matrix((np.ones(len(joined)), (joined[:, 0], joined[:, 1])),
                       shape=(n_faces, n_faces))
    _, label = connected_components(graph, directed=False)
    groups: dict[int, list[int]] = {}
    for f, lab in enumerate(label.tolist()):
        groups.setdefault(lab, []).append(f)
    return list(groups.values())


def _ears(xy: np.ndarray, cyc) -> list[tuple[int, int]]:
    """The n - 3 diagonals cutting a counter-clockwise simple polygon into triangles."""
    ring = list(cyc)
    size = max(float(np.ptp(xy[ring], axis=0).max()) ** 2, TINY)
    cuts = []
    while len(ring) > 3:
        for k in range(len(ring)):
            a, b, c = ring[k - 1], ring[k], ring[(k + 1) % len(ring)]
            ab, ac = xy[b] - xy[a], xy[c] - xy[a]
            if ab[0] * ac[1] - ab[1] * ac[0] <= EAR_AREA_RTOL * size:
                continue  # a right turn or a straight corner: not an ear
            tri = np.array([xy[a], xy[b], xy[c]])
            others = [o for o in ring if o not in (a, b, c)]
            if not any(_inside(tri, xy[o]) for o in others):
                cuts.append((a, c))
                del ring[k]
                break
        else:
            raise FabricationError(f"face {list(cyc)} is not a simple counter-clockwise "
                                   "polygon")
    return cuts


def _inside(tri: np.ndarray, p: np.ndarray) -> bool:
    """Whether p lies in the closed counter-clockwise triangle."""
    for i in range(3):
        e, w = tri[(i + 1) % 3] - tri[i], p - tri[i]
        if e[0] * w[1] - e[1] * w[0] < 0:
            return False
    return True


def _bars(xy: np.ndarray, edges, assignment, faces):
    """Bars (pairs of nodes) and the positions of the added off-plane nodes."""
    bars = [tuple(e) for e, a in zip(edges.tolist(), assignment) if a != "C"]
    have = {tuple(sorted(b)) for b in bars}
    extra = []
    for panel in _panels(_face_sides(edges, faces), assignment, len(faces)):
        verts = sorted({i for f in panel for i in faces[f]})
        if len(verts) < 4:
            continue
        for f in panel:
            for pair in _ears(xy, faces[f]) if len(faces[f]) > 3 else []:
                if tuple(sorted(pair)) not in have:
                    have.add(tuple(sorted(pair)))
                    bars.append(pair)
        pts = xy[verts]
        centre = pts.mean(axis=0)
        reach = float(np.sqrt(((pts - centre) ** 2).sum(axis=1).mean()))  # rms radius
        node = len(xy) + len(extra)
        extra.append(np.append(centre, reach))
        bars += [(i, node) for i in verts]
    return bars, extra


def rebuild(doc: dict) -> RebuiltFold:
    """The linkage of a FOLD document written by fabkit (design units: coordinates over
    ``fabkit:scale``).

    A 2D root frame is a flat crease pattern, rebuilt with its panels made rigid (see the module
    docstring); a 3D root frame (a folded form, e.g. a chain of sheets) is its edges as bars.

    Raises
    ------
    FabricationError
        A face that runs along no edge, or is not a simple counter-clockwise polygon.
    """
    x = np.asarray(doc["vertices_coords"], dtype=np.float64) / float(doc["fabkit:scale"])
    edges = np.asarray(doc["edges_vertices"], dtype=np.int64).reshape(-1, 2)
    assignment = tuple(doc["edges_assignment"])
    faces = tuple(tuple(int(i) for i in f) for f in doc["faces_vertices"])
    ports = {k: tuple(v) for k, v in doc["fabkit:ports"].items()}
    motion = doc["fabkit:motion"]
    flat = x.shape[1] == 2
    if flat:
        bars, extra = _bars(x, edges, assignment, faces)
        nodes = np.vstack([np.column_stack([x, np.zeros(len(x))])] + [e[None] for e in extra])
    else:
        bars = [tuple(e) for e, a in zip(edges.tolist(), assignment) if a != "C"]
        nodes = x
    net = Network(nodes, np.array(bars, dtype=np.int64), ports)
    return RebuiltFold(net, x.shape[0], edges, assignment, faces, flat, int(motion["samples"]),
                       motion.get("spacing", "uniform"), float(motion.get("step_off", 1e-3)))


def fold_angles(edges, faces, positions) -> np.ndarray:
    """Signed fold angle (degrees) of every edge between two faces, 0 on the others.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    faces : sequence of vertex cycles, counter-clockwise in the flat pattern
    positions : array_like, shape (N, 3)

    Returns
    -------
    numpy.ndarray, shape (E,)

    Examples
    --------
    Two triangles hinged on the x axis, the one on the right turned down by 60 degrees: a 60
    degree mountain.

    >>> x = [[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -0.5, -np.sqrt(0.75)]]
    >>> e = [[0, 1], [1, 2], [2, 0], [0, 3], [3, 1]]
    >>> np.round(fold_angles(e, [(0, 1, 2), (0, 3, 1)], x), 6).tolist()
    [-60.0, 0.0, 0.0, 0.0, 0.0]
    """
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    x = np.asarray(positions, dtype=np.float64)
    sides = _face_sides(e, faces)
    out = np.zeros(len(e))
    for k in np.flatnonzero((sides >= 0).all(axis=1)):
        u, v = e[k]
        axis = x[v] - x[u]
        # the vertex of each face farthest from the hinge line spans the face with the hinge
        left, right = (np.array(faces[f]) for f in sides[k])
        p = x[left[np.argmax(np.linalg.norm(np.cross(x[left] - x[u], axis), axis=1))]]
        q = x[right[np.argmax(np.linalg.norm(np.cross(x[right] - x[u], axis), axis=1))]]
        n_left, n_right = np.cross(axis, p - x[u]), np.cross(q - x[u], axis)
        turn = np.cross(n_left, n_right)
        angle = np.degrees(np.arctan2(np.linalg.norm(turn), float(n_left @ n_right)))
        out[k] = angle if float(np.cross(axis, p - x[u]) @ (q - x[u])) >= 0 else -angle
    return out


def _agreement(model: RebuiltFold):
    """Score of a configuration: +1 per M/V crease folded its way, -1 per one folded the other
    way or not folded (the file's assignment says which branch leaves the flat sheet)."""
    creases = [k for k, a in enumerate(model.assignment) if a in ("M", "V")]
    valley = np.array([model.assignment[k] == "V" for k in creases])

    def score(x):
        a = fold_angles(model.edges, model.faces, x)[creases]
        big = float(np.abs(a).max()) if a.size else 0.0
        folded = np.abs(a) > UNFOLDED_RTOL * big
        right = folded & ((a > 0) == valley)
        return float(right.sum() - (~right).sum())

    return score


def refold(model: RebuiltFold, drive: str, to: float) -> Refold:
    """Fold the rebuilt linkage to ``drive = to`` in the file's number of frames.

    From a flat sheet the branch is the one whose fold angles agree best with the file's
    assignment; from a folded form the drive is placed frame by frame (the file's spacing).

    Raises
    ------
    FabricationError
        The simulator cannot take the linkage there (its reason in the message).
    """
    if to is None:
        raise FabricationError("the design's motion.to (how far to fold) is not given")
    net = model.network
    try:
        if model.flat_start:
            names = [b.describe() for b in analyze_bifurcation(net).branches]
            traj = fold_through(net, drive, to, score=_agreement(model),
                                step_off_size=model.step_off, method="auto",
                                samples=model.samples - 1)
            if not traj.success:
                raise FabricationError(f"folding stopped: {traj.message}")
            return Refold(traj.positions, traj.stats.get("branch"), names)
        d0 = float(net.port_distance(drive))
        if model.spacing == "geometric":
            frac = 1.0 - np.geomspace(1.0, GEOMETRIC_END, model.samples)
            frac[0] = 0.0
        else:
            frac = np.linspace(0.0, 1.0, model.samples)
        values = d0 + frac * (float(to) - d0)
        pos, margin, _ = place(plan_construction(net, net.port(drive)), values)
        if (margin[1:] < 0).any():
            k = int(np.argmax(margin[1:] < 0)) + 1
            raise FabricationError(f"the motion ends before {drive} = {values[k]:.10g}")
        return Refold(pos, None, [])
    except KinematicsError as exc:
        raise FabricationError(str(exc)) from None
