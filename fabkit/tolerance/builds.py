"""Simulated builds of a design for its designer: the bar lengths of many laser-cut copies,
drawn from the laser process's error model (:mod:`fabkit.tolerance.processes`)."""

from __future__ import annotations

import numpy as np

from ..design.robustness import BUILDS
from .processes import ProcessGeometry, sample_lengths
from .spec import model_summary, tolerance_spec

__all__ = ["laser_builds"]


def laser_builds(design, settings=None):
    """Bar lengths of simulated laser-cut builds of a design: the tolerance analysis's laser
    model (bar length and kerf errors; hole play is the joints' freedom, not a length error)
    at the scale the kit of this template is cut at,
    :data:`~fabkit.design.robustness.BUILDS` builds, a fixed seed: what ``fabkit design`` judges
    its wishes and suggestions against (``fabkit.design_map(..., sample_builds=laser_builds)``).

    Parameters
    ----------
    design : Design
    settings : dict, optional
        ``--set`` overrides nested by section (``laser``, ``tolerance``), over the template's.

    Returns
    -------
    lengths : numpy.ndarray, shape (M, E)
        Design units, in the order of the design's edges.
    scale : float
        mm per design unit.
    model : str
        The errors in words.

    Examples
    --------
    >>> import fabkit
    >>> lengths, scale, model = laser_builds(fabkit.load_template("super_stable"))
    >>> lengths.shape, scale
    ((200, 6), 100.0)
    """

    spec = tolerance_spec(design, settings, process="laser", samples=BUILDS, seed=0)
    net = design.network
    lengths = np.linalg.norm(net.nodes[net.edges[:, 0]] - net.nodes[net.edges[:, 1]], axis=1)
    geo = ProcessGeometry(nodes=net.nodes, edges=net.edges, lengths=lengths)
    built = sample_lengths(geo, spec, np.random.default_rng(spec.seed))
    return built, float(spec.scale), model_summary(spec)
