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
import zipfile
import zlib

import numpy as np

from ..errors import InputFileError
from .workload import allow_large

__all__ = ["MAX_DEPTH", "MAX_DIGITS", "MAX_ZIP_ENTRIES", "MAX_TOML_VALUES", "load_json",
           "parse_xml", "open_zip", "read_zip_entry", "toml_shape", "load_toml", "refuse_dxf_entities",
           "MAX_DXF_ENTITIES", "damaged", "refuse_count"]

#: Deepest nesting of arrays and objects a JSON file fabkit reads may have: FOLD, a sweep's
#: spec and chunks and the export record nest four or five levels.
MAX_DEPTH = 64
#: Most digits one number in a file may have: a float64 holds 17 significant digits, so even
#: ``0.000…1`` written out in full stays far below.
MAX_DIGITS = 400
#: Deepest nesting of XML elements (an SVG drawing's groups, a 3MF model).
MAX_XML_DEPTH = 256

#: Most entries of a ZIP package fabkit reads (a 3MF holds a model, its relationships, content
#: types and two slicer settings files: a dozen at most).
MAX_ZIP_ENTRIES = 1000
#: Most values in a TOML file (counted by its ``=`` and ``,``): a template of the largest
#: ``[network]`` allowed (200 000 nodes, their edges) holds about 1.4 million.
MAX_TOML_VALUES = 2_000_000

# a string left open runs to the end of the text (its closing quote optional): every string
# is then matched once, where a required close would rescan the rest from every quote in it
_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"?', re.S)
_LONG_NUMBER = re.compile(rb"[0-9_]{%d,}" % (MAX_DIGITS + 1))
# TOML's strings (multi-line first) and comments: blanked before brackets are counted
_TOML_TEXT = re.compile(rb'"""(?:[^\\]|\\.)*?(?:"""|\Z)|\'\'\'.*?(?:\'\'\'|\Z)'
                        rb'|"(?:[^"\\\n]|\\.)*"?|\'[^\'\n]*\'?|#[^\n]*', re.S)#: Most structure tags (entities, and the sections, tables and blocks around them) in a DXF
#: file: the bundled kits' sheets hold a few hundred to a few thousand; ezdxf reads about
#: 20 000 a second, so the bound is about 10 s of reading before the check begins.
MAX_DXF_ENTITIES = 200_000
#: DXF structure tags ezdxf reads a second (100 000 points in 4.4 s), for the estimate.
DXF_TAGS_PER_SECOND = 20_000
# a DXF structure tag: the group code 0 on its own line, then a name (a value 0 is followed by
# the next group code, a number)
_DXF_TAG = re.compile(rb"^[ \t]*0[ \t]*\r?\n[ \t]*[A-Za-z_$]", re.M)
_DTD = re.compile(rb"<!(?:DOCTYPE|ENTITY)", re.I)


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


def toml_shape(text: str, path) -> None:
    """Refuse TOML text nested too deeply, holding a number of too many digits or too many
    values, measured on the text (its strings and comments blanked out) before ``tomllib``
    parses it: the parser recurses once per level of ``[[[...]]]`` or ``{a = {b = ...}}``, and
    Python refuses an integer of more than 4 300 digits with a ValueError naming neither.

    Raises
    ------
    InputFileError
        ``kind="bounds"``: nested more than :data:`MAX_DEPTH` deep, a number of more than
        :data:`MAX_DIGITS` digits, more than :data:`MAX_TOML_VALUES` values.
    """
    bare = _TOML_TEXT.sub(b'""', text.encode("utf-8", "surrogatepass"))
    _shape(bare, path, MAX_DEPTH)
    refuse_count(path, "values", bare.count(b",") + bare.count(b"=") + 1, MAX_TOML_VALUES)


def load_toml(data: bytes | str, path, *, what: str = "TOML") -> dict:
    """A TOML document from a file's bytes (or text), its shape bounded by :func:`toml_shape`
    before ``tomllib`` parses it: the one way fabkit parses TOML it did not write (a sweep's
    spec, a ``--set`` value; templates add their own messages on top of the same bound).

    Raises
    ------
    InputFileError
        ``kind="bounds"``: as :func:`toml_shape`; ``kind="damaged"``: not UTF-8, not TOML.
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python 3.10
        import tomli as tomllib

    if not isinstance(data, str):
        try:
            data = bytes(data).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise damaged(path, f"not {what}: not UTF-8 text (byte {exc.start:,})") from None
    toml_shape(data, path)
    try:
        return tomllib.loads(data)
    except tomllib.TOMLDecodeError as exc:
        raise damaged(path, f"not {what} ({' '.join(str(exc).split())[:120]})") from None
    except RecursionError:  # within the depth bound, yet past the parser's stack: damaged
        raise damaged(path, f"not {what} (nested too deeply to parse)") from None
    except ValueError:  # Python's own bound on an integer's digits, should the bound move
        raise damaged(path, f"not {what} (a number of thousands of digits)") from None


def refuse_dxf_entities(data: bytes | str, path) -> int:
    """The count of structure tags (group code 0: entities, sections, tables, blocks) in a DXF
    file's text, counted on the bytes before ezdxf reads it; refused past
    :data:`MAX_DXF_ENTITIES`.

    Raises
    ------
    InputFileError
        ``kind="bounds"``: more tags than the bound.
    """
    if isinstance(data, str):
        data = data.encode("utf-8", "surrogatepass")
    n = sum(1 for _ in _DXF_TAG.finditer(data))
    refuse_count(path, "DXF entities (group code 0)", n, MAX_DXF_ENTITIES,
                 f" (about {n / DXF_TAGS_PER_SECOND:,.0f} s for ezdxf to read)")
    return n


def open_zip(data: bytes, path, *, what: str = "a ZIP package") -> zipfile.ZipFile:
    """A ZIP package read from bytes, its entries counted (:data:`MAX_ZIP_ENTRIES`) before any
    is read.

    Raises
    ------
    InputFileError
        ``kind="damaged"``: not a ZIP; ``kind="bounds"``: too many entries.
    """
    import io

    try:
        z = zipfile.ZipFile(io.BytesIO(data))
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError, OSError,
            NotImplementedError) as exc:
        raise damaged(path, f"not {what} ({' '.join(str(exc).split())[:120]})") from None
    refuse_count(path, "entries in its ZIP directory", len(z.infolist()), MAX_ZIP_ENTRIES)
    return z


def read_zip_entry(z: zipfile.ZipFile, name: str, path) -> bytes:
    """One entry of a package opened by :func:`open_zip`, inflated in pieces of 1 MiB and held
    to the size its ZIP directory declares (which the caller estimated before): an entry that
    inflates to more (its CRC fails at the declared size, past which nothing is inflated) or to
    less is damaged.

    Raises
    ------
    InputFileError
        ``kind="damaged"``: the entry cannot be inflated, or lies about its size.
    """
    info = z.getinfo(name)
    declared, pieces, got = info.file_size, [], 0
    try:
        # zipfile inflates no more than the declared size, and an entry that holds more fails
        # its CRC there; one that holds less is caught below
        with z.open(info) as fh:
            while piece := fh.read(1 << 20):
                pieces.append(piece)
                got += len(piece)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, OSError, EOFError,
            ValueError, RuntimeError, zlib.error) as exc:
        raise damaged(path, f"{name} cannot be inflated "
                            f"({' '.join(str(exc).split())[:120]})") from None
    if got != declared:
        raise damaged(path, f"{name} inflates to {got:,} bytes, not the {declared:,} its ZIP "
                            "directory declares")
    return b"".join(pieces)


def parse_xml(data: bytes, path, *, max_elements: int, max_depth: int = MAX_XML_DEPTH,
              what: str = "XML", no_dtd: bool = False):
    """The root element of an XML document, its elements counted and their depth bounded while
    it is parsed (in pieces of 64 kB: past a bound the rest is never parsed).

    Expat (2.4 and later) refuses entity expansion that amplifies the input; no DTD, external
    entity or XInclude is ever fetched (ElementTree fetches none).

    With ``no_dtd``, a document that declares a DTD or entities (which a format such as 3MF
    never needs) is refused before it is parsed.

    Raises
    ------
    InputFileError
        ``kind="bounds"``: more elements or deeper than the bounds; ``kind="damaged"``: not
        well-formed XML, or a DTD where ``no_dtd`` refuses one.
    """
    if no_dtd and _DTD.search(data):
        raise damaged(path, f"declares a DTD or entities, which {what} never needs")
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
