"""One declared schema for every setting a user gives fabkit.

Templates (``[fabrication.laser]``, ``[fabrication.print]``, ``[fabrication.origami]``,
``[fabrication.tolerance]``, ``[fabrication] skip``, ``[motion] options``), ``--set
SECTION.KEY=VALUE`` on the command line and the keyword arguments of the Python API all pass
through the models declared here (pydantic, strict): unknown sections and keys are refused with
the known ones listed, types are strict (``"no"`` is not a boolean, ``2.5`` is not a whole
number, ``nan`` and ``inf`` are not lengths) and every range is stated once, beside its key.

What the schema cannot know stays with the stage that knows it and is checked there before
work: whether two settings agree (a hole and a bar width), whether a setting applies to the
chosen material or style, whether a printer or a screw is in its catalogue.

Every failure is one :class:`~fabkit.errors.SettingsError` (a ``ValueError`` too) that names the
key path and says why: ``fabrication.laser.min_web: must be >= 0, got -5``.

Examples
--------
>>> check_section("laser", {"kerf": 0.2}).kerf
0.2
>>> check_settings({"lasre": {"kerf": 0.2}})
Traceback (most recent call last):
...
fabkit.errors.SettingsError: lasre: unknown section; known: laser, motion, origami, print, tolerance; did you mean 'laser'?
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Optional, Union

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError

from ..errors import SettingsError, UsageError
from .suggest import did_you_mean

__all__ = ["Section", "LaserSection", "ScrewSection", "PrintSection", "OrigamiSection",
           "ToleranceSection", "MotionSection", "FABRICATION_SECTIONS", "OVERRIDE_SECTIONS",
           "METHOD_OPTIONS", "check_section", "check_table", "check_fabrication", "section_of",
           "check_settings", "check_method_options", "check_motion_ends", "describe_keys",
           "refuse_unused",
           "describe_validation_error", "LASER_FLAVOURS", "LASER_LABELS", "REFERENCE_SQUARES",
           "MATERIAL_NAMES", "HINGE_STYLES", "PRINT_LINKAGES", "ORIGAMI_SPACINGS"]

LASER_FLAVOURS = ("lwpolyline", "line-arc")
LASER_LABELS = ("text", "outlines", "none")
REFERENCE_SQUARES = ("engrave", "cut", "none")
MATERIAL_NAMES = ("PLA", "PETG", "TPU")
HINGE_STYLES = ("neck", "bridge")
#: How a printed network is built: ``"hinges"``, rigid triangles joined by thin hinges in one
#: solid; ``"pins"``, bars stacked in layers on printed pins, one body per bar (print in place).
PRINT_LINKAGES = ("hinges", "pins")
ORIGAMI_SPACINGS = ("uniform", "geometric")
PROCESS_NAMES = ("laser", "print", "origami")

#: Largest sample count of a sampled motion or folding (each sample is one configuration).
MAX_SAMPLES_SETTING = 1_000_000


class Section(BaseModel):
    """A table of settings: unknown keys refused, strict types, no NaN or infinity."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)

    def given(self) -> dict:
        """The settings that were given (not the defaults), as plain values."""
        return self.model_dump(exclude_unset=True)


def _mm(doc: str, *, ge: float | None = None, gt: float | None = None,
        le: float | None = None) -> Any:
    return Field(None, description=doc, ge=ge, gt=gt, le=le)


# --- laser ------------------------------------------------------------------------------------

class ScrewSection(Section):
    """``laser.screw`` as a table: a catalogue entry with some sizes changed, or a screw of
    one's own (then every size must be given)."""

    name: Optional[str] = _mm("catalogue entry the other sizes start from")
    barrel_diameter: Optional[float] = _mm("outer diameter of the barrel (mm)", gt=0)
    hole_diameter: Optional[float] = _mm("running hole cut in every bar (mm)", gt=0)
    head_diameter: Optional[float] = _mm("head diameter (mm)", gt=0)
    head_height: Optional[float] = _mm("head height (mm)", gt=0)
    lengths: Optional[list[Annotated[float, Field(gt=0)]]] = Field(
        None, min_length=1, description="post lengths sold (mm)")
    allowance: Optional[float] = _mm("axial play added before choosing a length (mm)", ge=0)


class LaserSection(Section):
    """``[fabrication.laser]``: laser-cut acrylic (lengths in mm)."""

    scale: Optional[float] = _mm("mm per design unit", gt=0)
    size: Optional[float] = _mm("largest extent of the network in mm (instead of scale)", gt=0)
    bar_width: Optional[float] = _mm("width of every bar", gt=0)
    thickness: Optional[float] = _mm("measured sheet thickness", gt=0)
    thickness_tolerance: Optional[float] = _mm("how far one sheet may differ", ge=0)
    kerf: Optional[float] = _mm("width the laser burns away (0: the service compensates)", ge=0)
    min_web: Optional[float] = _mm("least material between a hole and an edge", ge=0)
    clearance: Optional[float] = _mm("least gap between bars of one layer over the motion", gt=0,
                                     le=50)
    sheet_width: Optional[float] = _mm("sheet width", gt=0)
    sheet_height: Optional[float] = _mm("sheet height", gt=0)
    spacing: Optional[float] = _mm("gap between parts on a sheet", ge=0)
    margin: Optional[float] = _mm("border kept free on a sheet", ge=0)
    screw: Optional[Union[str, ScrewSection]] = Field(
        None, description="Chicago screw: a catalogue name or a table of sizes")
    spacer_diameter: Optional[float] = _mm("outer diameter of spacer rings", gt=0)
    flavour: Optional[Literal[LASER_FLAVOURS]] = Field(None, description="DXF outline entities")
    labels: Optional[Literal[LASER_LABELS]] = Field(None, description="part labels")
    label_height: Optional[float] = _mm("largest label height", gt=0)
    reference_square: Optional[Literal[REFERENCE_SQUARES]] = Field(
        None, description="100 mm square on the first sheet")
    max_layers: Optional[int] = Field(None, ge=1, description="most stacking layers accepted")
    motion_from: Optional[float] = _mm("drive value where the kit's motion starts (a state "
                                       "along the design's motion; default: its start)", gt=0)
    motion_to: Optional[float] = _mm("drive value where the kit's motion ends (default: "
                                     "motion.to)", gt=0)
    uncompensated: Optional[bool] = Field(
        None, description="also write the sheets drawn at true size (kerf not applied), for a "
                          "cutting service that compensates kerf itself")


# --- print ------------------------------------------------------------------------------------

def _upper(value):
    return value.upper() if isinstance(value, str) else value


class PrintSection(Section):
    """``[fabrication.print]``: 3D-printed networks (lengths in mm): triangle-hinge solids, or
    bar linkages printed in place on pins."""

    linkage: Optional[Literal[PRINT_LINKAGES]] = Field(
        None, description="hinges (rigid triangles joined by thin hinges, one solid) or pins "
                          "(bars in layers on printed pins, one body per bar); default: hinges "
                          "for a network made of triangles, else pins")

    material: Optional[Annotated[Literal[MATERIAL_NAMES], BeforeValidator(_upper)]] = Field(
        None, description="PLA, PETG or TPU (any case)")
    scale: Optional[float] = _mm("mm per design unit", gt=0)
    plate_thickness: Optional[float] = _mm("height of the rigid plates", gt=0)
    hinge_style: Optional[Literal[HINGE_STYLES]] = Field(None, description="neck or bridge")
    hinge_layers: Optional[int] = Field(None, ge=1, description="bridge thickness in layers "
                                                                "(bridge style only)")
    hinge_thickness: Optional[float] = _mm("bridge thickness (bridge style only)", gt=0)
    hinge_width: Optional[float] = _mm("in-plane width of a hinge arm", gt=0)
    hinge_length: Optional[float] = _mm("free length of a hinge", gt=0)
    gap: Optional[float] = _mm("smallest distance between two plates; plates that touch fuse "
                               "into a solid that is not watertight and cannot move: use "
                               "0.3-0.5", gt=0)
    layer_height: Optional[float] = _mm("print layer height", gt=0)
    nozzle_width: Optional[float] = _mm("nozzle width", gt=0)
    strain_limit: Optional[float] = Field(None, gt=0, le=1,
                                          description="bending strain allowed in a hinge")
    rigid_triangles: Optional[list[Annotated[list[Annotated[int, Field(ge=0)]],
                                             Field(min_length=3, max_length=3)]]] = Field(
        None, min_length=1, description="the rigid triangles as node-index triples")
    preview: Optional[bool] = Field(None, description="also make a PNG preview")
    threemf: Optional[bool] = Field(None, description="also write a 3MF file")
    printer: Optional[str] = Field(None, description="a printer of the catalogue")
    bed: Optional[Annotated[list[Annotated[float, Field(gt=0)]],
                            Field(min_length=2, max_length=2)]] = Field(
        None, description="a custom bed, width and depth (mm)")
    bed_margin: Optional[float] = _mm("kept free along every edge of the bed for the slicer's "
                                      "skirt, brim and support (default 10)", ge=0, le=100)
    # print-in-place bar linkages (linkage = "pins")
    bar_width: Optional[float] = _mm("width of every printed bar (pins)", gt=0, le=100)
    bar_thickness: Optional[float] = _mm("height of every printed bar, whole layers (pins)",
                                         gt=0, le=20)
    layer_gap: Optional[float] = _mm("vertical gap between stacked bars, and between a bar and "
                                     "a pin's cap or collar, whole layers (pins); 0.3-0.5 keeps "
                                     "the layers from fusing", gt=0, le=5)
    pin_diameter: Optional[float] = _mm("diameter of the printed pins (pins)", gt=0, le=50)
    pin_clearance: Optional[float] = _mm("radial clearance between a pin and the holes it turns "
                                         "in (pins); default: the printer's", gt=0, le=2)
    cap_diameter: Optional[float] = _mm("diameter of the caps that keep the bars on a pin, and "
                                        "of the collars that keep empty layers free (pins)",
                                        gt=0, le=100)
    clearance: Optional[float] = _mm("least gap between bars (or a bar and a cap) of one layer "
                                     "over the whole motion (pins)", gt=0, le=50)
    max_layers: Optional[int] = Field(None, ge=1, le=64,
                                      description="most layers of bars accepted (pins)")
    motion_from: Optional[float] = Field(
        None, gt=0, description="drive value where the printed linkage's motion starts (a "
                                "state along the design's motion; default: its start) (pins)")
    motion_to: Optional[float] = Field(
        None, gt=0, description="drive value where the printed linkage's motion ends "
                                "(default: motion.to) (pins)")


# --- origami ----------------------------------------------------------------------------------

class OrigamiSection(Section):
    """``[fabrication.origami]``: crease patterns and their folding."""

    assignment: Optional[list[Literal["B", "M", "V", "F", "U", "C"]]] = Field(
        None, description="one of B/M/V/F/U/C per network edge")
    faces: Optional[list[list[Annotated[int, Field(ge=0)]]]] = Field(
        None, description="faces as node cycles")
    sheet_size: Optional[float] = _mm("largest extent of a sheet's flat pattern, corner to corner (mm)",
                                      gt=0)
    samples: Optional[int] = Field(None, ge=2, le=MAX_SAMPLES_SETTING,
                                   description="configurations of the simulated folding")
    branch: Optional[Union[Literal["assignment"], Annotated[int, Field(ge=1)]]] = Field(
        None, description="'assignment' or a branch number (>= 1)")
    sign: Optional[Literal[1, -1]] = Field(None, description="direction along the branch")
    sheet: Optional[str] = Field(None, description="template of one sheet (chains of sheets)")
    sheets: Optional[list[list[Annotated[int, Field(ge=0)]]]] = Field(
        None, description="per sheet, the network node of each of its vertices")
    spacing: Optional[Literal[ORIGAMI_SPACINGS]] = Field(None, description="spacing of the "
                                                                           "samples")
    step_off: Optional[float] = Field(None, gt=0, le=0.1, description="step off the flat "
                                                                      "state (fraction)")
    relay: Optional[str] = Field(None, description="port that takes over the drive")
    medium: Optional[str] = Field(None, description="page the sheets of a chain are laid out "
                                                    "on: A4 (default), A3, Letter, Legal or "
                                                    "WIDTHxHEIGHT in mm")
    perforation_dash: Optional[float] = _mm("cut-ready sheet: length of each perforation cut "
                                            "along a crease (mm)", gt=0)
    perforation_gap: Optional[float] = _mm("cut-ready sheet: paper left between two cuts (mm)",
                                           gt=0)
    perforation_stop: Optional[float] = _mm("cut-ready sheet: paper left whole at each end of "
                                            "a crease, so the sheet holds together (mm)", gt=0)


# --- tolerance --------------------------------------------------------------------------------

class ToleranceSection(Section):
    """``[fabrication.tolerance]``: the Monte Carlo of manufacturing errors (mm at the
    process's own scale)."""

    process: Optional[Literal[PROCESS_NAMES]] = Field(None, description="laser, print or "
                                                                        "origami")
    scale: Optional[float] = _mm("mm per design unit", gt=0)
    length_sigma: Optional[float] = _mm("bar-length error (laser)", ge=0)
    kerf_sigma: Optional[float] = _mm("kerf error (laser)", ge=0)
    hole_clearance: Optional[float] = _mm("hole play (laser)", ge=0)
    thickness: Optional[float] = _mm("sheet thickness (laser)", gt=0)
    thickness_sigma: Optional[float] = _mm("sheet thickness error (laser)", ge=0)
    bar_width: Optional[float] = _mm("bar width (laser): the bars' section", gt=0)
    xy_sigma: Optional[float] = _mm("xy accuracy (print)", ge=0)
    shrinkage: Optional[float] = Field(None, ge=0, le=1, description="shrinkage (print)")
    shrinkage_sigma: Optional[float] = _mm("shrinkage spread (print)", ge=0)
    line_width_sigma: Optional[float] = _mm("line width error (print)", ge=0)
    hinge_length: Optional[float] = _mm("hinge length (print)", ge=0)
    crease_sigma: Optional[float] = _mm("crease position error (origami)", ge=0)
    cut_sigma: Optional[float] = _mm("cut error (origami)", ge=0)
    paper_thickness: Optional[float] = _mm("paper thickness (origami)", ge=0)
    compliance_sigma: Optional[float] = _mm("crease compliance (origami)", ge=0)
    limit: Optional[float] = _mm("allowed 95th-percentile port error (mm)", gt=0)
    limit_fraction: Optional[float] = Field(None, gt=0, description="default limit as a "
                                                                    "fraction of the module")
    min_reached: Optional[float] = Field(None, ge=0, le=1, description="fraction of builds "
                                                                       "that must reach")
    state_fraction: Optional[float] = Field(None, gt=0, le=1, description="how near a built "
                                            "state must stay to the designed one, as a fraction "
                                            "of the module's travel between its states")
    samples: Optional[int] = Field(None, ge=1, description="simulated builds")
    seed: Optional[int] = Field(None, ge=0, lt=2**63, description="random seed")


# --- motion -----------------------------------------------------------------------------------

class MotionSection(Section):
    """``--set motion.KEY=VALUE``: the template's ``[motion]``, changed for one run."""

    to: Optional[float] = _mm("target value of the drive", gt=0)
    drive: Optional[str] = Field(None, description="port whose distance is driven")
    method: Optional[Literal["auto", "constructive", "projected", "rk4-nullspace",
                             "branch"]] = Field(None, description="tracing method")


class _ProjectedOptions(Section):
    step: Optional[float] = Field(None, gt=0)
    max_step: Optional[float] = Field(None, gt=0)
    max_node_step: Optional[float] = Field(None, gt=0)
    min_step: Optional[float] = Field(None, gt=0)
    tol: Optional[float] = Field(None, gt=0, lt=1)
    max_steps: Optional[int] = Field(None, ge=1)
    contraction: Optional[float] = Field(None, gt=0, lt=1)
    max_angle: Optional[float] = Field(None, gt=0, le=90)
    detect_branch_points: Optional[bool] = None
    redundant_rtol: Optional[float] = Field(None, gt=0, lt=1)


class _ConstructiveOptions(Section):
    samples: Optional[int] = Field(None, ge=2, le=MAX_SAMPLES_SETTING)


class _RK4Options(Section):
    step: Optional[float] = Field(None, gt=0)
    max_steps: Optional[int] = Field(None, ge=1)


class _BranchOptions(Section):
    branch: Optional[int] = Field(None, ge=1)
    sign: Optional[Literal[1, -1]] = None
    step_off: Optional[float] = Field(None, gt=0, le=0.1)
    then: Optional[Literal["auto", "constructive", "projected", "rk4-nullspace"]] = None
    samples: Optional[int] = Field(None, ge=2, le=MAX_SAMPLES_SETTING)


#: Declared options of the built-in tracing methods (``[motion] options``).
METHOD_OPTIONS: dict[str, type[Section]] = {
    "projected": _ProjectedOptions,
    "constructive": _ConstructiveOptions,
    "rk4-nullspace": _RK4Options,
    "branch": _BranchOptions,
}

#: The tables of ``[fabrication]``, by name (``skip`` is a table of format → reason).
FABRICATION_SECTIONS: dict[str, type[Section]] = {
    "laser": LaserSection,
    "print": PrintSection,
    "origami": OrigamiSection,
    "tolerance": ToleranceSection,
}

#: The sections ``--set`` and the API's keyword arguments may change.
OVERRIDE_SECTIONS: dict[str, type[Section]] = {**FABRICATION_SECTIONS, "motion": MotionSection}


# --- checking ---------------------------------------------------------------------------------

def check_section(name: str, table, where: str | None = None) -> Section:
    """Validate one table of settings against its model.

    Parameters
    ----------
    name : str
        A key of :data:`OVERRIDE_SECTIONS` (``"laser"``, ``"motion"``, ...).
    table : dict
    where : str, optional
        Key path of the table for messages (default ``fabrication.<name>``).

    Returns
    -------
    Section
        The validated table; :meth:`Section.given` gives back what was set.

    Raises
    ------
    SettingsError
    """
    where = where or (name if name == "motion" else f"fabrication.{name}")
    return check_table(OVERRIDE_SECTIONS[name], table, where)


def check_table(model: type[Section], table, where: str) -> Section:
    """Validate ``table`` against ``model``; :class:`SettingsError` naming ``where`` and the key."""
    if not isinstance(table, dict):
        raise SettingsError(where, f"must be a table, got {_describe(table)}")
    try:
        return model.model_validate(table)
    except ValidationError as exc:
        raise _settings_error(exc, where, model) from None


def check_fabrication(table, where: str = "fabrication") -> dict:
    """Validate a template's whole ``[fabrication]`` table: known sections only, each
    against its model, ``skip`` a table of format → reason. Returns the table unchanged."""
    if not isinstance(table, dict):
        raise SettingsError(where, f"must be a table, got {_describe(table)}")
    known = sorted([*FABRICATION_SECTIONS, "skip"])
    for key, value in table.items():
        if key == "skip":
            if not isinstance(value, dict) or not all(
                    isinstance(k, str) and isinstance(v, str) and v.strip()
                    for k, v in value.items()):
                raise SettingsError(f"{where}.skip", "must be a table of format = \"reason\", "
                                                     "e.g. skip = { dxf = \"why\" }")
            continue
        if key not in FABRICATION_SECTIONS:
            raise SettingsError(f"{where}.{key}", f"unknown section; known: {', '.join(known)}"
                                                  + _hint(key, known))
        check_section(key, value, f"{where}.{key}")
    return table


def check_settings(settings, where: str = "", sections: dict | None = None) -> dict:
    """Validate overrides nested by section (``{"laser": {"kerf": 0.2}}``), as ``--set`` and
    the API's keyword arguments give them. Returns them unchanged.

    ``sections`` adds sections declared elsewhere (name → :class:`Section` model): an export
    format of one's own declares its settings as ``SETTINGS`` in its module (see
    :func:`fabkit.writers.check_export_settings`).

    Raises
    ------
    SettingsError
        An unknown section (``lasre``), a value that is not a table, or a bad key or value.
    """
    if settings is None:
        return {}
    if not isinstance(settings, dict):
        raise SettingsError(where, f"must be settings nested by section, got "
                                   f"{_describe(settings)}")
    known = {**OVERRIDE_SECTIONS, **(sections or {})}
    for key, value in settings.items():
        full = f"{where}.{key}" if where else key
        if key not in known:
            raise SettingsError(full, f"unknown section; known: {', '.join(sorted(known))}"
                                      + _hint(key, known))
        check_table(known[key], value, full)
    return settings


def refuse_unused(settings, used, why: str) -> None:
    """Refuse settings that nothing in this run reads, so that none is accepted without effect.

    The one rule for every command that takes ``--set``: a section that no stage of the run
    reads (``print`` when only DXF is made, ``laser`` for a design analysed as origami) is
    refused in one line (exit status 2), as a key of another process is.

    Parameters
    ----------
    settings : dict
        Overrides nested by section.
    used : collection of str
        The sections the run reads.
    why : str
        What the run reads, for the message (``"this export makes dxf, which reads laser"``).

    Raises
    ------
    UsageError
    """
    for section, table in (settings or {}).items():
        if section in used:
            continue
        keys = ", ".join(f"{section}.{k}" for k in table) if isinstance(table, dict) and table \
            else section
        raise UsageError("--set", f"{keys}: {section} settings have no effect here: {why}; "
                                  "remove them")


def _hint(name, known) -> str:
    """``"; did you mean 'kerf'?"`` for a misspelt section or key, else ``""``."""
    hint = did_you_mean(name, sorted(known))
    return f"; {hint}" if hint else ""


def section_of(settings, name: str) -> dict:
    """The ``name`` section of settings nested by section, checked against its model (the other
    sections are left to the stages that read them); ``{}`` when it is not given."""
    if settings is None:
        return {}
    if not isinstance(settings, dict):
        raise SettingsError("", f"settings must be nested by section, got {_describe(settings)}")
    table = settings.get(name)
    if table is None:
        return {}
    check_section(name, table, name)
    return dict(table)


def check_method_options(method: str, options, where: str = "motion.options") -> dict:
    """Validate a tracing method's options (``[motion] options``) with strict types.

    ``method`` ``"auto"`` accepts the options of ``constructive`` and ``projected`` (it picks
    one of them); a method of one's own (not declared here) is left to the method itself.
    """
    if not isinstance(options, dict):
        raise SettingsError(where, f"must be a table, got {_describe(options)}", kind="type")
    if method == "auto":
        names = ("constructive", "projected")
    elif method in METHOD_OPTIONS:
        names = (method,)
    else:
        return options
    fields = {f: m for m in names for f in METHOD_OPTIONS[m].model_fields}
    for key, value in options.items():
        if key not in fields:
            raise SettingsError(f"{where}.{key}", f"unknown option of the {method} method; "
                                                  f"known: {', '.join(sorted(fields))}",
                                kind="unknown")
        model = METHOD_OPTIONS[fields[key]]
        try:
            model.model_validate({key: value})
        except ValidationError as exc:
            raise _settings_error(exc, where, model) from None
    return options


class _PortEnd(Section):
    """One designed end value of a port (design units)."""

    value: float = Field(gt=0, description="distance the port is designed to end at")


def check_motion_ends(ends, ports, where: str = "motion.ends") -> dict:
    """Validate ``[motion] ends``: designed end values of ports, ``{ d2 = 1.3, d3 = 1.25 }``.

    Parameters
    ----------
    ends : object
        The table as read from the template.
    ports : iterable of str
        The network's ports (a key must name one).

    Returns
    -------
    dict of str to float

    Raises
    ------
    SettingsError
        Not a table, a key that is not a port, a value that is not a positive finite number.
    """
    if not isinstance(ends, dict):
        raise SettingsError(where, f"must be a table of port = distance, got {_describe(ends)}")
    known = sorted(ports)
    if not ends:
        raise SettingsError(where, "must name at least one port (or leave the key out)")
    out = {}
    for key, value in ends.items():
        if key not in known:
            raise SettingsError(f"{where}.{key}", "is not a port of the network; ports: "
                                                  + ", ".join(known))
        if isinstance(value, int) and not isinstance(value, bool):
            value = float(value)  # TOML's 1 is a distance too
        try:
            out[key] = _PortEnd.model_validate({"value": value}).value
        except ValidationError as exc:
            raise SettingsError(f"{where}.{key}", _explain(exc, where, _PortEnd)[1]) from None
    return out


def describe_keys(name: str) -> list[tuple[str, str, str]]:
    """(key, type and range, description) of every key of a section, for docs and messages."""
    model = OVERRIDE_SECTIONS[name]
    rows = []
    for key, info in model.model_fields.items():
        schema = model.model_json_schema()["properties"][key]
        rows.append((key, _type_text(schema), info.description or ""))
    return rows


# --- messages ---------------------------------------------------------------------------------

def _settings_error(exc: ValidationError, where: str, model) -> SettingsError:
    key, reason = _explain(exc, where, model)
    return SettingsError(key, reason, kind=_error_kind(exc))


#: pydantic error types of a value of the wrong type (a SettingsError of kind "type").
_TYPE_ERRORS = {"bool_type", "float_type", "float_parsing", "int_parsing", "int_type",
                "int_from_float", "string_type", "tuple_type", "list_type", "model_type",
                "dict_type", "bool_parsing"}


def _error_kind(exc: ValidationError) -> str:
    """The :attr:`SettingsError.kind` of a validation's first error (as :func:`_explain` picks
    it)."""
    err = _first_error(exc)
    if err["type"] == "extra_forbidden":
        return "unknown"
    if err["type"] == "missing":
        return "missing"
    value = err.get("input")
    if isinstance(value, float) and not math.isfinite(value):
        return "value"  # a number, but not a finite one (whatever type was asked for)
    return "type" if err["type"] in _TYPE_ERRORS else "value"


def _first_error(exc: ValidationError) -> dict:
    # a value tried against a Union fails every member: report the member that got furthest
    # (a table given for a screw is judged as a table, not as a catalogue name)
    errs = exc.errors(include_url=False)
    return max(errs, key=lambda e: (len(e["loc"]), not e["type"].endswith("_type"),
                                    e["type"] != "literal_error"))


def describe_validation_error(exc: ValidationError, model, where: str = "",
                              aliases: bool = False) -> str:
    """The first error of a pydantic validation as one sentence: ``key.path: must be ...,
    got ...`` (with the field's description). Used for files read back as well as settings.
    ``aliases``: the model names its fields by alias (``"fabkit:scale"``)."""
    key, reason = _explain(exc, where, model)
    return f"{key}: {reason}" if key else reason


def _explain(exc: ValidationError, where: str, model) -> tuple[str, str]:
    err = _first_error(exc)
    loc = [p for p in err["loc"] if not _is_union_tag(p)]
    key = where
    for part in loc:
        key += f"[{part}]" if isinstance(part, int) else (f".{part}" if key else str(part))
    loc = [str(p) for p in loc if not isinstance(p, int)]
    value = err.get("input")
    kind = err["type"]
    ctx = err.get("ctx") or {}
    parent = model
    for part in loc[:-1]:
        ann = parent.model_fields.get(part)
        sub = _section_in(ann.annotation) if ann is not None else None
        if sub is None:
            break
        parent = sub
    if kind == "missing":
        return key, "is missing"
    if kind == "extra_forbidden":
        return key, (f"unknown key; known: {', '.join(sorted(parent.model_fields))}"
                     + _hint(loc[-1] if loc else "", parent.model_fields))
    info = parent.model_fields.get(loc[-1]) if loc else None
    doc = f" ({info.description})" if info is not None and info.description else ""
    reasons = {
        "greater_than_equal": lambda: f"must be >= {_num(ctx.get('ge'))}",
        "greater_than": lambda: f"must be > {_num(ctx.get('gt'))}",
        "less_than_equal": lambda: f"must be <= {_num(ctx.get('le'))}",
        "less_than": lambda: f"must be < {_num(ctx.get('lt'))}",
        "too_long": lambda: f"must have at most {ctx.get('max_length')} entries",
        "bool_type": lambda: "must be true or false",
        "float_type": lambda: "must be a number",
        "float_parsing": lambda: "must be a number",
        "int_parsing": lambda: "must be a whole number",
        "int_type": lambda: "must be a whole number",
        "string_type": lambda: "must be a string",
        "finite_number": lambda: "must be a finite number",
        "literal_error": lambda: f"must be one of {ctx.get('expected')}",
        "too_short": lambda: ("must not be empty" if ctx.get("min_length") == 1 else
                              f"must have at least {ctx.get('min_length')} entries"),
        "tuple_type": lambda: "must be an array",
        "list_type": lambda: "must be an array",
        "model_type": lambda: "must be a table",
        "dict_type": lambda: "must be a table",
    }
    reason = reasons.get(kind, lambda: err["msg"][0].lower() + err["msg"][1:])()
    if kind == "finite_number" or (isinstance(value, float) and not math.isfinite(value)):
        reason = "must be a finite number"
    return key, f"{reason}, got {_describe(value)}{doc}"


def _is_union_tag(part) -> bool:
    # pydantic names the member of a Union it tried (``str``, ``ScrewSection``, ``int``) in loc
    return isinstance(part, str) and (part in ("str", "int", "float", "bool", "constrained-int",
                                               "constrained-float")
                                      or part.endswith("Section")
                                      or part.startswith("literal["))


def _section_in(annotation):
    from typing import get_args

    stack = [annotation]
    while stack:
        a = stack.pop()
        if isinstance(a, type) and issubclass(a, Section):
            return a
        stack.extend(get_args(a))
    return None


def _type_text(schema: dict) -> str:
    options = schema.get("anyOf", [schema])
    parts = []
    for o in options:
        t = o.get("type")
        if t == "null":
            continue
        if "enum" in o or "const" in o:
            parts.append(" | ".join(repr(v) for v in o.get("enum", [o.get("const")])))
            continue
        bounds = [f"{op} {o[k]}" for k, op in (("minimum", ">="), ("exclusiveMinimum", ">"),
                                                ("maximum", "<="), ("exclusiveMaximum", "<"))
                  if k in o]
        name = {"number": "number", "integer": "whole number", "boolean": "true/false",
                "string": "text", "array": "array", "object": "table"}.get(t, t or "table")
        parts.append(name + (f" ({', '.join(bounds)})" if bounds else ""))
    return " or ".join(parts)


def _num(v) -> str:
    if isinstance(v, int) and not isinstance(v, bool):
        return str(v)
    return f"{v:g}" if isinstance(v, float) else str(v)


def _describe(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, (list, tuple)):
        return "an array"
    return repr(value)
