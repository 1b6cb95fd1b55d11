"""Chains of origami sheets joined corner to corner (the paper's Fig. 5g-h)."""

from __future__ import annotations

import numpy as np

from ...errors import FabricationError
from ...kinematics import place, plan_construction
from ...model.network import Network
from ...numerics import rigid_fit

# -- chains of sheets ----------------------------------------------------------------------------

#: Local vertices of the next sheet (A', C', B') merged onto (B, D, C) of the previous sheet.
CHAIN_JOIN = {"next": (0, 2, 1), "prev": (1, 3, 2)}


#: The sheet's d2 must equal d1 = ``at`` to this relative error for ``at`` to be a fixed point
#: of its map (both exact placements; a near miss is a different design).
SHEET_FIXED_RTOL = 1e-9
#: Sheets of the chain are fitted onto each other's shared creases to this RMS (sheet units):
#: the rigid fit of exactly placed sheets leaves round-off, ~1e-15.
JOIN_RMS = 1e-9


def sheet_chain(sheet: Network, copies: int, at: float, *, reference=None) -> tuple[Network, list]:
    """Sheets of the paper's origami module joined corner to corner, three corners per join.

    Sheet k+1's corners A', C' are merged onto sheet k's corners B, D (its d2 pair onto the
    previous sheet's d1 pair) and its corner B' onto sheet k's corner C. Two boundary edges
    coincide (A'B' = BC and B'C' = CD, both sides of the square), so the third node adds exactly
    one constraint per join: the one that stops sheet k+1 hinging about the line BD. Two shared
    corners alone leave that hinge (k sheets, k motions); with the third the chain keeps one
    conformational motion for any number of sheets (3N - E = 3(2k + 3) - (6k + 2) = 7). Every
    corner is shared by at most three consecutive sheets. (Merging B' onto A instead also keeps
    one motion, but then every sheet shares the edge AB of sheet 1, like the pages of a book.)
    Chain ports: ``d1`` = sheet 1's (A, C), ``d{k+1}`` = sheet k's (B, D): the chain iterates
    the inverse of the sheet's map, ``d_k = f(d_{k+1})``.

    Parameters
    ----------
    sheet : Network
        One sheet with nodes A, B, C, D, P (0..4) and ports d1 = (B, D), d2 = (A, C).
    copies : int
        Number of sheets.
    at : float
        The sheet's d1 value of the crystalline state to build (every sheet alike): a fixed
        point of the map, d1 = d2.
    reference : array_like, shape (5, 3), optional
        A configuration of the sheet on the wanted branch (off the flat state) that decides the
        side of every intersection.

    Returns
    -------
    network : Network
        3 + 2·copies nodes, 2 + 6·copies edges.
    sheets : list of list of int
        Network node of each sheet's vertices A, B, C, D, P.

    Raises
    ------
    FabricationError
        ``at`` is not a fixed point of the sheet's map, or the sheets do not fit.
    """
    ref = sheet.nodes if reference is None else np.asarray(reference, dtype=np.float64)
    plan = plan_construction(sheet, sheet.port("d1"), ref)
    x, margin, _ = place(plan, [at])
    x = x[0]
    if margin[0] < 0:
        raise FabricationError(f"the sheet has no configuration with d1 = {at}")
    d2 = float(np.linalg.norm(x[0] - x[2]))
    if abs(d2 - at) > SHEET_FIXED_RTOL * at:
        raise FabricationError(f"d1 = {at} is not a fixed point of the sheet's map (d2 = {d2:.12g})")
    nodes = [x]
    maps = [list(range(5))]
    edges = [tuple(e) for e in sheet.edges.tolist()]
    n = 5
    nxt, prv = CHAIN_JOIN["next"], CHAIN_JOIN["prev"]
    for k in range(1, int(copies)):
        last = maps[-1]
        allx = np.vstack(nodes)
        dst = allx[[last[i] for i in prv]]
        fit = rigid_fit(x[list(nxt)], dst)
        rot, shift, rms = fit.rotation, fit.shift, float(fit.rms)
        if rms > JOIN_RMS:
            raise FabricationError(f"sheet {k + 1} does not fit onto sheet {k} (rms {rms:.1e})")
        y = x @ rot.T + shift
        local = [-1] * 5
        for a, b in zip(nxt, prv):
            local[a] = last[b]
        for a in range(5):
            if local[a] < 0:
                local[a] = n
                nodes.append(y[a][None])
                n += 1
        maps.append(local)
        present = {tuple(sorted(e)) for e in edges}
        for a, b in sheet.edges.tolist():
            key = (local[a], local[b])
            if tuple(sorted(key)) not in present:
                edges.append(key)
    ports = {"d1": (maps[0][0], maps[0][2])}
    for k, m in enumerate(maps):
        ports[f"d{k + 2}"] = (m[1], m[3])
    labels = [f"{'ABCDP'[a]}{k + 1}" for k, m in enumerate(maps) for a in range(5)
              if m[a] >= 0 and (k == 0 or a not in nxt)]
    net = Network(np.vstack(nodes), np.array(edges, dtype=np.int64), ports, labels)
    return net, maps
