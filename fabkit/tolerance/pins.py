"""Which bar ends of a print-in-place linkage turn on a pin with play.

At each joint of two or more bars the pin grows from one bar's body (its carrier, the joint's
lowest bar) and the others turn on it in holes ``pin_clearance`` wider (radially): every bar end
but the carrier's has that play. At a joint where the print is cut to fit the bed every bar has
a plain hole, joined by the maker's bolt. Which bar carries which pin is the print's plan's
(:func:`fabkit.fab.pinned.pinned_print`, computed once per design and settings and shared with
the export); the tolerance analysis and the elastic model read it here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import FabricationError
from ..fab.pinned import pinned_print

__all__ = ["PinPlay", "pin_play"]


@dataclass(frozen=True, eq=False)
class PinPlay:
    """The bar ends of a pin-jointed print that turn on a pin with play.

    Attributes
    ----------
    ends : numpy.ndarray, shape (E,)
        Per bar, 0 to 2.
    note : str
        Why the plan was not read (``""`` when it was).
    """

    ends: np.ndarray
    note: str = ""


def pin_play(design, print_settings) -> PinPlay:
    """The bar ends of a pin-jointed print that turn on a pin with play.

    Parameters
    ----------
    design : Design
        A planar bar network with a motion.
    print_settings : PrintSettings
        ``linkage = "pins"`` (as resolved by :func:`fabkit.tolerance.tolerance_spec`).

    Returns
    -------
    PinPlay
        Where the plan cannot be made with these settings (the bed too small, no stacking within
        ``max_layers``) the first bar at each joint is taken to carry its pin, and ``note`` says
        why.

    Examples
    --------
    >>> import fabkit
    >>> from fabkit.settings.printing import design_print_settings
    >>> d = fabkit.load_template("fourbar")
    >>> pin_play(d, design_print_settings(d, {"print": {"linkage": "pins"}})).ends.tolist()
    [1.0, 0.0, 2.0, 1.0]
    """
    net = design.network
    edges = np.asarray(net.edges, dtype=np.int64)
    note = ""
    try:
        plan = pinned_print(design, print_settings)
        carrier, cut = plan.carrier, set(plan.cut_joints)
    except FabricationError as exc:
        note = (f"the print's plan could not be made ({exc}): the first bar at each joint is "
                "taken to carry its pin")
        carrier, cut = {}, set()
        for bar, (i, j) in enumerate(edges.tolist()):
            carrier.setdefault(i, bar)
            carrier.setdefault(j, bar)
    degree = np.bincount(edges.ravel(), minlength=net.n_nodes)
    ends = np.zeros(edges.shape[0])
    for bar, (i, j) in enumerate(edges.tolist()):
        # a free end turns on nothing; a cut joint is bolted through plain holes
        ends[bar] = sum(1 for v in (i, j)
                        if degree[v] >= 2 and (v in cut or carrier.get(v) != bar))
    return PinPlay(ends, note)
