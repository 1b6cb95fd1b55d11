"""The front function of the kinematics: :func:`trace`, its registry ``METHODS`` and the choice
of the cheapest adequate method (:func:`select_method`)."""

from __future__ import annotations

from dataclasses import replace

from ..errors import ArgumentTypeError, ArgumentValueError, ConstructionError, KinematicsError
from ..io.workload import require
from ..model.network import Network
from .base import check_option, make_problem, Method
from .constructive import cached_plan, Constructive
from .projected import Projected
from .rk4_nullspace import RK4Nullspace
from .trajectory import Trajectory

__all__ = ["METHODS", "trace", "select_method"]

#: Registry of tracing methods: name → class. A user's own :class:`Method` subclass may be passed
#: to :func:`trace` directly.
#: The branch-switching method (:class:`~fabkit.kinematics.branching.BranchSwitch`) traces with
#: :func:`trace` after its step off a singular state; it is registered by the package
#: (``fabkit/kinematics/__init__.py``), so that this module does not import it back.
METHODS: dict[str, type[Method]] = {
    Constructive.name: Constructive,
    Projected.name: Projected,
    RK4Nullspace.name: RK4Nullspace,
}


def select_method(net: Network, drive, *, start=None) -> str:
    """The cheapest adequate method: ``"constructive"`` where a construction order exists from
    the drive pair (and the start is not a flat state), else ``"projected"``."""
    problem = make_problem(net, drive, to=1.0, start=start)
    try:
        cached_plan(problem.work, problem.drive, problem.start)
    except ConstructionError:
        return Projected.name
    return Constructive.name


def trace(net: Network, drive="d1", to=None, method="auto", *, start=None, hold=(), gauge=None,
          keep="all", ports=None, **options) -> Trajectory:
    """Trace the motion of a network while a distance (the drive) moves to a target value.

    Parameters
    ----------
    net : Network
        A network with one conformational motion (after held ports are fixed).
    drive : str or (int, int)
        Port name (``"d1"``) or node pair whose distance is driven.
    to : float
        Target value of the drive (design units).
    method : str or Method subclass
        ``"auto"`` (cheapest adequate), ``"constructive"``, ``"projected"``, ``"rk4-nullspace"``,
        or a :class:`Method` subclass.
    start : array_like, shape (N, d), optional
        Start configuration (must keep the edge lengths); ``net.nodes`` by default.
    hold : str or sequence, optional
        Ports whose distances are held at their start values (added as virtual edges); use it to
        drive one branch of a network with several motions.
    gauge : sequence of int, optional
        Nodes held still in the output (an edge in 2D, a triangle in 3D); chosen near the drive's
        first node by default.
    keep : "all", "ports" or int
        What the trajectory keeps: every configuration (default); or at every configuration the
        drive, arclength, edge error and every port's distance (``Trajectory.port_values``),
        with the positions of the first and last configurations only (``"ports"``) or of every
        k-th as well (an integer k). The rest is streamed, not stored: a 100 000-module chain's
        101 configurations would take 0.5 GB.
    ports : sequence of str, optional
        With ``keep="ports"`` or an integer: the ports whose distances are kept at every
        configuration (default: every port). A million-module chain's ports at 101
        configurations take 0.8 GB; ``ports=["d1", "d1000001"]`` keeps its ends only.
    **options
        Method options (see each method's docstring); an unknown option raises ``TypeError``.

    Returns
    -------
    Trajectory
        With ``status`` ``finished``, ``turning_point``, ``branch_point`` or ``failed`` and a
        message that says where and why.

    Raises
    ------
    ValueError
        Unknown method name (the message lists the valid ones).
    TypeError
        Unknown option.
    KinematicsError
        Invalid drive, target, start or keep; ``ConstructionError`` when
        ``method="constructive"`` and the network has no construction order.

    Examples
    --------
    >>> import fabkit
    >>> net = fabkit.Network([[-1, -1], [-1, 1], [1, -1], [1, 1]], [[0, 2], [0, 3], [1, 2], [1, 3]],
    ...                      ports={"d1": (0, 1), "d2": (2, 3)})
    >>> traj = fabkit.trace(net, drive="d1", to=2.5)
    >>> traj.method, str(traj.status)
    ('constructive', 'finished')
    >>> round(float(traj.distance("d1")[-1] * traj.distance("d2")[-1]), 12)
    4.0
    """
    if to is None:
        raise KinematicsError("`to` (the target value of the drive) is required")
    request = {"drive": drive, "to": to, "method": method, "hold": hold, "options": dict(options)}
    problem = make_problem(net, drive, to, start=start, hold=hold, gauge=gauge, keep=keep,
                           ports=ports)
    if isinstance(method, type) and issubclass(method, Method):
        cls = method
    elif method == "auto":
        known = set().union(*(c.options for c in METHODS.values()))
        unknown = sorted(set(options) - known)
        if unknown:
            raise ArgumentTypeError(unknown[0], f"is an unknown option of every method "
                                                f"(unknown option(s): {', '.join(unknown)}); "
                                                f"valid: {', '.join(sorted(known))}")
        for name, value in options.items():  # checked even when the chosen method drops it
            check_option("auto", name, value)
        try:
            plan = cached_plan(problem.work, problem.drive, problem.start)
        except ConstructionError:
            cls = Projected
        else:
            cls = Constructive
            options = {**options, "plan": options.get("plan") or plan}
        # under auto, options meant for the method not chosen are dropped
        options = {k: v for k, v in options.items() if k in cls.options}
    else:
        try:
            cls = METHODS[method]
        except (KeyError, TypeError):
            valid = ", ".join(["auto", *METHODS])
            raise ArgumentValueError("method", f"{method!r:.60} is unknown; valid methods: "
                                               f"{valid} (or a Method subclass)") from None
    if "samples" in options and cls.options.get("samples") is not None:
        check_option(cls.name, "samples", options["samples"])
        _require_samples(net, int(options["samples"]))
    return replace(cls(problem, **options).run(), request=request)


def _require_samples(net: Network, samples: int) -> None:
    """A sampled trace holds every sample's configuration while it computes: refused, before
    it starts, past the bounds of :func:`fabkit.io.workload.require`."""
    require(f"trace: samples = {samples:,} on {net.n_nodes:,} nodes",
            ("trace configuration node", samples * net.n_nodes), ("stored value", samples))
