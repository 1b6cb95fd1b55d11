"""Shared numerics: named tolerances, rigid best fits, projection onto edge lengths.

Every module that needs one of these uses the function here; none writes its own. The tolerances
are named once, each with a sentence on where its value comes from, so that a threshold has one
meaning wherever it is used.

Examples
--------
>>> import numpy as np
>>> from fabkit.numerics import rigid_fit
>>> src = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
>>> fit = rigid_fit(src, src[:, ::-1] + 1.0, handedness="any")
>>> bool(fit.rms < 1e-12), bool(np.linalg.det(fit.rotation) < 0)
(True, True)
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

__all__ = [
    "one_blas_thread",
    "SMALL_DENSE",
    "EPS",
    "FLAT_RTOL",
    "RANK_RTOL",
    "EDGE_RTOL",
    "SLOPE_TOL",
    "NEUTRAL_SLOPE_TOL",
    "START_RTOL",
    "DOMAIN_RTOL",
    "FIXED_POINT_RTOL",
    "TINY",
    "MM_SLACK",
    "COLLINEAR_PARENTS_RTOL",
    "FLAT_SHEET_RTOL",
    "TARGET_AT_TURN_RTOL",
    "FLAT_SIDE_SINE",
    "FRAME_MIN_SINE",
    "canonical_order",
    "canonical_frame",
    "RigidFit",
    "rigid_fit",
    "apply_fit",
    "Projection",
    "project_to_lengths",
    "row_norms",
]

#: Machine epsilon of float64: the relative round-off of one arithmetic operation.
EPS = float(np.finfo(np.float64).eps)

#: A triangle counts as flat when its squared height h² is above ``-FLAT_RTOL · r²`` but not above
#: zero: circle intersections of unit-size modules carry ~1e-16 relative round-off in h², and a
#: 10 000-module chain accumulates a few hundred ulps; 1e-12 keeps four decades of margin above
#: that while a real gap (no intersection) is orders of magnitude larger.
FLAT_RTOL = 1e-12

#: Singular values of the row-normalised rigidity matrix at or below ``RANK_RTOL · max(σ_max, 1)``
#: count as zero. Round-off puts the zero singular values of the paper's networks near 1e-15 and
#: the smallest genuine ones above 1e-6 (measured over the bundled templates), so 1e-9 sits in the
#: middle of that gap on a log scale.
RANK_RTOL = 1e-9

#: Relative edge-length error a projected configuration must reach to count as on the constraint
#: set: round-off leaves ~1e-15 on modules and up to ~1e-13 on 10 000-module chains, so 1e-12 is
#: met by every converged Newton solve and missed by any that stalled.
EDGE_RTOL = 1e-12

#: Slopes of a 1-D map within ``SLOPE_TOL`` of 0 or ±1 are called super-stable / marginal: the
#: exact derivatives are good to ~1e-12, and the paper's designed values (0, 1, 1.5) are meant
#: exactly, so a design that misses by more than 1e-6 is a different design.
SLOPE_TOL = 1e-6

#: A slope within this of ±1 is marginal (neutral). A fixed point of slope +1 is a touching
#: root of f(d) - d: changing the design by ε moves its slope off 1 by ~√ε (1e-6 for coordinates
#: changed by 1e-12 of their size, as typing them to 12 digits does) and may split it into two
#: fixed points that far apart, so the class is read with two decades of room above that.
NEUTRAL_SLOPE_TOL = 1e-4

#: A start configuration is accepted when its edges match their rest lengths to this relative
#: error: template coordinates are typed with ~10 significant digits, so 1e-8 admits them and
#: refuses a start that is visibly off its constraint set.
START_RTOL = 1e-8


#: A map argument this far (relative to the domain's size) outside a branch's domain still counts
#: as inside and is clipped to it: branch ends come from root finding to round-off, and arithmetic
#: on them (a chain's d_k) adds a few ulps that must not turn an end point into "no value".
DOMAIN_RTOL = 1e-12

#: A root of f(d) - d (or of f^m(d) - d) is a fixed point (cycle point) when the residual is at
#: most this, relative to the domain's size: brentq lands within a few ulps, so genuine roots sit
#: near 1e-15, while a near miss of a touching root (a local minimum of |f(d) - d|) stays far above.
FIXED_POINT_RTOL = 1e-10

#: A node placed from three parents (3D) has no place when the third parent lies within this
#: (relative to the first two's distance) of the line through them: the parents fix no plane, the
#: node may turn about that line (a flat state where branches meet, such as the flat origami
#: sheet), and the place computed there is round-off. Just above it the place is good to
#: ~EPS / 1e-9 ≈ 2e-7 relative (a chain of sheets keeps its first sheet this close to flat while
#: its last one unfolds); a branch that ends on such a state ends within an ulp of it.
COLLINEAR_PARENTS_RTOL = 1e-9

#: A sheet of paper counts as given flat when its nodes lie within this (relative to its size) of
#: one plane: template coordinates carry ~1e-16 of round-off and are typed to ~10 digits, while a
#: sheet folded by any visible angle leaves the plane by more than 1e-3.
FLAT_SHEET_RTOL = 1e-9

#: A target that lies past the end of its branch (a turning point of the drive) by at most this,
#: relative to the drive's values, is reached within rounding: the motion ends at the turning
#: point and says so. A design placed at a fold (the super-stable chain driven to D2* + 1e-12)
#: moves its turning point by ~1e-10 when its coordinates change by 1e-12, far below this, and
#: 1e-8 of a 100 mm module is 1 nm.
TARGET_AT_TURN_RTOL = 1e-8

#: A node reads its side of its parents' line (plane) off a reference configuration only when
#: the sine of its angle to them is at least this: nearer, the reference is a flat state and the
#: side is not a property of the design (a change of its coordinates by 1e-12 of its size, or
#: typing them to 10 digits, would pick it), so the branch is chosen by a stated rule instead.
FLAT_SIDE_SINE = 1e-8

#: A positive floor for a divisor or a scale that may be zero (a degenerate network, an empty
#: sum): far below any length, area or time fabkit meets, so it replaces only an exact zero and
#: changes no other value.
TINY = 1e-300

#: Slack of comparisons between lengths in mm (a part against a sheet or a bed, a screw against
#: its stack, a rounding to whole units): sums of mm values of up to metres carry ~1e-13 mm of
#: round-off, and 1e-9 mm is far below anything a laser or a printer makes, so a part that fits
#: exactly is not refused for an ulp.
MM_SLACK = 1e-9

# -- rigid best fit (Kabsch) -------------------------------------------------------------------

@dataclass(frozen=True)
class RigidFit:
    """A rigid motion ``y = x @ rotation.T + shift`` and the RMS distance it leaves.

    Attributes
    ----------
    rotation : numpy.ndarray, shape (..., d, d)
        Orthogonal; det +1 for a proper fit, -1 for an improper one.
    shift : numpy.ndarray, shape (..., d)
    rms : numpy.ndarray or float, shape (...)
        Root-mean-square distance between the moved source points and the destination points.
    """

    rotation: np.ndarray
    shift: np.ndarray
    rms: np.ndarray | float


def row_norms(v) -> np.ndarray:
    """Euclidean norms over the last axis of ``v`` (2 or 3 components, or any number), the
    bits of ``np.linalg.norm(v, axis=-1)``.

    The squares are added component by component, in the order numpy's reduction adds two or
    three numbers; numpy's reduction over a short last axis costs several times as much
    (0.4 s against 0.06 s for the 3·10⁶ rows of a million-module chain's plan).

    Examples
    --------
    >>> v = np.array([[3.0, 4.0], [1e-200, 0.0]])
    >>> row_norms(v).tolist() == np.linalg.norm(v, axis=-1).tolist()
    True
    """
    v = np.asarray(v, dtype=np.float64)
    if v.ndim == 0 or v.shape[-1] not in (2, 3):
        return np.linalg.norm(v, axis=-1)
    c = v[..., 0]
    out = c * c
    for k in range(1, v.shape[-1]):
        c = v[..., k]
        out += c * c
    return np.sqrt(out, out=out)


_HANDEDNESS = ("proper", "improper", "any")


def rigid_fit(src, dst, *, handedness: str = "proper") -> RigidFit:
    """Least-squares rigid motion of ``src`` onto ``dst`` (Kabsch), batched over leading axes.

    Parameters
    ----------
    src, dst : array_like, shape (..., K, d)
        Corresponding points, d = 2 or 3; leading axes broadcast against each other.
    handedness : {"proper", "improper", "any"}
        "proper" keeps det(rotation) = +1 (no mirror), "improper" forces a mirror image
        (det -1), "any" takes whichever fits best.

    Returns
    -------
    RigidFit

    Raises
    ------
    ValueError
        Unknown handedness, or shapes that do not match.

    Examples
    --------
    >>> fit = rigid_fit([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[1, 1, 1], [1, 2, 1], [0, 1, 1]])
    >>> round(float(fit.rms), 12), round(float(np.linalg.det(fit.rotation)), 12)
    (0.0, 1.0)
    """
    if handedness not in _HANDEDNESS:
        raise ValueError(f"`handedness` must be one of {', '.join(_HANDEDNESS)}, got {handedness!r}")
    p = np.asarray(src, dtype=np.float64)
    q = np.asarray(dst, dtype=np.float64)
    if p.ndim < 2 or p.shape[-1] != q.shape[-1] or p.shape[-2] != q.shape[-2]:
        raise ValueError(f"`src` and `dst` must both have shape (..., K, d), got {p.shape} and "
                         f"{q.shape}")
    cp = p.mean(axis=-2, keepdims=True)
    cq = q.mean(axis=-2, keepdims=True)
    h = np.swapaxes(p - cp, -1, -2) @ (q - cq)
    u, _, vt = np.linalg.svd(h)
    v, ut = np.swapaxes(vt, -1, -2), np.swapaxes(u, -1, -2)
    if handedness != "any":
        det = np.linalg.det(v @ ut)
        want = 1.0 if handedness == "proper" else -1.0
        # Flip the least significant axis where the fitted handedness is not the one asked for.
        flip = np.where(det * want < 0, -1.0, 1.0)
        v = v.copy()
        v[..., :, -1] *= flip[..., None]
    rot = v @ ut
    shift = cq[..., 0, :] - (cp @ np.swapaxes(rot, -1, -2))[..., 0, :]
    moved = p @ np.swapaxes(rot, -1, -2) + shift[..., None, :]
    rms = np.sqrt(np.mean(np.sum((moved - q) ** 2, axis=-1), axis=-1))
    return RigidFit(rot, shift, rms)


def apply_fit(fit: RigidFit, x) -> np.ndarray:
    """Move points by a fitted rigid motion.

    Parameters
    ----------
    fit : RigidFit
        From :func:`rigid_fit`, batched over leading axes (...).
    x : array_like, shape (..., N, d)

    Returns
    -------
    numpy.ndarray, shape (..., N, d)
    """
    x = np.asarray(x, dtype=np.float64)
    return x @ np.swapaxes(fit.rotation, -1, -2) + fit.shift[..., None, :]


# -- projection onto prescribed edge lengths -----------------------------------------------------

@dataclass(frozen=True)
class Projection:
    """The outcome of :func:`project_to_lengths`.

    Attributes
    ----------
    positions : numpy.ndarray, shape (..., N, d)
        The last iterate (on the constraint set when ``converged``).
    residual : float
        Largest relative length error left, ``max |ℓ - L| / L`` over edges, pairs and batch.
    converged : bool
        Whether ``residual <= rtol``.
    iterations : int
    """

    positions: np.ndarray
    residual: float
    converged: bool
    iterations: int


# Above this many unknowns per configuration, a dense pseudo-inverse (an SVD per step) costs more
# than sparse LSQR: modules (<= ~30 unknowns) go dense and batched, chains and lattices sparse.
_DENSE_MAX_UNKNOWNS = 96
# Up to this many, one rank-revealing QR per configuration (LAPACK gelsy) beats LSQR, whose
# iterations grow with the condition (the and-gate's 196 unknowns: 1.7 ms against 5.5 ms).
_QR_MAX_UNKNOWNS = 400
# Singular values below this fraction of the largest are taken as zero by the dense and QR
# steps: dependent rows (a state of self-stress) then give the least-squares step of least norm.
_STEP_RCOND = 1e-13


def project_to_lengths(edges, lengths, x0, *, pairs=(), targets=None, rtol: float = EDGE_RTOL,
                       max_iter: int = 40) -> Projection:
    """Gauss-Newton with minimum-norm steps onto ``|x_i - x_j| = L`` for every edge.

    Minimum-norm steps move the configuration as little as possible, so the result is the
    nearest point of the constraint set to first order: the right choice for correcting a
    predicted or perturbed configuration without adding a rigid motion. Newton runs down to the
    round-off floor (it stops when the residual no longer contracts), then the result is judged
    against ``rtol``.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    lengths : array_like, shape (E,) or (..., E)
        Prescribed lengths, > 0; a leading batch axis gives each configuration its own lengths.
    x0 : array_like, shape (N, d) or (B, N, d)
        Start configuration(s).
    pairs : sequence of (int, int), optional
        Extra distances to prescribe (e.g. a drive distance).
    targets : array_like, shape (P,) or (B, P), optional
        Their values.
    rtol : float
        Relative length error accepted as converged.
    max_iter : int

    Returns
    -------
    Projection
        Never raises on non-convergence: the caller decides on ``converged``.

    Examples
    --------
    >>> sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    >>> e = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    >>> p = project_to_lengths(e, np.ones(4), sq + 0.01 * np.eye(4, 2))
    >>> p.converged, bool(p.residual < 1e-14)
    (True, True)
    """
    x = np.array(x0, dtype=np.float64)
    single = x.ndim == 2
    if single:
        x = x[None]
    if x.ndim != 3:
        raise ValueError(f"`x0` must have shape (N, d) or (B, N, d), got {np.shape(x0)}")
    nb, n, dim = x.shape
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    pr = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    ij = np.concatenate([e, pr])
    lens = np.broadcast_to(np.asarray(lengths, dtype=np.float64), (nb, e.shape[0]))
    if pr.shape[0]:
        if targets is None:
            raise ValueError("`targets` must be given with `pairs`")
        tg = np.broadcast_to(np.asarray(targets, dtype=np.float64), (nb, pr.shape[0]))
        lens = np.concatenate([lens, tg], axis=1)
    if np.any(lens <= 0):
        raise ValueError("prescribed lengths must be positive")

    def residual(x):
        d = x[:, ij[:, 0]] - x[:, ij[:, 1]]
        ell = np.sqrt(np.einsum("bec,bec->be", d, d))
        return d, ell, ell - lens

    solver = (_dense_steps if n * dim <= _DENSE_MAX_UNKNOWNS
              else _qr_steps if n * dim <= _QR_MAX_UNKNOWNS else _sparse_steps)
    d, ell, res = residual(x)
    worst = float(np.max(np.abs(res) / lens)) if res.size else 0.0
    it, slow = 0, 0
    while it < max_iter and worst > EPS:
        u = d / np.maximum(ell, np.finfo(np.float64).tiny)[..., None]
        step = solver(u, ij, res, n, dim)
        x = x - step
        it += 1
        d, ell, res = residual(x)
        new = float(np.max(np.abs(res) / lens))
        # Quadratic convergence stalls at round-off: stop once an accepted residual stops halving.
        stalled = new > 0.5 * worst
        # Lengths that no configuration has (a network with a state of self-stress given
        # incompatible lengths) stall above rtol: stop after two steps that gain under 10 %.
        slow = slow + 1 if new > 0.9 * worst else 0
        worst = new
        if (stalled and worst <= rtol) or slow >= 2:
            break
    positions = x[0] if single else x
    return Projection(positions, worst, bool(worst <= rtol), it)


def _dense_steps(u, ij, res, n, dim):
    """Minimum-norm Gauss-Newton steps for a batch of small networks (batched pseudo-inverse)."""
    nb, m = res.shape
    rows = np.arange(m)
    jac = np.zeros((nb, m, n, dim))
    jac[:, rows, ij[:, 0]] = u
    # Subtract rather than assign: a pair may share a node with an edge row, never with itself.
    jac[:, rows, ij[:, 1]] -= u
    jac = jac.reshape(nb, m, n * dim)
    step = np.einsum("bij,bj->bi", np.linalg.pinv(jac, rcond=_STEP_RCOND), res)
    return step.reshape(nb, n, dim)


def _qr_steps(u, ij, res, n, dim):
    """Minimum-norm steps by a rank-revealing QR, one configuration at a time (mid-size)."""
    from scipy.linalg import lstsq

    nb, m = res.shape
    rows = np.arange(m)
    out = np.empty((nb, n * dim))
    jac = np.zeros((m, n, dim))
    for b in range(nb):
        jac[:] = 0.0
        jac[rows, ij[:, 0]] = u[b]
        jac[rows, ij[:, 1]] -= u[b]
        out[b] = lstsq(jac.reshape(m, n * dim), res[b], cond=_STEP_RCOND, lapack_driver="gelsy",
                       check_finite=False)[0]
    return out.reshape(nb, n, dim)


def _sparse_steps(u, ij, res, n, dim):
    """Minimum-norm steps by sparse LSQR, one configuration at a time (large networks)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.linalg import lsqr

    nb, m = res.shape
    rows = np.repeat(np.arange(m), 2 * dim)
    cols = np.concatenate([ij[:, :1] * dim + np.arange(dim), ij[:, 1:] * dim + np.arange(dim)],
                          axis=1).ravel()
    out = np.empty((nb, n * dim))
    for b in range(nb):
        vals = np.concatenate([u[b], -u[b]], axis=1).ravel()
        jac = csr_matrix((vals, (rows, cols)), shape=(m, n * dim))
        out[b] = lsqr(jac, res[b], atol=1e-15, btol=1e-15, iter_lim=20 * n * dim)[0]
    return out.reshape(nb, n, dim)


# -- an order and a frame that belong to a design -----------------------------------------

#: A bar sets the next axis of the frame when at least this part of its direction (the sine of
#: its angle to the axes so far) leaves their span: far from round-off, so the choice of bar
#: does not hang on the last bits of a nearly parallel one.
FRAME_MIN_SINE = 0.1


def canonical_order(edges, n: int) -> np.ndarray:
    """Joints in the order they first appear in the bar list, then joints on no bar.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    n : int
        Number of joints.

    Returns
    -------
    numpy.ndarray of int, shape (n,)
        ``order[k]`` is the joint at canonical position k.

    Examples
    --------
    >>> canonical_order([[2, 0], [0, 3]], 5).tolist()
    [2, 0, 3, 1, 4]
    """
    flat = np.asarray(edges, dtype=np.int64).reshape(-1)
    _, first = np.unique(flat, return_index=True)
    seen = flat[np.sort(first)]
    rest = np.setdiff1d(np.arange(n), seen, assume_unique=False)
    return np.concatenate([seen, rest]).astype(np.int64)


def canonical_frame(points, edges) -> np.ndarray:
    """An orthonormal frame that turns with the design (see the module docstring).

    Parameters
    ----------
    points : array_like, shape (N, d)
    edges : array_like of int, shape (E, 2)

    Returns
    -------
    numpy.ndarray, shape (d, d)
        Rows are the axes; a vector with coordinates ``c`` in the frame is ``c @ frame``.
        Proper (determinant +1) in 3D; in 2D it follows the design's own turn from its first
        bar to the next one across it.
    """
    x = np.asarray(points, dtype=np.float64)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    d = x.shape[1]
    vec = x[e[:, 1]] - x[e[:, 0]]
    norm = np.linalg.norm(vec, axis=1)
    vec = vec[norm > 0] / norm[norm > 0, None]
    axes: list[np.ndarray] = []
    want = d if d == 2 else 2
    for v in vec:
        r = v - sum((v @ a) * a for a in axes) if axes else v
        s = float(np.linalg.norm(r))
        if not axes or s >= FRAME_MIN_SINE:
            axes.append(r / max(s, TINY))
        if len(axes) == want:
            break
    if not axes:
        axes.append(np.eye(d)[0])
    if len(axes) < want:  # every bar on one line: a fixed perpendicular
        a = axes[0]
        k = int(np.argmin(np.abs(a)))
        if d == 2:
            axes.append(np.array([-a[1], a[0]]))
        else:
            p = np.cross(a, np.eye(3)[k])
            axes.append(p / np.linalg.norm(p))
    if d == 3:
        axes.append(np.cross(axes[0], axes[1]))
    return np.array(axes)


#: Printed numbers below this magnitude are round-off (1e-16 to 1e-15 of their scale) and differ
#: between CPUs' floating-point kernels: they are printed as round-off, never as digits, so that
#: every machine prints the same line.
ROUNDOFF_PRINT = 1e-12


def printed(value: float, spec: str = ".6g") -> str:
    """``value`` formatted with ``spec``, or ``"0 (round-off)"`` below :data:`ROUNDOFF_PRINT`.

    Examples
    --------
    >>> printed(-8.8e-16), printed(3.150961, ".4g")
    ('0 (round-off)', '3.151')
    """
    return "0 (round-off)" if abs(value) < ROUNDOFF_PRINT else format(value, spec)


def printed_residual(value: float) -> str:
    """A residual as ``"= 3.1e-09"``, or ``"< 1e-12"`` below :data:`ROUNDOFF_PRINT`."""
    return f"< {ROUNDOFF_PRINT:g}" if abs(value) < ROUNDOFF_PRINT else f"= {value:.1e}"


# -- one BLAS thread for small dense work -------------------------------------------------------
# Dense linear algebra on a network's small matrices (a trace's banded solves, a build's few
# hundred unknowns, the SVD of a rigidity matrix of a few hundred rows) gains nothing from BLAS
# threads: they only contend for the cores and spin between calls. The AND gate's tolerance
# builds took 16 s of CPU with OpenBLAS's default two threads on a two-core machine and 11 s with
# one (the SVD of its self-stresses alone: 4.7 s against 0.08 s). Work of that size runs inside
# one_blas_thread(); large dense work keeps the threads the process has (the user's setting, or
# the worker's share of the cores: fabkit.executor).

#: A dense matrix with at most this many rows and columns is small: its factorisation takes
#: milliseconds (an SVD of 1000 x 1000: ~0.5 s on one core), where threads cost more in start-up
#: and spinning than they save; larger work keeps the process's threads.
SMALL_DENSE = 1000

#: threadpoolctl's controller of the loaded BLAS and OpenMP libraries, with the number of
#: modules loaded when it looked them up: looking them up costs milliseconds (as much as a small
#: trace), so it is done again only after a module was imported (a library loads with the
#: module that needs it, as scipy.linalg brings its own OpenBLAS).
_controller: tuple[int, object] | None = None


def one_blas_thread():
    """Context manager: every loaded BLAS and OpenMP library on one thread within it.

    Examples
    --------
    >>> import numpy as np
    >>> with one_blas_thread():
    ...     float(np.linalg.svd(np.eye(3), compute_uv=False).sum())
    3.0
    """
    global _controller
    import threadpoolctl

    loaded = len(sys.modules)
    if _controller is None or _controller[0] != loaded:
        _controller = (loaded, threadpoolctl.ThreadpoolController())
    return _controller[1].limit(limits=1)
