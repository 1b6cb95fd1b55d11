"""``--set SECTION.KEY=VALUE``: the settings a command takes over a template's.

Every command that reads settings parses them here, so that each gets the same TOML values, the
same schema check (:mod:`fabkit.io.schema`) and the same did-you-mean for a misspelt key.
"""

from __future__ import annotations

from ..errors import InputFileError, SettingsError, UsageError
from ..io.formats import load_toml, toml_shape
from ..writers import check_export_settings


def parse_settings(items) -> dict:
    """``["laser.kerf=0.2", "laser.scale=10"]`` → ``{"laser": {"kerf": 0.2, "scale": 10}}``.

    Values are parsed as TOML values (numbers, booleans, quoted strings, arrays); anything that
    is not valid TOML is kept as a plain string.

    Raises
    ------
    UsageError
        An item without ``=`` or without a dotted key, a control character (a newline), a key
        given twice, or settings that the
        schema (:mod:`fabkit.io.schema`) refuses: an unknown section or key, a wrong type, a value
        out of range.
    """

    out: dict = {}
    for item in items:
        bad = [c for c in item if ord(c) < 32 or ord(c) == 127]
        if bad:  # a newline would end the TOML value: the rest would be dropped or misread
            raise UsageError("--set", f"{item[:60]!r}: holds a control character "
                                      f"({bad[0]!r}); give one SECTION.KEY=VALUE per --set")
        key, eq, text = item.partition("=")
        key = key.strip()
        if not eq or not key:
            raise UsageError("--set", f"{item!r}: expected SECTION.KEY=VALUE, e.g. "
                                      "laser.kerf=0.2")
        parts = key.split(".")
        if len(parts) < 2 or not all(parts):
            raise UsageError("--set", f"{item!r}: the key must name a section and a key, "
                                      "e.g. laser.kerf")
        try:  # its depth, digits and values bounded before the parser runs
            toml_shape(text.strip(), key)  # measured on the value itself: its own offsets
            value = load_toml(f"v = {text.strip()}", key)["v"]
        except InputFileError as exc:
            if exc.kind == "bounds":
                raise UsageError("--set", f"{key}: {exc.reason}") from None
            value = text.strip()  # not a TOML value: a plain string
        node = out
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise UsageError("--set", f"{item!r}: {part!r} is already set to a value")
        if parts[-1] in node:
            raise UsageError("--set", f"{item!r}: {key} is given twice")
        node[parts[-1]] = value

    try:  # one declared schema: unknown sections and keys, types and ranges
        check_export_settings(out)
    except SettingsError as exc:
        raise UsageError("--set", str(exc)) from None
    return out


def read_settings(args, reads: dict, why: str) -> dict:
    """The ``--set`` settings of a command, parsed and checked as every command checks them
    (:func:`parse_settings`: the schema, did-you-mean for a misspelt
    section or key), then refused where this command does not read them, so that none is
    accepted without effect.

    Parameters
    ----------
    args : argparse.Namespace
        With ``settings``, the ``--set`` items.
    reads : dict
        Section → the keys of it the command reads (None: every key).
    why : str
        What the command reads, for the message (``"sweep reads motion.to only"``).

    Returns
    -------
    dict
        The settings nested by section.

    Raises
    ------
    UsageError
        A malformed item, a key the schema does not know, or one the command does not read.
    """

    # the schema (and pydantic) is imported when settings are read, not when the command
    # line's parser is built: `fabkit --help` starts without it
    from ..io.schema import refuse_unused

    settings = parse_settings(args.settings)
    refuse_unused(settings, set(reads), why)
    for section, keys in reads.items():
        unread = [k for k in settings.get(section, {}) if keys is not None and k not in keys]
        if unread:
            raise UsageError("--set", f"{section}.{unread[0]}: has no effect here: {why}; "
                                      "remove it")
    return settings
