"""A design's modules on their own: each built module's map d_out = f(d_in), evaluated for many
builds at once.

A chain is an iterated map only if its modules are: module k carries port d_k to port d_{k+1}.
A chain built by :func:`fabkit.chain` records its copies (``Network.assembly``), an origami chain
lists its sheets (``[fabrication.origami] sheets``), and a single module is the whole network
with ports d1 and d2. Each module becomes a network of its own (the chain's nodes and bars that
belong to it, at the chain's start) with a construction plan from its input pair, so a built
module's map is its plan placed with the build's own bar lengths: every build, module and d_in
value is one column of one :func:`fabkit.kinematics.place` call per kind of module.
"""

from __future__ import annotations

import copy

import numpy as np

from ..errors import ConstructionError, FabkitError
from ..kinematics import place
from ..motion.modules import Module
from .processes import BuildLengths, interp_rows, ProcessGeometry, PROFILE_SAMPLES, state_profile

__all__ = ["ModuleMaps"]

#: Bisection steps that find where a built module's branch ends (its own turning point) inside
#: a window of half its motion: 2^-16 of the window (4e-6 of the motion) is far below any
#: error studied.
BRANCH_END_BISECTIONS = 16

#: The profile's first and last samples sit this far (relative to the branch's extent) inside
#: its ends: at an end itself (a turning point, a flat state where branches meet) the place of
#: a node hangs on round-off, while the profile is continuous there, so this moves it by at
#: most ~3e-5 of its range (at a square-root end) and makes it the same on every machine.
PROFILE_END_INSET = 1e-9


class ModuleMaps:
    """Built modules' maps, for every build and module at once.

    Parameters
    ----------
    modules : list of Module
    geo : ProcessGeometry, optional
        With ``process``: what a state takes off the bars (:func:`state_profile`: a print's
        bent hinges, a folded sheet); None: lengths do not depend on the state.
    process : str
    """

    def __init__(self, modules: list[Module], geo: ProcessGeometry | None = None,
                 process: str = "laser"):
        self.modules = modules
        self.geo, self.process = geo, process
        bending = geo is not None and process in ("print", "origami")
        self.bending = bending
        groups: dict = {}
        for m in modules:
            groups.setdefault(m.key(), []).append(m.index)
        self.groups = list(groups.values())
        self.tables = {}
        if bending:
            from ..maps import module_map

            for group in self.groups:
                first = modules[group[0]]
                try:
                    domain = module_map(first.network, "in", "out").domain
                except (ConstructionError, FabkitError):
                    d0 = float(first.network.port_distance("in"))
                    domain = (d0, d0 + 1.0)
                for k in group:
                    self.tables[k] = self._table(modules[k], domain)

    def _table(self, module: Module, domain) -> tuple[np.ndarray, np.ndarray]:
        """:func:`state_profile` of the module's bars along its nominal branch, tabulated."""
        inset = PROFILE_END_INSET * (domain[1] - domain[0])
        grid = np.linspace(domain[0] + inset, domain[1] - inset, PROFILE_SAMPLES)
        x, margin, _ = place(module.plan, grid)
        valid = margin >= 0
        if not valid.any():
            x = np.broadcast_to(module.network.nodes, x.shape)
        elif not valid.all():
            # a sample off this module's branch takes the state of the nearest one on it (never
            # the rest state: a jump in the profile would move every build near that end)
            ok = np.flatnonzero(valid)
            nearest = ok[np.clip(np.searchsorted(ok, np.arange(grid.size)), 0, ok.size - 1)]
            before = ok[np.clip(np.searchsorted(ok, np.arange(grid.size)) - 1, 0, ok.size - 1)]
            pick = np.where(np.abs(before - np.arange(grid.size))
                            <= np.abs(nearest - np.arange(grid.size)), before, nearest)
            x = x[pick]
        out = state_profile(self.geo, self.process, x, module.nodes, module.edges)
        return grid, np.zeros((grid.size, module.edges.size)) if out is None else out

    def _shortening(self, module: Module, values) -> np.ndarray:
        """:func:`state_profile` of the module's bars in its nominal state at each d_in,
        (Q, E_k), interpolated in its table; beyond the nominal branch, that of its end."""
        grid, table = self.tables[module.index]
        return interp_rows(np.asarray(values, dtype=np.float64), grid, table)

    def evaluate(self, builds: BuildLengths, values) -> tuple[np.ndarray, np.ndarray]:
        """d_out of every built module at the given d_in values.

        Parameters
        ----------
        builds : BuildLengths
            Lengths of the whole design's bars, M builds.
        values : array_like, shape (Q,) or (M, n, Q)
            d_in values: the same for every build and module, or each its own.

        Returns
        -------
        f : numpy.ndarray, shape (M, n, Q)
            NaN where the built module has no configuration.
        margin : numpy.ndarray, shape (M, n, Q)
            Smallest intersection margin (negative: no configuration).
        """
        m, n = builds.base.shape[0], len(self.modules)
        v = np.asarray(values, dtype=np.float64)
        q = v.shape[-1]
        per = np.broadcast_to(v, (m, n, q))
        f = np.full((m, n, q), np.nan)
        margin = np.full((m, n, q), -np.inf)
        for group in self.groups:
            first = self.modules[group[0]]
            radii, cols = [], []
            for k in group:
                mod = self.modules[k]
                lengths = builds.base[:, None, mod.edges]  # (M, 1, E_k)
                if self.bending and np.any(builds.bend):
                    if v.ndim == 1:
                        short = self._shortening(mod, v)[None]  # (1, Q, E_k)
                    else:
                        short = self._shortening(mod, per[:, k, :].ravel()).reshape(
                            m, q, mod.edges.size)
                    lengths = lengths - builds.bend[:, None, mod.edges] * short
                lengths = np.broadcast_to(lengths, (m, q, mod.edges.size))
                mask = mod.eidx >= 0
                r = np.where(mask[None, None], lengths[:, :, np.maximum(mod.eidx, 0)], 0.0)
                radii.append(r.reshape((m * q,) + mod.eidx.shape))
                cols.append(per[:, k, :].reshape(m * q))
            x, mg, _ = place(first.plan, np.concatenate(cols), radii=np.concatenate(radii))
            a, b = first.network.port("out")
            out = np.linalg.norm(x[:, a] - x[:, b], axis=-1)
            out = np.where(mg >= 0, out, np.nan)
            for slot, k in enumerate(group):
                sl = slice(slot * m * q, (slot + 1) * m * q)
                f[:, k, :] = out[sl].reshape(m, q)
                margin[:, k, :] = mg[sl].reshape(m, q)
        return f, margin

    def as_made(self) -> "ModuleMaps":
        """The same maps of the modules as made: no state takes anything off their bars."""
        out = copy.copy(self)
        out.bending = False
        return out

    def place_at(self, builds: BuildLengths, values,
                 bend: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Every built module placed at its own d_in value (its state), with its build's bar
        lengths as :meth:`evaluate` places it.

        Parameters
        ----------
        builds : BuildLengths
        values : numpy.ndarray, shape (M, n)
            d_in per build and module (NaN: not placed).
        bend : bool
            False: the bars as made, without what a folded state takes off them.

        Returns
        -------
        x : numpy.ndarray, shape (M, n, V, d)
            The module's nodes in its local order (NaN where not placed); every module has
            the first one's nodes.
        margin : numpy.ndarray, shape (M, n)
            Smallest intersection margin (negative: no configuration).
        """
        m, n = builds.base.shape[0], len(self.modules)
        v = np.asarray(values, dtype=np.float64)
        first = self.modules[0]
        x = np.full((m, n) + first.network.nodes.shape, np.nan)
        margin = np.full((m, n), -np.inf)
        # each module placed by its group's plan, as evaluate places it (the same round-off)
        plans = {k: self.modules[g[0]].plan for g in self.groups for k in g}
        for k, mod in enumerate(self.modules):
            here = np.isfinite(v[:, k])
            if not here.any():
                continue
            q = np.where(here, v[:, k], float(mod.network.port_distance("in")))
            lengths = builds.base[:, mod.edges]
            if bend and self.bending and np.any(builds.bend):
                lengths = lengths - builds.bend[:, mod.edges] * self._shortening(mod, q)
            mask = mod.eidx >= 0
            r = np.where(mask[None], lengths[:, np.maximum(mod.eidx, 0)], 0.0)
            xk, mg, _ = place(plans[k], q, radii=r)
            ok = here & (mg >= 0)
            x[ok, k] = xk[ok]
            margin[:, k] = np.where(here, mg, -np.inf)
        return x, margin

    def branch_end(self, builds: BuildLengths, window, toward: float):
        """Where each built module's branch ends inside ``window``, walking from the side
        nearer ``toward`` (the side the motion comes from).

        Parameters
        ----------
        builds : BuildLengths
        window : numpy.ndarray, shape (Q,)
            Increasing d_in values.
        toward : float
            A d_in value on the valid side.

        Returns
        -------
        end, f_end : numpy.ndarray, shape (M, n)
            The branch end and d_out there; NaN where the branch does not end inside the
            window (or is not valid where the walk starts).
        last, f_last : numpy.ndarray, shape (M, n)
            The window's last valid value before the end, and d_out there.
        """
        w = np.asarray(window, dtype=np.float64)
        if abs(toward - w[-1]) < abs(toward - w[0]):
            w = w[::-1]
        f, margin = self.evaluate(builds, w)
        ok = margin >= 0
        m, n, _ = ok.shape
        bad = ~ok
        bad[..., 0] = False
        has_end = ok[..., 0] & bad.any(axis=-1)
        first = np.argmax(bad, axis=-1)
        prev = np.maximum(first - 1, 0)
        last = np.where(has_end, w[prev], np.nan)
        f_last = np.where(has_end, np.take_along_axis(f, prev[..., None], axis=-1)[..., 0],
                          np.nan)
        lo, hi = last.copy(), np.where(has_end, w[first], np.nan)
        end = np.full((m, n), np.nan)
        f_end = np.full((m, n), np.nan)
        if not has_end.any():
            return end, f_end, last, f_last
        for _ in range(BRANCH_END_BISECTIONS):
            mid = 0.5 * (lo + hi)
            _, mg = self.evaluate(builds, np.where(has_end, mid, w[0])[..., None])
            good = mg[..., 0] >= 0
            lo = np.where(good, mid, lo)
            hi = np.where(good, hi, mid)
        fv, mg = self.evaluate(builds, np.where(has_end, lo, w[0])[..., None])
        end = np.where(has_end & (mg[..., 0] >= 0), lo, np.nan)
        f_end = np.where(np.isfinite(end), fv[..., 0], np.nan)
        return end, f_end, last, f_last
