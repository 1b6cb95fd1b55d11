"""Identical input gives identical DXF bytes, also across processes and string hash seeds."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys

import pytest

import fabkit
from fabkit.writers.dxf import sheet_dxf
from fabkit.fab.laser_plan import laser_plan

from conftest import TEMPLATES

_CODE = """
import hashlib, fabkit
from fabkit.writers.dxf import sheet_dxf
from fabkit.fab.laser_plan import laser_plan
plan = laser_plan(fabkit.load_template({path!r}), {{"laser": {{"flavour": {flavour!r}}}}})
print(hashlib.sha256(b"".join(sheet_dxf(s, plan, len(plan.sheets)) for s in plan.sheets)).hexdigest())
"""


def _digest_here(path, flavour):
    plan = laser_plan(fabkit.load_template(path), {"laser": {"flavour": flavour}})
    data = b"".join(sheet_dxf(s, plan, len(plan.sheets)) for s in plan.sheets)
    return hashlib.sha256(data).hexdigest()


def test_same_bytes_under_different_hash_seeds():
    # ezdxf writes the CLASS entries of the entity types in use by iterating a set of strings,
    # whose order follows the hash seed; fabkit sorts them
    path = str(TEMPLATES / "super_stable.toml")
    for flavour in ("lwpolyline", "line-arc"):
        digests = {_digest_here(path, flavour)}
        for seed in ("1", "2", "3"):
            env = dict(os.environ, PYTHONHASHSEED=seed)
            out = subprocess.run([sys.executable, "-c", _CODE.format(path=path, flavour=flavour)],
                                 env=env, capture_output=True, text=True, timeout=300, check=True)
            digests.add(out.stdout.strip())
        assert len(digests) == 1, flavour


# --- the exact searches stop at a count of work: the clock never changes a result ----------

def _with_clock(monkeypatch, seconds):
    """Run SciPy's milp with its wall-clock limit replaced: None drops it (a machine as fast as
    can be), a number sets it (a tiny one: a clock that jumps past the safety limit at once)."""
    import scipy.optimize
    from scipy.optimize._milp import milp as real

    def milp(c, **kw):
        options = dict(kw.pop("options", None) or {})
        options.pop("time_limit", None)
        if seconds is not None:
            options["time_limit"] = seconds
        return real(c, options=options, **kw)

    monkeypatch.setattr(scipy.optimize, "milp", milp)


def _layer_program():
    """The whole stacking program of the 8-module super-stable chain (48 bars) at 8 layers."""
    import numpy as np

    from fabkit.fab.layers import plan_layers, sample_chain
    from fabkit.settings.laser import laser_overrides, laser_settings

    design = fabkit.load_template(TEMPLATES / "super_stable_chain8.toml")
    net = design.network
    s = laser_settings(design.fabrication.get("laser", {}), laser_overrides({}),
                       network_size=net.size)
    sweep = sample_chain(net, design.motion, s.scale, s.sample_step, width=s.bar_width,
                         clearance=s.clearance, column_radius=0.5 * s.screw.head_diameter,
                         spacer_radius=0.5 * s.spacer_diameter, floor_limit=s.clearance)
    st = plan_layers(net.edges, sweep, s)
    edges, conf = np.asarray(net.edges), st.conflicts
    joint_bars = [np.flatnonzero((edges == j).any(axis=1)) for j in conf.screw_joints.tolist()]
    return edges.shape[0], conf, joint_bars, st.head_slots


def test_the_exact_layer_search_stops_at_its_nodes_whatever_the_clock(monkeypatch):
    """Cut off at 20 nodes, the solver's stacking and bound are the same with no clock at all,
    and a clock run out at once is an error naming the limit, never another stacking."""
    from fabkit.errors import ResourceError
    from fabkit.fab.layers.search import _milp_layers

    program = _layer_program()
    layer, bound, optimal = _milp_layers(*program, 8, node_limit=20)
    assert layer is not None and int(layer.max()) + 1 == 8 and bound == 5 and not optimal
    _with_clock(monkeypatch, None)
    fast = _milp_layers(*program, 8, node_limit=20)
    assert fast[0].tolist() == layer.tolist() and fast[1:] == (bound, optimal)
    _with_clock(monkeypatch, 1e-9)
    with pytest.raises(ResourceError, match=r"safety limit of 900 s .* work limit of 20 nodes"):
        _milp_layers(*program, 8, node_limit=20)


def test_the_rows_of_a_sheet_stop_at_their_nodes_whatever_the_clock(monkeypatch):
    """The super-stable chain's rows need 116 nodes: held to 20 the program falls back to first
    fit, the same with no clock at all; a clock run out at once is an error, never other rows."""
    import fabkit.fab.nest
    import fabkit.fab.shelves as shelves
    from fabkit.errors import ResourceError

    calls = []
    real = shelves.shelf_pack
    monkeypatch.setattr(fabkit.fab.nest, "shelf_pack",
                        lambda *a: calls.append(a) or real(*a))
    laser_plan(fabkit.load_template(TEMPLATES / "super_stable_chain.toml"))
    (args,) = calls
    solved = real(*args)
    monkeypatch.setattr(shelves, "MILP_NODES", 20)
    cut = real(*args)
    assert cut != solved  # the limit decides: first fit instead of the program's rows
    _with_clock(monkeypatch, None)
    assert real(*args) == cut
    monkeypatch.setattr(shelves, "MILP_NODES", 2_000)
    assert real(*args) == solved
    _with_clock(monkeypatch, 1e-9)
    with pytest.raises(ResourceError, match=r"safety limit of 900 s .* work limit of 2000 nodes"):
        real(*args)
