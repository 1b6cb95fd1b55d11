"""Building maps of networks: walking the whole motion and splitting it into monotone branches."""

from __future__ import annotations

import dataclasses

import numpy as np

from .. import arguments
from ..errors import ConstructionError, DesignError, FlatStateError
from ..kinematics import place, plan_construction
from ..model.network import checked_network, Network
from ..numerics import DOMAIN_RTOL, FLAT_RTOL, TINY
from .evaluate import Constructive2D, ConstructiveGeneral, port_pair
from .map1d import Map1D
from .results import Branch


#: Brent's method finds a branch end to this tolerance (relative to d_in): round-off.
ROOT_XTOL = 1e-15
#: A flat reference is nudged this far (relative to the network) to read which side each node
#: lies on: far above round-off, far below any feature of the motion.
FLAT_NUDGE = 1e-7
#: A value within this (relative to the network) of a branch's domain lies on the branch; the
#: next branch is probed this far past a turning point.
ON_BRANCH_RTOL = 1e-9


def _evaluator(net, plan, in_pair, out_pair):
    if net.dim == 2:
        return Constructive2D(plan, out_pair)
    return ConstructiveGeneral(plan, net, in_pair, out_pair)


def _turning_point(ev, signs, inside, outside):
    """The d_in where the branch with these signs ends, between a valid and an invalid value.

    The end is where a node's intersection vanishes (its margin crosses zero) or where the node
    has no place at all (its parents on one line: a flat state where branches meet, margin
    undefined); an undefined margin counts as -1, so the root search lands on that boundary
    too."""
    from scipy.optimize import brentq  # here: the command line's parent process needs none of it

    def margin(x):
        m = float(ev(np.array([x]), signs, derivative=False)[2][0])
        return m if np.isfinite(m) else -1.0

    if margin(outside) >= -FLAT_RTOL:
        return outside
    if not margin(inside) > 0.0:  # already flat (to round-off) where the search starts
        return inside
    t = brentq(margin, inside, outside, xtol=ROOT_XTOL * max(abs(inside), 1.0),
               rtol=4 * np.finfo(float).eps, maxiter=300)
    # land on the valid side, so the branch end evaluates
    step = np.spacing(t) * (1 if inside > t else -1)
    for _ in range(64):
        if margin(t) >= -FLAT_RTOL:
            break
        t += step
    if margin(t) < -FLAT_RTOL:  # an undefined stretch: back to the last value that evaluates
        t = inside
    return t


def _defined_start(ev, signs, d0, size):
    """``d0``, or the nearest value to it where the branch has a place, when the reference
    itself has none (its parents on one line: a flat state where branches meet)."""
    _, _, m, _ = ev(np.array([d0]), signs, derivative=False)
    if m[0] >= -FLAT_RTOL:
        return d0
    for k in range(48):  # from round-off outwards, both sides
        for side in (-1.0, 1.0):
            probe = d0 + side * size * ROOT_XTOL * 2.0 ** k
            _, _, m, _ = ev(np.array([probe]), signs, derivative=False)
            if m[0] >= -FLAT_RTOL:
                return float(probe)
    return d0


def _walk_branch(ev, signs, d0, size, samples):
    """Extent [lo, hi] of the branch with these signs that contains d0, and the step index of
    the node that becomes flat at each end (-1: no end found in range)."""
    ends = []
    d0 = _defined_start(ev, signs, d0, size)
    for direction in (-1.0, 1.0):
        # geometric search outwards: find the first invalid value
        # fine near d0, coarse far out: up to 4 network sizes away
        grid = d0 + direction * 4.0 * size * np.linspace(0, 1, samples)[1:] ** 2
        grid = grid[grid > 0]
        _, _, m, _ = ev(grid, signs, derivative=False)
        bad = np.flatnonzero(m < -FLAT_RTOL)
        if bad.size == 0:
            ends.append((float(grid[-1]) if grid.size else d0, -1))
            continue
        k = int(bad[0])
        inside = d0 if k == 0 else float(grid[k - 1])
        t = _turning_point(ev, signs, inside, float(grid[k]))
        _, _, _, w = ev(np.array([t]), signs, derivative=False)
        ends.append((t, int(w[0])))
    (lo, wlo), (hi, whi) = ends
    return lo, hi, wlo, whi


def _flat_nudge(x: np.ndarray, a: int, b: int) -> np.ndarray:
    """A deterministic unit-size perturbation of every node, fixed in the frame of the drive
    pair and of the start's own handedness, so the branch it selects does not depend on where
    (or mirrored how) the network is drawn."""
    n, d = x.shape
    u = x[b] - x[a]
    u = u / np.linalg.norm(u)
    rng = np.random.default_rng(0)
    coef = rng.standard_normal((n, d))
    if d == 2:
        v = np.array([-u[1], u[0]])
        rel = x - x[a]
        cross = rel[:, 0] * u[1] - rel[:, 1] * u[0]
        k = int(np.argmax(np.abs(cross)))
        hand = -np.sign(cross[k]) or 1.0  # the side of the node farthest from the drive axis
        return coef[:, :1] * u + hand * coef[:, 1:2] * v
    # 3D: a frame (u, v, w) from the two nodes farthest from the drive axis
    rel = x - x[a]
    perp = rel - np.outer(rel @ u, u)
    k = int(np.argmax(np.linalg.norm(perp, axis=1)))
    v = perp[k] / max(np.linalg.norm(perp[k]), TINY)
    w = np.cross(u, v)
    side = rel @ w
    j = int(np.argmax(np.abs(side)))
    hand = np.sign(side[j]) or 1.0
    return coef[:, :1] * u + coef[:, 1:2] * v + hand * coef[:, 2:3] * w


def module_map(net: Network, d_in="d1", d_out="d2", *, reference=None, toward: float | None = None,
               branch: int | None = None, max_branches: int = 64, name: str | None = None) -> Map1D:
    """The map d_out = f(d_in) of a module on the branch through its reference configuration.

    Parameters
    ----------
    net : Network
        A network with a construction order from the d_in pair (2D or 3D).
    d_in, d_out : str or (int, int)
        Ports (or node pairs) of the map.
    reference : array_like, shape (N, d), optional
        Configuration that selects the branch (``net.nodes`` by default).
    toward : float, optional
        When the reference is itself a turning point of d_in (it lies on two branches), the
        branch that contains this d_in value is taken.
    branch : int, optional
        Take ``branches[branch]`` of the walked motion instead (e.g. a linkage that starts
        flat, such as a collapsed 4-bar, leaves its start on two mirror branches in the same
        direction of d_in; the walk starts on the one given by a deterministic nudge).
    max_branches : int
        Stop walking the whole motion after this many branches.
    name : str, optional

    Returns
    -------
    Map1D
        With ``branches`` listing every monotone branch of the motion found by walking it.

    Raises
    ------
    ConstructionError
        No construction order from d_in (use :func:`map_from_trajectory` with a ``projected``
        trace), or the reference is a flat state.

    Examples
    --------
    >>> import fabkit
    >>> net = fabkit.Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]],
    ...                      ports={"d1": (0, 1), "d2": (2, 3)})
    >>> f = module_map(net)
    >>> round(f(2.5), 12), round(f.derivative(2.5), 12)
    (1.6, -0.64)
    """
    checked_network("net", net)
    if toward is not None:
        toward = arguments.real("toward", toward, positive=True)
    if branch is not None:
        branch = arguments.whole("branch", branch, minimum=0)
    max_branches = arguments.whole("max_branches", max_branches, minimum=1)
    a, b = port_pair(net, d_in)
    out = port_pair(net, d_out)
    x = net.nodes if reference is None else np.asarray(reference, dtype=np.float64)
    d0 = float(np.linalg.norm(x[a] - x[b]))
    size = float(max(net.size, d0))
    try:
        plan = plan_construction(net, (a, b), x)
    except FlatStateError:
        # A flat reference (e.g. a linkage that starts collapsed) lies at a turning point, on
        # two branches. Sides are taken from a slightly nudged copy; walking the motion finds
        # both branches, and `toward` picks one.
        plan = plan_construction(net, (a, b), x + FLAT_NUDGE * size * _flat_nudge(x, a, b))
    ev = _evaluator(net, plan, (a, b), out)
    samples = 2049
    signs0 = tuple(float(s) for s in plan.signs)

    def describe(w):
        if w < 0:
            return "end of the searched range"
        v = int(plan.order[w])
        par = ", ".join(str(int(p)) for p in plan.parents[w] if p >= 0)
        shape = "collinear" if net.dim == 2 else "coplanar"
        return f"turning point: node {v} {shape} with nodes {par}"

    lo, hi, wlo, whi = _walk_branch(ev, signs0, d0, size, samples)
    first = Branch(0, lo, hi, signs0, (describe(wlo), describe(whi)),
                   turning=(bool(wlo >= 0), bool(whi >= 0)))
    branches = [first]
    # walk the rest of the motion: at each end flip the side of the node that became flat
    seen = {signs0}
    for d_end, wk in ((lo, wlo), (hi, whi)):
        signs, previous = signs0, 0
        while wk >= 0 and len(branches) < max_branches and plan.signs[wk] != 0:
            # (a 3D gauge node has no side to flip: its half-plane is a convention)
            flipped = list(signs)
            flipped[wk] = -flipped[wk]
            signs = tuple(flipped)
            if signs in seen:  # back on a branch already walked: the motion is a closed loop
                break
            nlo, nhi, nwlo, nwhi = _walk_from_end(ev, signs, d_end, size, samples)
            if not nhi > nlo:
                break
            seen.add(signs)
            branches.append(Branch(len(branches), nlo, nhi, signs, (describe(nwlo), describe(nwhi)),
                                   previous=previous, entered_at=float(d_end),
                                   turning=(bool(nwlo >= 0), bool(nwhi >= 0))))
            previous = len(branches) - 1
            # continue from the far end of the new branch
            if abs(nhi - d_end) >= abs(nlo - d_end):
                d_end, wk = nhi, nwhi
            else:
                d_end, wk = nlo, nwlo
    # the branch through the reference (or, at a turning reference, the one toward `toward`)
    chosen = first
    if toward is not None and not first.lo <= toward <= first.hi:
        tol = ON_BRANCH_RTOL * size
        candidates = [br for br in branches
                      if br.lo - tol <= d0 <= br.hi + tol and br.lo <= toward <= br.hi]
        if not candidates:
            raise DesignError(f"no branch through the reference d_in = {d0:.10g} reaches "
                              f"{toward:.10g}")
        chosen = candidates[0]
    if branch is not None:
        if not 0 <= int(branch) < len(branches):
            raise DesignError(f"branch must be in 0..{len(branches) - 1} (the motion has "
                              f"{len(branches)} monotone branches), got {branch}")
        chosen = branches[int(branch)]
    if not chosen.hi > chosen.lo:
        raise ConstructionError(
            f"the reference configuration is a turning point of d_in = {d0:.10g}: the branch "
            "through it is a single point; pass `toward` to choose the branch on either side")

    def fun_for(br):
        def fun(d, derivative=True):
            f, df, _, _ = ev(np.asarray(d, dtype=np.float64), br.signs, derivative, margins=False)
            return f, df
        return fun

    def curve_fun(br, samples_per_branch):
        if samples_per_branch is None:
            return fun_for(br)
        g = np.linspace(br.lo, br.hi, int(samples_per_branch))
        return g, ev(g, br.signs, derivative=False)[0]

    def configuration(br, d):
        signed = dataclasses.replace(plan, signs=np.asarray(br.signs, dtype=np.float64))
        return place(signed, np.atleast_1d(np.asarray(d, dtype=np.float64)))[0]

    label = name or f"{port_label(net, d_in)} -> {port_label(net, d_out)}"
    return Map1D(fun=fun_for(chosen), domain=(chosen.lo, chosen.hi), branches=branches,
                 branch=chosen, source="constructive", name=label, curve_fun=curve_fun,
                 configuration_fun=configuration,
                 reference=d0 if _on(chosen, d0, size) else None)


def _on(br, d, size) -> bool:
    """d lies on the branch (to round-off of its ends: a reference where the branch has no
    place, such as a flat sheet where branches meet, lies ~1e-14 past its end)."""
    slack = DOMAIN_RTOL * max(size, 1.0)
    return br.lo - slack <= d <= br.hi + slack


def _walk_from_end(ev, signs, d_end, size, samples):
    """Branch with these signs that starts at the turning value d_end."""
    # The new branch exists on one side of d_end; probe both sides just off the end.
    eps = ON_BRANCH_RTOL * size
    for side in (-1.0, 1.0):
        probe = np.array([d_end + side * eps])
        _, _, m, _ = ev(probe, signs, derivative=False)
        if m[0] >= -FLAT_RTOL:
            lo, hi, wlo, whi = _walk_branch(ev, signs, float(probe[0]), size, samples)
            return lo, hi, wlo, whi
    return d_end, d_end, -1, -1


def port_label(net, spec):
    """A port as the name of a map: its name, or ``|xi - xj|`` for a pair of nodes.

    Parameters
    ----------
    net : Network
        The network (unused; kept beside :func:`~fabkit.maps.evaluate.port_pair`'s order).
    spec : str or (int, int)
        A port name or two node indices.

    Returns
    -------
    str
    """
    return spec if isinstance(spec, str) else f"|x{spec[0]} - x{spec[1]}|"
