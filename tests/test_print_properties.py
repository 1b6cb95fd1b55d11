"""Property: any accepted print settings give one watertight, consistently wound body whose
volume is the analytic one; settings that cannot work are refused with a FabricationError."""

from __future__ import annotations

import io

import trimesh
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from fabkit.design.assemble import chain
from fabkit.errors import FabricationError
from fabkit.writers.stl import binary_stl
from fabkit.fab.hinges import print_geometry, print_solid, solid_mesh
from fabkit.settings.printing import print_settings
from fabkit.bench.print_network import printed_module


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(copies=st.integers(1, 3),
       scale=st.floats(3.0, 8.0),
       gap=st.floats(0.2, 0.8),
       width=st.floats(0.4, 1.2),
       length=st.floats(1.0, 8.0),
       style=st.sampled_from(["neck", "bridge"]),
       layers=st.integers(1, 3))
def test_accepted_settings_give_a_sound_solid(copies, scale, gap, width, length, style, layers):
    net = chain(printed_module(), copies)
    bridge = {"hinge_layers": layers} if style == "bridge" else {}  # a neck has no layer count
    s = print_settings({"scale": scale, "gap": gap, "hinge_width": width,
                        "hinge_length": length, "hinge_style": style, **bridge})
    try:
        geo = print_geometry(net, s)
    except FabricationError as exc:
        assert "\n" not in str(exc)
        event("refused")
        return
    event("built")
    verts, faces = solid_mesh(print_solid(geo))
    mesh = trimesh.load(io.BytesIO(binary_stl(verts, faces)), file_type="stl")
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.body_count == 1
    assert abs(mesh.volume - geo.volume) <= 1e-6 * geo.volume
    assert geo.min_feature["plate_gap"] >= gap * (1 - 1e-9)
