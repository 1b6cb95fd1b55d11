"""A design's motion with elastic bars: its kit (laser) or pin-jointed print driven step by step.

What ``fabkit simulate --model elastic`` runs. The design's process gives the bars' material
and section and the joints' play: a laser kit is acrylic of the sheet's thickness and the bars'
width with the holes' clearance; a pin-jointed print is its material, ``bar_width`` ×
``bar_thickness``, with twice the pin's radial clearance (one per end). A crease pattern or a
print of triangles and flexure hinges has no bars for this model and is refused with the reason.
The process is the template's, or ``--set tolerance.process``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..builds.materials import Material, process_material
from ..builds.quasistatic import drive_elastically, ElasticMotion
from ..errors import TemplateError
from ..settings.design import design_settings
from ..kinematics import make_problem
from .pins import pin_play
from .processes import nominal_room_mm
from .spec import design_process, stated_process, tolerance_spec

__all__ = ["ElasticRun", "elastic_motion", "DEFAULT_STEPS"]

#: Quasi-static steps of the drive from its start to its target, both included.
DEFAULT_STEPS = 51


@dataclass
class ElasticRun:
    """A design driven with elastic bars, in mm.

    Attributes
    ----------
    motion : ElasticMotion
    edges : numpy.ndarray of int, shape (E, 2)
    drive : str
        The drive port's name.
    scale : float
        mm per design unit.
    process : str
    section_mm2 : float
    room_mm : float
        A bar's axial play (mm): the median over the bars (a print's bar that carries a pin
        has play at its other end only).
    """

    motion: ElasticMotion
    edges: np.ndarray
    drive: str
    scale: float
    process: str
    section_mm2: float
    room_mm: float

    @property
    def material(self) -> Material:
        return self.motion.material

    def summary(self) -> list[str]:
        """Terminal lines: the steps, the energy, the largest stress and where, the verdict."""
        m = self.motion
        peak = m.peak_stress
        k = int(np.argmax(peak))
        e = int(np.argmax(np.abs(m.stress[k]))) if m.stress.shape[1] else 0
        bar = tuple(int(v) for v in self.edges[e]) if self.edges.size else None
        lines = [f"elastic: {m.drive.size} quasi-static steps of {self.drive}, "
                 f"{m.drive[0]:.4g} to {m.drive[-1]:.4g} mm; {self.material.name} bars, "
                 f"{self.section_mm2:.3g} mm² section, {self.room_mm:.3g} mm play",
                 f"elastic: energy up to {float(m.energy.max()):.3g} mJ; the build stands "
                 f"unstrained at {int(m.closes.sum())} of {m.drive.size} steps",
                 f"elastic: largest stress {float(peak[k]):.3g} MPa, in bar {bar} at "
                 f"{self.drive} = {m.drive[k]:.4g} mm ({self.material.name} allows "
                 f"{self.material.allowable_mpa:g} MPa)" if peak[k] > 0 else
                 "elastic: no bar is strained (0 MPa): the play and the mechanism take the "
                 "whole drive"]
        return lines

    def over(self) -> str | None:
        """Where the stress first passes the material's allowable, in words, else None."""
        m = self.motion
        k = m.first_over()
        if k is None:
            return None
        e = int(np.argmax(np.abs(m.stress[k])))
        return (f"driven with elastic bars, bar {tuple(int(v) for v in self.edges[e])} reaches "
                f"the {self.material.allowable_mpa:g} MPa {self.material.name} allows at "
                f"{self.drive} = {m.crossing:.6g} mm, {abs(m.crossing - m.drive[-1]):.3g} mm "
                f"before the target ({abs(m.stress[-1]).max():.3g} MPa at the target): the build would "
                "craze or break on the way")

    def arrays(self) -> dict:
        """What ``elastic.npz`` holds."""
        m = self.motion
        return {"drive_mm": m.drive, "positions_mm": m.positions, "energy_mj": m.energy,
                "stress_mpa": m.stress, "closes": m.closes, "edges": self.edges,
                "allowable_mpa": np.array(self.material.allowable_mpa),
                "material": np.array(self.material.name)}


def _bars(design, settings) -> tuple[str, float, Material, float, np.ndarray]:
    """(process, scale, material, section mm², each bar's play mm) of a design's bars: the
    tolerance settings' (one resolution of the process's settings, the print's pins from its
    plan)."""
    path = design.path or design.name
    settings = design_settings(design, settings)  # once: the spec below reads the same
    process = stated_process(design, settings) or design_process(design)
    if process == "print" and settings.require("print").linkage != "pins":
        raise TemplateError(path, "fabrication.print.linkage",
                            "--model elastic drives bars; this print is triangles joined by "
                            "flexure hinges, which bend rather than stretch (print it with "
                            "linkage = \"pins\", or export the laser kit)")
    if process not in ("laser", "print"):
        raise TemplateError(path, "fabrication", f"--model elastic drives bars; this design is "
                                                 f"made by {process}, whose creases bend rather "
                                                 "than stretch")
    spec = tolerance_spec(design, settings, process=process)
    ends = pin_play(design, spec.print_settings).ends if process == "print" else None
    room = nominal_room_mm(spec, design.network.n_edges, ends)
    return (process, float(spec.scale), process_material(process, spec.material),
            float(spec.section_mm2), np.zeros(design.network.n_edges) if room is None else room)


def elastic_motion(design, to: float | None = None, steps: int = DEFAULT_STEPS,
                   settings=None) -> ElasticRun:
    """Drive a design's build with elastic bars from its start to its target.

    Parameters
    ----------
    design : Design
    to : float, optional
        Target of the drive (design units; default: the template's ``motion.to``).
    steps : int
        Quasi-static steps, the start and the target included (>= 2).
    settings : DesignSettings or dict, optional
        The design's resolved settings, or ``--set`` overrides by section (``laser``,
        ``print``, ``tolerance``), resolved once, here.

    Returns
    -------
    ElasticRun

    Raises
    ------
    TemplateError
        No target, or a process without bars (origami, a hinged print).

    Examples
    --------
    >>> from fabkit.templates import load_template
    >>> run = elastic_motion(load_template("fourbar"), steps=5)
    >>> run.process, bool(run.motion.closes.all()), float(run.motion.peak_stress.max()) < 1e-6
    ('laser', True, True)
    """
    path = design.path or design.name
    m = design.motion
    target = m.to if to is None else to
    if target is None:
        raise TemplateError(path, "motion.to", "--model elastic needs a target for the drive")
    if steps < 2:
        raise ValueError(f"steps must be at least 2, got {steps}")
    process, scale, material, section, room = _bars(design, settings)
    net = design.network
    problem = make_problem(net, m.drive, target, hold=m.hold)
    a, b = problem.drive
    values = np.linspace(problem.start_drive, float(target), steps) * scale
    held = [net.port(h) for h in (m.hold or ())]
    motion = drive_elastically(net.edges, net.edge_lengths * scale, room, net.nodes * scale,
                               (a, b), values, material, section, held=held)
    return ElasticRun(motion, np.asarray(net.edges), m.drive, scale, process, section,
                      float(np.median(room)) if room.size else 0.0)
