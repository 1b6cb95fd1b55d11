"""Choosing the final apex angle of every module of a curve-following chain, and binning them
into a few module types.

The zigzag model of :func:`fabkit.design.letters.strip_model`: module k is the triangle
(q_{k-1}, q_k, q_{k+1}) with legs D2* and final apex angle α_k, mirrored every second module;
the chain's centre line (the midpoints of the legs) steps by D2*·sin(α_k / 2) per module and
turns by half the difference of neighbouring apex angles. So the apex angles set both how fast
a chain advances and how fast it turns: the widest spread of apex angles sets the sharpest turn
(a chain turns by at most the spread per two modules).

* :func:`track` follows a curve with a beam search over the apex angles on offer. Every partial
  chain carries its progress along the curve: the arclength of the closest curve point, sought
  among the points a little behind to a few modules ahead of the last one (a chain may cut a
  corner it cannot turn, and never jumps to another pass of a curve that crosses itself). It
  costs the squared distance of its centre-line points to the curve, its heading error toward
  the curve ``LOOKAHEAD`` steps ahead times its step (squared), a lag (moving without progress)
  and, to break ties on straight stretches, a small pull toward the reference apex angle; it is
  finished when its progress reaches the curve's end, where its distance to the end is added.
  Turns faster than the chain can make are followed along :func:`rounded`.
* :func:`refine` then lets every apex angle take any value in the range: least squares on the
  distances of the centre line to the curve, with the exact Jacobian of the zigzag
  (:func:`centre_of`), the end held to the curve's end.
* :func:`bin_apexes` bins the angles into a few types (the authors' curvature designs round
  their modules' bases into bins the same way), :func:`follow` gives each module the type that
  reproduces the refined chain point by point, and :func:`refit_bins` refits the types' angles
  to the curve with every module's type held.

Neighbours must average ``MIN_PAIR_APEX_DEG`` throughout (laser kits,
:mod:`fabkit.design.curvature`): the searches forbid other pairs, the least squares penalise
them from just inside the rule.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..numerics import TINY
from .curvature import MIN_PAIR_APEX_DEG
from .fit import arclength, closest_on_curve, point_at
from .letters import strip_model

__all__ = ["Track", "track", "rounded", "refine", "bin_apexes", "follow", "refit_bins",
           "centre_of", "neighbours_ok", "strip_centreline", "strip_nodes", "BEAM_WIDTH",
           "PAIR_SLACK_DEG"]

#: Partial chains kept per module.
BEAM_WIDTH = 128
#: Slack (degrees) of the neighbour rule: two modules at exactly MIN_PAIR_APEX_DEG meet it
#: despite round-off of the measured apex angles.
PAIR_SLACK_DEG = 1e-6
#: Curve samples per reference step of the centre line (the resolution of progress).
SAMPLES_PER_STEP = 8
#: How far (reference steps) the closest curve point is sought behind and ahead of the last.
BEHIND, AHEAD = 1.0, 3.0
#: Weights of the cost terms, against the squared distance to the curve.
HEADING_WEIGHT = 0.25
#: The heading asked is toward the curve this many reference steps ahead of the progress.
LOOKAHEAD = 2.0
LAG_WEIGHT = 1.0
END_WEIGHT = 4.0
REFERENCE_WEIGHT = 1e-3
#: Cells (in reference steps and degrees) within which only the cheapest partial chain is kept,
#: so that the beam stays diverse enough to turn sharp corners.
CELL_STEP, CELL_DEG = 0.5, 10.0
#: Refinement: rounds of closest points, solver evaluations per round, and the weight of the
#: neighbour rule's penalty.
REFINE_ROUNDS = 3
REFINE_EVALUATIONS = 30
PAIR_WEIGHT = 100.0
#: The penalty of the neighbour rule starts this far (degrees) inside it, so that the optimum
#: keeps to the rule itself.
PAIR_MARGIN_DEG = 0.05
#: Bins: k-means rounds.
KMEANS_ROUNDS = 50
#: A turn within this (relative) of the limit keeps to it (round-off of the limiter).
RATE_RTOL = 1e-9


def neighbours_ok(apex_a_deg: float, apex_b_deg: float) -> bool:
    """Two neighbouring modules may stand side by side in a laser kit: their final apex angles
    (degrees) average at least ``MIN_PAIR_APEX_DEG``."""
    return 0.5 * (apex_a_deg + apex_b_deg) >= MIN_PAIR_APEX_DEG - PAIR_SLACK_DEG


def strip_centreline(apexes_deg, leg: float, start=(0.0, 0.0), heading: float = 0.0):
    """Centre line (K + 1, 2) of the zigzag of these final apex angles: its first step heads
    along ``heading`` from ``start``."""
    m = strip_nodes(apexes_deg, leg, start, heading)
    return 0.5 * (m[:-1] + m[1:])


def strip_nodes(apexes_deg, leg: float, start=(0.0, 0.0), heading: float = 0.0):
    """The designed nodes q_0 … q_{K+1} (K + 2, 2) of the zigzag whose centre line is
    :func:`strip_centreline` (same arguments): the ends of the chain's ports."""
    a = np.radians(np.asarray(apexes_deg, dtype=np.float64))
    mods = [_Apex(float(v), leg) for v in a]
    h0 = heading + 0.5 * (math.pi - float(a[0]))
    return strip_model(np.arange(len(a)), mods, start_heading=h0, origin=start)


@dataclass(frozen=True)
class _Apex:
    apex: float
    leg: float


@dataclass(frozen=True)
class Track:
    """A chain that follows a curve in the zigzag model.

    Attributes
    ----------
    types : numpy.ndarray of int, shape (K,)
        Index into the apex angles on offer, per module.
    apexes : numpy.ndarray, shape (K,)
        Final apex angle of every module (degrees).
    centre : numpy.ndarray, shape (K + 1, 2)
        The model's centre line, in the curve's frame (first point on the curve's start).
    cost : float
    """

    types: np.ndarray
    apexes: np.ndarray
    centre: np.ndarray
    cost: float


def _resampled(target: np.ndarray, step: float):
    s = arclength(target)
    n = max(2, int(math.ceil(s[-1] / step)) + 1)
    t = np.linspace(0.0, s[-1], n)
    return point_at(target, s, t), t


def _limited(theta: np.ndarray, rate: float) -> np.ndarray:
    """Mean of a forward and a backward slew-rate limiter at ``rate`` per sample: a step
    becomes a ramp centred on it, at half the rate."""
    fwd, bwd = theta.copy(), theta.copy()
    for i in range(1, len(theta)):
        fwd[i] = min(max(theta[i], fwd[i - 1] - rate), fwd[i - 1] + rate)
    for i in range(len(theta) - 2, -1, -1):
        bwd[i] = min(max(theta[i], bwd[i + 1] - rate), bwd[i + 1] + rate)
    return 0.5 * (fwd + bwd)


def rounded(target, max_curvature: float, spacing: float) -> np.ndarray:
    """The curve with its turns slowed to at most ``max_curvature`` (radians per unit length):
    its direction, sampled every ``spacing`` along it, passed through a slew-rate limiter
    forward and backward and averaged, at twice the limit (a corner becomes a ramp centred on
    it at the limit: a round), and again at the limit where a smooth turn still exceeds it;
    integrated back to points and stretched so that both ends stay on the curve's ends. Turns
    within the limit are kept as they are.

    Returns
    -------
    numpy.ndarray, shape (M', 2)
        ``target`` itself when nothing turns too fast.

    Examples
    --------
    >>> r = rounded([[0.0, 1.0], [0.0, 0.0], [1.0, 0.0]], 4.0, 0.01)
    >>> bool(np.allclose(r[0], [0, 1]) and np.allclose(r[-1], [1, 0]))
    True
    >>> d = np.diff(r, axis=0); a = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    >>> bool(np.max(np.abs(np.diff(a))) <= 1.1 * 4.0 * 0.01)   # the stretch adds a little
    True
    """
    curve, s = _resampled(np.asarray(target, dtype=np.float64), spacing)
    if len(curve) < 3:
        return np.asarray(target, dtype=np.float64)
    step = float(s[1] - s[0])
    d = np.diff(curve, axis=0)
    theta = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    rate = max_curvature * step
    if np.max(np.abs(np.diff(theta))) <= rate:
        return np.asarray(target, dtype=np.float64)
    th = _limited(theta, 2.0 * rate)
    if np.max(np.abs(np.diff(th))) > rate * (1.0 + RATE_RTOL):
        th = _limited(th, rate)
    out = curve[0] + np.vstack([[0.0, 0.0], np.cumsum(step * np.column_stack([np.cos(th),
                                                                              np.sin(th)]),
                                                      axis=0)])
    return out + (curve[-1] - out[-1]) * (s / s[-1])[:, None]


def next_joints(q_prev, q_cur, apex, leg, k: int):
    """The next joint of every chain for every module type: the apex step of module ``k``.

    The leg from ``q_cur`` turns by pi - apex from the direction q_prev -> q_cur, to the right
    for odd ``k`` and to the left for even ``k`` (mirrored modules alternate).

    Parameters
    ----------
    q_prev, q_cur : ndarray, shape (B, 2)
        The last two joints of each of B chains.
    apex : ndarray, shape (T,)
        Apex angle of each module type (radians).
    leg : float or ndarray broadcastable to (B, T, 1)
    k : int
        Module number, from 1.

    Returns
    -------
    ndarray, shape (B, T, 2)
    """
    sign = -1.0 if k % 2 == 1 else 1.0
    u = q_cur - q_prev
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    ang = sign * (math.pi - apex)
    c, sn = np.cos(ang), np.sin(ang)
    nu = np.stack([u[:, None, 0] * c - u[:, None, 1] * sn,
                   u[:, None, 0] * sn + u[:, None, 1] * c], axis=-1)
    return q_cur[:, None, :] + leg * nu


def track(target, apexes_deg, leg: float, *, reference_deg: float, width: int = BEAM_WIDTH,
          limit: int, max_curvature: float | None = None, stop=None) -> Track:
    """The sequence of apex angles whose zigzag follows ``target`` most closely.

    Parameters
    ----------
    target : array_like, shape (M, 2)
        The curve, design units.
    apexes_deg : array_like, shape (T,)
        Final apex angles on offer (degrees).
    leg : float
        D2*: the zigzag's leg.
    reference_deg : float
        The apex angle preferred where others do as well (straight stretches).
    width : int
        Partial chains kept per module.
    limit : int
        Most modules.
    max_curvature : float, optional
        The sharpest turn (radians per unit length) the chain is asked to make: faster turns
        of the curve are followed along :func:`rounded` (a chain that cannot turn in time
        would overshoot and wander back).
    stop : callable, optional
        Called once per module; may raise to interrupt a long search.

    Returns
    -------
    Track
        Empty ``types`` when no partial chain reached the curve's end within ``limit``.
    """
    target = np.asarray(target, dtype=np.float64)
    apex = np.radians(np.asarray(apexes_deg, dtype=np.float64))
    n = apex.size
    ref_step = leg * math.sin(math.radians(reference_deg) / 2)
    if max_curvature is not None:
        target = rounded(target, max_curvature, ref_step / SAMPLES_PER_STEP)
    curve, s_nodes = _resampled(target, ref_step / SAMPLES_PER_STEP)
    length = float(s_nodes[-1])
    seg_count = len(curve) - 1
    h = s_nodes[1] - s_nodes[0]
    behind = int(math.ceil(BEHIND * SAMPLES_PER_STEP))
    ahead = int(math.ceil(AHEAD * SAMPLES_PER_STEP))
    offsets = np.arange(-behind, ahead + 1)
    chord = point_at(target, arclength(target), min(0.5 * ref_step, length)) - target[0]
    heading0 = math.atan2(chord[1], chord[0])
    allowed = np.array([[neighbours_ok(math.degrees(a), math.degrees(b)) for b in apex]
                        for a in apex])
    reference_cost = REFERENCE_WEIGHT * (leg * (np.degrees(apex) - reference_deg) / 10.0) ** 2
    # one start per first type: the first leg turned so that the first centre-line step heads
    # along the curve's first chord; the first centre-line point is the curve's start
    start = heading0 + 0.5 * (math.pi - apex)
    d0 = leg * np.column_stack([np.cos(start), np.sin(start)])
    q_prev, q_cur = curve[0] - 0.5 * d0, curve[0] + 0.5 * d0
    last = np.arange(n)
    sigma = np.zeros(n)
    cost = np.zeros(n)
    history = []
    best = (math.inf, None, None)
    for k in range(1, int(limit) + 1):
        if stop is not None:
            stop()
        q_next = next_joints(q_prev, q_cur, apex, leg, k)            # (B, T, 2)
        m_old = 0.5 * (q_prev + q_cur)
        m_new = 0.5 * (q_cur[:, None, :] + q_next)
        step = m_new - m_old[:, None, :]
        seg = np.linalg.norm(step, axis=-1)
        # closest curve point within the window around the last progress
        base = np.clip(np.rint(sigma / h).astype(int), 0, seg_count)
        idx = np.clip(base[:, None] + offsets[None, :], 0, seg_count - 1)          # (B, W)
        a = curve[idx][:, None]                                                    # (B,1,W,2)
        ab = (curve[idx + 1] - curve[idx])[:, None]
        p = m_new[:, :, None, :]
        t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1),
                                                                 TINY), 0.0, 1.0)
        d2 = np.sum((p - a - t[..., None] * ab) ** 2, axis=-1)                     # (B,T,W)
        j = np.argmin(d2, axis=-1)
        dist2 = np.take_along_axis(d2, j[..., None], axis=-1)[..., 0]
        seg_index = np.take_along_axis(np.broadcast_to(idx[:, None, :], d2.shape),
                                       j[..., None], axis=-1)[..., 0]
        along = s_nodes[seg_index] + np.take_along_axis(t, j[..., None], axis=-1)[..., 0] * h
        sigma_new = np.maximum(sigma[:, None], along)
        # the heading asked: toward the curve a little ahead (a chain turns before a turn it
        # cannot take at once, as a driver does)
        ahead_pt = point_at(curve, s_nodes, sigma_new + LOOKAHEAD * ref_step)
        tangent = ahead_pt - m_new
        cross = step[..., 0] * tangent[..., 1] - step[..., 1] * tangent[..., 0]
        err = np.arctan2(cross, np.sum(step * tangent, axis=-1))
        lag = np.maximum(0.0, 0.5 * seg - (sigma_new - sigma[:, None]))
        c_new = (cost[:, None] + dist2 + HEADING_WEIGHT * (seg * err) ** 2
                 + LAG_WEIGHT * lag ** 2 + reference_cost[None, :])
        ok = np.eye(n, dtype=bool)[last] if k == 1 else allowed[last]
        c_new = np.where(ok, c_new, np.inf)
        done = sigma_new >= length - 0.5 * seg
        if np.any(done & np.isfinite(c_new)):
            total = np.where(done, c_new + END_WEIGHT * np.sum((m_new - curve[-1]) ** 2, axis=-1),
                             np.inf)
            b, tt = np.unravel_index(int(np.argmin(total)), total.shape)
            if total[b, tt] < best[0]:
                best = (float(total[b, tt]), k, (int(b), int(tt)))
        flat = np.where(done, np.inf, c_new).ravel()
        order = np.argsort(flat, kind="stable")
        order = order[np.isfinite(flat[order])]
        if order.size == 0 or flat[order[0]] >= best[0]:
            break  # every partial chain already costs more than the best finished one
        # the cheapest partial chain per cell of (position, heading, progress)
        mn = m_new.reshape(-1, 2)[order]
        head = np.arctan2(step.reshape(-1, 2)[order, 1], step.reshape(-1, 2)[order, 0])
        cell = np.column_stack([np.floor(mn / (CELL_STEP * ref_step)),
                                np.floor(np.degrees(head) / CELL_DEG),
                                np.floor(sigma_new.ravel()[order] / (CELL_STEP * ref_step))])
        _, first = np.unique(cell.astype(np.int64), axis=0, return_index=True)
        order = order[np.sort(first)[:int(width)]]
        parent, typ = np.divmod(order, n)
        history.append((parent, typ))
        q_prev, q_cur = q_cur[parent], q_next.reshape(-1, 2)[order]
        last, sigma, cost = typ, sigma_new.ravel()[order], flat[order]
    if best[1] is None:
        return Track(np.array([], dtype=int), np.array([]), np.zeros((0, 2)), math.inf)
    _, k_end, (b, t_last) = best
    types = [t_last]
    j = b
    for k in range(k_end - 1, 0, -1):
        parent, typ = history[k - 1]
        types.append(int(typ[j]))
        j = int(parent[j])
    types = np.array(types[::-1], dtype=int)
    apexes = np.degrees(apex[types])
    centre = strip_centreline(apexes, leg, start=curve[0], heading=heading0)
    return Track(types=types, apexes=apexes, centre=centre, cost=best[0])


def centre_of(apexes_rad: np.ndarray, heading: float, start, leg: float) -> np.ndarray:
    """Centre line (K + 1, 2) of the zigzag of these final apex angles (radians, vectorised
    form of :func:`strip_centreline`): step k is leg·sin(α_k / 2) long and turns from step
    k - 1 by half the difference of their apex angles, the side alternating."""
    a = np.asarray(apexes_rad, dtype=np.float64)
    k = np.arange(2, a.size + 1)
    side = np.where(k % 2 == 1, -1.0, 1.0)
    phi = heading + np.concatenate([[0.0], np.cumsum(side * (a[:-1] - a[1:]) / 2)])
    steps = (leg * np.sin(a / 2))[:, None] * np.column_stack([np.cos(phi), np.sin(phi)])
    return np.vstack([start, np.asarray(start, dtype=np.float64) + np.cumsum(steps, axis=0)])


def _centre_jacobian(a: np.ndarray, heading: float, leg: float) -> np.ndarray:
    """d(centre-line point j)/d(heading, α_1 … α_K) for j = 1 … K, shape (K, 2, K + 1).

    With φ_k the direction of step k and P_j = Σ_{k≤j} ℓ_k u⊥(φ_k): the heading turns every
    step (P_j); α_i lengthens step i and turns step i by -side_i / 2 and every later step by
    -side_i (α_1 turns the later steps by 1/2: the heading is the first step's)."""
    n = a.size
    k = np.arange(1, n + 1)
    side = np.where(k % 2 == 1, -1.0, 1.0)
    phi = heading + np.concatenate([[0.0], np.cumsum(side[1:] * (a[:-1] - a[1:]) / 2)])
    u = np.column_stack([np.cos(phi), np.sin(phi)])
    perp = np.column_stack([-u[:, 1], u[:, 0]])
    ell = leg * np.sin(a / 2)
    P = np.cumsum(ell[:, None] * perp, axis=0)                              # (K, 2)
    own = np.where(k == 1, 0.0, -0.5 * side)                                # turn of step i
    later = np.where(k == 1, 0.5, -side)                                    # of steps > i
    A = (0.5 * leg * np.cos(a / 2))[:, None] * u + (own * ell)[:, None] * perp - later[:, None] * P
    J = np.zeros((n, 2, n + 1))
    J[:, :, 0] = P
    lower = np.tril(np.ones((n, n), dtype=bool))                            # i <= j
    J[:, :, 1:] = np.where(lower[:, None, :], A.T[None, :, :]
                           + later[None, None, :] * P[:, :, None], 0.0)
    return J


def refine(target, apexes_deg, leg: float, *, low_deg: float, high_deg: float,
           rounds: int = REFINE_ROUNDS, stop=None) -> tuple[np.ndarray, np.ndarray]:
    """Apex angles, now any within [``low_deg``, ``high_deg``], that bring a chain closest to
    ``target``: least squares (scipy's bounded trust-region solver) on the distances of the
    centre-line points to their closest curve points (refreshed each round, sought near the
    last), with the chain's end held to the curve's end and neighbours averaging at least
    ``MIN_PAIR_APEX_DEG`` (a penalty). Starting from a chain that already follows the curve
    (:func:`track`), it balances what a step-by-step search cannot: a chain that must start
    turning before a corner, a turn spread over the modules that can make it.

    Returns
    -------
    apexes : numpy.ndarray, shape (K,)
        Degrees.
    centre : numpy.ndarray, shape (K + 1, 2)
        The refined chain's centre line (first point on the curve's start).
    """
    from scipy.optimize import least_squares

    target = np.asarray(target, dtype=np.float64)
    a0 = np.radians(np.clip(np.asarray(apexes_deg, dtype=np.float64), low_deg, high_deg))
    start = target[0]
    first = centre_of(a0, 0.0, start, leg)
    chord0 = first[1] - first[0]
    ref = point_at(target, arclength(target), np.linalg.norm(chord0)) - start
    heading = math.atan2(ref[1], ref[0]) - math.atan2(chord0[1], chord0[0])
    x = np.concatenate([[heading], a0])
    s_nodes = arclength(target)
    step = float(np.mean(leg * np.sin(a0 / 2)))
    pair_floor = math.radians(MIN_PAIR_APEX_DEG + PAIR_MARGIN_DEG)
    lower = np.concatenate([[-np.inf], np.full(a0.size, math.radians(low_deg))])
    upper = np.concatenate([[np.inf], np.full(a0.size, math.radians(high_deg))])
    x = np.clip(x, lower, upper)
    near = arclength(centre_of(x[1:], x[0], start, leg))[1:]
    for _ in range(int(rounds)):
        if stop is not None:
            stop()
        m = centre_of(x[1:], x[0], start, leg)
        _, near, match = closest_on_curve(m[1:], target, s_nodes, near, AHEAD * step)

        def residuals(v, match=match):
            c = centre_of(v[1:], v[0], start, leg)
            pair = PAIR_WEIGHT * leg * np.maximum(0.0, pair_floor - 0.5 * (v[1:-1] + v[2:]))
            return np.concatenate([(c[1:] - match).ravel(),
                                   math.sqrt(END_WEIGHT) * (c[-1] - target[-1]), pair])

        def jacobian(v):
            J = _centre_jacobian(v[1:], v[0], leg)                       # (K, 2, K + 1)
            n = v.size - 1
            active = (pair_floor - 0.5 * (v[1:-1] + v[2:])) > 0
            P = np.zeros((n - 1, n + 1))
            rows = np.arange(n - 1)
            P[rows, rows + 1] = P[rows, rows + 2] = np.where(active, -0.5 * PAIR_WEIGHT * leg, 0)
            return np.vstack([J.reshape(2 * n, n + 1), math.sqrt(END_WEIGHT) * J[-1], P])

        x = least_squares(residuals, x, jac=jacobian, bounds=(lower, upper), method="trf",
                          max_nfev=REFINE_EVALUATIONS, x_scale="jac", tr_solver="lsmr").x
    return np.degrees(x[1:]), centre_of(x[1:], x[0], start, leg)


def follow(centre, bins_deg, leg: float, *, width: int = BEAM_WIDTH, stop=None) -> np.ndarray:
    """The binned type of every module that reproduces a chain module by module: a beam
    search over the types whose cost is the squared distance of each centre-line point from
    the same point of ``centre`` (the refined chain, K + 1 points), plus its heading error
    times its step (squared); neighbours average at least ``MIN_PAIR_APEX_DEG``.

    Returns
    -------
    numpy.ndarray of int, shape (K,)
        Index into ``bins_deg`` per module (empty when the neighbour rule leaves no chain).
    """
    ref = np.asarray(centre, dtype=np.float64)
    apex = np.radians(np.asarray(bins_deg, dtype=np.float64))
    n, count = apex.size, len(ref) - 1
    allowed = np.array([[neighbours_ok(math.degrees(a), math.degrees(b)) for b in apex]
                        for a in apex])
    steps = np.diff(ref, axis=0)
    heading0 = math.atan2(steps[0, 1], steps[0, 0])
    start = heading0 + 0.5 * (math.pi - apex)
    d0 = leg * np.column_stack([np.cos(start), np.sin(start)])
    q_prev, q_cur = ref[0] - 0.5 * d0, ref[0] + 0.5 * d0
    last = np.arange(n)
    cost = np.zeros(n)
    history = []
    for k in range(1, count + 1):
        if stop is not None:
            stop()
        q_next = next_joints(q_prev, q_cur, apex, leg, k)
        m_new = 0.5 * (q_cur[:, None, :] + q_next)
        step = m_new - 0.5 * (q_prev + q_cur)[:, None, :]
        want = steps[k - 1]
        cross = step[..., 0] * want[1] - step[..., 1] * want[0]
        err = np.arctan2(cross, np.sum(step * want, axis=-1))
        seg = np.linalg.norm(step, axis=-1)
        c_new = (cost[:, None] + np.sum((m_new - ref[k]) ** 2, axis=-1)
                 + HEADING_WEIGHT * (seg * err) ** 2)
        ok = np.eye(n, dtype=bool)[last] if k == 1 else allowed[last]
        flat = np.where(ok, c_new, np.inf).ravel()
        order = np.argsort(flat, kind="stable")[:int(width)]
        order = order[np.isfinite(flat[order])]
        if order.size == 0:
            return np.array([], dtype=int)
        parent, typ = np.divmod(order, n)
        history.append((parent, typ))
        q_prev, q_cur = q_cur[parent], q_next.reshape(-1, 2)[order]
        last, cost = typ, flat[order]
    types, j = [], 0
    for k in range(count, 0, -1):
        parent, typ = history[k - 1]
        types.append(int(typ[j]))
        j = int(parent[j])
    return np.array(types[::-1], dtype=int)


def refit_bins(target, bins_deg, types, leg: float, *, low_deg: float, high_deg: float,
               rounds: int = 2, stop=None) -> np.ndarray:
    """The bins' apex angles refitted to the curve with every module's type held: least squares
    as in :func:`refine`, over the few bin angles (and the start heading) only.

    Returns
    -------
    numpy.ndarray, shape (T,)
        Degrees, ascending order not guaranteed.
    """
    from scipy.optimize import least_squares

    target = np.asarray(target, dtype=np.float64)
    types = np.asarray(types, dtype=int)
    t_count = len(bins_deg)
    A = np.zeros((types.size, t_count))
    A[np.arange(types.size), types] = 1.0
    a0 = np.radians(np.asarray(bins_deg, dtype=np.float64))
    start = target[0]
    s_nodes = arclength(target)
    first = centre_of(A @ a0, 0.0, start, leg)
    chord0 = first[1] - first[0]
    ref = point_at(target, s_nodes, np.linalg.norm(chord0)) - start
    x = np.concatenate([[math.atan2(ref[1], ref[0]) - math.atan2(chord0[1], chord0[0])], a0])
    lower = np.concatenate([[-np.inf], np.full(t_count, math.radians(low_deg))])
    upper = np.concatenate([[np.inf], np.full(t_count, math.radians(high_deg))])
    x = np.clip(x, lower, upper)
    step = float(np.mean(leg * np.sin(a0 / 2)))
    near = arclength(centre_of(A @ x[1:], x[0], start, leg))[1:]
    pairs = np.unique(np.sort(np.column_stack([types[:-1], types[1:]]), axis=1), axis=0)
    floor = math.radians(MIN_PAIR_APEX_DEG + PAIR_MARGIN_DEG)
    weight = PAIR_WEIGHT * leg
    for _ in range(int(rounds)):
        if stop is not None:
            stop()
        m = centre_of(A @ x[1:], x[0], start, leg)
        _, near, match = closest_on_curve(m[1:], target, s_nodes, near, AHEAD * step)

        def residuals(v, match=match):
            c = centre_of(A @ v[1:], v[0], start, leg)
            b = v[1:]
            pair = weight * np.maximum(0.0, floor - 0.5 * (b[pairs[:, 0]] + b[pairs[:, 1]]))
            return np.concatenate([(c[1:] - match).ravel(),
                                   math.sqrt(END_WEIGHT) * (c[-1] - target[-1]), pair])

        def jacobian(v):
            J = _centre_jacobian(A @ v[1:], v[0], leg)
            J = np.concatenate([J[:, :, :1], J[:, :, 1:] @ A], axis=2)
            b = v[1:]
            active = floor - 0.5 * (b[pairs[:, 0]] + b[pairs[:, 1]]) > 0
            P = np.zeros((len(pairs), t_count + 1))
            rows = np.arange(len(pairs))
            P[rows, 1 + pairs[:, 0]] += np.where(active, -0.5 * weight, 0.0)
            P[rows, 1 + pairs[:, 1]] += np.where(active, -0.5 * weight, 0.0)
            return np.vstack([J.reshape(-1, t_count + 1), math.sqrt(END_WEIGHT) * J[-1], P])

        x = least_squares(residuals, x, jac=jacobian, bounds=(lower, upper), method="trf",
                          max_nfev=REFINE_EVALUATIONS, x_scale="jac").x
    return np.degrees(x[1:])


def bin_apexes(apexes_deg, count: int, pin: bool = False) -> np.ndarray:
    """``count`` apex angles (degrees, ascending) that bin the given ones: a one-dimensional
    k-means; with ``pin``, its lowest and highest bins are pinned to the extreme angles (the
    sharpest turn survives the binning).

    Examples
    --------
    >>> bin_apexes([50, 51, 70, 71, 72, 86], 3).round(3).tolist()
    [50.5, 71.0, 86.0]
    >>> bin_apexes([50, 51, 70, 71, 72, 86], 3, pin=True).round(3).tolist()
    [50.0, 71.0, 86.0]
    """
    a = np.sort(np.asarray(apexes_deg, dtype=np.float64))
    uniq = np.unique(a)
    if count >= uniq.size:
        return uniq
    if count == 1:
        return np.array([float(np.median(a))])
    centres = np.quantile(a, (np.arange(count) + 0.5) / count)
    if pin:
        centres[0], centres[-1] = a[0], a[-1]
    for _ in range(KMEANS_ROUNDS):
        label = np.argmin(np.abs(a[:, None] - centres[None, :]), axis=1)
        new = np.array([a[label == i].mean() if np.any(label == i) else centres[i]
                        for i in range(count)])
        if pin:
            new[0], new[-1] = a[0], a[-1]
        if np.allclose(new, centres):
            break
        centres = new
    return np.unique(np.round(centres, 9))
