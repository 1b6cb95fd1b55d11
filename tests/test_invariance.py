"""A verdict is a property of the design: the same on every copy of it that is physically the same.

Each design is run as bundled and as three copies (tests/design_variants.py): its nodes
renumbered (every sum and factorisation over the nodes in another order), the whole design
turned and moved, and its coordinates perturbed by 1e-12 of its size (a design placed exactly
at a threshold, such as a flat sheet or a target at a fold, moved off it by far less than any
maker could tell); and with one and with two BLAS threads. The tolerance verdicts (flag, margin
to two significant digits, the fraction of builds that keep the behaviour, the criteria and
crystals), the mode counts of every bundled design and the laser layer plan of the super-stable
chain must not change. On a CPU that offers both, the origami sheet's verdict is also compared
under OpenBLAS's Haswell and SkylakeX kernels, whose last bits differ.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import fabkit
from design_variants import VARIANTS
from fabkit.templates import bundled_names
from fabkit.tolerance import analyse_tolerance, tolerance_spec

#: The builds the paper photographs working (Fig. 5), a chaotic chain and the AND gate.
TOLERANCE_DESIGNS = ["super_stable_chain", "origami_sheet", "origami_chain12", "printed_planar",
                     "printed_planar_chain10", "chaotic_chain", "and_gate"]

#: Builds of the AND gate, traced one by one (it has no construction order): its verdict (every
#: build goes together within its play, collapses its branch and keeps its trunk still) shows on
#: a few as on all of them.
AND_GATE_SAMPLES = 12


def _tolerance_facts(design) -> dict:
    """What a tolerance verdict says, in the precision a verdict is read."""
    spec = tolerance_spec(design, samples=AND_GATE_SAMPLES) if design.name == "and_gate" \
        else None
    res = analyse_tolerance(design, spec, attribute=design.name != "and_gate")
    b = res.behaviour
    return {
        "flagged": bool(res.flagged),
        "margin": f"{res.margin['value']:.2g}",
        "bound": res.margin["bound"],
        "sources": {k: f"{v['value']:.2g}" for k, v in res.margin["sources"].items()},
        "keep": round(float(res.keep_fraction), 3),
        "criteria": {k: round(float(j.ok.mean()), 3) for k, j in res.judged.items()},
        "end": (b.end, b.end_at),
        "crystals": [(c.value, c.kind, c.role, c.at_turning) for c in b.crystals],
        "order": b.order,
    }


def _expected(facts: dict) -> dict:
    """Facts to compare a copy's with: crystal values to 1e-5 (a touching fixed point, of slope
    1, moves by the square root of a change of the design: 1e-6 for the 1e-12 copy)."""
    return {**facts, "crystals": [(pytest.approx(v, rel=1e-5), *rest)
                                  for v, *rest in facts["crystals"]]}


def _variants():
    return [pytest.param(v, id=v) for v in VARIANTS]


@pytest.fixture(scope="module")
def bundled_facts():
    """The tolerance facts of each design as bundled (one BLAS setting: the machine's)."""
    return {n: _tolerance_facts(fabkit.load_template(n)) for n in TOLERANCE_DESIGNS}


@pytest.mark.parametrize("variant", _variants())
@pytest.mark.parametrize("name", TOLERANCE_DESIGNS)
def test_tolerance_verdict_is_the_same_on_a_copy(bundled_facts, name, variant):
    copy = VARIANTS[variant](fabkit.load_template(name))
    assert _tolerance_facts(copy) == _expected(bundled_facts[name])


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("name", TOLERANCE_DESIGNS)
def test_tolerance_verdict_is_the_same_with_any_blas_threads(bundled_facts, name, threads):
    with threadpool_limits(threads):
        assert _tolerance_facts(fabkit.load_template(name)) == _expected(bundled_facts[name])


def test_the_verdicts_are_the_known_ones(bundled_facts):
    """The copies agree with the right answers, not merely with one another."""
    f = bundled_facts
    for name in ("super_stable_chain", "origami_sheet", "origami_chain12", "printed_planar",
                 "printed_planar_chain10"):
        assert not f[name]["flagged"], name
        assert float(f[name]["margin"]) >= 1.0, name
    # the flat sheet starts at its flat crystal, at the end of its branch (where the motion
    # turns back); its slope there is the limit from inside, 0.0938 (not round-off)
    root2 = pytest.approx(np.sqrt(2), abs=1e-12)
    assert (root2, "stable", "start", True) in f["origami_sheet"]["crystals"]
    assert (pytest.approx(2 - np.sqrt(2), abs=1e-12), "unstable", "end", False) \
        in f["origami_sheet"]["crystals"]
    # the chain of sheets ends flat, at its branch's end, on every copy
    assert (root2, "unstable", "end", True) in f["origami_chain12"]["crystals"]
    assert f["chaotic_chain"]["flagged"]
    assert not f["and_gate"]["flagged"]
    assert f["and_gate"]["criteria"] == {"driven state": 1.0, "still ports": 1.0}
    assert f["and_gate"]["end"] == ("switch", "target")


def _mode_counts(net) -> tuple:
    m = fabkit.count_modes(net)
    return m.total, m.conformational, m.self_stress, m.certificate, bool(m.ambiguous)


@pytest.mark.parametrize("name", bundled_names())
def test_mode_counts_are_the_same_on_every_copy(name):
    d = fabkit.load_template(name)
    want = _mode_counts(d.network)
    for variant, make in VARIANTS.items():
        assert _mode_counts(make(d).network) == want, variant
    for threads in (1, 2):
        with threadpool_limits(threads):
            assert _mode_counts(fabkit.load_template(name).network) == want, threads


def _layer_plan(design) -> tuple:
    from fabkit.fab.laser_plan import laser_plan

    st = laser_plan(design).stacking
    return (st.n_layers, st.lower_bound, np.bincount(st.layer).tolist(),
            len(st.conflicts.pairs))


def test_the_layer_plan_is_the_same_on_every_copy():
    d = fabkit.load_template("super_stable_chain")
    want = _layer_plan(d)
    assert want[0] == want[1] == 7  # proven minimal
    for variant, make in VARIANTS.items():
        assert _layer_plan(make(d)) == want, variant
    with threadpool_limits(1):
        assert _layer_plan(d) == want


# --- OpenBLAS kernels ------------------------------------------------------------------------

def _cpu_flags() -> set:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    for line in text.splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


def _openblas() -> bool:
    import numpy  # noqa: F401  (loads numpy's BLAS, so threadpoolctl sees it)

    return any(i.get("internal_api") == "openblas" for i in threadpool_info())


def _verdict_under(kernel: str, tmp: Path) -> dict:
    out = tmp / kernel
    env = {**os.environ, "OPENBLAS_CORETYPE": kernel}
    rc = subprocess.run([sys.executable, "-m", "fabkit", "tolerance", "origami_sheet", "-o",
                         str(out)], env=env, capture_output=True, text=True)
    assert rc.returncode == 0, rc.stderr
    data = json.loads((out / "origami_sheet" / "tolerance.json").read_text())
    return {"flagged": data["flagged"], "margin": f"{data['margin']:.2g}",
            "sources": {k: f"{v['value']:.2g}" for k, v in data["source_margins"].items()},
            "crystals": [(round(c["value"], 6), c["kind"], c["at_turning_point"])
                         for c in data["behaviour"]["crystals"]]}


@pytest.mark.skipif(not {"avx2", "avx512f"} <= _cpu_flags(),
                    reason="needs a CPU with AVX2 and AVX-512, which both kernels run on")
@pytest.mark.skipif(not _openblas(), reason="numpy's BLAS is not OpenBLAS")
def test_the_sheet_verdict_is_the_same_under_the_haswell_and_skylakex_kernels(tmp_path):
    haswell = _verdict_under("Haswell", tmp_path)
    skylake = _verdict_under("SkylakeX", tmp_path)
    assert haswell == skylake
    assert not haswell["flagged"]


# --- thresholds with a stated tolerance ------------------------------------------------------

@pytest.mark.parametrize("nudge", [-1e-12, 0.0, 1e-12])
def test_bars_exactly_the_clearance_apart_do_not_conflict_on_any_machine(nudge):
    """Two bars drawn exactly the clearance apart meet it: round-off (or a nanometre of
    drawing) does not put them on different layers; a micrometre closer does."""
    from fabkit.fab.layers import find_conflicts

    width, clearance = 14.0, 1.0
    apart = width + clearance + nudge * 100.0
    x = np.array([[[0.0, 0.0], [100.0, 0.0], [0.0, apart], [100.0, apart]]])
    edges = [[0, 1], [2, 3]]
    c = find_conflicts(edges, x, width=width, clearance=clearance, column_radius=0.0,
                       screw_joints=[])
    assert c.pairs.shape[0] == 0
    x[0, 2:, 1] -= 1e-3
    c = find_conflicts(edges, x, width=width, clearance=clearance, column_radius=0.0,
                       screw_joints=[])
    assert c.pairs.tolist() == [[0, 1]]
    assert c.gap[0] == pytest.approx(clearance - 1e-3, abs=1e-9)
