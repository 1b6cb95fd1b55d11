"""Placing simulated builds: many builds and drive values in one pass, locks at turning points."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..builds.closure import play_ratio, self_stress_basis
from ..errors import FabkitError, FabricationError
from ..fab.creases import origami_model
from ..kinematics import place
from ..numerics import EDGE_RTOL
from ..settings.origami import origami_settings
from .processes import interp_rows, ProcessGeometry, PROFILE_SAMPLES, Sheet, state_profile
from ..model.network import chain_port_number, is_chain_port

#: Builds whose lengths must be realised and traced one by one (no construction order) are
#: slow; their number is capped at this.
PROJECTED_SAMPLES_CAP = 40

#: Bisection steps that find where a build locks (a turning point short of the target): 2^-18
#: of a 40th of the motion.
LOCK_BISECTIONS = 18

#: A simulated build is projected onto its own bar lengths to this relative error (its bars
#: carry process errors of ~1e-3, so a tighter fit adds nothing).
BUILD_RTOL = 1e-9


def chain_ports(net) -> list[str]:
    """Ports named d1, d2, ... in order, followed by the other ports.

    Parameters
    ----------
    net : fabkit.model.network.Network

    Returns
    -------
    list of str
        ``["d1", "d2", ..., "d10", ...]`` by number, then the other port names sorted.
    """
    chain = sorted((p for p in net.ports if is_chain_port(p)), key=chain_port_number)
    return chain + sorted(p for p in net.ports if p not in chain)


def to_drive_frame(x, a, b, ref_dir) -> np.ndarray:
    """Rigidly move configurations so node a is at the origin and a→b along ``ref_dir``.

    Parameters
    ----------
    x : array_like, shape (..., N, d)
        Configurations.
    a, b : int
        The drive's nodes.
    ref_dir : array_like, shape (2,)
        The direction a→b is turned to (2D).

    Returns
    -------
    numpy.ndarray, shape (..., N, d)
        In 2D rotated and translated; in 3D only translated (relative to node a).
    """
    x = np.asarray(x) - np.asarray(x)[..., a:a + 1, :]
    if x.shape[-1] != 2:
        return x
    u = x[..., b, :] / np.linalg.norm(x[..., b, :], axis=-1, keepdims=True)
    ang = np.arctan2(ref_dir[1], ref_dir[0]) - np.arctan2(u[..., 1], u[..., 0])
    c, s = np.cos(ang)[..., None], np.sin(ang)[..., None]
    return np.stack([c * x[..., 0] - s * x[..., 1], s * x[..., 0] + c * x[..., 1]], axis=-1)


def _place_builds(plan, values, radii) -> tuple[np.ndarray, np.ndarray]:
    """Place every build at its own drive values in one pass of :func:`fabkit.kinematics.place`,
    one column per (build, drive value) carrying its build's radii.

    Parameters
    ----------
    plan : ConstructionPlan
    values : numpy.ndarray, shape (M, G)
        Drive values of each build.
    radii : numpy.ndarray, shape (M, K, dim)
        Each build's distances of every placed node to its parents.

    Returns
    -------
    positions : numpy.ndarray, shape (M, G, N, d)
    margin : numpy.ndarray, shape (M, G)
        Smallest ``h² / r²`` over the intersections; negative where one does not exist.
    """
    m, g = values.shape
    x, margin, _ = place(plan, values.reshape(m * g), radii=np.repeat(radii, g, axis=0))
    return x.reshape((m, g) + x.shape[1:]), margin.reshape(m, g)


def _joint_turn(net, start, final) -> np.ndarray:
    """Largest turn (radians) between two bars at every joint from ``start`` to ``final`` (2D)."""
    i, j = net.edges[:, 0], net.edges[:, 1]
    if net.dim != 2:
        return np.zeros(net.n_nodes)
    ang = []
    for x in (start, final):
        dx = x[j] - x[i]
        ang.append(np.arctan2(dx[:, 1], dx[:, 0]))
    turn = np.angle(np.exp(1j * (ang[1] - ang[0])))  # each bar's own turn, wrapped
    hi = np.full(net.n_nodes, -np.inf)
    lo = np.full(net.n_nodes, np.inf)
    for ends in (i, j):
        np.maximum.at(hi, ends, turn)
        np.minimum.at(lo, ends, turn)
    return np.where(np.isfinite(hi), np.minimum(hi - lo, 2 * np.pi), 0.0)


def process_geometry(design, spec, problem, final) -> ProcessGeometry:
    """What a process's error model needs of a design besides its bars.

    Parameters
    ----------
    design : fabkit.templates.Design
    spec : fabkit.tolerance.spec.ToleranceSpec
        The process (``"print"``: the joints' turns over the motion; ``"origami"``: the cut
        boundary and the sheets of the flat pattern).
    problem : fabkit.kinematics.Problem
        The motion's problem (its start configuration).
    final : numpy.ndarray or None
        The nominal end configuration, shape (N, d); None: no joint turns.

    Returns
    -------
    ProcessGeometry
    """
    net = design.network
    turn = boundary = None
    if spec.process == "print" and final is not None:
        turn = _joint_turn(net, problem.start, final)
    sheets = None
    origami = spec.origami_settings if spec.process == "origami" else None
    if spec.process == "origami" and origami is None:  # a spec made by hand: the template's
        origami = _template_origami(design)
    if origami is not None:
        assignment = origami.assignment
        if assignment is not None and len(assignment) == net.n_edges:
            cut = net.edges[[a in ("B", "C") for a in assignment]]
            boundary = np.zeros(net.n_nodes, dtype=bool)
            boundary[cut.ravel()] = True
        sheets = _sheets(design, origami)
    return ProcessGeometry(net.nodes, net.edges, net.edge_lengths, turn, boundary, sheets)


def _template_origami(design):
    """The origami settings of the template alone, or None when it has none (or bad ones)."""
    try:
        return origami_settings(design)
    except FabkitError:
        return None


def _sheets(design, settings):
    """The sheets of an origami design, each with its flat pattern (None without one), from
    its origami settings as resolved (the command line's ``--set origami.*`` included)."""
    try:
        model = origami_model(design, settings)
    except FabricationError:
        return None
    lookup = {(min(i, j), max(i, j)) for i, j in design.network.edges.tolist()}
    out = []
    for sh in model.sheets:
        cp = sh.pattern
        nodes = np.asarray(sh.nodes, dtype=np.int64)
        edges = np.asarray(cp.edges, dtype=np.int64)
        if nodes.max() >= design.network.n_nodes or any(
                (min(nodes[i], nodes[j]), max(nodes[i], nodes[j])) not in lookup
                for i, j in edges.tolist()):
            return None
        boundary = np.zeros(nodes.size, dtype=bool)
        for (i, j), a in zip(edges.tolist(), cp.assignment):
            if a in ("B", "C"):
                boundary[[i, j]] = True
        creases = []
        for (i, j), a in zip(edges.tolist(), cp.assignment):
            if a not in ("M", "V", "F", "U"):
                continue
            third = []
            for face in cp.faces:
                f = list(face)
                for t in range(len(f)):  # the face's edge (i, j) in its own (ccw) direction
                    u, v = f[t], f[(t + 1) % len(f)]
                    if {u, v} == {i, j}:
                        third.append((u, v, [w for w in f if w not in (u, v)][0]))
            if len(third) == 2:
                (u, v, k), (_, _, l_) = third
                creases.append([u, v, k, l_])
        out.append(Sheet(nodes, np.asarray(cp.vertices, dtype=np.float64), edges, boundary,
                         np.asarray(creases, dtype=np.int64).reshape(-1, 4)))
    return tuple(out)


@dataclass
class Driven:
    """Builds driven along a sequence of drive values until each locks.

    Attributes
    ----------
    stop : numpy.ndarray, shape (M,)
        Drive value where each build ends: the last value, or where it locks (a turning point).
    final : numpy.ndarray, shape (M, N, d)
        Each build there.
    ports : numpy.ndarray, shape (M, P)
        Its port distances there (design units).
    sampled : numpy.ndarray, shape (M, V, P)
        Port distances at every drive value (NaN from where the build has locked).
    closed : numpy.ndarray of bool, shape (M,)
        The bars the construction does not use (states of self-stress) close within the
        clearance at the end.
    """

    stop: np.ndarray
    final: np.ndarray
    ports: np.ndarray
    sampled: np.ndarray
    closed: np.ndarray


class Driver:
    """Drives many builds of one design along its drive in one vectorised placement.

    Parameters
    ----------
    plan : ConstructionPlan
        Of the design's working network (held ports are virtual bars).
    problem : Problem
    net : Network
    pairs : numpy.ndarray of int, shape (P, 2)
        Port node pairs measured.
    geo : ProcessGeometry
    process : str
        What a state takes off the bars (:func:`~fabkit.tolerance.processes.state_profile`:
        a print's bent hinges, a folded sheet) is read off the nominal motion at the same drive
        value.
    valid : (float, float)
        Drive values between which the nominal motion exists (beyond, its ends are used).
    """

    def __init__(self, plan, problem, net, pairs, geo, process: str, valid):
        self.plan, self.problem, self.net, self.pairs = plan, problem, net, pairs
        self.eidx = plan.edge_index(problem.work)
        self.mask = self.eidx >= 0
        used = np.zeros(problem.work.n_edges, dtype=bool)
        used[self.eidx[self.mask]] = True
        self.unused = np.flatnonzero(~used[:net.n_edges])
        self.virtual = problem.work.edge_lengths[net.n_edges:]
        self.geo, self.process = geo, process
        self.bending = process in ("print", "origami")
        self.valid = (min(valid), max(valid))
        self.table = self._table() if self.bending else None

    def _table(self):
        """The state profile along the nominal motion, tabulated (None: none)."""
        grid = np.linspace(self.valid[0], self.valid[1], PROFILE_SAMPLES)
        x, margin, _ = place(self.plan, grid)
        ok = np.flatnonzero(margin >= 0)
        if ok.size == 0:
            return None
        x = x[ok[np.argmin(np.abs(grid[:, None] - grid[ok][None]), axis=1)]]
        out = state_profile(self.geo, self.process, x, np.arange(self.net.n_nodes),
                            np.arange(self.net.n_edges))
        return None if out is None else (grid, out)

    def shortening(self, values) -> np.ndarray | None:
        """:func:`state_profile` of every bar in the nominal state at each drive value,
        (..., E), interpolated along the nominal motion; None when lengths do not depend on
        the state."""
        if self.table is None:
            return None

        grid, table = self.table
        v = np.asarray(values, dtype=np.float64)
        return interp_rows(v.ravel(), grid, table).reshape(v.shape + (-1,))

    def radii(self, lengths) -> np.ndarray:
        """Radii of the plan's intersections from bar lengths (..., E) -> (..., K, dim)."""
        lengths = np.asarray(lengths)
        virtual = np.broadcast_to(self.virtual, lengths.shape[:-1] + self.virtual.shape)
        work = np.concatenate([lengths, virtual], axis=-1)
        return np.where(self.mask, work[..., np.maximum(self.eidx, 0)], 0.0)

    def drive(self, builds, values, clearance_units: float) -> Driven:
        """Drive every build along ``values`` (from the start); a build that locks stops there.

        Parameters
        ----------
        builds : BuildLengths
        values : numpy.ndarray, shape (V,) or (M, V)
            The same for every build, or each build its own.
        clearance_units : float
            How far a redundant bar may be from its length at the end and still close.

        Returns
        -------
        Driven
        """
        m = builds.base.shape[0]
        values = np.broadcast_to(np.asarray(values, dtype=np.float64), (m, np.shape(values)[-1]))
        v = values.shape[1]
        short = self.shortening(values if self.bending and np.ptp(values, axis=0).any()
                                else values[0])
        lengths = builds.base[:, None, :] if short is None else builds.over(short)
        radii = self.radii(np.broadcast_to(lengths, (m, v, builds.base.shape[1])))
        x, margin, _ = place(self.plan, values.ravel(),
                             radii=radii.reshape((m * v,) + self.eidx.shape))
        x = x.reshape((m, v) + x.shape[1:])
        margin = margin.reshape(m, v)
        bad = margin < 0
        bad[:, 0] = False
        fails = bad.any(axis=1)
        first = np.where(fails, np.argmax(bad, axis=1), v)
        sampled = np.linalg.norm(x[:, :, self.pairs[:, 0]] - x[:, :, self.pairs[:, 1]], axis=-1)
        sampled[np.arange(v)[None, :] >= first[:, None]] = np.nan
        final = x[:, -1].copy()
        stop = values[:, -1].copy()
        if fails.any():
            f = np.flatnonzero(fails)
            lo, hi = values[f, first[f] - 1], values[f, first[f]]
            rows = builds.select(f)
            for _ in range(LOCK_BISECTIONS):  # where each failing build locks
                mid = 0.5 * (lo + hi)
                s = self.shortening(mid)
                r = self.radii(rows.at(s))
                _, mm, _ = place(self.plan, mid, radii=r)
                ok = mm >= 0
                lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
            r = self.radii(rows.at(self.shortening(lo)))
            final[f] = place(self.plan, lo, radii=r)[0]
            stop[f] = lo
        ports = np.linalg.norm(final[:, self.pairs[:, 0]] - final[:, self.pairs[:, 1]], axis=-1)
        closed = np.ones(m, dtype=bool)
        if self.unused.size:
            i, j = self.net.edges[self.unused, 0], self.net.edges[self.unused, 1]
            got = np.linalg.norm(final[:, i] - final[:, j], axis=-1)
            end_lengths = builds.at(self.shortening(stop))[:, self.unused] if self.bending \
                else builds.base[:, self.unused]
            if builds.room is None:
                closed = np.abs(got - end_lengths).max(axis=1) <= clearance_units + EDGE_RTOL
            else:
                # the bars the construction left out miss their lengths by ``gap``; the play of
                # every bar of the loops they close takes that up (first order)
                gap = np.zeros_like(builds.base)
                gap[:, self.unused] = got - end_lengths
                w = self_stress_basis(self.net, place(self.plan, [self.valid[1]])[0][0])
                closed = play_ratio(w, gap, builds.room) <= 1.0 + EDGE_RTOL
        return Driven(stop, final, ports, sampled, closed)
