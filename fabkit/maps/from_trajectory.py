"""Maps read off a traced motion, corrected onto the constraint set."""

from __future__ import annotations

import numpy as np

from ..errors import KinematicsError
from ..numerics import project_to_lengths
from .evaluate import port_pair, slope_at
from .map1d import Map1D
from .results import Branch
from .walk import port_label


def _correct(net, X0, pair, targets):
    """Project configurations onto the edge lengths with |x_a - x_b| = target, batched."""
    proj = project_to_lengths(net.edges, net.edge_lengths, X0, pairs=[pair],
                              targets=np.asarray(targets, dtype=np.float64)[:, None])
    if not proj.converged:
        raise KinematicsError("Newton correction onto the constraint set did not converge "
                              "(a value beyond the traced branch?)")
    return proj.positions


def map_from_trajectory(traj, d_in="d1", d_out="d2", name: str | None = None) -> Map1D:
    """A map read off a traced motion (e.g. ``method="projected"``).

    The domain is the range of d_in covered by the trajectory (monotone up to a turning point:
    the tracing methods stop there). A value f(d) starts from the configuration interpolated
    between the two nearest samples and is corrected onto the constraint set with d_in = d by
    Newton's method; the slope is exact by implicit differentiation (:func:`slope_at`).

    Parameters
    ----------
    traj : Trajectory
    d_in, d_out : str or (int, int)

    Returns
    -------
    Map1D

    Raises
    ------
    KinematicsError
        When d_in is not monotone along the trajectory.
    """
    net = traj.network
    a, b = port_pair(net, d_in)
    out = port_pair(net, d_out)
    P = traj.positions
    din = np.linalg.norm(P[:, a] - P[:, b], axis=1)
    inc = np.diff(din)
    if not (np.all(inc > 0) or np.all(inc < 0)):
        raise KinematicsError("d_in is not monotone along this trajectory; split it at its "
                              "turning points first")
    order = np.argsort(din)
    din, P = din[order], P[order]

    def fun(d, derivative=True):
        d = np.asarray(d, dtype=np.float64)
        flat = np.atleast_1d(d).ravel()
        k = np.clip(np.searchsorted(din, flat) - 1, 0, din.size - 2)
        t = ((flat - din[k]) / (din[k + 1] - din[k]))[:, None, None]
        X0 = (1 - t) * P[k] + t * P[k + 1]
        X = _correct(net, X0, (a, b), flat)
        i, j = out
        f = np.linalg.norm(X[:, i] - X[:, j], axis=1)
        df = slope_at(net, X, (a, b), out) if derivative else None
        shape = d.shape
        return f.reshape(shape), (df.reshape(shape) if derivative else None)

    br = Branch(0, float(din[0]), float(din[-1]), (), ("end of the trajectory",) * 2)
    return Map1D(fun=fun, domain=(float(din[0]), float(din[-1])), branches=[br], branch=br,
                 source="trajectory", name=name or f"{port_label(net, d_in)} -> {port_label(net, d_out)}")
