"""Layer assignment: colourings, the order of the colour classes, the layer search and the
exact solver, and the stacking they give."""

from __future__ import annotations

import itertools
import math
import sys
from dataclasses import dataclass, field

import numpy as np

from ...errors import FabricationError, ResourceError
from .conflicts import Conflicts, find_conflicts
from .constants import (DEEP_LAYERS, DEEP_NODES, DEEP_TOTAL_NODES, DUAL_BOUND_SLACK,
                        HEAD_LAYERS_SLACK, MILP_BARS, MILP_NODES, MILP_SAFETY_SECONDS,
                        MILP_STEP_NODES, MILP_STEPS)
from .distances import incidence
from .propagate import PROPAGATE_BARS, added_span, deep_search
from .sampling import Sweep

# -- layer assignment -----------------------------------------------------------------------

@dataclass(frozen=True)
class JointStack:
    """The screw at one joint, bottom to top.

    Attributes
    ----------
    joint : int
    bars : tuple of int
        Bars threaded on the screw, bottom to top.
    layers : tuple of int
        Their layers.
    spacers : tuple of int
        Layers between the lowest and highest bar that the screw passes without a bar (each
        gets a spacer ring).
    stack_height : float
        Clamped thickness (mm) = layers spanned x sheet thickness.
    screw_length : float
        Post length chosen from the catalogue (mm).
    play : float
        screw_length - stack_height (mm), at the nominal thickness without washers.
    washers : int
        Thin washers that take up play and still let the screw close on the thickest sheets.
    play_range : (float, float)
        Axial play with the washers on the thickest and on the thinnest sheets (mm).
    fastener : Fastener or None
        What holds the stack, with the parts to buy (:func:`fabkit.settings.fasteners.fit_fastener`):
        a Chicago screw, one with extensions, or a bolt set for a deep stack.
    """

    joint: int
    bars: tuple[int, ...]
    layers: tuple[int, ...]
    spacers: tuple[int, ...]
    stack_height: float
    screw_length: float
    play: float
    washers: int = 0
    play_range: tuple[float, float] = (0.0, 0.0)
    fastener: object = None

    def order(self) -> list[str]:
        """Bottom-to-top description, e.g. ``["bar 3", "spacer", "bar 0"]``."""
        lo, hi = min(self.layers), max(self.layers)
        by_layer = dict(zip(self.layers, self.bars))
        return [f"bar {by_layer[z]}" if z in by_layer else "spacer" for z in range(lo, hi + 1)]


@dataclass(frozen=True, eq=False)
class Stacking:
    """Layer of every bar and the screw stack of every joint.

    Attributes
    ----------
    layer : numpy.ndarray of int, shape (E,)
        Layer of each bar (0 = bottom).
    n_layers : int
    joints : tuple of JointStack
    conflicts : Conflicts
    lower_bound : int
        No stacking has fewer layers: the largest clique of the conflict graph, raised to the
        exact solver's proven bound when colouring alone does not reach it.
    strategy : str
        The colouring strategy that won.
    head_slots : int
        Layers a screw head occupies above and below its stack.
    """

    layer: np.ndarray
    n_layers: int
    joints: tuple[JointStack, ...]
    conflicts: Conflicts
    lower_bound: int
    strategy: str
    head_slots: int
    stats: dict = field(default_factory=dict)

    @property
    def proven_minimal(self) -> bool:
        """True when no stacking has fewer layers: the count meets the proven lower bound.

        False means fewer layers were neither found nor ruled out (the exact solver ran out of
        time): the stacking has ``n_layers``, and at least ``lower_bound`` are needed.
        """
        return self.n_layers <= self.lower_bound

    def proof_text(self) -> str:
        """The layer count with what is proven about it, e.g. ``"6 layers (proven minimal)"``
        or ``"7 layers (at least 6 needed; fewer not ruled out)"``."""
        if self.proven_minimal:
            return f"{self.n_layers} layers (proven minimal)"
        return (f"{self.n_layers} layers (at least {self.lower_bound} needed; fewer not ruled "
                "out)")

    def joint_stack(self, joint: int) -> JointStack:
        for js in self.joints:
            if js.joint == joint:
                return js
        raise KeyError(f"joint {joint} has no screw")


_STRATEGIES = ("saturation_largest_first", "largest_first", "smallest_last", "independent_set",
               "connected_sequential_bfs", "connected_sequential_dfs")
# Strategies (and colour interchange) whose networkx implementation is quadratic in the bars.
_QUADRATIC = ("saturation_largest_first", "independent_set")
_QUADRATIC_BARS = 400


def _colourings(n_bars: int, pairs: np.ndarray):
    import networkx as nx

    g = nx.Graph()
    g.add_nodes_from(range(n_bars))
    g.add_edges_from(map(tuple, pairs.tolist()))
    found = []
    large = n_bars > _QUADRATIC_BARS
    for strategy in _STRATEGIES:
        if large and strategy in _QUADRATIC:
            continue  # networkx implements these in O(n^2): keep long chains near-linear
        col = nx.greedy_color(g, strategy=strategy, interchange=not large and strategy in (
            "largest_first", "smallest_last"))
        colours = np.array([col[k] for k in range(n_bars)], dtype=np.int64)
        # renumber classes by first appearance so equal colourings compare equal
        _, first = np.unique(colours, return_index=True)
        remap = np.empty(colours.max() + 1, dtype=np.int64)
        remap[colours[np.sort(first)]] = np.arange(first.size)
        found.append((strategy, remap[colours]))
    members = max(nx.find_cliques(g), key=len, default=[]) if n_bars else []
    return found, len(members), sorted(members)


def _spans(layer: np.ndarray, joint_bars: list[np.ndarray]):
    """Lowest and highest layer at every screw joint; ``layer`` shape (P, E) -> (P, J) each."""
    lo = np.stack([layer[:, jb].min(axis=1) for jb in joint_bars], axis=1)
    hi = np.stack([layer[:, jb].max(axis=1) for jb in joint_bars], axis=1)
    return lo, hi


def _score(layer, joint_bars, jpos, keepout, joint_pairs, head, keepout_span=None):
    """(violations, total span) for candidate layer assignments ``layer`` (P, E)."""
    lo, hi = _spans(layer, joint_bars)
    viol = np.zeros(layer.shape[0], dtype=np.int64)
    for rows, slack in ((keepout, head), (keepout_span, 0)):
        if rows is None or not rows.size:
            continue
        zb = layer[:, rows[:, 0]]
        j = jpos[rows[:, 1]]
        viol += ((zb >= lo[:, j] - slack) & (zb <= hi[:, j] + slack)).sum(axis=1)
    if joint_pairs.size:
        i, j = jpos[joint_pairs[:, 0]], jpos[joint_pairs[:, 1]]
        overlap = (lo[:, i] - head <= hi[:, j] + head) & (lo[:, j] - head <= hi[:, i] + head)
        viol += overlap.sum(axis=1)
    return viol, (hi - lo).sum(axis=1)


class _ClassScore:
    """:func:`_score` of ``perm[colours]`` for permutations ``perm`` of the colour classes,
    counted over the distinct colour sets of the joints (and distinct rules between them), so
    that scoring a permutation costs the same for a chain of 10 or 10 000 modules."""

    def __init__(self, colours, joint_bars, jpos, keepout, joint_pairs, head, keepout_span):
        sets = [tuple(sorted(set(colours[jb].tolist()))) for jb in joint_bars]
        index: dict = {}
        sid = np.array([index.setdefault(t, len(index)) for t in sets], dtype=np.int64)
        width = max(len(t) for t in index)
        self.pad = np.array([t + (t[0],) * (width - len(t)) for t in index], dtype=np.int64)
        self.count = np.bincount(sid, minlength=len(index))
        rows = [np.stack([colours[r[:, 0]], sid[jpos[r[:, 1]]], np.full(len(r), slack)], axis=1)
                for r, slack in ((keepout, head), (keepout_span, 0)) if r is not None and r.size]
        rows = np.concatenate(rows) if rows else np.zeros((0, 3), dtype=np.int64)
        self.rows, self.row_count = np.unique(rows, axis=0, return_counts=True)
        pairs = np.stack([sid[jpos[joint_pairs[:, 0]]], sid[jpos[joint_pairs[:, 1]]]], axis=1) \
            if joint_pairs.size else np.zeros((0, 2), dtype=np.int64)
        self.pairs, self.pair_count = np.unique(pairs, axis=0, return_counts=True)
        self.head = head

    def __call__(self, perms: np.ndarray):
        """(violations, total span) of every permutation, ``perms`` shape (P, k)."""
        lo = perms[:, self.pad].min(axis=2)
        hi = perms[:, self.pad].max(axis=2)
        viol = np.zeros(perms.shape[0], dtype=np.int64)
        if self.rows.size:
            c, u, slack = self.rows.T
            zb = perms[:, c]
            hit = (zb >= lo[:, u] - slack) & (zb <= hi[:, u] + slack)
            viol += hit.astype(np.int64) @ self.row_count
        if self.pairs.size:
            i, j = self.pairs.T
            h = self.head
            overlap = (lo[:, i] - h <= hi[:, j] + h) & (lo[:, j] - h <= hi[:, i] + h)
            viol += overlap.astype(np.int64) @ self.pair_count
        return viol, (hi - lo) @ self.count


def _best_order(colours, k, joint_bars, jpos, keepout, joint_pairs, head, keepout_span=None):
    """Order of the k colour classes (class -> layer) with no violation and shortest screws."""
    score = _ClassScore(colours, joint_bars, jpos, keepout, joint_pairs, head, keepout_span)
    if k <= 7:
        perms = np.array(list(itertools.permutations(range(k))), dtype=np.int64)
        v, s = score(perms)
        key = v * 10**9 + s
        i = int(np.argmin(key))
        return perms[i], int(v[i])
    # many layers: pairwise swaps from the identity until no swap improves (deterministic)
    perm = np.arange(k)
    v, s = score(perm[None])
    best = (int(v[0]), int(s[0]))
    improved = True
    while improved:
        improved = False
        for i, j in itertools.combinations(range(k), 2):
            cand = perm.copy()
            cand[[i, j]] = cand[[j, i]]
            v, s = score(cand[None])
            if (int(v[0]), int(s[0])) < best:
                perm, best, improved = cand, (int(v[0]), int(s[0])), True
    return perm, best[0]


def _search_layers(n_bars, conf, joint_bars, head, layer_counts, node_limit=60_000):
    """Depth-first search for layers meeting every rule, fewest layers first.

    Every rule is monotone in a partial assignment (a joint's span only grows as its bars get
    layers), so a rule broken by a partial assignment stays broken and the branch is pruned.
    Returns the layers (E,) or None when every layer count fails or the search has visited
    ``node_limit`` partial assignments in all beyond one per bar and layer count tried (a
    bound on time, about 1 s per 20 000).
    """
    screw = conf.screw_joints.tolist()
    n_nodes = max(screw, default=-1) + 1
    bars_of = {j: jb.tolist() for j, jb in zip(screw, joint_bars)}
    joints_of = [[] for _ in range(n_bars)]
    for j, jb in bars_of.items():
        for b in jb:
            joints_of[b].append(j)
    nbrs = [[] for _ in range(n_bars)]
    for a, b in conf.pairs.tolist():
        nbrs[a].append(b)
        nbrs[b].append(a)
    avoid_of_bar = [[] for _ in range(n_bars)]   # joints whose columns bar b must avoid
    avoiders = {j: [] for j in screw}            # bars that must avoid joint j's column
    for rows, slack in ((conf.keepout, head), (conf.keepout_span, 0)):
        for b, j in rows.tolist():
            avoid_of_bar[b].append((j, slack))
            avoiders[j].append((b, slack))
    partners = {j: [] for j in screw}
    for i, j in conf.joint_pairs.tolist():
        partners[i].append(j)
        partners[j].append(i)
    # static order: breadth first through shared joints from the most constrained bar
    weight = [len(nbrs[b]) + len(avoid_of_bar[b]) for b in range(n_bars)]
    order, seen = [], [False] * n_bars
    for start in sorted(range(n_bars), key=lambda b: (-weight[b], b)):
        if seen[start]:
            continue
        queue = [start]
        seen[start] = True
        while queue:
            b = queue.pop(0)
            order.append(b)
            nxt = sorted({c for j in joints_of[b] for c in bars_of[j]} | set(nbrs[b]),
                         key=lambda c: (-weight[c], c))
            for c in nxt:
                if not seen[c]:
                    seen[c] = True
                    queue.append(c)

    budget = [node_limit]
    for k in layer_counts:
        if budget[0] < 0:
            return None
        # a stacking places every bar once: that pass is not backtracking, and the budget
        # bounds only the backtracking (else a long chain could never be placed at all)
        budget[0] += n_bars
        z = [-1] * n_bars
        lo = [None] * n_nodes
        hi = [None] * n_nodes

        def ok(b, v):
            for c in nbrs[b]:
                if z[c] == v:
                    return False
            for j, sl in avoid_of_bar[b]:
                if lo[j] is not None and lo[j] - sl <= v <= hi[j] + sl:
                    return False
            for j in joints_of[b]:
                # the column's span with b in it (conditionals: cheaper than min/max calls on
                # the search's hottest lines)
                lj = lo[j]
                if lj is None:
                    l2 = h2 = v
                else:
                    hj = hi[j]
                    l2 = v if v < lj else lj
                    h2 = v if v > hj else hj
                for c, sl in avoiders[j]:
                    zc = z[c]
                    if zc >= 0 and l2 - sl <= zc <= h2 + sl:
                        return False
                for i in partners[j]:
                    li = lo[i]
                    if li is not None and l2 - head <= hi[i] + head and li - head <= h2 + head:
                        return False
            return True

        def by_cost(b):
            """Layers 0..k-1 by the screw length they add to b's columns, then by height."""
            return sorted(range(k), key=added_span(joints_of[b], lo, hi, k).__getitem__)

        def place(pos):
            if pos == len(order):
                return True
            budget[0] -= 1
            if budget[0] < 0:
                return False
            b = order[pos]
            for v in by_cost(b):
                if not ok(b, v):
                    continue
                saved = [(j, lo[j], hi[j]) for j in joints_of[b]]
                z[b] = v
                for j in joints_of[b]:
                    lo[j] = v if lo[j] is None else min(lo[j], v)
                    hi[j] = v if hi[j] is None else max(hi[j], v)
                if place(pos + 1):
                    return True
                z[b] = -1
                for j, l0, h0 in saved:
                    lo[j], hi[j] = l0, h0
            return False

        limit = sys.getrecursionlimit()
        sys.setrecursionlimit(max(limit, n_bars + 200))  # one frame per bar placed
        try:
            if place(0):
                return np.array(z, dtype=np.int64)
        finally:
            sys.setrecursionlimit(limit)
    return None


def _shorten_screws(layer, conf, joint_bars, jpos, head, max_rounds=100):
    """Shorter screws for a valid stacking without adding layers (deterministic descent).

    First the best order of its layers (as for colour classes), then the single move (a bar to
    another layer) or, up to :data:`MILP_BARS` bars, the swap of two bars' layers that shortens
    the screws most, until none does. Every candidate is checked against every rule, so the
    result is as valid as ``layer`` and has no more layers.
    """
    k = int(layer.max()) + 1
    perm, viol = _best_order(layer, k, joint_bars, jpos, conf.keepout, conf.joint_pairs, head,
                             conf.keepout_span)
    if viol == 0:
        layer = perm[layer]
    n_bars = layer.size
    adj = np.zeros((n_bars, n_bars), dtype=np.int64)
    adj[conf.pairs[:, 0], conf.pairs[:, 1]] = 1
    adj |= adj.T
    _, span0 = _score(layer[None], joint_bars, jpos, conf.keepout, conf.joint_pairs, head,
                      conf.keepout_span)
    best = int(span0[0])
    bar_v, val_v = np.repeat(np.arange(n_bars), k), np.tile(np.arange(k), n_bars)
    sa, sb = np.triu_indices(n_bars, k=1) if n_bars <= MILP_BARS else (np.zeros(0, int),) * 2
    for _ in range(max_rounds):
        # conflict partners of every bar on every layer: a bar may go where it has none
        within = adj @ (layer[:, None] == np.arange(k)[None]).astype(np.int64)  # (E, k)
        move = (val_v != layer[bar_v]) & (within[bar_v, val_v] == 0)
        swap = ((layer[sa] != layer[sb]) & (within[sa, layer[sb]] == adj[sa, sb])
                & (within[sb, layer[sa]] == adj[sa, sb]))
        cand = np.repeat(layer[None], int(move.sum() + swap.sum()), axis=0)
        m = int(move.sum())
        cand[np.arange(m), bar_v[move]] = val_v[move]
        rows = np.arange(m, cand.shape[0])
        cand[rows, sa[swap]], cand[rows, sb[swap]] = layer[sb[swap]], layer[sa[swap]]
        if not cand.shape[0]:
            break
        v, span = _score(cand, joint_bars, jpos, conf.keepout, conf.joint_pairs, head,
                         conf.keepout_span)
        span = np.where(v == 0, span, np.iinfo(np.int64).max)
        i = int(np.argmin(span))  # the first of the shortest: deterministic
        if span[i] >= best:
            break
        layer, best = cand[i], int(span[i])
    return layer


def _neighbourhood(n_bars, conf, joint_bars, seed, size):
    """The layer problem restricted to about ``size`` bars nearest ``seed`` (breadth first over
    conflicts, shared screws and keep-outs); returns ``(n, conf, joint_bars)`` renumbered.

    Every rule of the restriction is implied by a rule of the whole (a screw's span over fewer
    bars is shorter), so no stacking of the whole has fewer layers than the restriction needs.
    """
    nbr = [[] for _ in range(n_bars)]
    for a, b in conf.pairs.tolist():
        nbr[a].append(b)
        nbr[b].append(a)
    jpos = {int(j): i for i, j in enumerate(conf.screw_joints.tolist())}
    for b, j in np.concatenate([conf.keepout, conf.keepout_span]).tolist():
        for c in joint_bars[jpos[j]].tolist():
            nbr[b].append(c)
            nbr[c].append(b)
    keep_set, queue = set(seed), list(seed)
    while queue and len(keep_set) < size:
        b = queue.pop(0)
        for c in sorted(set(nbr[b])):
            if c not in keep_set and len(keep_set) < size:
                keep_set.add(c)
                queue.append(c)
    bars = np.array(sorted(keep_set), dtype=np.int64)
    new = np.full(n_bars, -1, dtype=np.int64)
    new[bars] = np.arange(bars.size)
    pairs = new[conf.pairs]
    pairs = pairs[(pairs >= 0).all(axis=1)]
    sub_joints, sub_bars = [], []
    for j, jb in zip(conf.screw_joints.tolist(), joint_bars):
        inside = new[jb]
        inside = inside[inside >= 0]
        if inside.size:
            sub_joints.append(j)
            sub_bars.append(inside)
    has = set(sub_joints)
    def restrict(rows):
        rows = rows[[new[b] >= 0 and j in has for b, j in rows.tolist()]] if rows.size else rows
        return (np.stack([new[rows[:, 0]], rows[:, 1]], 1) if rows.size
                else rows.reshape(0, 2)).astype(np.int64)

    keep = restrict(conf.keepout)
    jp = conf.joint_pairs[[i in has and j in has for i, j in conf.joint_pairs.tolist()]] \
        if conf.joint_pairs.size else conf.joint_pairs
    sub = Conflicts(pairs=pairs, kind=np.zeros(pairs.shape[0], dtype=object),
                    gap=np.zeros(pairs.shape[0]), sample=np.zeros(pairs.shape[0], dtype=np.int64),
                    keepout=keep, joint_pairs=jp.reshape(-1, 2).astype(np.int64),
                    screw_joints=np.array(sub_joints, dtype=np.int64),
                    keepout_span=restrict(conf.keepout_span))
    return int(bars.size), sub, sub_bars


def _milp_layers(n_bars, conf, joint_bars, head, max_layers, *, node_limit=MILP_NODES,
                 safety_seconds=MILP_SAFETY_SECONDS):
    """Fewest layers (at most ``max_layers``) meeting every rule, by mixed-integer programming
    (HiGHS through SciPy).

    Variables: the layer ``z_b`` of every bar, the lowest and highest layer ``lo_j``, ``hi_j``
    of every screw, the top layer ``top``, and one binary per either-or rule (a conflicting
    pair is ordered one way or the other; a bar passing a screw lies below or above its
    column; two close screws stack one above the other). The objective is
    ``top + eps * (total screw span)``: fewest layers first, then shortest screws.

    The solver stops after ``node_limit`` branch-and-bound nodes (a count of work, so the
    answer is the same on any machine); ``safety_seconds`` of wall-clock time only guard
    against a solver that never gets there, and reaching them is an error.

    Returns
    -------
    layer : numpy.ndarray of int or None
        The best assignment found (None when none was found within the node limit).
    bound : int
        A proven lower bound on the number of layers (from the solver's dual bound).
    optimal : bool
        True when the solver proved its answer: the layer count minimal, or (no layer given)
        that no stacking fits in ``max_layers`` layers, ``bound = max_layers + 1``.

    Raises
    ------
    ResourceError
        The solver ran past ``safety_seconds`` before its node limit.
    """
    from scipy.optimize import Bounds, LinearConstraint, milp
    from scipy.sparse import coo_matrix

    E, J = n_bars, len(joint_bars)
    K = int(max_layers)
    pairs, jp = conf.pairs, conf.joint_pairs
    keep = np.concatenate([conf.keepout, conf.keepout_span]).reshape(-1, 2)
    slack = np.r_[np.full(conf.keepout.shape[0], head), np.zeros(conf.keepout_span.shape[0])]
    P, Q, R = pairs.shape[0], keep.shape[0], jp.shape[0]
    # variable layout: z (E) | lo (J) | hi (J) | top (1) | y_pairs (P) | y_keep (Q) | y_joint (R)
    iz, ilo, ihi, itop = 0, E, E + J, E + 2 * J
    iyp = itop + 1
    iyq, iyr = iyp + P, iyp + P + Q
    n = iyr + R
    jidx = {int(j): k for k, j in enumerate(conf.screw_joints.tolist())}
    rows, cols, vals, lb, ub = [], [], [], [], []
    r = 0

    def add(terms, lo_, hi_):
        nonlocal r
        for c, v in terms:
            rows.append(r)
            cols.append(c)
            vals.append(v)
        lb.append(lo_)
        ub.append(hi_)
        r += 1

    inf = np.inf
    for b in range(E):
        add([(iz + b, 1.0), (itop, -1.0)], -inf, 0.0)
    for k, jb in enumerate(joint_bars):
        for b in jb.tolist():
            add([(ilo + k, 1.0), (iz + b, -1.0)], -inf, 0.0)
            add([(iz + b, 1.0), (ihi + k, -1.0)], -inf, 0.0)
    M = float(K + 2 * head + 2)
    for t, (a, b) in enumerate(pairs.tolist()):
        y = iyp + t  # y = 1: a above b
        add([(iz + a, 1.0), (iz + b, -1.0), (iyp + t, -M)], 1.0 - M, inf)
        add([(iz + b, 1.0), (iz + a, -1.0), (y, M)], 1.0, inf)
    for t, (b, j) in enumerate(keep.tolist()):
        k, sl = jidx[j], float(slack[t])
        y = iyq + t  # y = 1: bar above the column
        add([(iz + b, 1.0), (ilo + k, -1.0), (y, -M)], -inf, -sl - 1.0)
        add([(iz + b, 1.0), (ihi + k, -1.0), (y, -M)], sl + 1.0 - M, inf)
    for t, (i, j) in enumerate(jp.tolist()):
        ki, kj = jidx[i], jidx[j]
        y = iyr + t  # y = 0: column i above column j, y = 1: j above i
        add([(ihi + kj, 1.0), (ilo + ki, -1.0), (y, -M)], -inf, -2.0 * head - 1.0)
        add([(ihi + ki, 1.0), (ilo + kj, -1.0), (y, M)], -inf, M - 2.0 * head - 1.0)
    if P:
        # turning a stacking upside down keeps every rule: fix the order of one pair
        add([(iyp, 1.0)], 0.0, 0.0)
    A = coo_matrix((vals, (rows, cols)), shape=(r, n)).tocsr()
    eps = 1.0 / (J * K + 1.0)
    c = np.zeros(n)
    c[itop] = 1.0
    c[ihi:ihi + J] = eps
    c[ilo:ilo + J] = -eps
    lower = np.zeros(n)
    upper = np.ones(n)
    upper[:itop + 1] = K - 1
    integrality = np.ones(n)
    integrality[ilo:itop] = 0  # spans follow from the integer layers
    res = milp(c, constraints=LinearConstraint(A, lb, ub), integrality=integrality,
               bounds=Bounds(lower, upper),
               options={"node_limit": int(node_limit), "time_limit": float(safety_seconds),
                        "disp": False})
    if res.status == 1 and (res.get("mip_node_count") or 0) < node_limit:
        # the clock stopped it, not the work limit: its answer would depend on the machine
        raise ResourceError(
            f"the exact layer search ran past its safety limit of {safety_seconds:g} s of "
            f"wall-clock time before its work limit of {node_limit} nodes; the machine is too "
            "busy or too slow for this kit: export it again on a quieter one")
    if res.status == 2:  # proven infeasible: every stacking needs more than max_layers
        return None, K + 1, True
    dual = getattr(res, "mip_dual_bound", None)
    bound = int(math.floor(dual + DUAL_BOUND_SLACK)) + 1 if dual is not None and np.isfinite(dual) else 0
    if res.x is None:  # no stacking found in the nodes; a dual bound past K says no more
        return None, min(bound, K + 1), False
    layer = np.rint(res.x[:E]).astype(np.int64)
    k_found = int(layer.max()) + 1 if E else 0
    return layer, min(bound, k_found), res.status == 0


def plan_layers(edges, sweep: Sweep, settings) -> Stacking:
    """Assign every bar a layer so that nothing collides over the sampled motion.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    sweep : Sweep
        The motion, sampled by :func:`sample_motion` (positions in mm).
    settings : LaserSettings
        Bar width, clearance, sheet thickness, screw entry, spacer diameter, max_layers.

    Returns
    -------
    Stacking

    Raises
    ------
    FabricationError
        When no stacking found keeps bars clear of the screws, or it needs more layers than
        ``max_layers``, or a screw longer than the catalogue has.
    ResourceError
        The exact solver ran past its wall-clock safety net (``MILP_SAFETY_SECONDS``)
        before its work limit: no stacking is given rather than one that depends on the clock.

    Examples
    --------
    >>> import numpy as np
    >>> from fabkit.settings.laser import laser_settings
    >>> x = np.array([[[0, 0], [100, 0], [100, 100]]], dtype=float)
    >>> sw = Sweep(x, np.zeros(1), 0.5, 0.0, "given", "finished", "")
    >>> plan_layers([[0, 1], [1, 2]], sw, laser_settings()).layer.tolist()
    [0, 1]
    """
    edges = np.asarray(edges, dtype=np.int64)
    s = settings
    column_radius = 0.5 * s.screw.head_diameter
    spacer_radius = 0.5 * s.spacer_diameter
    # Where the samples are farther apart than the guarantee assumes (a chain at float
    # resolution, see sample_motion's floor_limit), widen the clearance by the excess so that
    # parts of one layer stay clearance / 2 apart between samples all the same.
    clearance = s.clearance + max(0.0, sweep.max_step - sweep.step_limit)
    conf = sweep.conflicts if sweep.conflicts is not None else find_conflicts(
        edges, sweep.positions, width=s.bar_width, clearance=clearance,
        column_radius=column_radius, spacer_radius=spacer_radius)
    head = int(math.ceil(s.screw.head_height / s.thickness - HEAD_LAYERS_SLACK))
    n_bars = edges.shape[0]
    inc = incidence(edges, sweep.positions.shape[1])
    joint_bars = [np.flatnonzero(inc[j]) for j in conf.screw_joints]
    jpos = np.full(sweep.positions.shape[1], -1, dtype=np.int64)
    jpos[conf.screw_joints] = np.arange(conf.screw_joints.size)
    colourings, clique, clique_bars = _colourings(n_bars, conf.pairs)
    candidates, seen = [], set()
    for strategy, colours in colourings:
        if colours.tobytes() in seen:  # strategies often agree; order each colouring once
            continue
        seen.add(colours.tobytes())
        k = int(colours.max()) + 1 if n_bars else 0
        if joint_bars:
            perm, viol = _best_order(colours, k, joint_bars, jpos, conf.keepout,
                                     conf.joint_pairs, head, conf.keepout_span)
        else:
            perm, viol = np.arange(k), 0
        layer = perm[colours]
        span = sum(int(layer[jb].max() - layer[jb].min()) for jb in joint_bars)
        candidates.append((viol, k, span, strategy, layer))
    viol, k, span, strategy, layer = min(candidates, key=lambda c: c[:3])
    deep = None
    if viol:
        # The column rules tie layers to their order: search layer numbers directly.
        if n_bars <= PROPAGATE_BARS:
            # The complete search with every rule propagated, to a count that does not depend
            # on max_layers, so the layers found and the bound proven are the design's own (the
            # cap is applied afterwards). On the bundled kits it finds the same counts as the
            # backtracking below in a tenth of its time or less, and finds the deep kits
            # (columns standing on one another) that the backtracking gives up on.
            deep = deep_search(n_bars, conf, joint_bars, head,
                               range(max(int(clique), 1), DEEP_LAYERS + 1),
                               node_limit=DEEP_NODES, total_limit=DEEP_TOTAL_NODES)
            if deep.layer is not None:
                layer = _shorten_screws(deep.layer, conf, joint_bars, jpos, head)
                strategy, viol, k = "propagation", 0, int(layer.max()) + 1
        if viol:  # too many bars for the complete search, or its budget ran out
            found = _search_layers(n_bars, conf, joint_bars, head,
                                   range(max(int(clique), 1), s.max_layers + 1))
            if found is not None:
                layer, strategy, viol = found, "backtracking", 0
                k = int(layer.max()) + 1
    elif k > clique:
        # The colourings stop above the clique bound; the search often reaches it in a fraction
        # of a second, where the exact solver needs its whole work limit to find the same count
        # (it proves nothing the clique does not already prove once the count meets it).
        found = _search_layers(n_bars, conf, joint_bars, head, range(max(int(clique), 1), k))
        if found is not None:
            layer = _shorten_screws(found, conf, joint_bars, jpos, head)
            strategy, k = "backtracking", int(layer.max()) + 1
    bound, proven = int(clique), (not viol and k == clique)
    if deep is not None:  # the complete search proved its own bound: no solver run on top
        bound = max(bound, deep.bound)
        proven = not viol and k <= bound
    if not proven and n_bars and deep is None:
        # Colouring ignores the column rules and the search stops at its budget: ask the exact
        # solver for a stacking with fewer layers; its dual bound is a proven lower bound.
        fewer = s.max_layers if viol else k - 1
        for size in () if viol else MILP_STEPS:
            if size >= min(n_bars, MILP_BARS) or k <= bound:
                break
            sub = _neighbourhood(n_bars, conf, joint_bars, clique_bars, size)
            _, sub_bound, _ = _milp_layers(*sub, head, fewer, node_limit=MILP_STEP_NODES)
            bound = max(bound, sub_bound)
        if viol or k > bound:  # not proven by a small neighbourhood
            if n_bars > MILP_BARS:
                # A few bars around the largest clique with only the rules among them: a
                # relaxation of the whole problem, so its proven bound holds for the whole.
                sub = _neighbourhood(n_bars, conf, joint_bars, clique_bars, MILP_BARS)
                _, sub_bound, _ = _milp_layers(*sub, head, fewer)
                bound = max(bound, sub_bound)
            else:
                found, milp_bound, optimal = _milp_layers(n_bars, conf, joint_bars, head,
                                                          fewer)
                if found is not None:
                    layer, k, viol, strategy = found, int(found.max()) + 1, 0, "milp"
                bound = max(bound, milp_bound)
        proven = not viol and k == bound
    if viol:
        x0 = sweep.positions[0][conf.screw_joints]
        d0 = np.sqrt(((x0[:, None] - x0[None]) ** 2).sum(-1))
        np.fill_diagonal(d0, np.inf)
        i, j = np.unravel_index(np.argmin(d0), d0.shape) if d0.size else (0, 0)
        where = (f"up to {DEEP_LAYERS} layers" if deep is not None else
                 f"max_layers = {s.max_layers}")
        if d0.size and d0[i, j] < 2 * column_radius:
            ji, jj = int(conf.screw_joints[i]), int(conf.screw_joints[j])
            raise FabricationError(
                f"joints {ji} and {jj} are {d0[i, j]:.3g} mm apart at the start, closer than "
                f"two screw heads ({2 * column_radius:g} mm), and no stacking within {where} "
                f"separates their screws (at least {bound if deep is None else deep.bound} "
                "layers needed); merge them in the design, or for chains of modules try "
                "mirror = \"alternate\"")
    if viol and deep is not None:
        fewer = ("fewer are ruled out by complete search" if deep.bound > clique else
                 "the largest clique of the conflict graph")
        raise FabricationError(
            f"no stacking of these bars found with up to {DEEP_LAYERS} layers; at least "
            f"{deep.bound} are needed ({fewer}): "
            + _violation_message(layer, joint_bars, conf, head, edges))
    if viol:
        if bound > s.max_layers:
            raise FabricationError(
                f"every stacking of these bars needs at least {bound} layers (proven by exact "
                f"search), more than max_layers = {s.max_layers}: "
                + _violation_message(layer, joint_bars, conf, head, edges))
        raise FabricationError(
            f"no stacking found within max_layers = {s.max_layers} in the exact search's "
            f"{MILP_NODES} nodes (at least {bound} layers are needed): "
            + _violation_message(layer, joint_bars, conf, head, edges))
    if k > s.max_layers:
        found = (f"{k} layers, proven minimal" if proven else
                 f"{k} layers found, at least {bound} needed")
        raise FabricationError(
            f"the bars need a stack deeper than max_layers = {s.max_layers} ({found}: "
            f"{k * s.thickness:g} mm of {s.thickness:g} mm sheet); raise max_layers (the "
            "hardware catalogue holds deep stacks with extension posts or bolts), or make "
            "room: larger scale or narrower bars")
    stacks = []
    from ...settings.fasteners import fit_fastener

    for j, jb in zip(conf.screw_joints.tolist(), joint_bars):
        order = np.argsort(layer[jb], kind="stable")
        bars = tuple(int(v) for v in jb[order])
        layers = tuple(int(v) for v in layer[jb][order])
        lo, hi = layers[0], layers[-1]
        spacers = tuple(z for z in range(lo, hi + 1) if z not in layers)
        height = (hi - lo + 1) * s.thickness
        try:  # the fastener must close on the thickest sheets the tolerance allows
            fit = fit_fastener(s.screw, hi - lo + 1, s.thickness, s.thickness_tolerance)
        except FabricationError as exc:
            raise FabricationError(f"joint {j}: {exc}") from None
        stacks.append(JointStack(joint=j, bars=bars, layers=layers, spacers=spacers,
                                 stack_height=height, screw_length=fit.length,
                                 play=fit.length - height, washers=fit.washers,
                                 play_range=(fit.play_min, fit.play_max), fastener=fit))
    return Stacking(layer=layer, n_layers=k, joints=tuple(stacks), conflicts=conf,
                    lower_bound=int(bound), strategy=strategy, head_slots=head,
                    stats={"candidates": [(c[3], c[1], c[0]) for c in candidates],
                           "clique": int(clique), "proven_minimal": bool(proven)})


def _violation_message(layer, joint_bars, conf, head, edges) -> str:
    jpos = {int(j): i for i, j in enumerate(conf.screw_joints)}
    lo = {j: int(layer[joint_bars[i]].min()) for j, i in jpos.items()}
    hi = {j: int(layer[joint_bars[i]].max()) for j, i in jpos.items()}
    for b, j, sl in [(b, j, head) for b, j in conf.keepout.tolist()] + \
            [(b, j, 0) for b, j in conf.keepout_span.tolist()]:
        if lo[j] - sl <= layer[b] <= hi[j] + sl:
            i0, i1 = edges[b]
            return (f"bar {b} (joints {i0}-{i1}) passes the screw at joint {j} during the "
                    "motion; use a larger scale or narrower bars, or raise max_layers")
    for i, j in conf.joint_pairs.tolist():
        return (f"the screws at joints {i} and {j} come too close during the motion and no "
                "stacking separates them; the joints may coincide (for chains try mirror = "
                "\"alternate\") or use a larger scale")
    return "no collision-free stacking found"


