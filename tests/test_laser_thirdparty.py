"""A third-party program opens fabkit's laser-cut DXF: LibreCAD's headless dxf2pdf.

LibreCAD is optional (installed by .ci/install.d/librecad.sh); without it the test skips and
says why. It hangs on malformed input, so it always runs under a timeout.
"""

from __future__ import annotations

import io
import os
import re
import shutil
import subprocess
import zlib

import ezdxf
import pytest

import fabkit
from fabkit.writers.dxf import export_design

from conftest import TEMPLATES

LIBRECAD = shutil.which("librecad")
pytestmark = pytest.mark.skipif(
    LIBRECAD is None, reason="LibreCAD is not installed (run .ci/install.d/librecad.sh)")


def _pdf_ops(pdf: bytes) -> dict:
    """Count path operators in the page content streams of a PDF."""
    ops = {"c": 0, "l": 0, "m": 0}
    for m in re.finditer(rb"stream\r?\n(.*?)endstream", pdf, re.S):
        try:
            data = zlib.decompress(m.group(1))
        except zlib.error:
            continue
        for op in ops:
            ops[op] += data.count(f" {op}\n".encode())
    return ops


def _dxf2pdf(tmp_path, name: str, text: str) -> dict:
    src = tmp_path / f"{name}.dxf"
    src.write_text(text)
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", XDG_RUNTIME_DIR=str(tmp_path))
    # -a fits the drawing to the page: without it LibreCAD 2.2 prints R2000+ files empty
    proc = subprocess.run([LIBRECAD, "dxf2pdf", "-a", "-t", str(tmp_path), str(src)],
                          env=env, cwd=tmp_path, capture_output=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-500:]
    pdf = tmp_path / f"{name}.pdf"
    assert pdf.exists() and pdf.read_bytes().startswith(b"%PDF")
    return _pdf_ops(pdf.read_bytes())


@pytest.mark.parametrize("flavour", ["lwpolyline", "line-arc"])
def test_librecad_draws_every_hole_and_the_round_ends(tmp_path, flavour):
    design = fabkit.load_template(TEMPLATES / "super_stable.toml")
    files = export_design(design, {"laser": {"labels": "none", "flavour": flavour}}).files
    text = files["laser_sheet1.dxf"].decode()
    doc = ezdxf.read(io.StringIO(text))
    n_circles = len(doc.modelspace().query("CIRCLE"))
    ops = _dxf2pdf(tmp_path, "sheet", text)
    # LibreCAD draws a circle as four Bezier curves: every hole and ring was read
    assert ops["c"] == 4 * n_circles
    # the same sheet with straight ends instead of half circles draws fewer segments, so the
    # round ends were read as arcs, not dropped or replaced by chords
    flat = ezdxf.read(io.StringIO(text))
    msp = flat.modelspace()
    for pl in msp.query("LWPOLYLINE"):
        pl.set_points([(x, y, 0.0) for x, y, *_ in pl.get_points("xyb")], format="xyb")
    for arc in msp.query("ARC"):
        s, e = arc.start_point, arc.end_point
        msp.add_line(s, e, dxfattribs={"layer": arc.dxf.layer})
        msp.delete_entity(arc)
    buf = io.StringIO()
    flat.write(buf)
    ops_flat = _dxf2pdf(tmp_path, "flat", buf.getvalue())
    assert ops["l"] > ops_flat["l"] + 6 * 2      # 6 bars x 2 round ends, several segments each
