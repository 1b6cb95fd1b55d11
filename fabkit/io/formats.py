"""Every parser behind one boundary: JSON and XML read with bounds checked before the work.

A file's bytes are read by :func:`fabkit.io.inputs.read_regular` (regular, bounded in size);
what a parser then does with them is bounded here. Nesting depth, the digits of a number and the
count of items are measured on the bytes before the parser runs (a JSON array nested 10⁵ deep
exhausts the parser's stack; a 5 001-digit integer is refused by Python itself, with a
ValueError that names neither the file nor the number), and whatever the parser raises is turned
into one :class:`~fabkit.errors.InputFileError` that names the file: ``kind="damaged"`` when the
parser refused the file, ``kind="bounds"`` when a bound did. Both exit with status 2.

Examples
--------
>>> load_json(b"[[[1]]]", "a.json")
[[[1]]]
>>> load_json(b"[" * 100_000 + b"]" * 100_000, "deep.fold")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
fabkit.errors.InputFileError: deep.fold: nested 100,000 levels deep, over the limit of 64: ...
"""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET

import numpy as np

from ..errors import InputFileError
from .workload import allow_large

__all__ = ["MAX_DEPTH", "MAX_DIGITS", "load_json", "parse_xml", "damaged",
           "refuse_count"]

#: Deepest nesting of arrays and objects a JSON file fabkit reads may have: FOLD, a sweep's
#: spec and chunks and the export record nest four or five levels.
MAX_DEPTH = 64
#: Most digits one number in a file may have: a float64 holds 17 significant digits, so even
#: ``0.000…1`` written out in full stays far below.
MAX_DIGITS = 400
#: Deepest nesting of XML elements (an SVG drawing's groups, a 3MF model).
MAX_XML_DEPTH = 256

_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.S)
_LONG_NUMBER = re.compile(rb"[0-9_]{%d,}" % (MAX_DIGITS + 1))


def damaged(path, reason: str) -> InputFileError:
    """The input error for a file its parser refused, naming the file (``kind="damaged"``)."""
    return InputFileError(path, reason, kind="damaged")


def refuse_count(path, what: str, value: int, limit: int, hint: str = "") -> None:
    """Raise the input error for a count over its bound (``kind="bounds"``), unless the bounds
    are lifted (``--allow-large``)."""
    if value > limit and not allow_large():
        raise InputFileError(path, f"{value:,} {what}, over the limit of {limit:,}"
                                   f"{hint}; fabkit --allow-large lifts the limit", kind="bounds")


def _shape(bare: bytes, path, max_depth: int) -> None:
    """Depth and digits of text whose strings and comments are blanked out."""
    codes = np.frombuffer(bare, dtype=np.uint8)
    step = (np.isin(codes, (ord("["), ord("{"))).astype(np.int32)
            - np.isin(codes, (ord("]"), ord("}"))).astype(np.int32))
    depth = int(np.cumsum(step).max(initial=0))
    if depth > max_depth:
        raise InputFileError(path, f"nested {depth:,} levels deep, over the limit of "
                                   f"{max_depth}: not a file fabkit wrote or reads", kind="bounds")
    long = _LONG_NUMBER.search(bare)
    if long:
        raise InputFileError(path, f"a number of more than {MAX_DIGITS} digits (at byte "
                                   f"{long.start():,}): no measure has that many", kind="bounds")


def load_json(data: bytes, path, *, max_depth: int = MAX_DEPTH, max_items: int | None = None,
              what: str = "JSON"):
    """A JSON document from a file's bytes, its depth, digits and items bounded before parsing.

    Parameters
    ----------
    data : bytes
        The file's content (read by :func:`fabkit.io.inputs.read_regular`).
    path : str or path-like
        Named in every error.
    max_depth : int
        Deepest nesting of arrays and objects.
    max_items : int, optional
        Most values in the document (counted by its commas), e.g. a chunk's records × fields.
    what : str
        What the file should be, for the message (``"FOLD JSON"``).

    Raises
    ------
    InputFileError
        ``kind="bounds"``: over a bound; ``kind="damaged"``: not UTF-8, not JSON.
    """
    if isinstance(data, str):
        data = data.encode("utf-8", "surrogatepass")
    bare = _JSON_STRING.sub(b'""', data)
    _shape(bare, path, max_depth)
    if max_items is not None:
        refuse_count(path, "values", bare.count(b",") + 1, max_items)
    try:
        return json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise damaged(path, f"not {what}: not UTF-8 text (byte {exc.start:,})") from None
    except (ValueError, RecursionError) as exc:  # JSONDecodeError is a ValueError
        raise damaged(path, f"not {what} ({' '.join(str(exc).split())[:120]})") from None


def parse_xml(data: bytes, path, *, max_elements: int, max_depth: int = MAX_XML_DEPTH,
              what: str = "XML"):
    """The root element of an XML document, its elements counted and their depth bounded while
    it is parsed (in pieces of 64 kB: past a bound the rest is never parsed).

    Expat (2.4 and later) refuses entity expansion that amplifies the input; no DTD, external
    entity or XInclude is ever fetched (ElementTree fetches none).

    Raises
    ------
    InputFileError
        ``kind="bounds"``: more elements or deeper than the bounds; ``kind="damaged"``: not
        well-formed XML.
    """
    parser = ET.XMLPullParser(events=("start", "end"))
    count = depth = 0
    root = None
    try:
        for k in range(0, max(len(data), 1), 1 << 16):
            parser.feed(data[k:k + (1 << 16)])
            for event, element in parser.read_events():
                if event == "end":
                    depth -= 1
                    continue
                root = element if root is None else root
                count += 1
                depth += 1
                if depth > max_depth:
                    raise InputFileError(path, f"elements nested more than {max_depth} deep",
                                         kind="bounds")
            refuse_count(path, "elements", count, max_elements)
        parser.close()
    except ET.ParseError as exc:
        raise damaged(path, f"not {what} ({' '.join(str(exc).split())[:120]})") from None
    except (ValueError, RecursionError, MemoryError) as exc:
        raise damaged(path, f"not {what} ({type(exc).__name__})") from None
    if root is None:
        raise damaged(path, f"not {what} (no element)")
    return root
