"""The print process's plan: the bodies of a printed network, decided once.

A network of rigid triangles prints as one hinged solid (:mod:`fabkit.fab.hinges`: plates,
hinges, the solid and its mesh, and how far the hinges bend along the traced motion); a bar
linkage prints in place with pins (:func:`fabkit.fab.pinned.pinned_print`: layers, pins,
pieces, beds). The print writers (:mod:`fabkit.writers.stl`) turn the plan into STL and 3MF
files and nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import FabricationError
from ..motion import motion_for
from ..settings.design import design_settings
from ..status import Status
from .slicer import placement_margin, slicer_settings, SlicerSettings

__all__ = ["PrintPlan", "print_plan", "hinge_motion"]


@dataclass(frozen=True, eq=False)
class PrintPlan:
    """The print process's plan.

    Attributes
    ----------
    design : Design
    settings : PrintSettings
        Resolved once from ``[fabrication.print]`` and the overrides.
    pinned : PinnedPrint or None
        A print-in-place bar linkage (``linkage = "pins"``); None for a hinged solid.
    geo, body : optional
        A hinged solid's geometry (:func:`fabkit.fab.hinges.print_geometry`) and solid.
    verts, faces : numpy.ndarray, optional
        The hinged solid's mesh.
    hinges : dict
        How far the hinges bend along the design's motion (:func:`hinge_motion`).
    slicer : SlicerSettings
        What the print's 3MF files tell the slicer (:func:`fabkit.fab.slicer.slicer_settings`).
    parts_margin : float
        How far (mm) the bed layout keeps the parts from the bed's edges: the printer's margin
        and the slicer's reach (:func:`fabkit.fab.slicer.placement_margin`).
    """

    design: object
    settings: object
    pinned: object = None
    geo: object = None
    body: object = None
    verts: np.ndarray | None = None
    faces: np.ndarray | None = None
    hinges: dict | None = None
    slicer: SlicerSettings | None = None
    parts_margin: float = 0.0

    @property
    def panels(self) -> list:
        """A hinged solid's rigid plates as node triples, sorted (what a drawing of the
        design's motion fills); none for a print-in-place linkage."""
        if self.geo is None:
            return []
        return [sorted(int(i) for i in t) for t in self.geo.triangles]


def print_plan(design, settings=None, motion=None) -> PrintPlan:
    """The print plan of a planar design.

    Parameters
    ----------
    design : Design
        A planar network: of rigid triangles (a hinged solid) or of bars (a print-in-place
        linkage), as ``linkage`` says.
    settings : DesignSettings, optional
        The design's settings, resolved once (:func:`fabkit.settings.design.design_settings`;
        a dict of overrides nested by section, ``{"print": {"gap": 0.3}}``, is resolved here).
    motion : TracedMotion, optional
        The design's motion, traced once by the pipeline: the hinges' bending and a linkage's
        stacking are measured along it. Traced here, once, when not given.

    Returns
    -------
    PrintPlan

    Raises
    ------
    FabricationError
        Invalid print settings, a network that is not planar or not made of triangles, plates
        that would touch, hinges that do not fit; bars that cannot be stacked or pinned.
    """
    from .hinges import print_geometry, print_solid, solid_mesh

    s = design_settings(design, settings).require("print")
    if design.network.dim != 2:
        raise FabricationError(f"printing needs a planar network; {design.name} is "
                               f"{design.network.dim}D")
    if s.linkage == "pins":
        from .pinned import pinned_print

        return PrintPlan(design, s, pinned=pinned_print(design, s, motion),
                         slicer=slicer_settings(s), parts_margin=placement_margin(s))
    geo = print_geometry(design.network, s)
    body = print_solid(geo)
    verts, faces = solid_mesh(body)
    return PrintPlan(design, s, geo=geo, body=body, verts=verts, faces=faces,
                     hinges=hinge_motion(design, geo, motion_for(design, motion)),
                     slicer=slicer_settings(s), parts_margin=placement_margin(s))


def hinge_motion(design, geo, motion) -> dict:
    """Largest hinge rotation along the design's motion and the bending strain it means.

    Parameters
    ----------
    design : Design
    geo : PrintGeometry
    motion : TracedMotion

    Returns
    -------
    dict
        ``status`` and, for a traced motion, ``max_rotation_deg``, ``bending_strain``,
        ``worst_joint``, ``strain_limit``, ``hinge_length_needed``.
    """
    from .hinges import hinge_bending

    s = geo.settings
    if design.motion.to is None:
        return {"status": "no motion in the template"}
    traj = motion.trajectory
    if traj is None:
        if motion.status is Status.NO_TARGET:
            return {"status": "no motion in the template"}
        return {"status": f"motion not traced: {motion.error or motion.message}"}
    turn, strain = hinge_bending(geo, traj.positions)
    k = int(np.argmax(strain)) if strain.size else 0
    return {"status": str(traj.status),
            "max_rotation_deg": float(np.degrees(turn.max())) if turn.size else 0.0,
            "bending_strain": float(strain[k]) if strain.size else 0.0,
            "worst_joint": int(geo.arm_joint[k]) if strain.size else None,
            "strain_limit": s.strain_limit,
            "hinge_length_needed": float(strain[k] / s.strain_limit * 2.0 * geo.arm_length[k])
            if strain.size else 0.0}
