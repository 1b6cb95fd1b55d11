"""Benchmark: build and verify a printed triangle-hinge network of about 1000 triangles.

:func:`benchmark_print` times each stage of the 3D-printing path on a chain of the paper's
printed module (four rigid triangles per module, Fig. 5i-k): the plate and hinge outlines, the
manifold3d solid (evaluation forced), the binary STL, reading it back with trimesh and the solid
checks, rebuilding the linkage from the solid and counting its modes, and optionally the
sequential transition on the rebuilt linkage. ``fabkit bench`` calls it; it is not a timed test.
"""

from __future__ import annotations

import io
import math
import time

import numpy as np

from ..check.stl import (as_built_tolerance, check_mesh, module_fixed_points, rebuild_linkage,
                         sequential_transition, slab_sections)
from ..design.assemble import chain
from ..writers.stl import binary_stl
from ..model.network import Network
from ..model.rigidity import count_modes

__all__ = ["PRINTED_MODULE", "printed_module", "benchmark_print"]

#: The paper's printed module ("printed_planar"): d1 = (6, 7), d2 = (1, 2); its rigid triangles
#: are (0, 1, 3), (0, 2, 4), (3, 5, 6), (4, 5, 7).
PRINTED_MODULE = {
    "nodes": [[5.2, 0.0], [5.2, -2.0], [5.2, 2.0], [4.0, -0.4], [4.0, 0.4], [2.2, 0.0],
              [0.0, -2.0], [0.0, 2.0]],
    "edges": [[0, 1], [0, 2], [0, 3], [0, 4], [1, 3], [2, 4], [3, 5], [3, 6], [4, 5], [4, 7],
              [5, 6], [5, 7]],
    "d1": (6, 7),
    "d2": (1, 2),
}


def printed_module() -> Network:
    """The printed module as a Network with ports d1 and d2."""
    m = PRINTED_MODULE
    return Network(m["nodes"], m["edges"], ports={"d1": m["d1"], "d2": m["d2"]})


def _frame_offset(net, s):
    """Design (scaled) coordinates minus print-frame coordinates (see ``print_geometry``)."""
    p = net.nodes * s.scale
    return 0.5 * (p.min(0) + p.max(0))


def benchmark_print(triangles: int = 1000, *, transition: bool = False, scale: float = 4.0,
                    settings: dict | None = None) -> dict:
    """Time building and verifying a printed chain of about ``triangles`` triangles.

    Parameters
    ----------
    triangles : int
        Target number of rigid triangles (rounded up to whole modules of 4).
    transition : bool
        Also simulate the sequential transition D1* -> D2* on the rebuilt linkage (slow for long
        chains: the front passes every module).
    scale : float
        Millimetres per design unit.
    settings : dict, optional
        Further ``[fabrication.print]`` keys (material, gap, hinge sizes ...).

    Returns
    -------
    dict
        ``modules``, ``triangles``, ``hinges``, ``mesh_triangles``, ``volume_rel_error``,
        ``watertight``, ``winding_consistent``, ``bodies``, ``conformational_modes``,
        ``node_deviation_mm``, and ``seconds``: a dict of wall times per stage
        (``network``, ``outlines``, ``solid``, ``stl``, ``read_and_check``, ``rebuild``,
        ``modes``, ``transition``, ``total``).

    Examples
    --------
    >>> r = benchmark_print(8)
    >>> r["watertight"], r["bodies"], r["conformational_modes"]
    (True, 1, 1)
    """
    import trimesh
    from scipy.spatial import cKDTree

    from ..fab.hinges import print_geometry, print_solid, solid_mesh
    from ..settings.printing import print_settings

    copies = max(1, math.ceil(triangles / 4))
    seconds = {}
    t_all = time.perf_counter()
    t = time.perf_counter()
    module = printed_module()
    net = chain(module, copies) if copies > 1 else module
    seconds["network"] = time.perf_counter() - t
    s = print_settings({"material": "TPU", "hinge_style": "neck", "hinge_width": 0.8,
                        "hinge_length": 4.0, "gap": 0.4, "scale": scale, **(settings or {})})
    t = time.perf_counter()
    geo = print_geometry(net, s)
    seconds["outlines"] = time.perf_counter() - t
    t = time.perf_counter()
    body = print_solid(geo)
    verts, faces = solid_mesh(body)  # forces manifold3d's lazy evaluation
    seconds["solid"] = time.perf_counter() - t
    t = time.perf_counter()
    data = binary_stl(verts, faces)
    seconds["stl"] = time.perf_counter() - t
    t = time.perf_counter()
    mesh = trimesh.load(io.BytesIO(data), file_type="stl", force="mesh")
    sections = slab_sections(mesh, s)
    checks = {c.name: c.as_dict() for c in check_mesh(mesh, s, geo.volume, sections)}
    seconds["read_and_check"] = time.perf_counter() - t
    t = time.perf_counter()
    built = rebuild_linkage(mesh, s, sections)
    offset = _frame_offset(net, s)
    dist, match = cKDTree(net.nodes * s.scale - offset).query(built.nodes)
    complete = len(built.nodes) == net.n_nodes and np.unique(match).size == net.n_nodes
    if complete:
        order = np.empty(net.n_nodes, dtype=np.int64)
        order[match] = np.arange(net.n_nodes)
        asbuilt = Network((built.nodes[order] + offset) / s.scale, match[built.edges],
                          ports=dict(net.ports))
    seconds["rebuild"] = time.perf_counter() - t
    t = time.perf_counter()
    modes = count_modes(asbuilt) if complete else None
    seconds["modes"] = time.perf_counter() - t
    result = {
        "modules": copies,
        "triangles": int(len(geo.triangles)),
        "hinges": int(len(geo.joints)),
        "mesh_triangles": int(len(faces)),
        "stl_bytes": len(data),
        "volume_rel_error": float(checks["volume = analytic volume of plates + hinges"]["value"]),
        "watertight": bool(mesh.is_watertight),
        "winding_consistent": bool(mesh.is_winding_consistent),
        "bodies": int(mesh.body_count),
        "thin_features": int(checks["no feature thinner than the nozzle"]["value"]),
        "rebuilt_nodes": int(len(built.nodes)),
        "rebuild_problems": list(built.problems),
        "conformational_modes": int(modes.conformational) if modes else None,
        "node_deviation_mm": float(dist.max()),
    }
    if transition and complete:
        t = time.perf_counter()
        fixed = module_fixed_points(module)
        tr = sequential_transition(asbuilt, module, copies, fixed,
                                   tolerance=as_built_tolerance(fixed, dist.max() / s.scale))
        seconds["transition"] = time.perf_counter() - t
        result["transition_ok"] = tr["ok"]
        result["transition_max_deviation"] = tr["max_deviation"]
        result["transition_tolerance"] = tr["tolerance"]
    seconds["total"] = time.perf_counter() - t_all
    result["seconds"] = seconds
    return result
