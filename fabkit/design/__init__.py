"""Design by the map: modules from wished fixed points, slopes and cycles, chains from drawn curves.

:func:`design_map` builds a module template whose map has exactly the wished fixed points (and
slope, and 2-cycle) with the paper's construction, choosing what the construction leaves free for
a module that can be built. :func:`design_curve_chain` builds a chain of curvature modules whose
final state follows a drawn curve (:func:`read_curve` reads SVG paths and CSV polylines).
Both check their result independently: the module's map is recomputed by
:func:`fabkit.module_map` from the network the written template builds; the chain is traced to
its final state and compared with the curve.

The package holds every way fabkit designs: ``solution_space`` places the variable nodes of a
module from what its designed nodes should do (positions, velocities, final positions);
``module`` and ``wishes`` design a module from its map; ``assemble`` joins modules into chains,
branches and tessellations; ``letters`` designs chains whose final states spell letters;
``curve`` and its helpers follow a drawn curve.
"""

import importlib

# Names of the modules below, imported on first use: ``fabkit.design.assemble`` (chains, used by
# fabkit.chain) then loads without the designer's modules.
_LAZY = {
    "design_curve_chain": "curve", "CurveDesign": "curve",
    "read_curve": "curve_files", "Curve": "curve_files",
    "design_map": "module", "MapDesign": "module",
    **{name: "wishes" for name in ("FixedPointWish", "MapWish", "WishError", "check_wish",
                                   "parse_cycle", "parse_decimal", "parse_fixed_point")},
}

__all__ = ["design_map", "MapDesign", "design_curve_chain", "CurveDesign", "read_curve", "Curve",
           "WishError", "FixedPointWish", "MapWish", "check_wish", "parse_fixed_point",
           "parse_cycle", "parse_decimal"]


def __getattr__(name):
    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
