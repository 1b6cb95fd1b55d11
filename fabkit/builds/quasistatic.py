"""A driven build, bars as springs: quasi-static steps of the least-energy assembly.

The rigid model follows a design's motion while its bars keep their lengths, and stops where
they cannot (a turning point, a lock). A real build is pushed on: its bars give. Here the drive
port is set to each of a row of values in turn and the build takes, at each, its least-energy
placement (:func:`fabkit.builds.assembly.assemble`, started from the previous step's), with its
joints' play as dead bands and its bars as springs ``k = E A / L``. Along the motion: the
elastic energy, the largest axial stress and the bar that carries it. Where a rigid motion
exists the energy stays zero (the play and the mechanism take the drive); past a lock it rises,
and the stress says whether the material takes it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .assembly import assemble, bar_stress
from .materials import bar_stiffness, Material

__all__ = ["ElasticMotion", "drive_elastically"]

#: Bisections placing where the stress reaches the allowable: the step between two quasi-static
#: steps shrinks 2^20-fold (a micrometre on a 100 mm drive step).
CROSSING_BISECTIONS = 20


@dataclass
class ElasticMotion:
    """A build driven step by step with elastic bars.

    Attributes
    ----------
    drive : numpy.ndarray, shape (K,)
        The drive port's distance at each step (mm).
    positions : numpy.ndarray, shape (K, N, d)
        Pin positions (mm).
    energy : numpy.ndarray, shape (K,)
        Elastic energy (N·mm = mJ).
    stress : numpy.ndarray, shape (K, E)
        Axial stress of every bar (MPa, tension positive).
    closes : numpy.ndarray of bool, shape (K,)
        The build stands without strain at that step (its bars within their play).
    material : Material
    crossing : float or None
        The drive value (mm) where the largest stress first reaches the material's allowable,
        placed by bisection between the steps around it (None: it never does).
    """

    drive: np.ndarray
    positions: np.ndarray
    energy: np.ndarray
    stress: np.ndarray
    closes: np.ndarray
    material: Material
    crossing: float | None = None

    @property
    def peak_stress(self) -> np.ndarray:
        """Largest |stress| at each step (MPa)."""
        return np.abs(self.stress).max(axis=1) if self.stress.shape[1] else \
            np.zeros(self.drive.size)

    def first_over(self) -> int | None:
        """The first step whose largest stress passes the material's allowable, else None."""
        over = np.flatnonzero(self.peak_stress > self.material.allowable_mpa)
        return int(over[0]) if over.size else None


def drive_elastically(edges, rest_mm, room_mm, x0_mm, drive_pair, values_mm, material: Material,
                      area_mm2, held=(), held_mm=None) -> ElasticMotion:
    """Drive a build through ``values_mm`` of its drive port, one least-energy step each.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    rest_mm : array_like, shape (E,)
        The bars' own lengths (mm).
    room_mm : float or array_like, shape (E,)
        Each bar's axial play (mm; 0: none).
    x0_mm : array_like, shape (N, d)
        Where the build starts (mm): the design's start, at the drive's first value.
    drive_pair : (int, int)
        The drive port's nodes.
    values_mm : array_like, shape (K,)
        The drive port's distance at each step (mm), in order.
    material : Material
    area_mm2 : float
        Every bar's section (mm²).
    held : sequence of (int, int), optional
        Ports held at their distances ``held_mm`` (default: those in ``x0_mm``).
    held_mm : array_like, optional

    Returns
    -------
    ElasticMotion

    Raises
    ------
    ValueError
        Shapes, non-finite values, a drive value that is not a positive distance.

    Examples
    --------
    A triangle of 100 mm acrylic bars (43.5 mm² section) whose base is pulled to 100.5 mm: the
    apex follows freely, the base bar takes the 0.5 mm, σ = E ε = 3200 · 0.005 = 16 MPa, and the
    energy is ½ k δ² = ½ · 1392 N/mm · 0.25 mm² = 174 mJ.

    >>> from fabkit.builds.materials import MATERIALS
    >>> x = np.array([[0.0, 0.0], [100.0, 0.0], [50.0, 50.0 * np.sqrt(3)]])
    >>> m = drive_elastically([[0, 1], [1, 2], [2, 0]], [100.0] * 3, 0.0, x, (0, 1),
    ...                       [100.0, 100.5], MATERIALS["acrylic"], 43.5)
    >>> m.peak_stress.round(6).tolist(), m.energy.round(6).tolist(), m.closes.tolist()
    ([0.0, 16.0], [0.0, 174.0], [True, False])
    """
    values = np.asarray(values_mm, dtype=np.float64).reshape(-1)
    if values.size == 0 or not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise ValueError("`values_mm` must be positive, finite distances (at least one)")
    rest = np.asarray(rest_mm, dtype=np.float64)
    x = np.asarray(x0_mm, dtype=np.float64)
    k = bar_stiffness(material, area_mm2, rest)
    hp = [tuple(map(int, drive_pair)), *[tuple(map(int, h)) for h in held]]
    if held_mm is None:
        held_mm = [float(np.linalg.norm(x[a] - x[b])) for a, b in hp[1:]]
    held_mm = np.asarray(held_mm, dtype=np.float64).reshape(-1)
    def step(v, x_from):
        a = assemble(edges, rest, room_mm, x_from, stiffness=k, held=hp,
                     targets=np.concatenate([[v], held_mm]))
        return a, bar_stress(a, rest, material.youngs_mpa)

    positions, energy, stress, closes = [], [], [], []
    for v in values:
        a, sigma = step(v, x)
        x = a.positions
        positions.append(x)
        energy.append(a.energy)
        stress.append(sigma)
        closes.append(a.closes)
    out = ElasticMotion(values, np.array(positions), np.array(energy), np.array(stress),
                        np.array(closes, dtype=bool), material)
    first = out.first_over()
    if first is not None:
        out.crossing = float(values[0]) if first == 0 else _crossing(
            step, values[first - 1], values[first], out.positions[first - 1],
            material.allowable_mpa)
    return out


def _crossing(step, lo: float, hi: float, x_lo, allowable: float) -> float:
    """Bisection for the drive value where the largest stress reaches ``allowable``, each trial
    assembled from the last value below it."""
    for _ in range(CROSSING_BISECTIONS):
        mid = 0.5 * (lo + hi)
        a, sigma = step(mid, x_lo)
        if np.abs(sigma).max() > allowable:
            hi = mid
        else:
            lo, x_lo = mid, a.positions
    return 0.5 * (lo + hi)
