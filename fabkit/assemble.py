"""Joining modules port to port: chains of copies and sequences of different modules.

A module's output port (d_out, e.g. "d2") is joined to the next module's input port (d_in, e.g.
"d1"): the two node pairs are merged, the next module moved rigidly (mirrored where asked) so
that they coincide. Each module is first put into the configuration whose input distance equals
the previous module's output distance (by constructive placement), so that the chain's reference
configuration satisfies every edge: d_{k+1} = f(d_k) holds by construction. The chain keeps ports
d1 … d_{k+1}.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import FabkitError, KinematicsError
from .network import Network

__all__ = ["chain", "join_transform", "build_chain"]


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
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    d = src.shape[1]
    u = src[1] - src[0]
    v = dst[1] - dst[0]
    if d == 2:
        au = np.arctan2(u[1], u[0])
        av = np.arctan2(v[1], v[0])
        if mirror:
            # reflect across the line of u, then rotate u onto v
            c, s = np.cos(2 * au), np.sin(2 * au)
            refl = np.array([[c, s], [s, -c]])
        else:
            refl = np.eye(2)
        a = av - au
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]) @ refl
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
        if np.linalg.norm(w) < 1e-15:
            if c > 0:
                r = np.eye(3)
            else:  # half turn about any axis perpendicular to u
                perp = np.cross(un, [1.0, 0.0, 0.0])
                if np.linalg.norm(perp) < 1e-8:
                    perp = np.cross(un, [0.0, 1.0, 0.0])
                perp /= np.linalg.norm(perp)
                r = 2.0 * np.outer(perp, perp) - np.eye(3)
        else:
            k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
            r = np.eye(3) + k + k @ k / (1.0 + c)
        rot = r @ refl
    shift = dst[0] - src[0] @ rot.T
    return rot, shift


def _module_at(module: Network, d_in: str, value: float, plan_cache: dict) -> np.ndarray:
    """Module configuration with its input distance at ``value`` (same branch as its reference)."""
    from .kinematics.constructive import place, plan_construction

    ref = module.port_distance(d_in)
    if abs(value - ref) <= 1e-12 * max(ref, 1.0):
        return module.nodes
    if "plan" not in plan_cache:
        plan_cache["plan"] = plan_construction(module, module.port(d_in))
    plan = plan_cache["plan"]
    x, margin, _ = place(plan, [value])
    if margin[0] < 0:
        raise KinematicsError(f"the module has no configuration with {d_in} = {value:.10g}")
    return x[0]


def chain(modules, copies: int | None = None, *, d_in: str = "d1", d_out: str = "d2",
          mirror=None) -> Network:
    """Join modules in a chain, each one's ``d_out`` port onto the next one's ``d_in`` port.

    Parameters
    ----------
    modules : Network or sequence of Network
        One module (repeated ``copies`` times) or the sequence of modules to join.
    copies : int, optional
        Number of copies when ``modules`` is a single module.
    d_in, d_out : str
        Port names of a module's input and output pairs.
    mirror : None, "alternate", or sequence of bool
        Mirror every second module (``"alternate"``) or the modules flagged True.

    Returns
    -------
    Network
        Ports ``d1 … d{k+1}`` (the chain's distances, d_{k+1} = f(d_k)); a module's other ports
        appear as ``name_k`` for module k (1-based).

    Raises
    ------
    FabkitError
        Missing ports, mismatched dimensions, or a module that cannot take the previous output
        distance (it lies outside the module's range).

    Examples
    --------
    >>> fourbar = Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]],
    ...                   ports={"d1": (0, 1), "d2": (2, 3)})
    >>> net = chain(fourbar, copies=3)
    >>> net.n_nodes, sorted(net.ports)
    (8, ['d1', 'd2', 'd3', 'd4'])
    """
    if isinstance(modules, Network):
        if copies is None or int(copies) < 1:
            raise FabkitError(f"`copies` must be a positive integer, got {copies!r}")
        seq = [modules] * int(copies)
    else:
        seq = list(modules)
        if copies is not None:
            seq = seq * int(copies)
        if not seq:
            raise FabkitError("a chain needs at least one module")
    k = len(seq)
    if mirror is None:
        flags = [False] * k
    elif isinstance(mirror, str):
        if mirror not in ("alternate", "none"):
            raise FabkitError(f"`mirror` must be None, 'alternate' or a list of booleans, got {mirror!r}")
        flags = [mirror == "alternate" and c % 2 == 1 for c in range(k)]
    else:
        flags = [bool(f) for f in mirror]
        if len(flags) != k:
            raise FabkitError(f"`mirror` has {len(flags)} entries for {k} modules")
    dim = seq[0].dim
    for c, m in enumerate(seq):
        if m.dim != dim:
            raise FabkitError(f"module {c + 1} is {m.dim}D but module 1 is {dim}D")
        for p in (d_in, d_out):
            if p not in m.ports:
                raise FabkitError(f"module {c + 1} has no port {p!r}")
    caches = {}
    node_blocks, edge_blocks = [], []
    ports = {}
    n_total = 0
    prev_out = None  # global indices of the previous output pair
    prev_pos = None  # their positions
    d_value = seq[0].port_distance(d_in)
    positions_all = []
    for c, m in enumerate(seq):
        cache = caches.setdefault(id(m), {})
        try:
            x = _module_at(m, d_in, d_value, cache)
        except KinematicsError as exc:
            raise FabkitError(f"module {c + 1} of the chain: {exc}") from None
        i0, i1 = m.port(d_in)
        o0, o1 = m.port(d_out)
        if prev_pos is None:
            rot, shift = (np.eye(dim), np.zeros(dim)) if not flags[c] else join_transform(
                x[[i0, i1]], x[[i0, i1]], mirror=True)
        else:
            rot, shift = join_transform(x[[i0, i1]], prev_pos, mirror=flags[c])
        y = x @ rot.T + shift
        index = np.empty(m.n_nodes, dtype=np.int64)
        fresh = np.ones(m.n_nodes, dtype=bool)
        if prev_out is not None:
            index[i0], index[i1] = prev_out
            fresh[[i0, i1]] = False
        index[fresh] = n_total + np.arange(fresh.sum())
        n_total += int(fresh.sum())
        positions_all.append(y[fresh])
        edge_blocks.append(index[m.edges])
        if c == 0:
            ports["d1"] = (int(index[i0]), int(index[i1]))
        ports[f"d{c + 2}"] = (int(index[o0]), int(index[o1]))
        for name, (a, b) in m.ports.items():
            if name not in (d_in, d_out):
                ports[f"{name}_{c + 1}"] = (int(index[a]), int(index[b]))
        prev_out = (int(index[o0]), int(index[o1]))
        prev_pos = y[[o0, o1]]
        d_value = float(np.linalg.norm(y[o0] - y[o1]))
    nodes = np.concatenate(positions_all, axis=0)
    edges = np.concatenate(edge_blocks, axis=0)
    return Network(nodes, edges, ports)


def build_chain(section: dict, ctx) -> Network:
    """Template builder for ``[chain]``: ``module`` (a template file) and ``copies``, or
    ``modules`` (a list of template files); optional ``mirror``, ``d_in``, ``d_out``."""
    ctx.check_keys(section, "chain", {"module", "modules", "copies", "mirror", "d_in", "d_out"})
    if ("module" in section) == ("modules" in section):
        raise ctx.error("chain", "give either `module` (with `copies`) or `modules`")
    if "module" in section:
        rel = ctx.get(section, "module", "chain", str)
        mods = [ctx.load(rel, "chain.module").network]
        copies = ctx.get(section, "copies", "chain", int)
        if copies < 1:
            raise ctx.error("chain.copies", f"must be at least 1, got {copies}")
    else:
        rels = ctx.get(section, "modules", "chain", list)
        mods = []
        for i, rel in enumerate(rels):
            if not isinstance(rel, str):
                raise ctx.error(f"chain.modules[{i}]", "must be a template file name")
            mods.append(ctx.load(rel, f"chain.modules[{i}]").network)
        copies = ctx.get(section, "copies", "chain", int, required=False, default=None)
    mirror = section.get("mirror")
    if mirror is not None and not (mirror in ("alternate", "none") or (
            isinstance(mirror, list) and all(isinstance(v, bool) for v in mirror))):
        raise ctx.error("chain.mirror", "must be \"alternate\", \"none\" or an array of booleans")
    d_in = ctx.get(section, "d_in", "chain", str, required=False, default="d1")
    d_out = ctx.get(section, "d_out", "chain", str, required=False, default="d2")
    try:
        target = mods[0] if "module" in section else mods
        return chain(target, copies, d_in=d_in, d_out=d_out, mirror=mirror)
    except FabkitError as exc:
        raise ctx.error("chain", str(exc)) from None
