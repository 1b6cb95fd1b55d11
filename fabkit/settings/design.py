"""A design's settings, resolved once: every process's table merged with the overrides.

The template's ``[fabrication]`` tables are merged with the command line's overrides (``--set``,
nested by section: ``{"laser": {"kerf": 0.2}, "print": {...}, "origami": {...},
"tolerance": {...}}``) and validated here, once per design, into one frozen
:class:`DesignSettings` that the Motion and Plan stages, the planners, the writers, the
tolerance analysis and the as-built checks read. Nothing below this module reads a raw settings
dict.

A process whose settings cannot be resolved (a web too thin for the screw, a sheet that is not
flat) does not stop the others: its error is kept, and raised with its own type and message by
whoever asks for that process (:meth:`DesignSettings.require`), where it was raised before
(the laser plan of a DXF export, the tolerance analysis of a laser kit).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

from ..errors import FabkitError, FabricationError, SettingsError, TemplateError
from ..io.schema import check_table, section_of, ToleranceSection
from .laser import laser_overrides, laser_settings, LaserSettings
from .origami import origami_settings, OrigamiSettings
from .printing import design_print_settings, PrintSettings

__all__ = ["DesignSettings", "ToleranceSettings", "design_settings", "tolerance_settings",
           "SECTIONS"]

#: The processes' sections a design's settings hold, in the order they are resolved.
SECTIONS = ("laser", "print", "origami", "tolerance")


def _frozen(value):
    """A read-only copy of nested settings: mappings become read-only, lists tuples."""
    if isinstance(value, Mapping):
        return MappingProxyType({k: _frozen(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v) for v in value)
    return value


def _thawed(value):
    """A plain, mutable copy of :func:`_frozen` settings (dicts and lists, as TOML gives)."""
    if isinstance(value, Mapping):
        return {k: _thawed(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return [_thawed(v) for v in value]
    return value


@dataclass(frozen=True)
class ToleranceSettings:
    """The tolerance analysis's settings as given, checked against the schema
    (:class:`fabkit.io.schema.ToleranceSection`): the template's table and the command line's,
    kept apart because a message names where a key came from, and because the process's own
    settings come between the defaults and them (:func:`fabkit.tolerance.tolerance_spec`).

    Attributes
    ----------
    table : Mapping
        The keys given in ``[fabrication.tolerance]``.
    command_line : Mapping
        The keys given as ``--set tolerance.<key>``.
    """

    table: Mapping = field(default_factory=lambda: MappingProxyType({}))
    command_line: Mapping = field(default_factory=lambda: MappingProxyType({}))

    @property
    def process(self) -> str | None:
        """The process the command line, else the template, names (None: neither does)."""
        for given in (self.command_line, self.table):
            if given.get("process") is not None:
                return given["process"]
        return None

    def sources(self) -> tuple:
        """``(where, keys)`` of the template's table, then the command line's."""
        return (("fabrication.tolerance", self.table), ("--set tolerance", self.command_line))


@dataclass(frozen=True, eq=False)
class DesignSettings:
    """A design's settings, resolved once (:func:`design_settings`).

    Attributes
    ----------
    laser : LaserSettings or None
        ``[fabrication.laser]`` with ``--set laser.*`` (defaults when the template has none);
        None when they cannot be resolved (the reason is in ``refused``).
    print : PrintSettings or None
        ``[fabrication.print]`` with ``--set print.*``, for the design's kind of print.
    origami : OrigamiSettings or None
        ``[fabrication.origami]`` with ``--set origami.*``; None without that table.
    tolerance : ToleranceSettings or None
        The tolerance analysis's settings as given; None when they fail the schema.
    overrides : Mapping
        The overrides as given (read-only), for the export's record and the exporters of
        one's own, which take them as a dict (:meth:`overrides_dict`).
    refused : Mapping of str to FabkitError
        Why a section could not be resolved, raised by :meth:`require`.
    """

    laser: LaserSettings | None = None
    print: PrintSettings | None = None
    origami: OrigamiSettings | None = None
    tolerance: ToleranceSettings | None = field(default_factory=ToleranceSettings)
    overrides: Mapping = field(default_factory=lambda: MappingProxyType({}))
    refused: Mapping = field(default_factory=lambda: MappingProxyType({}))

    def require(self, section: str):
        """The resolved settings of ``section``, or the error that kept them from resolving.

        Raises
        ------
        FabkitError
            The section's own error (:class:`~fabkit.errors.SettingsError`,
            :class:`~fabkit.errors.FabricationError`, ...), as its resolution raised it.
        """
        value = getattr(self, section)
        if value is None:
            raise self.refused[section]
        return value

    @property
    def stated_process(self) -> str | None:
        """The process ``--set tolerance.process``, else ``[fabrication.tolerance] process``,
        names (None: neither, or the tolerance settings fail the schema)."""
        return None if self.tolerance is None else self.tolerance.process

    def given(self, section: str, key: str) -> bool:
        """Whether the command line set ``section.key`` (``--set laser.kerf=0.2``)."""
        table = self.overrides.get(section)
        return isinstance(table, Mapping) and key in table

    def overrides_dict(self) -> dict:
        """The overrides as a plain dict nested by section (a copy)."""
        return _thawed(self.overrides)


def tolerance_settings(design, overrides: dict | None = None) -> ToleranceSettings:
    """The tolerance settings of a design: its ``[fabrication.tolerance]`` table and the
    ``tolerance`` section of the overrides, each checked against the schema.

    Raises
    ------
    TemplateError
        A key of the schema's refusal, naming the template and ``fabrication.tolerance.<key>``
        or ``--set tolerance.<key>``.
    """
    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    if overrides is not None and not isinstance(overrides, dict):
        section_of(overrides, "tolerance")  # the one message for settings that are not nested
    out = []
    for where, source in (("fabrication.tolerance", fab.get("tolerance", {})),
                          ("--set tolerance", (overrides or {}).get("tolerance", {}))):
        try:  # types and ranges: the declared schema (fabkit.io.schema.ToleranceSection)
            out.append(MappingProxyType(check_table(ToleranceSection, source, where).given()))
        except SettingsError as exc:
            raise TemplateError(design.path or design.name, exc.key, exc.reason) from None
    return ToleranceSettings(*out)


def _laser(design, overrides) -> LaserSettings:
    fab = getattr(design, "fabrication", None)
    table = fab.get("laser", {}) if isinstance(fab, dict) else {}
    if not isinstance(table, dict):
        raise FabricationError("[fabrication.laser] must be a table")
    return laser_settings(table, laser_overrides(overrides),
                          network_size=None if design is None else design.network.size)


def _origami(design, overrides) -> OrigamiSettings:
    return origami_settings(design, section_of(overrides, "origami"))


def _print(design, overrides) -> PrintSettings:
    return design_print_settings(design, overrides)


_RESOLVERS = {"laser": _laser, "print": _print, "origami": _origami,
              "tolerance": tolerance_settings}


def design_settings(design, settings=None) -> DesignSettings:
    """A design's settings, resolved once; resolved settings are handed back as they are.

    The one entry from raw settings: the batch calls it once per design before the Motion and
    Plan stages, and the public one-call functions (``export_design(design, settings)``,
    :func:`fabkit.tolerance.tolerance_spec`, the planners) call it on what they are given, so
    that a dict from a caller is resolved once at the entry and everything below is typed.

    Parameters
    ----------
    design : Design or None
        A loaded template (``--set motion.*`` already applied). None (a file checked without
        its design): the laser settings are the overrides over the defaults, and the other
        sections, which need the design, are refused.
    settings : DesignSettings or dict or None
        Resolved settings, or the overrides nested by section.

    Returns
    -------
    DesignSettings

    Examples
    --------
    >>> from fabkit.templates import parse_template
    >>> d = parse_template('[network]\\nnodes=[[0,0],[1,0],[0,1],[1,1]]\\n'
    ...                    'edges=[[0,1],[0,2],[1,3],[2,3]]\\nports={d1=[0,3]}')
    >>> s = design_settings(d, {"laser": {"kerf": 0.2}})
    >>> s.laser.kerf, s.given("laser", "kerf"), s.origami is None, design_settings(d, s) is s
    (0.2, True, True, True)
    """
    if isinstance(settings, DesignSettings):
        return settings
    resolved, refused = {}, {}
    for section in SECTIONS:
        if design is None and section != "laser":
            refused[section] = FabricationError(f"the {section} settings need the design")
            continue
        try:
            resolved[section] = _RESOLVERS[section](design, settings)
        except FabkitError as exc:  # raised by whoever asks for this process
            refused[section] = exc
    tolerance = resolved.pop("tolerance", None)
    return DesignSettings(**resolved, tolerance=tolerance,
                          overrides=_frozen(settings if isinstance(settings, dict) else {}),
                          refused=MappingProxyType(refused))
