"""The paper's reference method: RK4 on the conformational velocity from a dense null space.

Supplement "Numerical Form of the Iterated Map": at each evaluation the null space W of the
rigidity matrix is computed by a dense SVD, the rigid-body motions S are projected out
(``c = null(Sᵀ W)``), and the unit conformational velocity ``W c`` is integrated with classical
fourth-order Runge-Kutta at a fixed step. There is no correction, so edge lengths drift; the cost
per evaluation grows as about N^2.8. Kept as the baseline the other methods are measured against.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import KinematicsError
from ..model.rigidity import rigid_body_basis, rigidity_matrix
from .stepping import Step, StepMethod, Stop
from ..status import Status
from .trajectory import EventKind

__all__ = ["RK4Nullspace", "conformational_velocity"]

#: Default step in arclength, relative to the median edge (the paper's fixed step).
DEFAULT_STEP = 0.01
#: The landing on the target stops when the drive is this close (relative to the median edge).
LANDING_RTOL = 1e-15
#: Singular values of the null space's rigid components above this count as rigid motions.
RIGID_PART = 1e-8


def conformational_velocity(net, xf: np.ndarray, rtol: float = 1e-9):
    """Unit conformational velocity at a configuration, and the number of such motions.

    Returns
    -------
    v : numpy.ndarray, shape (d·N,) or None
        None when the count of conformational motions is not one.
    count : int
    """
    n, d = net.n_nodes, net.dim
    x = xf.reshape(n, d)
    r = rigidity_matrix(net, x).toarray()
    import scipy.linalg  # here, not at the top: the command line starts without scipy

    _, s, vt = scipy.linalg.svd(r, full_matrices=True)
    tol = rtol * max(s[0] if s.size else 0.0, 1.0) * float(np.median(net.edge_lengths))
    rank = int((s > tol).sum())
    w = vt[rank:].T  # orthonormal null space of R
    rigid = rigid_body_basis(x)
    coeff = rigid.T @ w  # rigid motions expressed in the null-space basis
    _, cs, cvt = np.linalg.svd(coeff, full_matrices=True)
    crank = int((cs > RIGID_PART).sum())
    c = cvt[crank:].T
    count = c.shape[1]
    if count != 1:
        return None, count
    v = (w @ c)[:, 0]
    return v / np.linalg.norm(v), count


class RK4Nullspace(StepMethod):
    """Fixed-step RK4 on the dense null-space velocity (the paper's method).

    Options
    -------
    step : float
        Step in arclength (default 0.01 × median edge length).
    max_steps : int
        Largest number of steps (default 100000).
    """

    name = "rk4-nullspace"
    options = {"step": None, "max_steps": 100000}

    def _start(self, x0: np.ndarray) -> Stop | None:
        p = self.problem
        self.net = p.work
        self.scale = float(np.median(self.net.edge_lengths))
        self.h = float(self.opts["step"] or DEFAULT_STEP * self.scale)
        if self.h <= 0 or not math.isfinite(self.h):
            raise KinematicsError(f"`step` must be positive, got {self.h}")
        self.evaluations = 0
        v0, count = conformational_velocity(self.net, x0)
        if v0 is None:
            return self._not_unique(x0, count)
        direction = self.direction()
        if self._drive_grad(x0) @ v0 * direction < 0:
            v0 = -v0
        self.like = v0
        self.g_prev = float(self._drive_grad(x0) @ v0) * direction
        return None

    def _step(self) -> Step | Stop:
        p = self.problem
        direction = self.direction()
        x, h = self.positions[-1], self.h
        f_old = (self._drive(x) - p.target) * direction
        stage = self._rk4(x, h, self.like)
        if isinstance(stage, Stop):
            return stage
        x_new, k4 = stage
        f_new = (self._drive(x_new) - p.target) * direction
        if f_new >= 0:
            # shorten the last step so that it ends on the target (a few secant passes)
            hh = h * (-f_old) / (f_new - f_old)
            for _ in range(3):
                stage = self._rk4(x, hh, self.like)
                if isinstance(stage, Stop):
                    return stage
                xe, k4 = stage
                fe = (self._drive(xe) - p.target) * direction
                slope = float(self._drive_grad(xe) @ k4) * direction
                if abs(fe) < LANDING_RTOL * self.scale or slope <= 0:
                    break
                hh -= fe / slope
            return Stop(Status.FINISHED, self.finished_message(), append=(xe,))
        v_here = self._field(x_new, k4)
        if v_here is None:
            return self._not_unique(x_new, self._count)
        g_new = float(self._drive_grad(x_new) @ v_here) * direction
        if g_new <= 0 < self.g_prev:
            dval = self._drive(x_new)
            detail = f"{p.drive_name} stops moving towards the target near {dval:.10g}"
            return Stop(Status.TURNING_POINT,
                        f"stopped at a turning point of {p.drive_name} ≈ {dval:.10g}: {detail}",
                        append=(x_new,), event=EventKind.TURNING_POINT, detail=detail)
        self.like, self.g_prev = v_here, g_new
        return Step(x_new)

    def _stats(self) -> dict:
        return {"evaluations": self.evaluations}

    # -- the velocity field ----------------------------------------------------------------------
    def _field(self, xf, like):
        """The unit conformational velocity oriented along ``like``; None where it is not unique
        (the count of motions is left in ``self._count``)."""
        self.evaluations += 1
        v, self._count = conformational_velocity(self.net, xf)
        if v is None:
            return None
        return v if v @ like >= 0 else -v

    def _rk4(self, x, h, like):
        """One classical RK4 step: (x_new, k4), or the Stop where the velocity is not unique."""
        k1 = self._field(x, like)
        k2 = None if k1 is None else self._field(x + 0.5 * h * k1, k1)
        k3 = None if k2 is None else self._field(x + 0.5 * h * k2, k1)
        k4 = None if k3 is None else self._field(x + h * k3, k1)
        if k4 is None:
            return self._not_unique(x, self._count)
        return x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4), k4

    def _not_unique(self, x, count) -> Stop:
        return Stop(Status.FAILED,
                    f"the network has {count} conformational motions at {self.problem.drive_name} "
                    f"= {self._drive(x):.10g}; the null-space velocity is not unique")

    def _drive(self, xf) -> float:
        a, b = self.problem.drive
        x = xf.reshape(self.problem.start.shape)
        return float(np.linalg.norm(x[a] - x[b]))

    def _drive_grad(self, xf) -> np.ndarray:
        a, b = self.problem.drive
        n, d = self.problem.start.shape
        x = xf.reshape(n, d)
        u = (x[a] - x[b]) / np.linalg.norm(x[a] - x[b])
        g = np.zeros(n * d)
        g[d * a: d * a + d] = u
        g[d * b: d * b + d] = -u
        return g
