"""Modules as 1-D maps d_out = f(d_in): branches, fixed points, cycles, Lyapunov exponents.

A module with one conformational motion traces a closed or open curve (d_in, d_out). Where the
network has a construction order from the d_in pair (the paper's 5-node modules, the 4-bar, and
their chains), every configuration is given in closed form by circle (2D) or sphere (3D)
intersections, with one side (+1/-1) per constructed node. Along a run of fixed sides, d_in is the
parameter of the curve, so that run is a *monotone branch*: a proper map. A branch ends where a
constructed node becomes collinear with its parents (a flat triangle): there d_in turns back, and
the motion continues with that node on the other side. :func:`module_map` walks the whole curve
this way, splitting it into branches, and returns the map on the branch through the reference
configuration.

Derivatives are exact: forward-mode differentiation of the intersection formulas (2D), or
implicit differentiation of the edge constraints (:func:`slope_at`, any network), never finite
differences. :func:`map_from_trajectory` reads a map off a traced motion (e.g. ``projected``) and
corrects every value onto the constraint set by Newton's method, so it agrees with the
constructive map to round-off.

The package splits along the work: :mod:`.results` (result objects), :mod:`.evaluate` (closed-form
evaluation and exact slopes), :mod:`.map1d` (:class:`Map1D`), :mod:`.walk` (:func:`module_map`,
walking the motion into branches) and :mod:`.from_trajectory` (:func:`map_from_trajectory`).
"""

from .evaluate import slope_at
from .from_trajectory import map_from_trajectory
from .map1d import Map1D
from .results import Branch, Cycle, FixedPoint, LyapunovResult, classify_slope
from .walk import module_map

__all__ = [
    "Map1D",
    "Branch",
    "FixedPoint",
    "Cycle",
    "LyapunovResult",
    "module_map",
    "map_from_trajectory",
    "slope_at",
    "classify_slope",
]
