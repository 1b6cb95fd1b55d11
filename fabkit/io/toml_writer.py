"""The one TOML writer of fabkit: templates the designer, the letters and the bench write.

Every key and every scalar goes through ``tomli_w``, so a name with a newline, a quote, a
backslash or any unicode writes valid TOML that reads back equal. Arrays and tables are laid out
here (inline, or a few items a line) because a template is read by people too: one point a line,
comments that say what was wished and how it was built. Comments are the one thing tomli_w does
not write; :class:`TomlDocument` writes them, one ``#`` per line of their text.
"""

from __future__ import annotations

import math
try:  # Python 3.11+
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from collections.abc import Mapping
from typing import Any

import numpy as np
import tomli_w

from ..errors import FabkitError

__all__ = ["toml_key", "toml_value", "TomlDocument"]


def toml_key(key: str) -> str:
    """A TOML key, bare when it can be and quoted (with escapes) when it must.

    Examples
    --------
    >>> toml_key("d1"), toml_key("two words")
    ('d1', '"two words"')
    """
    text = tomli_w.dumps({str(key): 0})
    return text[: -len(" = 0\n")]


def toml_value(value: Any) -> str:
    """One value as inline TOML: scalars written by tomli_w, arrays as ``[a, b]``, mappings as
    inline tables ``{ k = v }``; NumPy scalars and arrays as their Python values.

    Examples
    --------
    >>> toml_value('say "hi"\\n'), toml_value([[0.1, 2], {"d1": [0, 1]}])
    ('"say \\\\"hi\\\\"\\\\n"', '[[0.1, 2], { d1 = [0, 1] }]')
    """
    if isinstance(value, np.ndarray):
        value = value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, Mapping):
        if not value:
            return "{}"
        return "{ " + ", ".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, float) and not math.isfinite(value):
        raise FabkitError(f"cannot write {value!r} into a template: TOML readers of other tools "
                          "may refuse inf and nan")
    return tomli_w.dumps({"v": value})[len("v = "):].rstrip("\n")


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


class TomlDocument:
    """A TOML text built line by line: comments, ``key = value`` pairs, tables.

    Examples
    --------
    >>> doc = TomlDocument()
    >>> doc.comment("a module\\nwith two comment lines")
    >>> doc.value("name", "bar \\"one\\"")
    >>> doc.table("motion")
    >>> doc.value("to", 1.5, note="the final state")
    >>> print(doc.text(), end="")
    # a module
    # with two comment lines
    name = "bar \\"one\\""
    <BLANKLINE>
    [motion]
    to = 1.5  # the final state
    """

    def __init__(self) -> None:
        self._lines: list[str] = []

    def comment(self, text: str) -> None:
        """Comment lines, one per line of ``text`` (an empty text writes a bare ``#``)."""
        for line in str(text).splitlines() or [""]:
            self._lines.append(f"# {line}".rstrip())

    def value(self, key: str, value: Any, *, note: str | None = None,
              per_line: int | None = None) -> None:
        """``key = value``, with an optional trailing comment.

        Parameters
        ----------
        key : str
        value
            Anything :func:`toml_value` writes.
        note : str, optional
            A comment after the value, on the same line (newlines become spaces).
        per_line : int, optional
            Write an array over several lines, this many items a line, indented by four spaces
            (a list of points one a line, a long list of module files three or four a line).
        """
        head = f"{toml_key(key)} = "
        if per_line is not None and isinstance(value, (list, tuple, np.ndarray)) and len(value):
            items = [toml_value(v) for v in value]
            lines = [head + "["]
            for i in range(0, len(items), per_line):
                lines.append("    " + ", ".join(items[i:i + per_line]) + ",")
            lines.append("]")
        else:
            lines = [head + toml_value(value)]
        if note:
            lines[-1] += f"  # {_one_line(note)}"
        self._lines.extend(lines)

    def table(self, name: str) -> None:
        """A blank line and the header ``[name]`` (dotted names for nested tables)."""
        if self._lines and self._lines[-1] != "":
            self._lines.append("")
        self._lines.append("[" + ".".join(toml_key(part) for part in name.split(".")) + "]")

    def mapping(self, data: Mapping, where: tuple = (), *, per_line=None) -> None:
        """Every key of ``data``: its values first, then each non-empty table under its header
        (``[motion]``, ``[motion.options]``), however deep.

        Parameters
        ----------
        data : mapping
        where : tuple of str
            The keys of the table ``data`` is (empty: the top level, no header).
        per_line : dict of str to int, optional
            Arrays written over several lines, by dotted key (``{"network.nodes": 1}``).
        """
        per_line = per_line or {}
        if where:
            if self._lines and self._lines[-1] != "":
                self._lines.append("")
            self._lines.append("[" + ".".join(toml_key(k) for k in where) + "]")
        tables = [k for k, v in data.items() if isinstance(v, Mapping) and v]
        for key, value in data.items():
            if key not in tables:
                self.value(key, value, per_line=per_line.get(".".join((*where, key))))
        for key in tables:
            self.mapping(data[key], (*where, key), per_line=per_line)

    def blank(self) -> None:
        """An empty line."""
        self._lines.append("")

    def text(self) -> str:
        """The document, ending with a newline; checked to parse (a writer's bug is caught here,
        not in a user's later run)."""
        text = "\n".join(self._lines).rstrip("\n") + "\n"
        try:
            tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:  # pragma: no cover - a bug of this module
            raise FabkitError(f"fabkit wrote a template that is not valid TOML: {exc}") from exc
        return text
