"""Print settings for triangle-hinge networks: the ``[fabrication.print]`` table.

A template's ``[fabrication.print]`` table is merged with command-line overrides (``--set
print.gap=0.3``) over the defaults of the chosen material. Every value is checked here, once, and
a bad one raises a :class:`~fabkit.errors.FabricationError` whose message is one line naming the
key, the value and what to do.

All lengths are in millimetres except ``scale`` (millimetres per design unit).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from ..errors import FabricationError
from ..numerics import MM_SLACK
from ..schema import HINGE_STYLES, check_section, section_of

__all__ = ["PrintSettings", "MATERIALS", "HINGE_STYLES", "print_settings", "design_print_settings"]

# Hinge styles (HINGE_STYLES, declared in fabkit.schema). "neck": a narrow neck as tall as the
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
        A printer of :data:`fabkit.fab.printers.PRINTERS` (default ``"generic"``, 200 x 200 mm).
    bed : tuple of float or None
        A custom bed (width, depth) in mm, instead of the printer's.
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

    def printer_profile(self):
        """The :class:`~fabkit.fab.printers.Printer` these settings print on."""
        from .printers import printer_profile

        return printer_profile(self.printer, self.bed)

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

    def as_dict(self) -> dict:
        d = asdict(self)
        d["hinge_thickness"] = self.hinge_thickness
        d["bed"] = list(self.printer_profile().as_dict()["bed_mm"])
        if d["rigid_triangles"] is not None:
            d["rigid_triangles"] = [list(t) for t in d["rigid_triangles"]]
        return d


def print_settings(table: dict | None = None, overrides: dict | None = None,
                   where: str = "fabrication.print") -> PrintSettings:
    """Merge a ``[fabrication.print]`` table with overrides over the material's defaults.

    Parameters
    ----------
    table : dict, optional
        The template's ``[fabrication.print]`` table.
    overrides : dict, optional
        Command-line values (same keys) that take precedence over ``table``.
    where : str
        Key path used in messages.

    Returns
    -------
    PrintSettings

    Raises
    ------
    SettingsError
        Unknown key or material, a value of the wrong type or out of range (the schema,
        :class:`fabkit.schema.PrintSection`).
    FabricationError
        A hinge narrower than the nozzle, a hinge thickness that is not a whole number of
        layers or not thinner than the plates, a bridge setting on a neck-style print.

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
    from .printers import DEFAULT_PRINTER, printer_profile

    bed = given.get("bed")
    printer = printer_profile(given.get("printer", DEFAULT_PRINTER), bed, where)
    flags = {"printer": printer.name if bed is None else "custom",
             "bed": None if bed is None else (printer.width, printer.depth),
             "preview": given.get("preview", True), "threemf": given.get("threemf", True)}
    return PrintSettings(material=material, scale=values["scale"],
                         plate_thickness=values["plate_thickness"], hinge_style=style,
                         hinge_layers=int(values["hinge_layers"]),
                         hinge_width=values["hinge_width"], hinge_length=values["hinge_length"],
                         gap=values["gap"], layer_height=layer,
                         nozzle_width=values["nozzle_width"],
                         strain_limit=values["strain_limit"], rigid_triangles=triangles, **flags)


def design_print_settings(design, settings: dict | None = None):
    """The design's :class:`~fabkit.fab.printing.PrintSettings` with ``settings["print"]``
    overrides (a template's table, then the command line)."""
    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    return print_settings(fab.get("print", {}), section_of(settings, "print"))
