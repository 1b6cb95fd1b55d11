"""Printer profiles and the bed layout: orient, arrange, split a chain, refuse with a size."""

from __future__ import annotations

import io
import math
import re
import zipfile

import numpy as np
import pytest

import fabkit
from fabkit.errors import FabricationError
from fabkit.writers import export
from fabkit.fab.printers import bed_layout, best_orientation, chain_pieces
from fabkit.settings.printers import DEFAULT_PRINTER, PRINTERS, printer_profile

from conftest import TEMPLATES


def _items(data: bytes):
    """(object name, vertices (V, 3), 3 x 4 transform) of every build item of a 3MF file."""
    model = zipfile.ZipFile(io.BytesIO(data)).read("3D/3dmodel.model").decode()
    objects = {}
    for oid, name, body in re.findall(r'<object id="(\d+)" type="model" name="([^"]*)">(.*?)'
                                      r'</object>', model):
        v = np.array(re.findall(r'<vertex x="([^"]+)" y="([^"]+)" z="([^"]+)"/>', body), float)
        objects[oid] = (name, v)
    out = []
    for oid, tr in re.findall(r'<item objectid="(\d+)" transform="([^"]+)"/>', model):
        t = np.array(tr.split(), float)
        m = np.zeros((3, 4))
        m[:, :3] = t[:9].reshape(3, 3).T
        m[:, 3] = t[9:]
        out.append((*objects[oid], m))
    return out


def test_the_catalogue_has_the_common_beds_and_states_its_default():
    beds = {(p.width, p.depth) for p in PRINTERS.values()}
    assert {(180.0, 180.0), (250.0, 210.0), (256.0, 256.0)} <= beds
    assert DEFAULT_PRINTER == "generic" and printer_profile().width == 200.0
    with pytest.raises(FabricationError, match="unknown printer 'nope'; valid: mini"):
        printer_profile("nope")
    with pytest.raises(FabricationError, match=r"bed: must be \[width, depth\]"):
        printer_profile(bed=[100, -1])


def test_a_strip_too_long_for_the_bed_is_turned_into_it():
    strip = np.array([[0, 0], [207, 0], [207, 16], [0, 16]], float)
    ang, w, h = best_orientation(strip, 190, 190)
    c, s = math.cos(math.radians(ang)), math.sin(math.radians(ang))
    turned = strip @ np.array([[c, s], [-s, c]])
    assert np.ptp(turned[:, 0]) == pytest.approx(w) and w <= 190 and h <= 190
    assert best_orientation(strip, 250, 200)[0] == 0.0  # fits as it is: no turn


def test_pieces_are_arranged_in_rows_without_overlap():
    sq = np.array([[0, 0], [60, 0], [60, 40], [0, 40]], float)
    layout = bed_layout([sq] * 5, printer_profile(bed=[200, 200]), margin=5, spacing=5)
    assert {p.bed for p in layout} == {0}
    boxes = []
    for p in layout:
        m = p.matrix()
        q = sq @ m[:2, :2].T + m[:2, 3]
        assert q.min() >= 5 - 1e-9 and q.max() <= 195 + 1e-9
        boxes.append((*q.min(0), *q.max(0)))
    for i in range(5):
        for j in range(i):
            a, b = boxes[i], boxes[j]
            assert a[2] <= b[0] + 1e-9 or b[2] <= a[0] + 1e-9 or a[3] <= b[1] + 1e-9 \
                or b[3] <= a[1] + 1e-9


def test_a_chain_splits_between_modules_and_shares_the_port_nodes():
    net = fabkit.load_template(TEMPLATES / "printed_planar_chain10.toml").network
    (a, cut), (b, last) = chain_pieces(net, 2)
    assert cut == "d6" and last == ""
    assert set(a) & set(b) == set(net.port("d6"))
    assert set(a) | set(b) == set(range(net.n_nodes))


def test_the_default_export_turns_the_chain_onto_the_200_mm_bed(tmp_path):
    design = fabkit.load_template(TEMPLATES / "printed_planar_chain10.toml")
    files, report = export(design, "stl", tmp_path, print={"preview": False})
    items = _items((tmp_path / "printed_planar_chain10.3mf").read_bytes())
    assert len(items) == 1
    name, v, m = items[0]
    placed = v @ m[:, :3].T + m[:, 3]
    assert placed[:, :2].min() >= 5.0 - 1e-4 and placed[:, :2].max() <= 195.0 + 1e-4
    assert np.ptp(v[:, 0]) > 200.0  # as designed it is longer than the bed
    assert report["printer"]["pieces"][0]["angle_deg"] != 0.0
    assert "does not fit the generic bed" in report["printer"]["note"]
    assert report["warnings"] == []  # the bed-ready file takes care of it


def test_a_print_too_large_for_any_split_is_refused_with_the_size(tmp_path):
    design = fabkit.load_template(TEMPLATES / "printed_planar_chain10.toml")
    with pytest.raises(FabricationError) as err:
        export(design, "stl", tmp_path, print={"preview": False, "bed": [30, 30]})
    msg = str(err.value)
    assert "\n" not in msg
    need = re.search(r"needs a bed of at least (\d+) x (\d+) mm", msg)
    assert need and int(need.group(1)) > 30
    assert list(tmp_path.iterdir()) == []
