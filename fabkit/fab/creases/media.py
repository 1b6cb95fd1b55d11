"""The medium a chain of origami sheets is laid out on: a paper size for a printer, a laser's
bed or a vinyl cutter's width.

``origami.medium`` names one (``"A4"``, the default; ``"Letter"``, ``"A3"``, ``"Legal"``) or
gives any width and height in mm (``"600x400"`` for a laser bed, ``"305x1000"`` for a 305 mm
vinyl cutter's roll). Every page of the layout and of the cut file is exactly that size, so a
printer prints it at 100 % and a cutter takes it whole.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ...errors import FabricationError

__all__ = ["Medium", "MEDIA", "DEFAULT_MEDIUM", "medium"]


@dataclass(frozen=True)
class Medium:
    """A page size (mm, portrait: width across, height down)."""

    name: str
    width: float
    height: float

    def text(self) -> str:
        return f"{self.name} ({self.width:g} x {self.height:g} mm)"


#: Paper sizes by name (ISO 216, and the North American sizes).
MEDIA = {m.name.lower(): m for m in (
    Medium("A4", 210.0, 297.0), Medium("A3", 297.0, 420.0), Medium("Letter", 215.9, 279.4),
    Medium("Legal", 215.9, 355.6))}
DEFAULT_MEDIUM = "A4"


def medium(value=None, where: str = "fabrication.origami.medium") -> Medium:
    """The medium a setting names.

    Examples
    --------
    >>> medium().text(), medium("letter").width, medium("305x1000").height
    ('A4 (210 x 297 mm)', 215.9, 1000.0)
    """
    text = DEFAULT_MEDIUM if value is None else value
    if isinstance(text, str):
        if text.lower() in MEDIA:
            return MEDIA[text.lower()]
        m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*[xX×]\s*(\d+(?:\.\d+)?)\s*(?:mm)?\s*", text)
        if m and 0 < float(m.group(1)) <= 10000 and 0 < float(m.group(2)) <= 100000:
            w, h = float(m.group(1)), float(m.group(2))
            return Medium(f"{w:g} x {h:g} mm", w, h)
    raise FabricationError(f"{where}: {value!r} is not a medium; give A4, A3, Letter, Legal or "
                           "WIDTHxHEIGHT in mm (600x400 for a laser bed, 305x1000 for a 305 mm "
                           "vinyl cutter)")
