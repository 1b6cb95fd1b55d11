"""Plates and hinges of printed triangle networks: triangles found, gaps kept, refusals."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

import fabkit
from fabkit.design.assemble import chain
from fabkit.errors import FabricationError
from fabkit.fab.hinges import hinge_bending, print_geometry, rigid_triangles
from fabkit.settings.printing import print_settings

from conftest import TEMPLATES

MODULE_TRIANGLES = [[0, 1, 3], [0, 2, 4], [3, 5, 6], [4, 5, 7]]
SETTINGS = {"material": "TPU", "hinge_style": "neck", "hinge_width": 0.8, "hinge_length": 4.0,
            "gap": 0.4, "scale": 4.0}


@pytest.fixture(scope="module")
def printed(module):
    return module("printed_planar")


def test_cliques_are_the_papers_triangles(printed):
    assert rigid_triangles(printed).tolist() == MODULE_TRIANGLES
    assert rigid_triangles(printed, MODULE_TRIANGLES).tolist() == MODULE_TRIANGLES


def test_chain_cliques_are_the_module_triangles_of_every_copy(printed):
    net = chain(printed, 10)
    tri = rigid_triangles(net)
    assert tri.shape == (40, 3)
    # every edge in exactly one triangle: 4 triangles x 3 sides = 12 edges per module
    sides = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]]), axis=1)
    assert len(np.unique(sides, axis=0)) == net.n_edges == 120
    # the shared port nodes (1, 2 of one module = 6, 7 of the next) each join two triangles
    owners = np.bincount(tri.ravel(), minlength=net.n_nodes)
    for k in range(2, 11):
        a, b = net.port(f"d{k}")
        assert owners[a] == owners[b] == 2


def test_given_triangle_must_be_made_of_edges(printed):
    with pytest.raises(FabricationError, match=r"rigid triangle \[0, 1, 2\]: its side \[1, 2\] "
                                               r"is not an edge"):
        rigid_triangles(printed, [[0, 1, 2]] + MODULE_TRIANGLES[1:])


def test_edge_outside_triangles_refused(fourbar):
    with pytest.raises(FabricationError, match="no rigid triangles"):
        rigid_triangles(fourbar)
    net = fabkit.Network([[0, 0], [1, 0], [0, 1], [2, 1]], [[0, 1], [1, 2], [0, 2], [1, 3]])
    with pytest.raises(FabricationError, match=r"edge \(1, 3\) belongs to no rigid triangle"):
        rigid_triangles(net)


def test_plates_keep_the_gap_and_areas_are_exact(printed):
    s = print_settings(SETTINGS)
    geo = print_geometry(printed, s)
    polys = shapely.polygons(shapely.linearrings(np.concatenate(geo.plates), indices=np.repeat(
        np.arange(len(geo.plates)), [len(p) for p in geo.plates])))
    assert np.allclose(shapely.area(polys), geo.plate_areas, rtol=1e-12)
    assert np.all(geo.plate_areas > 0)  # counter-clockwise
    dist = shapely.distance(polys[:, None], polys[None])
    off = dist[~np.eye(len(polys), dtype=bool)]
    assert off.min() >= s.gap * (1 - 1e-9)
    assert geo.min_feature["plate_gap"] == pytest.approx(off.min())
    # every plate lies inside its triangle, half a gap from each side
    tri = geo.positions[geo.triangles]
    tri_polys = shapely.polygons(tri)
    assert np.all(shapely.contains(tri_polys, polys))
    inner = shapely.buffer(tri_polys, -0.5 * s.gap, join_style="mitre")
    assert np.all(shapely.area(shapely.difference(polys, inner)) < 1e-9)
    # 4 joints (0, 3, 4, 5), two arms each; free hinge length at least hinge_length
    assert geo.joints.tolist() == [0, 3, 4, 5]
    assert len(geo.arms) == 8
    assert np.all(geo.arm_length >= 0.5 * s.hinge_length - 1e-12)
    assert geo.min_feature["plate_neck"] >= s.hinge_width + s.nozzle_width - 1e-9
    assert geo.volume == pytest.approx(geo.plate_volume + geo.hinge_volume)
    # the outline is centred on the origin of the print frame
    assert np.allclose(geo.positions.min(0) + geo.positions.max(0), 0.0, atol=1e-12)


def test_scale_too_small_refused_with_the_scale_that_works(printed):
    with pytest.raises(FabricationError, match=r"triangle \(0, 3, 1\) is too small .*raise scale "
                                               r"above"):
        print_geometry(printed, print_settings({**SETTINGS, "scale": 0.3}))


def test_overlapping_triangles_refused():
    # two triangles sharing vertex 0 whose interiors overlap
    net = fabkit.Network([[0, 0], [10, 0], [0, 10], [10, 2], [2, 10]],
                         [[0, 1], [1, 2], [0, 2], [0, 3], [3, 4], [0, 4]])
    with pytest.raises(FabricationError, match="less than the 0.4 mm gap"):
        print_geometry(net, print_settings({"scale": 3.0, "hinge_length": 2.0}))


def test_separate_pieces_refused():
    net = fabkit.Network([[0, 0], [10, 0], [0, 10], [30, 0], [40, 0], [30, 10]],
                         [[0, 1], [1, 2], [0, 2], [3, 4], [4, 5], [3, 5]])
    with pytest.raises(FabricationError, match="form 2 separate pieces"):
        print_geometry(net, print_settings({"scale": 1.0}))


def test_3d_network_refused(module):
    with pytest.raises(FabricationError, match="planar; this network is 3D"):
        print_geometry(module("origami_sheet"), print_settings({}))


def test_hinge_bending_measures_relative_rotation():
    # two triangles joined at node 2; the second turns about it by up to 0.3 rad and back
    net = fabkit.Network([[0, 0], [10, 0], [10, 8], [20, 10], [12, 18]],
                         [[0, 1], [1, 2], [0, 2], [2, 3], [3, 4], [2, 4]])
    s = print_settings({"scale": 2.0, "hinge_length": 4.0})
    geo = print_geometry(net, s)
    assert geo.joints.tolist() == [2] and len(geo.arms) == 2
    angles = np.array([0.0, 0.1, 0.3, 0.2])
    c, si = np.cos(angles), np.sin(angles)
    rot = np.stack([np.stack([c, -si], -1), np.stack([si, c], -1)], -2)  # (S, 2, 2)
    x = np.repeat(net.nodes[None], len(angles), axis=0)
    x[:, 3:] = np.einsum("sij,nj->sni", rot, net.nodes[3:] - net.nodes[2]) + net.nodes[2]
    turn, strain = hinge_bending(geo, x)
    assert np.allclose(turn, 0.3, atol=1e-12)
    free = geo.arm_length.sum()
    assert np.allclose(strain, s.hinge_width * 0.3 / (2.0 * free), rtol=1e-12)


def test_template_triangles_match_cliques():
    design = fabkit.load_template(TEMPLATES / "printed_planar.toml")
    given = design.fabrication["print"]["rigid_triangles"]
    assert rigid_triangles(design.network, given).tolist() == rigid_triangles(
        design.network).tolist() == MODULE_TRIANGLES
