"""Every case of the stability study, with every method, keeps its class (docs/bench.md).

The expected classes are those of the study before the large-network work (sparse mode count,
banded factorisations in ``projected``): faster must not mean less honest at singularities.
"""

import pytest

from fabkit.bench import stability as stab

F, S = stab.FINISHED, stab.STOPPED_OK

#: (case, method) -> class; rk4-nullspace with step 0.02 as in the study.
EXPECTED = {
    ("fourbar_flat", "constructive"): S, ("fourbar_flat", "projected"): S,
    ("fourbar_flat", "rk4-nullspace"): S, ("fourbar_flat", "branch"): S,
    ("origami_flat", "constructive"): S, ("origami_flat", "projected"): S,
    ("origami_flat", "rk4-nullspace"): S, ("origami_flat", "branch"): F,
    ("turning_point", "constructive"): S, ("turning_point", "projected"): S,
    ("turning_point", "rk4-nullspace"): stab.MISPLACED, ("turning_point", "branch"): S,
    ("turning_point_away", "constructive"): F, ("turning_point_away", "projected"): F,
    ("turning_point_away", "rk4-nullspace"): F, ("turning_point_away", "branch"): F,
    ("super_stable", "constructive"): F, ("super_stable", "projected"): F,
    ("super_stable", "rk4-nullspace"): stab.INACCURATE, ("super_stable", "branch"): F,
    ("super_unstable", "constructive"): F, ("super_unstable", "projected"): F,
    ("super_unstable", "rk4-nullspace"): stab.WRONG_BRANCH, ("super_unstable", "branch"): F,
    ("self_stress", "constructive"): S, ("self_stress", "projected"): S,
    ("self_stress", "rk4-nullspace"): S, ("self_stress", "branch"): S,
    ("self_stress_held", "constructive"): S, ("self_stress_held", "projected"): S,
    ("self_stress_held", "rk4-nullspace"): S, ("self_stress_held", "branch"): S,
    ("chaotic", "constructive"): F, ("chaotic", "projected"): F,
    ("chaotic", "rk4-nullspace"): stab.INACCURATE, ("chaotic", "branch"): F,
}


@pytest.fixture(scope="module")
def cases():
    return {c.name: c for c in stab.stability_cases()}


def test_every_case_is_covered(cases):
    assert {name for name, _ in EXPECTED} == set(cases)


@pytest.mark.parametrize("name, method", sorted(EXPECTED))
def test_case_keeps_its_class(cases, name, method):
    opts = {"step": 0.02} if method == "rk4-nullspace" else None
    # the budget only guards against a runaway run: a class must not depend on the machine
    row = stab.run_case(cases[name], method, opts, budget=600)
    assert row["class"] == EXPECTED[name, method], row["message"]
    if row["class"] == F:
        assert row["edge_error"] <= 1e-9
    if row["class"] == S and row["status"] not in ("raised", "failed"):
        # stopped where the motion ends, with the bars intact
        assert row["stop_error"] <= cases[name].tol_stop
        assert row["edge_error"] <= 1e-6
