"""Beds of a printed network read back: the files of one export, and the bodies they hold.

A print is written bed by bed (``NAME.stl``, or ``NAME_bed1.stl``, ``NAME_bed2.stl`` ... and the
same for ``.3mf``), every piece turned and moved onto its bed. The checks read every bed of the
export and find each piece in the design by its own geometry (:mod:`fabkit.check.register`);
where the writer placed it is never asked.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

__all__ = ["bed_set", "split_bodies"]


def bed_set(path, folder=None) -> list[Path]:
    """The bed files of one export: ``NAME_bed<k>.<suffix>`` beside the given one (in bed
    order), else the file itself; listed through ``folder`` (a
    :class:`fabkit.io.readback.ReadBack`, or the held folder of fabkit's own they are in)."""
    from ..io.readback import ReadBack

    path = Path(path)
    m = re.fullmatch(r"(.*_bed)(\d+)(\.\w+)", path.name, flags=re.IGNORECASE)
    if not m:
        return [path]
    pattern = re.compile(re.escape(m.group(1)) + r"(\d+)" + re.escape(m.group(3)),
                         flags=re.IGNORECASE)
    found = [(int(q.group(1)), p) for p in ReadBack.of(folder).siblings(path)
             if (q := pattern.fullmatch(p.name))]
    return [p for _, p in sorted(found)] or [path]


def split_bodies(mesh) -> list:
    """The connected shells of a mesh (trimesh), in a fixed order (by their lowest vertex),
    each as the file has it: trimesh's ``split`` fills small holes of every body by default
    (``repair=True``), which would make a body with a triangle missing watertight again."""
    bodies = list(mesh.split(only_watertight=False, repair=False))
    return sorted(bodies, key=lambda b: tuple(np.round(b.bounds[0], 6)))
