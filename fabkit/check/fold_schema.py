"""What a FOLD file must hold before fabkit's check uses any of it (types, shapes, ranges).

A FOLD file is read from a user, so every field fabkit reads is declared here (pydantic,
strict) and checked before a number of it is used: coordinates finite and of one dimension,
indices whole and in range, assignments from the FOLD alphabet, fold angles in [-180, 180], the
``fabkit:*`` extensions with their types, and every count bounded before it sizes anything
(``fabkit:motion.samples`` is a count of configurations to fold: it goes through the work
estimate). Other keys of the FOLD specification are allowed and ignored.

:func:`fold_problems` returns the problems as sentences for the ``structure`` check; a damaged
file is a failed check (exit 1), never an internal error.
"""

from __future__ import annotations

from typing import Annotated, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..errors import BoundsError
from ..io.schema import describe_validation_error, MAX_SAMPLES_SETTING

__all__ = ["FoldFile", "fold_problems"]

#: Coordinates beyond this (mm) are not a sheet anyone folds; they also keep squares finite.
MAX_COORDINATE = 1e9

Coord = Annotated[float, Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
Index = Annotated[int, Field(ge=0)]


class _Part(BaseModel):
    # FOLD allows any other key (its own and other programs'): they are kept out of the check
    model_config = ConfigDict(extra="ignore", strict=True, allow_inf_nan=False,
                              populate_by_name=True)


class FoldFrame(_Part):
    vertices_coords: list[Annotated[list[Coord], Field(min_length=2, max_length=3)]]
    edges_foldAngle: Optional[list[Annotated[float, Field(ge=-180, le=180)]]] = None


class FoldMotion(_Part):
    drive: str
    to: float = Field(gt=0)
    samples: int = Field(ge=2, le=MAX_SAMPLES_SETTING)
    spacing: Literal["uniform", "geometric"] = "uniform"
    step_off: float = Field(1e-3, gt=0, le=0.1)
    branch: Optional[int] = None


class FoldSheet(_Part):
    vertices: list[Index]
    map: Optional[Annotated[list[str], Field(min_length=2, max_length=2)]] = None


class FoldFile(_Part):
    """The fields of a FOLD file that fabkit's check reads."""

    vertices_coords: Annotated[list[Annotated[list[Coord], Field(min_length=2, max_length=3)]],
                               Field(min_length=1)]
    edges_vertices: list[Annotated[list[Index], Field(min_length=2, max_length=2)]]
    edges_assignment: list[Literal["B", "M", "V", "F", "U", "C", "J"]]
    edges_foldAngle: Optional[list[Annotated[float, Field(ge=-180, le=180)]]] = None
    faces_vertices: list[Annotated[list[Index], Field(min_length=3)]]
    file_frames: list[FoldFrame] = []
    scale: float = Field(alias="fabkit:scale", gt=0)
    ports: dict[str, Annotated[list[Index], Field(min_length=2, max_length=2)]] = Field(
        alias="fabkit:ports", min_length=1)
    motion: FoldMotion = Field(alias="fabkit:motion")
    map: dict[str, list[Annotated[float, Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]]] = Field(
        alias="fabkit:map", min_length=1)
    sheets: list[FoldSheet] = Field([], alias="fabkit:sheets")


def _edge_problems(f) -> tuple[list[str], bool]:
    """Problems of the vertices and edges (one dimension, one entry per edge, fold angles of
    the assignment's sign), and whether every edge joins two existing vertices (if not, nothing
    that reads the edges can be checked)."""
    out = []
    nv, ne = len(f.vertices_coords), len(f.edges_vertices)
    dims = {len(c) for c in f.vertices_coords}
    if len(dims) != 1:
        out.append("vertices_coords mixes 2D and 3D vertices")
    if len(f.edges_assignment) != ne:
        out.append(f"edges_assignment has {len(f.edges_assignment)} entries for {ne} edges")
    if f.edges_foldAngle is not None and len(f.edges_foldAngle) != ne:
        out.append(f"edges_foldAngle has {len(f.edges_foldAngle)} entries for {ne} edges")
    elif f.edges_foldAngle is not None:
        wrong = [k for k, (a, t) in enumerate(zip(f.edges_assignment, f.edges_foldAngle))
                 if (a == "M" and t > 0) or (a == "V" and t < 0)]
        if wrong:
            k = wrong[0]
            out.append(f"edge {k} is {f.edges_assignment[k]} but its fold angle is "
                       f"{f.edges_foldAngle[k]} (valley positive, mountain negative)")
    if any(max(e) >= nv for e in f.edges_vertices) or any(a == b for a, b in f.edges_vertices):
        out.append("edges_vertices names vertices that do not exist (or an edge from a vertex "
                   "to itself)")
        return out, False
    return out, True


def _face_and_frame_problems(f) -> list[str]:
    """Faces made of edges, frames of every vertex in one dimension."""
    out, nv = [], len(f.vertices_coords)
    keys = {tuple(sorted(e)) for e in f.edges_vertices}
    for i, cyc in enumerate(f.faces_vertices):
        sides = list(zip(cyc, cyc[1:] + cyc[:1]))
        bad = next(((a, b) for a, b in sides if tuple(sorted((a, b))) not in keys), None)
        if bad:
            out.append(f"face {i} uses the side {bad[0]}-{bad[1]}, which is not an edge")
            break
    for k, fr in enumerate(f.file_frames):
        if len(fr.vertices_coords) != nv:
            out.append(f"file_frames[{k}] has {len(fr.vertices_coords)} vertices, not {nv}")
            break
        if len({len(c) for c in fr.vertices_coords}) != 1:
            out.append(f"file_frames[{k}] mixes 2D and 3D vertices")
            break
    return out


def _fabkit_problems(f) -> list[str]:
    """fabkit's own fields: ports and sheets naming vertices, the drive among the ports, the
    map's arrays of one length."""
    out, nv = [], len(f.vertices_coords)
    for name, (a, b) in f.ports.items():
        if max(a, b) >= nv or a == b:
            out.append(f"fabkit:ports.{name} names vertices {a}, {b} of {nv}")
    if f.motion.drive not in f.ports:
        out.append(f"fabkit:motion.drive {f.motion.drive!r} is not one of fabkit:ports")
    if f.motion.drive not in f.map:
        out.append(f"fabkit:map has no values of the drive {f.motion.drive!r}")
    lengths = {len(v) for v in f.map.values()}
    if len(lengths) > 1:
        out.append(f"fabkit:map's arrays differ in length ({sorted(lengths)})")
    elif lengths == {0}:
        out.append("fabkit:map is empty")
    unknown = sorted(set(f.map) - set(f.ports))
    if unknown:
        out.append(f"fabkit:map holds {unknown[0]!r}, which is not one of fabkit:ports")
    for k, sh in enumerate(f.sheets):
        if any(v >= nv for v in sh.vertices):
            out.append(f"fabkit:sheets[{k}] names a vertex that does not exist")
        if sh.map is not None and not set(sh.map) <= set(f.ports):
            out.append(f"fabkit:sheets[{k}].map names a port that is not in fabkit:ports")
    return out


def fold_problems(doc: dict) -> list[str]:
    """Problems of a FOLD document as sentences (empty when fabkit can use it).

    Types and ranges of every field first (:class:`FoldFile`), then what ties the fields
    together: one coordinate dimension, array lengths per edge and per vertex, indices in
    range, faces made of edges, ports and sheets naming vertices, the drive among the ports,
    the map's arrays of one length, and the work the file asks for (its samples times its
    vertices) within the bounds.
    """
    try:
        f = FoldFile.model_validate(doc)
    except ValidationError as exc:
        return [_sentence(exc)]
    nv = len(f.vertices_coords)
    out, edges_usable = _edge_problems(f)
    if not edges_usable:
        return out
    out += _face_and_frame_problems(f) + _fabkit_problems(f)
    if not out:
        from ..io.workload import require

        try:  # the file asks for a folding of samples x vertices: bounded before it starts
            require("fabkit:motion.samples", ("origami sample node", f.motion.samples * nv))
        except BoundsError as exc:
            out.append(str(exc))
    return out


def _sentence(exc: ValidationError) -> str:
    """The first error of a FOLD document as ``key[index].key: must be ..., got ...``."""
    return describe_validation_error(exc, FoldFile, "", aliases=True)
