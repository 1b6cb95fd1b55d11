"""Tolerance analysis: how far a built network strays from its design, per fabrication process.

A Monte Carlo over the manufacturing errors of the process that builds the design (laser-cut
bars, a 3D print, a folded sheet; see :mod:`fabkit.tolerance.processes` for each error model and
docs/printing.md, docs/batch.md for the defaults and where they come from). Lengths are in mm and
become design units through the process's own scale (the laser settings' scale, the print's
``scale``, the origami sheet's ``sheet_size``), so every figure is in the maker's millimetres.

A build is judged by what its design is for (:mod:`fabkit.tolerance.behaviour`), inferred from
the design's module map and motion or stated in the template (``[motion] intent``): its crystal
states (the module map's fixed points exist in every built module, with the same stability,
within the state tolerance), its order (a chain's modules switch one after another, one front),
its end state (every module ends in the designed crystal, or where it locks), or, where the
target value itself is the point, the port distances at the end (within the limit: a fraction
of the module size), or the final shape of a curvature design. Lengths of what a build is made
in (a print as printed, a sheet flat) carry that state's errors only; bent hinges and folded
panels add theirs as the build moves (:func:`~fabkit.tolerance.processes.state_profile`).

A design is flagged when fewer than ``min_reached`` of the builds keep its behaviour. Every
verdict carries a margin (:mod:`fabkit.tolerance.margin`): the factor by which every error of
the process may grow with the verdict unchanged (below 1 when flagged: how much more precise
the process must be), with the fraction of builds that keep the behaviour against the error
scale, for all sources together and for each alone.

Where a construction order exists (from the start, or from the folded target for a flat origami
sheet), builds, modules and drive values are placed by intersections in vectorised passes;
otherwise each build's lengths are realised by Gauss-Newton and traced by projected
continuation (capped in number).

For chains of modules the analysis also estimates the Lyapunov exponent λ of the module map
(from the chain's own gains ∂d_{k+1}/∂d_k, or by iterating a single module's map) and the
predictability horizon k* = ln(module size / error) / λ: how many modules until a manufacturing
error grows, as e^{λk}, to the size of a module.

The package splits along the work: :mod:`.processes` (each process's error model),
:mod:`.spec` (settings and their sources), :mod:`.placement` (placing many builds at once, locks),
:mod:`.modules` (each built module's map), :mod:`.behaviour` (what a design is for),
:mod:`.criteria` (judging builds against it), :mod:`.margin` (how far errors may grow),
:mod:`.horizon` (Lyapunov exponent, predictability horizon), :mod:`.analysis` (the Monte Carlo
and its verdict), :mod:`.result` (the result object) and :mod:`.figure` (its pictures).
"""

from __future__ import annotations

# Names provided by the modules of the package, imported on first use: the command line's
# parent process reads the settings' keys and processes (:mod:`.spec`) and needs none of the
# analysis (scipy.sparse, the builds' assembly).
_LAZY = {
    "analyse_tolerance": "analysis",
    "keep_chart": "figure",
    "tolerance_figure": "figure",
    "lyapunov_estimate": "horizon",
    "PROCESSES": "processes",
    "SOURCES": "processes",
    "ToleranceResult": "result",
    **dict.fromkeys(("PROCESS_FORMATS", "TOLERANCE_KEYS", "ToleranceSpec", "design_process",
                     "key_process", "made_process", "model_summary", "perturbed_lengths",
                     "refuse_foreign", "stated_process", "tolerance_spec"), "spec"),
}


def __getattr__(name):
    import importlib

    if name in _LAZY:
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


__all__ = ["ToleranceSpec", "ToleranceResult", "tolerance_spec", "analyse_tolerance",
           "perturbed_lengths", "lyapunov_estimate", "tolerance_figure", "TOLERANCE_KEYS",
           "PROCESSES", "SOURCES", "design_process", "model_summary", "keep_chart",
           "refuse_foreign", "key_process", "made_process", "stated_process", "PROCESS_FORMATS"]
