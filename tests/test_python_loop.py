"""The researcher's loop in Python, with no template written by hand: wishes → ``design_map``
→ ``chain`` → ``Design.from_network`` → ``fabkit.export`` → checks, and the pictures of
``fabkit.plot``. Files are read back with the libraries a maker's tools use (ezdxf, trimesh)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import fabkit
from fabkit.status import Status

#: The paper's designed module: super-stable at 1, a second fixed point at 2.
WISHES = [(1.0, 0.0), 2.0]


@pytest.fixture(scope="module")
def designed():
    return fabkit.design_map(WISHES, name="designed")


def _chain_design(designed, copies, name):
    net = fabkit.chain(designed.network, copies=copies, mirror="alternate")
    return fabkit.Design.from_network(net, drive="d1", to=1.5, name=name)


def test_design_map_is_one_result_unpacked_or_not(designed):
    design, report = designed
    assert design is designed and report is designed.report
    assert isinstance(design, fabkit.Design) and design.design is design
    # the attributes docs/design.md uses after unpacking
    values = sorted(p.value for p in design.map.fixed_points())
    assert values == pytest.approx([1.0, 2.0], abs=1e-9)
    assert "[design]" in design.template and design.network.n_nodes == 5
    assert report["wishes_met"]["fixed_points"][0]["residual"] < 1e-12
    traj = design.trace()  # a Design like any other
    assert traj.success


def test_the_laser_builds_have_a_public_home(designed):
    from fabkit.tolerance.builds import laser_builds

    assert fabkit.laser_builds is laser_builds
    lengths, scale, model = fabkit.laser_builds(designed)
    assert lengths.shape == (200, designed.network.n_edges) and scale == 100.0 and "kerf" in model


def test_a_designed_chain_exports_its_laser_kit(designed, tmp_path):
    import ezdxf

    design = _chain_design(designed, 20, "chain20")
    assert design.path is None and design.network.assembly.count == 20
    result = fabkit.export(design, to="dxf", out=tmp_path, previews=False, tolerance_samples=0)
    assert result.status is Status.OK, result.message
    assert result.exported_formats == ["dxf"] and result.path == "<chain20>"
    assert result.checks and all(c.ok for c in result.checks)
    sheets = sorted((tmp_path / "chain20").glob("laser_sheet*.dxf"))
    assert sheets
    holes = sum(len(ezdxf.readfile(s).modelspace().query("CIRCLE")) for s in sheets)
    # every bar of the 20 modules is cut with a hole at each end
    assert holes >= 2 * design.network.n_edges


def _print_export(designed, tmp_path, copies):
    import trimesh

    name = f"print{copies}"
    result = fabkit.export(_chain_design(designed, copies, name), to="stl", out=tmp_path,
                           previews=False, tolerance_samples=0)
    beds = sorted((tmp_path / name).glob(f"{name}_bed*.stl"))
    meshes = [trimesh.load(b, force="mesh") for b in beds]
    return result, beds, meshes


def test_a_short_designed_chain_prints(designed, tmp_path):
    result, beds, meshes = _print_export(designed, tmp_path, 3)
    assert result.status is Status.OK, result.message
    assert beds and all(len(m.faces) > 0 for m in meshes)
    # the print is checked as built from its STL and from its 3MF
    assert {c.file.rsplit(".", 1)[1] for c in result.checks} == {"stl", "3mf"}
    assert all(c.ok for c in result.checks)


def test_twenty_designed_modules_print_and_pass_their_checks(designed, tmp_path):
    result, beds, meshes = _print_export(designed, tmp_path, 20)
    assert len(beds) >= 1 and all(len(m.faces) > 0 for m in meshes)
    failed = [(c.file, [k for k in c.checks if not k.get("ok", True)]) for c in result.checks
              if not c.ok]
    assert result.status is Status.OK, failed


def test_a_design_made_in_code_saves_and_loads_back_equal(tmp_path):
    module = fabkit.load_template("super_stable").network
    net = fabkit.chain(module, copies=4)
    design = fabkit.Design.from_network(
        net, drive="d1", to=1.2, name="four", description="four modules",
        options={"samples": 51}, fabrication={"print": {"scale": 20.0}})
    back = fabkit.load_template(design.save(tmp_path / "four.toml"))
    assert back.path == tmp_path / "four.toml"
    assert (back.name, back.description, back.motion, back.fabrication) == \
        (design.name, design.description, design.motion, design.fabrication)
    assert np.array_equal(back.network.nodes, design.network.nodes)  # to the last bit
    assert np.array_equal(back.network.edges, design.network.edges)
    assert dict(back.network.ports) == dict(design.network.ports)
    # the saved design traces as the one in memory did
    a, b = design.trace(), back.trace()
    assert np.array_equal(a.distance("d5"), b.distance("d5"))


def test_a_chain_template_saves_standing_alone(tmp_path):
    chain = fabkit.load_template("super_stable_chain")
    back = fabkit.load_template(chain.save(tmp_path / "elsewhere.toml"))
    assert "network" in back.raw and "chain" not in back.raw  # no module file to find
    assert np.array_equal(back.network.nodes, chain.network.nodes)
    assert back.motion == chain.motion and back.fabrication == chain.fabrication


def test_a_designed_module_saves_its_commented_template(designed, tmp_path):
    path = designed.save(tmp_path / "m.toml")
    assert path.read_text() == designed.template
    back = fabkit.load_template(path)
    assert np.array_equal(back.network.nodes, designed.network.nodes)
    assert back.motion == designed.motion


def test_from_network_refuses_what_a_template_refuses():
    net = fabkit.load_template("fourbar").network
    with pytest.raises(fabkit.TemplateError, match="motion.drive: unknown port 'd9'"):
        fabkit.Design.from_network(net, drive="d9", to=1.0, name="x")
    with pytest.raises(fabkit.TemplateError, match="name"):
        fabkit.Design.from_network(net, name="../x")
    with pytest.raises(fabkit.FabkitError, match="must be a fabkit.Network"):
        fabkit.Design.from_network("fourbar")


def test_export_refuses_an_unknown_format_with_the_nearest(tmp_path):
    with pytest.raises(ValueError, match="unknown format 'stll'.*'stl'"):
        fabkit.export("fourbar", to="stll", out=tmp_path)
    assert not any(tmp_path.iterdir())


def test_the_plots_are_figures(designed):
    from matplotlib.figure import Figure

    from fabkit.fab.plans import make_plan

    chaotic = fabkit.load_template("chaotic")
    cob = fabkit.plot.cobweb(chaotic)
    assert isinstance(cob, Figure)
    (ax,) = cob.axes
    assert len(ax.lines) >= 4  # the map, the diagonal, an orbit and its marks
    traj = fabkit.trace(fabkit.chain(designed.network, copies=5, mirror="alternate"),
                        drive="d1", to=1.5)
    assert isinstance(fabkit.plot.motion(traj), Figure)
    assert isinstance(fabkit.plot.cobweb(designed), Figure)  # a designed module: its own map
    assert isinstance(fabkit.plot.cobweb(designed.map, d1=[1.2], steps=4), Figure)
    super_stable = fabkit.load_template("super_stable")
    assert isinstance(fabkit.plot.kit(make_plan("laser", super_stable)), Figure)
    assert isinstance(fabkit.plot.kit(make_plan("print", super_stable)), Figure)  # pins
    hinged = make_plan("print", fabkit.load_template("printed_planar_chain10"))
    assert hinged.pinned is None and isinstance(fabkit.plot.kit(hinged), Figure)
    with pytest.raises(TypeError, match="Trajectory"):
        fabkit.plot.motion(chaotic)


def test_the_plots_leave_pyplot_and_the_backend_alone():
    script = """
import matplotlib
matplotlib.use("pdf")
import sys
import fabkit
from fabkit.tolerance import analyse_tolerance, tolerance_spec
d = fabkit.load_template("super_stable")
figs = [fabkit.plot.cobweb(d), fabkit.plot.motion(d.trace()),
        fabkit.plot.tolerance(analyse_tolerance(d, tolerance_spec(d, samples=20),
                                                attribute=False))]
print(matplotlib.get_backend(), "matplotlib.pyplot" in sys.modules,
      *[type(f).__name__ for f in figs])
"""
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["pdf", "False", "Figure", "Figure", "Figure"]
