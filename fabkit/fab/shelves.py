"""Shelf packing: a laser kit's bars laid in rows as tall as a bar, first fit by length.

A kit's bars all have the bar's width, and its spacer rings are narrower: packed by boxes they
are a one-dimensional problem, rows of one bar's height filled with lengths. The general
packers (MaxRects, guillotine, skyline) treat them as any rectangles and leave a few percent of
every sheet in slivers; for a kit that fills nearly whole sheets that few percent is one more
sheet (and_gate: its bars and rings need 1.94 sheets by their boxes, and every general packer
opens a third sheet for six rings). Rows filled first fit by decreasing length waste at most one
part's length per row.

Parts taller than a row (the reference square) are placed first, at the left end of the rows
of the first sheets, which are shorter by their width.
"""

from __future__ import annotations

from collections import Counter

from ..errors import ResourceError

__all__ = ["shelf_pack"]


def shelf_pack(ids, sizes: dict, bin_w: int, bin_h: int) -> list[tuple] | None:
    """Pack boxes in rows on sheets of ``bin_w`` x ``bin_h``.

    Parameters
    ----------
    ids : list
        The parts to pack (keys of ``sizes``).
    sizes : dict
        Part -> (width, height) in whole units, spacing included (as the other packers get
        them); a part may be turned a quarter.
    bin_w, bin_h : int
        A sheet's usable size in the same units.

    Returns
    -------
    list of tuple or None
        ``[(sheet, x, y, w, h, part), ...]`` with ``(w, h)`` the part's box as placed (turned
        when it differs from ``sizes[part]``); None when a part fits no row nor sheet (the
        general packers decide then).

    Raises
    ------
    ResourceError
        The rows' integer program ran past :data:`MILP_SAFETY_SECONDS` before its work limit,
        :data:`MILP_NODES` (a safety net: the packing never depends on the machine's speed).
    """
    if not ids:
        return []
    lying = {n: (max(sizes[n]), min(sizes[n])) for n in ids}  # long side along the row
    # the row's height: the most common short side (the bars'), if nothing taller is common
    row_h = Counter(h for _, h in lying.values()).most_common(1)[0][0]
    if row_h <= 0 or row_h > bin_h or max(w for w, _ in lying.values()) > bin_w:
        return None
    rows_per_sheet = bin_h // row_h
    tall = sorted((n for n in ids if lying[n][1] > row_h), key=lambda n: (-lying[n][1], n))
    flat = sorted((n for n in ids if lying[n][1] <= row_h), key=lambda n: (-lying[n][0], n))
    used: list[list[int]] = []  # per sheet, per row: the length used from the left
    out = []

    def new_sheet():
        used.append([0] * rows_per_sheet)

    # tall parts: standing at the left of consecutive rows, the first sheets first
    for n in tall:
        w, h = lying[n]
        span = -(-h // row_h)
        if span > rows_per_sheet:
            return None
        placed = False
        for s, rows in enumerate(used):
            for r in range(rows_per_sheet - span + 1):
                left = max(rows[r:r + span])
                if left + w <= bin_w:
                    out.append((s, left, r * row_h, w, h, n))
                    for k in range(r, r + span):
                        rows[k] = left + w
                    placed = True
                    break
            if placed:
                break
        if not placed:
            new_sheet()
            out.append((len(used) - 1, 0, 0, w, h, n))
            for k in range(span):
                used[-1][k] = w
    # the rest: rows chosen as a cutting-stock problem (the fewest new rows), else first fit
    # by decreasing length
    rows = _rows_by_patterns(flat, lying, used, bin_w, rows_per_sheet)
    if rows is None:
        rows = _rows_first_fit(flat, lying, used, bin_w, rows_per_sheet)
    for (s, r), parts in sorted(rows.items()):
        left = used[s][r]
        for n in parts:
            w, h = lying[n]
            out.append((s, left, r * row_h, w, h, n))
            left += w
    return out


def _rows_first_fit(flat, lying, used, bin_w, rows_per_sheet) -> dict:
    """Parts to rows, first fit by decreasing length over the rows of every sheet opened
    (sheets opened as needed): ``{(sheet, row): [part, ...]}``."""
    left = [list(rows) for rows in used]
    rows: dict = {}
    for n in flat:
        w = lying[n][0]
        spot = next(((s, r) for s, lf in enumerate(left) for r, x in enumerate(lf)
                     if x + w <= bin_w), None)
        if spot is None:
            left.append([0] * rows_per_sheet)
            used.append([0] * rows_per_sheet)
            spot = (len(left) - 1, 0)
        s, r = spot
        left[s][r] += w
        rows.setdefault(spot, []).append(n)
    return rows


#: Most row patterns (sets of lengths that fit one row) the cutting-stock model enumerates; a
#: kit of many different lengths is packed first fit instead.
MAX_PATTERNS = 20000
#: Cost of filling a row already begun, against 1 for a new row: small enough never to trade a
#: new row for begun ones (a kit has far fewer than 10^6 rows), so the program asks for the
#: fewest new rows first and uses no begun row it does not need.
BEGUN_ROW_COST = 1e-6
#: Branch-and-bound nodes the integer program may take before first fit is used instead: a
#: count of work, not a time, so the sheets are the same on every machine, busy or quiet. The
#: bundled kits whose program is solved need at most 116 nodes (``super_stable_chain``; 108 for
#: ``and_gate``); ``period_two_chain16``'s needs 10 870 (a minute) and was cut off by the former
#: 5 s limit on this 2-core machine, so it keeps first fit. 500 nodes cost about 4 s of CPU there.
MILP_NODES = 500
#: Safety net on the integer program's wall-clock time (s), far beyond :data:`MILP_NODES` even on
#: a loaded machine: reaching it raises an error naming it, never different sheets.
MILP_SAFETY_SECONDS = 900.0


def _patterns(lengths: list, cap: int) -> list:
    """Every maximal choice of counts of ``lengths`` (longest first) that fits in ``cap``: no
    further part of any length fits beside it. None past :data:`MAX_PATTERNS`."""
    out = []
    shortest = min(lengths)

    def go(k, room, counts):
        if len(out) > MAX_PATTERNS:
            return
        if k == len(lengths) - 1:  # the shortest length fills what is left
            out.append(counts + [room // lengths[k]])
            return
        for c in range(room // lengths[k], -1, -1):
            go(k + 1, room - c * lengths[k], counts + [c])

    go(0, cap, [])
    if len(out) > MAX_PATTERNS:
        return None
    return [p for p in out if cap - sum(c * w for c, w in zip(p, lengths)) < shortest]


def _rows_by_patterns(flat, lying, used, bin_w, rows_per_sheet) -> dict | None:
    """Parts to rows with the fewest new rows, by integer programming over row patterns
    (the rows already begun by tall parts are filled first); None when the model is too large
    or not solved within :data:`MILP_NODES` nodes."""
    import numpy as np
    from scipy.optimize import Bounds, LinearConstraint, milp

    if not flat:
        return {}
    kinds = sorted({lying[n][0] for n in flat}, reverse=True)
    demand = np.array([sum(1 for n in flat if lying[n][0] == w) for w in kinds])
    # rows by room: those begun (beside a tall part, or empty rows of a sheet it opened) and new
    begun: dict = {}
    for s, rows in enumerate(used):
        for r, x in enumerate(rows):
            begun.setdefault(bin_w - x, []).append((s, r))
    classes = [(room, len(slots)) for room, slots in sorted(begun.items(), reverse=True)]
    classes.append((bin_w, None))  # new rows, as many as needed
    columns, owner = [], []
    for c, (room, _) in enumerate(classes):
        pats = _patterns(kinds, room) if room >= min(kinds) else [[0] * len(kinds)]
        if pats is None or len(columns) + len(pats) > MAX_PATTERNS:
            return None
        columns.extend(pats)
        owner.extend([c] * len(pats))
    a = np.array(columns, dtype=float).T  # kinds x patterns
    owner = np.array(owner)
    new = owner == len(classes) - 1
    cost = new.astype(float) + BEGUN_ROW_COST * (~new)  # fewest new rows, then fewest begun
    cons = [LinearConstraint(a, lb=demand, ub=np.inf)]
    for c, (_, n_slots) in enumerate(classes[:-1]):
        cons.append(LinearConstraint((owner == c).astype(float)[None, :], lb=0, ub=n_slots))
    res = milp(cost, constraints=cons, integrality=np.ones(len(columns)),
               bounds=Bounds(0, np.inf),
               options={"node_limit": MILP_NODES, "time_limit": MILP_SAFETY_SECONDS})
    if res.status == 1 and (res.get("mip_node_count") or 0) < MILP_NODES:
        # the clock stopped it, not the work limit: first fit now would depend on the machine
        raise ResourceError(
            f"packing the parts into rows ran past its safety limit of {MILP_SAFETY_SECONDS:g} s "
            f"of wall-clock time before its work limit of {MILP_NODES} nodes; the machine is "
            "too busy or too slow: export again on a quieter one")
    if res.x is None or not res.success:
        return None
    counts = np.rint(res.x).astype(int)
    queues = {w: [n for n in flat if lying[n][0] == w] for w in kinds}
    slots = {c: list(begun[room]) for c, (room, _) in enumerate(classes[:-1])}
    n_new = int(counts[new].sum())
    first_new = len(used)
    for _ in range(-(-n_new // rows_per_sheet)):
        used.append([0] * rows_per_sheet)
    fresh = [(s, r) for s in range(first_new, len(used)) for r in range(rows_per_sheet)]
    rows: dict = {}
    for j in np.flatnonzero(counts):
        for _ in range(counts[j]):
            slot = fresh.pop(0) if new[j] else slots[owner[j]].pop(0)
            parts = [queues[w].pop(0) for w, c in zip(kinds, columns[j])
                     for _ in range(c) if queues[w]]
            if parts:
                rows[slot] = parts
    # a surplus pattern may leave its new rows empty; the sheets opened for nothing go
    while len(used) > first_new and not any(s == len(used) - 1 for s, _ in rows):
        used.pop()
    return rows
