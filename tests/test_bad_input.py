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
    "unknown_method_option": ("motion.options.stepsize", ["unknown option", "known: samples"]),
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
    "name_not_a_folder": ("name", ["would leave the output folder"]),
    # bad indices and degenerate networks
    "edge_index_out_of_range": ("network.edges[3][1]", ["out of range 0..3"]),
    "self_loop_edge": ("network.edges[2]", ["to itself"]),
    "duplicate_edge": ("network.edges[0]", ["both join nodes 0 and 2"]),
    "coincident_nodes": ("network.edges[4]", ["zero length"]),
    # negative sizes and impossible fabrication
    "negative_target": ("motion.to", ["positive distance"]),
    "negative_samples": ("motion.options.samples", ["must be >= 2, got -5"]),
    "negative_length_sigma": ("fabrication.tolerance.length_sigma", [">= 0"]),
    "zero_scale": ("fabrication.tolerance.scale", ["> 0"]),
    "negative_kerf": ("fabrication.laser.kerf", ["must be >= 0, got -0.1"]),
    "hole_larger_than_bar": ("fabrication.laser", ["hole", "bigger than", "bar"]),
    # impossible motions
    "rigid_network": ("network", ["rigid", "no conformational motion"]),
    "two_motions": ("network", ["2 conformational motions"]),
    "unreachable_target": ("motion.to", ["not reached", "turning point"]),
    "singular_start": ("network.nodes", ["collinear", "flat state"]),
    "negative_max_step": ("motion.options.max_step", ["must be > 0, got -1"]),
    "too_few_steps": ("motion", ["not reached", "no target after 2 steps"]),
    # sizes that would not finish: refused before any work, with the way to lift the bound
    "chain_copies_huge": ("chain.copies", ["10,000,000", "limit of 20,000 modules",
                                           "--allow-large"]),
    "tessellation_huge": ("tessellation.shape", ["100,000,000", "modules"]),
    "motion_samples_huge": ("motion.options.samples", ["1,000,000,000", "limit"]),
    "motion_samples_infinite": ("motion.options.samples", ["must be finite"]),
    "max_steps_huge": ("motion.options.max_steps", ["limit of 1,000,000 steps"]),
    "tolerance_samples_huge": ("fabrication.tolerance.samples", ["Monte Carlo samples"]),
    "deeply_nested_arrays": ("", ["levels deep, over the limit of 64"]),
    "deeply_nested_tables": ("", ["levels deep, over the limit of 64"]),
}


def test_corpus_is_complete():
    files = {p.stem for p in BAD.glob("*.toml")}
    assert files == set(EXPECTED), files ^ set(EXPECTED)
    assert len(files) >= 50


@pytest.mark.parametrize("stem", sorted(EXPECTED))
def test_bad_template_gives_one_line_and_writes_nothing(stem, tmp_path, capsys):
    path = BAD / f"{stem}.toml"
    out = tmp_path / "out"
    # fewer Monte Carlo builds keep the corpus fast; not where the template's own count is the
    # error (the command line would override it)
    fast = [] if stem == "tolerance_samples_huge" else ["--tolerance-samples", "20"]
    rc = main(["export", str(path), "-o", str(out), *fast])
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
    from fabkit.writers import ExportResult

    text = "\\n".join(f"{v:.12g}" for v in design.network.edge_lengths) + "\\n"
    return ExportResult(files={"lengths.txt": text.encode()}, report={"edges": 4})
"""


def test_one_bad_design_does_not_stop_the_others(tmp_path, capsys, monkeypatch):
    """A minimal format of our own (a module file, so the export's worker processes import it
    too): one text file with the edge lengths, independent of the real formats."""
    import fabkit.writers

    mods = tmp_path / "mods"
    mods.mkdir()
    (mods / "fabkit_bad_input_text_format.py").write_text(TEXT_FORMAT)
    monkeypatch.syspath_prepend(str(mods))
    monkeypatch.setattr(fabkit.writers, "EXPORTERS", {"lengths": "fabkit_bad_input_text_format"})
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


# --- file-system conditions, sizes and options, generated ----------------------------------

def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("fabkit: error: ") and "Traceback" not in err
    return lines[0]


GOOD = Path(__file__).resolve().parents[1] / "templates" / "fourbar.toml"


def _special(kind: str, tmp_path: Path) -> tuple[str, list[str]]:
    """A path that is not a template file, and the words of its one-line error."""
    import os

    p = tmp_path / f"{kind}.toml"
    if kind == "fifo":
        os.mkfifo(p)
        return str(p), ["FIFO", "refused"]
    if kind == "device":
        return "/dev/zero", ["a device", "refused"]
    if kind == "link_loop":
        os.symlink(p, p)
        return str(p), ["symbolic-link loop"]
    if kind == "broken_link":
        os.symlink(tmp_path / "nowhere.toml", p)
        return str(p), ["no such file"]
    if kind == "huge_file":
        with open(p, "wb") as fh:
            fh.write(b"# padding\n" * (5 * 2**20 // 10))
        return str(p), ["bytes", "limit", "--allow-large"]
    if kind == "latin1":
        p.write_bytes("name = \"caf\xe9\"\n".encode("latin-1"))
        return str(p), ["not UTF-8"]
    raise AssertionError(kind)


SPECIAL = ["fifo", "device", "link_loop", "broken_link", "huge_file", "latin1"]


@pytest.mark.parametrize("kind", SPECIAL)
@pytest.mark.parametrize("command", ["export", "info", "simulate"])
def test_special_files_are_refused_in_one_line(kind, command, tmp_path, capsys):
    path, words = _special(kind, tmp_path)
    out = tmp_path / "out"
    args = [command, path] + (["-o", str(out)] if command != "info" else [])
    rc = main(args)
    line = _one_line(capsys.readouterr().err)
    assert rc == 1
    for w in words:
        assert w in line, line
    assert not out.exists() or not any(p.is_file() for p in out.rglob("*"))


def test_a_size_bound_is_lifted_by_allow_large(tmp_path, capsys):
    big = tmp_path / "many_samples.toml"
    network = GOOD.read_text().split("[motion]")[0]  # name, description and [network]
    big.write_text(network + '[motion]\nto = 3.0\nmethod = "constructive"\n'
                   "options = { samples = 100001 }\n")
    assert main(["info", str(big)]) == 1
    assert "limit of 100,000 configurations" in _one_line(capsys.readouterr().err)
    assert main(["--allow-large", "info", str(big)]) == 0
    assert "nodes, edges  4, 4" in capsys.readouterr().out
    assert main(["info", str(big)]) == 1  # the flag lasts one command
    capsys.readouterr()


#: Every command with a bad option value (exit 2) and with an output folder that is a file
#: (exit 1). Each: (arguments before -o, the bad option, words of its error).
COMMANDS = {
    "export": ([str(GOOD)], ["--jobs", "0"], ["--jobs", "at least 1"]),
    "simulate": ([str(GOOD)], ["--method", "warp"], ["--method", "unknown method 'warp'"]),
    "map": ([str(GOOD)], ["--orbits", "0", "--lyapunov"], ["--orbits", "at least 1"]),
    "tolerance": ([str(GOOD)], ["--seed", "-1"], ["--seed", "got -1"]),
    "letters": (["AB"], ["--beam", "0"], ["--beam", "at least 1"]),
    "fold": ([str(GOOD.parent / "origami_sheet.toml")], ["--branch", "-3"],
             ["--branch", "0 or more"]),
    "bench": (["--quick"], ["--budget", "abc"], ["--budget", "invalid float value"]),
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_refuses_an_output_folder_that_is_a_file(command, tmp_path, capsys):
    before, _, _ = COMMANDS[command]
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    for out, words in ((blocker, ["exists and is not a folder"]),
                       (blocker / "below", ["cannot be created", "is not a folder"])):
        rc = main([command, *before, "-o", str(out)])
        line = _one_line(capsys.readouterr().err)
        assert rc == 1, line
        for w in words:
            assert w in line, line
    assert blocker.read_text() == "not a folder"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_gives_a_bad_option_one_line_and_exit_2(command, tmp_path, capsys):
    before, bad, words = COMMANDS[command]
    out = tmp_path / "out"
    rc = main([command, *before, *bad, "-o", str(out)])
    line = _one_line(capsys.readouterr().err)
    assert rc == 2, line
    for w in words:
        assert w in line, line
    assert not out.exists()


@pytest.mark.parametrize("args, words", [
    (["map", str(GOOD), "--period", "1000"], ["--period", "limit of 24", "--allow-large"]),
    (["map", str(GOOD), "--steps", "10000000"], ["--steps", "limit"]),
    (["tolerance", str(GOOD), "--samples", "100000000"], ["--samples", "limit of 10,000"]),
    (["export", str(GOOD), "--tolerance-samples", "100000000"], ["limit of 10,000"]),
    (["export", str(GOOD), "--jobs", "100000"], ["--jobs", "worker processes (this machine has"]),
    (["simulate", str(GOOD), "--to", "nan"], ["--to", "finite"]),
    (["simulate", str(GOOD), "--to", "-1"], ["--to", "positive"]),
    (["letters", "AB", "--height", "inf"], ["--height", "finite"]),
    (["letters", "A" * 41], ["WORD", "limit of 40"]),
    (["export", str(GOOD), "--set", "laser"], ["--set", "SECTION.KEY=VALUE"]),
    (["export", str(GOOD), "--to", "gcode"], ["--to", "unknown format"]),
    (["fold", str(GOOD.parent / "origami_sheet.toml"), "--drive", "d9"], ["--drive", "'d9'"]),
    (["fold", str(GOOD.parent / "origami_sheet.toml"), "--sign", "2"], ["--sign", "invalid choice"]),
    (["export", str(GOOD), "--jobs", "two"], ["--jobs", "invalid int value"]),
    (["export", str(GOOD), "--no-such-option"], ["unrecognized arguments"]),
    (["simulate"], ["required", "TEMPLATE"]),
])
def test_bad_sizes_and_values_of_options_exit_2_before_work(args, words, tmp_path, capsys):
    out = tmp_path / "out"
    rc = main([*args, "-o", str(out)])
    line = _one_line(capsys.readouterr().err)
    assert rc == 2, line
    for w in words:
        assert w in line, line
    assert not out.exists()


def test_check_against_another_design_is_a_failed_check_not_a_crash(tmp_path, capsys):
    from fabkit.writers import export
    from fabkit.templates import load_template

    # the file, as the exporter writes it (in this process: the subject is the check)
    paths, _ = export(load_template(GOOD.parent / "origami_sheet.toml"), "fold", tmp_path)
    [fold] = [p for p in paths if p.suffix == ".fold"]
    rc = main(["check", str(fold), "--design", str(GOOD.parent / "origami_chain12.toml")])
    captured = capsys.readouterr()
    assert rc == 1 and captured.err == ""
    assert "FAIL  design_map" in captured.out and "does not match this file" in captured.out


@pytest.mark.parametrize("content, words", [
    (b"", ["not an STL file (0 bytes)"]),
    (b"\x00" * 80 + (1000).to_bytes(4, "little") + b"\x00" * 500,
     ["not a complete STL file", "1000 triangles", "cut off or corrupt"]),
    (bytes(range(256)) * 8, ["not a complete STL file"]),
    (b"solid x\nfacet normal 0 0 1\n garbage\nendsolid\n", ["holds no triangles"]),
    ("solid caf\xe9\n".encode("latin-1") + b"\x00" * 90, ["not a complete STL file"]),
])
def test_a_corrupt_stl_is_one_line_naming_the_file(content, words, tmp_path, capsys):
    path = tmp_path / "part.stl"
    path.write_bytes(content)
    rc = main(["check", str(path)])
    line = _one_line(capsys.readouterr().err)
    assert rc == 1 and str(path) in line
    assert "charset_normalizer" not in line
    for w in words:
        assert w in line, line
