"""Printer profiles: a small catalogue of common printers' beds (:data:`PRINTERS`).

The default is ``"generic"``, the 200 × 200 mm bed PrusaSlicer assumes when no printer profile is
chosen: a layout that fits it fits most printers in use. ``[fabrication.print] printer = "mk4"``
(or ``--set print.printer=mk4``) chooses another; ``bed = [W, H]`` gives any other bed in mm.

Every profile keeps a margin free along the bed's edges (:attr:`Printer.margin`, 10 mm a side
unless ``bed_margin`` says otherwise): the slicer's skirt, brim and the support around the parts
print there, never past the bed (the 3MF asks for a skirt and support that stay inside it,
:mod:`fabkit.fab.slicer`). How pieces are laid on a bed is :mod:`fabkit.fab.printers`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..errors import FabricationError

__all__ = ["Printer", "PRINTERS", "DEFAULT_PRINTER", "GENERIC_PIN_CLEARANCE", "printer_profile",
           "BED_MARGIN"]

#: Distance (mm) kept free along every edge of a bed by default: the slicer's skirt (one loop
#: 3 mm from the parts, as the 3MF asks), the support around the parts and the first layer's
#: squish all stay on the bed (PrusaSlicer's own skirt, 6 mm out, ran 1.1 mm past the bed of
#: parts placed 5 mm from its edges).
BED_MARGIN = 10.0


#: Radial clearance (mm) of a printed pin in its hole when the printer is not known: the 0.3 mm
#: that print-in-place joints need on most desktop printers with a 0.4 mm nozzle.
GENERIC_PIN_CLEARANCE = 0.3


@dataclass(frozen=True)
class Printer:
    """A printer's build volume (mm), and the radial clearance a print-in-place pin needs on it.

    ``pin_clearance`` is the gap (mm) between a printed pin and the hole it turns in that comes
    free after printing on this class of machine (makers' clearance tests with a 0.4 mm nozzle:
    0.2 mm on enclosed, calibrated machines, 0.35 mm on a stock bed-slinger); when the joints of
    a first print bind or rattle, set ``pin_clearance`` for your machine. ``margin`` is kept
    free along every edge of the bed (mm) for the slicer's skirt, brim and support.
    """

    name: str
    width: float
    depth: float
    height: float | None
    description: str
    pin_clearance: float = GENERIC_PIN_CLEARANCE
    margin: float = BED_MARGIN

    def as_dict(self) -> dict:
        return {"name": self.name, "bed_mm": [self.width, self.depth], "height_mm": self.height,
                "description": self.description, "pin_clearance_mm": self.pin_clearance,
                "margin_mm": self.margin}


#: Beds of common printers (makers' data sheets), smallest first.
PRINTERS: dict[str, Printer] = {p.name: p for p in (
    Printer("mini", 180.0, 180.0, 180.0, "Original Prusa MINI+ (180 x 180 mm)", 0.25),
    Printer("generic", 200.0, 200.0, 200.0,
            "PrusaSlicer's default bed when no printer profile is chosen (200 x 200 mm)",
            GENERIC_PIN_CLEARANCE),
    Printer("ender3", 220.0, 220.0, 250.0, "Creality Ender-3 (220 x 220 mm)", 0.35),
    Printer("mk4", 250.0, 210.0, 220.0, "Original Prusa MK4 / i3 MK3S+ (250 x 210 mm)", 0.25),
    Printer("x1", 256.0, 256.0, 256.0, "Bambu Lab X1 / P1 series (256 x 256 mm)", 0.2),
)}

#: The printer used when a template names none.
DEFAULT_PRINTER = "generic"


def printer_profile(name=None, bed=None, where: str = "fabrication.print",
                    margin: float | None = None) -> Printer:
    """A printer from the catalogue, or a custom bed.

    Parameters
    ----------
    name : str, optional
        A key of :data:`PRINTERS` (default :data:`DEFAULT_PRINTER`).
    bed : sequence of two numbers, optional
        A custom bed, width and depth in mm (overrides ``name``).
    where : str
        Key path for messages.
    margin : float, optional
        Distance kept free along the bed's edges (mm; default the profile's,
        :data:`BED_MARGIN`).

    Returns
    -------
    Printer

    Raises
    ------
    FabricationError
        An unknown printer or a bed that is not two positive numbers.

    Examples
    --------
    >>> printer_profile().width, printer_profile("mk4").depth, printer_profile(bed=[300, 300]).name
    (200.0, 210.0, 'custom')
    """
    if bed is not None:
        ok = isinstance(bed, (list, tuple)) and len(bed) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            and v > 0 for v in bed)
        if not ok:
            raise FabricationError(f"{where}.bed: must be [width, depth] in mm, got {bed!r}")
        printer = Printer("custom", float(bed[0]), float(bed[1]), None,
                          f"custom bed ({bed[0]:g} x {bed[1]:g} mm)")
    else:
        key = DEFAULT_PRINTER if name is None else name
        if not isinstance(key, str) or key.lower() not in PRINTERS:
            raise FabricationError(f"{where}.printer: unknown printer {name!r}; valid: "
                                   f"{', '.join(PRINTERS)} (or give bed = [width, depth] in mm)")
        printer = PRINTERS[key.lower()]
    if margin is not None:
        if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin >= 0
                and 2 * margin < min(printer.width, printer.depth)):
            raise FabricationError(f"{where}.bed_margin: must be at least 0 and leave room on "
                                   f"the {printer.width:g} x {printer.depth:g} mm bed, got "
                                   f"{margin!r}")
        printer = replace(printer, margin=float(margin))
    return printer
