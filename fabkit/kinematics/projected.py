"""Pseudo-arclength continuation on the constraint set, with sparse factorisations.

The configuration x (d·N coordinates) satisfies ``F(x) = 0``: one equation
``(|x_i - x_j|² - L²) / 2`` per edge and one gauge row per fixed coordinate (an edge, or in 3D a
triangle, is held still). With one conformational motion the Jacobian ``J = [R; G]`` has a
one-dimensional null space, the tangent t. It is found from the square sparse system
``A = [J; e_j]`` with ``A t = e_last``, where j is the largest component of the previous tangent
(a local parametrisation, as in PITCON). The factorisation is banded LAPACK (``gbtrf``) when
the network, its coordinates ordered node by node along a reverse Cuthill-McKee ordering and its
rows by where their entries lie, fits a band of at most :data:`~.bordered.BAND_LIMIT` diagonals (chains, strips:
O(N) with a small constant, several times cheaper than a general sparse LU), and SuperLU
otherwise (2D lattices: about O(N^1.5)). The orderings are computed once per trace; only the last
row moves. No Python-level loop runs over nodes or edges.

Each step: Euler predictor ``x + h t`` (plus a curvature term from the last two tangents);
one factorisation of A at the predicted point, reused by every chord-Newton iteration of the
corrector (the row e_j keeps x_j at its predicted value), by the new tangent and by the branch
test, so a step costs one factorisation and a few solves. The new tangent and the corrector's
first update are one solve with two right-hand sides, and a tangent that turns by more than 30°
refuses the step before the corrector runs. The step is rejected and halved when the tangent
turns too far or the corrector contracts worse than a ratio of 0.4 or fails to converge; after
easy steps h grows. Along the way:

- target: when the drive crosses the target, a final Newton solve replaces e_j by the drive
  equation, so the trace ends exactly on the target value;
- turning points of the drive: a sign change of ``∇drive · t``; located by a secant search and
  reported (the trace stops there, it never reverses the drive silently). The step's tangent
  comes from the factors at the predicted point; where the drive barely moves (1e-12 above the
  super-stable chain's collapsed fixed point its rate is 1e-7 of the motion) that tangent can
  flip the sign on its own, so a sign change is confirmed by the exact tangent at the new
  point before the trace stops;
- branch points: a sign change of ``τ = sign(det A) · sign(t_j)`` (the AUTO/MATCONT test function
  ``det [J; tᵀ]``), with det A's sign read off the LU factors; located by bisection and reported.

The gauge held by the rows G starts as the caller's and moves to the part of the network that
moves least when that is a clear gain (:meth:`Projected._follow_quiet_gauge`): a long chain whose
far end only turns rigidly about a collapse front otherwise carries that rotation in every
tangent, and its steps and rejections grew with the chain. The configurations are returned in
the caller's gauge frame. The loop runs with one BLAS thread (banded solves and vector
operations on one trace, where threads only contend).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import KinematicsError
from ..model.rigidity import count_modes
from ..numerics import START_RTOL
from .base import choose_gauge
from .bordered import BorderedSystem, gauge_rows, permutation_parity
from .stepping import Step, StepMethod, Stop
from ..status import Status
from ..numerics import one_blas_thread
from .trajectory import EventKind

__all__ = ["Projected", "gauge_rows", "permutation_parity", "singular_start_threshold"]


def singular_start_threshold(rows: int) -> float:
    """The smallest singular value below which a start of a bordered system of ``rows`` rows
    is singular: :data:`SINGULAR_START` up to :data:`SINGULAR_START_ROWS` rows, then falling as
    the square of the size (a long chain's regular start is that much worse conditioned), never
    below :data:`SINGULAR_START_FLOOR`.

    Examples
    --------
    >>> [f"{singular_start_threshold(n):.0e}" for n in (100, 40_000, 400_000, 4_000_000)]
    ['1e-09', '1e-09', '1e-11', '1e-13']
    """
    scale = min(1.0, SINGULAR_START_ROWS / max(int(rows), 1)) ** 2
    return max(SINGULAR_START * scale, SINGULAR_START_FLOOR)

#: Smallest step by default, relative to the median edge: a step this small that still fails
#: means a singular configuration ahead, not a step too large.
MIN_STEP_RTOL = 1e-10
#: A start whose bordered matrix [J; e_j] has a smallest singular value below this (row-scaled
#: system) is singular: a state of self-stress there (up to SINGULAR_START_ROWS rows; see
#: :func:`singular_start_threshold`).
SINGULAR_START = 1e-9
#: Rows of the bordered system up to which SINGULAR_START holds as it is. A larger network's
#: regular starts are worse conditioned: a chain of k modules has σ_min ≈ 3.5/k² (measured: 4-bar
#: chains, 3.3e-4 at 100 modules, 3.5e-8 at 10⁴, 3.5e-10 at 10⁵; a lattice of n nodes falls as
#: 1/n), so beyond it the threshold falls as the square of the rows.
SINGULAR_START_ROWS = 40_000
#: The threshold never falls below this: an exactly singular start (a flat sheet, a bifurcation)
#: keeps σ_min at round-off, ~1e-16 of the row-scaled matrix, and a regular 10⁶-module chain
#: has 3.5e-12.
SINGULAR_START_FLOOR = 1e-13
#: |∇drive · t| below this at the start: the drive is stationary (a turning point).
STATIONARY_DRIVE = 1e-12
#: The secant search for a turning point stops when its bracket is this small (relative to the
#: step or the network) or the drive's rate this close to zero.
TURN_BRACKET_RTOL = 1e-13
TURN_RATE_ZERO = 1e-13
#: The bisection for a branch point stops when its bracket is this small (relative to the network).
BRANCH_BRACKET_RTOL = 1e-12


#: The gauge moves to the stillest rigid element when holding the current one makes the
#: tangent this many times longer (see :meth:`Projected._follow_quiet_gauge`): a clear gain
#: only, so that networks whose motion is spread out keep the gauge near the drive.
GAUGE_SWITCH = 3.0

#: Accepted steps between two looks for a stiller gauge (a look costs a few vector operations
#: on the whole network, about a fifth of a step; a collapse front passes a module in about two
#: steps, so a gauge that starts to move is left within a few modules).
GAUGE_CHECK_EVERY = 8

class Projected(StepMethod):
    """Pseudo-arclength predictor-corrector (see the module docstring).

    Options
    -------
    step : float
        First step in arclength (default 0.1 × median edge length).
    max_step : float
        Largest step (default unlimited); lower it for finer output.
    max_node_step : float
        Largest distance any one node moves in a step, to first order (default unlimited): finer
        output where a few nodes move fast and coarse elsewhere (a collision check's samples),
        where ``max_step`` would refine the whole path as much as its fastest part needs.
    min_step : float
        Smallest step before giving up (default 1e-10 × median edge length).
    tol : float
        Newton tolerance on the relative edge-length residual (default 1e-14).
    max_steps : int
        Largest number of accepted steps (default 20000).
    contraction : float
        Largest accepted contraction ratio of the chord-Newton corrector (default 0.4).
    max_angle : float
        Largest turn of the tangent in one step, degrees (default 30).
    detect_branch_points : bool
        Watch the sign of det [J; tᵀ] (default True).
    redundant_rtol : float
        How far (relative) a bar left out of the square system as redundant at the start (a
        state of self-stress) may stray from its length before the trace stops there (default
        1e-9: a rigid bar). A build with joint play traces with its play here (its loops close
        within the play as they change along the motion).
    until : callable or None
        ``until(x) -> bool``, asked after every accepted step with the configuration x (shape
        (N, d)); the trace ends there, status ``failed`` (the message says why), at the first one it holds
        for (default None: never). x is in the tracer's frame, a rigid motion away from the
        caller's gauge when the tracer holds another part still: ask it about lengths and
        distances only.
    """

    name = "projected"
    aligned = True  # the gauge rows hold the gauge coordinates at their start values
    options = {
        "step": None,
        "max_step": None,
        "max_node_step": None,
        "min_step": None,
        "tol": 1e-14,
        "max_steps": 20000,
        "contraction": 0.4,
        "max_angle": 30.0,
        "detect_branch_points": True,
        "redundant_rtol": 1e-9,
        "until": None,
    }

    def solve(self):
        # banded solves and vector operations on one trace: BLAS threads only contend (a
        # 3000-module chain took 3.5 s with them on a busy two-core machine, 1.1 s without)
        with one_blas_thread():
            return super().solve()

    # -- set-up ---------------------------------------------------------------------------------
    def _setup(self):
        p = self.problem
        work = p.work
        x0 = p.start
        n, d = x0.shape
        self.n, self.d = n, d
        self.gauge = tuple(p.gauge)
        gcols = gauge_rows(x0, p.gauge)
        rest2 = work.edge_lengths ** 2
        e = work.n_edges
        rows_keep = None
        if e + gcols.size + 1 != d * n:
            rows_keep = self._independent_rows(work, x0, gcols)
        self.sys = BorderedSystem(work.edges, rest2, n, d, gcols, x0.ravel()[gcols], rows_keep)
        # Edges left out of the square system because they were redundant at the start (a state
        # of self-stress) are still watched: if the self-stress does not persist along the
        # motion, they would break silently.
        dropped = np.setdiff1d(np.arange(e), rows_keep) if rows_keep is not None else np.zeros(0, int)
        self.dropped = dropped
        self.dropped_edges = work.edges[dropped]
        self.dropped_rest2 = rest2[dropped]
        self.scale = float(np.median(work.edge_lengths))
        self.min_length = float(np.min(work.edge_lengths))
        self.all_edges_rest2 = rest2

    def _independent_rows(self, work, x0, gcols):
        """Edges whose rows of the rigidity matrix are independent at the start, dN - g - 1 of
        them (a windowed selection along the band, see
        :func:`fabkit.model.independent_edges.independent_edges`), for a network with states of
        self-stress and one conformational motion."""
        from ..model.independent_edges import independent_edges

        m = count_modes(work, x0)
        if m.conformational != 1:
            raise KinematicsError(
                f"the network has {m.conformational} conformational motions at the start ({m}); "
                "trace follows one motion: add edges, or hold ports with hold=[...]"
            )
        n, d = x0.shape
        return independent_edges(work, x0, rank=d * n - gcols.size - 1)

    def _tangent(self, xf, j, orient_like=None, direction_grad=None):
        """Factor A(x, e_j) and solve for the unit tangent; returns (t, lu, tau) or None."""
        lu = self.sys.factorize(xf, np.array([j]), np.array([1.0]))
        self.n_factor += 1
        if lu is None:
            return None
        # orient along orient_like, or (at the start) along the drive's gradient
        res = self._tangent_from(lu, j, orient_like if orient_like is not None else direction_grad)
        if res is None:
            return None
        return res[0], lu, res[1]

    def _walk_to_target(self, x, t, h):
        """Land on drive values approaching the target geometrically from x (each Newton solve
        starting from the last); the final configuration, or None if the walk fails or turns."""
        direction = self.direction()
        target = self.problem.target
        d0 = self._drive(x)
        y = x
        for k in list(range(1, 9)) + [None]:
            value = target if k is None else target + (d0 - target) * 0.3 ** k
            landed = self._land(y, value)
            if landed is None or np.linalg.norm(landed - y) > 2 * h:
                return None
            tl = self._tangent(landed, int(np.argmax(np.abs(t))), orient_like=t)
            if tl is None or self._broken_dropped(landed) is not None:
                return None
            if float(self._drive_grad(landed) @ tl[0]) * direction < 0:
                return None  # beyond the turning point: the mirror-image configuration
            y, t = landed, tl[0]
        return y

    def _land(self, guess, value=None):
        """Newton onto the configuration near ``guess`` whose drive equals the target."""
        a, b = self.problem.drive
        target = self.problem.target if value is None else value

        def res(xx):
            y = xx.reshape(self.n, self.d)
            return 0.5 * (float(np.sum((y[a] - y[b]) ** 2)) - target ** 2)

        def grad(xx):
            return self._drive_grad(xx) * self._drive(xx)

        return self._newton_on(guess, grad, res)

    def _tangent_from(self, lu, j, orient_like, raw=None):
        """Unit tangent and branch test τ from existing factors of A = [J; e_j]; ``raw`` is
        ``A⁻¹ e_last`` when already solved for."""
        if raw is None:
            rhs = np.zeros(self.sys.n_rows)
            rhs[-1] = 1.0
            raw = lu.solve(rhs)
        t = raw
        if not np.isfinite(t).all():
            return None
        t /= np.linalg.norm(t)
        if t @ orient_like < 0:
            t = -t
        tau = self.sys.det_sign(lu) * int(np.sign(t[j])) if self.opts["detect_branch_points"] else 1
        return t, tau

    def _drive_grad(self, xf):
        a, b = self.problem.drive
        x = xf.reshape(self.n, self.d)
        u = x[a] - x[b]
        u = u / np.linalg.norm(u)
        g = np.zeros_like(xf)
        g[self.d * a: self.d * a + self.d] = u
        g[self.d * b: self.d * b + self.d] = -u
        return g

    def _drive(self, xf):
        a, b = self.problem.drive
        x = xf.reshape(self.n, self.d)
        return float(np.linalg.norm(x[a] - x[b]))

    def _noise(self, x) -> tuple[float, float]:
        """Round-off floors: of a coordinate update (absolute), and of the relative edge residual.

        Coordinates of size |x| carry an absolute error of eps·|x|, so a long chain far from the
        origin cannot keep edges better than about eps·max|x| / min L; asking for more makes
        Newton chase noise.
        """
        big = float(np.max(np.abs(x)))
        eps = np.finfo(float).eps
        return 16.0 * eps * max(big, self.scale), 4.0 * eps * big / self.min_length

    def _correct(self, xp, lu, j, cj, first=None):
        """Chord Newton from xp with x_j held at cj; returns (x, iterations, theta) or None.

        The residual is evaluated once per iteration and tested before the next solve; the step
        is refused as soon as the iteration contracts worse than ``contraction``. ``first`` is
        (residual r at xp, solution of A y = r) when the caller has already solved for them
        (together with the tangent, see :meth:`_step`).
        """
        dx_floor, res_floor = self._noise(xp)
        tol = max(self.opts["tol"], res_floor)
        kappa = self.opts["contraction"]
        x = xp.copy()
        rhs = np.empty(self.sys.n_rows)  # [edge and gauge residuals; x_j - cj]
        r = self.sys.residual(x, out=rhs) if first is None else first[0]
        prev = None
        theta_max = 0.0
        for it in range(0, 16):
            if self.sys.rel_from_residual(r) <= tol:
                return x, it, theta_max
            if it == 0 and first is not None:
                y = first[1]
            else:
                rhs[-1] = x[j] - cj
                y = lu.solve(rhs)
            nrm = float(np.maximum.reduce(np.abs(y)))  # NaN or inf here if the solve failed
            if not math.isfinite(nrm):
                return None
            x -= y  # the update is -y
            r = self.sys.residual(x, out=rhs)
            if nrm <= dx_floor:  # at round-off: converged if the residual agrees
                return (x, it + 1, theta_max) if self.sys.rel_from_residual(r) <= tol else None
            if prev is not None:
                theta = nrm / prev
                theta_max = max(theta_max, theta)
                if theta > kappa:
                    return None
            prev = nrm
        return None

    def _newton_on(self, xg, row_grad_fn, row_res_fn, iterations=20):
        """Full Newton with the last row replaced by a scalar equation (value, gradient).

        Landings next to a collapsed (nearly flat) state converge slowly: 20 iterations let
        them reach the round-off floor instead of stopping at 100 × the tolerance."""
        x = xg.copy()
        dx_floor, res_floor = self._noise(xg)
        tol = max(self.opts["tol"], res_floor)
        for _ in range(iterations):
            g = row_grad_fn(x)
            nz = np.flatnonzero(g)
            lu = self.sys.factorize(x, nz, g[nz])
            self.n_factor += 1
            if lu is None:
                return None
            r = np.concatenate([self.sys.residual(x), [row_res_fn(x)]])
            dx = lu.solve(-r)
            if not np.isfinite(dx).all():
                return None
            x += dx
            if (self.sys.rel_edge_residual(x) <= tol
                    and abs(row_res_fn(x)) <= max(tol * self.scale ** 2, dx_floor * self.scale)):
                return x
        return x if self.sys.rel_edge_residual(x) <= 100 * tol else None

    # -- the stepping contract ------------------------------------------------------------------
    def _start(self, x0: np.ndarray) -> Stop | None:
        p = self.problem
        self.n_factor = 0
        self.counts = {"rejected": 0, "newton_iterations": 0}
        self._setup()
        scale = self.scale
        self.h = self.opts["step"] or 0.1 * scale
        self.h_max = self.opts["max_step"] or math.inf
        self.node_step = self.opts["max_node_step"] or math.inf
        self.h_min = self.opts["min_step"] or MIN_STEP_RTOL * scale
        self.max_cos = math.cos(math.radians(self.opts["max_angle"]))
        direction = self.direction()
        x = x0
        if self.sys.rel_edge_residual(x) > START_RTOL:
            raise KinematicsError("the start configuration does not keep the edge lengths")
        grad = self._drive_grad(x) * direction
        # First tangent from [J; ∇drive] t = e_last (needs no guess of a good row); then switch
        # to the local parametrisation by the tangent's largest component.
        first = None
        nz = np.flatnonzero(grad)
        lu0 = self.sys.factorize(x, nz, grad[nz])
        self.n_factor += 1
        if lu0 is not None:
            rhs = np.zeros(self.sys.n_rows)
            rhs[-1] = 1.0
            t0 = lu0.solve(rhs)
            if np.isfinite(t0).all() and np.linalg.norm(t0) > 0:
                j = int(np.argmax(np.abs(t0)))
                first = self._tangent(x, j, direction_grad=grad)
        if first is None:  # the drive may be stationary: try the coordinates one by one
            for j in np.argsort(-np.abs(grad))[: 4 * self.d]:
                if j in set(self.sys.gcols.tolist()):
                    continue
                first = self._tangent(x, int(j), direction_grad=grad)
                if first is not None:
                    break
        if first is None:
            return Stop(Status.FAILED, self._singular_message("start"))
        t, lu, tau = first
        sig = self.sys.sigma_min(lu, self.sys.n_rows)
        if sig < singular_start_threshold(self.sys.n_rows):
            return Stop(Status.FAILED, self._singular_message("start", sig))
        g_prev = float(self._drive_grad(x) @ t) * direction
        if abs(g_prev) < STATIONARY_DRIVE:
            return Stop(Status.TURNING_POINT,
                        f"the start is a turning point of {p.drive_name}: it cannot move towards "
                        f"{p.target:.10g} to first order",
                        event=EventKind.TURNING_POINT, detail="the drive is stationary at the start")
        f_prev = (self._drive(x) - p.target) * direction  # < 0 until the target is passed
        if f_prev >= 0:
            return Stop(Status.FINISHED, self.finished_message())
        j = int(np.argmax(np.abs(t)))
        # the state one step carries to the next
        self.state = (t, lu, j, tau, f_prev, g_prev)
        self.curvature = None
        self.accepted = 0
        self._follow_quiet_gauge(x, rescale=False)  # the first step is in units of the shape
        return None

    # -- the gauge that moves least -------------------------------------------------------------
    def _rigid_fields(self, x: np.ndarray, centre: np.ndarray) -> np.ndarray:
        """Rigid velocity fields about ``centre``, columns of shape (d·N,): translations and
        rotations."""
        c = x - centre
        n, d = x.shape
        if d == 2:  # filled in place: the same entries as the columns stacked below, at a
            # third of the cost (asked at every step of a trace that holds another part still)
            f = np.zeros((n, 2, 3))
            f[:, 0, 0] = 1.0
            f[:, 1, 1] = 1.0
            f[:, 0, 2] = -c[:, 1]
            f[:, 1, 2] = c[:, 0]
            return f.reshape(2 * n, 3)
        cols = [np.tile(np.eye(d)[a], n) for a in range(d)]
        cols += [np.cross(np.eye(3)[a], c).ravel() for a in range(3)]
        return np.column_stack(cols)

    def _held(self, fields: np.ndarray, t: np.ndarray, gauge) -> np.ndarray:
        """The tangent t as seen with ``gauge`` held still: t minus the rigid motion (columns of
        ``fields``) that the gauge nodes make."""
        g = np.asarray(gauge, dtype=np.int64)
        rows = (self.d * g[:, None] + np.arange(self.d)).ravel()
        beta = np.linalg.lstsq(fields[rows], t[rows], rcond=None)[0]
        return t - fields @ beta

    def _follow_quiet_gauge(self, xf: np.ndarray, rescale: bool = True) -> None:
        """Hold the part of the network that moves least.

        With the gauge near the drive, a part that only turns rigidly (the far end of a long
        chain, swung about the front of a collapse) carries the tangent: its nodes move in
        proportion to their distance, so the path in coordinates grows with the network and a
        linear predictor leaves the far nodes off their arcs (about a third of the steps of the
        mirrored super-stable chain were rejected, and their number grew with N). The tangent
        without rigid motion (least squares) tells where the network is still; when holding
        the current gauge makes the tangent more than ``GAUGE_SWITCH`` times longer than
        holding a rigid element at the stillest node, that element becomes the gauge. The
        configurations are then moved back into the caller's gauge frame (a rigid fit)."""
        t, lu, j, tau, f, g = self.state
        x = xf.reshape(self.n, self.d)
        fields = self._rigid_fields(x, x.mean(axis=0))
        # about the centroid the fields are nearly orthogonal: the normal equations are small
        # and well conditioned
        free = t - fields @ np.linalg.solve(fields.T @ fields, fields.T @ t)
        base = float(np.linalg.norm(free))
        if not base > 0:
            return
        speed = np.einsum("ij,ij->i", free.reshape(self.n, self.d), free.reshape(self.n, self.d))
        quiet = choose_gauge(self.problem.work, x, (int(np.argmin(speed)),) * 2)
        if set(quiet) == set(self.gauge):
            return
        now = float(np.linalg.norm(self._held(fields, t, self.gauge))) / base
        held = self._held(fields, t, quiet)
        then = float(np.linalg.norm(held)) / base
        gcols = gauge_rows(x, quiet)
        if now <= GAUGE_SWITCH * then or gcols.size != self.sys.gcols.size:
            return
        self.sys.regauge(gcols, xf[gcols].copy())
        exact = self._tangent(xf, int(np.argmax(np.abs(held))), orient_like=held)
        if exact is None:
            self.sys.regauge(gauge_rows(x, self.gauge), xf[gauge_rows(x, self.gauge)].copy())
            return
        self.gauge = tuple(quiet)
        self.aligned = False  # the caller's gauge is restored by a rigid fit
        self.counts["gauge_changes"] = self.counts.get("gauge_changes", 0) + 1
        t2, lu2, tau2 = exact
        direction = self.direction()
        self.state = (t2, lu2, int(np.argmax(np.abs(t2))), tau2, f,
                      float(self._drive_grad(xf) @ t2) * direction)
        self.curvature = None
        if rescale:
            self.h *= then / now  # the same progress of the shape per step

    def _step(self) -> Step | Stop:
        p = self.problem
        direction = self.direction()
        target = p.target
        x = self.positions[-1]
        t, lu, j, tau, f_prev, g_prev = self.state
        h_node = self.node_step / self._node_speed(x, t) if self.node_step < math.inf else math.inf
        while True:
            h = self.h = min(self.h, self.h_max, h_node)
            if h < self.h_min:
                return Stop(Status.FAILED,
                            f"the step size fell below {self.h_min:.1e} at {p.drive_name} = "
                            f"{self._drive(x):.10g}: the corrector does not converge (a "
                            "singular configuration ahead?)")
            xp = x + h * t
            if self.curvature is not None:
                xp += (0.5 * h * h) * self.curvature  # second-order predictor
            # Newton on the Jacobian at the predicted point: contracts far better than reusing
            # the previous point's LU, and the same factors then give the new tangent and det sign.
            lu_p = self.sys.factorize(xp, np.array([j]), np.array([1.0]))
            self.n_factor += 1
            if lu_p is None:
                self._reject()
                continue
            # the new tangent and the corrector's first update in one pass over the factors
            # (A t = e_last, A y = F(xp): x_j - xp[j] = 0 in the last row); a step that turns
            # the tangent too far is refused before the corrector runs
            both = np.zeros((2, self.sys.n_rows))
            both[0, -1] = 1.0
            r0 = self.sys.residual(xp, out=both[1])
            t_raw, y0 = lu_p.solve(both)
            nxt = self._tangent_from(lu_p, j, t, raw=t_raw)
            if nxt is None or float(nxt[0] @ t) < self.max_cos:
                self._reject()
                continue
            corr = self._correct(xp, lu_p, j, xp[j], first=(r0, y0))
            if corr is None:
                self._reject()
                continue
            x_new, its, theta = corr
            self.counts["newton_iterations"] += its
            t_new, tau_new = nxt
            j_new = int(np.argmax(np.abs(t_new)))
            f_new = (self._drive(x_new) - target) * direction
            g_new = float(self._drive_grad(x_new) @ t_new) * direction
            if f_new >= 0:  # the target lies in this step: land on it exactly
                frac = -f_prev / (f_new - f_prev) if f_new != f_prev else 1.0
                landed = self._land(x + frac * (x_new - x))
                if landed is not None and self._broken_dropped(landed) is not None:
                    return self._stop_locked(landed, x)
                if landed is not None and (g_new > 0 or g_prev > 0):
                    return Stop(Status.FINISHED, self.finished_message(), append=(landed,))
                if landed is None:
                    self._reject()
                    continue
            if tau_new != tau and self.opts["detect_branch_points"]:
                return self._stop_at_branch(x, t, lu, j, h, tau, g_prev * g_new < 0)
            if g_new * g_prev < 0 or g_new <= 0 and g_prev > 0:
                # t_new is the tangent at the predicted point: confirm the turn at x_new itself
                exact = self._tangent(x_new, j_new, orient_like=t_new)
                if exact is not None:
                    ge = float(self._drive_grad(x_new) @ exact[0]) * direction
                    if ge > 0 and g_prev > 0:
                        t_new, lu_p, tau_new, g_new = exact[0], exact[1], exact[2], ge
            if g_new * g_prev < 0 or g_new <= 0 and g_prev > 0:
                # the target may lie between x and the turning point, too close to the turn for
                # the step to have crossed it on this side: walk the drive towards it by landing
                landed = self._walk_to_target(x, t, h)
                if landed is not None:
                    return Stop(Status.FINISHED, self.finished_message(), append=(landed,))
                return self._stop_at_turning(x, t, lu, j, h, g_prev)
            if self._broken_dropped(x_new) is not None:
                return self._stop_locked(x_new, x)
            step = float(np.linalg.norm(x_new - x))
            self.curvature = (t_new - t) / step if step > 0 else None
            self.state = (t_new, lu_p, j_new, tau_new, f_new, g_new)
            # with the Jacobian at the predicted point the contraction grows like h²: aim at 0.1
            self.h *= min(2.0, max(0.7, math.sqrt(0.1 / max(theta, 0.025))))
            self.accepted += 1
            if self.accepted % GAUGE_CHECK_EVERY == 0:
                self._follow_quiet_gauge(x_new)
            return Step(x_new)

    def _node_speed(self, xf: np.ndarray, t: np.ndarray) -> float:
        """Largest node speed along the unit tangent t, as the caller sees it: in the caller's
        gauge, which the output is refitted to when the tracer holds another part still."""
        if set(self.gauge) != set(self.problem.gauge):
            x = xf.reshape(self.n, self.d)
            t = self._held(self._rigid_fields(x, x.mean(axis=0)), t, self.problem.gauge)
        v = t.reshape(self.n, self.d)
        speed = math.sqrt(float(np.max(np.einsum("ij,ij->i", v, v))))
        return speed if speed > 0 else math.inf

    def _reject(self):
        """A refused step: halve it and count it."""
        self.counts["rejected"] += 1
        self.h *= 0.5

    def _stats(self) -> dict:
        return {**self.counts, "factorizations": self.n_factor}

    def _stop_locked(self, x_bad, x_last) -> Stop:
        """The trace ends at ``x_last``: beyond it a redundant edge would break."""
        return Stop(Status.FAILED, self._locked_message(x_bad, x_last),
                    event=EventKind.SELF_STRESS_LOST,
                    detail="a state of self-stress vanishes: the network locks here")

    def _locked_message(self, x_bad, x_last) -> str:
        k, err = self._broken_dropped(x_bad)
        i0, i1 = (int(v) for v in self.dropped_edges[k])
        p = self.problem
        return (f"edge ({i0}, {i1}), redundant at the start (a state of self-stress), would break "
                f"by {err:.1e} (relative) beyond {p.drive_name} = {self._drive(x_last):.10g}: the "
                "self-stress does not persist there, so the network cannot follow this drive")

    def _broken_dropped(self, xf, limit: float | None = None):
        """(index, relative error) of the worst dropped edge beyond ``limit`` (the
        ``redundant_rtol`` option), else None."""
        if self.dropped.size == 0:
            return None
        limit = self.opts["redundant_rtol"] if limit is None else limit
        x = xf.reshape(self.n, self.d)
        diff = x[self.dropped_edges[:, 0]] - x[self.dropped_edges[:, 1]]
        rel = np.abs(np.sqrt(np.einsum("ij,ij->i", diff, diff) / self.dropped_rest2) - 1.0)
        k = int(np.argmax(rel))
        return (k, float(rel[k])) if rel[k] > limit else None

    # -- events ---------------------------------------------------------------------------------
    def _point_at(self, x, t, lu, j, hh):
        """The curve point at arclength ~hh from x along t, with its exact tangent and branch
        test; None where Newton fails.

        Chord Newton on ``lu`` (the factors at x, a regular point) first: next to a branch point a
        Jacobian taken there keeps the corrector on the branch it came from; the Jacobian at the
        predicted point is the fallback.
        """
        xp = x + hh * t
        corr = self._correct(xp, lu, j, xp[j])
        if corr is None:
            lu_p = self.sys.factorize(xp, np.array([j]), np.array([1.0]))
            self.n_factor += 1
            corr = None if lu_p is None else self._correct(xp, lu_p, j, xp[j])
        if corr is None:
            return None
        xn = corr[0]
        nxt = self._tangent(xn, int(np.argmax(np.abs(t))), orient_like=t)
        if nxt is None:
            return xn, None, None
        return xn, nxt[0], nxt[2]

    def _stop_at_turning(self, x, t, lu, j, h, g0) -> Stop:
        """Secant search for ∇drive·t = 0 within the step, then stop there."""
        p = self.problem
        direction = self.direction()
        exact = self._tangent(x, int(np.argmax(np.abs(t))), orient_like=t)
        if exact is not None:
            t, lu = exact[0], exact[1]
            j = int(np.argmax(np.abs(t)))
            g0 = float(self._drive_grad(x) @ t) * direction
        lo, glo, hi, ghi = 0.0, g0, h, None
        best = None
        for _ in range(40):
            # secant on the drive's rate; halving where it cannot (no bracket yet, or equal
            # rates at both ends)
            mid = 0.5 * (lo + hi) if ghi is None or ghi == glo else \
                lo + (hi - lo) * glo / (glo - ghi)
            if not lo < mid < hi:
                mid = 0.5 * (lo + hi)
            pt = self._point_at(x, t, lu, j, mid)
            if pt is None or pt[1] is None:
                hi = mid
                continue
            xm, tm, _ = pt
            gm = float(self._drive_grad(xm) @ tm) * direction
            best = xm
            if gm > 0:
                lo, glo = mid, gm
            else:
                hi, ghi = mid, gm
            if hi - lo <= TURN_BRACKET_RTOL * max(h, self.scale) or abs(gm) < TURN_RATE_ZERO:
                break
        dval = self._drive(x if best is None else best)
        kind = "largest" if direction > 0 else "smallest"
        detail = (f"{p.drive_name} reaches its {kind} value {dval:.10g} on this branch; beyond it "
                  "the motion continues with the drive moving back")
        return Stop(Status.TURNING_POINT,
                    f"stopped at a turning point of {p.drive_name} = {dval:.10g} before the "
                    f"target {p.target:.10g}: {detail}",
                    append=() if best is None else (best,), event=EventKind.TURNING_POINT,
                    detail=detail)

    def _stop_at_branch(self, x, t, lu, j, h, tau0, also_turning) -> Stop:
        """Bisection on the sign of det [J; tᵀ] within the step; stop just before the branch."""
        p = self.problem
        exact = self._tangent(x, int(np.argmax(np.abs(t))), orient_like=t)
        if exact is not None:  # the test function at x itself (the step's one was off the curve)
            tau0, lu, j = exact[2], exact[1], int(np.argmax(np.abs(t)))
        lo, hi = 0.0, h
        best = None
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            pt = self._point_at(x, t, lu, j, mid)
            if pt is None or pt[1] is None:
                hi = mid
                continue
            xm, _, taum = pt
            if taum == tau0:
                lo, best = mid, xm
            else:
                hi = mid
            if hi - lo <= BRANCH_BRACKET_RTOL * self.scale:
                break
        xb = x if best is None else best
        dval = self._drive(xb)
        sig = None
        nxt = self._tangent(xb, int(np.argmax(np.abs(t))), orient_like=t)
        if nxt is not None:
            sig = self.sys.sigma_min(nxt[1], self.sys.n_rows)
        extra = " (the drive also turns back there)" if also_turning else ""
        detail = (f"det [J; t] changes sign at {p.drive_name} ≈ {dval:.10g}: the rigidity matrix "
                  f"drops rank (a state of self-stress), where other branches of motion meet"
                  f"{extra}")
        if sig is not None:
            detail += f"; smallest singular value of the bordered matrix {sig:.1e}"
        return Stop(Status.BRANCH_POINT,
                    f"stopped at a branch point at {p.drive_name} ≈ {dval:.10g} before the "
                    f"target {p.target:.10g}: {detail}",
                    append=() if best is None else (best,), event=EventKind.BRANCH_POINT,
                    detail=detail)

    def _singular_message(self, where, sig=None):
        s = f" (smallest singular value {sig:.1e})" if sig is not None else ""
        return (f"the {where} configuration is singular{s}: the rigidity matrix has a state of "
                f"self-stress there, so the motion may branch or there may be several motions; "
                f"hold a port (hold=[...]) or start off the singular state")
