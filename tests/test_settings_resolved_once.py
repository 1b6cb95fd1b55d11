"""A design's settings are resolved once, into frozen dataclasses, and nothing below the entry
reads a raw settings dict (issue 46).

The batch resolves a design's settings (:func:`fabkit.settings.design.design_settings`) before
its Motion stage; the trace's needs, the planners, the writers, the tolerance analysis and the
as-built checks read that one typed value. Counted here through the pipeline with the checks and
the tolerance analysis on; the code of the stages below the entry is walked for raw probes.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import sys
from pathlib import Path

import pytest

import fabkit
from fabkit.errors import FabricationError
from fabkit.pipeline.design import export_one
from fabkit.settings.design import design_settings, DesignSettings

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"

#: The stages below the entry: they read typed settings only.
TYPED_STAGES = ("writers", "fab", "tolerance", "check", "report")

#: Names that hold settings in fabkit's code.
SETTINGS_NAMES = {"settings", "overrides"}

#: ``file: line text`` of probes allowed, with the reason (none: the one entry resolver is
#: fabkit/settings/design.py, outside the walked stages).
ALLOWED: dict[str, str] = {}


def _counted(monkeypatch, module_name: str, name: str) -> list:
    """Count every call of ``module_name.name``, wherever fabkit's modules imported it."""
    original = getattr(importlib.import_module(module_name), name)
    calls: list = []

    def counted(*args, **kwargs):
        calls.append(args[0] if args else None)
        return original(*args, **kwargs)

    for mod in list(sys.modules.values()):
        if getattr(mod, "__name__", "").startswith("fabkit") and \
                getattr(mod, name, None) is original:
            monkeypatch.setattr(mod, name, counted)
    return calls


@pytest.mark.parametrize("template, fmt", [("fourbar_chain", "dxf"), ("printed_planar", "stl")])
def test_each_design_resolves_its_settings_once(template, fmt, tmp_path, monkeypatch):
    # every module that may read settings is imported first, so the count sees them all
    for name in ("fabkit.check.dxf", "fabkit.check.stl", "fabkit.check.threemf",
                 "fabkit.writers.dxf", "fabkit.writers.stl", "fabkit.fab.laser_plan",
                 "fabkit.fab.print_plan", "fabkit.tolerance.spec", "fabkit.tolerance.elastic"):
        importlib.import_module(name)
    laser = _counted(monkeypatch, "fabkit.settings.laser", "laser_settings")
    printing = _counted(monkeypatch, "fabkit.settings.printing", "design_print_settings")
    origami = _counted(monkeypatch, "fabkit.settings.origami", "origami_settings")
    res = export_one(TEMPLATES / f"{template}.toml", [fmt], tmp_path, {}, check=True,
                     tolerance_samples=4, previews=False)
    assert not res.message, res.message
    checks = res.formats[fmt].checks
    assert checks and all(c.ok for c in checks), "the as-built check ran, and passed"
    folder = Path(res.folder)
    assert (folder / "report.json").is_file()
    assert '"tolerance"' in (folder / "report.json").read_text(), "the tolerance analysis ran"
    assert len(laser) == 1 and len(printing) == 1, (len(laser), len(printing))
    assert len(origami) == 1  # tried once: no [fabrication.origami] table, kept as its error


def test_the_public_one_call_api_resolves_a_dict_once(monkeypatch):
    from fabkit.fab.laser_plan import laser_plan

    laser = _counted(monkeypatch, "fabkit.settings.laser", "laser_settings")
    design = fabkit.load_template(TEMPLATES / "fourbar.toml")
    plan = laser_plan(design, {"laser": {"kerf": 0.2}})
    assert plan.settings.kerf == 0.2
    assert len(laser) == 1
    resolved = design_settings(design, {"laser": {"kerf": 0.2}})
    assert len(laser) == 2
    assert design_settings(design, resolved) is resolved  # handed back, not resolved again
    assert laser_plan(design, resolved).settings is resolved.laser
    assert len(laser) == 2


def _name(node) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    if isinstance(node, ast.BoolOp):  # (settings or {}).get(...)
        return _name(node.values[0])
    return None


def raw_probes(tree: ast.AST) -> list[tuple[int, str]]:
    """``(line, what)`` of every ``settings.get(...)``/``overrides.get(...)`` (also through
    ``(settings or {})``) and every ``settings["key"]`` subscript."""
    out = []
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == "get" and _name(node.func.value) in SETTINGS_NAMES):
            out.append((node.lineno, f"{_name(node.func.value)}.get(...)"))
        elif (isinstance(node, ast.Subscript) and _name(node.value) in SETTINGS_NAMES
              and isinstance(node.slice, ast.Constant) and isinstance(node.slice.value, str)):
            out.append((node.lineno, f"{_name(node.value)}[{node.slice.value!r}]"))
    return out


def test_the_probe_finder_finds_probes():
    src = ("a = settings.get('laser')\nb = (settings or {}).get('origami')\n"
           "c = model.settings.get('medium')\nd = overrides['print']\ne = settings.laser.kerf\n")
    assert [line for line, _ in raw_probes(ast.parse(src))] == [1, 2, 3, 4]


@pytest.mark.parametrize("stage", TYPED_STAGES)
def test_no_stage_below_the_entry_probes_a_raw_settings_dict(stage):
    found = []
    for path in sorted((ROOT / "fabkit" / stage).rglob("*.py")):
        lines = path.read_text().splitlines()
        for line, what in raw_probes(ast.parse(path.read_text())):
            key = f"{path.relative_to(ROOT)}: {lines[line - 1].strip()}"
            if key not in ALLOWED:
                found.append(f"{path.relative_to(ROOT)}:{line}: {what}")
    assert not found, "raw settings read below the entry:\n" + "\n".join(found)


def test_the_writers_take_the_slicer_settings_from_the_plan():
    for name in ("stl.py", "pinned.py"):
        tree = ast.parse((ROOT / "fabkit" / "writers" / name).read_text())
        imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        assert "fab.slicer" not in {m.lstrip(".") for m in imported if m}, name
    from fabkit.fab.plans import make_plan
    from fabkit.fab.slicer import slicer_settings

    design = fabkit.load_template(TEMPLATES / "printed_planar.toml")
    plan = make_plan("print", design, {"print": {"material": "PETG"}})
    assert plan.slicer == slicer_settings(plan.settings)
    assert plan.slicer.project["filament_type"] == "PETG"


def test_resolved_settings_are_frozen():
    design = fabkit.load_template(TEMPLATES / "origami_sheet.toml")
    s = design_settings(design, {"origami": {"samples": 21}})
    assert isinstance(s, DesignSettings) and s.origami.samples == 21
    for obj, field in ((s, "laser"), (s.laser, "kerf"), (s.print, "gap"),
                       (s.origami, "scale"), (s.tolerance, "table")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, field, None)
    with pytest.raises(TypeError):
        s.overrides["origami"]["samples"] = 3  # the overrides as given are read-only too
    assert s.overrides_dict() == {"origami": {"samples": 21}}


@pytest.mark.parametrize("template", ["origami_sheet", "origami_chain12"])
def test_the_origami_scale_is_the_models(template):
    from fabkit.fab.creases import origami_model
    from fabkit.tolerance import tolerance_spec

    design = fabkit.load_template(TEMPLATES / f"{template}.toml")
    s = design_settings(design)
    model = origami_model(design, s.origami)
    assert s.origami.scale == model.scale  # the same number, not a near one
    assert tolerance_spec(design, s).scale == model.scale
    assert s.origami.scale == pytest.approx(
        {"origami_sheet": 150.0 / 2 ** 0.5, "origami_chain12": 100.0 / 2 ** 0.5}[template])


def test_a_section_that_cannot_resolve_stops_only_its_process():
    design = fabkit.load_template(TEMPLATES / "fourbar_chain.toml")
    s = design_settings(design, {"laser": {"kerf": 9.0}})  # the kerf closes the 4.2 mm holes
    assert s.laser is None and s.print is not None
    with pytest.raises(FabricationError, match="kerf 9 mm would close"):
        s.require("laser")
    from fabkit.fab.plans import trace_needs

    assert trace_needs({"laser"}, design, s) == {}  # the plan says why, not the trace


def test_the_origami_error_model_reads_the_resolved_settings_not_the_template(monkeypatch):
    """The tolerance analysis's sheets and cut boundary come from the spec's resolved origami
    settings: the template is not read again (a ``--set origami.*`` would be lost there)."""
    import fabkit.tolerance.placement as placement
    from fabkit.tolerance.spec import tolerance_spec

    design = fabkit.load_template(TEMPLATES / "origami_sheet.toml")
    spec = tolerance_spec(design)
    assert spec.origami_settings is not None

    def reread(*_a, **_k):
        raise AssertionError("the template's origami table was read again")

    monkeypatch.setattr(placement, "origami_settings", reread)
    geo = placement.process_geometry(design, spec, None, None)
    assert geo.sheets and geo.boundary is not None
    assert int(geo.boundary.sum()) == len({i for e in design.network.edges[
        [a in ("B", "C") for a in spec.origami_settings.assignment]] for i in e})
