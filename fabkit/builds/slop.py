"""Slop: how far a port's distance wanders over the play of the joints, with the drive held.

A bar ``e`` whose pins sit in holes wider than the pins keeps its two pins at any distance in
``[L_e - c_e, L_e + c_e]`` (``c_e``, the bar's axial room). With the drive and the design's held
ports fixed, a network that is rigid on paper still lets every other port's distance change a
little: its *slop*. To first order at a configuration ``x``, bar length changes ``s`` with
``|s_e| <= c_e`` are taken up by a velocity ``u`` with ``R u = s`` (``R`` the row-normalised
rigidity matrix of the bars) and ``R_h u = 0`` (the held pairs' rows), and port ``p`` changes by
``r_p · u``; its slop is the range of ``r_p · u`` over that polytope, a linear program
(:func:`port_slop`).

Examples
--------
>>> import math
>>> import numpy as np
>>> from fabkit.model.network import Network
>>> net = Network([[0, 0], [0, 2], [2, 0], [2, 2]], [[0, 2], [0, 3], [1, 2], [1, 3]],
...               ports={"d1": (0, 1), "d2": (2, 3)})
>>> [d2] = port_slop(net, net.nodes, np.full(4, 0.1), held=[net.port("d1")])
>>> d2.port, round(d2.increase, 6), round(0.1 * (2 + 2 * math.sqrt(2)), 6)
('d2', 0.482843, 0.482843)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .. import arguments
from ..errors import ArgumentTypeError, ArgumentValueError
from ..model.matrix import rigidity_matrix
from ..model.network import checked_network, Network
from ..numerics import RANK_RTOL

__all__ = ["PortSlop", "port_slop", "MAX_AMPLIFICATION"]

#: A first-order slop above ``MAX_AMPLIFICATION`` times the largest room is reported as infinite:
#: it needs the held rigidity matrix to have a singular value at or below about
#: ``1 / MAX_AMPLIFICATION``, which fabkit's rank rule (``RANK_RTOL``) counts as zero — the held
#: network is singular there (a flat state) and the first-order number is round-off. HiGHS itself
#: calls such programs unbounded from about the same amplification (measured on the physical
#: 4-bar near its flat state: exact to 5e-9 up to 1.2e9, unbounded beyond), so the cut-off makes
#: the answer depend on fabkit's rule instead of on the solver's tolerances.
MAX_AMPLIFICATION = 1.0 / RANK_RTOL


@dataclass(frozen=True)
class PortSlop:
    """The slop of one port: how far its distance can move over the play, the held pairs fixed.

    Attributes
    ----------
    port : str
        The port's name.
    decrease : float
        Largest decrease of the port's distance (>= 0), in the unit of the room; ``inf`` when the
        held network does not fix the port (first order).
    increase : float
        Largest increase (>= 0), same unit; ``inf`` likewise.

    Examples
    --------
    >>> s = PortSlop("d2", 0.25, 0.25)
    >>> s.bounded, s.largest
    (True, 0.25)
    >>> PortSlop("d2", math.inf, math.inf).bounded
    False
    """

    port: str
    decrease: float
    increase: float

    @property
    def bounded(self) -> bool:
        """Whether the held network fixes the port to first order (both changes finite)."""
        return math.isfinite(self.decrease) and math.isfinite(self.increase)

    @property
    def largest(self) -> float:
        """The larger of the two changes."""
        return max(self.decrease, self.increase)


def port_slop(net: Network, positions, room, *, held=(), ports=None) -> list[PortSlop]:
    """First-order slop of ports: the largest change of their distances over the joints' play.

    Parameters
    ----------
    net : Network
        The bars (edges) and, by default, the ports.
    positions : array_like, shape (N, d)
        The configuration at which the slop is taken. Only its directions matter (the rigidity
        matrix is row-normalised), so its unit is free; the results are in the unit of ``room``.
    room : array_like, shape (E,), or float
        Axial room ``c_e >= 0`` of every bar (the two holes' radial clearances summed), finite;
        one number gives every bar the same room. A bar with no room is exact.
    held : sequence of (int, int), optional
        Node pairs whose distances are held exactly: the drive and the design's held ports (for
        a port, ``net.port("d1")``).
    ports : mapping of str to (int, int), optional
        The ports to measure, name → node pair; by default every port of ``net`` that is not a
        held pair (in the network's order).

    Returns
    -------
    list of PortSlop
        One per port, in the order of ``ports``. A port the held network does not fix (it is not
        rigid at ``positions``: the held pairs leave a motion, or the state is flat) has
        ``decrease = increase = inf`` and ``bounded`` False; nothing is raised for it.

    Raises
    ------
    ArgumentTypeError
        ``net`` not a Network, ``ports`` not a mapping (also a ``TypeError``).
    ArgumentValueError
        ``positions`` of the wrong shape or not finite, a bar of no length at ``positions``,
        ``room`` of the wrong shape, negative or not finite, a pair in ``held`` or ``ports``
        that is not two distinct node indices in range or whose nodes coincide (also a
        ``ValueError``); the message names the argument and the value.
    RuntimeError
        The solver fails on a program that always has a solution (``u = 0, s = 0`` is
        feasible): numerical trouble, reported with the port and the solver's message.

    Notes
    -----
    For each port ``p = (i, j)`` the linear program in the velocities ``u`` (free) and the bar
    length changes ``s`` is

        maximise ``r_p · u``  subject to  ``R u - s = 0``,  ``R_h u = 0``,  ``-c <= s <= c``

    (``R`` the row-normalised rigidity matrix of the bars, ``R_h`` and ``r_p`` the unit rows of
    the held pairs and of the port), solved by HiGHS with sparse constraints built once per call:
    only the objective changes from port to port. Rigid-body motions lie in the null space of
    both constraint blocks and change no distance, so the program is bounded exactly when every
    motion the held network allows to first order leaves the port's distance alone; it needs no
    gauge. The program is solved with the room divided by its largest value, so HiGHS's absolute
    tolerances apply to numbers of order one whatever the unit.

    *Symmetry.* The feasible set is symmetric under ``(u, s) → (-u, -s)`` (the room is the same
    on both sides of a bar's length), so the largest decrease equals the largest increase
    exactly; one program per port gives both. The nonlinear slop differs between the two
    directions only at second order: the relative difference is of the order of the room over
    the bars' lengths (4e-4 for 0.2 of room on a 4-bar with bars of about 250).

    *Closed form and self-stress.* Where the held network is isostatic, ``δd_p = λ · s`` with
    ``λ`` unique, and the slop is ``Σ |λ_e| c_e``. A state of self-stress ``w`` (of the bars and
    held pairs together) makes the lengths compatible only when ``w · s = 0`` over the bars, so
    the slop is smaller than ``Σ |λ_e| c_e`` for any one solution ``λ`` of
    ``λ R + μ R_h = r_p``; it is the least of ``Σ |λ_e| c_e`` over all of them (the dual
    program).

    *Unbounded.* Whether the program is bounded does not depend on the room (the recession cone
    is ``R u = 0, R_h u = 0`` for any ``c >= 0``), so a port left free by the held pairs is
    infinite even with no room at all; a network with no room is therefore still solved for
    boundedness, and its bounded ports get exactly 0. A flat state (a node on the line of the
    two it is placed from, e.g. the physical 4-bar at ``d1 = 1`` with ``d1`` held) is singular:
    the first-order slop is infinite there, and reported so, while the true slop is finite but of
    order ``√(c L)`` rather than ``c``. Near such a state the first-order slop grows like one
    over the distance to it and stops being a good estimate once it is no longer small beside
    that distance; beyond ``MAX_AMPLIFICATION`` times the largest room it is reported as
    infinite.

    Examples
    --------
    A 4-bar (two triangles on the drive ``d1``), 0.1 of room per bar:

    >>> import numpy as np
    >>> from fabkit.model.network import Network
    >>> net = Network([[0, 0], [0, 2], [2, 0], [2, 2]], [[0, 2], [0, 3], [1, 2], [1, 3]],
    ...               ports={"d1": (0, 1), "d2": (2, 3)})
    >>> [d2] = port_slop(net, net.nodes, 0.1, held=[net.port("d1")])
    >>> round(d2.decrease, 4), round(d2.increase, 4), d2.bounded
    (0.4828, 0.4828, True)

    Without the drive held, the 4-bar is a mechanism and every port is free:

    >>> [(s.port, s.largest, s.bounded) for s in port_slop(net, net.nodes, 0.1)]
    [('d1', inf, False), ('d2', inf, False)]
    """
    checked_network("net", net)
    x = arguments.positions("positions", positions, net)
    c = _checked_room(room, net)
    held_pairs = _checked_pairs("held", held, x)
    if ports is None:
        held_keys = {tuple(sorted(p)) for p in held_pairs.tolist()}
        chosen = {name: pair for name, pair in net.ports.items()
                  if tuple(sorted(pair)) not in held_keys}
    else:
        if not isinstance(ports, Mapping):
            raise ArgumentTypeError("ports", "must be a mapping of port name to (i, j) node "
                                             f"pair, got {type(ports).__name__}")
        chosen = dict(ports)
    names = [str(name) for name in chosen]
    port_pairs = _checked_pairs("ports", list(chosen.values()), x, names=names)
    if not names:
        return []

    n, d = x.shape
    e = net.n_edges
    scale = float(c.max()) if e else 0.0
    bound = c / scale if scale > 0 else c  # room in units of the largest: HiGHS's tolerances
    r = rigidity_matrix(net, x, normalized=True)
    h = _pair_rows(x, held_pairs)
    a_eq = sp.bmat([[r, -sp.identity(e, format="csr")],
                    [h, sp.csr_matrix((h.shape[0], e))]], format="csr")
    b_eq = np.zeros(a_eq.shape[0])
    bounds = np.concatenate([np.column_stack([np.full(d * n, -np.inf), np.full(d * n, np.inf)]),
                             np.column_stack([-bound, bound])])
    objective = _pair_rows(x, port_pairs)  # (P, d·N), 2d entries per row: kept sparse
    out = []
    for k, name in enumerate(names):
        row = objective[[k]].toarray().ravel()
        value = _largest_increase(name, row, a_eq, b_eq, bounds, e)
        slop = math.inf if value > MAX_AMPLIFICATION else (value * scale if scale > 0 else 0.0)
        out.append(PortSlop(name, slop, slop))
    return out


def _largest_increase(name: str, row: np.ndarray, a_eq, b_eq, bounds, e: int) -> float:
    """max ``row · u`` over the play polytope (room scaled to at most 1); ``inf`` if unbounded."""
    from scipy.optimize import linprog  # here: the command line's parent process needs none of it

    c = np.concatenate([-row, np.zeros(e)])  # linprog minimises
    res = linprog(c, A_eq=a_eq, b_eq=b_eq, bounds=bounds, method="highs")
    if res.status == 4:
        # "unbounded or infeasible" (presolve does not tell which; u = 0, s = 0 is feasible, but
        # let the simplex say it): solve again without presolve
        res = linprog(c, A_eq=a_eq, b_eq=b_eq, bounds=bounds, method="highs",
                      options={"presolve": False})
    if res.status == 3:
        return math.inf
    if res.status != 0:
        raise RuntimeError(f"the slop program of port {name!r} failed (status {res.status}), "
                           f"although u = 0, s = 0 is feasible: {res.message}")
    return max(float(-res.fun), 0.0)


def _pair_rows(x: np.ndarray, pairs: np.ndarray) -> sp.csr_matrix:
    """Unit rows ``(x_i - x_j)/|x_i - x_j|`` at node i's columns, the negative at node j's."""
    n, d = x.shape
    k = pairs.shape[0]
    diff = x[pairs[:, 0]] - x[pairs[:, 1]]
    diff = diff / np.linalg.norm(diff, axis=1, keepdims=True)
    rows = np.repeat(np.arange(k), 2 * d)
    cols = np.concatenate([d * pairs[:, [0]] + np.arange(d), d * pairs[:, [1]] + np.arange(d)],
                          axis=1).ravel()
    vals = np.concatenate([diff, -diff], axis=1).ravel()
    return sp.csr_matrix((vals, (rows, cols)), shape=(k, d * n))


def _checked_room(room, net: Network) -> np.ndarray:
    try:
        c = np.asarray(room, dtype=np.float64)
    except (TypeError, ValueError):
        raise ArgumentTypeError("room", "must be an array of one room per bar, got "
                                        f"{type(room).__name__}") from None
    e = net.n_edges
    if c.ndim == 0:
        c = np.full(e, float(c))
    if c.shape != (e,):
        raise ArgumentValueError("room", f"must have shape ({e},) (one value per bar) or be one "
                                         f"number, got shape {c.shape}")
    bad = np.flatnonzero(~np.isfinite(c) | (c < 0))
    if bad.size:
        k = int(bad[0])
        raise ArgumentValueError("room", f"must be finite and >= 0, got {float(c[k])!r} for "
                                         f"bar {k} {net.edges[k].tolist()}")
    return c


def _checked_pairs(argument: str, pairs, x: np.ndarray, names=None) -> np.ndarray:
    """``pairs`` as an int array (K, 2) of distinct nodes in range that lie apart at ``x``."""
    n = x.shape[0]
    if isinstance(pairs, (str, bytes)):
        raise ArgumentTypeError(argument, "must be a sequence of (i, j) node pairs, got "
                                          f"{pairs!r} (for a port, pass net.port({pairs!r}))")
    try:
        items = list(pairs)
    except TypeError:
        raise ArgumentTypeError(argument, "must be a sequence of (i, j) node pairs, got "
                                          f"{type(pairs).__name__}") from None

    def where(k: int) -> str:
        return f"{argument}[{names[k]!r}]" if names is not None else f"{argument}[{k}]"

    values = np.zeros((len(items), 2))
    for k, pair in enumerate(items):  # once per call, to name the first bad pair
        try:
            if isinstance(pair, (str, bytes)) or len(pair) != 2:
                raise ValueError
            values[k] = [float(v) for v in pair]
        except (TypeError, ValueError):
            raise ArgumentValueError(where(k), f"must be a pair of node indices, got "
                                               f"{pair!r}") from None
    whole = np.isfinite(values) & (values == np.round(values))
    bad = np.flatnonzero(~whole.all(axis=1))
    if bad.size:
        k = int(bad[0])
        raise ArgumentValueError(where(k), f"must be a pair of node indices, got {items[k]!r}")
    out = values.astype(np.int64)
    bad = np.flatnonzero(((out < 0) | (out >= n)).any(axis=1))
    if bad.size:
        k = int(bad[0])
        v = int(out[k][(out[k] < 0) | (out[k] >= n)][0])
        raise ArgumentValueError(where(k), f"names node {v}, but the network has nodes "
                                           f"0..{n - 1}")
    bad = np.flatnonzero(out[:, 0] == out[:, 1])
    if bad.size:
        k = int(bad[0])
        raise ArgumentValueError(where(k), f"joins node {int(out[k, 0])} to itself")
    bad = np.flatnonzero((x[out[:, 0]] == x[out[:, 1]]).all(axis=1))
    if bad.size:
        k = int(bad[0])
        raise ArgumentValueError(where(k), f"joins nodes {int(out[k, 0])} and {int(out[k, 1])}, "
                                           "which lie at one point of positions (no direction "
                                           "to hold or measure)")
    return out
