"""Tracing the one-parameter motion of a network: :func:`trace` and its ``METHODS``.

Like ``scipy.integrate.solve_ivp``: one front function, a registry of interchangeable methods
(one file each), and a result object with a status and a message. A method that cannot reach the
target returns what it has, with the reason, rather than raising deep inside its loop.

Levels of model, cheapest first: the 1-D map (``fabkit.maps``), ``"constructive"`` (exact
placement by intersections, where a construction order exists), ``"projected"`` (pseudo-arclength
predictor-corrector on the constraint set, any network with one motion) and ``"rk4-nullspace"``
(the paper's reference method, kept as a baseline).

:func:`trace` and the registry live in ``tracer.py``; the branch-switching method of
``branching.py`` traces with it after stepping off a singular state and joins the registry here.
"""

from __future__ import annotations

from .base import Mark, Method, Solved, Problem, align_to_gauge, choose_gauge, make_problem
from .branching import BranchSwitch, analyze_bifurcation, fold_through
from .constructive import ConstructionPlan, place, plan_construction
from .stepping import Step, StepMethod, Stop
from .tracer import METHODS, select_method, trace
from ..status import Status
from .trajectory import Event, EventKind, Trajectory

__all__ = [
    "METHODS",
    "trace",
    "select_method",
    "Trajectory",
    "Status",
    "Event",
    "EventKind",
    "Method",
    "Mark",
    "Solved",
    "Step",
    "StepMethod",
    "Stop",
    "Problem",
    "make_problem",
    "ConstructionPlan",
    "plan_construction",
    "place",
    "choose_gauge",
    "align_to_gauge",
    "analyze_bifurcation",
    "fold_through",
]

# the branch-switching method traces with `trace` itself, so it joins the registry here
METHODS[BranchSwitch.name] = BranchSwitch
