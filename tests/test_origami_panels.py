"""Crease patterns with quadrilateral and larger panels: the apex rule, F diagonals, branches."""

from __future__ import annotations

import numpy as np
import pytest

import fabkit
from fabkit.fab.creases import (CreasePattern, fold_angles, network_from_pattern,
                                planar_faces)
from fabkit.kinematics.branching import analyze_bifurcation, fold_through

# a 2 x 2 square with a vertical (x = 1) and a horizontal (y = 1) crease: four square panels
V = [[0, 0], [1, 0], [2, 0], [2, 1], [2, 2], [1, 2], [0, 2], [0, 1], [1, 1]]
E = [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 6], [6, 7], [7, 0],
     [1, 8], [3, 8], [5, 8], [7, 8]]


def test_planar_faces_are_counter_clockwise():
    faces = planar_faces(V, E)
    assert faces == ((0, 1, 8, 7), (1, 2, 3, 8), (3, 4, 5, 8), (5, 6, 7, 8))


def test_map_fold_has_two_branches_one_per_crease_line():
    cp = CreasePattern(V, E, ["B"] * 8 + ["V", "M", "V", "M"], planar_faces(V, E))
    net, info = network_from_pattern(cp, ports={"d1": (0, 4), "d2": (2, 6)})
    assert (net.n_nodes, net.n_edges) == (13, 32) and len(info["apex"]) == 4
    m = fabkit.count_modes(net)
    assert (m.conformational, m.self_stress) == (2, 1)
    bif = analyze_bifurcation(net)
    assert len(bif.branches) == 2
    folded_lines = set()
    for b in (1, 2):
        traj = fold_through(net, "d1", 2.5, branch=b, sign=1)
        assert str(traj.status) == "finished" and traj.max_edge_error < 1e-12
        ang = fold_angles(cp.edges, cp.faces, traj.final[:9])
        moving = tuple(np.flatnonzero(np.abs(ang) > 1.0).tolist())
        assert len(moving) == 2
        assert ang[moving[0]] == pytest.approx(ang[moving[1]], abs=1e-9)  # one straight line folds
        folded_lines.add(moving)
    assert folded_lines == {(8, 10), (9, 11)}  # the vertical line, then the horizontal one
    # the two branches fold the same amount: the assignment V/M/V/M cannot choose between them
    with pytest.raises(fabkit.KinematicsError, match="several branches"):
        fold_through(net, "d1", 2.5)


def test_facet_edges_join_faces_into_one_rigid_panel():
    # a 2 x 1 rectangle creased at x = 1, each square half cut into two triangles by an F edge
    v = [[0, 0], [1, 0], [2, 0], [2, 1], [1, 1], [0, 1]]
    e = [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 0], [1, 4], [0, 4], [1, 3]]
    cp = CreasePattern(v, e, ["B"] * 6 + ["V", "F", "F"], planar_faces(v, e))
    assert all(len(f) == 3 for f in cp.faces)
    net, info = network_from_pattern(cp)
    assert len(info["apex"]) == 2 and all(len(vs) == 4 for _, vs in info["apex"])
    assert info["diagonals"] == []  # the F edges already triangulate the panels
    m = fabkit.count_modes(net)
    assert (m.conformational, m.self_stress) == (1, 0)
    # read as creases instead, the F edges would be hinges: three motions
    hinged, _ = network_from_pattern(CreasePattern(v, e, ["B"] * 6 + ["V", "U", "U"], cp.faces))
    assert fabkit.count_modes(hinged).conformational == 3


def test_bad_patterns_are_named():
    with pytest.raises(fabkit.FabricationError, match="unknown edge assignment 'X'"):
        CreasePattern(V, E, ["B"] * 8 + ["V", "X", "V", "M"], planar_faces(V, E))
    with pytest.raises(fabkit.FabricationError, match="12 edges but 3 assignments"):
        CreasePattern(V, E, ["B"] * 3, planar_faces(V, E))
    with pytest.raises(fabkit.FabricationError, match="not an edge"):
        CreasePattern(V, E, ["B"] * 12, [(0, 1, 2, 8)]).edge_faces()
