"""The as-built same-layer check: the smallest gaps between parts that share a layer."""

from __future__ import annotations

import math

import numpy as np

from .distances import (bar_distance_kernel, box_pairs, exact_least, incidence,
                        point_segment_distance, share_joint)

def stacking_gaps(edges, layer, positions, *, width: float, joints=(), head_slots: int = 1,
                  column_radius: float = 0.0, spacer_radius: float | None = None) -> dict:
    """Smallest gaps between parts that share a layer, over sampled configurations.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    layer : array_like of int, shape (E,)
    positions : array_like, shape (S, N, 2)
        Configurations in mm.
    width : float
    joints : sequence of JointStack
        Screws to check bars and other screws against (none: bars only).
    head_slots : int
    column_radius : float
        Radius of the screw heads (they occupy ``head_slots`` layers above and below a stack).
    spacer_radius : float, optional
        Radius of the spacer rings, checked against bars on the stack's own layers.

    Returns
    -------
    dict
        ``bar_gap`` (mm, smallest outline gap between non-adjacent bars of one layer; inf when
        no two share a layer), ``bar_pair`` and ``sample`` where it occurs; ``screw_gap``
        (smallest gap from a bar to a screw column whose layers it occupies) and
        ``column_gap`` (between screw columns that share layers).
    """
    edges = np.asarray(edges, dtype=np.int64)
    layer = np.asarray(layer)
    x = np.asarray(positions, dtype=np.float64)
    inc = incidence(edges, x.shape[1])
    out = {"bar_gap": math.inf, "bar_pair": None, "sample": None,
           "screw_gap": math.inf, "column_gap": math.inf}
    # Only the smallest gap of each kind is reported, exactly: pairs are taken from their swept
    # boxes, nearest first (a segment distance is never below its boxes' distance), and of
    # those, pairs that cannot reach the minimum are measured at every 32nd sample only (see
    # _least). The whole kit's pairs, quadratic in its size, are never formed.
    lo_n, hi_n = x.min(axis=0), x.max(axis=0)
    bar_lo = np.minimum(lo_n[edges[:, 0]], lo_n[edges[:, 1]])
    bar_hi = np.maximum(hi_n[edges[:, 0]], hi_n[edges[:, 1]])
    whole = float(np.hypot(*(hi_n.max(axis=0) - lo_n.min(axis=0)))) + 1.0

    def bar_pairs(reach):
        a, b = box_pairs(bar_lo, bar_hi, bar_lo, bar_hi, reach, same=True)
        keep = (layer[a] == layer[b]) & ~share_joint(edges, a, b)
        return a[keep], b[keep]

    gap, k, where, (a, b) = exact_least(bar_distance_kernel(edges), x, width, bar_pairs,
                                         lambda g: g + width, 2.0 * width, whole)
    if k >= 0:
        out.update(bar_gap=gap, bar_pair=[int(a[k]), int(b[k])], sample=where)
    if joints:
        js = list(joints)
        jid = np.array([st.joint for st in js], dtype=np.int64)
        z0 = np.array([min(st.layers) for st in js]) - head_slots  # the column with its heads
        z1 = np.array([max(st.layers) for st in js]) + head_slots
        r_max = max(column_radius, spacer_radius or 0.0)
        jlo, jhi = lo_n[jid], hi_n[jid]

        def screw_pairs(reach):  # a bar and a column whose layers it occupies, near ones only
            bb, jk = box_pairs(bar_lo, bar_hi, jlo, jhi, reach)
            keep = (layer[bb] >= z0[jk]) & (layer[bb] <= z1[jk]) & ~inc[jid[jk], bb]
            return bb[keep], jk[keep]

        def screw_offset(arrays):
            bb, jk = arrays
            radius = np.full(bb.size, column_radius)
            if spacer_radius is not None:
                # on the stack's own layers the spacer rings are the wider part of the column
                inner = (layer[bb] >= z0[jk] + head_slots) & (layer[bb] <= z1[jk] - head_slots)
                radius[inner] = max(column_radius, spacer_radius)
            return 0.5 * width + radius

        out["screw_gap"], _, _, _ = exact_least(
            lambda xs, bi, ki: point_segment_distance(xs[:, jid[ki]], xs[:, edges[bi, 0]],
                                                      xs[:, edges[bi, 1]]),
            x, screw_offset, screw_pairs, lambda g: g + 0.5 * width + r_max,
            1.5 * width + r_max, whole)

        def column_pairs(reach):  # two columns that share a layer, near ones only
            ia, ib = box_pairs(jlo, jhi, jlo, jhi, reach, same=True)
            keep = (z0[ia] <= z1[ib]) & (z0[ib] <= z1[ia])
            return ia[keep], ib[keep]

        out["column_gap"], _, _, _ = exact_least(
            lambda xs, i1, i2: np.sqrt(((xs[:, jid[i1]] - xs[:, jid[i2]]) ** 2).sum(-1)), x,
            2.0 * column_radius, column_pairs, lambda g: g + 2.0 * column_radius,
            2.0 * width + 2.0 * column_radius, whole)
    return out
