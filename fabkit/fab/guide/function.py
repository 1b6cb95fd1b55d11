"""The functional test of a design with more than one input (pure data, nothing drawn).

A design whose motion holds ports while it drives one (``[motion] hold``) has as many inputs
as ports it drives and holds: the AND gate's trunk end d1 and branch end d1_b. Its guide asks
the maker to push each input alone and then all of them, one after another, and to measure
every port that moves. The distances are those of fabkit's own tracer
(:func:`fabkit.kinematics.trace`) run on the design: each input is driven toward the design's
target (the same share of its start as the designed drive's) while the other inputs are held
where they are; an input whose motion stops before its target (a state of self-stress, a lock)
is reported where it stops, with the tracer's reason.
"""

from __future__ import annotations

import re
import string
from dataclasses import dataclass

import numpy as np

from ...errors import FabkitError
from ...kinematics import trace
from ...status import Status
from .flow import Block

__all__ = ["InputCase", "FunctionTest", "function_test", "MOVES_MM", "design_inputs", "port_key",
           "function_blocks"]

#: Why a pushed input stops before its target, in a maker's words (by the tracer's status).
_STOPS = {Status.TURNING_POINT: "the motion turns back there",
          Status.BRANCH_POINT: "the motion reaches a branch point there",
          None: "the network locks there: it cannot follow this push further"}
#: A port counts as moving in a case when its centre-to-centre distance changes by at least
#: this much (mm): what a maker reads off a ruler at once.
MOVES_MM = 0.5


@dataclass(frozen=True)
class InputCase:
    """One way of pushing the inputs.

    Attributes
    ----------
    pushed : tuple of str
        The inputs pushed, in the order they are pushed.
    reached : tuple of (str, float, float, str)
        Each pushed input: its name, where it ends (mm), its target (mm), and "" when it got
        there, else why it stopped (from the tracer's status, in words).
    moved : list of (str, float, float)
        Ports whose distance changes by at least :data:`MOVES_MM`: name, start and end (mm).
    still : list of str
        Every other port.
    """

    pushed: tuple
    reached: tuple
    moved: list
    still: list


@dataclass(frozen=True)
class FunctionTest:
    """The inputs of a design, their letters, and the cases the maker tries.

    Attributes
    ----------
    inputs : tuple of str
        The input ports in port order.
    letters : dict
        Input → its letter (``A``, ``B``, ...).
    starts_mm : dict
        Input → its distance at the start (mm).
    cases : list of InputCase
        Each input alone, then all of them.
    """

    inputs: tuple
    letters: dict
    starts_mm: dict
    cases: list


def port_key(name: str) -> tuple:
    """Ports in order along their chain: d1, d2, ..., d10, then d1_b, d2_b, ... (a branch's
    ports after the trunk's, each in its own order)."""
    m = re.fullmatch(r"([A-Za-z]*)(\d+)(\w*)", name)
    return (m.group(1), m.group(3), int(m.group(2)), "") if m else (name, "", -1, name)


def design_inputs(design) -> tuple:
    """The ports a maker pushes or holds: the designed drive and every held port, in port
    order (one input for a design that holds nothing)."""
    m = design.motion
    return tuple(sorted({m.drive, *(m.hold or ())}, key=port_key))


def _case(design, inputs, pushed, scale: float) -> InputCase:
    net, m = design.network, design.motion
    ratio = float(m.to) / float(net.port_distance(m.drive))
    x = np.asarray(net.nodes, dtype=np.float64)
    reached = []
    for p in pushed:
        target = float(net.port_distance(p)) * ratio
        held = [q for q in inputs if q != p]
        try:
            tr = trace(net, drive=p, to=target, method=m.method, start=x, hold=held,
                       keep="ports", **m.options)
        except FabkitError:  # it cannot even start: it stays where it is
            reached.append((p, float(net.port_distance(p, x)) * scale, target * scale,
                            "it does not move at all from there"))
            continue
        x = np.asarray(tr.positions[-1], dtype=np.float64)
        why = "" if tr.success else _STOPS.get(tr.status, _STOPS[None])
        reached.append((p, float(net.port_distance(p, x)) * scale, target * scale, why))
    moved, still = [], []
    for name in sorted(net.ports, key=port_key):
        a, b = float(net.port_distance(name)) * scale, float(net.port_distance(name, x)) * scale
        if abs(b - a) >= MOVES_MM:
            moved.append((name, a, b))
        else:
            still.append(name)
    return InputCase(tuple(pushed), tuple(reached), moved, still)


def function_test(design, scale: float) -> FunctionTest | None:
    """The functional test of a design with more than one input (None for one input or no
    target).

    Parameters
    ----------
    design : Design
    scale : float
        mm per design unit.

    Returns
    -------
    FunctionTest or None
    """
    m = design.motion
    if m.to is None or not m.hold or m.drive not in design.network.ports:
        return None
    net = design.network
    key = (net.nodes.tobytes(), net.edges.tobytes(), net.edge_lengths.tobytes(),
           repr(sorted(net.ports.items())), repr((m.drive, m.to, m.method, m.hold, m.options)),
           float(scale))
    if _MADE.get("key") != key:  # the same test for the kit's pictures and for its guide
        _MADE.clear()
        _MADE.update(key=key, test=_function_test(design, scale))
    return _MADE["test"]


#: The last functional test made: a laser kit's guide plan is made once for its pictures and
#: again with the design's verdict, and the test's traces (four on the AND gate) are the same.
_MADE: dict = {}


def _function_test(design, scale: float) -> FunctionTest:
    inputs = design_inputs(design)
    letters = {p: string.ascii_uppercase[k] for k, p in enumerate(inputs)}
    starts = {p: float(design.network.port_distance(p)) * scale for p in inputs}
    cases = [_case(design, inputs, (p,), scale) for p in inputs]
    cases.append(_case(design, inputs, inputs, scale))
    return FunctionTest(inputs, letters, starts, cases)


def _names(names: list) -> str:
    return ", ".join(names) if names else "none"


def function_blocks(ft: FunctionTest, net, barrel: float) -> list:
    """The functional test's text: how to push each input, and per case every port that moves
    (start → end, mm) and those that stay.

    Parameters
    ----------
    ft : FunctionTest
    net : Network
        The design's network (the inputs' joints).
    barrel : float
        The post's diameter (mm): distances are measured between posts plus this.

    Returns
    -------
    list of Block
    """
    named = "; ".join(f"{ft.letters[p]} = {p} (joints J{net.port(p)[0]} and J{net.port(p)[1]}, "
                      f"{ft.starts_mm[p]:.1f} mm apart at the start)" for p in ft.inputs)
    letters = ", ".join(ft.letters[p] for p in ft.inputs)
    intro = (f"This design has {len(ft.inputs)} inputs: {named}. Test it as a gate: push each "
             f"input alone ({letters}), holding the others where they are, then all of them, "
             "one after another in the order given; put the kit back to its start between "
             "cases. Measure each distance centre to centre: the gap between the two posts plus "
             f"{barrel:g} mm (the post diameter). A port 'moves' when its distance changes by "
             f"at least {MOVES_MM:g} mm. The numbers are fabkit's simulation of the design.")
    blocks = [Block(None, (intro,), style="body")]
    for case in ft.cases:
        who = " then ".join(f"{ft.letters[p]} ({p})" for p in case.pushed)
        held = [p for p in ft.inputs if p not in case.pushed]
        head = (f"{' + '.join(ft.letters[p] for p in case.pushed)}"
                f"{' only' if len(case.pushed) == 1 else ' (both)' if len(case.pushed) == 2 else ''}"
                f": push {who}" + (f"; hold {', '.join(ft.letters[p] for p in held)}"
                                   if held else ""))
        rows = []
        for p, end, target, why in case.reached:
            rows.append(f"{ft.letters[p]} ({p}) reaches {end:.1f} mm (target {target:.1f} mm)"
                        if not why else
                        f"{ft.letters[p]} ({p}) stops at {end:.1f} mm, {abs(end - target):.1f} mm short "
                        f"of {target:.1f} mm: {why}; do not force it")
        rows += [f"{name:>6}: {a:7.1f} → {b:7.1f} mm" for name, a, b in case.moved]
        rows.append(f"Stay within {MOVES_MM:g} mm: {_names(case.still)}")
        blocks.append(Block(head, tuple(rows)))
    return blocks
