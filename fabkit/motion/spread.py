"""Where a chain's motion went: which modules moved, and whether the motion stayed local.

Driving a chain's first port moves every module only where the modules' map carries the motion
on: near a stable fixed point a change of a module's input dies out along the chain, and the
motion stays in the first modules (the paper's localisation at the edge); near an unstable one
it grows, and the far end moves first. Reaching the drive's target says nothing of this, so a
traced chain is also read module by module: how far each module's output port went from its
start, as a fraction of the drive's own travel. A module **moved** when its output went farther
than the state tolerance of the designed ends (:data:`fabkit.motion.intent.STATE_FRACTION`
of the drive's travel). The motion is **localised** when some modules did not move.

The chain is the one the drive belongs to: ports ``d1, d2, ...`` (or ``d1_b, d2_b, ...`` for a
drive ``d1_b``), module ``k`` taking ``d_k`` to ``d_{k+1}``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..numerics import TINY

__all__ = ["ModuleSpread", "module_spread", "shape_missed", "chain_of", "SPREAD_BLOCKS"]

#: A chain port's name: its module number and the chain's suffix (``d3_b``: 3, ``_b``).
CHAIN_PORT = re.compile(r"d(\d+)(_\w+)?")

#: Characters of the terminal strip, from a module that did not move to one that went the whole
#: travel of the drive (or more).
SPREAD_BLOCKS = "▁▂▃▄▅▆▇█"


@dataclass(frozen=True)
class ModuleSpread:
    """How far each module of a driven chain moved.

    Attributes
    ----------
    ports : tuple of str
        The chain's ports in order, the drive's first.
    reach : numpy.ndarray, shape (n,)
        Per module (``k`` = 1..n), the largest excursion of its output port from its start over
        the motion, over the drive's travel.
    tolerance : float
        The excursion (same fraction) past which a module counts as moved.
    """

    ports: tuple
    reach: np.ndarray
    tolerance: float

    @property
    def modules(self) -> int:
        return int(self.reach.size)

    @property
    def moved(self) -> np.ndarray:
        """Per module, whether it moved (bool, shape (n,))."""
        return self.reach > self.tolerance

    @property
    def localised(self) -> bool:
        return not bool(self.moved.all())

    def where(self) -> str:
        """``"the driven end"``, ``"the far end"`` or ``""``: where the modules that moved sit,
        when they are one run at an end of the chain."""
        k = np.flatnonzero(self.moved)
        if not k.size or k.size == self.modules or k[-1] - k[0] + 1 != k.size:
            return ""
        return "the driven end" if k[0] == 0 else "the far end" if k[-1] == self.modules - 1 \
            else ""

    def sentence(self) -> str:
        """One clause: ``"spread: all 8 modules moved"``, ``"localised at the driven end:
        modules 1–3 of 12 moved"``."""
        n = self.modules
        k = np.flatnonzero(self.moved) + 1
        if k.size == n:
            return f"spread: all {n} modules moved"
        if not k.size:
            return f"localised: none of the {n} modules moved (the drive's port alone did)"
        where = self.where()
        return f"localised{' at ' + where if where else ''}: {_runs(k)} of {n} moved"

    def strip(self) -> str:
        """The modules as a row of blocks, each as high as its output went (terminal)."""
        levels = np.clip(np.round(self.reach * (len(SPREAD_BLOCKS) - 1)), 0,
                         len(SPREAD_BLOCKS) - 1).astype(int)
        return "".join(SPREAD_BLOCKS[i] for i in levels)

    def as_dict(self) -> dict:
        return {"modules": self.modules, "moved": int(self.moved.sum()),
                "localised": self.localised, "where": self.where(),
                "tolerance": self.tolerance, "ports": list(self.ports),
                "reach": [float(v) for v in self.reach], "sentence": self.sentence()}


def _runs(k) -> str:
    """``[1, 2, 3, 7]`` → ``"modules 1–3, 7"``."""
    out, run = [], [int(k[0])]
    for v in k[1:]:
        if v == run[-1] + 1:
            run.append(int(v))
        else:
            out.append(run)
            run = [int(v)]
    out.append(run)
    text = ", ".join(f"{r[0]}" if len(r) == 1 else f"{r[0]}–{r[-1]}" for r in out)
    return ("module " if len(k) == 1 else "modules ") + text


def chain_of(ports, drive: str) -> list[str]:
    """The chain ports the drive belongs to, in order (``d1, d2, ...`` or ``d1_b, d2_b, ...``);
    empty when the drive is not the first port of a chain."""
    m = CHAIN_PORT.fullmatch(drive)
    if m is None or m.group(1) != "1":
        return []
    suffix = m.group(2)
    found = {int(q.group(1)): p for p in ports
             if (q := CHAIN_PORT.fullmatch(p)) is not None and q.group(2) == suffix}
    out = []
    k = 1
    while k in found:
        out.append(found[k])
        k += 1
    return out


def module_spread(design, trajectory) -> ModuleSpread | None:
    """How far each module of a design's driven chain moved along a traced motion.

    Parameters
    ----------
    design : Design
    trajectory : Trajectory
        Its traced motion (every configuration kept).

    Returns
    -------
    ModuleSpread or None
        None for a motion that is not a chain's (fewer than two modules, a drive that is not
        the chain's first port) or a drive that did not move.

    Examples
    --------
    >>> import fabkit
    >>> d = fabkit.load_template("fourbar_chain")
    >>> module_spread(d, d.trace()).sentence()
    'spread: all 4 modules moved'
    """
    from .intent import STATE_FRACTION

    chain = chain_of(design.network.ports, design.motion.drive)
    if len(chain) < 3:
        return None
    drive = np.asarray(trajectory.drive, dtype=np.float64)
    travel = float(np.max(np.abs(drive - drive[0]))) if drive.size else 0.0
    if travel <= TINY * max(1.0, abs(float(drive[0]))):
        return None
    reach = np.array([float(np.max(np.abs(h - h[0]))) for h in
                      (np.asarray(trajectory.distance(p)) for p in chain[1:])]) / travel
    return ModuleSpread(tuple(chain), reach, STATE_FRACTION)


def shape_missed(design, spread: ModuleSpread | None) -> str:
    """Why a design whose intent is a shape (``[motion] intent = "shape"``: a curve, a letter)
    did not take it: some of its modules never moved; ``""`` when it did or is not one."""
    from .intent import template_intent

    if spread is None or not spread.localised or template_intent(design) != "shape":
        return ""
    return (f"its intent is a shape and the motion is {spread.sentence()}: the modules that "
            "did not move keep their start shape")
