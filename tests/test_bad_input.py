"""The bad-input corpus: every malformed or impossible template gives one line naming the file, the
key and the cause, a non-zero exit code, and writes no file."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from fabkit.cli import main

BAD = Path(__file__).resolve().parent / "bad_templates"

#: file stem -> (key the message names, or "" for the whole file; words of the cause)
EXPECTED = {
    # not TOML at all
    "syntax_error": ("", ["not valid TOML", "line 2"]),
    "unterminated_string": ("", ["not valid TOML", "line 1"]),
    "duplicate_key": ("", ["not valid TOML", "line 5"]),
    "json_not_toml": ("", ["not valid TOML"]),
    "binary_png": ("", ["not a text file"]),
    "empty": ("", ["no section that builds the network"]),
    "no_builder_section": ("", ["no section that builds the network"]),
    # missing or unknown keys
    "missing_nodes": ("network.nodes", ["missing required key"]),
    "missing_edges": ("network.edges", ["missing required key"]),
    "unknown_top_key": ("colour", ["unknown key"]),
    "unknown_network_key": ("network.nodez", ["unknown key"]),
    "unknown_motion_key": ("motion.speed", ["unknown key"]),
    "unknown_method": ("motion.method", ["unknown method 'euler'"]),
    "unknown_drive_port": ("motion.drive", ["unknown port 'd7'"]),
    "unknown_method_option": ("motion.options.stepsize", ["unknown key"]),
    "hold_unknown_port": ("motion.hold[0]", ["must name a port"]),
    "two_builders": ("chain", ["give only one of"]),
    "tolerance_unknown_key": ("fabrication.tolerance.kerf_sigma_mm", ["unknown key"]),
    "chain_missing_module": ("chain.module", ["no template file"]),
    "chain_refers_to_itself": ("chain.module", ["refers back to itself"]),
    # wrong types and units
    "nodes_not_array": ("network.nodes", ["must be an array", "string 'square'"]),
    "coordinate_with_unit": ("network.nodes[1][1]", ["must be a number", "'1 mm'"]),
    "target_with_unit": ("motion.to", ["must be a number", "'3 mm'"]),
    "target_boolean": ("motion.to", ["must be a number", "boolean"]),
    "edge_float_index": ("network.edges[0][1]", ["integer node index"]),
    "port_not_pair": ("network.ports.d1", ["pair of node indices"]),
    "four_coordinates": ("network.nodes[0]", ["2 or 3 entries", "got 4"]),
    "mixed_dimensions": ("network.nodes", ["mix 2 and 3"]),
    "nan_coordinate": ("network.nodes[1][1]", ["must be finite"]),
    "chain_copies_not_integer": ("chain.copies", ["must be an integer"]),
    "name_not_a_folder": ("name", ["cannot be a folder name"]),
    # bad indices and degenerate networks
    "edge_index_out_of_range": ("network.edges[3][1]", ["out of range 0..3"]),
    "self_loop_edge": ("network.edges[2]", ["to itself"]),
    "duplicate_edge": ("network.edges[0]", ["both join nodes 0 and 2"]),
    "coincident_nodes": ("network.edges[4]", ["zero length"]),
    # negative sizes and impossible fabrication
    "negative_target": ("motion.to", ["positive distance"]),
    "negative_samples": ("motion", ["samples", "at least 2"]),
    "negative_length_sigma": ("fabrication.tolerance.length_sigma", [">= 0"]),
    "zero_scale": ("fabrication.tolerance.scale", ["> 0"]),
    "negative_kerf": ("fabrication.laser", ["kerf", ">= 0"]),
    "hole_larger_than_bar": ("fabrication.laser", ["hole", "bigger than", "bar"]),
    # impossible motions
    "rigid_network": ("network", ["rigid", "no conformational motion"]),
    "two_motions": ("network", ["2 conformational motions"]),
    "unreachable_target": ("motion.to", ["not reached", "turning point"]),
    "singular_start": ("network.nodes", ["collinear", "flat state"]),
}


def test_corpus_is_complete():
    files = {p.stem for p in BAD.glob("*.toml")}
    assert files == set(EXPECTED), files ^ set(EXPECTED)
    assert len(files) >= 30


@pytest.mark.parametrize("stem", sorted(EXPECTED))
def test_bad_template_gives_one_line_and_writes_nothing(stem, tmp_path, capsys):
    path = BAD / f"{stem}.toml"
    out = tmp_path / "out"
    rc = main(["export", str(path), "-o", str(out), "--tolerance-samples", "20"])
    err = capsys.readouterr().err
    assert rc != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("fabkit: error: ")
    assert path.name in line  # the file
    key, words = EXPECTED[stem]
    if key:
        assert f": {key}: " in line, line  # the key
    for w in words:  # the cause
        assert w in line, line
    assert "Traceback" not in err
    written = [p for p in out.rglob("*") if p.is_file()] if out.exists() else []
    assert written == []


@pytest.mark.parametrize("stem", ["two_motions", "binary_png"])
def test_bad_template_exit_code_from_a_real_process(stem, tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "fabkit.cli", "export", str(BAD / f"{stem}.toml"),
                           "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert len(proc.stderr.strip().splitlines()) == 1
    assert f"{stem}.toml" in proc.stderr
    assert not out.exists() or not any(p.is_file() for p in out.rglob("*"))


TEXT_FORMAT = """
FORMAT = "lengths"


def applies(design):
    return True


def export_design(design, settings):
    from fabkit.export import ExportResult

    text = "\\n".join(f"{v:.12g}" for v in design.network.edge_lengths) + "\\n"
    return ExportResult(files={"lengths.txt": text.encode()}, report={"edges": 4})
"""


def test_one_bad_design_does_not_stop_the_others(tmp_path, capsys, monkeypatch):
    """A minimal format of our own (a module file, so the export's worker processes import it
    too): one text file with the edge lengths, independent of the real formats."""
    import fabkit.export

    mods = tmp_path / "mods"
    mods.mkdir()
    (mods / "fabkit_bad_input_text_format.py").write_text(TEXT_FORMAT)
    monkeypatch.syspath_prepend(str(mods))
    monkeypatch.setattr(fabkit.export, "EXPORTERS", {"lengths": "fabkit_bad_input_text_format"})
    good = Path(__file__).resolve().parents[1] / "templates" / "fourbar.toml"
    out = tmp_path / "out"
    rc = main(["export", str(BAD / "rigid_network.toml"), str(good), "-o", str(out),
               "--tolerance-samples", "10"])
    captured = capsys.readouterr()
    assert rc == 1
    assert (out / "fourbar" / "report.json").is_file()
    lengths = [float(v) for v in (out / "fourbar" / "lengths.txt").read_text().split()]
    assert lengths == pytest.approx([2.0, 8 ** 0.5, 8 ** 0.5, 2.0], rel=1e-11)
    assert not (out / "rigid_network").exists()
    assert "1 exported, 1 failed" in captured.out
    assert "rigid_network.toml: network: the network is rigid" in captured.err
