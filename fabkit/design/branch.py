"""How far a module's states sit from the folds of its map's branch.

A build's bars move the folds (the ends of the branch, where d1 turns back): a fixed point or a
cycle closer to a fold than the errors reach is lost. The designer keeps every wished state at
least :data:`MIN_BRANCH_MARGIN` of itself from a fold, and reports the margin of every fixed
point and 2-cycle of the branch.
"""

from __future__ import annotations

__all__ = ["MIN_BRANCH_MARGIN", "branch_margins", "on_branch"]

#: Least distance of every wished state from the nearest fold of its branch, as a fraction of
#: the state: a wish 1.8e-4 from its fold (slope -55.7 there) lost its fixed point in 2 of 6
#: simulated builds; at 2 % the laser's errors (0.05 mm bars, 0.2 mm hole play at 100 mm per
#: unit) move the fold far less than that.
MIN_BRANCH_MARGIN = 0.02


def branch_margins(fmap, values) -> list[dict]:
    """Distance of each wished state to the nearest fold of its branch (an end of the map's
    domain, where d1 turns back): a build's bars move the fold, and a state closer to it than
    their errors reach is lost.

    Returns
    -------
    list of dict
        Per value: ``value``, ``margin`` (design units), ``fraction`` (of the value) and
        ``fold`` (the d1 of the nearer fold).
    """
    lo, hi = fmap.domain
    out = []
    for v in values:
        fold = lo if v - lo <= hi - v else hi
        margin = abs(v - fold)
        out.append({"value": float(v), "margin": float(margin), "fraction": float(margin / v),
                    "fold": float(fold)})
    return out


def on_branch(fmap) -> dict:
    """Every fixed point and 2-cycle of the map's branch, each with its distance to the
    nearest fold (:func:`branch_margins`), and the branch's domain and what ends it.

    Examples
    --------
    >>> from fabkit.design import design_map
    >>> b = on_branch(design_map([], (1.3, 1.8)).map)
    >>> [round(p["value"], 6) for p in b["fixed_points"]]
    [1.596294]
    """
    fps = fmap.fixed_points()
    cycles = fmap.cycles(2)
    out_fps = []
    for p, m in zip(fps, branch_margins(fmap, [p.value for p in fps])):
        out_fps.append({**p.as_dict(), "branch_margin": m["margin"],
                        "branch_margin_fraction": m["fraction"], "fold": m["fold"]})
    out_cycles = []
    for c in cycles:
        ms = branch_margins(fmap, list(c.values))
        worst = min(ms, key=lambda m: m["fraction"])
        out_cycles.append({**c.as_dict(), "branch_margin": worst["margin"],
                           "branch_margin_fraction": worst["fraction"], "fold": worst["fold"]})
    ends = list(fmap.branch.ends) if fmap.branch is not None else ["", ""]
    return {"domain": list(fmap.domain), "ends": ends, "fixed_points": out_fps,
            "cycles": out_cycles}
