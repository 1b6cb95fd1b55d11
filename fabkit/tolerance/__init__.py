"""Tolerance analysis: how far a built network strays from its design, per fabrication process.

A Monte Carlo over the manufacturing errors of the process that builds the design (laser-cut
bars, a 3D print, a folded sheet; see :mod:`fabkit.tolerance.processes` for each error model and
docs/printing.md, docs/batch.md for the defaults and where they come from). Lengths are in mm and
become design units through the process's own scale (the laser settings' scale, the print's
``scale``, the origami sheet's ``sheet_size``), so every figure is in the maker's millimetres.

Each sampled build is driven to the template's target ``motion.to`` (the input is set exactly:
the error is in the structure, not the actuation). Where a construction order exists (from the
start, or from the folded target for a flat origami sheet) all builds and all drive values are
placed by intersections in one vectorised pass; otherwise each build's lengths are realised by
Gauss-Newton and traced by projected continuation. A build that locks at a turning point short of
the target ends there (the maker pulls until it stops): it *reaches* the target when it locks
within the limit of it, and its ports are measured where it locked.

A design is flagged only when the process's errors keep it from its target: fewer than
``min_reached`` of the builds reach it, or the 95th-percentile port error exceeds the limit
(default ``limit_fraction`` of the module size, the mean designed port distance). The verdict of
a flagged design names the error source that stops it (each source is simulated alone).

For chains of modules the analysis also estimates the Lyapunov exponent λ of the module map
(from the chain's own gains ∂d_{k+1}/∂d_k, or by iterating a single module's map) and the
predictability horizon k* = ln(module size / error) / λ: how many modules until a manufacturing
error grows, as e^{λk}, to the size of a module.

The package splits along the work: :mod:`.processes` (each process's error model),
:mod:`.spec` (settings and their sources), :mod:`.placement` (placing many builds at once, locks),
:mod:`.horizon` (Lyapunov exponent, predictability horizon), :mod:`.analysis` (the Monte Carlo
and its verdict), :mod:`.result` (the result object) and :mod:`.figure` (its picture).
"""

from __future__ import annotations

from .analysis import analyse_tolerance
from .figure import tolerance_figure
from .horizon import lyapunov_estimate
from .processes import PROCESSES, SOURCES
from .result import ToleranceResult
from .spec import (TOLERANCE_KEYS, ToleranceSpec, design_process, model_summary, perturbed_lengths,
                   tolerance_spec)

__all__ = ["ToleranceSpec", "ToleranceResult", "tolerance_spec", "analyse_tolerance",
           "perturbed_lengths", "lyapunov_estimate", "tolerance_figure", "TOLERANCE_KEYS",
           "PROCESSES", "SOURCES", "design_process", "model_summary"]
