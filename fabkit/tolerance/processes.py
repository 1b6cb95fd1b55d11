"""Error models of the three ways fabkit builds a network: laser-cut bars, a 3D print, folded paper.

Every model turns the design's rest geometry into the effective rest lengths of ``M`` simulated
builds (design units), drawing its random numbers in a fixed order so that switching an error
source off (to find which one stops a build) leaves the others' draws unchanged. Lengths in the
parameters are millimetres; ``scale`` (mm per design unit) converts.

Laser (acrylic bars and Chicago screws; defaults from docs/fabrication notes)
    ``bar length``: hole-to-hole length ``N(0, length_sigma)`` per bar (laser positioning);
    ``kerf``: each hole's diameter ``N(0, kerf_sigma)`` off (uneven kerf), which widens or
    tightens its play; ``hole play``: the barrel sits anywhere in a hole ``hole_clearance`` wider
    than it (uniform over the disc), moving the bar's end along its axis; ``sheet thickness``:
    ``N(thickness, thickness_sigma)`` per build, a bar tilts in its holes by up to
    ``atan(clearance / thickness)``, which shortens it by ``L (1 - cos θ)``.

Print (triangle plates joined by flexure hinges, printed flat in one piece)
    ``xy accuracy``: every joint printed ``N(0, xy_sigma)`` off per in-plane coordinate (typical
    FDM dimensional accuracy 0.1-0.2 mm); ``shrinkage``: the part shrinks by a fraction
    ``N(shrinkage, shrinkage_sigma)`` per build as it cools (material default; 0 if the slicer
    compensates); ``line width``: extrusion ``N(0, line_width_sigma)`` wider than the nozzle
    width per build, which grows every plate by half of it on each side and so shortens each
    hinge's free length by it; ``hinge flexure``: a hinge of free length ``ℓ`` turned by ``θ``
    bends into an arc whose chord is ``ℓ sin(θ/2) / (θ/2)``, so every bar loses
    ``ℓ/2 (1 - sin(θ/2)/(θ/2))`` at each of its joints (``θ``: that joint's largest turn at the
    target). Layer height and hinge thickness (a whole number of layers) set the hinges'
    stiffness and strain, not the joint-to-joint geometry: they are checked by the print
    export's strain check, not here.

Origami (a creased sheet, the paper's bar-and-joint idealisation: creases and boundary edges
are rigid bars, crease intersections are joints)
    ``crease position``: every crease vertex folded ``N(0, crease_sigma)`` off its drawn place
    per coordinate (hand folding along a printed line); ``cut``: boundary corners
    ``N(0, cut_sigma)`` off (knife or cutter); ``paper thickness``: a sheet of thickness ``t``
    folds about its inner surface, so the hinge line sits up to ``t`` (uniformly, any direction)
    from the mid-surface line the bars idealise; ``crease compliance``: creases and panels are
    not rigid, panels bow between their corners, which shortens each bar by a half-normal of
    ``compliance_sigma`` (bars never stretch).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ..numerics import TINY

__all__ = ["PROCESSES", "SOURCES", "NOT_KINEMATIC", "ProcessGeometry", "sample_lengths"]

#: The processes and, for each, its error sources (names used in verdicts) with the spec keys
#: each one reads.
SOURCES: dict[str, dict[str, tuple[str, ...]]] = {
    "laser": {"bar length": ("length_sigma",), "kerf": ("kerf_sigma",),
              "hole play": ("hole_clearance",), "sheet thickness": ("thickness_sigma",)},
    "print": {"xy accuracy": ("xy_sigma",), "shrinkage": ("shrinkage", "shrinkage_sigma"),
              "line width": ("line_width_sigma",), "hinge flexure": ("hinge_length",)},
    "origami": {"crease position": ("crease_sigma",), "cut": ("cut_sigma",),
                "paper thickness": ("paper_thickness",),
                "crease compliance": ("compliance_sigma",)},
}
PROCESSES = tuple(SOURCES)

#: Quantities of a process that do not move a joint in the rigid-bar model, and why.
NOT_KINEMATIC = {
    "print": {"layer height": "sets the hinge thickness (whole layers): stiffness and strain, "
                              "checked by the print export, not the joint positions",
              "hinge thickness": "stiffness and bending strain only (print export's check)"},
}


#: Below this half-angle (radians) sin(x)/x is 1 to round-off (its error is x²/6).
SINC_SMALL = 1e-9


@dataclass(frozen=True)
class ProcessGeometry:
    """What the error models need of a design besides its rest lengths.

    Attributes
    ----------
    nodes : numpy.ndarray, shape (N, d)
        Rest positions (design units): the flat pattern / printed layout.
    edges : numpy.ndarray of int, shape (E, 2)
    lengths : numpy.ndarray, shape (E,)
        Design rest lengths (design units); position errors are added to these.
    joint_turn : numpy.ndarray, shape (N,) or None
        Largest turn (radians) between two bars at each joint from the start to the target.
    boundary : numpy.ndarray of bool, shape (N,) or None
        Origami: nodes on the sheet's cut boundary.
    """

    nodes: np.ndarray
    edges: np.ndarray
    lengths: np.ndarray
    joint_turn: np.ndarray | None = None
    boundary: np.ndarray | None = None


def _active(spec, sources) -> set:
    names = set(SOURCES[spec.process])
    return names if sources is None else names & set(sources)


def _moved(geo: ProcessGeometry, pos) -> np.ndarray:
    """Rest lengths plus the change that moving the nodes to ``pos`` (M, N, d) makes."""
    i, j = geo.edges[:, 0], geo.edges[:, 1]
    nominal = np.linalg.norm(geo.nodes[i] - geo.nodes[j], axis=-1)
    return geo.lengths[None, :] + np.linalg.norm(pos[:, i] - pos[:, j], axis=-1) - nominal


def _laser(geo: ProcessGeometry, spec, rng, on: set) -> np.ndarray:
    L = np.asarray(geo.lengths, dtype=np.float64)
    m, e = spec.samples, L.size
    L_mm = L * spec.scale
    t = np.maximum(spec.thickness + spec.thickness_sigma * rng.standard_normal(m),
                   0.1 * spec.thickness)
    length_err = spec.length_sigma * rng.standard_normal((m, e))
    kerf = spec.kerf_sigma * rng.standard_normal((m, e, 2))
    radius_u = np.sqrt(rng.random((m, e, 2)))
    angle_u = rng.random((m, e, 2))
    tilt_u = rng.random((m, e))
    play = (spec.hole_clearance if "hole play" in on else 0.0) \
        + (kerf if "kerf" in on else np.zeros_like(kerf))
    clearance = np.maximum(play, 0.0)
    out = np.zeros((m, e))
    if "bar length" in on:
        out += length_err
    # barrel position in each hole: uniform over the disc of radius clearance / 2
    along = 0.5 * clearance * radius_u * np.cos(2.0 * np.pi * angle_u)
    out += along[..., 1] - along[..., 0]
    if "hole play" in on or "sheet thickness" in on:
        # tilt in the holes, bounded by the tighter hole of the bar; the nominal sheet when its
        # thickness is not a source, the nominal hole when its play is not
        tt = t if "sheet thickness" in on else np.full(m, spec.thickness)
        room = clearance if "hole play" in on else np.full_like(clearance, spec.hole_clearance)
        tilt = np.arctan(room.min(axis=2) / tt[:, None]) * tilt_u
        out -= L_mm[None, :] * (1.0 - np.cos(tilt))
    return L[None, :] + out / spec.scale


def _print(geo: ProcessGeometry, spec, rng, on: set) -> np.ndarray:
    x = geo.nodes * spec.scale
    m = spec.samples
    i, j = geo.edges[:, 0], geo.edges[:, 1]
    xy = spec.xy_sigma * rng.standard_normal((m,) + x.shape)
    shrink = spec.shrinkage + spec.shrinkage_sigma * rng.standard_normal(m)
    width = spec.line_width_sigma * rng.standard_normal(m)
    pos = x[None] + (xy if "xy accuracy" in on else np.zeros_like(xy))
    L = _moved(geo, pos / spec.scale) * spec.scale
    if "shrinkage" in on:
        L = L * (1.0 - shrink[:, None])
    if ("hinge flexure" in on or "line width" in on) and geo.joint_turn is not None:
        # the plates grow by half the extra width on each side: a shorter free hinge length
        ell = np.maximum(spec.hinge_length - (width if "line width" in on else 0.0 * width), 0.0)
        half = 0.5 * geo.joint_turn  # (N,)
        sinc = np.where(half > SINC_SMALL, np.sin(half) / np.where(half > SINC_SMALL, half, 1.0), 1.0)
        loss = 0.5 * ell[:, None] * (1.0 - sinc)[None, :]  # (M, N) mm at each joint
        if "hinge flexure" not in on:
            nominal = 0.5 * spec.hinge_length * (1.0 - sinc)[None, :]
            loss = loss - nominal  # the line width's share only
        L = L - loss[:, i] - loss[:, j]
    return L / spec.scale


def _origami(geo: ProcessGeometry, spec, rng, on: set) -> np.ndarray:
    x = geo.nodes * spec.scale
    m, (n, d) = spec.samples, x.shape
    i = geo.edges[:, 0]
    boundary = geo.boundary if geo.boundary is not None else np.zeros(n, dtype=bool)
    g = rng.standard_normal((m, n, d))
    direction = rng.standard_normal((m, n, d))
    reach = rng.random((m, n))
    bow = np.abs(rng.standard_normal((m, i.size)))
    sigma = np.where(boundary, spec.cut_sigma if "cut" in on else 0.0,
                     spec.crease_sigma if "crease position" in on else 0.0)
    pos = x[None] + sigma[None, :, None] * g
    if "paper thickness" in on:
        # the hinge line of a crease vertex sits up to t from the drawn (mid-surface) line
        u = direction / np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), TINY)
        pos = pos + np.where(boundary, 0.0, spec.paper_thickness * reach)[..., None] * u
    L = _moved(geo, pos / spec.scale) * spec.scale
    if "crease compliance" in on:
        L = L - spec.compliance_sigma * bow
    return L / spec.scale


_MODELS = {"laser": _laser, "print": _print, "origami": _origami}


def sample_lengths(geo: ProcessGeometry, spec, rng, sources=None) -> np.ndarray:
    """Effective rest lengths of ``spec.samples`` builds under the process's errors.

    Parameters
    ----------
    geo : ProcessGeometry
    spec : ToleranceSpec
        Its ``process`` picks the model.
    rng : numpy.random.Generator
    sources : iterable of str, optional
        Only these error sources (names of :data:`SOURCES`); None: all of them.

    Returns
    -------
    numpy.ndarray, shape (M, E)
        Design units.

    Examples
    --------
    >>> from fabkit.tolerance import ToleranceSpec
    >>> geo = ProcessGeometry(np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[0, 1]]),
    ...                       np.array([1.0]))
    >>> spec = ToleranceSpec(process="print", scale=10.0, samples=3)
    >>> sample_lengths(geo, spec, np.random.default_rng(0), sources=()).tolist()
    [[1.0], [1.0], [1.0]]
    """
    return _MODELS[spec.process](geo, spec, rng, _active(spec, sources))
