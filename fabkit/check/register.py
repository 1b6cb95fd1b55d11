"""Pieces of a print read back, found in the design by their geometry alone.

A print's beds hold its pieces turned and moved wherever the writer put them; no file says
where (an STL carries no placement). The checks do not ask the writer's layout: each piece
rebuilt from a file (joints in bed millimetres, and the bars or plate sides between them) is
laid onto the design's nodes by a rigid motion found from the piece itself. One of its bars is
laid onto every design edge of the same length, both ways round; the motion that brings most
of the piece's joints onto design nodes wins, refined by a least-squares fit over all of them.

A piece may fit the design in several places (a chain of equal modules, a symmetric network);
the places of all pieces are then chosen together so that every design edge is built exactly
once. A joint shared by two pieces is a joint where the print is cut, to be joined by hand.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..numerics import apply_fit, rigid_fit

__all__ = ["Placement", "place_pieces", "pieces_of"]

#: Anchor bars tried per piece (its longest), so that one wrong bar does not lose the piece.
ANCHORS = 3
#: Most rigid motions scored per piece.
MAX_CANDIDATES = 4000
#: Most alternative places kept per piece for the joint choice.
MAX_PLACES = 64
#: Joints moved by candidate motions and looked up at once (bounds the memory of a piece of
#: many joints: its candidates are tried in groups of this many joints).
MOVED_JOINTS = 2**16


@dataclass(frozen=True)
class Placement:
    """Where a piece read back lies in the design.

    Attributes
    ----------
    match : numpy.ndarray of int, shape (M,)
        The design node of each of the piece's joints.
    deviation : numpy.ndarray, shape (M,)
        Distance (mm) of each joint, moved by the fit, from its design node.
    rotation : numpy.ndarray, shape (2, 2)
    shift : numpy.ndarray, shape (2,)
        The fit: design = bed @ rotation.T + shift (mm).
    """

    match: np.ndarray
    deviation: np.ndarray
    rotation: np.ndarray
    shift: np.ndarray


def pieces_of(n_joints: int, bars) -> list[np.ndarray]:
    """The connected pieces of joints joined by bars (arrays of joint indices, in order)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    bars = np.asarray(bars, dtype=np.int64).reshape(-1, 2)
    adj = coo_matrix((np.ones(len(bars)), (bars[:, 0], bars[:, 1])), shape=(n_joints,) * 2)
    n, label = connected_components(adj, directed=False)
    return [np.flatnonzero(label == k) for k in range(n)]


def _candidates(xy, bars, design_xy, design_edges, length_tol: float):
    """The rigid motions tried for one piece, in the order they are tried (its longest bars
    first, each onto every design edge of its length, both ways round; at most
    :data:`MAX_CANDIDATES`): (anchor joint, design node it goes to, turn), one array each."""
    d_len = np.linalg.norm(design_xy[design_edges[:, 0]] - design_xy[design_edges[:, 1]], axis=1)
    b_len = np.linalg.norm(xy[bars[:, 0]] - xy[bars[:, 1]], axis=1)
    anchor, start, turn = [], [], []
    for k in np.argsort(-b_len, kind="stable")[:ANCHORS]:
        a, b = bars[k]
        u = xy[b] - xy[a]
        ends = design_edges[np.flatnonzero(np.abs(d_len - b_len[k]) <= length_tol)]
        ij = np.stack([ends, ends[:, ::-1]], axis=1).reshape(-1, 2)  # each edge both ways
        v = design_xy[ij[:, 1]] - design_xy[ij[:, 0]]
        anchor.append(np.full(len(ij), a))
        start.append(ij[:, 0])
        turn.append(np.arctan2(v[:, 1], v[:, 0]) - np.arctan2(u[1], u[0]))
    if not anchor:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    return tuple(np.concatenate(c)[:MAX_CANDIDATES] for c in (anchor, start, turn))


def _fits(xy, bars, design_xy, design_edges, reach: float, length_tol: float):
    """Candidate places of one piece: (joints within ``reach``, rms, Placement), best first.

    The candidate motions are tried many at once (:data:`MOVED_JOINTS` joints moved and looked
    up together); each set of joints one brings onto design nodes (the first candidate to bring
    it) is then refined by a least-squares fit, the fits of as many joints made together
    (:func:`fabkit.numerics.rigid_fit` is batched)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(design_xy)
    anchor, start, turn = _candidates(xy, bars, design_xy, design_edges, length_tol)
    seen, hits, nears = set(), [], []
    step = max(1, MOVED_JOINTS // len(xy))
    for c0 in range(0, turn.size, step):
        c, s = np.cos(turn[c0:c0 + step]), np.sin(turn[c0:c0 + step])
        rot = np.stack([np.stack([c, -s], axis=1), np.stack([s, c], axis=1)], axis=1)
        moved = (xy[None] - xy[anchor[c0:c0 + step]][:, None]) @ np.swapaxes(rot, -1, -2) \
            + design_xy[start[c0:c0 + step]][:, None]
        dist, near = tree.query(moved.reshape(-1, 2), distance_upper_bound=reach)
        hit = np.isfinite(dist).reshape(-1, len(xy))
        near = np.where(hit, near.reshape(hit.shape), -1)
        for r in np.flatnonzero(hit.sum(axis=1) >= min(3, len(xy))).tolist():
            key = near[r].tobytes()
            if key not in seen:  # each set of joints on nodes once, where first met
                seen.add(key)
                hits.append(hit[r])
                nears.append(near[r])
    if not hits:
        return []
    hit, near = np.array(hits), np.array(nears)
    count = hit.sum(axis=1)
    found = {}
    for k in np.unique(count):
        group = np.flatnonzero(count == k)
        fit = rigid_fit(np.broadcast_to(xy, (len(group), *xy.shape))[hit[group]].reshape(-1, k, 2),
                        design_xy[near[group][hit[group]]].reshape(-1, k, 2))
        # every joint to its nearest design node under the refined motion
        dev, match = tree.query(apply_fit(fit, xy).reshape(-1, 2))
        dev, match = dev.reshape(len(group), -1), match.reshape(len(group), -1)
        for g, n in enumerate(group.tolist()):
            found[n] = (fit.rotation[g], fit.shift[g], dev[g], match[g])
    out = []
    for n in range(len(hit)):
        rotation, shift, dev, match = found[n]
        if np.linalg.det(rotation) < 0:  # pragma: no cover - a proper fit
            continue
        out.append((int(count[n]), float(np.sqrt(np.mean(dev ** 2))),
                    Placement(match, dev, rotation, shift)))
    out.sort(key=lambda c: (-c[0], c[1]))
    return out[:MAX_PLACES]


def place_pieces(pieces, design_xy, design_edges, *, tol: float,
                 shared=None, accept=None, partial: bool = False
                 ) -> list[Placement | None]:
    """Lay every piece onto the design (see the module docstring).

    Parameters
    ----------
    pieces : list of (xy, bars)
        Each piece's joints (M, 2) in bed millimetres and its bars (B, 2) as pairs of its
        joint indices.
    design_xy : numpy.ndarray, shape (N, 2)
        The design's nodes, mm.
    design_edges : numpy.ndarray of int, shape (E, 2)
    tol : float
        Largest joint deviation (mm) of a piece built as designed; places within it are
        preferred, and together must cover every design edge once.
    shared : list of numpy.ndarray of int, optional
        What else the file says about each piece's joints (a print-in-place linkage is cut
        between pieces where a joint has plain holes and no pin, and nowhere it has a pin): per
        piece, per joint, +1 where another piece must meet it, -1 where none may, 0 either way.
        The first choice of places that keeps them wins, else the first that covers the design.
        They are kept while the places are chosen, not only tested at the end: identical pieces
        (the modules of a chain) leave too many choices to try one by one.
    accept : callable, optional
        ``accept(places) -> bool``: what else a whole choice of places must meet (a
        print-in-place linkage's bars laid flat are the edges the pieces leave, found by their
        lengths); the first choice it accepts wins, else the first that covers the design.
    partial : bool
        The pieces build part of the design (each design edge at most once); ``accept`` judges
        what is left.

    Returns
    -------
    list of Placement or None
        Per piece, its place (None: nothing of the design fits it).
    """
    design_xy = np.asarray(design_xy, dtype=np.float64)
    design_edges = np.asarray(design_edges, dtype=np.int64)
    d_len = np.linalg.norm(design_xy[design_edges[:, 0]] - design_xy[design_edges[:, 1]], axis=1)
    # far enough to find a joint moved by a writer's mistake, near enough to tell joints apart
    reach = 0.45 * float(d_len.min()) if len(d_len) else 1.0
    edge_key = {tuple(e): k for k, e in enumerate(np.sort(design_edges, axis=1).tolist())}
    options = []
    for xy, bars in pieces:
        bars = np.asarray(bars, dtype=np.int64).reshape(-1, 2)
        fits = _fits(np.asarray(xy, dtype=np.float64), bars, design_xy, design_edges, reach,
                     max(tol, reach))
        good = [f[2] for f in fits if f[0] == len(xy) and f[2].deviation.max() <= tol]
        covered = []
        for p in good:
            keys = {edge_key.get(tuple(sorted(e))) for e in p.match[bars].tolist()}
            covered.append(keys if None not in keys and len(keys) == len(bars) else None)
        options.append(([p for p, c in zip(good, covered) if c is not None],
                        [c for c in covered if c is not None],
                        fits[0][2] if fits else None))
    tests = [(shared, accept)] if shared is not None or accept is not None else []
    for rules, test in tests + [(None, None)]:
        chosen = _cover(options, None if partial else len(design_edges), len(design_xy),
                        rules, test)
        if chosen is not None:
            return chosen
    # no exact cover: each piece's best place, for the checks to say what is wrong
    return [best for _, _, best in options]


def _cover(options, n_edges: int | None, n_nodes: int, shared=None, accept=None):
    """One place per piece so that every design edge is built once (``n_edges`` None: at most
    once) (depth-first, pieces with the fewest places first), every joint shared or alone as
    ``shared`` says and the whole choice accepted by ``accept``, or None."""
    order = sorted(range(len(options)), key=lambda k: len(options[k][0]))
    if any(not options[k][0] for k in order):
        return None
    rules = ([np.asarray(r, dtype=np.int64) for r in shared] if shared is not None
             else [np.zeros(len(options[k][0][0].match), dtype=np.int64)
                   for k in range(len(options))])
    # the places (piece, option) that put a joint on each design node, for the look-ahead
    at_node: list[list] = [[] for _ in range(n_nodes)]
    for k in range(len(options)):
        for o, place in enumerate(options[k][0]):
            for j, v in enumerate(place.match.tolist()):
                if rules[k][j] >= 0:
                    at_node[v].append((k, o))
    chosen: dict[int, Placement] = {}
    used: set = set()
    holders = np.zeros(n_nodes, dtype=np.int64)
    alone = np.zeros(n_nodes, dtype=bool)   # a placed piece's joint no other piece may meet
    needs = np.zeros(n_nodes, dtype=np.int64)  # placed joints that another piece must meet
    budget = [20000]

    def fits(k, place, edges) -> bool:
        nodes, rule = place.match, rules[k]
        return not (used & edges) and not alone[nodes].any() and \
            not (holders[nodes[rule < 0]] > 0).any()

    def can_still_meet(v) -> bool:
        return any(k not in chosen and not (used & options[k][1][o]) for k, o in at_node[v])

    def go(depth: int) -> bool:
        if depth == len(order):
            return (n_edges is None or len(used) == n_edges) and \
                not ((needs > 0) & (holders < 2)).any() and (accept is None or accept(
                    [chosen[k] for k in range(len(options))]))
        k = order[depth]
        for place, edges in zip(*options[k][:2]):
            budget[0] -= 1
            if budget[0] < 0 or not fits(k, place, edges):
                continue
            nodes, rule = place.match, rules[k]
            used.update(edges)
            chosen[k] = place
            holders[nodes] += 1
            alone[nodes[rule < 0]] = True
            np.add.at(needs, nodes[rule > 0], 1)
            lonely = np.flatnonzero((needs > 0) & (holders < 2))
            if all(can_still_meet(int(v)) for v in lonely) and go(depth + 1):
                return True
            np.add.at(needs, nodes[rule > 0], -1)
            alone[nodes[rule < 0]] = False
            holders[nodes] -= 1
            del chosen[k]
            used.difference_update(edges)
        return False

    return [chosen[k] for k in range(len(options))] if go(0) else None
