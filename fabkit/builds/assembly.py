"""A build put together: bars with their own lengths, pins with play, and elastic give.

One energy answers both questions a maker has of a kit (../DESIGN.md, levels 5 and 6). Bar ``e``
with its own length ``L_e`` and axial room ``c_e`` (its holes' play) costs nothing while its pin
distance ``ℓ_e`` lies in ``[L_e - c_e, L_e + c_e]`` and ``½ k_e (|ℓ_e - L_e| - c_e)²`` beyond it
(``k_e = E A / L``: a spring with the play as a dead band). The least-energy placement of the
pins says:

- energy zero: the build **closes within its play** (no force needed);
- otherwise it is **forced**: the bars carry ``σ_e = E ε_e`` (``ε_e``: elongation beyond the
  play over the rest length), which decides whether the material takes it.

The energy is minimised by semi-smooth Gauss-Newton (bars inside their play contribute nothing to
the step, bars past it a spring each) with Levenberg-Marquardt damping and a backtracking line
search; held pairs (the drive, held ports) are exact constraints of every step. Among the many
zero-energy placements that play allows, the one taken uses the least play: bars as near their
own lengths as the loops let them be (:data:`INNER_STIFFNESS`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..numerics import TINY

__all__ = ["Assembled", "assemble", "bar_stress", "CLOSE_RTOL", "SETTLE_RTOL"]

#: A build closes within its play when no bar is strained past its play by more than this
#: fraction of its rest length: 1e-7 is 0.00001 mm on a 100 mm bar and 0.0003 MPa in acrylic,
#: nothing a maker can feel, and well above where the solver's steps stall on a flat loop (its
#: bars lying along one line, where lengths change only to second order with a sideways move).
CLOSE_RTOL = 1e-7

#: Stiffness of a bar within its play, as a fraction of its stiffness past it. Play costs no force
#: a maker can feel, but of the many placements it allows the one taken is the one that uses
#: least of it: each bar as near its own length as the others let it be (a build without
#: self-stress takes its own lengths exactly; one with a loop spreads the loop's misfit over it).
INNER_STIFFNESS = 1e-6

#: Weight of the proximal term against the bars' mean stiffness: small enough that it strains no
#: bar by more than ~1e-12 of the displacement, large enough to fix the rigid motions and the
#: mechanism's own motion, which no bar resists.
PROXIMAL = 1e-12

#: The solver stops when a step moves no pin by more than this fraction of the mean bar length.
STEP_RTOL = 1e-13

#: The solver narrows every play by this fraction of the bar's rest length (a quarter of
#: :data:`CLOSE_RTOL`), so that a bar pulled back to its play lands inside rather than on its edge.
INSIDE = 0.25e-7

#: The line search gives up halving a step below this fraction of it.
MIN_LINE_STEP = 1e-8

#: A flat loop (bars along one line) gives way only to second order: the solver stops after
#: three steps that lower the energy by less than this fraction.
STALL_RTOL = 1e-6

#: Stall fraction for a build that only has to say whether it closes and how it then moves (a
#: probe of the tolerance margin, not a reported placement): once no bar is past its play, the
#: energy left is the inner stiffness' tie-break between placements the play allows, and the
#: solver stops after three steps that lower it by less than this fraction. At ten times a laser
#: kit's errors the AND gate's builds close in a few dozen steps, then trade bars at the edges of
#: their play for up to 300 more, to placements 0.2–1.8 mm from where they settle (a build's play
#: is that wide): polishing them to :data:`STALL_RTOL` buys nothing (tests/test_builds.py).
SETTLE_RTOL = 1e-2

#: Cap on the steps. A kit whose loops run through bars without play (a print's bar that
#: carries both its pins) closes slowly, its bars at the edges of their play trading places in
#: the steps: the AND gate printed on pins needs up to ~210 where a laser kit needs ~10.
MAX_STEPS = 400

#: Above this many unknowns the steps are solved sparse (SuperLU) rather than dense.
DENSE_MAX_UNKNOWNS = 600

@dataclass(frozen=True)
class Assembled:
    """A build as it goes together.

    Attributes
    ----------
    positions : numpy.ndarray, shape (N, d)
        Pin positions.
    lengths : numpy.ndarray, shape (E,)
        Pin-to-pin distances of the bars (the lengths the build moves with).
    slack : numpy.ndarray, shape (E,)
        How much of its play each bar uses, ``|slack| <= room``.
    excess : numpy.ndarray, shape (E,)
        Elongation beyond the play (``lengths - rest - slack``): zero where a bar fits, its
        elastic strain times its rest length where the build is forced.
    energy : float
        Elastic energy ``½ Σ k_e excess_e²`` (force unit times length unit of the inputs).
    closes : bool
        No bar is strained past its play by more than :data:`CLOSE_RTOL` of its rest length.
    iterations : int
        Gauss-Newton steps taken.
    """

    positions: np.ndarray
    lengths: np.ndarray
    slack: np.ndarray
    excess: np.ndarray
    energy: float
    closes: bool
    iterations: int

    @property
    def strain(self) -> np.ndarray:
        """Axial strain of every bar beyond its play (needs the rest lengths: see
        :func:`bar_stress`); here relative to the pin distance."""
        return self.excess / self.lengths


def _check(edges, rest, room, x0, stiffness):
    e = np.asarray(edges, dtype=np.int64)
    if e.ndim != 2 or e.shape[1] != 2:
        raise ValueError(f"`edges` must have shape (E, 2), got {np.shape(edges)}")
    x = np.array(x0, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] not in (2, 3) or not np.all(np.isfinite(x)):
        raise ValueError(f"`x0` must be finite with shape (N, 2) or (N, 3), got {np.shape(x0)}")
    if e.size and (e.min() < 0 or e.max() >= x.shape[0]):
        raise ValueError(f"`edges` name nodes outside 0..{x.shape[0] - 1}")
    n_e = e.shape[0]
    r = np.asarray(rest, dtype=np.float64).reshape(-1)
    c = np.broadcast_to(np.asarray(room, dtype=np.float64), (n_e,)).copy() if np.ndim(room) == 0 \
        else np.asarray(room, dtype=np.float64).reshape(-1)
    k = np.ones(n_e) if stiffness is None else np.broadcast_to(
        np.asarray(stiffness, dtype=np.float64), (n_e,)).copy()
    for name, v in (("rest", r), ("room", c), ("stiffness", k)):
        if v.shape != (n_e,):
            raise ValueError(f"`{name}` must have shape ({n_e},), got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"`{name}` must be finite")
    if np.any(r <= 0) or np.any(c < 0) or np.any(k <= 0):
        raise ValueError("`rest` and `stiffness` must be > 0 and `room` >= 0")
    return e, r, c, k, x


def assemble(edges, rest, room, x0, *, stiffness=None, held=(), targets=None,
             max_iterations: int = MAX_STEPS, settle: float | None = None) -> Assembled:
    """Put a build together: the least-energy placement of pins whose bars have play.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    rest : array_like, shape (E,)
        Each bar's own hole-to-hole length (the build's, errors included).
    room : float or array_like, shape (E,)
        Each bar's axial room ``c_e >= 0``: its pin distance may be anything in
        ``[rest - c, rest + c]`` at no force (0: a bar that fits only at its own length).
    x0 : array_like, shape (N, d)
        Where the pins start (the nominal configuration).
    stiffness : array_like, shape (E,), optional
        Axial stiffness ``k_e = E A / L`` (force per length); the same for every bar when not
        given (then the energy is in length² and only ``closes`` and the placement mean much).
    held : sequence of (int, int), optional
        Node pairs whose distance is held exactly (the drive, held ports), at ``targets``.
    targets : array_like, shape (P,), optional
        Held distances (default: their distances in ``x0``).
    max_iterations : int
        Cap on the Gauss-Newton steps.
    settle : float, optional
        Stall fraction once every bar is within its play (:data:`SETTLE_RTOL` for a build whose
        placement is not reported); default :data:`STALL_RTOL` throughout.

    Returns
    -------
    Assembled

    Raises
    ------
    ValueError
        Shapes, non-finite or out-of-range values, nodes that do not exist, a ``settle`` that
        is not a positive number.

    Examples
    --------
    A braced square whose side is 0.01 too long, with 0.002 of room per bar: the loop's six
    bars give 0.002 · (4 + 2√2) = 0.0137 together, enough to close it; 0.001 is not.

    >>> sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    >>> e = [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3]]
    >>> rest = np.array([1.01, 1, 1, 1, np.sqrt(2), np.sqrt(2)])
    >>> assemble(e, rest, 0.002, sq).closes, assemble(e, rest, 0.001, sq).closes
    (True, False)
    """
    e, r, c, k, x = _check(edges, rest, room, x0, stiffness)
    n, d = x.shape
    hp = np.asarray(held, dtype=np.int64).reshape(-1, 2)
    if hp.size and (hp.min() < 0 or hp.max() >= n):
        raise ValueError(f"`held` names nodes outside 0..{n - 1}")
    ht = (np.linalg.norm(x[hp[:, 0]] - x[hp[:, 1]], axis=1) if targets is None
          else np.asarray(targets, dtype=np.float64).reshape(-1))
    if ht.shape != (hp.shape[0],) or not np.all(np.isfinite(ht)) or np.any(ht <= 0):
        raise ValueError(f"`targets` must hold {hp.shape[0]} positive distances")
    if settle is not None and not (math.isfinite(settle) and settle > 0):
        raise ValueError(f"`settle` must be a positive fraction, got {settle!r}")
    nx, p = n * d, hp.shape[0]
    mu = PROXIMAL * float(np.mean(k)) if k.size else 1.0
    x_ref = x.copy()
    step_tol = STEP_RTOL * (float(np.mean(r)) if r.size else 1.0)
    dense = nx + p <= DENSE_MAX_UNKNOWNS
    bar_rows = np.repeat(np.arange(e.shape[0]), 2 * d)
    bar_cols = np.concatenate([d * e[:, [0]] + np.arange(d), d * e[:, [1]] + np.arange(d)],
                              axis=1).ravel()
    held_rows = np.repeat(np.arange(p), 2 * d)
    held_cols = np.concatenate([d * hp[:, [0]] + np.arange(d), d * hp[:, [1]] + np.arange(d)],
                               axis=1).ravel()

    # where each bar's outer product lands in the dense saddle-point matrix (fixed: the bars'
    # columns do not change between steps)
    kkt_flat = _kkt_positions(bar_cols.reshape(e.shape[0], 2 * d), nx + p) if dense else None

    # the energy is minimised with every play a little narrower (``band``), so that a bar pulled
    # back to its play lands inside it rather than on its edge, and bars do not chatter across it
    band = np.where(c > 0, np.maximum(c - INSIDE * r, 0.0), 0.0)
    low = -band
    close_tol = CLOSE_RTOL * r
    # contiguous index arrays: ``take`` gathers several times faster than indexing with a
    # column of the edge array (the state is evaluated a few times per step)
    e0, e1, h0, h1 = (np.ascontiguousarray(a[:, k]) for a in (e, hp) for k in (0, 1))

    def state(xx):
        diff = xx.take(e0, axis=0)
        diff -= xx.take(e1, axis=0)
        ell = np.sqrt(np.einsum("ec,ec->e", diff, diff))
        delta = ell - r
        excess = delta - np.clip(delta, low, band)
        hd = xx.take(h0, axis=0)
        hd -= xx.take(h1, axis=0)
        hl = np.sqrt(np.einsum("ec,ec->e", hd, hd))
        within = delta - excess
        energy = 0.5 * float(np.sum(k * (excess ** 2 + INNER_STIFFNESS * within ** 2))) \
            + 0.5 * mu * float(np.sum((xx - x_ref) ** 2))
        return diff, ell, excess, hd, hl, energy

    def merit(energy, hl, weight):
        return energy + weight * float(np.abs(hl - ht).sum())

    import scipy.sparse as sp  # here, not at the top: the command line starts without scipy
    import scipy.sparse.linalg as spla

    diff, ell, excess, hd, hl, energy = state(x)
    damping = mu
    penalty = 0.0
    it = stall = 0
    for it in range(1, max_iterations + 1):
        u = diff / np.maximum(ell, TINY)[:, None]
        active = excess != 0.0
        # a bar past its play is a spring; within it, a spring INNER_STIFFNESS as stiff
        sk = np.sqrt(k * np.where(active, 1.0, INNER_STIFFNESS))
        rows = sk[:, None] * np.concatenate([u, -u], axis=1)  # each bar's row of the Jacobian
        pull = np.where(active, excess, ell - r)
        grad = np.bincount(bar_cols, (rows * (sk * pull)[:, None]).ravel(), minlength=nx) \
            + mu * (x - x_ref).ravel()
        hu = hd / np.maximum(hl, TINY)[:, None]
        cons_vals = np.concatenate([hu, -hu], axis=1).ravel()
        rhs = np.concatenate([-grad, -(hl - ht)])
        if dense:
            sol = np.linalg.solve(_dense_kkt(rows, kkt_flat, cons_vals, held_rows, held_cols,
                                             nx, p, mu + damping), rhs)
        else:
            jac = sp.csr_matrix((rows.ravel(), (bar_rows, bar_cols)), shape=(e.shape[0], nx))
            hess = (jac.T @ jac + (mu + damping) * sp.identity(nx)).tocsr()
            cons = sp.csr_matrix((cons_vals, (held_rows, held_cols)), shape=(p, nx))
            sol = spla.spsolve(sp.bmat([[hess, cons.T], [cons, None]], format="csc"), rhs)
        dx = sol[:nx].reshape(n, d)
        if p:
            penalty = max(penalty, 2.0 * float(np.abs(sol[nx:]).max()) + TINY)
        if not np.all(np.isfinite(dx)):
            break
        old = merit(energy, hl, penalty)
        t = 1.0
        while True:
            trial = state(x + t * dx)
            if merit(trial[5], trial[4], penalty) <= old or t < MIN_LINE_STEP:
                break
            t *= 0.5
        x = x + t * dx
        diff, ell, excess, hd, hl, energy = trial
        damping = max(mu, damping / 4.0) if t == 1.0 else min(damping * 4.0, 1e6 * k.max())
        if t * float(np.abs(dx).max()) <= step_tol:
            break
        # closed: every bar within its play and every held pair at its distance
        closed = settle is not None and bool(np.all(np.abs(excess) <= close_tol)
                                             and np.all(np.abs(hl - ht) <= CLOSE_RTOL * ht))
        quiet = settle if closed else STALL_RTOL
        stall = stall + 1 if old - merit(energy, hl, penalty) <= quiet * abs(old) else 0
        if stall >= 3:
            break
    delta = ell - r
    excess = delta - np.clip(delta, -c, c)
    inside = np.abs(excess) <= CLOSE_RTOL * r
    excess = np.where(inside, 0.0, excess)
    slack = delta - excess
    energy = 0.5 * float(np.sum(k * excess ** 2))
    return Assembled(x, ell, slack, excess, energy, bool(inside.all()), it)


def _kkt_positions(cols: np.ndarray, size: int) -> np.ndarray:
    """Flat positions in a (size, size) matrix of each bar's outer product, the bars' columns
    ``cols`` of shape (E, 2d): the ``flat`` of :func:`_dense_kkt`."""
    return (cols[:, :, None] * size + cols[:, None, :]).ravel()


def _dense_kkt(rows, flat, cons_vals, held_rows, held_cols, nx: int, p: int,
               shift: float) -> np.ndarray:
    """The step's saddle-point matrix ``[[JᵀJ + shift·I, Cᵀ], [C, 0]]``, dense.

    ``rows`` holds each bar's nonzero Jacobian entries (shape (E, 2d)), whose outer products
    land at ``flat`` (:func:`_kkt_positions`); ``JᵀJ`` is their sum, added up with one
    ``bincount`` (a few hundred unknowns: building sparse matrices per step cost several times
    the solve itself). ``C`` (the held pairs) has ``cons_vals`` at ``held_rows``, ``held_cols``.
    """
    size = nx + p
    m = np.bincount(flat, (rows[:, :, None] * rows[:, None, :]).ravel(),
                    minlength=size * size).reshape(size, size)
    diag = np.arange(nx)
    m[diag, diag] += shift
    m[nx + held_rows, held_cols] = cons_vals
    m[held_cols, nx + held_rows] = cons_vals
    return m


def bar_stress(assembled: Assembled, rest, youngs) -> np.ndarray:
    """Axial stress ``σ_e = E ε_e`` of every bar of an assembled build (tension positive).

    Parameters
    ----------
    assembled : Assembled
    rest : array_like, shape (E,)
        The bars' own lengths (the ``rest`` given to :func:`assemble`).
    youngs : float or array_like, shape (E,)
        Young's modulus (MPa gives MPa).

    Returns
    -------
    numpy.ndarray, shape (E,)
    """
    return np.asarray(youngs, dtype=np.float64) * assembled.excess / np.asarray(rest, dtype=float)
