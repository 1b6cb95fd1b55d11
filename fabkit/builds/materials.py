"""Stiffness and strength of what bars are made of, for the elastic level of a build.

Figures are typical values from material data sheets, rounded to what a maker's part shows; the
allowable stress is what a bar may carry for as long as a model stands assembled, well below the
short-term strength (creep, crazing at cut edges, layer bonds of a print).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Material", "MATERIALS", "process_material", "bar_stiffness"]


@dataclass(frozen=True)
class Material:
    """A bar material of the elastic level.

    Attributes
    ----------
    name : str
    youngs_mpa : float
        Young's modulus E (MPa = N/mm²).
    allowable_mpa : float
        Axial stress a bar may carry while the model stands assembled (MPa).
    note : str
        Where the figures come from, and why the allowable stress is what it is.
    """

    name: str
    youngs_mpa: float
    allowable_mpa: float
    note: str


#: The materials fabkit builds in, by the names the process settings use (laser: acrylic; print:
#: the print material).
MATERIALS: dict[str, Material] = {
    "acrylic": Material(
        "acrylic (PMMA)", 3200.0, 15.0,
        "E 2.9-3.3 GPa, tensile strength 65-75 MPa; a bar held strained for months crazes from "
        "its laser-cut edges at 15-20 MPa, so 15 MPa is allowed"),
    "PLA": Material(
        "PLA", 3500.0, 15.0,
        "E 3.0-3.6 GPa printed, strength 40-60 MPa along the layers; PLA creeps under a steady "
        "load at room temperature, so about a third of the strength is allowed"),
    "PETG": Material(
        "PETG", 2100.0, 12.0,
        "E 1.9-2.2 GPa printed, strength 40-50 MPa; creeps less than PLA but is softer"),
    "TPU": Material(
        "TPU (95A)", 26.0, 5.0,
        "E about 26 MPa, strength about 30 MPa; a TPU bar stretches rather than breaks, the "
        "allowable stress keeps its strain under 20 %"),
}


def process_material(process: str, print_material: str | None = None) -> Material:
    """The bar material of a process: acrylic for laser-cut bars, the print's material for a print.

    Parameters
    ----------
    process : str
        ``"laser"`` or ``"print"``.
    print_material : str, optional
        The print's material (``"PLA"``, ``"PETG"``, ``"TPU"``); PLA when not given.

    Returns
    -------
    Material

    Raises
    ------
    ValueError
        A process without bars (``"origami"``: paper creases bend, they have no axial give that
        this model describes) or an unknown material.

    Examples
    --------
    >>> process_material("laser").youngs_mpa
    3200.0
    """
    if process == "laser":
        return MATERIALS["acrylic"]
    if process == "print":
        name = print_material or "PLA"
        if name not in MATERIALS:
            raise ValueError(f"print material {name!r} has no elastic data; known: "
                             f"{', '.join(k for k in MATERIALS if k != 'acrylic')}")
        return MATERIALS[name]
    raise ValueError(f"process {process!r} has no bar material (known: laser, print)")


def bar_stiffness(material: Material, area_mm2, rest_mm) -> np.ndarray:
    """Axial stiffness ``k = E A / L`` of every bar (N/mm).

    Parameters
    ----------
    material : Material
    area_mm2 : float or array_like, shape (E,)
        Cross-section of each bar (mm²): width times thickness.
    rest_mm : array_like, shape (E,)
        Rest lengths (mm), > 0.

    Returns
    -------
    numpy.ndarray, shape (E,)

    Examples
    --------
    >>> bar_stiffness(MATERIALS["acrylic"], 14.5 * 3.0, [100.0]).round(1).tolist()
    [1392.0]
    """
    rest = np.asarray(rest_mm, dtype=np.float64)
    if rest.size and not np.all(rest > 0):
        raise ValueError("rest lengths must be > 0")
    return material.youngs_mpa * np.broadcast_to(np.asarray(area_mm2, dtype=np.float64),
                                                 rest.shape) / rest
