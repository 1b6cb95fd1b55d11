"""The command line starts at once: its help, and a listing of the templates, import none of the
heavy libraries that only the work needs (scipy, matplotlib, pydantic, the mesh and DXF
libraries).

The command line reads its commands' names and help from their source and imports the module
of the command run alone (:func:`fabkit.cli.build_parser`), so ``fabkit --help`` imports no
command's module; ``fabkit CMD --help`` imports that command's, so a module-level import of a
heavy library anywhere on the way from a command to the core would load it for its help too.
Each run is in a fresh interpreter, where ``sys.modules`` shows what was imported. How fast it
starts is measured by benchmarks, not asserted here.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: Libraries that no help and no listing of the templates may import.
HEAVY = ("scipy", "matplotlib", "pydantic", "trimesh", "ezdxf", "shapely", "manifold3d")

# Runs ``main`` once per command line given as a JSON list of argument lists (``null``: every
# ``CMD --help`` of the parser, after ``--help``), and prints, per heavy library loaded, the
# first command line after which it was in sys.modules.
_RUN = """
import argparse, contextlib, io, json, sys
from fabkit.cli import build_parser, main

heavy = json.loads(sys.argv[1])
runs = json.loads(sys.argv[2])
if runs is None:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    runs = [["--help"]] + [[name, "--help"] for name in sorted(sub.choices)]
first, codes = {}, {}
for argv in runs:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        codes[" ".join(argv)] = main(argv)
    for lib in heavy:
        if lib in sys.modules and lib not in first:
            first[lib] = " ".join(argv)
print(json.dumps({"runs": [" ".join(a) for a in runs], "codes": codes, "first": first}))
"""


def _run(runs, heavy=HEAVY, env=None) -> dict:
    proc = subprocess.run([sys.executable, "-c", _RUN, json.dumps(heavy), json.dumps(runs)],
                          capture_output=True, text=True, cwd=ROOT, timeout=300,
                          env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin",
                               "PYTHONPATH": str(ROOT), **(env or {})})
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _leaks(found: dict) -> str:
    return "; ".join(f"{lib} (first after `fabkit {argv}`)"
                     for lib, argv in sorted(found["first"].items()))


def test_help_of_the_command_line_and_of_every_command_imports_no_heavy_library():
    found = _run(None)
    assert len(found["runs"]) >= 13 and found["runs"][0] == "--help", found["runs"]
    assert set(found["codes"].values()) == {0}, found["codes"]
    assert not found["first"], "imported by the help: " + _leaks(found)


def test_listing_the_bundled_templates_imports_no_heavy_library():
    # the listing reads the templates' files; it builds none (that needs scipy and pydantic)
    found = _run([["templates"]])
    assert found["codes"] == {"templates": 0}
    assert not found["first"], "imported by the listing: " + _leaks(found)


def _command_modules() -> tuple:
    from fabkit.cli import _command_index

    return tuple(c.module for c in _command_index())


def test_the_help_imports_no_command_and_a_command_only_its_own():
    modules = _command_modules()
    assert len(modules) >= 12 and "fabkit.commands.templates" in modules
    found = _run([["--help"]], modules)
    assert found["codes"] == {"--help": 0} and not found["first"], _leaks(found)
    for argv, own in ((["templates"], "templates"), (["map", "--help"], "map"),
                      (["--debug", "info", "--help"], "info")):
        found = _run([argv], modules)
        assert set(found["first"]) == {f"fabkit.commands.{own}"}, _leaks(found)


def test_the_defaults_named_in_the_help_are_those_of_the_models():
    # the help states them without importing the models (which import scipy); they must agree
    from fabkit.commands import TOLERANCE_SAMPLES
    from fabkit.commands.simulate import DEFAULT_STEPS
    from fabkit.tolerance.elastic import DEFAULT_STEPS as MODEL_STEPS
    from fabkit.tolerance.spec import ToleranceSpec

    assert DEFAULT_STEPS == MODEL_STEPS
    assert TOLERANCE_SAMPLES == ToleranceSpec().samples


def test_the_parent_of_an_export_loads_none_of_the_work_s_libraries(tmp_path):
    # ``fabkit export`` loads each template in its own process (to name its folder, order the
    # work and refuse bad settings before any starts) and hands it to a worker: the work's
    # libraries are the workers' to load. The chain here is built by the parent too (it looks
    # for the mirroring its modules need, and is a print made of triangles). Its worker ends
    # as it is handed the design, so only the parent is measured.
    from fabkit.pipeline import FAULT_ENV

    name = "printed_planar_chain10"
    argv = ["export", name, "-o", str(tmp_path / "out"), "--jobs", "1"]
    work = tuple(lib for lib in HEAVY if lib != "pydantic")  # the settings' schema is read
    found = _run([argv], heavy=work, env={FAULT_ENV: f"{name}@taken:exit"})
    assert found["codes"][" ".join(argv)] != 0  # the first design's worker did end
    assert not found["first"], _leaks(found)
