"""Print settings: the ``[fabrication.print]`` table.

Two kinds of print share the table (``linkage``): ``"hinges"``, rigid triangles joined by thin
hinges in one solid (:mod:`fabkit.fab.hinges`), and ``"pins"``, bars stacked in layers on printed
pins, one body per bar, printed in place (:mod:`fabkit.fab.pinned`). A template's table is merged
with command-line overrides (``--set print.gap=0.3``) over the defaults of the chosen material
and kind. Types and ranges are declared in :class:`fabkit.io.schema.PrintSection`; what only the
settings together can tell (a hole that leaves too thin a web, a height that is not a whole
number of layers) is checked here, once, and a bad one raises a
:class:`~fabkit.errors.FabricationError` whose message is one line naming the key, the value and
what to do.

All lengths are in millimetres except ``scale`` (millimetres per design unit).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from ..errors import FabricationError
from ..io.schema import check_section, HINGE_STYLES, section_of
from ..numerics import MM_SLACK
from ..model.triangles import rigid_triangles
from .printers import DEFAULT_PRINTER, printer_profile

__all__ = ["PrintSettings", "MATERIALS", "HINGE_STYLES", "PIN_DEFAULTS", "print_settings",
           "design_print_settings", "default_linkage"]

# Hinge styles (HINGE_STYLES, declared in fabkit.io.schema). "neck": a narrow neck as tall as the
# plates less one layer, bending in the plane of the print (stiff out of the plane, compliant in
# it). "bridge": a thin bridge of whole layers on the build plate (the paper's "thin layer of
# material").

#: Defaults per material (mm). ``strain_limit`` is the bending strain a hinge may see in repeated
#: use (well under the material's yield strain): it sets how long a neck must be for a given
#: width and rotation (see docs/printing.md).
MATERIALS: dict[str, dict] = {
    "PLA": {"plate_thickness": 3.0, "hinge_style": "neck", "hinge_layers": 2, "hinge_width": 0.8,
            "hinge_length": 6.0, "gap": 0.4, "layer_height": 0.2, "nozzle_width": 0.4,
            "strain_limit": 0.02},
    "PETG": {"plate_thickness": 3.0, "hinge_style": "neck", "hinge_layers": 2, "hinge_width": 0.8,
             "hinge_length": 6.0, "gap": 0.4, "layer_height": 0.2, "nozzle_width": 0.4,
             "strain_limit": 0.03},
    "TPU": {"plate_thickness": 3.0, "hinge_style": "bridge", "hinge_layers": 3, "hinge_width": 1.2,
            "hinge_length": 6.0, "gap": 0.5, "layer_height": 0.2, "nozzle_width": 0.4,
            "strain_limit": 0.25},
}

_DEFAULT_SCALE = 10.0

#: Defaults of a print-in-place bar linkage (``linkage = "pins"``), mm. A 3 mm pin in a 3.6 mm
#: hole (0.3 mm radial clearance on the generic printer) leaves 1.7 mm of web in a 7 mm bar; the
#: 6 mm caps overlap the hole by 1.2 mm and stay inside the bar's round end; 2.4 mm bars (12
#: layers of 0.2 mm) with 0.4 mm between layers. 40 mm per design unit makes the paper's
#: modules 60-110 mm across, and their shortest bars (0.57 units) 23 mm between hole centres.
#: Up to 24 layers (67 mm of pin), as for the laser kit: a deep stack is a taller print, not a
#: refusal (the NETWORK letters' chain needs 15).
PIN_DEFAULTS: dict[str, float] = {"scale": 50.0, "bar_width": 7.0, "bar_thickness": 2.4,
                                  "layer_gap": 0.4, "pin_diameter": 3.0, "cap_diameter": 5.0,
                                  "clearance": 0.5, "max_layers": 24}

#: Keys that apply to one kind of print only.
_HINGE_KEYS = ("plate_thickness", "hinge_style", "hinge_layers", "hinge_thickness",
               "hinge_width", "hinge_length", "gap", "strain_limit", "rigid_triangles")
_PIN_KEYS = ("bar_width", "bar_thickness", "layer_gap", "pin_diameter", "pin_clearance",
             "cap_diameter", "clearance", "max_layers", "motion_from", "motion_to")



#: Least radial clearance of a printed pin in its hole (mm): an extruded wall is placed to about
#: 0.05 mm, so a smaller gap prints fused (printers need 0.3-0.4 mm for bodies to part).
MIN_PIN_CLEARANCE = 0.05

#: A thickness is a whole number of print layers when it is within this fraction of a layer of
#: one (typed values such as 0.6 mm / 0.2 mm carry round-off only).
WHOLE_LAYERS_RTOL = 1e-6


@dataclass(frozen=True)
class PrintSettings:
    """Validated print settings (lengths in mm).

    Attributes
    ----------
    material : str
        ``"PLA"``, ``"PETG"`` or ``"TPU"``: picks the defaults below.
    scale : float
        Millimetres per design unit.
    plate_thickness : float
        Height of the rigid plates.
    hinge_style : str
        ``"neck"`` or ``"bridge"`` (see ``HINGE_STYLES``).
    hinge_layers : int
        Bridge thickness in layers (``"bridge"`` style).
    hinge_width : float
        In-plane width of a hinge arm; at least the nozzle width.
    hinge_length : float
        Free length of a hinge between two plates (twice the distance from the joint to where
        a plate starts).
    gap : float
        Smallest distance between two plates (> 0: plates that touch are not a sound solid).
    layer_height, nozzle_width : float
    strain_limit : float
        Bending strain allowed in a hinge (a warning is reported above it).
    rigid_triangles : tuple of (int, int, int) or None
        The rigid triangles; None: every 3-clique of the network.
    preview : bool
        Also make a PNG preview.
    threemf : bool
        Also write a 3MF file (the bed-ready layout: oriented, arranged or split to fit).
    printer : str
        A printer of :data:`fabkit.settings.printers.PRINTERS` (default ``"generic"``, 200 x 200 mm).
    bed : tuple of float or None
        A custom bed (width, depth) in mm, instead of the printer's.
    linkage : str
        ``"hinges"`` or ``"pins"`` (see the module docstring); the fields below are those of a
        print-in-place bar linkage.
    bar_width, bar_thickness : float
        Width and height of every bar (the height a whole number of layers).
    layer_gap : float
        Vertical gap between stacked bars, and between a bar and a cap or collar (whole layers).
    pin_diameter, pin_clearance : float
        The printed pins and the radial gap to the holes they turn in.
    cap_diameter : float
        Caps above the top bar of every pin, and collars on the pin in layers it passes
        without a bar.
    clearance : float
        Least gap between bars, or a bar and a cap, of one layer over the whole motion.
    max_layers : int
        Most layers of bars accepted.
    motion_from, motion_to : float or None
        The part of the design's motion the printed linkage follows (drive values; None: the
        design's start and its ``motion.to``), as for the laser kit
        (:func:`fabkit.motion.window.motion_window`).
    """

    material: str
    scale: float
    plate_thickness: float
    hinge_style: str
    hinge_layers: int
    hinge_width: float
    hinge_length: float
    gap: float
    layer_height: float
    nozzle_width: float
    strain_limit: float
    rigid_triangles: tuple | None = None
    preview: bool = True
    threemf: bool = True
    printer: str = "generic"
    bed: tuple | None = None
    bed_margin: float | None = None
    linkage: str = "hinges"
    bar_width: float = PIN_DEFAULTS["bar_width"]
    bar_thickness: float = PIN_DEFAULTS["bar_thickness"]
    layer_gap: float = PIN_DEFAULTS["layer_gap"]
    pin_diameter: float = PIN_DEFAULTS["pin_diameter"]
    pin_clearance: float = 0.3
    cap_diameter: float = PIN_DEFAULTS["cap_diameter"]
    clearance: float = PIN_DEFAULTS["clearance"]
    max_layers: int = int(PIN_DEFAULTS["max_layers"])
    motion_from: float | None = None
    motion_to: float | None = None

    def printer_profile(self):
        """The :class:`~fabkit.settings.printers.Printer` these settings print on."""
        return printer_profile(self.printer, self.bed, margin=self.bed_margin)

    @property
    def hinge_thickness(self) -> float:
        """Height of the hinge material (mm): ``hinge_layers`` layers for a bridge; for a neck
        the plate thickness less its top layer (the plates' top layer stays free of hinge
        material, which keeps every plate's outline readable from the printed solid)."""
        if self.hinge_style == "neck":
            return self.plate_thickness - self.layer_height
        return self.hinge_layers * self.layer_height

    @property
    def arm_length(self) -> float:
        """Distance from a joint to where a plate starts (half the hinge length)."""
        return 0.5 * self.hinge_length

    @property
    def hole_diameter(self) -> float:
        """Hole a pin turns in: the pin plus twice the radial clearance (mm)."""
        return self.pin_diameter + 2.0 * self.pin_clearance

    @property
    def layer_pitch(self) -> float:
        """Height from one layer of bars to the next: a bar and a gap (mm)."""
        return self.bar_thickness + self.layer_gap

    @property
    def cone_height(self) -> float:
        """Height of the cone under a cap or collar (mm): whole layers, at least the overhang
        ``(cap_diameter - pin_diameter) / 2``, so that it is no flatter than 45 degrees and
        prints without support."""
        rise = 0.5 * (self.cap_diameter - self.pin_diameter)
        return math.ceil(rise / self.layer_height - WHOLE_LAYERS_RTOL) * self.layer_height

    def as_dict(self) -> dict:
        d = asdict(self)
        d["bed"] = list(self.printer_profile().as_dict()["bed_mm"])
        if self.linkage == "pins":
            for key in _HINGE_KEYS + ("hinge_layers",):
                d.pop(key, None)
            d.update(hole_diameter=self.hole_diameter, layer_pitch=self.layer_pitch,
                     cone_height=self.cone_height)
            return d
        for key in _PIN_KEYS:
            d.pop(key)
        d["hinge_thickness"] = self.hinge_thickness
        if d["rigid_triangles"] is not None:
            d["rigid_triangles"] = [list(t) for t in d["rigid_triangles"]]
        return d


def print_settings(table: dict | None = None, overrides: dict | None = None,
                   where: str = "fabrication.print", *, linkage: str = "hinges") -> PrintSettings:
    """Merge a ``[fabrication.print]`` table with overrides over the material's defaults.

    Parameters
    ----------
    table : dict, optional
        The template's ``[fabrication.print]`` table.
    overrides : dict, optional
        Command-line values (same keys) that take precedence over ``table``.
    where : str
        Key path used in messages.
    linkage : str
        The kind of print when the table does not name one (``"hinges"`` or ``"pins"``;
        :func:`default_linkage` chooses it for a design).

    Returns
    -------
    PrintSettings

    Raises
    ------
    SettingsError
        Unknown key or material, a value of the wrong type or out of range (the schema,
        :class:`fabkit.io.schema.PrintSection`).
    FabricationError
        A hinge narrower than the nozzle, a hinge thickness that is not a whole number of
        layers or not thinner than the plates, a bridge setting on a neck-style print; a key
        of the other kind of print; pins, holes, caps and bars that do not fit together.

    Examples
    --------
    >>> s = print_settings({"material": "PLA", "scale": 4.0}, {"gap": 0.3})
    >>> s.gap, s.hinge_thickness
    (0.3, 2.8)
    >>> print_settings({"hinge_style": "bridge", "hinge_thickness": 0.4}).hinge_layers
    2
    """
    merged = {**(table or {}), **(overrides or {})}
    given = check_section("print", merged, where).given()
    linkage = given.get("linkage", linkage)
    other = _PIN_KEYS if linkage == "hinges" else _HINGE_KEYS
    stray = [k for k in other if k in given]
    if stray:  # a key of the other kind would be silently dropped
        raise FabricationError(
            f"{where}.{stray[0]}: applies to linkage = \"{'pins' if linkage == 'hinges' else 'hinges'}\" "
            f"only; this print is linkage = \"{linkage}\"; remove {stray[0]} or set linkage")
    if linkage == "pins":
        return _pin_settings(given, where)
    material = given.get("material", "PLA")
    values = {**MATERIALS[material], "scale": _DEFAULT_SCALE}
    values.update({k: float(v) for k, v in given.items()
                   if k in ("scale", "plate_thickness", "hinge_width", "hinge_length", "gap",
                            "layer_height", "nozzle_width", "strain_limit")})
    style = given.get("hinge_style", values["hinge_style"])
    values["hinge_style"] = style
    layer = values["layer_height"]
    thin = [k for k in ("hinge_thickness", "hinge_layers") if k in given]
    if thin and style != "bridge":
        # a neck's thickness is the plate's less one layer: these would be silently dropped
        raise FabricationError(
            f"{where}.{thin[0]}: applies to hinge_style = \"bridge\" only; this print uses "
            f"\"{style}\" hinges (the {material} default), whose thickness follows the plates; "
            f"set hinge_style = \"bridge\" or remove {thin[0]}")
    if len(thin) == 2:
        raise FabricationError(f"{where}: give hinge_thickness or hinge_layers, not both")
    if "hinge_thickness" in given:
        t = float(given["hinge_thickness"])
        n = round(t / layer)
        if n < 1 or abs(n * layer - t) > WHOLE_LAYERS_RTOL * layer:
            lo, hi = max(1, math.floor(t / layer)), max(1, math.ceil(t / layer))
            raise FabricationError(
                f"{where}.hinge_thickness: {t:g} mm is not a whole number of {layer:g} mm "
                f"layers; use {lo * layer:g} or {hi * layer:g}")
        values["hinge_layers"] = int(n)
    elif "hinge_layers" in given:
        values["hinge_layers"] = int(given["hinge_layers"])
    if values["hinge_width"] < values["nozzle_width"]:
        raise FabricationError(
            f"{where}.hinge_width: {values['hinge_width']:g} mm is thinner than the "
            f"{values['nozzle_width']:g} mm nozzle; a printer cannot lay down that feature")
    if values["plate_thickness"] < 2 * layer - MM_SLACK:
        raise FabricationError(f"{where}.plate_thickness: {values['plate_thickness']:g} mm is "
                               f"less than two {layer:g} mm layers")
    plate_layers = values["plate_thickness"] / layer
    if abs(plate_layers - round(plate_layers)) > WHOLE_LAYERS_RTOL:
        raise FabricationError(
            f"{where}.plate_thickness: {values['plate_thickness']:g} mm is not a whole number "
            f"of {layer:g} mm layers")
    if style == "bridge" and values["hinge_layers"] * layer >= values["plate_thickness"]:
        raise FabricationError(
            f"{where}.hinge_layers: a {values['hinge_layers'] * layer:g} mm bridge is not "
            f"thinner than the {values['plate_thickness']:g} mm plates; use fewer layers")
    triangles = given.get("rigid_triangles")
    if triangles is not None:
        triangles = tuple(tuple(t) for t in triangles)
    flags, _ = _printer_flags(given, where)
    return PrintSettings(material=material, scale=values["scale"],
                         plate_thickness=values["plate_thickness"], hinge_style=style,
                         hinge_layers=int(values["hinge_layers"]),
                         hinge_width=values["hinge_width"], hinge_length=values["hinge_length"],
                         gap=values["gap"], layer_height=layer,
                         nozzle_width=values["nozzle_width"],
                         strain_limit=values["strain_limit"], rigid_triangles=triangles, **flags)


def _printer_flags(given: dict, where: str) -> tuple[dict, object]:
    bed = given.get("bed")
    printer = printer_profile(given.get("printer", DEFAULT_PRINTER), bed, where,
                              margin=given.get("bed_margin"))
    return {"printer": printer.name if bed is None else "custom",
            "bed": None if bed is None else (printer.width, printer.depth),
            "bed_margin": given.get("bed_margin"),
            "preview": given.get("preview", True), "threemf": given.get("threemf", True)}, printer


def _whole_layers(value: float, layer: float, key: str, where: str) -> None:
    n = value / layer
    if round(n) < 1 or abs(n - round(n)) > WHOLE_LAYERS_RTOL:
        lo, hi = max(1, math.floor(n)), max(1, math.ceil(n))
        raise FabricationError(f"{where}.{key}: {value:g} mm is not a whole number of {layer:g} mm "
                               f"layers; use {lo * layer:g} or {hi * layer:g}")


def _optional(value) -> float | None:
    return None if value is None else float(value)


def _pin_settings(given: dict, where: str) -> PrintSettings:
    """Settings of a print-in-place bar linkage (``linkage = "pins"``), checked together."""
    material = given.get("material", "PLA")
    base = MATERIALS[material]
    values = {**PIN_DEFAULTS, "layer_height": base["layer_height"],
              "nozzle_width": base["nozzle_width"]}
    values.update({k: v for k, v in given.items() if k in values})
    flags, printer = _printer_flags(given, where)
    values["pin_clearance"] = float(given.get("pin_clearance", printer.pin_clearance))
    layer, nozzle = float(values["layer_height"]), float(values["nozzle_width"])
    for key in ("bar_thickness", "layer_gap"):
        _whole_layers(float(values[key]), layer, key, where)
    pin, cap, width = (float(values[k]) for k in ("pin_diameter", "cap_diameter", "bar_width"))
    hole = pin + 2.0 * values["pin_clearance"]
    if values["pin_clearance"] < MIN_PIN_CLEARANCE - MM_SLACK:
        raise FabricationError(f"{where}.pin_clearance: a {values['pin_clearance']:g} mm gap "
                               "between pin and hole is below what an extruded wall keeps "
                               f"(about {MIN_PIN_CLEARANCE:g} mm): the pin prints fused to its "
                               f"hole; use >= {MIN_PIN_CLEARANCE:g} mm (0.3-0.4 mm parts "
                               "reliably)")
    if pin < 3.0 * nozzle - MM_SLACK:
        raise FabricationError(f"{where}.pin_diameter: a {pin:g} mm pin is less than three "
                               f"{nozzle:g} mm nozzle widths and prints as a blob, not a round "
                               f"pin; use >= {3 * nozzle:g} mm")
    if width - hole < 4.0 * nozzle - MM_SLACK:
        raise FabricationError(
            f"{where}.bar_width: a {width:g} mm bar around a {hole:g} mm hole (pin "
            f"{pin:g} + 2 x {values['pin_clearance']:g} clearance) leaves less than two "
            f"{nozzle:g} mm perimeters of web on each side; use bar_width >= "
            f"{hole + 4 * nozzle:g} mm or a thinner pin")
    if cap < hole + 2.0 * nozzle - MM_SLACK:
        raise FabricationError(
            f"{where}.cap_diameter: a {cap:g} mm cap overlaps the {hole:g} mm hole by less than "
            f"one {nozzle:g} mm nozzle width on each side and would not hold the bars; use "
            f">= {hole + 2 * nozzle:g} mm")
    if cap > width + MM_SLACK:
        raise FabricationError(f"{where}.cap_diameter: a {cap:g} mm cap is wider than the "
                               f"{width:g} mm bars; use <= {width:g} mm")
    s = PrintSettings(material=material, scale=float(values["scale"]),
                      plate_thickness=base["plate_thickness"], hinge_style=base["hinge_style"],
                      hinge_layers=base["hinge_layers"], hinge_width=base["hinge_width"],
                      hinge_length=base["hinge_length"], gap=base["gap"], layer_height=layer,
                      nozzle_width=nozzle, strain_limit=base["strain_limit"], linkage="pins",
                      bar_width=width, bar_thickness=float(values["bar_thickness"]),
                      layer_gap=float(values["layer_gap"]), pin_diameter=pin,
                      pin_clearance=float(values["pin_clearance"]), cap_diameter=cap,
                      clearance=float(values["clearance"]),
                      max_layers=int(values["max_layers"]),
                      motion_from=_optional(given.get("motion_from")),
                      motion_to=_optional(given.get("motion_to")), **flags)
    if s.cone_height > s.bar_thickness + MM_SLACK:
        raise FabricationError(
            f"{where}.cap_diameter: the 45-degree cone under a {cap:g} mm collar on a {pin:g} mm "
            f"pin is {s.cone_height:g} mm tall, more than the {s.bar_thickness:g} mm layer it "
            "must fit in; use a smaller cap_diameter or thicker bars")
    return s


def default_linkage(network) -> str:
    """``"hinges"`` for a planar network made of rigid triangles, else ``"pins"``."""
    try:
        rigid_triangles(network)
    except FabricationError:
        return "pins"
    return "hinges"


def design_print_settings(design, settings: dict | None = None):
    """The design's :class:`~fabkit.settings.printing.PrintSettings` with ``settings["print"]``
    overrides (a template's table, then the command line); the kind of print is the table's
    ``linkage``, else :func:`default_linkage` of the design's network."""
    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    table, overrides = fab.get("print", {}), section_of(settings, "print")
    named = {**(table if isinstance(table, dict) else {}), **overrides}.get("linkage")
    linkage = named if named is not None else default_linkage(design.network)
    return print_settings(table, overrides, linkage=linkage)
