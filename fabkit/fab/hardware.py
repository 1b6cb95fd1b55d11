"""Chicago-screw catalogue: barrel, running hole, head and the post lengths one can buy.

A Chicago screw (sex bolt) is a barrel with a female thread and a screw with a male one; the
barrel's post length is the thickness it clamps. Vendors name it by that length ("3/16 in"),
not by its diameter. The default entry is the metric set used for laser-cut linkages: M3
thread, 4.0 mm barrel, 4.2 mm running hole, 8.5 mm heads 1.9 mm tall, posts 4-16 mm in 1 mm
steps then 18, 20, 22, 25, 28, 30 mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from ..errors import FabricationError
from ..numerics import MM_SLACK
from ..schema import ScrewSection, check_table

__all__ = ["ScrewSpec", "CATALOGUE", "DEFAULT_SCREW", "screw_spec", "choose_length", "ScrewFit",
           "fit_screw", "WASHER_THICKNESS"]

#: Thickness of the thin washers (shims) listed to take up large axial play (mm).
WASHER_THICKNESS = 0.5


@dataclass(frozen=True)
class ScrewSpec:
    """One catalogue entry (all lengths in mm).

    Attributes
    ----------
    name : str
    barrel_diameter : float
        Outer diameter of the barrel (the pin the bars turn on).
    hole_diameter : float
        Running hole cut in every bar (barrel + running clearance).
    head_diameter, head_height : float
        The heads at both ends of the stack.
    lengths : tuple of float
        Post lengths available, ascending.
    allowance : float
        Axial play added to the stack height before choosing a length.
    """

    name: str
    barrel_diameter: float
    hole_diameter: float
    head_diameter: float
    head_height: float
    lengths: tuple[float, ...]
    allowance: float = 0.1

    def as_dict(self) -> dict:
        return {f.name: (list(getattr(self, f.name)) if f.name == "lengths" else getattr(self, f.name))
                for f in fields(self)}


_METRIC_LENGTHS = tuple(float(v) for v in [*range(4, 17), 18, 20, 22, 25, 28, 30])

#: Built-in entries; a template may override any field of one of them.
CATALOGUE: dict[str, ScrewSpec] = {
    "M3-chicago": ScrewSpec("M3-chicago", 4.0, 4.2, 8.5, 1.9, _METRIC_LENGTHS),
    "M4-chicago": ScrewSpec("M4-chicago", 5.0, 5.2, 10.0, 2.0, _METRIC_LENGTHS[1:]),
    "M5-chicago": ScrewSpec("M5-chicago", 6.0, 6.2, 12.0, 2.5, _METRIC_LENGTHS[2:]),
}

DEFAULT_SCREW = "M3-chicago"

_FIELDS = {f.name for f in fields(ScrewSpec)}
#: What a screw of one's own must give (the rest have defaults).
_SIZE_FIELDS = ("barrel_diameter", "hole_diameter", "head_diameter", "head_height", "lengths")



def screw_spec(entry=None) -> ScrewSpec:
    """Resolve a catalogue entry: a name, a table of overrides, or None for the default.

    Parameters
    ----------
    entry : str, dict or None
        ``"M3-chicago"``; or ``{"name": "M3-chicago", "hole_diameter": 4.3, ...}`` (fields not
        given come from the named entry, the default when no name is given).

    Returns
    -------
    ScrewSpec

    Raises
    ------
    FabricationError
        Unknown entry or field, or a non-positive / inconsistent size.

    Examples
    --------
    >>> screw_spec({"hole_diameter": 4.3}).hole_diameter
    4.3
    """
    if entry is None:
        return CATALOGUE[DEFAULT_SCREW]
    if isinstance(entry, ScrewSpec):
        spec = entry
    elif isinstance(entry, str):
        if entry not in CATALOGUE:
            raise FabricationError(f"unknown screw {entry!r}; catalogue entries: "
                                   f"{', '.join(CATALOGUE)} (or give a table with its sizes)")
        return CATALOGUE[entry]
    elif isinstance(entry, dict):
        given = check_table(ScrewSection, entry, "laser.screw").given()
        name = given.get("name")
        if name is not None and name not in CATALOGUE:
            # a screw of one's own: a misspelt catalogue name must not pass as one
            missing = [f for f in _SIZE_FIELDS if f not in given]
            if missing:
                raise FabricationError(
                    f"unknown screw {name!r}; catalogue entries: {', '.join(CATALOGUE)}; a "
                    f"screw of your own needs every size ({', '.join(missing)} missing)")
        base = CATALOGUE[name] if name in CATALOGUE else CATALOGUE[DEFAULT_SCREW]
        values = {k: (tuple(sorted(float(x) for x in v)) if k == "lengths" else
                      (v if k == "name" else float(v))) for k, v in given.items()}
        spec = replace(base, **values)
    else:
        raise FabricationError(f"screw must be a catalogue name or a table, got {entry!r}")
    if spec.hole_diameter < spec.barrel_diameter:
        raise FabricationError(
            f"screw hole_diameter {spec.hole_diameter} mm is smaller than the barrel "
            f"{spec.barrel_diameter} mm: the bars would not turn; use barrel + 0.2 mm")
    if spec.head_diameter <= spec.hole_diameter:
        raise FabricationError(
            f"screw head_diameter {spec.head_diameter} mm must exceed the hole "
            f"{spec.hole_diameter} mm, or the head pulls through")
    return spec


def choose_length(spec: ScrewSpec, stack: float) -> float:
    """Shortest post length that clamps a stack of ``stack`` mm plus the allowance.

    Raises
    ------
    FabricationError
        When the stack is taller than the longest post in the catalogue entry.

    Examples
    --------
    >>> choose_length(screw_spec(), 6.0)
    7.0
    """
    need = stack + spec.allowance
    for length in spec.lengths:
        if length >= need - MM_SLACK:
            return float(length)
    raise FabricationError(
        f"a joint stack of {stack:.2f} mm (+{spec.allowance} mm play) needs a screw longer than "
        f"the longest {spec.name} post ({spec.lengths[-1]:g} mm); add longer lengths to the screw "
        "entry, use thinner sheet, or reduce the layers (smaller bar_width or larger scale)")


@dataclass(frozen=True)
class ScrewFit:
    """A screw chosen for a stack of sheets whose thickness is only known within a tolerance.

    Attributes
    ----------
    layers : int
        Sheets clamped (bars and spacer rings).
    length : float
        Post length (mm): closes on the thickest sheets, ``layers x (t + tol)`` plus the
        allowance.
    stack_min, stack_max : float
        Stack height on the thinnest and thickest sheets (mm).
    washers : int
        Thin washers (``WASHER_THICKNESS``) to add under a head; still closes on the thickest
        sheets.
    play_min, play_max : float
        Axial play with the washers, on the thickest and thinnest sheets (mm).
    """

    layers: int
    length: float
    stack_min: float
    stack_max: float
    washers: int
    play_min: float
    play_max: float

    @property
    def closes(self) -> bool:
        """True when the post is long enough for the thickest stack with its washers."""
        return self.play_min >= -MM_SLACK


def fit_screw(spec: ScrewSpec, layers: int, thickness: float, tolerance: float) -> ScrewFit:
    """Post length and washers for ``layers`` sheets of ``thickness +- tolerance`` mm.

    Raises
    ------
    FabricationError
        When even the longest post is too short for the thickest stack.

    Examples
    --------
    >>> f = fit_screw(screw_spec(), 7, 3.0, 0.15)     # 7 sheets may be 22.05 mm
    >>> f.length, f.stack_max, f.washers, round(f.play_max, 2)
    (25.0, 22.05, 5, 2.55)
    """
    stack_min = layers * (thickness - tolerance)
    stack_max = layers * (thickness + tolerance)
    length = choose_length(spec, stack_max)
    washers = int(math.floor((length - stack_max - spec.allowance) / WASHER_THICKNESS + MM_SLACK))
    washers = max(washers, 0)
    fill = washers * WASHER_THICKNESS
    return ScrewFit(layers=int(layers), length=length, stack_min=round(stack_min, 9),
                    stack_max=round(stack_max, 9), washers=washers,
                    play_min=round(length - stack_max - fill, 9),
                    play_max=round(length - stack_min - fill, 9))
