"""Leaving a singular configuration (a kinematic bifurcation) along a chosen branch.

At a configuration where the rigidity matrix R drops rank, a network has states of self-stress
(``R^T ω = 0``) and more infinitesimal motions than finite ones: the flat origami sheet is the
classic case (one self-stress, two first-order motions, two branches of finite motion). Tracing
methods cannot start there: the tangent is not unique. This module

1. detects the singularity (``count_modes``: S > 0 and more than one conformational motion);
2. enumerates the branches leaving it by the **second-order test**: a first-order motion
   ``v = Z c`` (Z: conformational zero modes) extends to second order, ``R a = -q(v)`` with
   ``q_e = |v_i - v_j|²``, exactly when ``ω · q(v) = 0`` for every self-stress ω. That is a
   quadratic form in the coefficients, ``cᵀ H_k c = 0`` with
   ``H_k = Σ_e ω_ke (ΔZ_e)ᵀ (ΔZ_e)`` (the stress matrix seen on the first-order motions). With one
   self-stress and two motions, an indefinite H has two null lines: two branches, each passing
   through the singular state (directions ±c are mirror images of each other);
3. picks a branch (by index, or by a caller's score of the candidate configurations, e.g. the
   mountain/valley assignment of a crease pattern), steps off along the second-order curve
   ``x0 + s v + s²/2 a`` and projects back onto the constraint set by Gauss-Newton;
4. continues with :func:`fabkit.trace` from the stepped-off configuration, and returns the whole
   path, the singular state first, as one :class:`~fabkit.kinematics.Trajectory`.

The dense algebra here is meant for the singular state of modest networks (up to a few thousand
coordinates); the continuation after the step is the ordinary sparse one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConstructionError, KinematicsError
from ..model.network import Network
from ..numerics import START_RTOL, TINY, project_to_lengths
from ..model.rigidity import count_modes, rigidity_matrix, self_stresses, zero_modes
from .base import Mark, Method, Solved, make_problem
from .tracer import trace
from .trajectory import EventKind, Trajectory

__all__ = ["Branch", "Bifurcation", "analyze_bifurcation", "step_off", "fold_through",
           "BranchSwitch", "turning_branches", "side_words"]

#: Largest number of first-order motions for which branches are enumerated.
MAX_MODES = 8


#: A port's first- or second-order rate below this (per unit of arclength on a unit network)
#: counts as zero: the rates come from least squares on the rigidity matrix, good to ~1e-12.
RATE_ZERO = 1e-9
#: An eigenvalue of the normalised quadratic form (largest entry 1) below this is zero: the
#: form then has one null line instead of two.
FORM_ZERO = 1e-12
#: Gauss-Newton for a null line stops when its step is below this (unit vectors: round-off).
LINE_STEP_ZERO = 1e-15
#: A converged line is a null line of the normalised forms when cᵀ H_k c is below this.
LINE_RESIDUAL = 1e-11
#: Two unit lines with |c·g| within this of 1 are the same line.
SAME_LINE = 1e-8
#: A branch's direction is oriented by its largest component; components within this fraction of
#: the largest count as tied (mirror-symmetric networks have several), and the first one wins.
ORIENT_TIE = 1e-6
#: Three nodes lie on one line (a flat triple) when twice their triangle's area is below this
#: fraction of the network's size squared.
FLAT_SINE = 1e-9
#: A candidate stepped off the branch point must move the drive by more than this (relative)
#: in the asked direction: round-off moves it by ~1e-16.
STEP_OFF_RTOL = 1e-14


@dataclass(frozen=True)
class Branch:
    """One branch of motion through a singular configuration.

    Attributes
    ----------
    index : int
        1-based number of the branch in :attr:`Bifurcation.branches`.
    coefficients : numpy.ndarray, shape (m,)
        Unit vector c in the basis of the conformational zero modes with ``cᵀ H_k c = 0``.
    tangent : numpy.ndarray, shape (d·N,)
        First-order velocity ``v = Z c`` (unit norm); ``-v`` is the mirror direction.
    curvature : numpy.ndarray, shape (d·N,)
        Second-order term a with ``R a = -q(v)`` (minimum norm).
    port_rates : dict of str to (float, float)
        First and second derivative of every port distance along ``s ↦ x0 + s v + s²/2 a``.
    residual : float
        Largest ``|cᵀ H_k c|`` relative to ``max ‖H_k‖`` (how exactly the test is met).
    words : str
        Where the branch goes, in words, when its ports' rates do not tell it from another
        (the two ways out of a turning point: :func:`side_words`).
    """

    index: int
    coefficients: np.ndarray
    tangent: np.ndarray
    curvature: np.ndarray
    port_rates: dict
    residual: float
    words: str = ""

    def describe(self) -> str:
        """One line: which port distances change on this branch and which stay put."""
        if self.words:
            return f"branch {self.index}: {self.words}"
        moving = {k: v[1] for k, v in self.port_rates.items() if abs(v[1]) > RATE_ZERO or abs(v[0]) > RATE_ZERO}
        still = sorted(k for k in self.port_rates if k not in moving)
        parts = [f"branch {self.index}:"]
        if moving:
            parts.append("moves " + ", ".join(
                f"{k} (d''={v:+.4g})" for k, v in sorted(moving.items())))
        if still:
            parts.append("keeps " + ", ".join(still) + " constant to second order")
        return " ".join(parts)


@dataclass(frozen=True)
class Bifurcation:
    """What the second-order test finds at a configuration.

    Attributes
    ----------
    positions : numpy.ndarray, shape (N, d)
    modes : ModeCount
    singular : bool
        True when there is a self-stress and more than one conformational motion.
    stresses : numpy.ndarray, shape (E, S)
        Self-stresses as edge tensions per unit length (left null space of the normalised R).
    zero_modes : numpy.ndarray, shape (d·N, m)
        Orthonormal conformational first-order motions.
    forms : numpy.ndarray, shape (S, m, m)
        The quadratic forms H_k of the second-order test.
    branches : tuple of Branch
    message : str
    """

    positions: np.ndarray
    modes: object
    singular: bool
    stresses: np.ndarray
    zero_modes: np.ndarray
    forms: np.ndarray
    branches: tuple = ()
    message: str = ""

    def summary(self) -> str:
        """A few lines for a terminal."""
        lines = [self.message]
        lines += ["  " + b.describe() for b in self.branches]
        return "\n".join(lines)


def _stress_forms(net: Network, x: np.ndarray, stresses: np.ndarray, modes: np.ndarray):
    n, d = x.shape
    i, j = net.edges[:, 0], net.edges[:, 1]
    lengths = np.linalg.norm(x[i] - x[j], axis=1)
    z = modes.reshape(n, d, -1)
    dz = z[i] - z[j]  # (E, d, m)
    omega = stresses / lengths[:, None]  # tensions of the unnormalised R
    return np.einsum("ek,eda,edb->kab", omega, dz, dz)


def _null_lines(forms: np.ndarray, seed: int = 0) -> list[np.ndarray]:
    """Unit vectors c (up to sign) with cᵀ H_k c = 0 for all k."""
    s, m, _ = forms.shape
    scale = max(float(np.abs(forms).max()), TINY)
    h = forms / scale
    if s == 1 and m == 2:
        lam, u = np.linalg.eigh(h[0])
        if lam[0] * lam[1] > 0:
            return []
        if abs(lam[0]) < FORM_ZERO or abs(lam[1]) < FORM_ZERO:
            zero = u[:, 0] if abs(lam[0]) < abs(lam[1]) else u[:, 1]
            return [zero]
        out = []
        for sgn in (1.0, -1.0):
            c = math.sqrt(abs(lam[1])) * u[:, 0] + sgn * math.sqrt(abs(lam[0])) * u[:, 1]
            out.append(c / np.linalg.norm(c))
        return out
    # General case: Gauss-Newton on [cᵀ H_k c; |c|² - 1] from deterministic starts.
    rng = np.random.default_rng(seed)
    found: list[np.ndarray] = []
    for _ in range(64 * m):
        c = rng.standard_normal(m)
        c /= np.linalg.norm(c)
        for _ in range(60):
            f = np.append(np.einsum("a,kab,b->k", c, h, c), c @ c - 1.0)
            jac = np.vstack([2.0 * np.einsum("kab,b->ka", h, c), 2.0 * c])
            step = np.linalg.lstsq(jac, -f, rcond=None)[0]
            c = c + step
            if np.linalg.norm(step) < LINE_STEP_ZERO:
                break
        c /= np.linalg.norm(c)
        if np.abs(np.einsum("a,kab,b->k", c, h, c)).max() > LINE_RESIDUAL:
            continue
        if all(abs(float(c @ g)) < 1 - SAME_LINE for g in found):
            found.append(c)
    return found


def _port_rates(net: Network, x: np.ndarray, v: np.ndarray, a: np.ndarray) -> dict:
    n, d = x.shape
    vv, aa = v.reshape(n, d), a.reshape(n, d)
    out = {}
    for name, (i, j) in net.ports.items():
        u = x[i] - x[j]
        dist = float(np.linalg.norm(u))
        dv, da = vv[i] - vv[j], aa[i] - aa[j]
        first = float(u @ dv) / dist
        second = (float(dv @ dv) + float(u @ da)) / dist - first ** 2 / dist
        out[name] = (first, second)
    return out


def analyze_bifurcation(net: Network, positions=None) -> Bifurcation:
    """Detect a singular configuration and enumerate the branches of motion through it.

    Parameters
    ----------
    net : Network
    positions : array_like, shape (N, d), optional
        The configuration to test (``net.nodes`` by default); it must keep the edge lengths.

    Returns
    -------
    Bifurcation
        ``singular`` is False (and ``branches`` empty) at a regular configuration.

    Raises
    ------
    KinematicsError
        When the configuration breaks edges, or has more than ``MAX_MODES`` first-order motions
        (the enumeration is not attempted; step off by hand).

    Examples
    --------
    >>> import fabkit, numpy as np
    >>> r = np.sqrt(0.5)
    >>> sheet = fabkit.Network([[-r, 0, 0], [0, r, 0], [r, 0, 0], [0, -r, 0], [0, 0.2071, 0]],
    ...     [[0, 1], [0, 3], [1, 2], [2, 3], [0, 4], [1, 4], [2, 4], [3, 4]],
    ...     ports={"d1": (1, 3), "d2": (0, 2)})
    >>> bif = analyze_bifurcation(sheet)
    >>> bif.singular, bif.modes.self_stress, len(bif.branches)
    (True, 1, 2)
    """
    x = net.nodes if positions is None else np.asarray(positions, dtype=np.float64)
    err = float(net.edge_error(x))
    if err > START_RTOL:
        raise KinematicsError(f"the configuration breaks edges (largest relative error {err:.1e})")
    modes = count_modes(net, x)
    singular = modes.self_stress > 0 and modes.conformational > 1
    if not singular:
        return Bifurcation(x, modes, False, np.zeros((net.n_edges, 0)),
                           np.zeros((x.size, 0)), np.zeros((0, 0, 0)), (),
                           f"regular configuration: {modes}")
    if modes.conformational > MAX_MODES:
        raise KinematicsError(
            f"the configuration has {modes.conformational} first-order motions and "
            f"{modes.self_stress} self-stresses; branches are enumerated for at most {MAX_MODES} "
            "motions: start from a configuration off the singular state")
    w = self_stresses(net, x)
    z = zero_modes(net, x)
    forms = _stress_forms(net, x, w, z)
    lines = _null_lines(forms)
    r = rigidity_matrix(net, x).toarray()
    n, d = x.shape
    i, j = net.edges[:, 0], net.edges[:, 1]
    branches = []
    scale = max(float(np.abs(forms).max()), TINY)
    raw = []
    for c in lines:
        v = z @ c
        v /= np.linalg.norm(v)
        # a null line is found up to sign, and which sign depends on the LAPACK build (the
        # eigenvectors' signs): orient it by the geometry, so that branch signs ("+", "-") and
        # every configuration derived from them are the same on every machine
        big = np.abs(v)
        first = int(np.flatnonzero(big >= (1.0 - ORIENT_TIE) * big.max())[0])
        if v[first] < 0:
            v, c = -v, -c
        vv = v.reshape(n, d)
        q = np.einsum("ed,ed->e", vv[i] - vv[j], vv[i] - vv[j])
        a = np.linalg.lstsq(r, -q, rcond=None)[0]
        res = float(np.abs(np.einsum("a,kab,b->k", c, forms, c)).max()) / scale
        raw.append((c, v, a, _port_rates(net, x, v, a), res))

    def order(item):
        # a numbering that does not depend on round-off in the bases: branches that move fewer
        # ports first, then by the second-order rates of the ports (by name)
        rates = item[3]
        moving = sum(abs(rates[k][1]) > RATE_ZERO for k in rates)
        return (moving, tuple(round(abs(rates[k][1]), 9) for k in sorted(rates)))

    for k, (c, v, a, rates, res) in enumerate(sorted(raw, key=order), start=1):
        branches.append(Branch(k, c, v, a, rates, res))
    if not branches:
        msg = (f"singular configuration ({modes}) with no real branch: the self-stress makes it "
               "rigid to second order (no finite motion leaves it)")
    else:
        msg = (f"bifurcation: {modes}; the second-order test on the self-stress finds "
               f"{len(branches)} branch(es) of motion through this configuration")
    return Bifurcation(x, modes, True, w, z, forms, tuple(branches), msg)


def turning_branches(net: Network, positions, drive) -> Bifurcation | None:
    """The two ways out of a start where the drive is stationary on a regular motion.

    A network with one first-order motion and no state of self-stress moves along one curve;
    where the drive is at its least or greatest value along it (the physical 4-bar's flat
    state, a minimum of d1), both directions of that curve move the drive the same way, to
    second order: two branches, mirror images of each other at a flat state. Branch 1 is the
    way that opens a flat state away from the rest of the network (a node leaving the line of
    its neighbours to the side where no other node lies; else the tangent oriented by its
    largest component, as for bifurcations), branch 2 its mirror image.

    Parameters
    ----------
    net : Network
    positions : array_like, shape (N, d)
    drive : (int, int)

    Returns
    -------
    Bifurcation or None
        ``singular`` False, two branches; None where the start is not such a turning point
        (the drive moves to first order, or the motion is not one curve).

    Examples
    --------
    >>> import fabkit
    >>> d = fabkit.load_template("physical_fourbar")
    >>> turn = turning_branches(d.network, d.network.nodes, d.network.port("d1"))
    >>> [b.index for b in turn.branches], side_words(d.network, turn.positions,
    ...                                              turn.branches[0].tangent)
    ([1, 2], 'node 2 leaves the line 0–1 to its right (away from node 3)')
    """
    x = np.asarray(positions, dtype=np.float64)
    modes = count_modes(net, x)
    if modes.conformational != 1 or modes.self_stress:
        return None
    z = zero_modes(net, x)
    if z.shape[1] != 1:
        return None
    v = z[:, 0] / np.linalg.norm(z[:, 0])
    big = np.abs(v)
    if v[int(np.flatnonzero(big >= (1.0 - ORIENT_TIE) * big.max())[0])] < 0:
        v = -v
    n, d = x.shape
    vv = v.reshape(n, d)
    i, j = net.edges[:, 0], net.edges[:, 1]
    q = np.einsum("ed,ed->e", vv[i] - vv[j], vv[i] - vv[j])
    a = np.linalg.lstsq(rigidity_matrix(net, x).toarray(), -q, rcond=None)[0]
    ports = {**net.ports, "drive": tuple(int(k) for k in drive)}
    rates = _port_rates(Network(x, net.edges, ports), x, v, a)
    first, second = rates.pop("drive")
    if abs(first) > RATE_ZERO or abs(second) <= RATE_ZERO:
        return None
    mirror = _port_rates(Network(x, net.edges, net.ports), x, -v, a)
    # the way that opens the flat state away from the rest of the network first (it unfolds
    # rather than folds onto itself, as a maker pulling a flat linkage open does)
    found = _leaving(net, x, v)
    if found is not None and found[5]:
        v, rates, mirror = -v, mirror, rates
    branches = (Branch(1, np.array([1.0]), v, a, rates, 0.0, side_words(net, x, v)),
                Branch(2, np.array([-1.0]), -v, a, mirror, 0.0, side_words(net, x, -v)))
    what = "least" if second > 0 else "greatest"
    return Bifurcation(x, modes, False, np.zeros((net.n_edges, 0)), z, np.zeros((0, 1, 1)),
                       branches, f"the drive is at its {what} value along the motion here (a "
                                 "turning point): both ways along it move the drive the same "
                                 "way, two branches")


def _leaving(net: Network, x, v):
    """``(node, p, q, rate, other, same)`` of a 2D motion leaving a flat state: the node that
    leaves the line of two of its neighbours fastest (``rate``: the signed area's derivative,
    positive to the left of p → q), and the first node off that line with whether it lies on
    that side (None without one); None in 3D or without a flat triple."""
    if x.shape[1] != 2:
        return None
    v = np.asarray(v, dtype=np.float64).reshape(x.shape)
    size = max(float(np.ptp(x, axis=0).max()), TINY)
    neigh = {k: set() for k in range(x.shape[0])}
    for a_, b_ in net.edges.tolist():
        neigh[a_].add(b_)
        neigh[b_].add(a_)

    def cross(u, w):
        return float(u[0] * w[1] - u[1] * w[0])

    best = None
    for k, ns in neigh.items():
        ns = sorted(ns)
        for ii in range(len(ns)):
            for jj in range(ii + 1, len(ns)):
                p, q = ns[ii], ns[jj]
                if abs(cross(x[q] - x[p], x[k] - x[p])) > FLAT_SINE * size ** 2:
                    continue
                rate = cross(v[q] - v[p], x[k] - x[p]) + cross(x[q] - x[p], v[k] - v[p])
                if best is None or abs(rate) > abs(best[3]):
                    best = (k, p, q, rate)
    if best is None or abs(best[3]) <= RATE_ZERO * size:
        return None
    k, p, q, rate = best
    others = [m for m in range(x.shape[0]) if m not in (k, p, q)
              and abs(cross(x[q] - x[p], x[m] - x[p])) > FLAT_SINE * size ** 2]
    if not others:
        return k, p, q, rate, None, None
    m = others[0]
    return k, p, q, rate, m, cross(x[q] - x[p], x[m] - x[p]) * rate > 0


def side_words(net: Network, positions, tangent) -> str:
    """Where a 2D motion leaving a flat state goes, in words: the node that leaves the line of
    two of its neighbours fastest, and to which side (with a node that lies on that side, or
    away from one); ``""`` in 3D or without a flat triple."""
    found = _leaving(net, np.asarray(positions, dtype=np.float64), tangent)
    if found is None:
        return ""
    k, p, q, rate, m, same = found
    text = f"node {k} leaves the line {p}–{q} to its {'left' if rate > 0 else 'right'}"
    if m is not None:
        text += f" ({'the side of' if same else 'away from'} node {m})"
    return text


def _project(net: Network, xf: np.ndarray) -> np.ndarray:
    """Minimum-norm Gauss-Newton back onto the constraint set ``|x_i - x_j| = L``."""
    proj = project_to_lengths(net.edges, net.edge_lengths, xf.reshape(net.nodes.shape))
    if not proj.converged:
        raise KinematicsError("could not project the stepped-off configuration back onto the "
                              "edge lengths: use a smaller step_off")
    return proj.positions.ravel()


def step_off(net: Network, bifurcation: Bifurcation, branch: int, sign: float = 1.0,
             size: float = 1e-3) -> np.ndarray:
    """A configuration on a branch, a short way from the singular state.

    Parameters
    ----------
    net : Network
    bifurcation : Bifurcation
        From :func:`analyze_bifurcation`.
    branch : int
        1-based branch number.
    sign : {+1, -1}
        Direction along the branch (the two are mirror images at a flat state).
    size : float
        Step length s relative to the median edge length.

    Returns
    -------
    numpy.ndarray, shape (N, d)
        ``x0 + s v + s²/2 a`` projected onto the edge lengths (relative error below 1e-12).

    Raises
    ------
    KinematicsError
        Unknown branch, or the projection fails.
    """
    if not 1 <= int(branch) <= len(bifurcation.branches):
        raise KinematicsError(f"no branch {branch}: the configuration has "
                              f"{len(bifurcation.branches)} branch(es)")
    b = bifurcation.branches[int(branch) - 1]
    s = float(size) * float(np.median(net.edge_lengths)) * (1.0 if sign >= 0 else -1.0)
    x0 = np.asarray(bifurcation.positions, dtype=np.float64).ravel()
    guess = x0 + s * b.tangent + 0.5 * s * s * b.curvature
    return _project(net, guess).reshape(bifurcation.positions.shape)


@dataclass(frozen=True)
class _Candidate:
    branch: int
    sign: float
    positions: np.ndarray
    score: float = 0.0


def _choose(net, bif, drive, direction, branch, sign, score, size):
    """(branch, sign, positions) to continue on; KinematicsError with the options otherwise."""
    cands = []
    for b in bif.branches:
        for sg in (1.0, -1.0):
            cands.append((b.index, sg))
    if branch is not None:
        if not 1 <= int(branch) <= len(bif.branches):
            raise KinematicsError(f"no branch {branch}: the start has {len(bif.branches)} "
                                  f"branch(es) ({'; '.join(b.describe() for b in bif.branches)})")
        cands = [c for c in cands if c[0] == int(branch)]
    if sign is not None:
        cands = [c for c in cands if c[1] == (1.0 if sign >= 0 else -1.0)]
    # the drive must move towards the target on the chosen branch
    i, j = drive
    d0 = float(np.linalg.norm(bif.positions[i] - bif.positions[j]))
    usable = []
    for bi, sg in cands:
        x = step_off(net, bif, bi, sg, size)
        dd = float(np.linalg.norm(x[i] - x[j])) - d0
        if dd * direction > STEP_OFF_RTOL * max(d0, 1.0):
            usable.append(_Candidate(bi, sg, x))
    if not usable:
        what = "; ".join(b.describe() for b in bif.branches)
        raise KinematicsError(f"no branch through the singular state moves the drive towards the "
                              f"target ({what}): drive another port or pick another target")
    if score is not None:
        usable = [replace(c, score=float(score(c.positions))) for c in usable]
        best = max(c.score for c in usable)
        top = [c for c in usable if c.score == best]
        if len(top) > 1:
            raise KinematicsError(
                "the branch choice is ambiguous: branches "
                + ", ".join(f"{c.branch}{'+' if c.sign > 0 else '-'}" for c in top)
                + " score alike; name one with branch=... and sign=...")
        return top[0]
    if len({c.branch for c in usable}) > 1:
        raise KinematicsError(
            "several branches move the drive towards the target ("
            + ", ".join(sorted({str(c.branch) for c in usable}))
            + "): name one with branch=...")
    return usable[0]


def fold_through(net: Network, drive="d1", to=None, *, start=None, branch=None, sign=None,
                 score=None, step_off_size: float = 1e-3, method: str = "auto",
                 **options) -> Trajectory:
    """Trace a motion that starts at a singular configuration, on a chosen branch.

    Parameters
    ----------
    net : Network
    drive : str or (int, int)
        Port (or node pair) driven.
    to : float
        Target value of the drive.
    start : array_like, shape (N, d), optional
        Singular start configuration (``net.nodes`` by default). A regular start is traced
        directly.
    branch : int, optional
        1-based branch number from :func:`analyze_bifurcation`.
    sign : {+1, -1}, optional
        Direction along the branch; both are tried when omitted.
    score : callable, optional
        ``score(positions (N, d)) -> float`` evaluated on the stepped-off configuration of every
        candidate (branch, sign); the highest wins (e.g. agreement with a mountain/valley
        assignment).
    step_off_size : float
        Length of the step off the singular state relative to the median edge length.
    method : str
        Method used after the step (see :func:`fabkit.trace`); ``"auto"`` is resolved on the
        stepped-off configuration, and a ``samples`` option is dropped when it resolves to
        ``"projected"``.
    **options
        Options of that method.

    Returns
    -------
    Trajectory
        Starts at the singular configuration; ``method`` reads ``"branch/<method>"``; the first
        event (kind ``"bifurcation"``) says which branch was taken; ``stats["branch"]``,
        ``stats["sign"]`` and ``stats["branches"]`` record the choice.

    Raises
    ------
    KinematicsError
        No branch moves the drive towards the target, an ambiguous choice, or a failed step.

    Examples
    --------
    >>> import fabkit, numpy as np
    >>> r = np.sqrt(0.5)
    >>> sheet = fabkit.Network([[-r, 0, 0], [0, r, 0], [r, 0, 0], [0, -r, 0], [0, 0.2071, 0]],
    ...     [[0, 1], [0, 3], [1, 2], [2, 3], [0, 4], [1, 4], [2, 4], [3, 4]],
    ...     ports={"d1": (1, 3), "d2": (0, 2)})
    >>> traj = fold_through(sheet, "d1", 1.0, sign=1)
    >>> traj.stats["branch"], str(traj.status)
    (2, 'finished')
    """
    if to is None:
        raise KinematicsError("`to` (the target value of the drive) is required")
    problem = make_problem(net, drive, to, start=start)
    work = problem.work
    bif = analyze_bifurcation(work, problem.start)
    turning = None
    if not bif.singular:
        turning = turning_branches(work, problem.start, problem.drive)
        if turning is None:
            return trace(net, drive=drive, to=to, method=method, start=start, **options)
        # each way out is its own branch (the two are mirror images): the first unless named
        bif, sign = turning, 1.0
        branch = 1 if branch is None else branch
    if not bif.branches:
        raise KinematicsError(bif.message)
    direction = 1.0 if problem.target >= problem.start_drive else -1.0
    cand = _choose(work, bif, problem.drive, direction, branch, sign, score, step_off_size)
    if method == "auto":
        # resolve "auto" here so that constructive-only options (samples) never reach a method
        # that does not know them
        from .constructive import plan_construction

        try:
            plan_construction(work, problem.drive, cand.positions)
            method = "constructive"
        except ConstructionError:
            method = "projected"
            options.pop("samples", None)
    named = problem.drive_name if problem.drive_name in work.ports else problem.drive
    traj = trace(work, drive=named, to=to, method=method, start=cand.positions, **options)
    x0 = bif.positions
    pos = np.concatenate([x0[None], traj.positions], axis=0)
    if turning is not None:
        taken = turning.branches[cand.branch - 1]
        other = turning.branches[2 - cand.branch]
        detail = (f"left the start, a turning point of {problem.drive_name}, on branch "
                  f"{cand.branch} of 2" + (f" ({taken.words})" if taken.words else "")
                  + f"; branch {other.index} is its mirror image"
                  + (f" ({other.words})" if other.words else ""))
    else:
        detail = (f"left the singular state ({bif.modes.self_stress} self-stress, "
                  f"{bif.modes.conformational} first-order motions, {len(bif.branches)} "
                  f"branches) on branch {cand.branch} in direction "
                  f"{'+' if cand.sign > 0 else '-'}")
    marks = [Mark(EventKind.BIFURCATION, 0, detail)]
    marks += [Mark(e.kind, e.index + 1, e.detail) for e in traj.events]
    step = float(np.linalg.norm(traj.positions[0] - x0))
    arclength = np.concatenate([[0.0], step + traj.arclength])
    stats = {**traj.stats, "branch": cand.branch, "sign": int(cand.sign),
             "branches": [b.describe() for b in bif.branches], "step_off": step,
             "turning_start": turning is not None}
    return problem.trajectory(pos, f"branch/{traj.method}", traj.status,
                              f"{detail}; then {traj.message}", marks, stats, arclength)


class BranchSwitch(Method):
    """Tracing method that starts at a singular configuration (see :func:`fold_through`).

    Options
    -------
    branch : int or None
        1-based branch number (default: the only branch that moves the drive towards the target).
    sign : +1, -1 or None
        Direction along the branch (default: +1 unless a score decides).
    step_off : float
        Step off the singular state, relative to the median edge length (default 1e-3).
    then : str
        Method used after the step (default "auto").
    samples : int
        Samples of the constructive method after the step (default 101).
    """

    name = "branch"
    options = {"branch": None, "sign": None, "step_off": 1e-3, "then": "auto", "samples": 101}

    def solve(self) -> Solved:
        p = self.problem
        o = self.opts
        extra = {"samples": o["samples"]} if o["then"] in ("auto", "constructive") else {}
        sign = o["sign"]
        if sign is None and o["branch"] is not None:
            sign = 1
        drive = p.drive_name if p.drive_name in p.work.ports else p.drive
        traj = fold_through(p.work, drive, p.target, start=p.start, branch=o["branch"],
                            sign=sign, step_off_size=o["step_off"], method=o["then"], **extra)
        method = traj.method if traj.method.startswith(self.name) else f"{self.name}/{traj.method}"
        marks = tuple(Mark(e.kind, e.index, e.detail) for e in traj.events)
        return Solved(traj.positions, traj.status, traj.message, marks, traj.stats,
                       traj.arclength, aligned=True, method=method)
