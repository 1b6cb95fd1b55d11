"""Beds of a printed network read back: the files of one export, and each piece back in its frame.

A print is written bed by bed (``NAME.stl``, or ``NAME_bed1.stl``, ``NAME_bed2.stl`` ... and the
same for ``.3mf``), every piece turned and moved onto its bed (:mod:`fabkit.fab.printers`). To
compare what a file holds with the design, the checks put each piece back where the design has
it: the placement the exporter chooses is recomputed from the design and the settings (the
exporters' layouts are pure, :func:`fabkit.export.stl.hinge_layout` and
:func:`fabkit.fab.pinned.pinned_print`), each body read back is given to the placed piece whose
bed rectangle holds its centre, and the placement is undone. A file made otherwise does not
match the design, and the checks say so.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

__all__ = ["bed_set", "split_bodies", "assign_bodies", "unplace"]


def bed_set(path) -> list[Path]:
    """The bed files of one export: ``NAME_bed<k>.<suffix>`` beside the given one (in bed
    order), else the file itself."""
    path = Path(path)
    m = re.fullmatch(r"(.*_bed)(\d+)(\.\w+)", path.name, flags=re.IGNORECASE)
    if not m:
        return [path]
    pattern = re.compile(re.escape(m.group(1)) + r"(\d+)" + re.escape(m.group(3)),
                         flags=re.IGNORECASE)
    found = [(int(q.group(1)), p) for p in path.parent.iterdir()
             if (q := pattern.fullmatch(p.name)) and p.is_file()]
    return [p for _, p in sorted(found)] or [path]


def split_bodies(mesh) -> list:
    """The connected shells of a mesh (trimesh), in a fixed order (by their lowest vertex)."""
    bodies = list(mesh.split(only_watertight=False))
    return sorted(bodies, key=lambda b: tuple(np.round(b.bounds[0], 6)))


def assign_bodies(bodies, placements, margin: float = 1.0) -> dict:
    """Which placed piece each body belongs to: the one whose rectangle on the bed holds the
    body's centre (``margin`` mm of slack).

    Parameters
    ----------
    bodies : list of trimesh.Trimesh
    placements : list of Placement
        The pieces on this bed.

    Returns
    -------
    dict
        Piece index -> list of bodies; bodies outside every rectangle under ``-1``.
    """
    out: dict = {}
    for body in bodies:
        c = 0.5 * (body.bounds[0][:2] + body.bounds[1][:2])
        owner = -1
        for p in placements:
            lo = _placed_box(p)
            if np.all(c >= lo[0] - margin) and np.all(c <= lo[1] + margin):
                owner = p.piece
                break
        out.setdefault(owner, []).append(body)
    return out


def _placed_box(p) -> np.ndarray:
    """The bed rectangle a placed piece fills (its turned bounding box)."""
    return np.array([p.box_lo, np.asarray(p.box_lo) + np.asarray(p.size)])


def unplace(mesh, matrix):
    """The mesh moved back from the bed by the inverse of a 4 x 4 (or 3 x 4) placement."""
    import trimesh

    m = np.eye(4)
    m[:np.asarray(matrix).shape[0], :] = matrix
    inv = np.linalg.inv(m)
    v = np.asarray(mesh.vertices, dtype=np.float64) @ inv[:3, :3].T + inv[:3, 3]
    return trimesh.Trimesh(v, np.asarray(mesh.faces), process=False)
