"""Joining modules node pair to node pair: chains, sequences, branches and 2D tessellations.

A module's output port (``d_out``, e.g. "d2") is joined to the next module's input port
(``d_in``, e.g. "d1"): the two node pairs are merged and the next module is moved rigidly
(mirrored where asked) so that they coincide. In a chain each module is first put into the
configuration whose input distance equals the previous module's output distance (constructive
placement on the module alone), so the chain's reference configuration keeps every edge length
and d_{k+1} = f(d_k) holds by construction. A chain keeps ports d1 … d_{k+1}.

The general :func:`join` merges any number of node pairs (two in the plane; in 3D two shared
nodes leave a hinge about their axis, so a third shared node is needed to keep one motion) and
works for 2D and 3D networks alike; :func:`branch` attaches one network's port to another's
(the AND gate: a chain's end on another chain's middle) and :func:`tessellate` repeats a module
on a 2D lattice.

Cost: a chain of k modules is built in O(k) — one constructive placement per module whose input
differs from its reference, integer bookkeeping per module, and one vectorised transform of all
coordinates at the end.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import arguments
from ..errors import ArgumentTypeError, ArgumentValueError, FabkitError, KinematicsError
from ..io.workload import require
from ..kinematics.constructive import place, plan_construction
from ..model.network import Assembly, ChainPorts, checked_network, is_chain_port, Network
from ..numerics import DOMAIN_RTOL, rigid_fit, TINY

__all__ = [
    "chain",
    "join",
    "JoinResult",
    "join_transform",
    "branch",
    "tessellate",
    "build_chain",
    "build_tessellation",
]

# Relative mismatch allowed between the two node pairs (or node sets) that a join merges.
_JOIN_RTOL = 1e-9


#: Unit vectors whose cross product is shorter than this are parallel (or opposite) to
#: round-off: the rotation between them is the identity or a half turn.
PARALLEL_TOL = 1e-15
#: A helper axis closer than this to the rotation axis (|u × e_x| below it) is replaced by e_y,
#: which then lies at least ~0.7 away from it.
AXIS_CHOICE_TOL = 1e-8


def join_transform(src, dst, mirror: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Rigid motion ``y = x @ rot.T + shift`` taking the point pair ``src`` onto ``dst``.

    Parameters
    ----------
    src, dst : array_like, shape (2, d)
        Node pairs with equal distances.
    mirror : bool
        2D: use the improper motion (a reflection) instead of a rotation. 3D: reflect through the
        plane that contains the pair's line and the z axis (or the x axis when the line is
        vertical) before the rotation.

    Returns
    -------
    rot : numpy.ndarray, shape (d, d)
    shift : numpy.ndarray, shape (d,)

    Examples
    --------
    >>> rot, shift = join_transform([[0, 0], [1, 0]], [[2, 0], [2, 1]])
    >>> np.round(np.array([[0.0, 0.0], [1.0, 0.0]]) @ rot.T + shift, 12).tolist()
    [[2.0, 0.0], [2.0, 1.0]]
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    d = src.shape[1]
    u = src[1] - src[0]
    v = dst[1] - dst[0]
    if d == 2:
        au = math.atan2(u[1], u[0])
        av = math.atan2(v[1], v[0])
        if mirror:
            # reflect across the line of u, then rotate u onto v
            c, s = math.cos(2 * au), math.sin(2 * au)
            refl = np.array([[c, s], [s, -c]])
        else:
            refl = np.eye(2)
        a = av - au
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]) @ refl
    else:
        un = u / np.linalg.norm(u)
        vn = v / np.linalg.norm(v)
        refl = np.eye(3)
        if mirror:
            ref_axis = np.array([0.0, 0.0, 1.0]) if abs(un[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
            normal = np.cross(un, ref_axis)
            normal /= np.linalg.norm(normal)
            refl = np.eye(3) - 2.0 * np.outer(normal, normal)
        w = np.cross(un, vn)
        c = float(un @ vn)
        if np.linalg.norm(w) < PARALLEL_TOL:
            if c > 0:
                r = np.eye(3)
            else:  # half turn about any axis perpendicular to u
                perp = np.cross(un, [1.0, 0.0, 0.0])
                if np.linalg.norm(perp) < AXIS_CHOICE_TOL:
                    perp = np.cross(un, [0.0, 1.0, 0.0])
                perp /= np.linalg.norm(perp)
                r = 2.0 * np.outer(perp, perp) - np.eye(3)
        else:
            k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
            r = np.eye(3) + k + k @ k / (1.0 + c)
        rot = r @ refl
    shift = dst[0] - src[0] @ rot.T
    return rot, shift


@dataclass(frozen=True)
class JoinResult:
    """The outcome of :func:`join`.

    Attributes
    ----------
    network : Network
        The joined network: the first network's nodes keep their indices 0..N1-1, the second's
        unshared nodes follow in their original order.
    second_index : numpy.ndarray of int, shape (N2,)
        Where each node of the second network went.
    """

    network: Network
    second_index: np.ndarray


def _pairs_from(first: Network, second: Network, at) -> list[tuple[int, int]]:
    if isinstance(at, tuple) and len(at) == 2 and all(isinstance(p, str) for p in at):
        pa, pb = at
        for net, p, which in ((first, pa, "first"), (second, pb, "second")):
            if p not in net.ports:
                known = ", ".join(sorted(net.ports)) or "none"
                raise FabkitError(f"the {which} network has no port {p!r}; its ports: {known}")
        (a0, a1), (b0, b1) = first.port(pa), second.port(pb)
        return [(a0, b0), (a1, b1)]
    try:
        pairs = [(int(i), int(j)) for i, j in at]
    except (TypeError, ValueError):
        raise FabkitError(
            f"`at` must be two port names or a list of (first node, second node) pairs, got {at!r}"
        ) from None
    return pairs


def join(first: Network, second: Network, at, *, mirror: bool = False,
         ports: str = "{name}_b", second_positions=None) -> JoinResult:
    """Merge nodes of ``second`` into nodes of ``first``, moving ``second`` rigidly.

    Parameters
    ----------
    first, second : Network
        Networks of the same dimension.
    at : (str, str) or sequence of (int, int)
        Two port names ``(port_of_first, port_of_second)`` — the port pairs are merged in order —
        or explicit ``(node_of_first, node_of_second)`` pairs (at least 2; in 3D give 3 nodes
        not on one line, or the two parts keep a free hinge rotation about the shared axis).
    mirror : bool
        Move ``second`` by an improper motion (its mirror image is joined).
    ports : str
        Format for the second network's port names in the result (``{name}`` is replaced).
    second_positions : array_like, shape (N2, d), optional
        Configuration of ``second`` to join (its reference by default); it must keep the edge
        lengths.

    Returns
    -------
    JoinResult

    Raises
    ------
    FabkitError
        Different dimensions, unknown ports, node indices out of range, merged node sets whose
        shapes differ (the distances do not match), or port names that collide.

    Examples
    --------
    >>> bar = Network([[0, 0], [1, 0], [0, 1]], [[0, 1], [0, 2]], ports={"p": (1, 2)})
    >>> res = join(bar, bar, ("p", "p"), mirror=True)
    >>> res.network.n_nodes, res.second_index.tolist()
    (4, [3, 1, 2])
    """
    if first.dim != second.dim:
        raise FabkitError(f"cannot join a {second.dim}D network to a {first.dim}D network")
    pairs = _pairs_from(first, second, at)
    if len(pairs) < 2:
        raise FabkitError(f"a join merges at least 2 node pairs, got {len(pairs)}")
    for i, j in pairs:
        if not 0 <= i < first.n_nodes:
            raise FabkitError(f"node {i} is not in the first network (nodes 0..{first.n_nodes - 1})")
        if not 0 <= j < second.n_nodes:
            raise FabkitError(f"node {j} is not in the second network (nodes 0..{second.n_nodes - 1})")
    fa = np.array([p[0] for p in pairs])
    sb = np.array([p[1] for p in pairs])
    if len(set(fa.tolist())) != len(fa) or len(set(sb.tolist())) != len(sb):
        raise FabkitError("each node may be merged only once in a join")
    y = second.nodes if second_positions is None else np.asarray(second_positions, dtype=np.float64)
    if y.shape != second.nodes.shape:
        raise FabkitError(f"`second_positions` must have shape {second.nodes.shape}, got {y.shape}")
    src, dst = y[sb], first.nodes[fa]
    if len(pairs) == 2:
        rot, shift = join_transform(src, dst, mirror=mirror)
    else:
        fit = rigid_fit(src, dst, handedness="improper" if mirror else "proper")
        rot, shift = fit.rotation, fit.shift
    scale = max(first.size, second.size, TINY)
    # The merged node sets must have the same shape: compare all their pairwise distances.
    dist_first = np.linalg.norm(dst[:, None] - dst[None], axis=-1)
    dist_second = np.linalg.norm(src[:, None] - src[None], axis=-1)
    gap = np.abs(dist_first - dist_second)
    if gap.max() > _JOIN_RTOL * scale:
        u, v = np.unravel_index(int(np.argmax(gap)), gap.shape)
        raise FabkitError(
            f"the merged nodes do not match: nodes {fa[u]} and {fa[v]} are "
            f"{dist_first[u, v]:.10g} apart in the first network but nodes {sb[u]} and {sb[v]} "
            f"are {dist_second[u, v]:.10g} apart in the second"
        )
    moved = y @ rot.T + shift
    if float(np.abs(moved[sb] - dst).max()) > 1e3 * _JOIN_RTOL * scale:
        raise FabkitError("the merged nodes cannot be brought together by a rigid motion "
                          f"{'with' if mirror else 'without'} reflection; try mirror={not mirror}")
    index = np.full(second.n_nodes, -1, dtype=np.int64)
    index[sb] = fa
    fresh = index < 0
    index[fresh] = first.n_nodes + np.arange(int(fresh.sum()))
    nodes = np.concatenate([first.nodes, moved[fresh]], axis=0)
    nodes[fa] = first.nodes[fa]  # shared nodes stay exactly where the first network has them
    new_edges = index[second.edges]
    edges = np.concatenate([first.edges, new_edges], axis=0)
    # An edge present in both networks between merged nodes is one bar, not two.
    key = np.sort(edges, axis=1)
    _, keep = np.unique(key, axis=0, return_index=True)
    edges = edges[np.sort(keep)]
    out_ports = dict(first.ports)
    for name, (i, j) in second.ports.items():
        new = ports.format(name=name)
        if new in out_ports:
            raise FabkitError(f"port {new!r} exists in both networks; pass another `ports` format")
        out_ports[new] = (int(index[i]), int(index[j]))
    return JoinResult(Network(nodes, edges, out_ports), index)


def branch(trunk: Network, limb: Network, *, at: str, end: str, mirror: bool = False,
           swap: bool = False, ports: str = "{name}_b") -> Network:
    """Attach the port ``end`` of ``limb`` to the port ``at`` of ``trunk`` (e.g. its middle).

    The AND gate of the paper is ``branch(chain8, chain8, at="d5", end="d9")``: the end of one
    super-stable chain joined to the middle of another, the free ends facing outwards.

    Parameters
    ----------
    trunk, limb : Network
    at : str
        Port of the trunk (its nodes keep their indices).
    end : str
        Port of the limb merged onto ``at``, first node onto first node.
    mirror : bool
        Join the limb's mirror image.
    swap : bool
        Merge the limb's port nodes in reverse order.
    ports : str
        Format of the limb's port names in the result (default ``"{name}_b"``: d1_b, d2_b, …).

    Returns
    -------
    Network

    Raises
    ------
    FabkitError
        Unknown ports or distances that differ between the two ports.
    ArgumentTypeError
        ``trunk`` or ``limb`` not a Network, ``at`` or ``end`` not a port name.

    Examples
    --------
    >>> rod = Network([[0, 0], [1, 0], [2, 0.5]], [[0, 2], [1, 2]], ports={"p": (0, 1)})
    >>> net = branch(rod, rod, at="p", end="p", mirror=True)
    >>> net.n_nodes, sorted(net.ports), net.nodes[3].tolist()
    (4, ['p', 'p_b'], [2.0, -0.5])
    """
    trunk, limb = checked_network("trunk", trunk), checked_network("limb", limb)
    for net, p, which in ((trunk, at, "trunk"), (limb, end, "limb")):
        if not isinstance(p, str):
            raise ArgumentTypeError("at" if which == "trunk" else "end",
                                    f"must be a port name, got {type(p).__name__}")
        if p not in net.ports:
            raise FabkitError(f"the {which} has no port {p!r}")
    (a0, a1), (b0, b1) = trunk.port(at), limb.port(end)
    pairs = [(a0, b1), (a1, b0)] if swap else [(a0, b0), (a1, b1)]
    return join(trunk, limb, pairs, mirror=mirror, ports=ports).network


def _module_at(module: Network, d_in: str, value: float, plan_cache: dict) -> np.ndarray:
    """Module configuration with its input distance at ``value`` (same branch as its reference)."""
    ref = plan_cache.get("ref")
    if ref is None:
        ref = plan_cache["ref"] = float(module.port_distance(d_in))
    if abs(value - ref) <= DOMAIN_RTOL * max(ref, 1.0):
        return module.nodes
    if "plan" not in plan_cache:
        plan_cache["plan"] = plan_construction(module, module.port(d_in))
    x, margin, _ = place(plan_cache["plan"], [value])
    if margin[0] < 0:
        raise KinematicsError(f"the module has no configuration with {d_in} = {value:.10g}")
    return x[0]


#: Two nodes of a chain closer than this share of its size stand on one another: the modules
#: were joined on the wrong side (a 5-node module of the paper chained unmirrored folds back
#: onto the module before it, five of its nodes on that module's nodes).
COINCIDENT_RTOL = 1e-9


def _mirror_flags(mirror, k: int) -> list[bool]:
    if mirror is None:
        return [False] * k
    if isinstance(mirror, str):
        arguments.choice("mirror", mirror, ("auto", "alternate", "none"))
        return [mirror == "alternate" and c % 2 == 1 for c in range(k)]
    if not isinstance(mirror, (list, tuple)) or not all(isinstance(f, bool) for f in mirror):
        raise ArgumentTypeError("mirror", "must be 'auto', 'alternate', 'none' or a list of "
                                          f"booleans, got {type(mirror).__name__}")
    if len(mirror) != k:
        raise ArgumentValueError("mirror", f"has {len(mirror)} entries for {k} modules")
    return list(mirror)


#: Candidate pairs :func:`stacked_nodes` measures at once (bounds its memory when many nodes
#: share a coordinate, as the nodes of a straight chain do).
STACKED_CHUNK = 1 << 20


def stacked_nodes(nodes, tol: float) -> int:
    """How many pairs of nodes stand within ``tol`` of one another.

    Sorted along the coordinate of widest spread, only pairs within ``tol`` along it are
    measured (numpy alone: a template's chain is built by the command line's parent process
    too, which loads no scipy).

    Parameters
    ----------
    nodes : array_like, shape (N, d)
    tol : float
        Largest distance of a pair counted (inclusive).

    Returns
    -------
    int
        Unordered pairs ``i < j`` with ``|x_i - x_j| <= tol``.
    """
    x = np.asarray(nodes, dtype=float)
    n = x.shape[0]
    if n < 2:
        return 0
    axis = int(np.argmax(np.ptp(x, axis=0)))
    x = x[np.argsort(x[:, axis], kind="stable")]
    key = x[:, axis]
    rows = np.arange(n)
    # node i's candidates are the nodes i+1 .. ends[i]-1 after it in that order
    counts = np.searchsorted(key, key + tol, side="right") - rows - 1
    total, start = 0, 0
    while start < n:
        upto = np.cumsum(counts[start:])
        stop = start + max(1, int(np.searchsorted(upto, STACKED_CHUNK, side="right")))
        c = counts[start:stop]
        i = np.repeat(rows[start:stop], c)
        j = i + 1 + np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        d = x[j] - x[i]
        total += int(np.count_nonzero(np.einsum("ij,ij->i", d, d) <= tol * tol))
        start = stop
    return total


def _stacked_nodes(net: Network) -> int:
    """How many pairs of a network's nodes stand on one another (:data:`COINCIDENT_RTOL`)."""
    return stacked_nodes(net.nodes, COINCIDENT_RTOL * max(float(net.size), 1.0))


#: Modules of a chain that ``mirror="auto"`` builds to look for nodes standing on one another:
#: the whole chain up to this length (then it is the chain returned), its first modules beyond.
#: A module whose copies turn by 360°/n closes a ring after n copies, so a short prefix misses
#: it (a designed module with a fixed point at 1 stacks its 7th copy on its 1st).
AUTO_PROBE_MODULES = 256


def _auto_chain(seq: list, d_in: str, d_out: str):
    """The chain of ``seq`` joined as it is when no two of its nodes stand on one another, else
    with every second module mirrored, with the rule used; (network, rule) or (None, rule) when
    only a prefix was probed (the caller builds the whole chain with that rule).

    Raises
    ------
    FabkitError
        Neither keeps the nodes apart (pass ``mirror`` as a list of booleans).
    """
    probe = seq[:AUTO_PROBE_MODULES]
    found = {}
    for rule in ("none", "alternate"):
        net = chain(probe, d_in=d_in, d_out=d_out, mirror=rule)
        found[rule] = _stacked_nodes(net)
        if not found[rule]:
            return (net if len(probe) == len(seq) else None), rule
    raise FabkitError(f"the modules stand on one another however they are chained: joined as "
                      f"they are, {found['none']} pair(s) of nodes of the first "
                      f"{len(probe)} modules coincide, every second one mirrored "
                      f"{found['alternate']}; pass mirror as a list of booleans, one per module")


def chain(modules, copies: int | None = None, *, d_in: str = "d1", d_out: str = "d2",
          mirror="auto") -> Network:
    """Join modules in a chain, each one's ``d_out`` port onto the next one's ``d_in`` port.

    Parameters
    ----------
    modules : Network or sequence of Network
        One module (repeated ``copies`` times) or the sequence of modules to join (repeated
        ``copies`` times when ``copies`` is given).
    copies : int, optional
        Number of copies when ``modules`` is a single module.
    d_in, d_out : str
        Port names of a module's input and output pairs (``d_in="d2", d_out="d1"`` chains the
        inverse map).
    mirror : "auto", "alternate", "none" or sequence of bool
        Mirror every second module (``"alternate"``: the paper's 5-node modules, whose output
        pair lies the other way round from their input pair), none (``"none"`` or None), or the
        modules flagged True. ``"auto"`` (the default) picks what planar modules need: none when
        joined as they are no two nodes of the chain stand on one another, else
        ``"alternate"`` (3D modules: none); the whole chain is looked at up to
        :data:`AUTO_PROBE_MODULES` modules, its first ones beyond; the chain's
        ``assembly.mirrored`` says which copies it mirrored.

    Returns
    -------
    Network
        Ports ``d1 … d{k+1}`` (the chain's distances, d_{k+1} = f(d_k)); a module's other ports
        appear as ``name_k`` for module k (1-based).

    Raises
    ------
    FabkitError
        Missing ports, mismatched dimensions, a module that cannot take the previous output
        distance (it lies outside the module's range), or (``"auto"``) modules whose nodes
        stand on one another mirrored or not.

    Notes
    -----
    O(k). A chain whose modules sit at their references (a chain at a fixed point of its map,
    the usual long chain) is built from arrays, its ports a :class:`ChainPorts` table and its
    :class:`~fabkit.model.network.Assembly` one index array per distinct module: a million
    super-stable modules in a few seconds. Other chains are built module by module, each placed
    at the distance the one before gives it.

    Examples
    --------
    >>> fourbar = Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]],
    ...                   ports={"d1": (0, 1), "d2": (2, 3)})
    >>> net = chain(fourbar, copies=3)
    >>> net.n_nodes, sorted(net.ports)
    (8, ['d1', 'd2', 'd3', 'd4'])
    """
    if isinstance(modules, Network):
        if copies is None:
            raise ArgumentTypeError("copies", "is needed with one module (how many copies?)")
        base = [modules]
    elif isinstance(modules, (list, tuple)):
        base = list(modules)
        if not base:
            raise ArgumentValueError("modules", "must hold at least one module")
        for c, m in enumerate(base):
            checked_network(f"modules[{c}]", m)
    else:
        raise ArgumentTypeError("modules", "must be a fabkit.Network or a list of them, got "
                                           f"{type(modules).__name__}")
    repeat = 1 if copies is None else arguments.whole("copies", copies, minimum=1)
    # the whole chain's size, before a node of it is made
    require("chain", ("node", repeat * sum(m.n_nodes for m in base)))
    seq = base * repeat
    k = len(seq)
    if isinstance(mirror, str) and mirror == "auto":
        # planar modules: a mirror image is the module's other handedness; a 3D module's
        # mirror is through a plane of the designer's choosing, so it is never guessed
        mirror = "none"
        if k > 1 and base[0].dim == 2:
            whole, mirror = _auto_chain(seq, d_in, d_out)
            if whole is not None:
                return whole
    flags = _mirror_flags(mirror, k)
    dim = seq[0].dim
    # Per distinct module: ports, the local ranks of the nodes that a joined copy adds, and a
    # cache for constructive placement.
    kinds: dict[int, dict] = {}
    for c, m in enumerate(base):  # the sequence repeats these: each distinct one is among them
        if m.dim != dim:
            raise FabkitError(f"module {c + 1} is {m.dim}D but module 1 is {dim}D")
        if id(m) in kinds:
            continue
        arguments.port("d_in", d_in, m)
        arguments.port("d_out", d_out, m)
        i0, i1 = m.port(d_in)
        o0, o1 = m.port(d_out)
        fresh = np.ones(m.n_nodes, dtype=bool)
        fresh[[i0, i1]] = False
        rank = np.cumsum(fresh) - 1
        kinds[id(m)] = dict(inp=(i0, i1), out=(o0, o1), fresh=fresh, rank=rank,
                            d_ref=float(m.port_distance(d_in)), d_out_ref=float(m.port_distance(d_out)),
                            src_ref=m.nodes[[i0, i1]], dst_ref=m.nodes[[o0, o1]],
                            fresh_ref=m.nodes[fresh],
                            n_fresh=int(fresh.sum()), cache={},
                            extra=[(n, p) for n, p in m.ports.items() if n not in (d_in, d_out)])

    fast = _chain_at_reference(base, repeat, kinds, flags, dim, d_in)
    if fast is not None:
        return fast
    local_blocks, edge_blocks, layout = [], [], []
    src = np.empty((k, 2, dim))   # each module's input pair, in its own (local) frame
    dst = np.empty((k, 2, dim))   # its output pair, local frame
    ports: dict[str, tuple[int, int]] = {}
    n_total = 0
    prev_out = None  # global indices of the previous module's output pair
    d_value = float(seq[0].port_distance(d_in))
    for c, m in enumerate(seq):
        kind = kinds[id(m)]
        i0, i1 = kind["inp"]
        o0, o1 = kind["out"]
        if abs(d_value - kind["d_ref"]) <= DOMAIN_RTOL * max(kind["d_ref"], 1.0):
            x, fresh_block = m.nodes, kind["fresh_ref"]  # at its reference: nothing to place
            src[c], dst[c] = kind["src_ref"], kind["dst_ref"]
            d_value = kind["d_out_ref"]
        else:
            try:
                x = _module_at(m, d_in, d_value, kind["cache"])
            except KinematicsError as exc:
                raise FabkitError(f"module {c + 1} of the chain: {exc}") from None
            fresh_block = x[kind["fresh"]]
            src[c], dst[c] = x[[i0, i1]], x[[o0, o1]]
            d_value = float(np.linalg.norm(dst[c, 1] - dst[c, 0]))
        if prev_out is None:
            index = np.arange(m.n_nodes, dtype=np.int64)
            n_new = m.n_nodes
            local_blocks.append(x)
        else:
            index = n_total + kind["rank"]
            index[i0], index[i1] = prev_out
            n_new = kind["n_fresh"]
            local_blocks.append(fresh_block)
        edge_blocks.append(index[m.edges])
        layout.append((m, index, bool(flags[c])))
        n_total += n_new
        gi = index.tolist()
        if c == 0:
            ports["d1"] = (gi[i0], gi[i1])
        prev_out = (gi[o0], gi[o1])
        ports[f"d{c + 2}"] = prev_out
        for name, (a, b) in kind["extra"]:
            ports[f"{name}_{c + 1}"] = (gi[a], gi[b])
    counts = np.array([b.shape[0] for b in local_blocks])
    owner = np.repeat(np.arange(k), counts)
    local = np.concatenate(local_blocks, axis=0)
    if dim == 2:
        nodes = _place_chain_2d(src, dst, np.array(flags), local, owner)
    else:
        nodes = _place_chain_3d(src, dst, flags, local, owner)
    edges = np.concatenate(edge_blocks, axis=0)
    # how the chain was joined, so that a construction plan can be tiled from the modules' own
    # plans instead of searched node by node (see fabkit.kinematics.constructive.cached_plan)
    return Network(nodes, edges, ports, assembly=Assembly.from_copies(layout, d_in))


def _chain_at_reference(base, repeat, kinds, flags, dim, d_in) -> Network | None:
    """The chain built from arrays when every module sits at its own reference (each one's
    output distance is the next one's input distance as drawn: a chain at a fixed point of its
    map, the usual large chain) and no module has ports besides its input and output; None
    otherwise (the module-by-module build places each one at its input).

    Node indices: a copy's new nodes follow the earlier copies' in order; its input pair is the
    previous copy's output pair, found by pointer jumping where an output node is itself an
    input node (the super-stable module's d2 = (1, 2) shares node 1 with its d1 = (0, 1)).
    """
    ids = list(kinds)
    where = {key: q for q, key in enumerate(ids)}
    info = [kinds[key] for key in ids]
    if any(kk["extra"] for kk in info):
        return None
    kid = np.tile(np.array([where[id(m)] for m in base], dtype=np.int64), repeat)
    d_ref = np.array([kk["d_ref"] for kk in info])
    d_out = np.array([kk["d_out_ref"] for kk in info])
    prev, this = d_out[kid[:-1]], d_ref[kid[1:]]
    if np.any(np.abs(prev - this) > DOMAIN_RTOL * np.maximum(this, 1.0)):
        return None
    k = kid.size
    modules = [base[int(np.flatnonzero(kid == q)[0])] for q in range(len(info))]
    first = modules[kid[0]]
    counts = np.array([kk["n_fresh"] for kk in info], dtype=np.int64)[kid]
    counts[0] = first.n_nodes
    offset = np.concatenate([[0], np.cumsum(counts)[:-1]])
    # the output pair of every copy: a new node of it, or one of its input nodes (the previous
    # copy's output): pointers back, resolved by doubling
    val = np.full(2 * k, -1, dtype=np.int64)
    ptr = np.full(2 * k, -1, dtype=np.int64)
    for q, kk in enumerate(info):
        members = np.flatnonzero(kid == q)
        for s, o in enumerate(kk["out"]):
            if kk["fresh"][o]:
                val[2 * members + s] = offset[members] + kk["rank"][o]
            else:
                ptr[2 * members + s] = 2 * (members - 1) + (0 if o == kk["inp"][0] else 1)
    val[:2] = info[kid[0]]["out"]  # the first copy keeps its own numbering
    ptr[:2] = -1
    open_ = np.flatnonzero(ptr >= 0)
    while open_.size:
        target = ptr[open_]
        done = ptr[target] < 0
        val[open_[done]] = val[target[done]]
        ptr[open_[done]] = -1
        ptr[open_[~done]] = ptr[target[~done]]
        open_ = open_[~done]
    out_pair = val.reshape(k, 2)
    in_pair = np.empty((k, 2), dtype=np.int64)
    in_pair[0] = info[kid[0]]["inp"]
    in_pair[1:] = out_pair[:-1]
    n_total = int(counts.sum())
    local = np.empty((n_total, dim))
    e_counts = np.array([modules[q].n_edges for q in range(len(info))], dtype=np.int64)[kid]
    e_offset = np.concatenate([[0], np.cumsum(e_counts)[:-1]])
    edges = np.empty((int(e_counts.sum()), 2), dtype=np.int64)
    index = []
    for q, kk in enumerate(info):
        m = modules[q]
        members = np.flatnonzero(kid == q)
        idx = offset[members][:, None] + kk["rank"][None, :]
        i0, i1 = kk["inp"]
        idx[:, i0], idx[:, i1] = in_pair[members, 0], in_pair[members, 1]
        later = members > 0
        rows = offset[members[later]][:, None] + np.arange(kk["n_fresh"])
        local[rows] = kk["fresh_ref"][None]
        if not later.all():  # the first copy: every node of it, as drawn
            idx[0] = np.arange(m.n_nodes)
            local[:m.n_nodes] = m.nodes
        edges[e_offset[members][:, None] + np.arange(m.n_edges)] = idx[:, m.edges]
        index.append(idx)
    ports = ChainPorts(np.concatenate([in_pair[:1], out_pair]))
    # what the network does not keep goes before it copies what it keeps (the peak of a
    # million-module build)
    del val, ptr, out_pair, in_pair, offset, e_counts, e_offset, idx, rows
    src = np.stack([kk["src_ref"] for kk in info])[kid]
    dst = np.stack([kk["dst_ref"] for kk in info])[kid]
    owner = np.repeat(np.arange(k), counts)
    del counts
    fl = np.asarray(flags, dtype=bool)
    nodes = _place_chain_2d(src, dst, fl, local, owner) if dim == 2 else \
        _place_chain_3d(src, dst, fl, local, owner)
    del src, dst, owner, local
    return Network(nodes, edges, ports,
                   assembly=Assembly(tuple(modules), kid, tuple(index), fl, d_in))


def _place_chain_2d(src, dst, flags, local, owner) -> np.ndarray:
    """Global coordinates of a planar chain (complex arithmetic, O(k)).

    Module k's transform is ``T_k = T_{k-1} ∘ A_k`` where ``A_k`` takes its input pair (local
    frame) onto module k-1's output pair (module k-1's local frame); a transform is
    ``z ↦ r·z + t`` or, mirrored, ``z ↦ r·conj(z) + t`` with ``|r| = 1``.
    """
    zs = src[..., 0] + 1j * src[..., 1]   # (k, 2)
    zd = dst[..., 0] + 1j * dst[..., 1]
    k = zs.shape[0]
    rel = np.zeros(k, dtype=bool)
    rel[1:] = flags[1:] ^ flags[:-1]
    u = zs[:, 1] - zs[:, 0]
    u = np.where(rel, np.conj(u), u)
    v = np.empty(k, dtype=complex)
    v[1:] = zd[:-1, 1] - zd[:-1, 0]
    v[0] = zs[0, 1] - zs[0, 0]
    r = (v / np.abs(v)) / (u / np.abs(u))
    anchor = np.empty(k, dtype=complex)
    anchor[1:] = zd[:-1, 0]
    anchor[0] = zs[0, 0]
    s0 = np.where(rel, np.conj(zs[:, 0]), zs[:, 0])
    t = anchor - r * s0
    # The first module: identity, or its reflection across the line of its own input pair.
    if flags[0]:
        e = (zs[0, 1] - zs[0, 0]) / abs(zs[0, 1] - zs[0, 0])
        r[0], t[0] = e * e, zs[0, 0] - e * e * np.conj(zs[0, 0])
    else:
        r[0], t[0] = 1.0, 0.0
    # Compose: T_c = T_{c-1} ∘ A_c. Under a mirrored T_{c-1} (z ↦ R·conj(z) + T) the step's
    # coefficients enter conjugated, so with the mirror flags known beforehand (each copy's own
    # flag) the composition is a running product of the (conjugated) rotations and a running
    # sum of the rotated shifts, in the same order as a loop would take them
    gm = flags.astype(bool)
    before = np.empty(k, dtype=bool)  # T_{c-1} mirrored
    before[0] = False
    before[1:] = gm[:-1]
    rr = np.where(before, np.conj(r), r)
    tt = np.where(before, np.conj(t), t)
    gr = np.cumprod(rr)
    prev = np.empty(k, dtype=complex)
    prev[0] = 1.0
    prev[1:] = gr[:-1]
    gt = np.cumsum(prev * tt)
    # in place: three temporaries of a million-module chain's nodes, not six
    # (the operands in the order of `gr * z + gt`: a vectorised complex product need not
    # round the same with its operands swapped)
    z = 1j * local[:, 1]
    np.add(local[:, 0], z, out=z)
    np.conjugate(z, out=z, where=gm[owner])
    np.multiply(gr[owner], z, out=z)
    np.add(z, gt[owner], out=z)
    out = np.empty((z.size, 2))
    out[:, 0] = z.real
    out[:, 1] = z.imag
    return out


def _place_chain_3d(src, dst, flags, local, owner) -> np.ndarray:
    """Global coordinates of a 3D chain: one :func:`join_transform` per module."""
    k = src.shape[0]
    rots = np.empty((k, 3, 3))
    shifts = np.empty((k, 3))
    prev = None
    for c in range(k):
        if prev is None:
            rot, shift = (join_transform(src[0], src[0], mirror=True) if flags[0]
                          else (np.eye(3), np.zeros(3)))
        else:
            rot, shift = join_transform(src[c], prev, mirror=flags[c])
        rots[c], shifts[c] = rot, shift
        prev = dst[c] @ rot.T + shift
    return np.einsum("rij,rj->ri", rots[owner], local) + shifts[owner]


def tessellate(module: Network, shape: tuple[int, int], *, x_join: tuple[str, str] = ("d2", "d1"),
               y_join: tuple[str, str], tol: float = 1e-9) -> Network:
    """Repeat a 2D module on a lattice, joining neighbours port to port in two directions.

    Copy (i, j) (row i, column j) is the reference module moved rigidly so that its
    ``x_join[1]`` port lands on the ``x_join[0]`` port of copy (i, j-1) and its ``y_join[1]`` port
    on the ``y_join[0]`` port of copy (i-1, j). Merged nodes must coincide (the lattice must
    close); bars that two copies share become one bar.

    Parameters
    ----------
    module : Network
        A 2D module at the configuration to repeat.
    shape : (int, int)
        Rows and columns.
    x_join, y_join : (str, str)
        ``(port of the left/lower copy, port of the right/upper copy)``.
    tol : float
        Relative tolerance for nodes that must coincide.

    Returns
    -------
    Network
        Ports ``{name}_{i}_{j}`` for every port of every copy (0-based row and column).

    Raises
    ------
    FabkitError
        3D module, unknown ports, pairs of different lengths, or a lattice that does not close
        (a copy's nodes would have to be in two places at once).

    Examples
    --------
    >>> sq = Network([[0, 0], [1, 0], [1, 1], [0, 1]], [[0, 1], [1, 2], [2, 3], [3, 0]],
    ...              ports={"l": (0, 3), "r": (1, 2), "b": (0, 1), "t": (3, 2)})
    >>> net = tessellate(sq, (2, 3), x_join=("r", "l"), y_join=("t", "b"))
    >>> net.n_nodes, net.n_edges
    (12, 17)
    """
    checked_network("module", module)
    if module.dim != 2:
        raise FabkitError("tessellate works on 2D modules")
    if not isinstance(shape, (list, tuple)) or len(shape) != 2:
        raise ArgumentTypeError("shape", f"must be (rows, columns), got {shape!r:.40}")
    rows = arguments.whole("shape[0]", shape[0], minimum=1)
    cols = arguments.whole("shape[1]", shape[1], minimum=1)
    require("tessellate", ("node", rows * cols * module.n_nodes))
    for name, pair in (("x_join", x_join), ("y_join", y_join)):
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise ArgumentTypeError(name, f"must be two port names, got {pair!r:.40}")
        for i, p in enumerate(pair):
            arguments.port(f"{name}[{i}]", p, module)
    x = module.nodes
    tx_rot, tx_shift = join_transform(x[list(module.port(x_join[1]))], x[list(module.port(x_join[0]))])
    ty_rot, ty_shift = join_transform(x[list(module.port(y_join[1]))], x[list(module.port(y_join[0]))])
    for name, pair in (("x_join", x_join), ("y_join", y_join)):
        la, lb = (float(module.port_distance(p)) for p in pair)
        if abs(la - lb) > tol * max(la, lb):
            raise FabkitError(f"`{name}` joins ports of lengths {la:.10g} and {lb:.10g}")
    # Lattice transform of copy (i, j): Ty^i ∘ Tx^j (a closed lattice makes the order irrelevant).
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = module.n_nodes
    col_rot, col_shift = [np.eye(2)], [np.zeros(2)]
    for _ in range(1, cols):
        col_rot.append(tx_rot @ col_rot[-1])
        col_shift.append(col_shift[-1] @ tx_rot.T + tx_shift)
    copies = []
    row_rot, row_shift = np.eye(2), np.zeros(2)
    for i in range(rows):
        for j in range(cols):
            rot = row_rot @ col_rot[j]
            shift = col_shift[j] @ row_rot.T + row_shift
            copies.append(x @ rot.T + shift)
        row_rot, row_shift = ty_rot @ row_rot, row_shift @ ty_rot.T + ty_shift
    pos = np.concatenate(copies, axis=0)  # copy c = i*cols + j owns rows c*n .. c*n + n - 1
    # Merged nodes are the connected components of the graph of explicit joins.
    grid = np.arange(rows * cols).reshape(rows, cols)
    xa, xb = (np.array(module.port(p)) for p in x_join)
    ya, yb = (np.array(module.port(p)) for p in y_join)
    left, right = grid[:, :-1].ravel(), grid[:, 1:].ravel()
    low, up = grid[:-1, :].ravel(), grid[1:, :].ravel()
    src = np.concatenate([(left[:, None] * n + xa).ravel(), (low[:, None] * n + ya).ravel()])
    dst = np.concatenate([(right[:, None] * n + xb).ravel(), (up[:, None] * n + yb).ravel()])
    total = pos.shape[0]
    graph = coo_matrix((np.ones(src.size), (src, dst)), shape=(total, total))
    _, label = connected_components(graph, directed=False)
    first = np.full(label.max() + 1, total, dtype=np.int64)
    np.minimum.at(first, label, np.arange(total))
    roots = first[label]
    scale = max(float(np.ptp(pos, axis=0).max()), TINY)
    gap = np.linalg.norm(pos - pos[roots], axis=1)
    if gap.max() > tol * scale:
        bad = int(np.argmax(gap))
        raise FabkitError(
            f"the lattice does not close: node {bad % n} of copy ({bad // n // cols}, "
            f"{bad // n % cols}) is {gap.max():.3g} away from the node it is joined to"
        )
    uniq, index = np.unique(roots, return_inverse=True)
    nodes = pos[uniq]
    offsets = (np.arange(rows * cols) * n)[:, None]
    edges = index[(module.edges[None, :, :] + offsets[:, :, None]).reshape(-1, 2)]
    key = np.sort(edges, axis=1)
    _, keep = np.unique(key, axis=0, return_index=True)
    edges = edges[np.sort(keep)]
    ports = {}
    for i in range(rows):
        for j in range(cols):
            c = i * cols + j
            for name, (a, b) in module.ports.items():
                ports[f"{name}_{i}_{j}"] = (int(index[c * n + a]), int(index[c * n + b]))
    return Network(nodes, edges, ports)


def _load_modules(section: dict, ctx, where: str) -> tuple[list[Network], int | None, bool]:
    if ("module" in section) == ("modules" in section):
        raise ctx.error(where, "give either `module` (with `copies`) or `modules`")
    if "module" in section:
        rel = ctx.get(section, "module", where, str)
        mods = [ctx.load(rel, f"{where}.module").network]
        copies = ctx.get(section, "copies", where, int)
        if copies < 1:
            raise ctx.error(f"{where}.copies", f"must be at least 1, got {copies}")
        return mods, copies, True
    rels = ctx.get(section, "modules", where, list)
    if not rels:
        raise ctx.error(f"{where}.modules", "must name at least one template")
    cache: dict[str, Network] = {}
    mods = []
    for i, rel in enumerate(rels):
        if not isinstance(rel, str):
            raise ctx.error(f"{where}.modules[{i}]", "must be a template file name")
        if rel not in cache:  # one Network per file: the chain plans each distinct module once
            cache[rel] = ctx.load(rel, f"{where}.modules[{i}]").network
        mods.append(cache[rel])
    copies = ctx.get(section, "copies", where, int, required=False, default=None)
    if copies is not None and copies < 1:
        raise ctx.error(f"{where}.copies", f"must be at least 1, got {copies}")
    return mods, copies, False


def modules_in(net: Network) -> int:
    """How many modules a network was assembled from (1 for a network that is not a chain)."""
    return net.assembly.count if net.assembly is not None else 1


def _chain_from_section(section: dict, ctx, where: str) -> Network:
    mods, copies, single = _load_modules(section, ctx, where)
    repeat = copies if copies is not None else 1
    ctx.bound_modules(f"{where}.copies" if copies is not None else f"{where}.modules",
                      repeat * sum(modules_in(m) for m in mods),
                      repeat * sum(m.n_nodes for m in mods))
    mirror = section.get("mirror", "auto")
    if not (mirror in ("auto", "alternate", "none") or (
            isinstance(mirror, list) and all(isinstance(v, bool) for v in mirror))):
        raise ctx.error(f"{where}.mirror",
                        "must be \"auto\", \"alternate\", \"none\" or an array of booleans")
    d_in = ctx.get(section, "d_in", where, str, required=False, default="d1")
    d_out = ctx.get(section, "d_out", where, str, required=False, default="d2")
    try:
        return chain(mods[0] if single else mods, copies, d_in=d_in, d_out=d_out, mirror=mirror)
    except FabkitError as exc:
        raise ctx.error(where, str(exc)) from None


def build_chain(section: dict, ctx) -> Network:
    """Template builder for ``[chain]``.

    Keys: ``module`` (a template file) and ``copies``, or ``modules`` (a list of template files,
    optionally repeated ``copies`` times); optional ``mirror`` ("alternate", "none" or an array of
    booleans), ``d_in``, ``d_out``. An optional ``[chain.branch]`` table attaches a second chain
    (same keys) by its port ``end`` to this chain's port ``at`` (optional ``join_mirror``,
    ``swap``); its ports get the suffix ``_b`` (d1_b, …).
    """
    allowed = {"module", "modules", "copies", "mirror", "d_in", "d_out", "branch"}
    ctx.check_keys(section, "chain", allowed)
    trunk = _chain_from_section({k: v for k, v in section.items() if k != "branch"}, ctx, "chain")
    if "branch" not in section:
        return trunk
    sub = ctx.get(section, "branch", "chain", dict)
    ctx.check_keys(sub, "chain.branch", allowed - {"branch"} | {"at", "end", "join_mirror", "swap"})
    at = ctx.get(sub, "at", "chain.branch", str)
    end = ctx.get(sub, "end", "chain.branch", str)
    join_mirror = ctx.get(sub, "join_mirror", "chain.branch", bool, required=False, default=False)
    swap = ctx.get(sub, "swap", "chain.branch", bool, required=False, default=False)
    limb = _chain_from_section({k: v for k, v in sub.items()
                                if k not in ("at", "end", "join_mirror", "swap")}, ctx, "chain.branch")
    if at not in trunk.ports:
        raise ctx.error("chain.branch.at", f"the chain has no port {at!r} (ports d1..d{len([p for p in trunk.ports if is_chain_port(p)])})")
    if end not in limb.ports:
        raise ctx.error("chain.branch.end", f"the branch has no port {end!r}")
    try:
        return branch(trunk, limb, at=at, end=end, mirror=join_mirror, swap=swap)
    except FabkitError as exc:
        raise ctx.error("chain.branch", str(exc)) from None


def build_tessellation(section: dict, ctx) -> Network:
    """Template builder for ``[tessellation]``: ``module`` (a template file), ``shape`` = [rows,
    cols], ``x_join`` and ``y_join`` = [port of the lower/left copy, port of the upper/right]."""
    ctx.check_keys(section, "tessellation", {"module", "shape", "x_join", "y_join"})
    rel = ctx.get(section, "module", "tessellation", str)
    module = ctx.load(rel, "tessellation.module").network
    shape = ctx.get(section, "shape", "tessellation", list)
    if len(shape) != 2 or any(isinstance(v, bool) or not isinstance(v, int) or v < 1 for v in shape):
        raise ctx.error("tessellation.shape", "must be two positive integers [rows, cols]")
    ctx.bound_modules("tessellation.shape", shape[0] * shape[1] * modules_in(module),
                      shape[0] * shape[1] * module.n_nodes)
    joins = []
    for key in ("x_join", "y_join"):
        val = ctx.get(section, key, "tessellation", list, required=key == "y_join",
                      default=["d2", "d1"])
        if len(val) != 2 or not all(isinstance(v, str) for v in val):
            raise ctx.error(f"tessellation.{key}", "must be two port names")
        joins.append(tuple(val))
    try:
        return tessellate(module, tuple(shape), x_join=joins[0], y_join=joins[1])
    except FabkitError as exc:
        raise ctx.error("tessellation", str(exc)) from None
