"""An exact layer search that propagates every stacking rule: deep stacks and their proofs.

The rules of a stacking (see :mod:`fabkit.fab.layers`) for ``K`` layers:

* bars that conflict lie on different layers;
* a bar that passes a screw column lies outside the column's layers (its span, widened by the
  head slots above and below: ``keepout``; by nothing: ``keepout_span``);
* two screw columns that come close have disjoint layer spans, heads included: one stands
  wholly above the other (``joint_pairs``).

A screw spans only the layers of its own bars, so joints whose columns meet in the plane (two
joints that coincide, a joint folded onto its neighbour's) are legal when one stack stands on
top of the other. Such kits are deep, and the greedy colourings break the column rules there.

This search keeps the layers each bar may still take as a bit mask and, on every assignment,
removes what the rules forbid: the layer from the bar's conflicting neighbours; a column's span
from the domains of the bars that must avoid it; once a bar that must avoid a column sits at
``z``, the column's bars to one side of ``z`` (the side its first bar chose); once one column
of a close pair has a bar, the other column's bars away from it. A domain left with one layer
is assigned at once, an empty one fails the branch. Bars are chosen by the fewest layers left
per failure weight (dom/wdeg: bars that have caused failures come first), layers by the
screw length they add.

The search is complete: when it visits every branch for ``K`` layers without finding a stacking
it has proven that none exists, whatever the cap on layers. The number of branches it may visit
is a count, not a time, so a result does not depend on the machine.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from .constants import DEEP_NODES, DEEP_TOTAL_NODES

__all__ = ["DeepSearch", "deep_search", "propagate_layers", "PROPAGATE_BARS"]

#: Largest kit searched this way. A branch of a large kit looks only at the bars narrowed along
#: it (below), so the search grows with the kit about linearly: the chains that ``fabkit design
#: --curve`` makes of a 10 m sine, 207 modules (1242 bars) and of a 31 m one, 624 modules (3744
#: bars), are stacked in 8 layers, proven minimal, in 0.23 s and 0.82 s of CPU. At 800 bars (the
#: limit when every branch scanned every bar) the 207-module chain fell to the colourings and the
#: exact solver, which found no stacking in their budgets: its laser kit could not be made.
PROPAGATE_BARS = 8000
#: Kits of at least this many bars keep, along each branch, the bars whose domains were
#: narrowed, and choose the bar to place among those (and the blamed ones) instead of scanning
#: every bar; below it keeping them costs more than the scan saves (physical_fourbar_chain's 48
#: bars and curvature_chain's 96 search 5-10 % faster without; and_gate's 192 a fifth faster
#: with).
CANDIDATE_BARS = 128


@dataclass(frozen=True)
class DeepSearch:
    """What the deep search found for a range of layer counts.

    Attributes
    ----------
    layer : numpy.ndarray of int or None
        A stacking meeting every rule with the fewest layers found (None: none found).
    bound : int
        Proven lower bound: every count below it was searched completely without a stacking.
    nodes : int
        Branches visited in all.
    tried : tuple of (int, str)
        Each layer count tried and what came of it: ``"found"``, ``"none"`` (proven) or
        ``"budget"`` (not decided within the node budget).
    """

    layer: np.ndarray | None
    bound: int
    nodes: int
    tried: tuple


class _Rules:
    """The stacking rules indexed by bar and by joint, for the propagation."""

    def __init__(self, n_bars, conf, joint_bars, head):
        self.n = int(n_bars)
        self.head = int(head)
        screw = [int(j) for j in conf.screw_joints]
        self.bars_at = {j: [int(b) for b in jb] for j, jb in zip(screw, joint_bars)}
        self.joints_of = [[] for _ in range(self.n)]
        for j, bs in self.bars_at.items():
            for b in bs:
                self.joints_of[b].append(j)
        nbrs = [set() for _ in range(self.n)]
        for a, b in conf.pairs.tolist():
            nbrs[a].add(b)
            nbrs[b].add(a)
        self.nbrs = [sorted(s) for s in nbrs]
        self.avoid = [[] for _ in range(self.n)]      # bar -> (joint, slack) it must avoid
        self.avoiders = {j: [] for j in screw}         # joint -> (bar, slack) avoiding it
        for rows, slack in ((conf.keepout, self.head), (conf.keepout_span, 0)):
            for b, j in np.asarray(rows).reshape(-1, 2).tolist():
                self.avoid[b].append((j, slack))
                self.avoiders[j].append((b, slack))
        self.partners = {j: [] for j in screw}
        for i, j in np.asarray(conf.joint_pairs).reshape(-1, 2).tolist():
            self.partners[i].append(j)
            self.partners[j].append(i)
        self.degree = [len(self.nbrs[b]) + len(self.avoid[b])
                       + sum(len(self.avoiders[j]) + len(self.partners[j])
                             for j in self.joints_of[b]) for b in range(self.n)]


def propagate_layers(n_bars, conf, joint_bars, head, layers, node_limit=DEEP_NODES):
    """A stacking with at most ``layers`` layers meeting every rule, by complete search.

    Parameters
    ----------
    n_bars : int
    conf : Conflicts
    joint_bars : list of numpy.ndarray
        Bars at each screw joint, in the order of ``conf.screw_joints``.
    head : int
        Layers a screw head takes above and below its stack.
    layers : int
        Layer count allowed.
    node_limit : int
        Branches the search may visit.

    Returns
    -------
    layer : numpy.ndarray of int or None
    nodes : int
        Branches visited.
    exhausted : bool
        True when no stacking was found and every branch was visited: none exists.
    """
    rules = _Rules(n_bars, conf, joint_bars, head)
    return _search(rules, int(layers), int(node_limit), [1.0] * rules.n)


def added_span(joints, lo, hi, K: int) -> list:
    """For each layer 0..K-1, the screw length (in layers) a bar placed there adds to its
    columns ``joints``, whose placed bars span ``lo[j]..hi[j]`` (None: none placed yet)."""
    c = [0] * K
    for j in joints:
        lj = lo[j]
        if lj is not None:
            hj = hi[j]
            for v in range(min(lj, K)):
                c[v] += lj - v
            for v in range(hj + 1, K):
                c[v] += v - hj
    return c


def _search(rules: _Rules, K: int, node_limit: int, weight: list):
    n, head = rules.n, rules.head
    if n == 0:
        return np.zeros(0, dtype=np.int64), 0, False
    if K <= 0:
        return None, 0, True
    full = (1 << K) - 1
    gap = 2 * head
    bars_at, joints_of, nbrs = rules.bars_at, rules.joints_of, rules.nbrs
    # each bar's rules with the bar lists they narrow looked up once, not on every branch
    avoid = [[(j, sl, bars_at[j]) for j, sl in rules.avoid[b]] for b in range(n)]
    own = [[(j, rules.avoiders[j],
             [(i, bars_at[i]) for i in rules.partners[j]], bars_at[j])
            for j in joints_of[b]] for b in range(n)]

    # Bits of the layers from a upwards (``up[a + o]``) and from 0 up to b (``upto[b + o]``)
    # for a, b in -o..K-1+o, every bound the rules below take; the layers a..b are
    # ``up[a + o] & upto[b + o]``. Two list lookups instead of a call on the search's hottest
    # lines (the rules are checked millions of times in a deep search).
    o = gap + 2
    up = [full & ~((1 << max(a, 0)) - 1) if a < K else 0 for a in range(-o, K + o)]
    upto = [(1 << (min(b, K - 1) + 1)) - 1 if b >= 0 else 0 for b in range(-o, K + o)]

    # The layers (z) and column spans (lo, hi) are changed in place and put back on the way
    # out of a branch (ztrail, jtrail); only the domains are copied per branch.
    z = [-1] * n
    n_joints = max(bars_at, default=-1) + 1
    lo = [None] * n_joints   # lowest and highest layer of the bars placed at each joint
    hi = [None] * n_joints
    ztrail: list = []
    jtrail: list = []
    weighted = set()   # bars whose failure weight is above 1

    def assign(dom, bar, value, narrowed, z=z, lo=lo, hi=hi, nbrs=nbrs, avoid=avoid, own=own,
               up=up, upto=upto, o=o, gap=gap, weight=weight) -> bool:
        """Place ``bar`` on ``value`` and propagate; every bar whose domain was narrowed is
        added to ``narrowed``. The narrowings are listed (``touched``) in the order of the
        rules, repeats kept: that order picks the bar a failure is blamed on and the order
        in which forced bars are placed."""
        queue = [(bar, value)]
        pop, push = queue.pop, queue.append
        while queue:
            b, v = pop()
            zb = z[b]
            if zb >= 0:
                if zb != v:
                    return False
                continue
            if not (dom[b] >> v) & 1:
                return False
            z[b], dom[b] = v, 1 << v
            ztrail.append(b)
            touched: list = []
            add = touched.append
            m = ~(1 << v)
            for c in nbrs[b]:  # a neighbour on v fails whatever the narrowing before it did
                zc = z[c]
                if zc < 0:
                    dom[c] &= m
                    add(c)
                elif zc == v:
                    return False
            vo = v + o
            for j, sl, bj in avoid[b]:  # b passes column j: the column stands to one side
                lj = lo[j]
                if lj is not None:
                    if lj - sl <= v <= hi[j] + sl:
                        return False
                    side = up[vo + sl + 1] if lj > v else upto[vo - sl - 1]
                else:
                    side = ~(up[vo - sl] & upto[vo + sl])
                for c in bj:
                    if z[c] < 0:
                        dom[c] &= side
                        add(c)
            for j, avs, parts, bj in own[b]:  # b widens its own columns
                lj = lo[j]
                if lj is None:
                    l2 = h2 = v
                    jtrail.append((j, None, None))
                else:
                    hj = hi[j]
                    l2 = v if v < lj else lj
                    h2 = v if v > hj else hj
                    jtrail.append((j, lj, hj))
                lo[j], hi[j] = l2, h2
                lo2, ho2 = l2 + o, h2 + o
                # A placed bar passing the column keeps the column's bars to one side of it.
                # Placed avoiders in a row narrow the same bars one after the other: one pass
                # with their sides together lists each bar where the first pass did, and
                # again nowhere else, so the order of ``touched`` that counts is the same.
                keep = -1
                for c, sl in avs:
                    zc = z[c]
                    if zc < 0:
                        if keep != -1:
                            _narrow(dom, z, bj, keep, add)
                            keep = -1
                        dom[c] &= ~(up[lo2 - sl] & upto[ho2 + sl])
                        add(c)
                        continue
                    if l2 - sl <= zc <= h2 + sl:
                        return False
                    keep &= up[zc + o + sl + 1] if l2 > zc else upto[zc + o - sl - 1]
                if keep != -1:
                    _narrow(dom, z, bj, keep, add)
                for i, bi in parts:  # close columns: disjoint spans, heads included
                    li = lo[i]
                    if li is None:
                        side = ~(up[lo2 - gap] & upto[ho2 + gap])
                        for c in bi:
                            if z[c] < 0:
                                dom[c] &= side
                                add(c)
                        continue
                    hii = hi[i]
                    if not (hii + gap < l2 or h2 + gap < li):
                        return False
                    if hii < l2:   # column i below column j
                        s_i, s_j = upto[lo2 - gap - 1], up[hii + o + gap + 1]
                    else:
                        s_i, s_j = up[ho2 + gap + 1], upto[li + o - gap - 1]
                    for c in bi:
                        if z[c] < 0:
                            dom[c] &= s_i
                            add(c)
                    for c in bj:
                        if z[c] < 0:
                            dom[c] &= s_j
                            add(c)
            if narrowed is not None:
                narrowed.update(touched)
            # the first emptied domain in rule order fails the branch; single layers are
            # forced (0 and single bits both have no two bits set)
            for c in touched:
                d = dom[c]
                if not d & (d - 1):
                    if not d:
                        weight[c] += 1.0
                        weight[b] += 1.0
                        weighted.add(c)
                        weighted.add(b)
                        return False
                    push((c, d.bit_length() - 1))
        return True

    def _narrow(dom, z, bars, keep, add):
        for c in bars:
            if z[c] < 0:
                dom[c] &= keep
                add(c)

    def undo(zm, jm):
        for b in ztrail[zm:]:
            z[b] = -1
        del ztrail[zm:]
        for j, l2, h2 in reversed(jtrail[jm:]):  # a column's oldest span put back last
            lo[j], hi[j] = l2, h2
        del jtrail[jm:]

    layers_in: dict = {}   # domain -> its layers, ascending

    def by_added_span(b, d):
        """The layers left in domain d, by the screw length they add to b's columns, then
        by height."""
        values = layers_in.get(d)
        if values is None:
            values = layers_in[d] = [v for v in range(K) if (d >> v) & 1]
        for j in joints_of[b]:
            if lo[j] is not None:
                c = added_span(joints_of[b], lo, hi, K)
                return sorted(values, key=c.__getitem__)  # stable
        return values  # no column placed yet: nothing added anywhere, by height

    nodes = [0]
    # the bar to branch on: fewest layers left per failure weight, ties to the higher degree,
    # then the lower index (the lower rank)
    scan = sorted(range(n), key=lambda b: (-rules.degree[b], b))
    rank = [0] * n
    for r, b in enumerate(scan):
        rank[b] = r
    top = float(K)

    def choose(dom, narrowed):
        """The bar to branch on (-1: none left). A bar never narrowed and never blamed has
        every layer at weight 1, the largest key there is (K): the smallest key is among the
        narrowed and the weighted bars unless they are all at K. Then, when those bars are
        many, or when the narrowed bars are not kept (``None``), every bar is scanned."""
        best, least = -1, top
        if narrowed is not None and 2 * (len(narrowed) + len(weighted)) < n:
            br = n
            for bars in (narrowed, weighted):
                for b in bars:
                    if z[b] < 0:
                        key = dom[b].bit_count() / weight[b]
                        if key < least or (key == least and rank[b] < br):
                            best, least, br = b, key, rank[b]
            if least < top:
                return best
        best, least = -1, float("inf")
        for b in scan:
            if z[b] < 0:
                key = dom[b].bit_count() / weight[b]
                if key < least:
                    best, least = b, key
        return best

    def solve(dom, narrowed):
        nodes[0] += 1
        if nodes[0] > node_limit:
            return None
        best = choose(dom, narrowed)
        if best < 0:
            return list(z)
        values = by_added_span(best, dom[best])
        last = values[-1]
        for v in values:
            zm, jm = len(ztrail), len(jtrail)
            # the last layer tried works on this branch's own domains: the caller drops them
            # (and undoes the trail past its own mark) once this branch returns
            if v == last:
                d2, n2 = dom, narrowed
            else:
                d2, n2 = dom[:], None if narrowed is None else set(narrowed)
            if assign(d2, best, v, n2):
                found = solve(d2, n2)
                if found is not None:
                    return found
            undo(zm, jm)
            if nodes[0] > node_limit:
                return None
        return None

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, n + 200))  # one frame per bar placed
    try:
        found = solve([full] * n, set() if n >= CANDIDATE_BARS else None)
    finally:
        sys.setrecursionlimit(limit)
    if found is not None:
        return np.array(found, dtype=np.int64), nodes[0], False
    return None, nodes[0], nodes[0] <= node_limit


def deep_search(n_bars, conf, joint_bars, head, counts, *, node_limit=DEEP_NODES,
                total_limit=DEEP_TOTAL_NODES) -> DeepSearch:
    """The fewest layers among ``counts`` (ascending) for which a stacking exists.

    ``counts[0]`` must itself be a proven lower bound (the largest clique of the conflict
    graph): it is the bound reported until a count is searched completely. Each count gets up to ``node_limit`` branches (and all counts together
    ``total_limit``); a count searched completely without a stacking raises the proven bound.
    Each count starts with fresh failure weights (those learnt on a count with no stacking
    mislead the search on the next).

    Examples
    --------
    >>> import numpy as np
    >>> from fabkit.fab.layers import Conflicts
    >>> e = np.zeros((0, 2), dtype=np.int64)
    >>> conf = Conflicts(pairs=np.array([[0, 1], [1, 2], [0, 2]]), kind=np.array([]),
    ...                  gap=np.zeros(3), sample=np.zeros(3, dtype=np.int64), keepout=e,
    ...                  joint_pairs=e, screw_joints=np.zeros(0, dtype=np.int64))
    >>> r = deep_search(3, conf, [], 1, range(1, 5))
    >>> int(r.layer.max()) + 1, r.bound, [t for t in r.tried]
    (3, 3, [(1, 'none'), (2, 'none'), (3, 'found')])
    """
    rules = _Rules(n_bars, conf, joint_bars, head)
    bound, used, tried = 0, 0, []
    counts = list(counts)
    if counts:
        bound = counts[0]
    for k in counts:
        budget = min(node_limit, total_limit - used)
        if budget <= 0:
            break
        layer, nodes, exhausted = _search(rules, k, budget, [1.0] * rules.n)
        used += nodes
        if layer is not None:
            tried.append((k, "found"))
            return DeepSearch(layer, bound, used, tuple(tried))
        tried.append((k, "none" if exhausted else "budget"))
        if exhausted:  # none with at most k layers, so none with fewer either
            bound = max(bound, k + 1)
    return DeepSearch(None, bound, used, tuple(tried))
