"""A design's modules on their own, and the construction plan of its motion.

A chain is an iterated map only if its modules are: module k carries port d_k to port d_{k+1}.
A chain built by :func:`fabkit.chain` records its copies (``Network.assembly``), an origami chain
lists its sheets (``[fabrication.origami] sheets``), and a single module is the whole network
with ports d1 and d2. Each module becomes a network of its own (the chain's nodes and bars that
belong to it, at the chain's start) with a construction plan from its input pair.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConstructionError, FabkitError
from ..kinematics import plan_construction
from ..kinematics.constructive import cached_plan
from ..model.network import is_chain_port, Network

__all__ = ["Module", "chain_modules", "find_plan"]


@dataclass(frozen=True, eq=False)
class Module:
    """One module of a design, on its own.

    Attributes
    ----------
    index : int
        Position in the chain (0: the module driven by d1).
    nodes : numpy.ndarray of int
        The design's nodes that belong to it (its local node order).
    edges : numpy.ndarray of int
        The design's bars that belong to it, in its local edge order.
    network : Network
        The module at the design's start, with ports ``in`` (d_k) and ``out`` (d_{k+1}).
    plan : ConstructionPlan
        Construction from the ``in`` pair, sides from the reference configuration.
    eidx : numpy.ndarray of int
        Local edge of every (placed node, parent) pair of the plan (-1: none).
    rest : numpy.ndarray, shape (n, d)
        The module's nodes in the design's rest layout (the printed state).
    """

    index: int
    nodes: np.ndarray
    edges: np.ndarray
    network: Network
    plan: object
    eidx: np.ndarray
    rest: np.ndarray

    def key(self) -> tuple:
        """Modules with equal keys share one placement (same order, parents and sides)."""
        p = self.plan
        return (p.seed, p.order.tobytes(), p.parents.tobytes(), p.signs.tobytes(),
                self.eidx.tobytes())


def _node_sets(design) -> list[np.ndarray] | None:
    net = design.network
    if net.assembly is not None:
        return [np.asarray(idx, dtype=np.int64) for _m, idx, _f in net.assembly.copies]
    fab = design.fabrication if isinstance(design.fabrication, dict) else {}
    sheets = (fab.get("origami") or {}).get("sheets") if isinstance(fab.get("origami"), dict) \
        else None
    if isinstance(sheets, list) and sheets:
        try:
            return [np.asarray(s, dtype=np.int64) for s in sheets]
        except (TypeError, ValueError):
            return None
    chain = [p for p in net.ports if is_chain_port(p)]
    if sorted(chain) == ["d1", "d2"]:
        return [np.arange(net.n_nodes)]
    return None


def chain_modules(design, references) -> list[Module] | None:
    """The modules of a design, or None when it is not a chain of 1-D maps.

    Parameters
    ----------
    design : Design
    references : sequence of numpy.ndarray, shape (N, d)
        Configurations of the whole design tried in turn for the sides of each module's plan
        (its start, then its end: a flat start has no sides).

    Returns
    -------
    list of Module or None
        None when the design records no modules, a module does not hold its ports d_k and
        d_{k+1}, or a module has no construction order from d_k.
    """
    net = design.network
    sets = _node_sets(design)
    if not sets:
        return None
    lookup = {(min(i, j), max(i, j)): k for k, (i, j) in enumerate(net.edges.tolist())}
    modules = []
    for k, s in enumerate(sets):
        pin, pout = net.ports.get(f"d{k + 1}"), net.ports.get(f"d{k + 2}")
        if pin is None or pout is None or s.size != np.unique(s).size \
                or s.min() < 0 or s.max() >= net.n_nodes:
            return None
        local = {int(v): i for i, v in enumerate(s.tolist())}
        if not all(v in local for v in (*pin, *pout)):
            return None
        ids = sorted(e for (i, j), e in lookup.items() if i in local and j in local)
        edges = [[local[int(net.edges[e, 0])], local[int(net.edges[e, 1])]] for e in ids]
        ports = {"in": (local[pin[0]], local[pin[1]]), "out": (local[pout[0]], local[pout[1]])}
        plan = sub = None
        for ref in references:
            try:
                sub = Network(np.asarray(ref)[s], edges, ports)
                plan = plan_construction(sub, sub.port("in"))
                break
            except (ConstructionError, FabkitError):
                plan = None
        if plan is None or plan.order.size != s.size - 2:
            return None
        modules.append(Module(k, s, np.asarray(ids, dtype=np.int64), sub, plan,
                              plan.edge_index(sub), net.nodes[s]))
    return modules


def find_plan(problem, trajectory):
    """The cached construction plan from the start; from the target's sides when the start is a
    flat state (a flat origami sheet); None when there is no construction order."""
    try:
        return cached_plan(problem.work, problem.drive, problem.start)
    except ConstructionError:
        pass
    final = getattr(trajectory, "final", None)
    if final is None or np.shape(final) != problem.start.shape:
        return None
    try:
        return plan_construction(problem.work, problem.drive, final)
    except ConstructionError:
        return None
