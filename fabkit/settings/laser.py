"""Laser-cutting settings: the template's ``[fabrication.laser]`` table merged with overrides.

Every setting has a default that gives a working export for the bundled templates. Types and
ranges are declared once, in :class:`fabkit.io.schema.LaserSection`; what only the settings
together can tell (a hole that leaves too thin a web) is checked here, with one line that names
the setting, the value and a fix.

Lengths are millimetres; design units become millimetres through ``scale`` (mm per design
unit) or ``size`` (mm: the largest extent of the network's reference configuration).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from ..errors import FabricationError
from ..io.schema import check_section, LaserSection, section_of
from ..numerics import MM_SLACK
from .fasteners import screw_spec, ScrewSpec

__all__ = ["LaserSettings", "laser_settings", "laser_overrides", "DEFAULT_SCALE",
           "DEFAULT_MAX_LAYERS", "LASER_KEYS"]

#: mm per design unit when neither ``scale`` nor ``size`` is given: the paper's modules (edges
#: 0.57-2.8 units) become bars of 57-283 mm, comfortably longer than two 4.2 mm holes.
DEFAULT_SCALE = 100.0
#: Narrowest default bar (mm): a bar of the paper's kits.
_MIN_BAR_WIDTH = 14.0
#: Most stacking layers accepted by default (a policy, not a limit of the hardware: 24 sheets of
#: 3 mm are 72 mm, which the catalogue's bolts and Chicago screws with extensions still hold).
DEFAULT_MAX_LAYERS = 24



@dataclass(frozen=True)
class LaserSettings:
    """Resolved laser settings (mm unless said otherwise).

    Attributes
    ----------
    scale : float
        mm per design unit.
    bar_width : float
        Width of every bar (its round ends have radius ``bar_width / 2``; default: the
        screw's hole plus twice the minimum web, to the half millimetre above, at least 14 mm:
        14.5 mm for the default 5 mm barrel).
    thickness : float
        Measured sheet thickness: the layer pitch and the basis of screw lengths.
    thickness_tolerance : float
        How far one sheet may differ from ``thickness`` (mm): screws are chosen to close on
        the thickest stack, with shims taking up the play on the nominal sheet.
    kerf : float
        Width of the laser's cut; outlines grow and holes shrink by ``kerf / 2`` (0 when the
        cutting service compensates itself).
    min_web : float
        Least material between a hole and any edge (default 1.5 x thickness).
    clearance : float
        Least gap between two bars (or a bar and a screw head) of one layer over the motion.
    sheet_width, sheet_height, spacing, margin : float
        Sheet size, gap between parts, and border kept free.
    screw : ScrewSpec
    spacer_diameter : float
        Outer diameter of the spacer rings cut for layers a screw passes without a bar
        (default: the hole plus twice the minimum web, at least the screw head).
    flavour : str
        ``"lwpolyline"`` (closed LWPOLYLINE with bulges) or ``"line-arc"`` (LINE + ARC, for
        programs that ignore bulges).
    labels : str
        ``"outlines"`` (glyph outlines, the default: many CAM importers drop TEXT),
        ``"text"`` (TEXT entities) or ``"none"``.
    label_height : float
        Largest text height; labels shrink to fit between a bar's holes.
    reference_square : str
        ``"engrave"``, ``"cut"`` or ``"none"``: a 100 mm square on the first sheet.
    max_layers : int
        Refuse designs that need more stacking layers than this (a policy: deep stacks are held
        by the long fasteners of :mod:`fabkit.settings.fasteners`).
    motion_from, motion_to : float or None
        Drive values where the kit's motion starts and ends, when the kit covers only part of
        the design's motion (None: the design's start and ``motion.to``).
    uncompensated : bool
        Also write every sheet drawn at true size (no kerf applied), for a cutting service that
        compensates kerf itself.
    """

    scale: float = DEFAULT_SCALE
    bar_width: float = 14.5
    thickness: float = 3.0
    thickness_tolerance: float = 0.15
    kerf: float = 0.15
    min_web: float = 4.5
    clearance: float = 1.0
    sheet_width: float = 600.0
    sheet_height: float = 400.0
    spacing: float = 3.0
    margin: float = 5.0
    screw: ScrewSpec = field(default_factory=screw_spec)
    spacer_diameter: float = 14.2
    flavour: str = "lwpolyline"
    labels: str = "outlines"
    label_height: float = 3.5
    reference_square: str = "engrave"
    max_layers: int = DEFAULT_MAX_LAYERS
    motion_from: float | None = None
    motion_to: float | None = None
    uncompensated: bool = False

    def as_dict(self) -> dict:
        d = asdict(self)
        d["screw"] = self.screw.as_dict()
        return d

    @property
    def sample_step(self) -> float:
        """Largest node displacement (mm) allowed between two samples of the motion."""
        return 0.5 * self.clearance


#: Keys accepted in ``[fabrication.laser]`` (and as overrides): those of the declared schema.
LASER_KEYS = set(LaserSection.model_fields)


def laser_overrides(settings: dict | None) -> dict:
    """The laser overrides of an exporter's settings (nested by section, as ``--set`` and the
    API give them), checked against the schema.

    Examples
    --------
    >>> laser_overrides({"laser": {"kerf": 0.2}, "print": {"gap": 0.4}})
    {'kerf': 0.2}
    """
    return section_of(settings, "laser")


def laser_settings(table: dict | None = None, overrides: dict | None = None, *,
                   network_size: float | None = None) -> LaserSettings:
    """Resolve laser settings from a template table and overrides (overrides win).

    Types and ranges of every key are those of :class:`fabkit.io.schema.LaserSection`; here the
    defaults are filled in and the settings are checked against one another.

    Parameters
    ----------
    table : dict, optional
        The template's ``[fabrication.laser]`` table.
    overrides : dict, optional
        Values from the command line or a caller, same keys.
    network_size : float, optional
        Largest extent of the network (design units); needed when ``size`` is given.

    Returns
    -------
    LaserSettings

    Raises
    ------
    SettingsError
        Unknown key, wrong type or a value out of range (the schema).
    FabricationError
        Settings that cannot be cut together (web thinner than the hole allows, a kerf that
        closes the holes, ...), with a suggested fix.

    Examples
    --------
    >>> s = laser_settings({"kerf": 0.2}, {"bar_width": 15})
    >>> s.kerf, s.bar_width, s.min_web
    (0.2, 15.0, 4.5)
    """
    merged = dict(table or {})
    merged.update(overrides or {})
    given = check_section("laser", merged).given()
    values: dict = {k: float(v) for k, v in given.items()
                    if k not in ("scale", "size", "screw", "flavour", "labels",
                                 "reference_square", "max_layers", "uncompensated")}
    if given.get("scale") is not None and given.get("size") is not None:
        raise FabricationError("give either laser scale (mm per design unit) or size (mm), not both")
    if given.get("size") is not None:
        if not network_size:
            raise FabricationError("laser setting size needs the network's extent; give scale instead")
        values["scale"] = float(given["size"]) / network_size
    elif given.get("scale") is not None:
        values["scale"] = float(given["scale"])
    for key in ("flavour", "labels", "reference_square", "max_layers", "uncompensated"):
        if given.get(key) is not None:
            values[key] = given[key]
    values["screw"] = screw_spec(merged.get("screw"))
    thickness = values.get("thickness", LaserSettings.thickness)
    values.setdefault("min_web", 1.5 * thickness)
    # bars wide enough for the screw's hole and the minimum web on both sides
    values.setdefault("bar_width", max(_MIN_BAR_WIDTH, math.ceil(
        2.0 * (values["screw"].hole_diameter + 2 * values["min_web"]) - MM_SLACK) / 2.0))
    # spacer rings keep the bars' minimum web around their hole, and cover a screw head
    values.setdefault("spacer_diameter", max(values["screw"].head_diameter,
                                             values["screw"].hole_diameter + 2 * values["min_web"]))
    s = LaserSettings(**{k: v for k, v in values.items() if v is not None})
    _check_consistency(s)
    return s


def _check_consistency(s: LaserSettings) -> None:
    hole = s.screw.hole_diameter
    if hole >= s.bar_width:
        raise FabricationError(
            f"the {hole:g} mm screw hole is bigger than the {s.bar_width:g} mm bar: use "
            f"bar_width >= {hole + 2 * s.min_web:.1f} mm or a smaller screw")
    web = 0.5 * (s.bar_width - hole)
    if web < s.min_web - MM_SLACK:
        raise FabricationError(
            f"hole-to-edge web {web:.2f} mm is below the minimum {s.min_web:.2f} mm "
            f"(1.5 x sheet thickness by default): use bar_width >= {hole + 2 * s.min_web:.1f} mm "
            "or lower min_web")
    if s.kerf >= hole:
        raise FabricationError(f"kerf {s.kerf:g} mm would close the {hole:g} mm holes; "
                               "measure the kerf again (typically 0.1-0.25 mm)")
    if s.spacer_diameter < hole + 2 * s.min_web - MM_SLACK:
        raise FabricationError(f"spacer_diameter {s.spacer_diameter:g} mm leaves less than the "
                               f"{s.min_web:g} mm minimum web around the {hole:g} mm hole; use "
                               f"at least {hole + 2 * s.min_web:.1f} mm")
    if s.thickness_tolerance >= s.thickness:
        raise FabricationError(f"thickness_tolerance {s.thickness_tolerance:g} mm is not below "
                               f"the {s.thickness:g} mm sheet thickness")
    free_w = s.sheet_width - 2 * s.margin
    free_h = s.sheet_height - 2 * s.margin
    if free_w <= 0 or free_h <= 0:
        raise FabricationError(f"sheet margin {s.margin:g} mm leaves no room on a "
                               f"{s.sheet_width:g} x {s.sheet_height:g} mm sheet")
    if s.reference_square != "none" and min(free_w, free_h) < 100.0:
        raise FabricationError(
            f"a {s.sheet_width:g} x {s.sheet_height:g} mm sheet (margin {s.margin:g}) cannot hold "
            "the 100 mm reference square; use a larger sheet or reference_square = \"none\"")
