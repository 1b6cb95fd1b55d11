"""Every reader behind one boundary, every network peer bounded, nothing taken silently.

Each case is a file, an option or an API call that used to end in an internal error (exit 70), a
raw Python exception, or minutes of work: it now ends in one line naming the file, the stream or
the option, with the documented exit status, before the work.
"""

from __future__ import annotations

import json
import os
import socket
import struct
import subprocess
import sys
import threading
import zipfile
from pathlib import Path

import numpy as np
import pytest

import fabkit
from fabkit.cli import main
from fabkit.errors import (ArgumentTypeError, FabkitError, InputFileError, NetworkError,
                           TemplateError)
from fabkit.check.threemf import read_package
from fabkit.io.formats import (load_json, MAX_DEPTH, MAX_DIGITS, MAX_DXF_ENTITIES,
                               MAX_TOML_VALUES, MAX_ZIP_ENTRIES, parse_xml, refuse_dxf_entities,
                               toml_shape)

ROOT = Path(__file__).resolve().parents[1]


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("fabkit: error: ") and "Traceback" not in err
    return lines[0]


FOLD = {"file_spec": 1.1, "vertices_coords": [[0, 0], [1, 0], [1, 1], [0, 1]],
        "edges_vertices": [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]],
        "edges_assignment": ["B", "B", "B", "B", "M"], "faces_vertices": [[0, 1, 2], [0, 2, 3]]}


# --- the readers ------------------------------------------------------------------------------

def test_json_depth_digits_and_values_are_counted_before_parsing():
    with pytest.raises(InputFileError) as info:
        load_json(b"[" * 100_000 + b"]" * 100_000, "deep.json")
    assert info.value.kind == "bounds" and info.value.exit_code == 2
    assert f"over the limit of {MAX_DEPTH}" in str(info.value)
    with pytest.raises(InputFileError) as info:
        load_json(b"[" + b"7" * 5001 + b"]", "digits.json")
    assert info.value.kind == "bounds" and f"more than {MAX_DIGITS} digits" in str(info.value)
    # brackets and digits inside strings are text, not structure
    assert load_json(b'{"a": "[[[[' + b"9" * 5000 + b'"}', "s.json")["a"].startswith("[[[[9")
    with pytest.raises(InputFileError) as info:
        load_json(b"[1, 2, 3]", "many.json", max_items=2)
    assert info.value.kind == "bounds" and "3 values" in str(info.value)
    with pytest.raises(InputFileError) as info:
        load_json(b'{"a": ', "cut.json")
    assert info.value.kind == "damaged" and str(info.value).startswith("cut.json: not JSON")


def test_xml_elements_are_counted_while_parsing():
    with pytest.raises(InputFileError) as info:
        parse_xml(b"<a>" + b"<b/>" * 100_000 + b"</a>", "many.xml", max_elements=1000)
    assert info.value.kind == "bounds" and "elements, over the limit of 1,000" in str(info.value)
    with pytest.raises(InputFileError) as info:
        parse_xml(b"<a>" * 300 + b"</a>" * 300, "deep.xml", max_elements=10_000)
    assert info.value.kind == "bounds"
    with pytest.raises(InputFileError) as info:
        parse_xml(b"<a><b></a>", "bad.xml", max_elements=10)
    assert info.value.kind == "damaged"


@pytest.mark.parametrize("name, text, words", [
    ("deep.fold", "[" * 100_000 + "]" * 100_000, "nested 100,000 levels deep"),
    ("digits.fold", json.dumps(FOLD).replace('"file_spec": 1.1', '"file_spec": ' + "1" * 5001),
     "a number of more than 400 digits"),
    ("values.fold", json.dumps({**FOLD, "edges_vertices": [[0, 1]] * 1_100_000}),
     "2,200,020 values, over the limit of 2,000,000"),
    ("cut.fold", json.dumps(FOLD)[:40], "not FOLD JSON"),
])
def test_a_fold_file_past_the_readers_bounds_is_one_line_and_exit_2(tmp_path, capsys, name,
                                                                      text, words):
    path = tmp_path / name
    path.write_text(text)
    rc = main(["check", str(path)])
    line = one_line(capsys.readouterr().err)
    assert rc == 2
    assert line.startswith(f"fabkit: error: {path}: ") and words in line


def test_a_fold_file_with_its_edges_repeated_is_a_failed_check(tmp_path, capsys):
    path = tmp_path / "repeated.fold"
    path.write_text(json.dumps({**FOLD, "edges_vertices": FOLD["edges_vertices"] * 20_000,
                                "edges_assignment": FOLD["edges_assignment"] * 20_000}))
    assert main(["check", str(path)]) == 1
    assert "FAIL  structure" in capsys.readouterr().out


def _use_doubling(levels: int) -> str:
    parts = ['<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink"'
             ' width="100mm" height="100mm" viewBox="0 0 100 100"><defs>'
             '<path id="u0" d="M 0 0 L 10 10 L 20 5"/>']
    parts += [f'<g id="u{i}"><use xlink:href="#u{i - 1}"/><use href="#u{i - 1}"/></g>'
              for i in range(1, levels + 1)]
    return "".join(parts) + f'</defs><use href="#u{levels}"/></svg>'


@pytest.mark.parametrize("name, text, words", [
    ("use.svg", _use_doubling(29), "elements with every <use> expanded, over the limit of "
                                   "100,000"),
    ("long.svg", '<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0'
                 + " l1 0" * 10**6 + '"/></svg>', "2,000,002 numbers in its path data"),
    ("xinclude.svg", '<svg xmlns="http://www.w3.org/2000/svg" xmlns:xi="http://www.w3.org/2001/'
                     'XInclude"><path d="M 0 0 L 100 0"><xi:include href="x.txt" parse="text"/>'
                     '</path></svg>', "holds an XInclude"),
])
def test_an_svg_curve_past_the_bounds_is_refused_before_svgelements_reads_it(tmp_path, capsys,
                                                                           name, text, words):
    path = tmp_path / name
    path.write_text(text)
    rc = main(["design", "--curve", str(path), "-o", str(tmp_path / "out")])
    line = one_line(capsys.readouterr().err)
    assert rc == 2 and words in line and str(path) in line
    assert not (tmp_path / "out").exists()


def test_a_70_byte_corner_gets_its_nearest_feasible_wish_from_a_bounded_search(tmp_path,
                                                                               capsys):
    path = tmp_path / "corner.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0 L 100 0 L 200 50"/>'
                    "</svg>")
    rc = main(["design", "--curve", str(path), "-o", str(tmp_path / "out")])
    line = one_line(capsys.readouterr().err)
    assert rc == 2
    assert "is shorter than two modules" in line and "nearest feasible: --curve" in line


def test_a_print_with_far_more_triangles_than_its_design_is_refused(tmp_path, capsys):
    assert main(["export", "printed_planar", "--to", "stl", "-o", str(tmp_path / "e"),
                 "--tolerance-samples", "0", "--no-previews", "-q"]) == 0
    data = (tmp_path / "e" / "printed_planar" / "printed_planar.stl").read_bytes()
    n = struct.unpack("<I", data[80:84])[0]
    big = tmp_path / "big.stl"
    big.write_bytes(data[:80] + struct.pack("<I", n * 2000) + data[84:84 + 50 * n] * 2000)
    capsys.readouterr()
    rc = main(["check", str(big), "--design", "printed_planar"])
    line = one_line(capsys.readouterr().err)
    assert rc == 2
    assert f"{n * 2000:,} triangles for a design of 12 bars, over the limit of 60,000" in line


THREEMF_NS = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"


def _package(path: Path, model: bytes) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("3D/3dmodel.model", model)
    return path


@pytest.mark.parametrize("name, model, kind, words", [
    ("many.3mf", f'<model unit="millimeter" xmlns="{THREEMF_NS}"><resources>'.encode()
     + b"<a/>" * 10**6 + b"</resources></model>", "bounds",
     "elements, over the limit of 1,000,000"),
    ("deep.3mf", b"<a>" * 10**5 + b"</a>" * 10**5, "bounds", "elements nested more than 256 deep"),
    ("dtd.3mf", b'<!DOCTYPE model [<!ENTITY e "x">]><model>&e;</model>', "damaged",
     "declares a DTD or entities, which a 3MF's 3D/3dmodel.model never needs"),
    ("cut.3mf", f'<model xmlns="{THREEMF_NS}"><resources>'.encode(), "damaged",
     "not a 3MF's 3D/3dmodel.model (no element found"),
])
def test_a_3mf_model_is_parsed_within_the_xml_bounds(tmp_path, capsys, name, model, kind,
                                                     words):
    path = _package(tmp_path / name, model)
    with pytest.raises(InputFileError) as info:
        read_package(path)
    assert info.value.kind == kind and words in str(info.value)
    assert str(info.value).startswith(f"{path}: ")
    rc = main(["check", str(path)])
    line = one_line(capsys.readouterr().err)
    assert rc == 2 and line == f"fabkit: error: {info.value}"


def _declared_size(data: bytes, size: int) -> bytes:
    """A ZIP whose central directory declares its one entry inflates to ``size`` bytes."""
    at = data.index(b"PK\x01\x02") + 24  # the entry's uncompressed size
    return data[:at] + struct.pack("<I", size) + data[at + 4:]


def test_a_3mf_entry_that_lies_about_its_size_is_damaged(tmp_path):
    model = (f'<model unit="millimeter" xmlns="{THREEMF_NS}"><resources/><build/>'
             '</model>').encode()
    data = _package(tmp_path / "true.3mf", model).read_bytes()
    assert zipfile.ZipFile(tmp_path / "true.3mf").getinfo("3D/3dmodel.model").file_size \
        == len(model)
    more = tmp_path / "more.3mf"
    more.write_bytes(_declared_size(data, len(model) + 1000))
    with pytest.raises(InputFileError) as info:
        read_package(more)
    assert info.value.kind == "damaged"
    assert str(info.value) == (f"{more}: 3D/3dmodel.model inflates to {len(model):,} bytes, "
                               f"not the {len(model) + 1000:,} its ZIP directory declares")
    less = tmp_path / "less.3mf"  # inflated no further than declared: its CRC fails there
    less.write_bytes(_declared_size(data, 20))
    with pytest.raises(InputFileError) as info:
        read_package(less)
    assert info.value.kind == "damaged" and "3D/3dmodel.model cannot be inflated (Bad CRC-32" \
        in str(info.value)


def test_a_3mf_of_more_zip_entries_than_a_package_holds_is_refused(tmp_path):
    path = tmp_path / "entries.3mf"
    with zipfile.ZipFile(path, "w") as z:
        for k in range(MAX_ZIP_ENTRIES + 1):
            z.writestr(f"x/{k}", b"")
    with pytest.raises(InputFileError) as info:
        read_package(path)
    assert info.value.kind == "bounds"
    assert f"{MAX_ZIP_ENTRIES + 1:,} entries in its ZIP directory" in str(info.value)


@pytest.mark.parametrize("name, text, words", [
    ("deep.toml", "[network]\nnodes = " + "[" * 10**5 + "]" * 10**5,
     "nested 100,000 levels deep, over the limit of 64"),
    ("tables.toml", "a = " + "{b = " * 10**5 + "1" + "}" * 10**5,
     "nested 100,000 levels deep, over the limit of 64"),
    ("digits.toml", "name = 'd'\n[network]\nnodes = [[0, " + "1" * 5001 + "]]",
     "a number of more than 400 digits"),
])
def test_a_template_past_the_toml_bounds_is_refused_before_parsing(tmp_path, capsys, name,
                                                                   text, words):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputFileError) as info:
        fabkit.load_template(path)
    assert info.value.kind == "bounds" and words in str(info.value)
    assert str(info.value).startswith(f"{path}: ")
    assert info.value.__cause__ is None and info.value.__context__ is None
    rc = main(["simulate", str(path)])
    line = one_line(capsys.readouterr().err)
    assert rc == 2 and line == f"fabkit: error: {info.value}"


def test_toml_strings_and_comments_are_text_not_structure():
    toml_shape('a = "[[[[' + "9" * 5000 + '"  # ' + "{" * 100 + "\nb = '''" + "[" * 100
               + "'''\n", "s.toml")
    with pytest.raises(InputFileError) as info:
        toml_shape("a = [" + "1," * MAX_TOML_VALUES + "]", "many.toml")
    assert info.value.kind == "bounds" and "values, over the limit of 2,000,000" in str(info.value)


def test_a_dxf_of_two_million_entities_is_refused_before_ezdxf_reads_it(tmp_path, capsys,
                                                                      monkeypatch):
    import ezdxf
    from ezdxf import recover

    def never(*args, **kwargs):
        raise AssertionError("ezdxf read a file past the bound")

    monkeypatch.setattr(ezdxf, "readfile", never)
    monkeypatch.setattr(recover, "readfile", never)
    path = tmp_path / "laser_sheet1.dxf"
    path.write_bytes(b"  0\nSECTION\n  2\nENTITIES\n" + b"  0\nPOINT\n" * 2 * 10**6
                     + b"  0\nENDSEC\n  0\nEOF\n")
    rc = main(["check", str(path)])
    line = one_line(capsys.readouterr().err)
    assert rc == 2
    assert line == (f"fabkit: error: {path}: 2,000,003 DXF entities (group code 0), over the "
                    f"limit of {MAX_DXF_ENTITIES:,} (about 100 s for ezdxf to read); fabkit "
                    "--allow-large lifts the limit")
    # a value 0 (the next line a group code) is no entity
    assert refuse_dxf_entities(b"  0\nLINE\n  8\n0\n 10\n0\n  0\nEOF\n", "x.dxf") == 2


# --- the Python API ---------------------------------------------------------------------------

def test_read_curve_is_bounded_and_takes_bytes_only():
    with pytest.raises(InputFileError) as info:
        fabkit.read_curve(b"0,0\n" * 12 * 2**20, "x.csv")
    assert info.value.kind == "bounds" and "over the limit of 16,777,216" in str(info.value)
    with pytest.raises(InputFileError) as info:
        fabkit.read_curve(b"0,0\n" * 300_000, "x.csv")
    assert "300,001 lines, over the limit of 200,000" in str(info.value)
    with pytest.raises(ArgumentTypeError, match="must be the file's content as bytes, got str"):
        fabkit.read_curve("0,0\n1,1\n", "x.csv")


def test_design_map_counts_the_fixed_points_before_reading_them():
    with pytest.raises(FabkitError, match="more than 16 fixed points given"):
        fabkit.design_map(fixed_points=np.linspace(1.0, 2.0, 10**6))


def test_load_template_with_a_name_too_long_for_the_system():
    with pytest.raises(TemplateError, match="cannot read: File name too long"):
        fabkit.load_template("y" * 300)


def test_a_network_of_complex_nodes_is_refused():
    with pytest.raises(NetworkError, match="must be real coordinates"):
        fabkit.Network(np.array([[0, 0], [1, 0], [0, 1j]]), [[0, 1], [1, 2], [0, 2]])


def test_branch_names_an_argument_that_is_not_a_network():
    with pytest.raises(ArgumentTypeError, match="trunk must be a fabkit.Network, got None"):
        fabkit.branch(None, None, at="d2", end="d1")
    rod = fabkit.Network([[0, 0], [1, 0], [2, 0.5]], [[0, 2], [1, 2]], ports={"p": (0, 1)})
    with pytest.raises(ArgumentTypeError, match="end must be a port name, got NoneType"):
        fabkit.branch(rod, rod, at="p", end=None)


# --- network peers ----------------------------------------------------------------------------

def _serving(on_connection):
    """A local server whose thread hands every connection it accepts to ``on_connection``,
    until the server is closed."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)

    def serve():
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            on_connection(conn)

    threading.Thread(target=serve, daemon=True).start()
    return server


def _peer(first: bytes | None):
    """A local server that accepts every connection and sends ``first`` (None: nothing)."""
    held = []

    def greet(conn):
        held.append(conn)  # kept open: the client sees silence, not a closed connection
        if first is not None:
            conn.sendall(first)

    return _serving(greet)


@pytest.mark.parametrize("first, words", [
    (None, "did not answer within the connect timeout of 1 s"),
    (struct.pack("Q", 2**63 - 1), "announces a first message of 9,223,372,036,854,775,807 "
                                  "bytes, over the limit of 1,048,576"),
    (struct.pack("Q", 100) + b"x" * 10, "did not answer within the connect timeout"),
])
def test_a_scheduler_that_never_speaks_or_announces_exabytes_is_refused(tmp_path, capsys,
                                                                        first, words):
    pytest.importorskip("distributed")
    server = _peer(first)
    try:
        port = server.getsockname()[1]
        rc = main(["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:2", "--scheduler",
                   f"tcp://127.0.0.1:{port}", "--connect-timeout", "1", "--no-plots", "-q",
                   "-o", str(tmp_path / "s")])
    finally:
        server.close()
    line = one_line(capsys.readouterr().err)
    assert rc == 1 and words in line and f"tcp://127.0.0.1:{port}" in line


# --- nothing taken silently -------------------------------------------------------------------

@pytest.mark.parametrize("argv, words", [
    (["export", "fourbar", "--to", "dxf", "--set", "laser.kerf=0.2\nlaser.kerf=5"],
     "holds a control character ('\\n')"),
    (["export", "fourbar", "--to", "dxf", "--set", "laser.clearance=100000"],
     "laser.clearance: must be <= 50, got 100000"),
    (["export", "fourbar", "--to", "dxf", "--set", "laser.kerf=" + "1" * 5000],
     "a number of more than 400 digits (at byte 0)"),
    (["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:2", "--lyapunov-protocol",
      "1000000000:1000000000:1000000000"], "lyapunov_orbits must be at most 100,000"),
    (["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:2", "--lyapunov-protocol",
      "100000:10000000:10000000"], "over the limit of 1,000,000,000"),
    (["sweep", "chaotic", "--vary", "nodes[4].x=-1e308:1e308:3"],
     "START and STOP must lie within ±1e+09"),
    (["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:2", "--connect-timeout", "inf"],
     "--connect-timeout must be a number of seconds above 0 and at most 3600"),
])
def test_a_value_out_of_range_is_one_line_and_exit_2_before_work(tmp_path, capsys, argv, words):
    rc = main(argv + ["-o", str(tmp_path / "o")])
    line = one_line(capsys.readouterr().err)
    assert rc == 2 and words in line
    assert not (tmp_path / "o").exists()


def _fabkit(args, **kwargs):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "fabkit", *args], env=env,
                          capture_output=True, **kwargs)


def test_a_closed_stdout_is_one_line():
    proc = subprocess.run([sys.executable, "-m", "fabkit", "templates"], stdout=None,
                          stderr=subprocess.PIPE, close_fds=True, pass_fds=(),
                          env=dict(os.environ, PYTHONPATH=str(ROOT)),
                          preexec_fn=lambda: os.close(1))
    assert proc.returncode == 1
    assert proc.stderr.decode().strip() == ("fabkit: error: standard output is closed; give it a "
                                            "file or /dev/null (> /dev/null)")


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_full_stdout_is_named():
    with open("/dev/full", "w") as full:
        proc = subprocess.run([sys.executable, "-m", "fabkit", "templates"], stdout=full,
                              stderr=subprocess.PIPE,
                              env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 1
    assert proc.stderr.decode().strip() == ("fabkit: error: standard output: No space left on "
                                            "device")


SWEEP = ["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:2", "--measure", "fixed_points",
         "-j", "1", "--no-plots", "-q"]


def test_a_sweeps_folder_in_the_way_is_named_and_nothing_is_replaced(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(SWEEP + ["-o", str(out)]) == 0
    csv_before = (out / "sweep.csv").read_bytes()
    (out / "sweep.json").unlink()
    (out / "sweep.json").mkdir()
    capsys.readouterr()
    rc = main(SWEEP[:3] + ["nodes[4].x=-0.3:-0.2:3"] + SWEEP[4:] + ["-o", str(out)])
    line = one_line(capsys.readouterr().err)
    assert rc == 1
    assert line == (f"fabkit: error: {out / 'sweep.json'}: is a folder where the sweep writes "
                    "its file; remove it or choose another -o")
    assert (out / "sweep.csv").read_bytes() == csv_before
    (out / "sweep.json").rmdir()
    for f in (out / "chunks").iterdir():
        f.unlink()
    (out / "chunks").rmdir()
    (out / "chunks").write_text("")
    rc = main(SWEEP + ["-o", str(out)])
    line = one_line(capsys.readouterr().err)
    assert rc == 1 and line == (f"fabkit: error: {out / 'chunks'}: is a file where the sweep "
                                "keeps its folder of finished chunks; remove it or choose "
                                "another -o")


def test_a_truncated_spec_is_called_damaged(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(SWEEP + ["-o", str(out)]) == 0
    spec = out / "chunks" / "spec.json"
    spec.write_bytes(spec.read_bytes()[:20])
    capsys.readouterr()
    rc = main(SWEEP + ["-o", str(out)])
    line = one_line(capsys.readouterr().err)
    assert rc == 2
    assert line.startswith(f"fabkit: error: {spec}: damaged (not a sweep's spec")
    assert line.endswith(f"delete {out / 'chunks'} to start the sweep again")
    assert "different sweep" not in line


# --- sweep specs and --set values pass the TOML bound before the parser -----------------------

def test_a_sweep_spec_nested_too_deeply_is_refused_before_the_parser(tmp_path, capsys):
    from fabkit.sweep import read_sweep_file

    spec = tmp_path / "deep.toml"
    spec.write_text('[sweep]\ntemplate = "chaotic"\nvary = ["nodes[4].x=-0.3:-0.2:2"]\n'
                    f"description = {'[' * 100}1{']' * 100}\n")
    with pytest.raises(InputFileError) as info:
        read_sweep_file(spec)
    assert info.value.kind == "bounds" and info.value.path == str(spec)
    assert f"nested 100 levels deep, over the limit of {MAX_DEPTH}" in info.value.reason
    capsys.readouterr()
    assert main(["sweep", str(spec), "--no-plots", "-q", "-o", str(tmp_path / "s")]) == 2
    line = one_line(capsys.readouterr().err)
    assert line.startswith(f"fabkit: error: {spec}: nested 100 levels deep")
    assert not (tmp_path / "s").exists()


def test_a_sweep_spec_number_of_too_many_digits_is_refused(tmp_path):
    from fabkit.sweep import read_sweep_file

    spec = tmp_path / "digits.toml"
    spec.write_text('[sweep]\ntemplate = "chaotic"\nvary = ["nodes[4].x=-0.3:-0.2:2"]\n'
                    f"protocol = {{ lyapunov_orbits = {'7' * 500} }}\n")
    with pytest.raises(InputFileError) as info:
        read_sweep_file(spec)
    assert info.value.kind == "bounds"
    assert f"a number of more than {MAX_DIGITS} digits" in info.value.reason


@pytest.mark.parametrize("value, words", [
    ("print.bed=" + "[" * 100 + "]" * 100, "print.bed: nested 100 levels deep, over the limit "
                                           f"of {MAX_DEPTH}"),
    ("laser.kerf=" + "1" * 500, f"laser.kerf: a number of more than {MAX_DIGITS} digits"),
])
def test_a_set_value_past_the_toml_bounds_is_refused_by_them(value, words):
    from fabkit.commands.settings import parse_settings
    from fabkit.errors import UsageError

    with pytest.raises(UsageError) as info:
        parse_settings([value])
    assert words in str(info.value)
    assert len(str(info.value).splitlines()) == 1


# --- every message of a peer bounded, not only its first --------------------------------------

def _message(payload: bytes) -> bytes:
    """One dask message of one frame: its size, the frame count and length, the frame."""
    body = struct.pack("QQ", 1, len(payload)) + payload
    return struct.pack("Q", len(body)) + body


def _scripted_peer(replies):
    """A local server that, on each connection, sends a handshake message, then answers each
    read from the client with the next of ``replies`` (bytes sent as they are)."""
    def script(conn):
        conn.sendall(_message(b"handshake"))
        for reply in replies:
            if not conn.recv(1 << 16):
                break
            conn.sendall(reply)

    return _serving(script)


@pytest.mark.parametrize("reply, words", [
    (struct.pack("Q", 2**63 - 1), "announces a message of 9,223,372,036,854,775,807 bytes, "
                                  "over the limit of 1,048,576"),
    (struct.pack("QQQ", 16, 1, 2**40), f"announces a message of {16 + 2**40:,} bytes"),
    (_message(b"x" * 100)[:30], "did not send the rest of a message within the connect timeout"),
])
def test_a_later_message_past_a_bound_is_cut_off_before_it_is_read(reply, words):
    """The handshake passes; the next message announces exabytes (in its size, or in a frame
    length sent after the first frames), or stops half-way: the guard cuts it off, says why,
    and refuses every later connection."""
    from fabkit.sweep.peer import PeerGuard

    server = _scripted_peer([_message(b"fine"), reply])
    port = server.getsockname()[1]
    try:
        with PeerGuard(f"tcp://127.0.0.1:{port}", ("127.0.0.1", port), 1.0) as guard:
            host, guarded = guard.address.removeprefix("tcp://").split(":")
            with socket.create_connection((host, int(guarded)), timeout=10) as client:
                assert client.recv(1 << 16) == _message(b"handshake")
                client.sendall(b"register")
                assert client.recv(1 << 16) == _message(b"fine")  # a message within bounds
                client.sendall(b"next")
                rest = b""
                while part := client.recv(1 << 16):  # cut off: closed, nothing passed on
                    rest += part
            assert rest == b""
            assert guard.failure is not None and words in guard.failure, guard.failure
            with pytest.raises(OSError):  # and no connection after it
                socket.create_connection((host, int(guarded)), timeout=2).close()
    finally:
        server.close()


def test_a_dask_scheduler_that_announces_exabytes_after_its_handshake_is_one_line(tmp_path,
                                                                                  capsys):
    """A peer that speaks dask's handshake, then answers the client's registration with a
    message of 2⁶³−1 bytes: one line and exit 1 (it was a MemoryError, exit 70, after 31 s)."""
    distributed = pytest.importorskip("distributed")
    import asyncio

    ready, box = threading.Event(), {}

    async def handler(comm):  # after the handshake dask's listener made: the registration
        await comm.read()
        await comm.stream.write(struct.pack("Q", 2**63 - 1))
        await asyncio.sleep(60)

    async def listen():
        listener = distributed.comm.listen("tcp://127.0.0.1:0", handler)
        await listener.start()
        box["address"], box["loop"] = listener.contact_address, asyncio.get_running_loop()
        ready.set()
        await asyncio.sleep(3600)

    threading.Thread(target=asyncio.run, args=(listen(),), daemon=True).start()
    assert ready.wait(30)
    rc = main(["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:2", "--scheduler",
               box["address"], "--connect-timeout", "5", "--no-plots", "-q",
               "-o", str(tmp_path / "s")])
    line = one_line(capsys.readouterr().err)
    assert rc == 1, line
    assert (f"the scheduler at {box['address']} announces a message of "
            "9,223,372,036,854,775,807 bytes, over the limit of 1,048,576") in line
