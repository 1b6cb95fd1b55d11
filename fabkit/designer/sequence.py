"""Choosing the type of every module of a curve-following chain.

Candidates come from three searches over the zigzag model of :func:`fabkit.letters.strip_model`
(design units): the letters' beam search (:func:`fabkit.letters.design_curve`), a beam search
that respects the neighbour rule and starts along the curve, and the plain alternations a, b, a, b, ... (a
circular arc's chain). Sequences that put two narrow modules side by side are dropped (see
``MIN_PAIR_APEX_DEG``); of those whose fitted centre line lies within ``REGULAR_SLACK`` of the
best, the most regular one is taken.
"""

from __future__ import annotations

import math

import numpy as np

from ..numerics import apply_fit, rigid_fit
from .curvature import MIN_PAIR_APEX_DEG

__all__ = ["choose_types", "neighbours_ok", "REGULAR_SLACK"]

#: Type sequences whose fit error is within this fraction of the best count as equally good
#: (the most regular of them is taken).
REGULAR_SLACK = 0.25
#: Partial designs kept per module by the neighbour-respecting beam search.
BEAM_WIDTH = 64
#: Slack (degrees) of the neighbour rule: the straight type at exactly MIN_PAIR_APEX_DEG
#: beside itself meets it despite round-off of the measured apex angles.
PAIR_SLACK_DEG = 1e-6


def neighbours_ok(m1, m2) -> bool:
    """Two neighbouring modules may stand side by side in a laser kit: their final apex angles
    average at least ``MIN_PAIR_APEX_DEG``."""
    return math.degrees(0.5 * (m1.apex + m2.apex)) >= MIN_PAIR_APEX_DEG - PAIR_SLACK_DEG


def _sequence_ok(types, modules) -> bool:
    return all(neighbours_ok(modules[a], modules[b]) for a, b in zip(types[:-1], types[1:]))


def _centre_line(types, modules, **kw) -> np.ndarray:
    from ..letters import strip_model

    m = strip_model(types, modules, **kw)
    return 0.5 * (m[:-1] + m[1:])


def _beam(target: np.ndarray, modules, limit: int, width: int) -> np.ndarray:
    """Module types chosen by a beam search that keeps the chain's centre line on ``target``
    (design units) and never puts two modules side by side that ``neighbours_ok`` refuses.

    The zigzag is grown module by module as in :func:`fabkit.letters.strip_model` (module k
    turns the leg direction by (π - apex) clockwise for odd k, anticlockwise for even k); each
    partial design costs the squared distance of every new centre-line point from the target
    point at the same arclength plus its heading error times the step, squared. Starting
    heading: along the target's first chord."""
    from ..letters import _point_at, _resample

    s_nodes = _resample(target)
    length = float(s_nodes[-1])
    chord = target[np.searchsorted(s_nodes, min(0.05 * length, s_nodes[-1]))] - target[0]
    heading0 = math.atan2(chord[1], chord[0])
    apex = np.array([m.apex for m in modules])
    leg = modules[0].leg
    n = apex.size
    allowed = np.array([[neighbours_ok(modules[a], modules[b]) for b in range(n)]
                        for a in range(n)])
    # one start per first type: the first leg turned so that the first centre-line step heads
    # along the target's first chord; state: the last two zigzag points, the last type (the
    # first type to come, before module 1), arclength, cost
    start = heading0 + 0.5 * (math.pi - apex)
    d0 = leg * np.column_stack([np.cos(start), np.sin(start)])
    q_prev, q_cur = target[0] - 0.5 * d0, target[0] + 0.5 * d0
    last = np.arange(n)
    s = np.zeros(n)
    cost = np.zeros(n)
    history = []
    best = (math.inf, None, None)
    for k in range(1, limit + 1):
        sign = -1.0 if k % 2 == 1 else 1.0
        u = q_cur - q_prev
        u = u / np.linalg.norm(u, axis=1, keepdims=True)
        ang = sign * (math.pi - apex)
        c, sn = np.cos(ang), np.sin(ang)
        nu = np.stack([u[:, None, 0] * c - u[:, None, 1] * sn,
                       u[:, None, 0] * sn + u[:, None, 1] * c], axis=-1)
        q_next = q_cur[:, None, :] + leg * nu                       # (B, T, 2)
        m_old = 0.5 * (q_prev + q_cur)
        m_new = 0.5 * (q_cur[:, None, :] + q_next)
        step = m_new - m_old[:, None, :]
        seg = np.linalg.norm(step, axis=-1)
        s_new = s[:, None] + seg
        here = _point_at(target, s_nodes, s_new)
        ahead = _point_at(target, s_nodes, s_new + seg) - here
        cross = step[..., 0] * ahead[..., 1] - step[..., 1] * ahead[..., 0]
        err = np.arctan2(cross, np.sum(step * ahead, axis=-1))
        c_new = cost[:, None] + np.sum((m_new - here) ** 2, axis=-1) + (seg * err) ** 2
        ok = np.eye(n, dtype=bool)[last] if k == 1 else allowed[last]
        c_new = np.where(ok, c_new, np.inf)
        done = s_new >= length - 0.5 * seg
        for b, t in zip(*np.nonzero(done & np.isfinite(c_new))):
            total = c_new[b, t] + float(np.sum((m_new[b, t] - target[-1]) ** 2))
            if total < best[0]:
                best = (total, k, (b, t))
        flat = np.where(done, np.inf, c_new).ravel()
        order = np.argsort(flat, kind="stable")[:width]
        order = order[np.isfinite(flat[order])]
        if order.size == 0 or flat[order[0]] >= best[0]:
            break  # every partial design already costs more than the best finished one
        parent, typ = np.divmod(order, n)
        history.append((parent, typ))
        q_prev, q_cur = q_cur[parent], q_next.reshape(-1, 2)[order]
        last, s, cost = typ, s_new.ravel()[order], flat[order]
    if best[1] is None:
        return np.array([], dtype=int)
    _, k_end, (b, t) = best
    # history[k - 1] holds, for module k's kept states, their parent state and their type
    types = [int(t)]
    j = int(b)
    for k in range(k_end - 1, 0, -1):
        parent, typ = history[k - 1]
        types.append(int(typ[j]))
        j = int(parent[j])
    return np.array(types[::-1], dtype=int)


def _alternation(target: np.ndarray, modules, a: int, b: int, limit: int) -> np.ndarray:
    """Types a, b, a, b, ... as long as the target: the chain of a circular arc."""
    length = float(np.sum(np.linalg.norm(np.diff(target, axis=0), axis=1)))
    types = [a, b]
    while len(types) < limit:
        seg = np.linalg.norm(np.diff(_centre_line(types, modules), axis=0), axis=1)
        if seg.sum() >= length - 0.5 * seg[-1]:
            break
        types.append(types[-2])
    return np.array(types, dtype=int)


def strip_error(types, modules, target) -> float:
    """RMS distance of a type sequence's centre line, rigidly fitted onto the target at equal
    arclength, to the target, plus the distance between their ends (design units)."""
    from ..letters import _point_at, _resample, polyline_distance

    c = _centre_line(types, modules)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
    ref = _point_at(target, _resample(target), s)
    moved = apply_fit(rigid_fit(c, ref, handedness="proper"), c)
    d = polyline_distance(moved, target)
    return float(np.sqrt(np.mean(d ** 2)) + np.linalg.norm(moved[-1] - target[-1]))


def _kinds(types) -> int:
    """Distinct runs of three neighbouring types (with the mirror parity of the first)."""
    t = np.asarray(types)
    return len({(int(t[k]), int(t[k + 1]), int(t[k + 2]), k % 2) for k in range(len(t) - 2)})


def choose_types(target: np.ndarray, modules, *, beam: int, limit: int) -> np.ndarray:
    """The type (index into ``modules``) of every module of the chain that follows ``target``.

    Parameters
    ----------
    target : numpy.ndarray, shape (M, 2)
        The curve in design units.
    modules : list of fabkit.letters.CurvatureModule
    beam : int
        Beam width of the letters' search.
    limit : int
        Most modules.

    Returns
    -------
    numpy.ndarray of int
    """
    from ..letters import design_curve

    n = len(modules)
    options = [design_curve(target, modules, beam=int(beam), max_modules=limit).types]
    options.append(_beam(target, modules, limit, BEAM_WIDTH))
    options += [_alternation(target, modules, a, b, limit) for a in range(n) for b in range(n)
                if a != b]
    options = [o for o in options if len(o) >= 2 and _sequence_ok(o, modules)]
    errors = [strip_error(o, modules, target) for o in options]
    best = min(errors)
    near = [k for k, e in enumerate(errors) if e <= best * (1 + REGULAR_SLACK)]
    k = min(near, key=lambda i: (_kinds(options[i]), errors[i]))
    return np.asarray(options[k], dtype=int)
