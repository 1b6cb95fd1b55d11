"""Designing a module from what its designed nodes should do (positions, velocities, final
positions): solution spaces of variable nodes, and placing them.

A *variable node* joined by edges to all n = d + 1 designed nodes must keep those edge lengths
while the designed nodes move as specified. For a velocity specification (positions x_S and
velocities v_S) the velocity v of a node at x must satisfy (x_Si - x)·(v_Si - v) = 0 for every i:
n linear equations in d unknowns, solvable exactly when the augmented matrix
[x_Si - x | (x_Si - x)·v_Si] is singular. Each row is affine in x, and after subtracting the first
row from the others only one row still depends on x, so its determinant is a quadratic polynomial
in x: the solution space is a conic (2D) or a quadric (3D). For a displacement specification
(initial x0_S, final x1_S) the final position x1 of the node is affine in its initial position x
(from the differences of |x1_Si - x1|² = |x0_Si - x|²), and the one remaining equation is again
quadratic in x. Both are stored as a symmetric (d+1)×(d+1) matrix Q with [x, 1] Q [x, 1]ᵀ = 0
(supplement, "Elaborating on Single Module Design: Velocity / Displacement").

Two spaces meet in at most 4 points in 2D; :meth:`SolutionSpace.intersect` finds them exactly
(the resultant of the two conics is a quartic; its roots are polished by Newton's method), and in
3D returns points of the intersection curve, plane slice by plane slice. :func:`design_module`
places variable nodes (given, at intersections, or at the points of a space nearest to hints),
builds the module, checks with the rigidity count that it has exactly one conformational motion,
and reports which specifications are met and to what residual.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from ..errors import DesignError
from ..model.network import Network
from ..model.rigidity import count_modes
from ..numerics import TINY

__all__ = ["SolutionSpace", "DesignReport", "velocity_space", "displacement_space",
           "design_module", "build_designed_module"]

# Points of a space closer than this (relative to the design's size) to a designed node are the
# trivial solutions (a zero-length edge), never a variable node.
_TRIVIAL_RTOL = 1e-7


#: A quadratic whose leading coefficient is this small against the others is linear along the
#: line (the line is parallel to an asymptote).
LINEAR_RTOL = 1e-14
#: Newton on the two conditions stops when both residuals are below this: below the round-off
#: of evaluating them at unit scale, so only an exact hit stops it early.
POLISHED = 1e-17
#: A root of the resultant counts as real when its imaginary part is below this, relative: a
#: double root (a tangency) comes out of the companion matrix split by ~√ε ≈ 1e-8.
REAL_ROOT_RTOL = 1e-6
#: Below this the two conics share their y-quadratic at x, and y comes from the first alone.
SHARED_QUADRATIC = 1e-12
#: Intersection points closer than this (relative to the network) are one (a double root).
DUPLICATE_RTOL = 1e-9
#: A specification whose conditions all vanish to this (relative to their typical size) puts
#: no condition on the node: round-off of the fit leaves ~1e-15.
NO_CONDITION_RTOL = 1e-12


def _as_points(value, name, dim=None, count=None) -> np.ndarray:
    try:
        x = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise DesignError(f"`{name}` must be an array of points, got {value!r}") from None
    if x.ndim != 2 or x.shape[1] not in (2, 3):
        raise DesignError(f"`{name}` must have shape (n, 2) or (n, 3), got {x.shape}")
    if dim is not None and x.shape[1] != dim:
        raise DesignError(f"`{name}` must have {dim} coordinates per point, got {x.shape[1]}")
    if count is not None and x.shape[0] != count:
        raise DesignError(f"`{name}` must have {count} points (one per designed node), "
                          f"got {x.shape[0]}")
    if not np.all(np.isfinite(x)):
        raise DesignError(f"`{name}` must be finite")
    return x


def _monomials(x: np.ndarray) -> np.ndarray:
    """Quadratic monomials of points x (K, d): columns matching :func:`_q_from_coeffs`."""
    k, d = x.shape
    cols = [x[:, i] * x[:, j] for i in range(d) for j in range(i, d)]
    cols += [x[:, i] for i in range(d)]
    cols.append(np.ones(k))
    return np.stack(cols, axis=1)


def _q_from_coeffs(c: np.ndarray, d: int) -> np.ndarray:
    Q = np.zeros((d + 1, d + 1))
    k = 0
    for i in range(d):
        for j in range(i, d):
            if i == j:
                Q[i, i] = c[k]
            else:
                Q[i, j] = Q[j, i] = 0.5 * c[k]
            k += 1
    for i in range(d):
        Q[i, d] = Q[d, i] = 0.5 * c[k]
        k += 1
    Q[d, d] = c[k]
    return Q


def _homogeneous(x) -> tuple[np.ndarray, bool]:
    """Points (d,) or (K, d) as homogeneous rows [x, 1], shape (K, d+1), and whether one was given."""
    x = np.asarray(x, dtype=np.float64)
    X = np.atleast_2d(x)
    return np.concatenate([X, np.ones((X.shape[0], 1))], axis=1), x.ndim == 1


@dataclass(frozen=True, eq=False)
class SolutionSpace:
    """Admissible positions x of a variable node joined to all designed nodes.

    The set {x : [x, 1] Q [x, 1]ᵀ = 0}, a conic in 2D and a quadric in 3D.

    Attributes
    ----------
    kind : str
        ``"velocity"`` or ``"displacement"``.
    designed : numpy.ndarray, shape (n, d)
        Initial positions of the designed nodes (n = d + 1).
    target : numpy.ndarray, shape (n, d)
        Their velocities (velocity space) or final positions (displacement space).
    Q : numpy.ndarray, shape (d + 1, d + 1)
        Symmetric matrix of the quadratic form (unit Frobenius norm, in design units).
    """

    kind: str
    designed: np.ndarray
    target: np.ndarray
    Q: np.ndarray = field(repr=False)

    @property
    def dim(self) -> int:
        return int(self.designed.shape[1])

    @property
    def scale(self) -> float:
        c = self.designed.mean(axis=0)
        return float(max(np.max(np.linalg.norm(self.designed - c, axis=1)), TINY))

    # -- exact conditions -------------------------------------------------------------------
    def condition(self, x) -> np.ndarray:
        """The defining polynomial computed from the specification itself (not from Q).

        Velocity: det [x_Si - x | (x_Si - x)·v_Si]. Displacement: |x1_S0 - x1(x)|² - |x0_S0 - x|²
        with x1(x) the node's final position. Zero exactly on the space.

        Parameters
        ----------
        x : array_like, shape (d,) or (K, d)

        Returns
        -------
        numpy.ndarray, shape () or (K,)
        """
        x = np.asarray(x, dtype=np.float64)
        single = x.ndim == 1
        X = np.atleast_2d(x)
        S, T = self.designed, self.target
        if self.kind == "velocity":
            rel = S[None] - X[:, None]                        # (K, n, d)
            rhs = np.einsum("knd,nd->kn", rel, T)
            M = np.concatenate([rel, rhs[..., None]], axis=2)  # (K, n, d + 1)
            val = np.linalg.det(M)
        else:
            x1 = self.partner(X)
            val = (np.sum((T[0] - x1) ** 2, axis=1) - np.sum((S[0] - X) ** 2, axis=1))
        return val[0] if single else val

    def partner(self, x) -> np.ndarray:
        """What goes with a variable node at x: its velocity (velocity space, least squares
        over the n equations) or its final position (displacement space).

        Parameters
        ----------
        x : array_like, shape (d,) or (K, d)

        Returns
        -------
        numpy.ndarray, same shape as x
        """
        x = np.asarray(x, dtype=np.float64)
        single = x.ndim == 1
        X = np.atleast_2d(x)
        S, T = self.designed, self.target
        if self.kind == "velocity":
            rel = S[None] - X[:, None]                        # (K, n, d)
            rhs = np.einsum("knd,nd->kn", rel, T)
            out = np.stack([np.linalg.lstsq(r, b, rcond=None)[0] for r, b in zip(rel, rhs)])
        else:
            # |x1_Si - x1|² - |x1_S0 - x1|² = |x0_Si - x|² - |x0_S0 - x|²  (i = 1..n-1): linear
            A = 2.0 * (T[0] - T[1:])                          # (n-1, d)
            base = np.sum(T[1:] ** 2, axis=1) - np.sum(T[0] ** 2)
            r0 = np.sum((S[None, 1:] - X[:, None]) ** 2, axis=2) - np.sum((S[0] - X) ** 2, axis=1)[:, None]
            rhs = r0 - base[None]
            out = np.linalg.lstsq(A, rhs.T, rcond=None)[0].T
        return out[0] if single else out

    def residual(self, x) -> np.ndarray:
        """Physical residual of a variable node at x (design units).

        Velocity: the largest rate of change of an edge length, max_i |(x_Si - x)·(v_Si - v)|
        divided by the edge length, with v from :meth:`partner`. Displacement: the largest change
        of an edge length between the initial and final positions, max_i ||x1_Si - x1| -
        |x0_Si - x||. Zero (to round-off) exactly on the space.
        """
        x = np.asarray(x, dtype=np.float64)
        single = x.ndim == 1
        X = np.atleast_2d(x)
        S, T = self.designed, self.target
        P = self.partner(X)
        if self.kind == "velocity":
            rel = S[None] - X[:, None]
            rate = np.einsum("knd,knd->kn", rel, T[None] - P[:, None])
            r = np.max(np.abs(rate) / np.linalg.norm(rel, axis=2), axis=1)
        else:
            l0 = np.linalg.norm(S[None] - X[:, None], axis=2)
            l1 = np.linalg.norm(T[None] - P[:, None], axis=2)
            r = np.max(np.abs(l1 - l0), axis=1)
        return r[0] if single else r

    def evaluate(self, x) -> np.ndarray:
        """[x, 1] Q [x, 1]ᵀ (zero on the space; Q has unit norm). Shape () or (K,)."""
        H, single = _homogeneous(x)
        v = np.einsum("ki,ij,kj->k", H, self.Q, H)
        return v[0] if single else v

    def gradient(self, x) -> np.ndarray:
        """Gradient of :meth:`evaluate`, shape (d,) or (K, d)."""
        H, single = _homogeneous(x)
        g = 2.0 * H @ self.Q[:, : self.dim]
        return g[0] if single else g

    # -- geometry -----------------------------------------------------------------------------
    def on_line(self, origin, direction) -> np.ndarray:
        """Parameters t where origin + t·direction lies on the space (0, 1 or 2 real values)."""
        o = np.append(np.asarray(origin, float), 1.0)
        u = np.append(np.asarray(direction, float), 0.0)
        a, b, c = u @ self.Q @ u, 2.0 * (u @ self.Q @ o), o @ self.Q @ o
        if abs(a) <= LINEAR_RTOL * (abs(b) + abs(c)):
            return np.array([-c / b]) if b != 0 else np.array([])
        disc = b * b - 4 * a * c
        if disc < 0:
            return np.array([])
        sq = np.sqrt(disc)
        q = -0.5 * (b + np.copysign(sq, b))   # stable quadratic roots
        roots = [q / a] + ([c / q] if q != 0 else [])
        return np.array(sorted(roots))

    def nearest(self, point) -> np.ndarray:
        """A point of the space near ``point``: along the gradient line through it (exact; the
        point itself if it lies on the space).

        Raises
        ------
        DesignError
            When the line misses the space.
        """
        p = np.asarray(point, dtype=np.float64)
        g = self.gradient(p)
        if np.linalg.norm(g) == 0:
            raise DesignError(f"cannot project {p.tolist()} onto the {self.kind} space "
                              "(zero gradient there)")
        t = self.on_line(p, g / np.linalg.norm(g))
        if t.size == 0:
            raise DesignError(f"the {self.kind} space has no point near {p.tolist()}; "
                              "move the hint closer to it")
        return p + t[np.argmin(np.abs(t))] * g / np.linalg.norm(g)

    def sample(self, count: int = 400, center=None, radius: float | None = None) -> np.ndarray:
        """Points of the space: where rays from ``center`` (2D: a fan of directions; 3D: a
        Fibonacci sphere of directions) cross it, within ``radius``.

        Returns
        -------
        numpy.ndarray, shape (M, d)
        """
        c = self.designed.mean(axis=0) if center is None else np.asarray(center, float)
        R = 4.0 * self.scale if radius is None else float(radius)
        if self.dim == 2:
            th = np.linspace(0, np.pi, int(count), endpoint=False)
            dirs = np.stack([np.cos(th), np.sin(th)], axis=1)
        else:
            i = np.arange(int(count)) + 0.5
            phi = np.arccos(1 - i / count)  # upper hemisphere: lines cover both halves
            th = np.pi * (1 + 5 ** 0.5) * i
            dirs = np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], 1)
        pts = np.array([c + t * u for u in dirs for t in self.on_line(c, u) if abs(t) <= R])
        return self._nontrivial(pts.reshape(-1, self.dim))

    def _nontrivial(self, pts: np.ndarray) -> np.ndarray:
        """Drop points at a designed node (a zero-length edge solves every condition)."""
        if pts.size == 0:
            return pts
        dist = np.min(np.linalg.norm(pts[:, None] - self.designed[None], axis=2), axis=1)
        return pts[dist > _TRIVIAL_RTOL * self.scale]

    def restricted(self, origin, u, v) -> np.ndarray:
        """The 3×3 conic this quadric cuts out of the plane origin + s·u + t·v."""
        T = np.zeros((self.dim + 1, 3))
        T[: self.dim, 0], T[: self.dim, 1], T[: self.dim, 2] = u, v, origin
        T[self.dim, 2] = 1.0
        return T.T @ self.Q @ T

    def intersect(self, other: "SolutionSpace", slices: int = 60) -> np.ndarray:
        """Exact common points of two spaces.

        2D: the (at most 4) intersection points of the two conics, polished by Newton's method
        on both defining polynomials, trivial points (at a designed node) removed. 3D: points of
        the intersection curve, cut by ``slices`` parallel planes.

        Returns
        -------
        numpy.ndarray, shape (M, d)
        """
        if self.dim != other.dim:
            raise DesignError("cannot intersect a 2D space with a 3D one")
        if self.dim == 2:
            pts = _conic_intersections(self.Q, other.Q)
        else:
            c = self.designed.mean(axis=0)
            R = 4.0 * self.scale
            normal = np.array([0.3, 0.5, 0.81])
            normal /= np.linalg.norm(normal)
            u = np.cross(normal, [1.0, 0, 0])
            u /= np.linalg.norm(u)
            v = np.cross(normal, u)
            pts = []
            for h in np.linspace(-R, R, int(slices)):
                o = c + h * normal
                for st in _conic_intersections(self.restricted(o, u, v), other.restricted(o, u, v)):
                    pts.append(o + st[0] * u + st[1] * v)
            pts = np.array(pts).reshape(-1, 3)
        if pts.size:
            pts = self._nontrivial(np.array([_polish(p, self, other) for p in pts]))
        return pts

    def as_dict(self) -> dict:
        return {"kind": self.kind, "Q": self.Q.tolist()}


def _polish(p, s1, s2, iters=8):
    """Newton on the two exact conditions (2D: 2 equations, 2 unknowns; 3D: minimum-norm steps
    that stay close to the slice point)."""
    x = np.array(p, dtype=np.float64)
    for _ in range(iters):
        F = np.array([s1.evaluate(x), s2.evaluate(x)])
        J = np.stack([s1.gradient(x), s2.gradient(x)])
        if np.max(np.abs(F)) < POLISHED:
            break
        step = np.linalg.lstsq(J, F, rcond=None)[0]
        x = x - step
    return x


def _conic_intersections(Q1: np.ndarray, Q2: np.ndarray) -> np.ndarray:
    """Real common points of two conics [x y 1] Q [x y 1]ᵀ = 0 (resultant in x, a quartic)."""
    # A fixed rotation keeps designs aligned with the axes (e.g. two points on one vertical line)
    # away from the degenerate cases of eliminating y.
    th = 0.4142135623730951
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1.0]])
    A1, A2 = R.T @ Q1 @ R, R.T @ Q2 @ R  # conics in rotated coordinates x' = Rᵀ x

    def coeffs(Q):
        # Q as a quadratic in y: a y² + b(x) y + c(x), polynomials in x (numpy.polynomial order)
        a = np.array([Q[1, 1]])
        b = np.array([2 * Q[1, 2], 2 * Q[0, 1]])
        c = np.array([Q[2, 2], 2 * Q[0, 2], Q[0, 0]])
        return a, b, c

    P = np.polynomial.polynomial
    a1, b1, c1 = coeffs(A1)
    a2, b2, c2 = coeffs(A2)
    ac = P.polysub(P.polymul(a1, c2), P.polymul(a2, c1))
    ab = P.polysub(P.polymul(a1, b2), P.polymul(a2, b1))
    bc = P.polysub(P.polymul(b1, c2), P.polymul(b2, c1))
    res = P.polysub(P.polymul(ac, ac), P.polymul(ab, bc))
    res = np.trim_zeros(res, "b")
    if res.size < 2:
        return np.zeros((0, 2))
    roots = P.polyroots(res)
    scale = max(1.0, float(np.max(np.abs(roots)))) if roots.size else 1.0
    pts = []
    for r in roots:
        if abs(r.imag) > REAL_ROOT_RTOL * max(1.0, abs(r)):
            continue
        x = r.real
        den = P.polyval(x, ab)
        if abs(den) > SHARED_QUADRATIC:
            ys = [-P.polyval(x, ac) / den]
        else:  # both conics share the same y-quadratic here: take the roots of the first
            qa, qb, qc = P.polyval(x, a1), P.polyval(x, b1), P.polyval(x, c1)
            disc = qb * qb - 4 * qa * qc
            ys = [] if disc < 0 or qa == 0 else [(-qb + s * np.sqrt(disc)) / (2 * qa) for s in (1, -1)]
        for y in ys:
            pts.append(R[:2, :2] @ np.array([x, y]))
    if not pts:
        return np.zeros((0, 2))
    pts = np.array(pts)
    # drop duplicates (double roots)
    out = []
    for p in pts:
        if all(np.linalg.norm(p - q) > DUPLICATE_RTOL * scale for q in out):
            out.append(p)
    return np.array(out)


def _fit_space(kind, designed, target) -> SolutionSpace:
    n, d = designed.shape
    if n != d + 1:
        raise DesignError(f"a solution space needs exactly {d + 1} designed nodes in {d}D "
                          f"(one variable node joined to all of them), got {n}")
    proto = SolutionSpace(kind, designed, target, np.zeros((d + 1, d + 1)))
    # The condition is an exact quadratic polynomial: fitting it at enough well-spread points
    # recovers its coefficients to round-off.
    c = designed.mean(axis=0)
    s = proto.scale
    rng = np.random.default_rng(12345)
    pts = c + s * rng.uniform(-2.0, 2.0, size=(6 * (d + 1) ** 2, d))
    with np.errstate(all="ignore"):
        vals = proto.condition(pts)
        M = _monomials((pts - c) / s)
    if not (np.isfinite(vals).all() and np.isfinite(M).all()):
        # before LAPACK, which would print to the terminal and fail on what overflowed
        raise DesignError(f"the {kind} specification overflows floating point (designed nodes "
                          f"of size {s:.3g}): give positions and targets of ordinary size")
    coef, *_ = np.linalg.lstsq(M, vals, rcond=None)
    Qn = _q_from_coeffs(coef, d)        # in normalised coordinates y = (x - c) / s
    T = np.eye(d + 1)
    T[:d, :d] /= s
    T[:d, d] = -c / s                   # y = T x
    Q = T.T @ Qn @ T
    norm = np.linalg.norm(Q)
    # size of the condition's terms: positions ~ s, velocities ~ |v| (velocity: a determinant
    # of d + 1 rows, one of them ~ s |v|); final positions ~ s (displacement: squared lengths)
    vmax = float(np.max(np.abs(target))) or 1.0
    typical = s ** d * s * vmax if kind == "velocity" else s * s
    if not np.isfinite(norm) or np.max(np.abs(vals)) <= NO_CONDITION_RTOL * typical:
        raise DesignError(f"the {kind} specification puts no condition on the variable node "
                          "(every position is a solution): the designed motion is rigid")
    return SolutionSpace(kind, designed, target, Q / norm)


def velocity_space(designed, velocities) -> SolutionSpace:
    """Positions of a variable node compatible with designed node velocities.

    Parameters
    ----------
    designed : array_like, shape (d + 1, d)
        Positions of the designed nodes (design units).
    velocities : array_like, shape (d + 1, d)
        Their velocities (design units per unit time; only directions and ratios matter).

    Returns
    -------
    SolutionSpace

    Raises
    ------
    DesignError
        Wrong shapes, or a rigid-body velocity (no condition).

    Examples
    --------
    >>> s = velocity_space([[-0.866, -0.5], [0, 1], [0.866, -0.5]], [[-0.5, 0], [0, 0], [0, 0]])
    >>> abs(float(s.condition(s.nearest([-1.0, 1.0])))) < 1e-12
    True
    """
    x = _as_points(designed, "designed")
    v = _as_points(velocities, "velocities", x.shape[1], x.shape[0])
    return _fit_space("velocity", x, v)


def displacement_space(designed, final) -> SolutionSpace:
    """Initial positions of a variable node compatible with designed initial and final
    positions (the node's final position is :meth:`SolutionSpace.partner`).

    Parameters
    ----------
    designed : array_like, shape (d + 1, d)
    final : array_like, shape (d + 1, d)

    Returns
    -------
    SolutionSpace
    """
    x = _as_points(designed, "designed")
    f = _as_points(final, "final", x.shape[1], x.shape[0])
    return _fit_space("displacement", x, f)


@dataclass(frozen=True, eq=False)
class DesignReport:
    """A designed module and how well it meets its specification.

    Attributes
    ----------
    network : Network
        Designed nodes first (0..n-1), then the variable nodes; each variable node joined to
        every designed node.
    spaces : list of SolutionSpace
    variable : numpy.ndarray, shape (m, d)
    residuals : dict
        Per space kind: the largest :meth:`SolutionSpace.residual` over the variable nodes.
    meets : dict
        Per space kind: residual <= tol.
    modes : ModeCount
    final_positions : numpy.ndarray or None
        The whole module's final configuration (displacement specification).
    """

    network: Network
    spaces: list
    variable: np.ndarray
    residuals: dict
    meets: dict
    modes: object
    final_positions: np.ndarray | None = None
    tol: float = 1e-10

    def as_dict(self) -> dict:
        out = {
            "variable_nodes": self.variable.tolist(),
            "residuals": self.residuals,
            "meets": self.meets,
            "tolerance": self.tol,
            "conformational_motions": int(self.modes.conformational),
            "self_stresses": int(self.modes.self_stress),
        }
        net = self.network
        if "d1" in net.ports and "d2" in net.ports:
            out["initial"] = {"d1": float(net.port_distance("d1")),
                              "d2": float(net.port_distance("d2"))}
            if self.final_positions is not None:
                out["final"] = {"d1": float(net.port_distance("d1", self.final_positions)),
                                "d2": float(net.port_distance("d2", self.final_positions))}
        return out


def _choose(candidates: np.ndarray, near: np.ndarray, what: str) -> np.ndarray:
    if candidates.shape[0] < near.shape[0]:
        raise DesignError(f"the {what} has only {candidates.shape[0]} admissible point(s); "
                          f"{near.shape[0]} variable nodes were asked for")
    chosen, used = [], set()
    for h in near:
        order = np.argsort(np.linalg.norm(candidates - h, axis=1))
        k = next(int(i) for i in order if int(i) not in used)
        used.add(k)
        chosen.append(candidates[k])
    return np.array(chosen)


def design_module(designed, *, velocities=None, final=None, variable=None, near=None,
                  ports=None, tol: float = 1e-10) -> DesignReport:
    """Design a module: designed nodes plus variable nodes on the solution spaces.

    Parameters
    ----------
    designed : array_like, shape (d + 1, d)
        Initial positions of the designed nodes.
    velocities : array_like, shape (d + 1, d), optional
        Designed velocities (fix the slope of the map at the initial point).
    final : array_like, shape (d + 1, d), optional
        Designed final positions (fix a second point of the map).
    variable : array_like, shape (m, d), optional
        Variable nodes given explicitly (checked against the spaces, not moved).
    near : array_like, shape (m, d), optional
        How to choose the variable nodes: with both specifications, the intersection point of
        the two spaces nearest to each hint; with one, the point of its space nearest to each
        hint. Without hints and with both specifications, the pair (2D) of intersection points
        that gives one conformational motion with the best-conditioned rigidity matrix.
    ports : dict, optional
        Port name -> node pair (default d1 = (0, 1), d2 = (1, 2)).
    tol : float
        Residual (design units) below which a specification counts as met.

    Returns
    -------
    DesignReport

    Raises
    ------
    DesignError
        No specification, inconsistent shapes, no admissible points, or a module without
        exactly one conformational motion (the message says how many it has).

    Examples
    --------
    >>> r = design_module([[-0.866, -0.5], [0, 1], [0.866, -0.5]],
    ...                   velocities=[[-0.5, 0], [0, 0], [0, 0]],
    ...                   final=[[-1.4722, -0.85], [0, 1.7], [1.4722, -0.85]],
    ...                   near=[[-0.9, -1.5], [-0.9, 1.5]])
    >>> r.meets, r.modes.conformational
    ({'velocity': True, 'displacement': True}, 1)
    """
    x0 = _as_points(designed, "designed")
    n, d = x0.shape
    spaces = []
    if velocities is not None:
        spaces.append(velocity_space(x0, velocities))
    if final is not None:
        spaces.append(displacement_space(x0, final))
    if not spaces:
        raise DesignError("give `velocities`, `final` or both: the specification of the motion")
    if variable is not None:
        var = _as_points(variable, "variable", d)
    elif near is not None:
        hints = _as_points(near, "near", d)
        if len(spaces) == 2:
            if d != 2:
                raise DesignError("in 3D, both specifications meet in curves: give `variable` "
                                  "points (e.g. from SolutionSpace.intersect) explicitly")
            var = _choose(spaces[0].intersect(spaces[1]), hints,
                          "intersection of the velocity and displacement spaces")
        else:
            var = np.array([spaces[0].nearest(h) for h in hints])
    elif len(spaces) == 2 and d == 2:
        var = None
        cands = spaces[0].intersect(spaces[1])
        best = -1.0
        for combo in itertools.combinations(range(len(cands)), 2):
            trial = _module(x0, cands[list(combo)], ports)
            mc = count_modes(trial)
            if mc.conformational == 1 and mc.self_stress == 0 and mc.smallest_nonzero > best:
                best, var = mc.smallest_nonzero, cands[list(combo)]
        if var is None:
            raise DesignError(f"no pair of the {len(cands)} intersection points gives a module "
                              "with one conformational motion; change the specification")
    else:
        raise DesignError("say where the variable nodes go: give `variable` positions or "
                          "`near` hints (one per variable node)")
    net = _module(x0, var, ports)
    modes = count_modes(net)
    if modes.conformational != 1:
        raise DesignError(
            f"the designed module has {modes.conformational} conformational motions "
            f"({modes.self_stress} self-stresses); it needs exactly 1: add or move variable nodes")
    residuals = {s.kind: float(np.max(s.residual(var))) for s in spaces}
    meets = {k: bool(v <= tol) for k, v in residuals.items()}
    final_positions = None
    disp = [s for s in spaces if s.kind == "displacement"]
    if disp:
        final_positions = np.concatenate([disp[0].target, disp[0].partner(var)], axis=0)
    return DesignReport(network=net, spaces=spaces, variable=var, residuals=residuals,
                        meets=meets, modes=modes, final_positions=final_positions, tol=tol)


def _module(x0, var, ports) -> Network:
    n = x0.shape[0]
    m = var.shape[0]
    edges = [(i, n + j) for j in range(m) for i in range(n)]
    if ports is None:
        ports = {"d1": (0, 1), "d2": (1, 2)} if n >= 3 else {}
    return Network(np.concatenate([x0, var], axis=0), edges, ports=dict(ports))


_DESIGN_KEYS = {"designed", "velocities", "final", "variable", "near", "ports", "tolerance"}


def build_designed_module(section: dict, ctx) -> Network:
    """Builder of the ``[design]`` template section (see :func:`design_module`)::

        [design]
        designed = [[-0.866, -0.5], [0.0, 1.0], [0.866, -0.5]]   # initial positions
        velocities = [[-0.5, 0.0], [0.0, 0.0], [0.0, 0.0]]       # optional
        final = [[-1.472, -0.85], [0.0, 1.7], [1.472, -0.85]]     # optional
        near = [[-0.9, -1.5], [-0.9, 1.5]]    # where to choose the variable nodes (or `variable`)
        ports = { d1 = [0, 1], d2 = [1, 2] }  # optional (this is the default)
        tolerance = 1e-10                     # optional

    The builder's report (variable nodes, residuals, which specifications are met, mode count,
    initial and final d1, d2) goes into ``ctx.meta["design"]``.
    """
    ctx.check_keys(section, "design", _DESIGN_KEYS)

    def points(key, required=False):
        value = ctx.get(section, key, "design", list, required=required)
        if value is None:
            return None
        try:
            return _as_points(value, key)
        except DesignError as exc:
            raise ctx.error(f"design.{key}", str(exc).replace(f"`{key}` ", "")) from None

    designed = points("designed", required=True)
    kwargs = {k: points(k) for k in ("velocities", "final", "variable", "near")}
    for key in ("velocities", "final"):
        if kwargs[key] is not None and kwargs[key].shape != designed.shape:
            raise ctx.error(f"design.{key}", f"must have shape {designed.shape} like `designed`, "
                                             f"got {kwargs[key].shape}")
    ports_raw = ctx.get(section, "ports", "design", dict, required=False)
    ports = None
    if ports_raw is not None:
        ports = {}
        for name, pair in ports_raw.items():
            if (not isinstance(pair, list) or len(pair) != 2
                    or any(isinstance(v, bool) or not isinstance(v, int) for v in pair)):
                raise ctx.error(f"design.ports.{name}", "must be a pair of node indices")
            ports[name] = tuple(pair)
    tol = ctx.get(section, "tolerance", "design", "number", required=False, default=1e-10)
    try:
        report = design_module(designed, ports=ports, tol=tol, **kwargs)
    except DesignError as exc:
        raise ctx.error("design", str(exc)) from None
    if not all(report.meets.values()):
        failed = ", ".join(f"{k} (residual {report.residuals[k]:.3g})"
                           for k, ok in report.meets.items() if not ok)
        raise ctx.error("design", f"the variable nodes do not meet the {failed} specification "
                                  f"to {tol:g}; move them onto the solution spaces")
    ctx.meta["design"] = report.as_dict()
    return report.network
