"""Limits and slacks of the stacking, with their origin."""

from __future__ import annotations


#: Samples per block when scanning pairs over the motion (bounds memory to ~block x pairs).
BLOCK_SAMPLES = 256
#: Largest (samples x pairs) block measured at once: 2^20 doubles (8 MB) per array, so the
#: kernels' temporaries stay near 100 MB however many pairs a kit has.
BLOCK_ELEMENTS = 2**20
#: Refuse motions that need more samples than this to meet the step bound.
MAX_SAMPLES = 200_000
#: Work limit of the exact layer search: branch-and-bound nodes of the solver (HiGHS through
#: SciPy); past it the best stacking found and the solver's proven lower bound are reported. A
#: count, not a time, so the result is the same on every machine, busy or quiet. It replaces a
#: 20 s limit: the solver explores about 470 nodes per second of CPU on the 60 bars of a
#: 200-module chain (17 227 nodes in 37 s of CPU), so 10 000 is about what 20 s bought on a
#: quiet 2-core machine. On the bundled kits the solver proves its answer in presolve (0 nodes,
#: ``curvature_contract``), far below the limit.
MILP_NODES = 10_000
#: Larger problems get their bound from a neighbourhood of the largest clique only.
MILP_BARS = 60
#: Smaller neighbourhoods tried first when a valid stacking is at hand (each proves a bound for
#: the whole; the bundled chains' counts are proven on 16 bars in a fifth of the time of 60).
MILP_STEPS = (16, 32)
#: The work limit of each of the :data:`MILP_STEPS` (nodes; it replaces 5 s, as
#: :data:`MILP_NODES` replaces 20 s).
MILP_STEP_NODES = 2_000
#: Safety net on the exact layer search's wall-clock time (s), far beyond the
#: :data:`MILP_NODES` (about 20 s of CPU) even on a loaded machine: reaching it raises an error
#: naming it, never a different stacking.
MILP_SAFETY_SECONDS = 900.0

# The deep search (fabkit.fab.layers.propagate) tries layer counts up to DEEP_LAYERS, whatever
# the cap (96 mm of 3 mm sheet, deeper than any kit a maker would stack), each with a budget of
# branches and all of them with a total (about 15 000 branches a second on one core): the
# bundled deep kits' proofs take 10 500 (and_gate, 12 layers) and 11 200 (curvature_chain, 15).
#: Most layers the deep search tries.
DEEP_LAYERS = 32
#: Branches the deep search may take per layer count.
DEEP_NODES = 12_000
#: Branches the deep search may take over all layer counts.
DEEP_TOTAL_NODES = 80_000


#: A sampled step may exceed its limit by this relative amount (round-off of the bisection).
STEP_RTOL = 1e-9
#: The solver's dual bound counts as an integer within this (HiGHS reports bounds to ~1e-9).
DUAL_BOUND_SLACK = 1e-6
#: Screw heads spanning a whole number of sheets to round-off take that many layers, not one more.
HEAD_LAYERS_SLACK = 1e-12


