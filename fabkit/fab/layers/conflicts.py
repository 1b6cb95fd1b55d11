"""Which bars, screws and columns come close anywhere along the motion."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...numerics import MM_SLACK
from .distances import (bar_distance_kernel, bars_sharing_joints, box_pairs, incidence,
                        point_segment_distance, pruned_min_over_samples, share_joint)

@dataclass(frozen=True, eq=False)
class Conflicts:
    """Everything the stacking must respect, measured over a sweep.

    Attributes
    ----------
    pairs : numpy.ndarray of int, shape (C, 2)
        Bar pairs that must be on different layers.
    kind : numpy.ndarray of str, shape (C,)
        ``"joint"`` (share a joint) or ``"sweep"`` (come closer than the clearance).
    gap : numpy.ndarray, shape (C,)
        Smallest outline gap over the motion (mm; negative = overlap), NaN for joint pairs.
    sample : numpy.ndarray of int, shape (C,)
        Sample where the gap is smallest (-1 for joint pairs).
    keepout : numpy.ndarray of int, shape (K, 2)
        (bar, joint) pairs: the bar passes the joint's screw column (must avoid its layers).
    joint_pairs : numpy.ndarray of int, shape (J, 2)
        Joints whose screw columns come close (their layer spans must not meet).
    screw_joints : numpy.ndarray of int
        Joints that get a screw (two or more bars).
    keepout_span : numpy.ndarray of int, shape (K2, 2)
        (bar, joint) pairs: the bar passes the joint's spacer rings (wider than its heads) but
        not its heads: it must avoid the layers of the stack itself, not the head layers.
    """

    pairs: np.ndarray
    kind: np.ndarray
    gap: np.ndarray
    sample: np.ndarray
    keepout: np.ndarray
    joint_pairs: np.ndarray
    screw_joints: np.ndarray
    keepout_span: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))


def closer_than(gap, clearance: float):
    """Gaps below the clearance by more than round-off (:data:`~fabkit.numerics.MM_SLACK`): a
    gap that meets it to within a nanometre (two bars drawn exactly the clearance apart) is
    kept, on every machine, instead of being decided by the last bits of its sampling."""
    return np.asarray(gap) < clearance - MM_SLACK


def find_conflicts(edges, positions, *, width: float, clearance: float,
                   column_radius: float, screw_joints=None,
                   spacer_radius: float | None = None) -> Conflicts:
    """Measure which bars, screws and columns come close anywhere along a sampled motion.

    Parameters
    ----------
    edges : array_like of int, shape (E, 2)
    positions : array_like, shape (S, N, 2)
        Sampled configurations in mm.
    width : float
        Bar width (mm): outlines are the joint segments grown by ``width / 2``.
    clearance : float
        Least gap allowed between parts of one layer (mm).
    column_radius : float
        Radius of a screw column (largest of head and spacer radius, mm).
    spacer_radius : float, optional
        Radius of the spacer rings inside a stack, when larger than ``column_radius`` (the
        heads): bars that pass them but not the heads go to ``keepout_span``.
    screw_joints : array_like of int, optional
        Joints that carry a screw (default: every joint of two or more of these bars; a piece
        cut out of a larger network passes the joints that have screws in the whole).

    Returns
    -------
    Conflicts
    """
    edges = np.asarray(edges, dtype=np.int64)
    x = np.asarray(positions, dtype=np.float64)
    n_nodes = x.shape[1]
    inc = incidence(edges, n_nodes)
    # bars that share a joint always conflict (from the joints' bar lists: O(bars))
    ja, jb = bars_sharing_joints(edges, n_nodes)
    # Only pairs whose swept boxes (over the whole motion) come within reach need the scan,
    # and only those are ever formed (sort and sweep: linear in the kit, not quadratic).
    lo_n, hi_n = x.min(axis=0), x.max(axis=0)                      # (N, 2) each
    r_col = max(column_radius, spacer_radius or 0.0)
    reach = 0.5 * width + clearance + r_col
    bar_lo = np.minimum(lo_n[edges[:, 0]], lo_n[edges[:, 1]]) - reach
    bar_hi = np.maximum(hi_n[edges[:, 0]], hi_n[edges[:, 1]]) + reach
    fa, fb = box_pairs(bar_lo, bar_hi, bar_lo, bar_hi, 0.0, same=True)
    keep = ~share_joint(edges, fa, fb)
    fa, fb = fa[keep], fb[keep]
    if fa.size:
        seg_gap, where = pruned_min_over_samples(bar_distance_kernel(edges), x, width + clearance,
                                                 fa, fb)
    else:
        seg_gap, where = np.zeros(0), np.zeros(0, dtype=np.int64)
    gap = seg_gap - width
    close = closer_than(gap, clearance)
    pairs = np.concatenate([np.stack([ja, jb], 1), np.stack([fa[close], fb[close]], 1)]).reshape(-1, 2)
    kind = np.array(["joint"] * ja.size + ["sweep"] * int(close.sum()), dtype=object)
    gaps = np.concatenate([np.full(ja.size, np.nan), gap[close]])
    samples = np.concatenate([np.full(ja.size, -1), where[close]]).astype(np.int64)

    degree = inc.sum(axis=1)
    screw_joints = (np.flatnonzero(degree >= 2) if screw_joints is None
                    else np.asarray(screw_joints, dtype=np.int64))
    # bar vs screw column at a joint the bar does not belong to (near ones only)
    bb, jk = box_pairs(bar_lo, bar_hi, lo_n[screw_joints], hi_n[screw_joints], reach)
    jj = screw_joints[jk]
    keep = ~inc[jj, bb]
    bb, jj = bb[keep], jj[keep]
    if bb.size:
        d, _ = pruned_min_over_samples(
            lambda xs, bi, ji: point_segment_distance(xs[:, ji], xs[:, edges[bi, 0]],
                                                      xs[:, edges[bi, 1]]),
            x, 0.5 * width + r_col + clearance, bb, jj)
        near = closer_than(d - 0.5 * width - column_radius, clearance)
        keepout = np.stack([bb[near], jj[near]], 1)
        span = ~near & closer_than(d - 0.5 * width - r_col, clearance)
        keepout_span = np.stack([bb[span], jj[span]], 1)
    else:
        keepout = keepout_span = np.zeros((0, 2), dtype=np.int64)
    # screw column vs screw column
    if screw_joints.size >= 2:
        sl, sh = lo_n[screw_joints], hi_n[screw_joints]
        ia, ib = box_pairs(sl, sh, sl, sh, 2 * reach, same=True)
        ia, ib = screw_joints[ia], screw_joints[ib]
        d, _ = pruned_min_over_samples(
            lambda xs, i1, i2: np.sqrt(((xs[:, i1] - xs[:, i2]) ** 2).sum(-1)),
            x, 2.0 * r_col + clearance, ia, ib)
        near = closer_than(d - 2.0 * r_col, clearance)
        joint_pairs = np.stack([ia[near], ib[near]], 1).reshape(-1, 2)
    else:
        joint_pairs = np.zeros((0, 2), dtype=np.int64)
    return Conflicts(pairs=pairs.astype(np.int64), kind=kind, gap=gaps, sample=samples,
                     keepout=keepout.astype(np.int64), joint_pairs=joint_pairs.astype(np.int64),
                     screw_joints=screw_joints,
                     keepout_span=keepout_span.reshape(-1, 2).astype(np.int64))


