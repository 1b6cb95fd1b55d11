"""Inverse curvature design: a sequence of curvature modules whose final state follows a curve.

The curvature modules (Fig 4a-c) share the fixed points D1* and D2* of a symmetric map
(d1 = d2 all along the motion), so a chain of them driven from d1 = D1* to D2* ends with every
module in its designed final shape. Joined d2 to d1 with consecutive modules mirrored, the
designed nodes q_0, q_1, … of the chain form a zigzag: module k is the triangle
(q_{k-1}, q_k, q_{k+1}) with legs |q_{k-1} q_k| = |q_k q_{k+1}| = d and base ("bottom") b_k. In
the initial state every triangle is equilateral (d = b = D1*) and the zigzag is straight; in the
final state the apex angle ``α_k = 2 asin(b_k / 2 D2*)`` depends on the module's type, and the
strip turns by ``α_{k+1} - α_k`` (with alternating sign) from one module to the next. Choosing
the type of every module is then a path-following problem over a 3-letter alphabet, solved here
by beam search: the strip's centre line (the midpoints of the legs) must pass through the target
polyline at the same arclength.

:func:`design_curve` does that for any polyline; :func:`glyph` gives single-stroke capital letters
and :func:`design_word` spells a word, one chain per letter (Fig 4e-f).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import DesignError, FabkitError
from ..io.toml_writer import TomlDocument
from ..kinematics.constructive import place, plan_construction
from ..model.network import Network
from ..numerics import TINY

__all__ = ["CurvatureModule", "CurveFit", "curvature_modules", "design_curve", "strip_model",
           "glyph", "GLYPHS", "design_word", "chain_centerline", "polyline_distance",
           "letter_template"]


#: Consecutive target points closer than this (design units) are one point.
DISTINCT_POINT = 1e-12
#: A curvature module's final leg d2 must equal its final d1 (and the modules' legs each other)
#: to this relative error: they are placed exactly, so only a different design misses it.
LEG_RTOL = 1e-9


@dataclass(frozen=True)
class CurvatureModule:
    """One module type available to the inverse design.

    Attributes
    ----------
    name : str
        Short name (``"contract"``, ``"maintain"``, ``"expand"``).
    network : Network
        The module (ports d1 = (0, 1), d2 = (1, 2)), at its initial state d1 = d2 = D1*.
    leg : float
        d1 = d2 in the final state (D2*).
    bottom : float
        Distance between nodes 0 and 2 in the final state.
    template : str
        File name of its template (written next to the chain templates).
    """

    name: str
    network: Network
    leg: float
    bottom: float
    template: str = ""

    @property
    def apex(self) -> float:
        """Angle at node 1 in the final state (radians)."""
        return float(2.0 * np.arcsin(self.bottom / (2.0 * self.leg)))


def curvature_modules(networks: dict, final: float, templates: dict | None = None) -> list[CurvatureModule]:
    """Measure each module's final shape: its bottom distance when d1 = ``final`` (D2*).

    Parameters
    ----------
    networks : dict of str to Network
        Module name → network with ports d1 = (0, 1) and d2 = (1, 2).
    final : float
        The common final fixed point D2*.
    templates : dict of str to str, optional
        Module name → template file name.

    Returns
    -------
    list of CurvatureModule

    Raises
    ------
    DesignError
        A module that cannot reach ``final`` or for which ``final`` is not a fixed point
        (d2 ≠ d1 there, to 1e-9): the chain would not end in the designed shapes.
    """
    out = []
    for name, net in networks.items():
        for p in ("d1", "d2"):
            if p not in net.ports:
                raise DesignError(f"curvature module {name!r} has no port {p!r}")
        (a, b), (c, e) = net.port("d1"), net.port("d2")
        if b != c:
            raise DesignError(f"curvature module {name!r}: d1 and d2 must share their second/first "
                              "node (d1 = (0, 1), d2 = (1, 2))")
        plan = plan_construction(net, (a, b))
        x, margin, _ = place(plan, [final])
        if margin[0] < 0:
            raise DesignError(f"curvature module {name!r} cannot reach d1 = {final:.10g}")
        leg2 = float(np.linalg.norm(x[0, c] - x[0, e]))
        if abs(leg2 - final) > LEG_RTOL * final:
            raise DesignError(f"curvature module {name!r}: d2 = {leg2:.10g} at d1 = {final:.10g}; "
                              "the final state must be a fixed point d1 = d2")
        bottom = float(np.linalg.norm(x[0, a] - x[0, e]))
        out.append(CurvatureModule(name, net, final, bottom, (templates or {}).get(name, "")))
    return out


def _resample(points: np.ndarray):
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    return s


def _point_at(points: np.ndarray, s_nodes: np.ndarray, s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, s_nodes[-1])
    return np.stack([np.interp(s, s_nodes, points[:, 0]), np.interp(s, s_nodes, points[:, 1])], axis=-1)


def polyline_distance(points, polyline) -> np.ndarray:
    """Distance of each point to a polyline (vectorised over points and segments).

    Parameters
    ----------
    points : array_like, shape (P, 2)
    polyline : array_like, shape (M, 2)

    Returns
    -------
    numpy.ndarray, shape (P,)

    Examples
    --------
    >>> polyline_distance([[0.5, 1.0], [2.0, 0.0]], [[0, 0], [1, 0]]).tolist()
    [1.0, 1.0]
    """
    p = np.asarray(points, dtype=np.float64)[:, None, :]
    a = np.asarray(polyline, dtype=np.float64)[:-1][None]
    b = np.asarray(polyline, dtype=np.float64)[1:][None]
    ab = b - a
    t = np.clip(np.einsum("pmi,pmi->pm", p - a, ab) / np.maximum(np.einsum("pmi,pmi->pm", ab, ab), TINY), 0, 1)
    nearest = a + t[..., None] * ab
    return np.linalg.norm(p - nearest, axis=-1).min(axis=1)


def strip_model(types, modules: list[CurvatureModule], start_heading: float = 0.0,
                origin=(0.0, 0.0)) -> np.ndarray:
    """Final-state designed nodes q_0 … q_{K+1} of a chain of curvature modules (the zigzag).

    Parameters
    ----------
    types : sequence of int
        Index into ``modules`` for each module of the chain.
    modules : list of CurvatureModule
    start_heading : float
        Direction of q_0 → q_1 (radians).
    origin : (float, float)
        Midpoint of q_0 and q_1.

    Returns
    -------
    numpy.ndarray, shape (K + 2, 2)
    """
    leg = modules[0].leg
    apex = np.array([m.apex for m in modules])[np.asarray(types, dtype=int)]
    k = np.arange(1, apex.size + 1)
    turn = np.where(k % 2 == 1, -1.0, 1.0) * (np.pi - apex)  # module 1 turns clockwise
    heading = start_heading + np.concatenate([[0.0], np.cumsum(turn)])
    steps = leg * np.column_stack([np.cos(heading), np.sin(heading)])
    q0 = np.asarray(origin, dtype=np.float64) - 0.5 * steps[0]
    return np.vstack([q0, q0 + np.cumsum(steps, axis=0)])


@dataclass(frozen=True)
class CurveFit:
    """Result of :func:`design_curve`.

    Attributes
    ----------
    types : numpy.ndarray of int, shape (K,)
        Module type (index into ``modules``) of every module.
    names : list of str
        Their names.
    model : numpy.ndarray, shape (K + 2, 2)
        Final-state zigzag of the designed nodes in the target's frame.
    centerline : numpy.ndarray, shape (K + 1, 2)
        Midpoints of the zigzag's legs.
    target : numpy.ndarray, shape (M, 2)
        The target polyline (in design units).
    rms_error, max_error, end_error : float
        Distances of the centre line to the target polyline (design units), and of its end to
        the target's end.
    """

    types: np.ndarray
    names: list
    model: np.ndarray
    centerline: np.ndarray
    target: np.ndarray
    rms_error: float
    max_error: float
    end_error: float
    modules: list = field(default_factory=list, repr=False)


def design_curve(target, modules: list[CurvatureModule], *, beam: int = 48,
                 headings: int = 36, max_modules: int = 2000) -> CurveFit:
    """Choose a module type for every module so that the chain's final state follows ``target``.

    Parameters
    ----------
    target : array_like, shape (M, 2)
        Target polyline in design units (M ≥ 2), traversed from its first to its last point.
    modules : list of CurvatureModule
        The available module types (all with the same final leg length D2*).
    beam : int
        Beam width of the search (partial designs kept per step).
    headings : int
        Number of start headings tried.
    max_modules : int
        Safety limit on the chain length.

    Returns
    -------
    CurveFit

    Raises
    ------
    DesignError
        Fewer than 2 distinct target points, module types with different final legs, or a
        target longer than ``max_modules`` modules can cover.

    Notes
    -----
    Cost of a partial design: the sum over modules of the squared distance between the centre
    line after module k and the target point at the same arclength. Module steps are b_k / 2
    along the centre line (0.44 to 1.3 design units for the paper's modules), so the chain length
    follows from the target's length.
    """
    pts = np.asarray(target, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise DesignError(f"`target` must have shape (M, 2), got {pts.shape}")
    keep = np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > DISTINCT_POINT])
    pts = pts[keep]
    if pts.shape[0] < 2:
        raise DesignError("`target` needs at least 2 distinct points")
    if not modules:
        raise DesignError("no curvature modules given")
    legs = np.array([m.leg for m in modules])
    if np.ptp(legs) > LEG_RTOL * legs[0]:
        raise DesignError("the curvature modules must share the final leg length D2*")
    leg = float(legs[0])
    s_nodes = _resample(pts)
    length = float(s_nodes[-1])
    apex = np.array([m.apex for m in modules])
    n_types = apex.size
    # State of each candidate: last two zigzag points, arclength of the centre line, cost, and the
    # parent pointer/type for back-tracking.
    tangent = pts[1] - pts[0]
    base = np.arctan2(tangent[1], tangent[0])
    theta0 = base + np.linspace(-np.pi, np.pi, int(headings), endpoint=False)
    q_prev = pts[0] - 0.5 * leg * np.column_stack([np.cos(theta0), np.sin(theta0)])
    q_cur = pts[0] + 0.5 * leg * np.column_stack([np.cos(theta0), np.sin(theta0)])
    s = np.zeros(theta0.size)
    cost = np.zeros(theta0.size)
    history_parent, history_type = [], []
    finished = []  # (total cost, step index, candidate index, parents, types)
    for k in range(1, int(max_modules) + 1):
        sign = -1.0 if k % 2 == 1 else 1.0
        u = q_cur - q_prev
        u = u / np.linalg.norm(u, axis=1, keepdims=True)
        ang = sign * (np.pi - apex)  # (T,)
        c, sn = np.cos(ang), np.sin(ang)
        # rotate u by each turn: (C, T, 2)
        nu = np.stack([u[:, None, 0] * c - u[:, None, 1] * sn, u[:, None, 0] * sn + u[:, None, 1] * c], axis=-1)
        q_next = q_cur[:, None, :] + leg * nu
        m_old = 0.5 * (q_prev + q_cur)
        m_new = 0.5 * (q_cur[:, None, :] + q_next)
        s_new = s[:, None] + np.linalg.norm(m_new - m_old[:, None, :], axis=-1)
        dev = m_new - _point_at(pts, s_nodes, s_new)
        c_new = cost[:, None] + np.einsum("cti,cti->ct", dev, dev)
        flat_cost = c_new.ravel()
        parent = np.repeat(np.arange(q_cur.shape[0]), n_types)
        typ = np.tile(np.arange(n_types), q_cur.shape[0])
        done = s_new.ravel() >= length
        if done.any():
            end_gap = np.linalg.norm(m_new.reshape(-1, 2)[done] - pts[-1], axis=1)
            for idx, total in zip(np.flatnonzero(done), flat_cost[done] + end_gap ** 2):
                finished.append((float(total), k, int(idx), parent, typ))
        alive = np.flatnonzero(~done)
        if alive.size == 0:
            history_parent.append(parent)
            history_type.append(typ)
            break
        # Many sequences give the same strip (C-C, M-M and E-E are all straight at different
        # speeds): keep only the cheapest candidate per cell of (position, heading, arclength) so
        # that the beam stays diverse enough to turn sharp corners.
        by_cost = alive[np.argsort(flat_cost[alive], kind="stable")]
        mn = m_new.reshape(-1, 2)[by_cost]
        step = mn - np.repeat(m_old, n_types, axis=0)[by_cost]
        head = np.arctan2(step[:, 1], step[:, 0])
        cell = np.column_stack([np.floor(mn / (0.5 * leg)), np.floor(head / (np.pi / 18)),
                                np.floor(s_new.ravel()[by_cost] / (0.5 * leg))]).astype(np.int64)
        _, first = np.unique(cell, axis=0, return_index=True)
        order = by_cost[np.sort(first)[: int(beam)]]
        history_parent.append(parent[order])
        history_type.append(typ[order])
        q_prev = np.repeat(q_cur, n_types, axis=0)[order]
        q_cur = q_next.reshape(-1, 2)[order]
        s = s_new.ravel()[order]
        cost = flat_cost[order]
        if finished and min(f[0] for f in finished) < cost.min():
            break
    else:
        raise DesignError(f"the target ({length:.4g} design units) needs more than {max_modules} "
                          "modules; scale it down or raise `max_modules`")
    if not finished:
        raise DesignError("no design reached the end of the target")
    total, k_end, idx, parent, typ = min(finished, key=lambda f: f[0])
    types = [int(typ[idx])]
    j = int(parent[idx])
    for step in range(k_end - 2, -1, -1):
        types.append(int(history_type[step][j]))
        j = int(history_parent[step][j])
    types = np.array(types[::-1], dtype=int)
    # j is now the start heading that the best design came from
    model = strip_model(types, modules, start_heading=float(theta0[j]), origin=pts[0])
    center = 0.5 * (model[:-1] + model[1:])
    dist = polyline_distance(center, pts)
    return CurveFit(types=types, names=[modules[t].name for t in types], model=model,
                    centerline=center, target=pts, rms_error=float(np.sqrt(np.mean(dist ** 2))),
                    max_error=float(dist.max()), end_error=float(np.linalg.norm(center[-1] - pts[-1])),
                    modules=list(modules))


def chain_centerline(net: Network, positions, k: int) -> np.ndarray:
    """Centre line of a curvature chain: midpoints of the ports d1 … d_{k+1}, shape (k + 1, 2)."""
    x = np.asarray(positions, dtype=np.float64)
    pairs = np.array([net.port(f"d{i}") for i in range(1, k + 2)])
    return 0.5 * (x[pairs[:, 0]] + x[pairs[:, 1]])


# Single-stroke capital letters on a box of height 1 and width about 0.7 (one chain per letter
# cannot branch: letters such as E, F, H, K, T are drawn in one stroke, retracing where needed).
GLYPHS: dict[str, list[tuple[float, float]]] = {
    "A": [(0.0, 0.0), (0.35, 1.0), (0.7, 0.0)],
    "B": [(0.0, 0.0), (0.0, 1.0), (0.45, 0.96), (0.6, 0.77), (0.45, 0.55), (0.05, 0.5),
          (0.5, 0.45), (0.65, 0.22), (0.45, 0.03), (0.05, 0.0)],
    "C": [(0.7, 0.85), (0.5, 1.0), (0.2, 0.95), (0.02, 0.7), (0.0, 0.5), (0.02, 0.3), (0.2, 0.05),
          (0.5, 0.0), (0.7, 0.15)],
    "D": [(0.0, 0.0), (0.0, 1.0), (0.4, 0.95), (0.65, 0.7), (0.68, 0.5), (0.65, 0.3), (0.4, 0.05),
          (0.0, 0.0)],
    "E": [(0.7, 1.0), (0.3, 1.0), (0.05, 0.85), (0.1, 0.62), (0.4, 0.52), (0.1, 0.42),
          (0.0, 0.18), (0.3, 0.0), (0.7, 0.0)],
    "F": [(0.7, 1.0), (0.0, 1.0), (0.0, 0.55), (0.5, 0.55), (0.0, 0.55), (0.0, 0.0)],
    "G": [(0.7, 0.85), (0.5, 1.0), (0.2, 0.95), (0.02, 0.7), (0.0, 0.45), (0.1, 0.12), (0.35, 0.0),
          (0.65, 0.08), (0.7, 0.45), (0.4, 0.45)],
    "H": [(0.0, 1.0), (0.0, 0.0), (0.0, 0.5), (0.7, 0.5), (0.7, 1.0), (0.7, 0.0)],
    "I": [(0.35, 1.0), (0.35, 0.0)],
    "J": [(0.6, 1.0), (0.6, 0.25), (0.45, 0.02), (0.2, 0.02), (0.05, 0.2)],
    "K": [(0.0, 1.0), (0.0, 0.0), (0.08, 0.38), (0.65, 1.0), (0.45, 0.95), (0.2, 0.5),
          (0.7, 0.0)],
    "L": [(0.0, 1.0), (0.0, 0.0), (0.65, 0.0)],
    "M": [(0.0, 0.0), (0.0, 1.0), (0.35, 0.35), (0.7, 1.0), (0.7, 0.0)],
    "N": [(0.0, 0.0), (0.0, 1.0), (0.7, 0.0), (0.7, 1.0)],
    "O": [(0.35, 1.0), (0.1, 0.9), (0.0, 0.5), (0.1, 0.1), (0.35, 0.0), (0.6, 0.1), (0.7, 0.5),
          (0.6, 0.9), (0.35, 1.0)],
    "P": [(0.0, 0.0), (0.0, 1.0), (0.45, 0.97), (0.62, 0.77), (0.45, 0.55), (0.0, 0.5)],
    "Q": [(0.35, 1.0), (0.1, 0.9), (0.0, 0.5), (0.1, 0.1), (0.35, 0.0), (0.6, 0.1), (0.7, 0.5),
          (0.6, 0.9), (0.35, 1.0), (0.2, 0.8), (0.75, -0.1)],
    "R": [(0.0, 0.0), (0.0, 1.0), (0.45, 0.97), (0.62, 0.77), (0.45, 0.55), (0.05, 0.5),
          (0.65, 0.0)],
    "S": [(0.7, 0.85), (0.4, 1.0), (0.05, 0.85), (0.1, 0.6), (0.6, 0.42), (0.68, 0.15),
          (0.35, 0.0), (0.0, 0.15)],
    "T": [(0.0, 1.0), (0.7, 1.0), (0.72, 0.92), (0.6, 0.84), (0.42, 0.84), (0.35, 0.76),
          (0.35, 0.0)],
    "U": [(0.0, 1.0), (0.0, 0.3), (0.15, 0.03), (0.35, 0.0), (0.55, 0.03), (0.7, 0.3), (0.7, 1.0)],
    "V": [(0.0, 1.0), (0.35, 0.0), (0.7, 1.0)],
    "W": [(0.0, 1.0), (0.17, 0.0), (0.35, 0.7), (0.53, 0.0), (0.7, 1.0)],
    "X": [(0.0, 1.0), (0.7, 0.0), (0.35, 0.5), (0.7, 1.0), (0.0, 0.0)],
    "Y": [(0.0, 1.0), (0.35, 0.5), (0.7, 1.0), (0.35, 0.5), (0.35, 0.0)],
    "Z": [(0.0, 1.0), (0.7, 1.0), (0.0, 0.0), (0.7, 0.0)],
}


def glyph(letter: str, height: float = 1.0) -> np.ndarray:
    """The single-stroke polyline of a capital letter, scaled to ``height`` design units.

    Parameters
    ----------
    letter : str
        One of A-Z.
    height : float

    Returns
    -------
    numpy.ndarray, shape (M, 2)

    Raises
    ------
    FabkitError
        Not a capital letter A-Z, or a height that is not positive.

    Examples
    --------
    >>> glyph("L", 10.0).tolist()
    [[0.0, 10.0], [0.0, 0.0], [6.5, 0.0]]
    """
    if not (isinstance(letter, str) and len(letter) == 1 and letter in GLYPHS):
        raise FabkitError(f"no glyph for {letter!r}: letters must be capitals A-Z")
    if not height > 0:
        raise FabkitError(f"`height` must be positive, got {height}")
    return np.array(GLYPHS[letter], dtype=np.float64) * float(height)


def design_word(word: str, modules: list[CurvatureModule], *, height: float = 40.0,
                beam: int = 48, progress=None) -> list[CurveFit]:
    """One :class:`CurveFit` per letter of ``word`` (capitals A-Z), each letter ``height`` tall.
    ``progress(done, total, letter)`` is called as each letter's search starts.

    Raises
    ------
    FabkitError
        Empty word or a character outside A-Z (the message names it).
    """
    if not word:
        raise FabkitError("the word is empty")
    bad = [c for c in word if c not in GLYPHS]
    if bad:
        raise FabkitError(f"cannot spell {bad[0]!r}: use capital letters A-Z only")
    cache: dict[str, CurveFit] = {}
    fits = []
    for i, c in enumerate(word):
        if progress is not None:
            progress(i, len(word), c)
        if c not in cache:
            cache[c] = design_curve(glyph(c, height), modules, beam=beam)
        fits.append(cache[c])
    return fits


def letter_template(fit: CurveFit, letter: str, word: str, final: float,
                    module_files: dict[str, str]) -> str:
    """Text of a ``[chain]`` template for one designed letter.

    Parameters
    ----------
    fit : CurveFit
    letter, word : str
        For the name and description.
    final : float
        D2*, the drive target.
    module_files : dict of str to str
        Module name → template file name (next to the written template).

    Returns
    -------
    str
        TOML text: ``[chain]`` with ``modules`` and ``mirror = "alternate"``, ``[motion]`` from
        D1* to ``final``.
    """
    counts = {n: fit.names.count(n) for n in dict.fromkeys(fit.names)}
    summary = ", ".join(f"{c} {n}" for n, c in counts.items())
    height = float(np.ptp(fit.target[:, 1])) or 1.0
    doc = TomlDocument()
    doc.comment(f"Fig 4e-f: letter {letter} of {word}: a chain of curvature modules whose final "
                "state follows the letter's stroke")
    doc.value("name", f"{word.lower()}_{letter.lower()}")
    doc.value("description",
              f"letter {letter}: {len(fit.names)} curvature modules ({summary}); fit error rms "
              f"{fit.rms_error / height:.4f}, max {fit.max_error / height:.4f} of the letter "
              "height")
    doc.value("figure", "Fig 4e-f")
    doc.table("chain")
    doc.value("modules", [module_files[name] for name in fit.names], per_line=4)
    doc.value("mirror", "alternate")
    doc.table("motion")
    doc.value("drive", "d1")
    doc.value("to", float(final), note="D2*: every module in its final shape")
    doc.value("method", "constructive")
    return doc.text()
