"""Template loading: good templates build; every bad one names file, key path and reason."""

import numpy as np
import pytest

import fabkit
from fabkit import TemplateError, load_template
from fabkit.templates import parse_template

from conftest import TEMPLATES

GOOD = """
name = "tri4"
description = "a 4-bar"
[network]
nodes = [[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]
edges = [[0, 2], [0, 3], [1, 2], [1, 3]]
ports = { d1 = [0, 1], d2 = [2, 3] }
[motion]
drive = "d1"
to = 2.5
method = "projected"
options = { max_step = 0.1 }
"""


def test_good_template_round_trip():
    d = parse_template(GOOD, "mem.toml")
    assert d.name == "tri4" and d.network.n_edges == 4
    assert d.motion.to == 2.5 and d.motion.method == "projected"
    assert d.motion.options == {"max_step": 0.1}
    traj = d.trace()
    assert traj.success and traj.method == "projected"
    assert abs(traj.distance("d1")[-1] - 2.5) < 1e-12


@pytest.mark.parametrize("name", ["fourbar", "fourbar_chain2", "super_stable", "super_stable_chain8"])
def test_bundled_core_templates_load_and_trace(name):
    d = load_template(TEMPLATES / f"{name}.toml")
    m = fabkit.count_modes(d.network)
    assert m.conformational == 1 and m.self_stress == 0
    traj = d.trace()
    assert traj.success, traj.message
    assert traj.max_edge_error < 1e-12


def test_chain_template_builds_ports():
    d = load_template(TEMPLATES / "fourbar_chain2.toml")
    assert sorted(d.network.ports) == ["d1", "d2", "d3"]
    traj = d.trace()
    d1, d2, d3 = (traj.distance(p) for p in ("d1", "d2", "d3"))
    np.testing.assert_allclose(d1 * d2, 4.0, atol=1e-12)
    np.testing.assert_allclose(d3, d1, atol=1e-12)


BAD = [
    ("syntax", "[network\nnodes = 1", "", "not valid TOML"),
    ("no builder", 'name = "x"\n', "", "no section that builds the network"),
    ("missing nodes", "[network]\nedges = [[0, 1]]\n", "network.nodes", "missing required key"),
    ("missing edges", "[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\n", "network.edges", "missing required key"),
    ("wrong type", '[network]\nnodes = "abc"\nedges = [[0, 1]]\n', "network.nodes", "must be an array"),
    ("bad coordinate", '[network]\nnodes = [[0.0, "a"], [1.0, 0.0]]\nedges = [[0, 1]]\n', "network.nodes[0][1]", "must be a number"),
    ("bad width", "[network]\nnodes = [[0.0], [1.0, 0.0]]\nedges = [[0, 1]]\n", "network.nodes[0]", "must have 2 or 3 entries"),
    ("bad index", "[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\nedges = [[0, 5]]\n", "network.edges[0][1]", "out of range 0..1"),
    ("float index", "[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\nedges = [[0, 1.0]]\n", "network.edges[0][1]", "integer node index"),
    ("zero length", "[network]\nnodes = [[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]]\nedges = [[0, 1], [1, 2]]\n", "network.edges[0]", "zero length"),
    ("duplicate edge", "[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\nedges = [[0, 1], [1, 0]]\n", "network.edges[0]", "both join nodes 0 and 1"),
    ("unknown key", "[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\nedges = [[0, 1]]\ncolour = 3\n", "network.colour", "unknown key"),
    ("unknown top", "speed = 1\n[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\nedges = [[0, 1]]\n", "speed", "unknown key"),
    ("bad port", "[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\nedges = [[0, 1]]\nports = { d1 = [0, 9] }\n", "network.ports.d1[1]", "out of range"),
    ("bad drive", "[network]\nnodes = [[0.0, 0.0], [1.0, 0.0]]\nedges = [[0, 1]]\n[motion]\ndrive = \"d9\"\n", "motion.drive", "unknown port 'd9'"),
    ("negative to", GOOD.replace("to = 2.5", "to = -1.0"), "motion.to", "positive distance"),
    ("bad method", GOOD.replace('"projected"', '"euler"'), "motion.method", "unknown method 'euler'"),
    ("bad option", GOOD.replace("max_step", "max_stp"), "motion.options.max_stp", "unknown option of the projected method"),
]


@pytest.mark.parametrize("case, text, key, reason", BAD, ids=[b[0] for b in BAD])
def test_bad_templates_name_file_key_reason(tmp_path, case, text, key, reason):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(TemplateError) as info:
        load_template(path)
    err = info.value
    assert err.key == key
    assert reason in err.reason
    msg = str(err)
    assert "\n" not in msg and str(path) in msg and (key in msg if key else True)


def test_unreadable_files(tmp_path):
    with pytest.raises(TemplateError, match="no such file"):
        load_template(tmp_path / "missing.toml")
    with pytest.raises(TemplateError, match="is a folder"):
        load_template(tmp_path)
    binary = tmp_path / "image.toml"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00")
    with pytest.raises(TemplateError, match="not a text file"):
        load_template(binary)


def test_chain_referring_to_missing_module(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('[chain]\nmodule = "nope.toml"\ncopies = 3\n')
    with pytest.raises(TemplateError, match=r"chain.module: no template file 'nope.toml'"):
        load_template(path)


def test_module_templates_hold_the_papers_geometry(paper_modules):
    # The templates are fabkit's one home of the paper's modules; the paper's input data is the
    # independent reference they were written from (same nodes, edges in the same order, ports).
    for name, m in paper_modules.items():
        net = load_template(TEMPLATES / f"{name}.toml").network
        tol = 1e-9 if "design" in m else 0.0  # designed modules are solved, to 8-10 digits
        np.testing.assert_allclose(net.nodes, np.array(m["nodes"], dtype=float), rtol=0, atol=tol,
                                   err_msg=name)
        assert np.array_equal(net.edges, np.array(m["edges"])), name
        assert net.port("d1") == tuple(m["d1"]) and net.port("d2") == tuple(m["d2"]), name


def test_referenced_templates_are_loaded_with_the_design(tmp_path):
    chain = load_template(TEMPLATES / "printed_planar_chain10.toml")
    assert chain.references["chain.module"].name == "printed_planar"
    sheets = load_template(TEMPLATES / "origami_chain12.toml")
    assert sheets.references["fabrication.origami.sheet"].name == "origami_sheet"
    # a reference to a missing file is a template error at load time, at its key
    text = (TEMPLATES / "origami_chain12.toml").read_text()
    bad = tmp_path / "chain.toml"
    bad.write_text(text.replace('sheet = "origami_sheet.toml"', 'sheet = "no_such_sheet.toml"'))
    with pytest.raises(TemplateError, match=r"fabrication\.origami\.sheet: no template file"):
        load_template(bad)
