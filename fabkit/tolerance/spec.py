"""Tolerance settings: the process a design is built by, its error parameters and limits."""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..errors import FabricationError, SettingsError, TemplateError, UsageError
from ..settings.design import design_settings, DesignSettings, tolerance_settings
from ..io.schema import check_table, refuse_unused, section_of, ToleranceSection
from ..numerics import TINY
from ..motion.intent import LIMIT_FRACTION, STATE_FRACTION
from .processes import (PIN_EXTRA_KEYS, PROCESS_EXTRA_KEYS, PROCESSES, ProcessGeometry,
                        sample_lengths, SOURCES, spec_sources)

#: Linear shrinkage after cooling, mean and standard deviation (fractions), by print material:
#: typical figures quoted by filament makers for parts that the slicer does not compensate.
SHRINKAGE = {"PLA": (0.003, 0.001), "PETG": (0.004, 0.0015), "TPU": (0.006, 0.002)}


@dataclass(frozen=True)
class ToleranceSpec:
    """Manufacturing errors of one process and the acceptance limits (lengths in mm).

    Attributes
    ----------
    process : str
        ``"laser"``, ``"print"`` or ``"origami"``: which error model applies (default: the
        design's fabrication table).
    scale : float
        mm per design unit (default: the process's own scale).
    length_sigma, kerf_sigma, hole_clearance, thickness, thickness_sigma : float
        Laser: bar-length σ (0.05 mm, laser positioning), hole-diameter σ from uneven kerf
        (0.03 mm), hole minus barrel diameter (the screw's 4.2 - 4.0 = 0.2 mm: the joints' play,
        a freedom of the assembly rather than an error), sheet thickness and its build-to-build
        σ (3.0 ± 0.15 mm: extruded acrylic, ~5 %).
    bar_width : float
        Laser: the bars' width (mm; the laser settings'), with ``thickness`` their section for
        the elastic level (a build forced together, :mod:`fabkit.builds`).
    xy_sigma, shrinkage, shrinkage_sigma, line_width_sigma, hinge_length : float
        Print: joint position σ per coordinate (0.1 mm, typical FDM accuracy), shrinkage
        fraction and its σ (by material, :data:`SHRINKAGE`), extrusion-width σ (0.03 mm), the
        hinges' free length (the print settings').
    linkage, material : str
        Print: ``"hinges"`` (triangle plates on flexures) or ``"pins"`` (bars printed in place
        on pins), and the material (the print settings').
    pin_clearance, bar_thickness : float
        A pin-jointed print: each hole's radial play round its pin, and the bars' height (with
        ``bar_width`` their section for the elastic level); the print settings'.
    print_settings : PrintSettings or None
        The print's settings as resolved (template, then command line): a pin-jointed print's
        plan says which bar carries each pin (:mod:`fabkit.tolerance.pins`).
    origami_settings : OrigamiSettings or None
        The origami settings as resolved (template, then command line): the sheets, their
        crease assignment and the cut boundary the error model perturbs
        (:mod:`fabkit.tolerance.placement`).
    crease_sigma, cut_sigma, paper_thickness, compliance_sigma : float
        Origami: crease-vertex position σ (0.5 mm, folding by hand on a printed line), boundary
        σ (0.2 mm, knife or cutter), paper thickness (0.1 mm, 80 g/m² copy paper), panel bowing
        σ (0.2 mm).
    limit : float or None
        Allowed error of every port distance at the end, where the port distances are what a
        design is for (mm); None:
        ``limit_fraction`` of the module size.
    limit_fraction : float
        Default limit as a fraction of the mean designed port distance (0.02: a 2 % change of
        a module's shape is about what a maker sees by eye).
    min_reached : float
        Fraction of builds that must keep the design's behaviour (default 0.95).
    state_fraction : float
        A built module is in a designed state (a crystal, its lock) within this fraction of
        its travel between its states (default 0.25: nearer that state than the middle of
        the transition by a factor of two); see :mod:`fabkit.tolerance.behaviour`.
    samples : int
        Number of simulated builds (default 200).
    seed : int
        Seed of the random numbers (same seed, same result).
    """

    process: str = "laser"
    scale: float = 50.0
    length_sigma: float = 0.05
    kerf_sigma: float = 0.03
    hole_clearance: float = 0.2
    thickness: float = 3.0
    thickness_sigma: float = 0.15
    bar_width: float = 14.5
    xy_sigma: float = 0.1
    shrinkage: float = 0.003
    shrinkage_sigma: float = 0.001
    line_width_sigma: float = 0.03
    hinge_length: float = 6.0
    linkage: str = "hinges"
    material: str = "PLA"
    pin_clearance: float = 0.3
    bar_thickness: float = 2.4
    print_settings: object = field(default=None, repr=False)
    origami_settings: object = field(default=None, repr=False)
    crease_sigma: float = 0.5
    cut_sigma: float = 0.2
    paper_thickness: float = 0.1
    compliance_sigma: float = 0.2
    limit: float | None = None
    limit_fraction: float = LIMIT_FRACTION
    min_reached: float = 0.95
    state_fraction: float = STATE_FRACTION
    samples: int = 200
    seed: int = 0

    def process_keys(self) -> tuple[str, ...]:
        """The spec fields that belong to this process (its error sources' parameters)."""
        keys = [k for src in spec_sources(self).values() for k in src]
        if self.process == "print" and self.linkage == "pins":
            return tuple(keys) + PIN_EXTRA_KEYS
        return tuple(keys) + PROCESS_EXTRA_KEYS.get(self.process, ())

    @property
    def section_mm2(self) -> float:
        """A bar's cross-section (mm²) for the elastic level: laser ``bar_width`` ×
        ``thickness``, a pin-jointed print ``bar_width`` × ``bar_thickness``."""
        return self.bar_width * (self.bar_thickness if self.process == "print"
                                 else self.thickness)


TOLERANCE_KEYS = {f.name for f in fields(ToleranceSpec)} - {"print_settings", "origami_settings"}
_OWNER = {k: proc for proc in PROCESSES for src in SOURCES[proc].values() for k in src}
_OWNER.update({k: proc for proc, keys in PROCESS_EXTRA_KEYS.items() for k in keys})


def key_process(key: str) -> str | None:
    """The process a tolerance key belongs to (``"xy_sigma"`` → ``"print"``), or None for a
    key of every process (``samples``, ``seed``, ``scale``)."""
    return _OWNER.get(key)


def refuse_foreign(settings, process: str, name: str) -> None:
    """Refuse ``--set`` settings a tolerance analysis of ``process`` does not read: another
    process's section (``print`` under laser) or a tolerance key of another process
    (``tolerance.xy_sigma`` under laser), in the one way of :func:`fabkit.io.schema.refuse_unused`.

    Parameters
    ----------
    settings : dict
        Overrides nested by section (``--set``).
    process : str
        The process the design is analysed as.
    name : str
        The design's name, for the message.

    Raises
    ------
    UsageError
    SettingsError
        ``settings`` not nested by section, or a tolerance key the schema refuses.
    """
    tol = check_table(ToleranceSection, section_of(settings, "tolerance"), "tolerance").given()
    process = tol.get("process") or process
    for key in tol:
        if _OWNER.get(key, process) != process:
            raise UsageError("--set", f"tolerance.{key}: is a {_OWNER[key]} error; {name} is "
                                      f"analysed as {process} (set tolerance.process = "
                                      f"\"{_OWNER[key]}\" to change that)")
    others = [s for s in (settings or {}) if s in PROCESSES and s != process]
    refuse_unused(settings, {"motion", "tolerance", process},
                  f"{name} is analysed as {process} (set tolerance.process = "
                  f"\"{others[0] if others else process}\" to change that)")


def design_process(design) -> str:
    """The process a design is built by: its ``[fabrication.tolerance] process``, else the first
    of its origami / print / laser tables, else origami for 3D networks and laser for planar."""
    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    table = fab.get("tolerance")
    if isinstance(table, dict) and table.get("process") in PROCESSES:
        return table["process"]
    for proc, key in (("origami", "origami"), ("print", "print"), ("laser", "laser")):
        if key in fab:
            return proc
    return "origami" if design.network.dim == 3 else "laser"


#: The formats that each process makes (a report section speaks for the process of its files).
PROCESS_FORMATS = {"laser": ("dxf",), "origami": ("svg", "fold", "cp"), "print": ("stl",)}


def stated_process(design, settings=None) -> str | None:
    """The process ``--set tolerance.process``, else the template, names, or None.

    ``settings``: the design's :class:`~fabkit.settings.design.DesignSettings`, or overrides
    nested by section (only their tolerance section is read: tolerance settings the schema
    refuses state no process)."""
    if isinstance(settings, DesignSettings):
        return settings.stated_process
    try:
        return tolerance_settings(design, settings).process
    except (TemplateError, SettingsError):
        return None


def made_process(design, formats, settings=None) -> str:
    """The process a design's export is made by and judged as: the one stated
    (:func:`stated_process`); else the design's own (:func:`design_process`) when any of its
    formats is made; else the process whose files are made (``fabkit export super_stable --to
    stl`` writes a print, and is reported and judged as one: the print's scale and error
    model, not the laser's).

    Parameters
    ----------
    design : Design
    formats : iterable of str
        The formats that are made.
    settings : DesignSettings or dict, optional
        The design's settings (:func:`stated_process`: ``tolerance.process``).

    Returns
    -------
    str
        ``"laser"``, ``"print"`` or ``"origami"``.
    """
    stated = stated_process(design, settings)
    if stated is not None:
        return stated
    own = design_process(design)
    made = set(formats)
    if not made or made & set(PROCESS_FORMATS[own]):
        return own
    for proc in ("origami", "laser", "print"):
        if made & set(PROCESS_FORMATS[proc]):
            return proc
    return own


def _refused(design, section: str, exc: Exception) -> Exception:
    """The error of a process's settings as the tolerance analysis says it: a fabrication
    error names the template and its table; a schema error names its key already."""
    if isinstance(exc, FabricationError):
        return TemplateError(design.path or design.name, f"fabrication.{section}", str(exc))
    return exc


def _process_settings(design, settings: DesignSettings, section: str):
    if getattr(settings, section) is None and section in settings.refused:
        raise _refused(design, section, settings.refused[section]) from None
    return getattr(settings, section)


def _laser_defaults(design, settings: DesignSettings) -> dict:
    """Scale, thickness and hole clearance from the laser settings."""
    s = _process_settings(design, settings, "laser")
    out = {"scale": float(s.scale), "thickness": float(s.thickness),
           "bar_width": float(s.bar_width)}
    screw = getattr(s, "screw", None)
    if screw is not None:
        out["hole_clearance"] = float(screw.hole_diameter - screw.barrel_diameter)
    return out


def _print_defaults(design, settings: DesignSettings) -> dict:
    """Scale, hinge length and the material's shrinkage from the print settings."""
    s = _process_settings(design, settings, "print")
    mean, sd = SHRINKAGE.get(s.material, SHRINKAGE["PLA"])
    out = {"scale": float(s.scale), "hinge_length": float(s.hinge_length), "shrinkage": mean,
           "shrinkage_sigma": sd, "linkage": s.linkage, "material": s.material}
    if s.linkage == "pins":
        out.update({"pin_clearance": float(s.pin_clearance), "bar_width": float(s.bar_width),
                    "bar_thickness": float(s.bar_thickness), "print_settings": s})
    return out


def _origami_defaults(design, settings: DesignSettings) -> dict:
    """Scale from the sheet size of the [fabrication.origami] settings, measured on the flat
    sheet (150 mm over the network's extent when the template has no origami table)."""
    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    if "origami" not in fab:
        return {"scale": 150.0 / max(float(design.network.size), TINY)}
    s = _process_settings(design, settings, "origami")
    return {"scale": float(s.scale), "origami_settings": s}


_DEFAULTS = {"laser": _laser_defaults, "print": _print_defaults, "origami": _origami_defaults}


def tolerance_spec(design, settings=None, **overrides) -> ToleranceSpec:
    """The tolerance settings of a design: defaults < the process's settings (scale, sheet,
    hinge, material) < the template's ``[fabrication.tolerance]`` table < ``--set
    tolerance.*`` (command line) < ``overrides``.

    Parameters
    ----------
    design : Design
    settings : DesignSettings or dict, optional
        The design's settings, resolved once (:func:`fabkit.settings.design.design_settings`);
        command-line overrides nested by section (``{"tolerance": {"samples": 50}}``) are
        resolved here.
    **overrides
        Final say on any field of :class:`ToleranceSpec`.

    Returns
    -------
    ToleranceSpec

    Raises
    ------
    TemplateError
        Unknown key, a key of another process, wrong type, or a negative or zero value, naming
        ``fabrication.tolerance.<key>``; invalid settings of the process (they give the scale).

    Examples
    --------
    >>> from fabkit.templates import parse_template
    >>> d = parse_template('[network]\\nnodes=[[0,0],[1,0],[0,1],[1,1]]\\n'
    ...                    'edges=[[0,1],[0,2],[1,3],[2,3]]\\nports={d1=[0,3]}\\n'
    ...                    '[fabrication.tolerance]\\nscale=20\\nsamples=10')
    >>> tolerance_spec(d).scale, tolerance_spec(d, samples=5).samples, tolerance_spec(d).process
    (20.0, 5, 'laser')
    """
    path = design.path or design.name
    settings = design_settings(design, settings)
    if settings.tolerance is None:
        raise settings.refused["tolerance"]
    try:  # types and ranges: the declared schema (fabkit.io.schema.ToleranceSection)
        given = check_table(ToleranceSection, overrides, "tolerance option").given()
    except SettingsError as exc:
        raise TemplateError(path, exc.key, exc.reason) from None
    checked = [*settings.tolerance.sources(), ("tolerance option", given)]
    process = design_process(design)
    for _, keys in checked:
        if keys.get("process") is not None:
            process = keys["process"]
    values: dict = {"process": process}
    values.update(_DEFAULTS[process](design, settings))
    for where, keys in checked:
        for key, value in keys.items():
            if key == "process":
                continue
            if _OWNER.get(key, process) != process:  # a setting that does not apply here
                raise TemplateError(path, f"{where}.{key}",
                                    f"is a {_OWNER[key]} error; this design is analysed as "
                                    f"{process} (set process = \"{_OWNER[key]}\" to change "
                                    "that)")
            values[key] = value if key in ("samples", "seed") or value is None else float(value)
    return ToleranceSpec(**values)


def perturbed_lengths(lengths, spec: ToleranceSpec, rng) -> tuple[np.ndarray, np.ndarray]:
    """Sample the edge lengths of ``spec.samples`` laser-cut builds (every laser error source).

    Parameters
    ----------
    lengths : array_like, shape (E,)
        Design lengths (design units).
    spec : ToleranceSpec
    rng : numpy.random.Generator

    Returns
    -------
    built : numpy.ndarray, shape (M, E)
        Effective lengths of every build (design units).
    thickness : numpy.ndarray, shape (M,)
        Sheet thickness of every build (mm).

    Examples
    --------
    >>> spec = ToleranceSpec(samples=4, length_sigma=0, kerf_sigma=0, hole_clearance=0)
    >>> built, t = perturbed_lengths([1.0, 2.0], spec, np.random.default_rng(0))
    >>> bool(np.allclose(built, [[1.0, 2.0]] * 4))
    True
    """
    L = np.asarray(lengths, dtype=np.float64)
    geo = ProcessGeometry(np.zeros((L.size + 1, 2)), np.zeros((L.size, 2), dtype=np.int64), L)
    state = rng.bit_generator.state
    built = sample_lengths(geo, replace(spec, process="laser"), rng)
    # the thickness is the first draw of the laser model: replay it
    rng2 = np.random.Generator(type(rng.bit_generator)())
    rng2.bit_generator.state = state
    t = np.maximum(spec.thickness + spec.thickness_sigma * rng2.standard_normal(spec.samples),
                   0.1 * spec.thickness)
    return built, t


def model_summary(spec: ToleranceSpec) -> str:
    """One sentence: the process's error sources with their values, in mm.

    Examples
    --------
    >>> model_summary(ToleranceSpec(process="origami", scale=100.0))[:40]
    'origami: crease position σ 0.5 mm, cut σ'
    """
    if spec.process == "laser":
        parts = [f"bar length σ {spec.length_sigma:g} mm", f"kerf σ {spec.kerf_sigma:g} mm",
                 f"hole play {spec.hole_clearance:g} mm (a freedom)",
                 f"sheet {spec.thickness:g} ± {spec.thickness_sigma:g} mm"]
    elif spec.process == "print" and spec.linkage == "pins":
        parts = [f"xy accuracy σ {spec.xy_sigma:g} mm",
                 f"shrinkage {100 * spec.shrinkage:g} ± {100 * spec.shrinkage_sigma:g} %",
                 f"line width σ {spec.line_width_sigma:g} mm",
                 f"pin play {spec.pin_clearance:g} mm radial (a freedom)",
                 f"{spec.material} bars {spec.bar_width:g} x {spec.bar_thickness:g} mm"]
    elif spec.process == "print":
        parts = [f"xy accuracy σ {spec.xy_sigma:g} mm",
                 f"shrinkage {100 * spec.shrinkage:g} ± {100 * spec.shrinkage_sigma:g} %",
                 f"line width σ {spec.line_width_sigma:g} mm",
                 f"hinge flexure over {spec.hinge_length:g} mm"]
    else:
        parts = [f"crease position σ {spec.crease_sigma:g} mm", f"cut σ {spec.cut_sigma:g} mm",
                 f"paper {spec.paper_thickness:g} mm thick",
                 f"crease compliance σ {spec.compliance_sigma:g} mm"]
    kind = f"{spec.process} (pin-jointed)" if spec.process == "print" and \
        spec.linkage == "pins" else spec.process
    return f"{kind}: " + ", ".join(parts) + f" (scale {spec.scale:.4g} mm per unit)"
