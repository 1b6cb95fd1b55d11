"""Checks of the Python API's arguments, at the boundary of each public function.

A wrong argument is answered where it enters, in fabkit's words and naming the argument —
``copies must be a whole number, got 2.5`` — instead of from deep inside (an AttributeError on
``None.nodes``, a ``copies=2.5`` that quietly builds 2 copies, a ``copies=10**7`` that runs
out of memory). The errors are :class:`~fabkit.errors.ArgumentTypeError` (also a
``TypeError``) and :class:`~fabkit.errors.ArgumentValueError` (also a ``ValueError``), as
Python users expect; sizes past the bounds are :class:`~fabkit.errors.BoundsError` with the
estimate (``FABKIT_ALLOW_LARGE=1`` lifts them).

Examples
--------
>>> whole("copies", 3, minimum=1)
3
>>> whole("copies", 2.5, minimum=1)
Traceback (most recent call last):
...
fabkit.errors.ArgumentTypeError: copies must be a whole number, got 2.5
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .errors import ArgumentTypeError, ArgumentValueError
from .numerics import EDGE_RTOL, TINY

__all__ = ["whole", "real", "choice", "port", "names"]


def whole(name: str, value, minimum: int | None = None, maximum: int | None = None) -> int:
    """``value`` as an int when it is a whole number (not a bool, not 2.5 or 2.0) in range."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ArgumentTypeError(name, f"must be a whole number, got {_show(value)}")
    value = int(value)
    if minimum is not None and value < minimum:
        raise ArgumentValueError(name, f"must be at least {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise ArgumentValueError(name, f"must be at most {maximum}, got {value}")
    return value


def real(name: str, value, *, positive: bool = False, minimum: float | None = None) -> float:
    """``value`` as a float when it is a finite real number (not a bool), in range."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ArgumentTypeError(name, f"must be a number, got {_show(value)}")
    value = float(value)
    if not math.isfinite(value):
        raise ArgumentValueError(name, f"must be finite, got {value}")
    if positive and value <= 0:
        raise ArgumentValueError(name, f"must be positive, got {value:g}")
    if minimum is not None and value < minimum:
        raise ArgumentValueError(name, f"must be at least {minimum:g}, got {value:g}")
    return value


def choice(name: str, value, choices):
    """``value`` when it is one of ``choices`` (compared with ``==``)."""
    try:
        ok = value in tuple(choices)
    except TypeError:  # an unhashable value compared with hashables is simply not one of them
        ok = False
    if not ok:
        listed = ", ".join(repr(c) for c in choices)
        raise ArgumentValueError(name, f"must be one of {listed}, got {_show(value)}")
    return value


def port(name: str, value, net) -> str:
    """``value`` when it names a port of ``net``."""
    if not isinstance(value, str):
        raise ArgumentTypeError(name, f"must be a port name (a string), got {_show(value)}")
    if value not in net.ports:
        known = ", ".join(sorted(net.ports)) or "none"
        raise ArgumentValueError(name, f"{value!r} is not a port of the network (ports: "
                                       f"{known})")
    return value


def names(name: str, value, net) -> tuple:
    """A sequence of port names of ``net`` (a string alone is one name, not its letters)."""
    if isinstance(value, str):
        value = (value,)
    if not isinstance(value, (list, tuple)):
        raise ArgumentTypeError(name, f"must be a list of port names, got {_show(value)}")
    return tuple(port(f"{name}[{i}]", v, net) for i, v in enumerate(value))


def positions(name: str, value, net) -> np.ndarray:
    """A configuration of ``net``: an (N, d) array of finite coordinates in which every edge
    has a length (beyond round-off of the coordinates; an edge of no length has no direction).
    """
    try:
        x = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ArgumentTypeError(name, "must be an array of node coordinates, got "
                                      f"{type(value).__name__}") from None
    if x.shape != net.nodes.shape:
        raise ArgumentValueError(name, f"must have shape {net.nodes.shape} (one row per node), "
                                       f"got {x.shape}")
    if not np.isfinite(x).all():
        i = int(np.flatnonzero(~np.isfinite(x).all(axis=1))[0])
        raise ArgumentValueError(name, f"must be finite, got {x[i].tolist()} for node {i}")
    if net.n_edges:
        lengths = np.linalg.norm(x[net.edges[:, 1]] - x[net.edges[:, 0]], axis=1)
        short = np.flatnonzero(lengths <= EDGE_RTOL * max(float(np.abs(x).max()), TINY))
        if short.size:
            a, b = (int(v) for v in net.edges[short[0]])
            raise ArgumentValueError(name, f"puts nodes {a} and {b} of edge {int(short[0])} at "
                                           "one point; every edge needs a length")
    return x


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else f"a {type(value).__name__}"
