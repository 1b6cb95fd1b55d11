"""First-order test of whether a build's bars go together within their joints' play.

Bars with lengths ``L + δL`` (``δL``: the build's length errors) fit a network whose nominal
configuration realises ``L`` when some change of the pin distances ``s`` within the play,
``|s_e| <= c_e``, makes ``δL + s`` a compatible length change: one that a motion of the nodes
makes, ``R u = δL + s``. By the fundamental theorem of linear algebra that holds exactly when
``δL + s`` is orthogonal to every state of self-stress (the left null space ``W`` of the rigidity
matrix ``R``): ``Wᵀ (δL + s) = 0``.

The test here gives, per build, the **play ratio** ``τ``: the smallest factor on every bar's
room with which such an ``s`` exists. ``τ <= 1``: the build closes within its play (to first
order); ``τ > 1``: it does not, and the play would have to grow by ``τ``. With one state of
self-stress ``w`` this is ``|w·δL| / Σ|w_e| c_e`` (the play of every bar in the loop adds up);
with several it is a small linear program per build.
"""

from __future__ import annotations

import numpy as np

from ..model.matrix import rigidity_matrix
from ..model.rigidity import self_stresses
from ..numerics import TINY

__all__ = ["self_stress_basis", "play_ratio", "play_ratio_sparse"]

#: Entries of a state of self-stress below this fraction of its largest are round-off of the SVD
#: (bars outside the loop), and are dropped so the play of bars outside the loop never counts.
STRESS_SUPPORT_RTOL = 1e-9


#: Errors whose projection on the states of self-stress is below this fraction of the largest
#: error are compatible already (round-off of the projection): they need no play.
COMPATIBLE_RTOL = 1e-15


def self_stress_basis(net, positions=None) -> np.ndarray:
    """States of self-stress of a network at a configuration, cleaned of round-off.

    Parameters
    ----------
    net : fabkit.Network
    positions : array_like, shape (N, d), optional
        The configuration (default: the network's own).

    Returns
    -------
    numpy.ndarray, shape (E, S)
        Orthonormal columns (tensions per unit length, normalised rigidity matrix); S = 0 for a
        network without self-stress.

    Examples
    --------
    >>> from fabkit import Network
    >>> square = Network([[0, 0], [1, 0], [1, 1], [0, 1]],
    ...                  [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3]])
    >>> w = self_stress_basis(square)[:, 0]
    >>> bool(np.allclose(np.abs(w / w[0]), [1, 1, 1, 1, np.sqrt(2), np.sqrt(2)]))
    True
    """
    w = np.array(self_stresses(net, positions), dtype=np.float64)
    if w.size:
        big = np.abs(w).max(axis=0, keepdims=True)
        w[np.abs(w) < STRESS_SUPPORT_RTOL * big] = 0.0
    return w


def play_ratio(stresses, gap, room, *, time_limit: float | None = None) -> np.ndarray:
    """Per build, the smallest factor on the play with which its bars close (first order).

    Parameters
    ----------
    stresses : array_like, shape (E, S)
        States of self-stress (:func:`self_stress_basis`).
    gap : array_like, shape (E,) or (M, E)
        Each bar's length error ``δL`` (built minus the length the configuration realises).
    room : array_like, shape (E,) or (M, E)
        Each bar's axial room ``c_e >= 0`` (same unit as ``gap``).
    time_limit : float, optional
        Seconds each build's linear program may take (several states of self-stress): a safety
        net only, reaching it raises; ``τ`` never depends on the machine's speed (the programs
        are solved to optimality, without a limit by default; no caller in fabkit sets one).

    Returns
    -------
    numpy.ndarray, shape (M,) (or a float array of shape () for one build)
        ``τ``: 0 without self-stress or when the errors are compatible; ``<= 1`` when the build
        closes within its play; ``inf`` when no play can close it (the loop's bars have none).

    Raises
    ------
    TimeoutError
        A build's linear program passed ``time_limit``.

    Notes
    -----
    With many states of self-stress the program over the dense basis grows as S × E: on a
    30 × 30 4-bar lattice (812 states, 2730 bars) it takes minutes a build where
    :func:`play_ratio_sparse` takes a quarter of a second (``fabkit bench --parts levels``).

    Examples
    --------
    A braced square: one state of self-stress, tensions 1 on the sides and -√2 on the
    diagonals. A side 0.1 too long needs 0.1 of room over the whole loop:

    >>> from fabkit import Network
    >>> sq = Network([[0, 0], [1, 0], [1, 1], [0, 1]],
    ...              [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3]])
    >>> w = self_stress_basis(sq)
    >>> gap = [0.1, 0, 0, 0, 0, 0]
    >>> room = 0.1 / (4 + 2 * np.sqrt(2)) * np.ones(6)   # exactly enough, spread over the loop
    >>> float(play_ratio(w, gap, room).round(12))
    1.0
    """
    w = np.asarray(stresses, dtype=np.float64)
    g = np.asarray(gap, dtype=np.float64)
    single = g.ndim == 1
    g = np.atleast_2d(g)
    c = np.broadcast_to(np.asarray(room, dtype=np.float64), g.shape)
    if w.ndim != 2 or w.shape[0] != g.shape[1]:
        raise ValueError(f"`stresses` must have shape ({g.shape[1]}, S), got {w.shape}")
    if not np.all(np.isfinite(c)) or np.any(c < 0):
        raise ValueError("`room` must be finite and >= 0")
    m, s = g.shape[0], w.shape[1]
    if s == 0:
        out = np.zeros(m)
    elif s == 1:
        need = np.abs(g @ w[:, 0])
        have = (np.abs(w[:, 0]) * c).sum(axis=1)
        tiny = COMPATIBLE_RTOL * np.maximum(np.abs(g).max(axis=1), TINY)
        out = np.where(need <= tiny, 0.0,
                       np.where(have > 0, need / np.where(have > 0, have, 1.0), np.inf))
    else:
        out = np.array([_ratio_lp(w, g[k], c[k], time_limit) for k in range(m)])
    return out[0] if single else out


def play_ratio_sparse(net, gap, room, positions=None, *,
                      time_limit: float | None = None) -> np.ndarray:
    """The play ratio without the self-stress basis: one sparse linear program per build.

    ``τ = min t`` subject to ``R u - s = δL`` and ``|s_e| <= t c_e``, in the nodes' motion ``u``,
    the pin distances' change ``s`` and ``t``: the same number as :func:`play_ratio` (a length
    change is compatible exactly when it is ``R u`` for some ``u``), found without a dense SVD,
    so that a lattice of 10⁴ cells with 10⁴ states of self-stress is tested in seconds.

    Parameters
    ----------
    net : fabkit.Network
    gap : array_like, shape (E,) or (M, E)
    room : array_like, shape (E,) or (M, E)
    positions : array_like, shape (N, d), optional
        The configuration (default: the network's own).
    time_limit : float, optional
        Seconds each build's linear program may take: a safety net only, reaching it raises
        (none by default).

    Returns
    -------
    numpy.ndarray, shape (M,) (or shape () for one build)

    Raises
    ------
    TimeoutError
        A build's linear program passed ``time_limit``.

    Examples
    --------
    The braced square of :func:`play_ratio`, the same answer:

    >>> from fabkit import Network
    >>> sq = Network([[0, 0], [1, 0], [1, 1], [0, 1]],
    ...              [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3]])
    >>> room = 0.1 / (4 + 2 * np.sqrt(2)) * np.ones(6)
    >>> float(play_ratio_sparse(sq, [0.1, 0, 0, 0, 0, 0], room).round(9))
    1.0
    """
    r = rigidity_matrix(net, positions, normalized=True).tocsr()
    e, nd = r.shape
    g = np.asarray(gap, dtype=np.float64)
    single = g.ndim == 1
    g = np.atleast_2d(g)
    if g.shape[1] != e:
        raise ValueError(f"`gap` must have {e} columns (one per bar), got {g.shape[1]}")
    c = np.broadcast_to(np.asarray(room, dtype=np.float64), g.shape)
    if not np.all(np.isfinite(c)) or np.any(c < 0):
        raise ValueError("`room` must be finite and >= 0")
    import scipy.sparse as sp  # here, not at the top: the command line starts without scipy
    from scipy.optimize import linprog

    eye = sp.identity(e, format="csr")
    a_eq = sp.hstack([r, -eye, sp.csr_matrix((e, 1))], format="csr")
    cost = np.zeros(nd + e + 1)
    cost[-1] = 1.0
    bounds = [(None, None)] * (nd + e) + [(0, None)]
    zero = sp.csr_matrix((e, nd))
    out = np.empty(g.shape[0])
    for k in range(g.shape[0]):
        col = sp.csr_matrix(-c[k][:, None])
        a_ub = sp.vstack([sp.hstack([zero, eye, col]), sp.hstack([zero, -eye, col])],
                         format="csr")
        # interior point: on k x k 4-bar lattices 5x faster than the dual simplex at k = 30
        # (0.22 s against 1.1 s) and at k = 100 a minute where the simplex took over 12
        res = linprog(cost, A_ub=a_ub, b_ub=np.zeros(2 * e), A_eq=a_eq, b_eq=g[k],
                      bounds=bounds, method="highs-ipm",
                      options={} if time_limit is None else {"time_limit": float(time_limit)})
        if res.status == 2:  # no play closes it: the incompatible bars have none
            out[k] = np.inf
        elif res.status == 1 and time_limit is not None:
            raise TimeoutError(f"play ratio: a build's linear program passed its time limit of "
                               f"{time_limit:g} s")
        elif res.status != 0:
            raise RuntimeError(f"play ratio: the linear program ended with {res.message}")
        else:
            out[k] = float(res.x[-1])
    return out[0] if single else out


def _ratio_lp(w, g, c, time_limit=None) -> float:
    """min τ subject to Wᵀ s = -Wᵀ g and |s_e| <= τ c_e (variables s, τ)."""
    rhs = -(w.T @ g)
    if np.abs(rhs).max() <= COMPATIBLE_RTOL * max(np.abs(g).max(), TINY):
        return 0.0
    free = c > 0
    if not free.any():
        return np.inf
    wf, cf = w[free], c[free]
    k = wf.shape[0]
    cost = np.zeros(k + 1)
    cost[-1] = 1.0
    import scipy.sparse as sp
    from scipy.optimize import linprog

    # the bounds |s_e| <= τ c_e as a sparse block: dense, it grows as the square of the bars
    eye = sp.identity(k, format="csr")
    col = sp.csr_matrix(-cf[:, None])
    a_ub = sp.vstack([sp.hstack([eye, col]), sp.hstack([-eye, col])], format="csr")
    a_eq = np.hstack([wf.T, np.zeros((w.shape[1], 1))])
    res = linprog(cost, A_ub=a_ub, b_ub=np.zeros(2 * k), A_eq=a_eq, b_eq=rhs,
                  bounds=[(None, None)] * k + [(0, None)], method="highs",
                  options={} if time_limit is None else {"time_limit": float(time_limit)})
    if res.status == 2:  # the loop's own bars cannot take the incompatibility: no play helps
        return np.inf
    if res.status == 1 and time_limit is not None:
        raise TimeoutError(f"play ratio: a build's linear program passed its time limit of "
                           f"{time_limit:g} s")
    if res.status != 0:
        raise RuntimeError(f"play ratio: the linear program ended with {res.message}")
    return float(res.x[-1])
