"""Stacking layers: which bar sits on which sheet layer so that nothing collides over the motion.

Bars lie flat in parallel layers, one sheet thick each, and turn on Chicago screws through
their holes. Two bars must sit on different layers when

* they share a joint (both are threaded on its screw), or
* their outlines come closer than ``clearance`` at some sampled configuration of the motion.

A screw with its heads is a column at its joint spanning the layers of its bars plus
``head_slots`` layers above and below (the heads). A bar that passes within ``clearance`` of a
column during the motion must lie outside the column's layers, and two columns that come close
must not share a layer. Those two rules depend on the order of the layers, not only on which
bars share one, so the layers are found in two steps: a graph colouring of the conflict graph
(networkx greedy strategies; the fewest colours wins, the largest clique is a lower bound), then
the order of the colour classes that breaks no column rule and needs the shortest screws.
When that breaks a column rule or uses more layers than the clique bound, the whole problem
is solved as a mixed-integer program (:mod:`fabkit.fab.layers.search`), which either proves
the layer count minimal or reports the best count found with a proven lower bound.

Sampling guarantee. The motion is sampled (adaptively, see :func:`sample_motion`) so that no
node moves more than ``h = clearance / 2`` between consecutive samples. Every point of a bar is
a convex combination of its two joints, so on the straight-line interpolation between two
samples every bar point is within ``h / 2`` of where it is at the nearer sample, and the gap
between two bars can shrink by at most ``h = clearance / 2`` relative to the nearer sample.
Bars of one layer are at least ``clearance`` apart at every sample, hence at least
``clearance / 2`` apart between samples; the true path deviates from the chord between samples
only to second order in ``h``, far below that margin.
A motion that ends in (or passes) a flat state where nodes move while the drive stands still
cannot be sampled this way; it is refused with the drive value where it happens.

Chains of modules are sampled window by window instead (:func:`sample_chain`): module k moves
exactly as the module alone at its own input distance d_k, so a few consecutive modules are
sampled as a short chain over the range d_k sweeps, where its own drive does not stand still
even when the whole chain's does (a collapse front). The work does not grow with the length.
"""


from __future__ import annotations


from .conflicts import Conflicts, find_conflicts
from .distances import point_segment_distance, segment_distance
from .gaps import stacking_gaps
from .sampling import Sweep, sample_chain, sample_motion
from .search import JointStack, Stacking, plan_layers

__all__ = ["Sweep", "sample_motion", "sample_chain", "segment_distance", "point_segment_distance",
           "Conflicts", "find_conflicts", "JointStack", "Stacking", "plan_layers",
           "stacking_gaps"]
