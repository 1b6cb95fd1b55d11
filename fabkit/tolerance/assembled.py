"""Builds put together with the play their joints have, forced where it is too small, and the
slop the play leaves at the ports (../DESIGN.md, levels 5 and 6; :mod:`fabkit.builds`).

A laser kit is assembled from parts: its bars, each with its own length error, must all fit on
the pins at once. A network without a state of self-stress takes any lengths (the rigid model
answers); one with self-stress goes together when the holes' play closes its loops (the play
model answers, first order and then on the nonlinear network), or is forced together by
straining the acrylic (the elastic model answers: the stress in the bars against the material's
allowable stress). Prints and folded sheets are made in one piece, assembled as they are made:
none of this applies to them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..builds.assembly import assemble, bar_stress
from ..builds.closure import play_ratio, play_ratio_sparse, self_stress_basis
from ..builds.materials import bar_stiffness, Material, process_material
from ..builds.slop import port_slop
from ..numerics import TINY
from ..numerics import one_blas_thread
from .processes import bar_play_ends, nominal_room_mm
from ..model.network import is_chain_port

__all__ = ["Assemblies", "assemble_builds", "slop_summary", "MODEL_NAMES"]

#: A chain's slop "does not grow" when its fitted growth over the whole chain is below this
#: fraction of the largest port's slop (a super-stable chain: each module's play stays local).
FLAT_SLOP_FRACTION = 0.01

#: What each level of model is called in verdicts and reports.
MODEL_NAMES = {"rigid": "rigid bars (no state of self-stress: any lengths go together)",
               "play": "rigid bars with joint play",
               "elastic": "elastic bars with joint play (some builds are forced together)"}


@dataclass(frozen=True, eq=False)
class Assemblies:
    """Every build of a Monte Carlo as it goes together.

    Attributes
    ----------
    model : str
        The level that answered: ``"rigid"``, ``"play"`` or ``"elastic"`` (:data:`MODEL_NAMES`).
    self_stresses : int
        States of self-stress of the network at its start.
    ratio : numpy.ndarray, shape (M,)
        First-order play ratio of every build (:func:`fabkit.builds.closure.play_ratio`):
        ``<= 1`` closes within the play.
    closes : numpy.ndarray of bool, shape (M,)
        The build goes together within its play (the nonlinear assembly).
    stress_mpa : numpy.ndarray, shape (M,)
        Largest axial stress of a bar of the least-energy assembly (0 where it closes).
    force_n : numpy.ndarray, shape (M,)
        Largest force a bar puts on its pin there (N).
    worst_joint : numpy.ndarray of int, shape (M,)
        The joint that carries it (-1 where the build closes).
    positions : numpy.ndarray, shape (M, N, d)
        Each build as assembled (design units).
    material : Material
    allowable_mpa : float
    loop_nodes : list of int
        Joints of the bars the states of self-stress involve (where play closes the loops).
    room_mm : float
        Each bar's nominal axial room (mm).
    needed_room_mm : float or None
        The room per bar with which 95 % of the builds would close (first order, one state of
        self-stress), None otherwise.
    joint_kind : str
        ``"hole"`` (a laser kit's screws in holes) or ``"pin"`` (a print's pins).
    turning_ends : float
        Pins: the mean number of a loop bar's ends that turn on a pin.
    """

    model: str
    self_stresses: int
    ratio: np.ndarray
    closes: np.ndarray
    stress_mpa: np.ndarray
    force_n: np.ndarray
    worst_joint: np.ndarray
    positions: np.ndarray
    material: Material
    allowable_mpa: float
    loop_nodes: list
    room_mm: float
    needed_room_mm: float | None
    joint_kind: str = "hole"
    turning_ends: float = 2.0

    @property
    def forced(self) -> np.ndarray:
        """Builds that do not close but can be forced together within the allowable stress."""
        return ~self.closes & (self.stress_mpa <= self.allowable_mpa)

    @property
    def buildable(self) -> np.ndarray:
        """Builds that close, or can be forced together."""
        return self.closes | self.forced

    def sentence(self) -> str:
        """What a maker needs to know of how the builds go together, in one clause."""
        m = self.closes.size
        n = int(self.closes.sum())
        head = (f"{n} of {m} builds assemble within their play ({self.room_mm:.3g} mm per bar; "
                f"model: {MODEL_NAMES[self.model]})")
        forced = int(self.forced.sum())
        over = int((~self.buildable).sum())
        tail = []
        if forced:
            k = np.flatnonzero(self.forced)
            tail.append(f"{forced} more can be forced together (up to "
                        f"{self.stress_mpa[k].max():.3g} MPa in a bar, {self.force_n[k].max():.3g} N "
                        f"on joint {int(self.worst_joint[k][np.argmax(self.force_n[k])])}; "
                        f"{self.material.name} allows {self.allowable_mpa:g} MPa)")
        if over:
            k = np.flatnonzero(~self.buildable)
            tail.append(f"{over} would need up to {self.stress_mpa[k].max():.3g} MPa, over the "
                        f"{self.allowable_mpa:g} MPa {self.material.name} allows")
        if (forced or over) and self.needed_room_mm is not None and self.loop_nodes:
            joints = ", ".join(map(str, self.loop_nodes))
            if self.joint_kind == "pin":
                tail.append(f"print the pins at joints {joints} with "
                            f"{self.needed_room_mm / self.turning_ends:.2g} mm radial clearance "
                            "(print.pin_clearance) and 95% close")
            else:
                tail.append(f"ream the holes at joints {joints} to {self.needed_room_mm:.2g} mm "
                            "over the barrel and 95% close")
        return head + ("; " + "; ".join(tail) if tail else "")

    def as_dict(self) -> dict:
        """JSON-ready summary (no per-build arrays)."""
        return {"model": self.model, "model_name": MODEL_NAMES[self.model],
                "self_stresses": self.self_stresses, "builds": int(self.closes.size),
                "assemble": int(self.closes.sum()), "forced": int(self.forced.sum()),
                "not_buildable": int((~self.buildable).sum()),
                "first_order_close": int((self.ratio <= 1.0).sum()),
                "first_order_agrees": int(((self.ratio <= 1.0) == self.closes).sum()),
                "play_ratio_p95": float(np.percentile(self.ratio, 95, method="higher")) if self.ratio.size
                else None,
                "worst_stress_mpa": float(self.stress_mpa.max()) if self.stress_mpa.size else 0.0,
                "worst_joint_force_n": float(self.force_n.max()) if self.force_n.size else 0.0,
                "material": self.material.name, "youngs_mpa": self.material.youngs_mpa,
                "allowable_mpa": self.allowable_mpa, "loop_joints": list(self.loop_nodes),
                "room_mm": self.room_mm, "needed_room_mm": self.needed_room_mm,
                "sentence": self.sentence()}


def assemble_builds(net, builds, spec, start, play_ends=None, *,
                    settle: float | None = None) -> Assemblies:
    """Put every build together with its play; force it where the play does not close it.

    Parameters
    ----------
    net : fabkit.Network
    builds : fabkit.tolerance.processes.BuildLengths
        With ``room`` (laser); lengths and room in design units.
    spec : ToleranceSpec
        Scale (mm per unit), the bars' section (``bar_width`` × ``thickness``) and process.
    start : numpy.ndarray, shape (N, d)
        The nominal configuration the builds are put together around (design units).
    play_ends : numpy.ndarray, shape (E,), optional
        A pin-jointed print: per bar, its ends that turn on a pin (what clearance to print
        follows from the room a loop needs).
    settle : float, optional
        The builds' stall fraction once they close (:func:`fabkit.builds.assembly.assemble`):
        :data:`~fabkit.builds.assembly.SETTLE_RTOL` where only whether a build keeps its
        behaviour is asked, not where it sits.

    Returns
    -------
    Assemblies

    Notes
    -----
    The builds' steps solve small dense systems (a few hundred unknowns) on one BLAS thread:
    more threads only contend there (the AND gate's 104 builds took several times the CPU with
    two).
    """
    s = spec.scale
    rest = builds.base * s
    room = builds.room * s
    m = rest.shape[0]
    x0 = np.asarray(start, dtype=np.float64) * s
    nominal = net.edge_lengths * s
    w = self_stress_basis(net, start)
    # one state: the closed form; several: the sparse program, which needs no basis and stays
    # fast where the program over a dense basis of many states does not
    ratio = np.zeros(0) if not m else play_ratio(w, rest - nominal[None, :], room) \
        if w.shape[1] <= 1 else play_ratio_sparse(net.with_nodes(x0), rest - nominal[None, :],
                                                  room)
    material = process_material(spec.process, spec.material)
    area = spec.section_mm2
    closes = np.ones(m, dtype=bool)
    stress = np.zeros(m)
    force = np.zeros(m)
    joint = np.full(m, -1)
    positions = np.repeat(np.asarray(start, dtype=np.float64)[None], m, axis=0)
    with one_blas_thread():
        assembled = [assemble(net.edges, rest[b], room[b], x0,
                              stiffness=bar_stiffness(material, area, rest[b]), settle=settle)
                     for b in range(m)]
    for b, a in enumerate(assembled):
        positions[b] = a.positions / s
        closes[b] = a.closes
        if not a.closes:
            sigma = np.abs(bar_stress(a, rest[b], material.youngs_mpa))
            stress[b] = float(sigma.max())
            bar = int(np.argmax(sigma))
            force[b] = stress[b] * area
            joint[b] = int(net.edges[bar, 0])
    support = np.flatnonzero(np.abs(w).max(axis=1) > 0) if w.size else np.zeros(0, dtype=int)
    loop = sorted(set(net.edges[support].ravel().tolist()))
    nominal_room = float(np.median(room)) if room.size else 0.0
    needed = None
    if w.shape[1] == 1 and m:
        wv = w[:, 0]
        need = np.abs((rest - nominal[None, :]) @ wv) / max(float(np.abs(wv).sum()), TINY)
        needed = float(np.percentile(need, 95))
    model = "rigid" if w.shape[1] == 0 else ("play" if closes.all() else "elastic")
    return Assemblies(model, int(w.shape[1]), np.asarray(ratio, dtype=float), closes, stress,
                      force, joint, positions, material, material.allowable_mpa, loop,
                      nominal_room, needed, *_joints(spec, net, support, play_ends))


def _joints(spec, net, support, play_ends) -> tuple[str, float]:
    """The kind of the kit's joints and, for pins, the mean number of a loop bar's ends that
    turn on one (a bar's room over it is the radial clearance to print)."""
    if spec.process != "print":
        return "hole", 2.0
    ends = bar_play_ends(play_ends, net.n_edges)
    return "pin", max(float(np.mean(ends[support])) if len(support) else 2.0, 1.0)


def slop_summary(net, spec, ports, pairs, held, states, play_ends=None) -> dict | None:
    """The slop of every port with the drive held, at the start and the end of the motion.

    Parameters
    ----------
    net : fabkit.Network
    spec : ToleranceSpec
        Every bar's axial room is its ends' radial play
        (:func:`fabkit.tolerance.processes.nominal_room_mm`: a laser kit's ``hole_clearance``,
        a pin-jointed print's ``pin_clearance`` per end that turns on a pin); joints without
        play (flexures, creases) have no slop (None is returned).
    ports : list of str
    pairs : numpy.ndarray of int, shape (P, 2)
        Their node pairs.
    held : sequence of (int, int)
        The drive's pair and any held ports.
    states : dict of str to numpy.ndarray (N, d)
        Configurations by name (``"start"``, ``"end"``), design units.
    play_ends : numpy.ndarray, shape (E,), optional
        A pin-jointed print: per bar, its ends that turn on a pin.

    Returns
    -------
    dict or None
        ``ports`` (per port: ``start_mm``, ``end_mm``; None where unbounded), ``output`` (the
        port at the far end: the last of a chain's d1, d2, ..., else the last port not held),
        ``output_start_mm``, ``output_end_mm``, ``growth_mm_per_module`` (chains), ``room_mm``,
        ``sentence``.
    """
    room = nominal_room_mm(spec, net.n_edges, play_ends)
    if room is None or not room.any():
        return None
    heldset = {tuple(sorted(map(int, h))) for h in held}
    named = {p: (int(a), int(b)) for p, (a, b) in zip(ports, pairs.tolist())
             if tuple(sorted((int(a), int(b)))) not in heldset}
    if not named:
        return None
    out = {p: {} for p in named}
    # first order says nothing past the network's own size: there the drive no longer holds
    # the network (a module at a turning point, a flat state), and the slop is unbounded to
    # first order
    size_mm = float(net.size) * spec.scale
    for state, x in states.items():
        for r in port_slop(net, np.asarray(x) * spec.scale, room, held=list(held), ports=named):
            out[r.port][f"{state}_mm"] = r.largest if r.bounded and r.largest <= size_mm \
                else None
    chain = [p for p in named if is_chain_port(p)]
    output = chain[-1] if chain else list(named)[-1]
    rows = [{"port": p, **v} for p, v in out.items()]
    pins = spec.process == "print"
    res = {"ports": rows, "output": output,
           "room_mm": float(spec.pin_clearance if pins else spec.hole_clearance),
           "play": "radial pin play" if pins else "hole play",
           "output_start_mm": out[output].get("start_mm"),
           "output_end_mm": out[output].get("end_mm")}
    k = np.array([int(p[1:]) for p in chain], dtype=float)
    for state in states if len(chain) >= 2 else ():
        # how it grows: in the first state where every port of the chain is bounded (a fit
        # over the few ports a near-singular state leaves bounded would say nothing)
        v = np.array([out[p].get(f"{state}_mm") for p in chain], dtype=float)
        if np.isfinite(v).all():
            res["growth_mm_per_module"] = float(np.polyfit(k, v, 1)[0])
            res["growth_state"] = state
            res["chain_slop_mm"] = float(np.max(v))
            res["modules"] = int(k.max() - k.min())
            break
    res["sentence"] = _slop_sentence(res)
    return res


def _slop_sentence(res) -> str:
    def mm(v):
        return "unbounded to first order (a singular state)" if v is None or not \
            math.isfinite(v) else f"±{v:.3g} mm"
    text = (f"slop at {res['output']} with the drive held: {mm(res['output_start_mm'])} at the "
            f"start, {mm(res['output_end_mm'])} at the end ({res['room_mm']:g} mm {res['play']})")
    g = res.get("growth_mm_per_module")
    where = "" if res.get("growth_state") == "start" else f" (at the {res.get('growth_state')})"
    if g is not None and abs(g) * res["modules"] < FLAT_SLOP_FRACTION * res["chain_slop_mm"]:
        text += f"; it does not grow along the chain{where} (each module's slop stays its own)"
    elif g is not None:
        text += f"; it {'grows' if g > 0 else 'falls'} by {abs(g):.3g} mm per module along " \
                f"the chain{where}"
    return text
