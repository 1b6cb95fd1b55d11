"""The parts a laser kit's fasteners take, as lines of a bill of materials.

The catalogue of screws, pins and washers, and the choice of the fastener that holds each
joint's stack, are what a design asks of the hardware: :mod:`fabkit.settings.fasteners`. Here
they become the lines a buyer orders.
"""

from __future__ import annotations

import math

from ..settings.fasteners import merge_parts, PartLine, ScrewSpec

__all__ = ["spares", "part_lines", "part_family"]


def spares(count: int) -> int:
    """Spare parts to order beside ``count``: a tenth, at least two (small parts get lost).

    Examples
    --------
    >>> spares(5), spares(74)
    (2, 8)
    """
    return max(2, int(math.ceil(0.1 * count))) if count else 0


def part_lines(fasteners) -> list[PartLine]:
    """Every part of the given fasteners, one line per kind, in a stable order."""
    order = {"chicago screw": 0, "extension": 1, "clevis pin": 2, "split pin": 3, "washer": 4}
    merged = merge_parts(ln for f in fasteners for ln in f.parts)
    size = ("post_length_mm", "length_mm", "inner_diameter_mm", "diameter_mm")
    return sorted(merged, key=lambda ln: (order.get(ln.kind, 9),
                                          [float(ln.size.get(k, 0.0)) for k in size], ln.key))


def part_family(line: PartLine, spec: ScrewSpec) -> str:
    """The standard or product family a part line follows (what a buyer searches for)."""
    if line.kind in ("chicago screw", "extension"):
        return spec.family
    if line.kind == "clevis pin":
        return "ISO 2341 B"
    if line.kind == "split pin":
        return "ISO 1234"
    name = str(line.size.get("washer", ""))
    return " ".join(name.split()[:2]) if name[:3] in ("DIN", "ISO") else name
