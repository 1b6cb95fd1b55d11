"""The printing benchmark's function runs end to end on a small network (not a timing test)."""

from __future__ import annotations

from fabkit.bench.print_network import benchmark_print


def test_benchmark_print_small_chain():
    r = benchmark_print(16, transition=True)
    assert r["modules"] == 4 and r["triangles"] == 16
    assert r["hinges"] == 4 * 4 + 2 * 3
    assert r["watertight"] and r["winding_consistent"] and r["bodies"] == 1
    assert r["volume_rel_error"] <= 1e-6
    assert r["thin_features"] == 0
    assert r["rebuild_problems"] == [] and r["rebuilt_nodes"] == 2 + 6 * 4
    assert r["conformational_modes"] == 1
    assert r["transition_ok"]
    assert r["transition_max_deviation"] < 1e-4
    assert set(r["seconds"]) >= {"network", "outlines", "solid", "stl", "read_and_check",
                                 "rebuild", "modes", "transition", "total"}
    assert all(v >= 0 for v in r["seconds"].values())
