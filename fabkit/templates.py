"""Template files (TOML): a design's network, its motion and its fabrication settings.

A template has one section that builds the network and optional sections around it::

    name = "fourbar"                 # optional, defaults to the file name
    description = "4-bar linkage (antiparallelogram)"

    [network]                        # explicit network ...
    nodes = [[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]
    edges = [[0, 2], [0, 3], [1, 2], [1, 3]]
    ports = { d1 = [0, 1], d2 = [2, 3] }

    [motion]                         # what `fabkit simulate` traces
    drive = "d1"
    to = 3.0
    method = "auto"                  # auto | constructive | projected | rk4-nullspace
    hold = []                        # ports held at their start values
    options = { samples = 101 }      # method options
    intent = "auto"                  # what a build must keep (fabkit.tolerance.behaviour)

    [fabrication.laser]              # read by the fabrication stages, not by the core

Instead of ``[network]`` a template may have ``[chain]`` (copies of another template joined port
to port, see :mod:`fabkit.design.assemble`) or another builder section registered in ``BUILDERS``.
Every error is a :class:`~fabkit.errors.TemplateError` naming the file, the key path and the
reason.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from .errors import (ArgumentTypeError, BoundsError, brief, FabkitError, InputFileError,
                     NetworkError, SettingsError, TemplateError, UnsafeNameError)
from .kinematics import METHODS, trace
from .model.network import Network
from .io.formats import toml_shape
from .io.outputs import check_name, write_atomic
from .io.toml_writer import TomlDocument
from .io.suggest import close_names, nearest_file
from .io.workload import require

__all__ = ["Design", "Motion", "network_section", "template_text", "TemplateContext",
           "load_template", "parse_template", "BUILDERS", "SELF_CONTAINED", "TOP_LEVEL_KEYS", "BUNDLED_PACKAGE", "bundled_folder", "bundled_names", "bundled_template",
           "is_template_name", "resolve_template", "with_settings"]

#: Sections that build the network: name → "module:function". The function takes the section
#: (a dict) and a :class:`TemplateContext` and returns a Network. Exactly one must be present.
BUILDERS: dict[str, str] = {
    "network": "fabkit.templates:build_network",
    "chain": "fabkit.design.assemble:build_chain",
    "design": "fabkit.design.solution_space:build_designed_module",
    "tessellation": "fabkit.design.assemble:build_tessellation",
}

#: Bounds checked before a network is built (lifted by ``fabkit --allow-large`` or the
#: environment variable ``FABKIT_ALLOW_LARGE=1``): beyond them the work takes hours or the memory
#: runs out before a single line of feedback.
MAX_FILE_BYTES = 4 * 2**20      #: a template file (the largest bundled one is a few kB)
MAX_MODULES = 20_000            #: modules of a chain or tessellation
MAX_NODES = 200_000             #: nodes of an explicit [network]
MAX_MOTION_SAMPLES = 100_000    #: motion.options.samples (configurations of a sampled trace)
MAX_MOTION_STEPS = 1_000_000    #: motion.options.max_steps


def allow_large() -> bool:
    """True when the size bounds are lifted (``FABKIT_ALLOW_LARGE=1``, set by --allow-large)."""
    import os

    return os.environ.get("FABKIT_ALLOW_LARGE", "") == "1"


def _bound(ctx, key: str, quantity: str, value, limit) -> None:
    if value > limit and not allow_large():
        raise BoundsError(f"{ctx.path}: {key}", quantity, value, limit, "fabkit --allow-large")


def _check_sizes(ctx, builder_key: str, section: dict, raw: dict) -> None:
    """Refuse sizes that cannot finish before building anything (one line, the key named)."""
    def count(value):
        return value if isinstance(value, int) and not isinstance(value, bool) else None

    if builder_key == "chain":
        copies = count(section.get("copies"))
        mods = section.get("modules")
        n = len(mods) if isinstance(mods, list) else 1
        if copies is not None:
            _bound(ctx, "chain.copies", "modules", copies * n, MAX_MODULES)
        elif isinstance(mods, list):
            _bound(ctx, "chain.modules", "modules", n, MAX_MODULES)
    elif builder_key == "tessellation":
        shape = section.get("shape")
        if (isinstance(shape, list) and len(shape) == 2
                and all(count(v) is not None for v in shape)):
            _bound(ctx, "tessellation.shape", "modules", shape[0] * shape[1], MAX_MODULES)
    elif builder_key == "network" and isinstance(section.get("nodes"), list):
        _bound(ctx, "network.nodes", "nodes", len(section["nodes"]), MAX_NODES)
        ctx.count_nodes("network.nodes", len(section["nodes"]))
    motion = raw.get("motion")
    options = motion.get("options") if isinstance(motion, dict) else None
    if isinstance(options, dict):
        for key, limit, what in (("samples", MAX_MOTION_SAMPLES, "configurations"),
                                 ("max_steps", MAX_MOTION_STEPS, "steps")):
            v = options.get(key)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                _bound(ctx, f"motion.options.{key}", what, int(v), limit)
            elif isinstance(v, float):
                raise ctx.error(f"motion.options.{key}", f"must be finite, got {v}")


#: Keys allowed at the top level besides the builder sections.
TOP_LEVEL_KEYS = {"name", "description", "figure", "notes", "motion", "fabrication", "analysis",
                  "tags"}

_MOTION_KEYS = {"drive", "to", "method", "hold", "options", "start", "intent", "ends"}


@dataclass(frozen=True)
class Motion:
    """The motion a template asks to trace.

    Attributes
    ----------
    drive : str
        Port driven.
    to : float or None
        Target value of the drive (None: the template only describes geometry).
    method : str
    hold : tuple of str
    options : dict
        Method options.
    """

    drive: str = "d1"
    to: float | None = None
    method: str = "auto"
    hold: tuple[str, ...] = ()
    options: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Design:
    """A loaded template.

    Attributes
    ----------
    name : str
    description : str
    path : pathlib.Path or None
    network : Network
    motion : Motion
    fabrication : dict
        The raw ``[fabrication]`` section (validated by the fabrication stage that reads it).
    raw : dict
        The whole parsed file.
    meta : dict
        Anything a builder reports about how it built the network (e.g. design residuals).
    references : dict of str to Design
        The templates this one refers to, loaded with it, by key path (``"chain.module"``,
        ``"fabrication.origami.sheet"``): later stages read them here, never from disk.
    """

    name: str
    description: str
    path: Path | None
    network: Network
    motion: Motion
    fabrication: dict
    raw: dict
    meta: dict = field(default_factory=dict)
    references: dict = field(default_factory=dict)

    def trace(self, **overrides):
        """Trace the template's motion (keywords override ``method``, ``to``, options)."""
        m = self.motion
        to = overrides.pop("to", m.to)
        method = overrides.pop("method", m.method)
        if to is None or not m.drive:
            raise TemplateError(self.path or self.name, "motion",
                                "no [motion] with a drive port and a target `to` is given")
        opts = {**m.options, **overrides}
        return trace(self.network, drive=m.drive, to=to, method=method, hold=m.hold, **opts)

    @classmethod
    def from_network(cls, network: Network, *, drive: str = "d1", to: float | None = None,
                     name: str = "design", description: str = "", method: str = "auto",
                     hold=(), options: dict | None = None, ends: dict | None = None,
                     intent: str | None = None, fabrication: dict | None = None) -> "Design":
        """A design made from a network in code: a chain, a tessellation, a designed module.

        It is what the template :meth:`save` writes describes (an explicit ``[network]``, its
        ``[motion]`` and ``[fabrication]``), checked as a template is; the network itself is
        kept, with its assembly record (a chain's modules, which the laser guide pages by).

        Parameters
        ----------
        network : Network
        drive : str
            The port the motion drives (``[motion] drive``).
        to : float, optional
            The drive's target (None: geometry only, nothing to trace).
        name : str
            The design's name, also its output folder's (letters, digits, ``_ . + -``).
        description : str
        method, hold, options, ends, intent
            The other keys of ``[motion]`` (see :mod:`fabkit.templates`), when given.
        fabrication : dict, optional
            The ``[fabrication]`` section, nested by process (``{"print": {"scale": 20}}``).

        Returns
        -------
        Design
            ``path`` is None until it is saved and loaded.

        Raises
        ------
        TemplateError
            A drive or held port the network does not have, a bad option, a bad name or
            fabrication setting; the message names the key.

        Examples
        --------
        >>> import fabkit
        >>> net = fabkit.chain(fabkit.load_template("super_stable").network, copies=3)
        >>> d = fabkit.Design.from_network(net, drive="d1", to=1.2, name="three")
        >>> d.name, d.motion.drive, d.motion.to, d.network.n_nodes
        ('three', 'd1', 1.2, 11)
        """
        if not isinstance(network, Network):
            raise ArgumentTypeError("network", f"must be a fabkit.Network, got "
                                               f"{type(network).__name__}")
        motion = {"drive": drive, "to": to, "method": method, "hold": list(hold),
                  "options": options, "ends": ends, "intent": intent}
        raw = {"name": name, "description": description, "network": network_section(network),
               "motion": {k: v for k, v in motion.items() if v not in (None, [], {})},
               "fabrication": dict(fabrication or {})}
        raw = {k: v for k, v in raw.items() if v not in ("", {})}
        design = _from_raw(raw, Path(f"<{name}>"), network=network)
        return dataclasses.replace(design, path=None)

    def save(self, path) -> Path:
        """Write the design's template (TOML) that :func:`load_template` reads back to an equal
        design: the same name, network (nodes to the last bit, edges, ports, labels), motion and
        fabrication settings.

        A template built from other files (``[chain]``, ``[tessellation]``) is written with its
        network explicit, so that the file stands alone wherever it is saved; an explicit
        network keeps no record of the modules it was assembled from (``network.assembly``,
        which a laser kit's guide pages by): export the design itself to keep it.

        Parameters
        ----------
        path : str or pathlib.Path
            The file to write (replaced if it exists).

        Returns
        -------
        pathlib.Path
            The file written.

        Raises
        ------
        OutputError
            The folder cannot be written, or a full disk (the message names the file; nothing
            half-written is left: :func:`fabkit.io.outputs.write_atomic`).
        """
        path = Path(path)
        write_atomic(path, template_text(self).encode("utf-8"))
        return path


#: Builder sections that stand alone (no other file named in them): kept as written when a
#: design is saved; any other is saved as the explicit network it built.
SELF_CONTAINED = ("network", "design")


def network_section(network: Network) -> dict:
    """The ``[network]`` section that builds ``network`` (nodes, edges, ports, labels)."""
    section = {"nodes": network.nodes.tolist(), "edges": network.edges.tolist(),
               "ports": {str(k): [int(i), int(j)] for k, (i, j) in network.ports.items()}}
    if network.labels is not None:
        section["labels"] = [str(x) for x in network.labels]
    return section


def template_text(design: "Design") -> str:
    """The TOML text of a design's template (:meth:`Design.save`)."""
    raw = dict(design.raw)
    builder = next((k for k in BUILDERS if k in raw), None)
    if builder not in SELF_CONTAINED:
        raw.pop(builder, None)
        raw = {"network": network_section(design.network), **raw}
    raw["name"] = design.name
    first = ("name", "description")
    order = [k for k in first if k in raw] + [k for k in raw if k not in first]
    doc = TomlDocument()
    doc.mapping({k: raw[k] for k in order},
                per_line={"network.nodes": 1, "network.edges": 6, "network.labels": 8})
    return doc.text()


class _Loading:
    """One template read with every template it refers to, however deep: each file is read
    once (a file named by many spellings, ``./x.toml`` and ``././x.toml``, is one file), and
    the nodes of every network built on the way count together against the work estimate."""

    def __init__(self):
        self.loaded: dict[str, "Design"] = {}
        self.nodes = 0


class TemplateContext:
    """What a builder gets besides its section: the file, key paths, typed getters, errors."""

    def __init__(self, path: Path | str, raw: dict, stack: tuple[str, ...] = (),
                 loading: _Loading | None = None):
        self.path = Path(path)
        self.raw = raw
        self.stack = stack
        self.meta: dict = {}
        self.references: dict = {}
        self.loading = loading if loading is not None else _Loading()

    # errors and typed access ----------------------------------------------------------------
    def error(self, key: str, reason: str) -> TemplateError:
        return TemplateError(self.path, key, reason)

    def get(self, table: dict, key: str, where: str, kind, *, required=True, default=None):
        """``table[key]`` checked against ``kind`` (a type, tuple of types, or "number")."""
        full = f"{where}.{key}" if where else key
        if key not in table:
            if required:
                raise self.error(full, "missing required key")
            return default
        value = table[key]
        if kind == "number":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise self.error(full, f"must be a number, got {_describe(value)}")
            if not math.isfinite(value):
                raise self.error(full, f"must be finite, got {value}")
            return float(value)
        if kind is int and isinstance(value, bool):
            raise self.error(full, f"must be an integer, got {_describe(value)}")
        if not isinstance(value, kind):
            want = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
            want = {"dict": "a table", "list": "an array", "str": "a string", "int": "an integer",
                    "bool": "true or false"}.get(want, want)
            raise self.error(full, f"must be {want}, got {_describe(value)}")
        return value

    def bound_modules(self, key: str, modules: int, nodes: int) -> None:
        """Refuse, before building it, a network of ``modules`` modules and ``nodes`` nodes
        in all (counted through every level of nesting: a chain of chains multiplies) that is
        over :data:`MAX_MODULES` or over the bounds of :func:`fabkit.io.workload.require`."""
        _bound(self, key, "modules (after every level of nesting)", modules, MAX_MODULES)
        self.count_nodes(key, nodes)

    def count_nodes(self, key: str, nodes: int) -> None:
        """Add the nodes of a network about to be built to those of every network built for
        the same template (its references included), and refuse the total past the bounds of
        :func:`fabkit.io.workload.require` before building."""
        total = self.loading.nodes + int(nodes)
        require(f"{self.path}: {key}", ("node", total))
        self.loading.nodes = total

    def check_keys(self, table: dict, where: str, allowed) -> None:
        unknown = sorted(set(table) - set(allowed))
        if unknown:
            raise self.error(f"{where}.{unknown[0]}" if where else unknown[0],
                             f"unknown key; allowed keys here: {', '.join(sorted(allowed))}")

    def load(self, relative: str, key: str) -> "Design":
        """Load another template named relative to this one (for chains and sequences); a bare
        name not found next to this one is a bundled template (see :func:`resolve_template`)."""
        if not relative.strip():  # else it would name the folder this template is in
            raise self.error(key, "is empty: name a template file (e.g. \"fourbar.toml\")")
        target = resolve_template(relative, base=self.path.parent).resolve()
        if str(target) in self.stack:
            raise self.error(key, f"template {relative!r} refers back to itself")
        if not target.exists():
            also = ", nor a bundled template of that name" if is_template_name(relative) else ""
            raise self.error(key, f"no template file {relative!r} next to this one{also}")
        design = self.loading.loaded.get(str(target))
        if design is None:  # read once, however many times and spellings name it
            design = load_template(target, _stack=self.stack + (str(self.path.resolve()),),
                                   _loading=self.loading)
            self.loading.loaded[str(target)] = design
        self.references.setdefault(key, design)
        return design


def _describe(value: Any) -> str:
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"string {value!r}"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return f"an array of {len(value)}"
    return f"{type(value).__name__} {value!r}"


def _matrix(ctx: TemplateContext, value, key: str, width, integer: bool) -> list[list]:
    if not isinstance(value, list) or not value:
        raise ctx.error(key, f"must be a non-empty array of rows, got {_describe(value)}")
    rows = []
    for i, row in enumerate(value):
        k = f"{key}[{i}]"
        if not isinstance(row, list):
            raise ctx.error(k, f"must be an array, got {_describe(row)}")
        if len(row) not in width:
            raise ctx.error(k, f"must have {' or '.join(map(str, width))} entries, got {len(row)}")
        for c, v in enumerate(row):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ctx.error(f"{k}[{c}]", f"must be a number, got {_describe(v)}")
            if integer and not isinstance(v, int):
                raise ctx.error(f"{k}[{c}]", f"must be an integer node index, got {v!r}")
            if not integer and not math.isfinite(v):
                raise ctx.error(f"{k}[{c}]", f"must be finite, got {v}")
        rows.append(row)
    return rows


def build_network(section: dict, ctx: TemplateContext) -> Network:
    """Builder of the explicit ``[network]`` section: nodes, edges, ports, labels, dim."""
    ctx.check_keys(section, "network", {"nodes", "edges", "ports", "labels", "dim"})
    nodes = _matrix(ctx, ctx.get(section, "nodes", "network", list), "network.nodes", (2, 3), False)
    dims = {len(r) for r in nodes}
    if len(dims) > 1:
        raise ctx.error("network.nodes", "rows mix 2 and 3 coordinates")
    dim = dims.pop()
    if "dim" in section:
        want = ctx.get(section, "dim", "network", int)
        if want != dim:
            raise ctx.error("network.dim", f"says {want} but the nodes have {dim} coordinates")
    n = len(nodes)
    edges = _matrix(ctx, ctx.get(section, "edges", "network", list), "network.edges", (2,), True)
    for k, (i, j) in enumerate(edges):
        for c, v in enumerate((i, j)):
            if not 0 <= v < n:
                raise ctx.error(f"network.edges[{k}][{c}]",
                                f"node index {v} is out of range 0..{n - 1}")
    ports = ctx.get(section, "ports", "network", dict, required=False, default={})
    clean_ports = {}
    for name, pair in ports.items():
        key = f"network.ports.{name}"
        if (not isinstance(pair, list) or len(pair) != 2
                or any(isinstance(v, bool) or not isinstance(v, int) for v in pair)):
            raise ctx.error(key, f"must be a pair of node indices, got {_describe(pair)}")
        for c, v in enumerate(pair):
            if not 0 <= v < n:
                raise ctx.error(f"{key}[{c}]", f"node index {v} is out of range 0..{n - 1}")
        clean_ports[name] = tuple(pair)
    labels = ctx.get(section, "labels", "network", list, required=False)
    try:
        return Network(nodes, edges, clean_ports, labels)
    except NetworkError as exc:
        raise ctx.error(f"network.{exc.key}" if exc.key else "network", str(exc)) from None


def _parse_motion(ctx: TemplateContext, section: dict, net: Network) -> Motion:
    ctx.check_keys(section, "motion", _MOTION_KEYS)
    drive = ctx.get(section, "drive", "motion", str, required=False, default="d1")
    if drive not in net.ports:
        known = ", ".join(sorted(net.ports)) or "none"
        raise ctx.error("motion.drive", f"unknown port {drive!r}; the network has ports: {known}")
    to = ctx.get(section, "to", "motion", "number", required=False)
    if to is not None and to <= 0:
        raise ctx.error("motion.to", f"must be a positive distance, got {to}")
    method = ctx.get(section, "method", "motion", str, required=False, default="auto")

    if method != "auto" and method not in METHODS:
        raise ctx.error("motion.method",
                        f"unknown method {method!r}; valid: auto, {', '.join(METHODS)}")
    hold = ctx.get(section, "hold", "motion", list, required=False, default=[])
    for i, h in enumerate(hold):
        if not isinstance(h, str) or h not in net.ports:
            raise ctx.error(f"motion.hold[{i}]", f"must name a port of the network, got {h!r}")
    if "ends" in section:  # designed end values of ports (fabkit.motion.ends)
        from .errors import SettingsError
        from .io.schema import check_motion_ends

        try:
            check_motion_ends(section["ends"], net.ports)
        except SettingsError as exc:
            raise ctx.error(exc.key, exc.reason) from None
    options = ctx.get(section, "options", "motion", dict, required=False, default={})
    if options:
        from .errors import SettingsError
        from .io.schema import check_method_options

        try:  # strict types and ranges, declared in fabkit.io.schema
            check_method_options(method, options)
        except SettingsError as exc:
            raise ctx.error(exc.key, exc.reason) from None
        samples = options.get("samples")
        if isinstance(samples, int) and not isinstance(samples, bool):
            from .io.workload import require

            # a sampled trace holds every sample's configuration: samples x nodes
            require(f"{ctx.path}: motion.options.samples",
                    ("trace configuration node", samples * net.n_nodes),
                    ("stored value", samples))
    return Motion(drive=drive, to=to, method=method, hold=tuple(hold), options=dict(options))


def _check_fabrication(ctx, fabrication: dict) -> None:
    """Every ``[fabrication]`` table against the declared schema (:mod:`fabkit.io.schema`), when
    the template is read: a misspelt section or key, a wrong type or a value out of range is
    refused before any work, by every command."""
    from .io.schema import check_fabrication

    try:
        check_fabrication(fabrication)
    except SettingsError as exc:
        raise ctx.error(exc.key, exc.reason) from None


def with_settings(design: "Design", settings: dict | None) -> "Design":
    """The design with the ``motion`` section of ``settings`` (``--set motion.to=2.9``) in
    place of the template's ``[motion]`` values; the fabrication sections are left to the
    stages that read them. Every section is checked against the schema.

    Raises
    ------
    SettingsError
        A bad section, key or value.
    TemplateError
        A drive that is not a port of the network.
    """
    from dataclasses import replace

    from .io.schema import section_of

    motion = section_of(settings, "motion")
    if not motion:
        return design
    if "drive" in motion and motion["drive"] not in design.network.ports:
        known = ", ".join(sorted(design.network.ports)) or "none"
        raise TemplateError(design.path or design.name, "motion.drive",
                            f"--set motion.drive: unknown port {motion['drive']!r}; the network "
                            f"has ports: {known}")
    if "to" in motion:
        motion["to"] = float(motion["to"])
    return replace(design, motion=replace(design.motion, **motion))


def _design_name(ctx, raw, path: Path) -> str:
    """The design's name, safe as a folder name (:func:`fabkit.io.outputs.check_name`).

    A ``name`` set in the template is checked as written; without one, the file's stem is used
    with every character that cannot be in a folder name replaced by ``_``.
    """
    if "name" in raw:
        name = ctx.get(raw, "name", "", str)
        key = "name"
    else:
        name = re.sub(r"[^A-Za-z0-9_.+-]", "_", path.stem).lstrip("._+-") or "design"
        key = ""
    try:
        return check_name(name, "the name")
    except UnsafeNameError as exc:
        fix = "" if key else " (it comes from the file name; rename the file or set name = ...)"
        raise ctx.error(key, f"{brief(name)} {exc.reason}{fix}") from None


def parse_template(text: str, path: Path | str = "<string>", _stack=(),
                   _loading: _Loading | None = None) -> Design:
    """Parse template text (see the module docstring). ``path`` is used in messages and to
    resolve relative references.

    Its nesting, the digits of its numbers and the count of its values are measured on the
    text before it is parsed (:func:`fabkit.io.formats.toml_shape`): past them an
    :class:`~fabkit.errors.InputFileError` of kind ``"bounds"`` names the file."""
    path = Path(path)
    toml_shape(text, path)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise TemplateError(path, "", f"not valid TOML: {exc}") from None
    except RecursionError:  # the parser recurses once per level of [[[...]]] or {a={b=...}}
        raise TemplateError(path, "", "not a template: arrays or tables nested too deeply "
                                      "for TOML to parse") from None
    except ValueError:  # Python's own bound on the digits of an integer (4300)
        raise TemplateError(path, "", "not a template: a number of thousands of digits (no "
                                      "measure has that many)") from None
    return _from_raw(raw, path, _stack, _loading)


def _from_raw(raw: dict, path: Path, _stack=(), _loading: _Loading | None = None,
              network: Network | None = None) -> Design:
    """The design of a parsed template; ``network``, when given, is the network its builder
    section describes (a network made in code: kept as it is, with its assembly record)."""
    ctx = TemplateContext(path, raw, tuple(_stack), _loading)
    present = [k for k in BUILDERS if k in raw]
    if not present:
        raise ctx.error("", f"no section that builds the network; give one of: "
                            f"{', '.join('[' + k + ']' for k in BUILDERS)}")
    if len(present) > 1:
        raise ctx.error(present[1], f"give only one of {', '.join(present)}")
    ctx.check_keys(raw, "", TOP_LEVEL_KEYS | set(BUILDERS))
    name = _design_name(ctx, raw, path)  # before any work: the name becomes a folder name
    builder_key = present[0]
    section = ctx.get(raw, builder_key, "", dict)
    _check_sizes(ctx, builder_key, section, raw)
    net = network if network is not None else _built(ctx, builder_key, section)
    description = ctx.get(raw, "description", "", str, required=False, default="")
    if "motion" in raw:
        motion = _parse_motion(ctx, ctx.get(raw, "motion", "", dict), net)
    else:  # geometry only: drive d1 if there is such a port, nothing to trace otherwise
        motion = Motion(drive="d1" if "d1" in net.ports else "")
    fabrication = ctx.get(raw, "fabrication", "", dict, required=False, default={})
    _check_fabrication(ctx, fabrication)
    origami = fabrication.get("origami")
    if isinstance(origami, dict) and isinstance(origami.get("sheet"), str):
        # a chain of sheets names the template of one sheet: load it now, with the design
        ctx.load(origami["sheet"], "fabrication.origami.sheet")
    return Design(name=name, description=description, path=path, network=net, motion=motion,
                  fabrication=fabrication, raw=raw, meta=ctx.meta, references=ctx.references)


def _built(ctx: TemplateContext, builder_key: str, section: dict) -> Network:
    """The network a template's builder section builds."""
    module_name, func_name = BUILDERS[builder_key].split(":")
    try:
        builder: Callable = getattr(importlib.import_module(module_name), func_name)
    except (ImportError, AttributeError):
        raise ctx.error(builder_key, f"this fabkit cannot build [{builder_key}] sections") from None
    try:
        return builder(section, ctx)
    except (TemplateError, BoundsError):
        raise
    except FabkitError as exc:
        raise ctx.error(builder_key, str(exc)) from None


def load_template(path, *, _stack=(), _loading: _Loading | None = None) -> Design:
    """Read and validate a template file.

    Parameters
    ----------
    path : str or pathlib.Path
        A file; or, as a string, the name of a bundled template (``"fourbar"``), which a file of
        that name in the current folder overrides (see :func:`resolve_template`).

    Returns
    -------
    Design

    Raises
    ------
    TemplateError
        Unreadable file, TOML syntax error, missing or unknown key, wrong type, bad index,
        invalid network; the message names the file, the key path and the reason.
    InputFileError
        Not a regular file (a FIFO, a device, a socket), or a symbolic-link loop: refused before
        reading, since reading may never end.
    BoundsError
        A file larger than :data:`MAX_FILE_BYTES`, or sizes beyond the bounds (see
        :func:`parse_template`).
    """
    import errno
    import os
    import stat

    if not isinstance(path, (str, os.PathLike)):
        from .errors import ArgumentTypeError

        raise ArgumentTypeError("path", f"must be a file path or a bundled template's name, "
                                        f"got {type(path).__name__}")
    if "\x00" in os.fspath(path):
        from .errors import ArgumentValueError

        raise ArgumentValueError("path", f"holds a NUL character, which no file name has: "
                                         f"{os.fspath(path)[:80]!r}")
    name, path = path, resolve_template(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        also = (", nor a bundled template of that name (fabkit templates lists them)"
                if is_template_name(str(name)) and str(name).removesuffix(".toml")
                not in bundled_names() else "")
        raise TemplateError(path, "", f"no such file{also}{_nearest_template(name)}") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise InputFileError(path, "symbolic-link loop: the link never reaches a "
                                       "file", kind="loop") from None
        raise TemplateError(path, "", f"cannot read: {exc.strerror}") from None
    if stat.S_ISDIR(st.st_mode):
        raise TemplateError(path, "", "is a folder, not a template file")
    if not stat.S_ISREG(st.st_mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode) else
                "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else
                "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise InputFileError(path, f"is {kind}, not a template file: refused",
                             kind="not_regular")
    if st.st_size > MAX_FILE_BYTES and not allow_large():
        raise BoundsError(str(path), "bytes", st.st_size, MAX_FILE_BYTES,
                          "fabkit --allow-large")
    try:
        with open(path, "rb") as fh:  # read at most the bound: the file may grow meanwhile
            data = fh.read(MAX_FILE_BYTES + 1 if not allow_large() else -1)
    except IsADirectoryError:
        raise TemplateError(path, "", "is a folder, not a template file") from None
    except OSError as exc:
        raise TemplateError(path, "", f"cannot read: {exc.strerror}") from None
    if len(data) > MAX_FILE_BYTES and not allow_large():
        raise BoundsError(str(path), "bytes", len(data), MAX_FILE_BYTES, "fabkit --allow-large")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise TemplateError(path, "", "not a text file (not UTF-8): a template is TOML text") from None
    return parse_template(text, path, _stack, _loading)


def _nearest_template(name) -> str:
    """``"; did you mean 'super_stable'?"`` for a misspelt template: among the bundled names and
    the templates of the current folder for a bare name, among the templates beside it for a
    path; ``""`` when none is alike."""
    if is_template_name(str(name)):  # a name, or a path as plain as one
        stem = str(name).removesuffix(".toml")
        if stem in bundled_names():  # a path on purpose (./fourbar): no other name was meant
            return ""
        here = [p.stem for p in Path().glob("*.toml")]
        found = close_names(stem, sorted(set(bundled_names()) | set(here)), n=1)
        return f"; did you mean {found[0]!r}?" if found else ""
    hint = nearest_file(name, "*.toml")
    return f"; {hint}" if hint else ""


#: The package whose data files are the bundled templates. In the repo they live in ``templates/``
#: at the top, their only copy; pyproject.toml maps this package onto that folder (``package-dir``),
#: so wheels, sdists and editable installs all carry them.
BUNDLED_PACKAGE = "fabkit.bundled_templates"

#: What a bundled template's name looks like: letters, digits, ``_`` and ``-``, with or without
#: ``.toml``. Anything else (a ``/``, ``..``, a leading dot, a drive) is a path, never a name, so a
#: name cannot reach outside the bundled folder.
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]*(?:\.toml)?")


def bundled_folder() -> Path:
    """The folder of the bundled templates, found with :mod:`importlib.resources`.

    A source tree run without installing (``PYTHONPATH=.``) has no ``fabkit.bundled_templates``
    package; the ``templates`` folder beside the package is used then.

    Raises
    ------
    FabkitError
        The installed package is not on the file system (e.g. inside a zip file).
    """
    import importlib.resources

    try:
        root = importlib.resources.files(BUNDLED_PACKAGE)
    except ModuleNotFoundError:
        root = Path(__file__).resolve().parents[1] / "templates"
    if not isinstance(root, Path):
        raise FabkitError(f"the bundled templates ({BUNDLED_PACKAGE}) are not files on disk "
                          f"({root}); install fabkit from a wheel or a folder")
    return root


def bundled_names() -> list[str]:
    """Names of the bundled templates, sorted (``["and_gate", ..., "velocity_design_example"]``)."""
    return sorted(p.stem for p in bundled_folder().glob("*.toml"))


def is_template_name(text) -> bool:
    """True when ``text`` is a string of the form of a bundled template's name (``fourbar``,
    ``fourbar.toml``); False for anything with a folder part (``./fourbar``, ``a/b.toml``,
    ``..``) and for :class:`pathlib.Path` objects, which are always paths."""
    return isinstance(text, str) and bool(_NAME.fullmatch(text))


def bundled_template(name: str) -> Path:
    """Path of a bundled template by name (``"super_stable"`` → ``.../super_stable.toml``).

    Raises
    ------
    KeyError
        No such bundled template, or not a name (the message lists the valid names).
    """
    folder = bundled_folder()
    path = folder / f"{name.removesuffix('.toml')}.toml" if is_template_name(name) else None
    if path is None or not path.is_file():
        raise KeyError(f"no bundled template {name!r}; valid: "
                       f"{', '.join(bundled_names()) or 'none'} (in {folder})")
    return path


def _present(path: Path) -> bool:
    """Something is at ``path`` (a link too); a name the system cannot look up (too long) is
    not there, and reading it says why."""
    try:
        return path.exists() or path.is_symlink()
    except OSError:
        return False


def resolve_template(name, base=None) -> Path:
    """The template file that ``name`` stands for: a path, or a bundled template by name.

    A ``name`` with a folder part, or a :class:`pathlib.Path`, is a path, taken as given
    (relative to ``base``). A bare name (``fourbar`` or ``fourbar.toml``) is first looked for in
    ``base``, as given and then with ``.toml`` added, so that a user's own file of that name
    wins; otherwise it is the bundled template of that name. When nothing matches the path is returned as given, for the reader to
    say that there is no such file.

    Parameters
    ----------
    name : str or pathlib.Path
    base : str or pathlib.Path, optional
        The folder relative names are read in (default: the current folder).

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> resolve_template("fourbar").name, resolve_template("fourbar").parent == bundled_folder()
    ('fourbar.toml', True)
    >>> str(resolve_template("../fourbar.toml"))
    '../fourbar.toml'
    """
    folder = Path(base) if base is not None else Path()
    given = folder / name
    if not is_template_name(name) or _present(given):
        return given
    text = name
    if not text.endswith(".toml"):
        own = folder / f"{text}.toml"
        if _present(own):
            return own
    bundled = bundled_folder() / f"{text.removesuffix('.toml')}.toml"
    return bundled if _present(bundled) and bundled.is_file() else given

