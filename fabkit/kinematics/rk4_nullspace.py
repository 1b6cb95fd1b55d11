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
import scipy.linalg

from ..errors import KinematicsError
from ..rigidity import rigid_body_basis, rigidity_matrix
from .base import Mark, Method, Outcome
from .trajectory import EventKind, Status

__all__ = ["RK4Nullspace", "conformational_velocity"]


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
    _, s, vt = scipy.linalg.svd(r, full_matrices=True)
    tol = rtol * max(s[0] if s.size else 0.0, 1.0) * float(np.median(net.edge_lengths))
    rank = int((s > tol).sum())
    w = vt[rank:].T  # orthonormal null space of R
    rigid = rigid_body_basis(x)
    coeff = rigid.T @ w  # rigid motions expressed in the null-space basis
    _, cs, cvt = np.linalg.svd(coeff, full_matrices=True)
    crank = int((cs > 1e-8).sum())
    c = cvt[crank:].T
    count = c.shape[1]
    if count != 1:
        return None, count
    v = (w @ c)[:, 0]
    return v / np.linalg.norm(v), count


class RK4Nullspace(Method):
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

    def solve(self) -> Outcome:
        p = self.problem
        net = p.work
        n, d = p.start.shape
        scale = float(np.median(net.edge_lengths))
        h = float(self.opts["step"] or 0.01 * scale)
        if h <= 0 or not math.isfinite(h):
            raise KinematicsError(f"`step` must be positive, got {h}")
        direction = self.direction()
        target = p.target
        a, b = p.drive

        def drive(xf):
            x = xf.reshape(n, d)
            return float(np.linalg.norm(x[a] - x[b]))

        def dgrad(xf):
            x = xf.reshape(n, d)
            u = (x[a] - x[b]) / np.linalg.norm(x[a] - x[b])
            g = np.zeros(n * d)
            g[d * a: d * a + d] = u
            g[d * b: d * b + d] = -u
            return g

        evals = [0]

        def field(xf, like):
            evals[0] += 1
            v, count = conformational_velocity(net, xf)
            if v is None:
                raise _Stop(count)
            return v if v @ like >= 0 else -v

        x = p.start.ravel().copy()
        positions = [x.copy()]
        marks = []
        try:
            v0, count = conformational_velocity(net, x)
            if v0 is None:
                raise _Stop(count)
            if dgrad(x) @ v0 * direction < 0:
                v0 = -v0
            like = v0
            g_prev = float(dgrad(x) @ v0) * direction
            status, message = Status.FAILED, f"no target after {self.opts['max_steps']} steps"
            for _ in range(int(self.opts["max_steps"])):
                f_old = (drive(x) - target) * direction
                k1 = field(x, like)
                k2 = field(x + 0.5 * h * k1, k1)
                k3 = field(x + 0.5 * h * k2, k1)
                k4 = field(x + h * k3, k1)
                x_new = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
                f_new = (drive(x_new) - target) * direction
                if f_new >= 0:
                    # shorten the last step so that it ends on the target (a few secant passes)
                    hh = h * (-f_old) / (f_new - f_old)
                    for _ in range(3):
                        k1 = field(x, like)
                        k2 = field(x + 0.5 * hh * k1, k1)
                        k3 = field(x + 0.5 * hh * k2, k1)
                        k4 = field(x + hh * k3, k1)
                        xe = x + hh / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
                        fe = (drive(xe) - target) * direction
                        slope = float(dgrad(xe) @ k4) * direction
                        if abs(fe) < 1e-15 * scale or slope <= 0:
                            break
                        hh -= fe / slope
                    positions.append(xe)
                    status, message = Status.FINISHED, self.finished_message()
                    break
                v_here = field(x_new, k4)
                g_new = float(dgrad(x_new) @ v_here) * direction
                if g_new <= 0 < g_prev:
                    dval = drive(x_new)
                    detail = f"{p.drive_name} stops moving towards the target near {dval:.10g}"
                    marks.append(Mark(EventKind.TURNING_POINT, len(positions), detail))
                    positions.append(x_new)
                    status = Status.TURNING_POINT
                    message = f"stopped at a turning point of {p.drive_name} ≈ {dval:.10g}: {detail}"
                    break
                positions.append(x_new)
                x, like, g_prev = x_new, v_here, g_new
        except _Stop as stop:
            status = Status.FAILED
            message = (f"the network has {stop.count} conformational motions at "
                       f"{p.drive_name} = {drive(x):.10g}; the null-space velocity is not unique")
        X = np.array(positions).reshape(len(positions), n, d)
        return Outcome(X, status, message, tuple(marks),
                       {"steps": len(positions) - 1, "evaluations": evals[0]})


class _Stop(Exception):
    def __init__(self, count):
        super().__init__(count)
        self.count = count
