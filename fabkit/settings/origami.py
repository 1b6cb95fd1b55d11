"""Origami settings: the template's ``[fabrication.origami]`` table merged with overrides.

Types and ranges are declared in :class:`fabkit.io.schema.OrigamiSection`; here the defaults
are filled in and the sheet's size becomes a scale (mm per design unit), measured once on the
flat sheet: every origami writer and the tolerance analysis read that one number.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..errors import FabricationError, SettingsError
from ..io.schema import check_section
from ..io.workload import require
from ..model.flat import flat_coords, point_diameter

__all__ = ["OrigamiSettings", "origami_settings", "design_where"]


@dataclass(frozen=True)
class OrigamiSettings:
    """Resolved origami settings (mm unless said otherwise).

    Attributes
    ----------
    scale : float
        mm per design unit: ``sheet_size`` over the flat sheet's extent corner to corner (its
        diameter, the same however the sheet is drawn or turned; for a chain of sheets, the
        sheet template's).
    sheet_size : float
        Largest extent of one sheet's flat pattern, corner to corner (default 150 mm).
    samples : int
        Configurations of the simulated folding (default 41).
    branch : str or int
        ``"assignment"`` (the branch out of the flat state the crease assignment names) or a
        branch number.
    sign : int or None
        Direction along the branch (1 or -1; None: chosen by the assignment).
    spacing : str
        ``"uniform"`` or ``"geometric"`` spacing of the samples.
    step_off : float
        Step off the flat state (fraction).
    relay : str or None
        Port that takes over the drive.
    medium : str or None
        Page the sheets of a chain are laid out on (None: A4).
    perforation_dash, perforation_gap, perforation_stop : float or None
        The cut-ready sheet's perforation (None: the defaults of
        :data:`fabkit.fab.creases.perforation.PERFORATION`).
    assignment : tuple of str or None
        One of B/M/V/F/U/C per network edge (a single sheet).
    faces : tuple of tuple of int or None
        Faces as node cycles (None: found from the flat pattern).
    sheet : str or None
        Template of one sheet (a chain of sheets).
    sheets : tuple of tuple of int or None
        Per sheet of a chain, the network node of each of its vertices.
    """

    scale: float
    sheet_size: float = 150.0
    samples: int = 41
    branch: str | int = "assignment"
    sign: int | None = None
    spacing: str = "uniform"
    step_off: float = 1e-3
    relay: str | None = None
    medium: str | None = None
    perforation_dash: float | None = None
    perforation_gap: float | None = None
    perforation_stop: float | None = None
    assignment: tuple | None = None
    faces: tuple | None = None
    sheet: str | None = None
    sheets: tuple | None = None

    @property
    def chain(self) -> bool:
        """A chain of sheets (``sheets`` given), not a single sheet."""
        return self.sheets is not None


def design_where(design) -> str:
    """The template file (or the design's name) for error messages."""
    return str(design.path) if getattr(design, "path", None) else design.name


def _err(where, key, reason) -> FabricationError:
    return FabricationError(f"{where}: fabrication.origami.{key}: {reason}")


def _nested(value):
    """Lists of lists (as TOML gives them) as tuples of tuples."""
    if value is None:
        return None
    return tuple(tuple(v) if isinstance(v, list) else v for v in value)


def _flat_sheet(design):
    """The flat pattern's coordinates of a single-sheet design."""
    net = design.network
    if net.dim != 3:
        raise FabricationError(f"{design_where(design)}: origami needs a 3D network (nodes with "
                               "x, y, z)")
    flat = flat_coords(net.nodes, net.edges)
    if flat is None:
        raise FabricationError(f"{design_where(design)}: the network of a single sheet must be "
                               "given flat (all nodes in one plane)")
    return flat


def _sheet_design(design, given: dict):
    """The template of one sheet of a chain, as loaded with the design."""
    where = design_where(design)
    if not isinstance(given.get("sheet"), str):
        raise _err(where, "sheet", "a design with `sheets` needs `sheet`: the template of one "
                                   "sheet")
    sheet = design.references.get("fabrication.origami.sheet")
    if sheet is None:
        raise _err(where, "sheet", "the sheet template was not loaded with the design (load the "
                                   "design with fabkit.load_template)")
    return sheet


def origami_settings(design, overrides: dict | None = None) -> OrigamiSettings:
    """Resolve a design's ``[fabrication.origami]`` table with overrides (overrides win).

    Parameters
    ----------
    design : Design
        A loaded template (the flat sheet gives the scale; a chain's sheet template is in
        ``design.references``).
    overrides : dict, optional
        The ``origami`` section of the command line's settings.

    Returns
    -------
    OrigamiSettings

    Raises
    ------
    SettingsError
        A key of the wrong type or out of range (the schema), naming the template.
    BoundsError
        More samples than can be folded in reasonable time and memory.
    FabricationError
        No ``[fabrication.origami]`` table, a network that is not a flat 3D sheet, a chain
        without its sheet template.
    """
    where = design_where(design)
    fab = design.fabrication.get("origami") if isinstance(design.fabrication, dict) else None
    if not isinstance(fab, dict):
        raise FabricationError(f"{where}: the template has no [fabrication.origami] table")
    try:
        given = check_section("origami", {**fab, **(overrides or {})}).given()
    except SettingsError as exc:  # name the template, as the other origami errors do
        raise SettingsError(f"{where}: {exc.key}", exc.reason, exc.kind) from None
    values = {k: v for k, v in given.items() if v is not None}
    for key in ("assignment",):
        if key in values:
            values[key] = tuple(values[key])
    for key in ("faces", "sheets"):
        if key in given:
            values[key] = _nested(given[key]) if given[key] is not None else ()
    s = OrigamiSettings(scale=1.0, **values)
    # every sample of the folding is a configuration of the whole network
    require(f"{where}: fabrication.origami.samples", ("origami sample node",
                                                      s.samples * design.network.n_nodes))
    if design.network.dim != 3:
        raise FabricationError(f"{where}: origami needs a 3D network (nodes with x, y, z)")
    flat = _flat_sheet(_sheet_design(design, given) if s.chain else design)
    return replace(s, scale=float(s.sheet_size) / point_diameter(flat))
