"""The export pipeline: a design's motion traced once per motion window and handed to every
stage; no exporter, check or report traces it again; the reports head with the verdict."""

from __future__ import annotations

import ast
import sys
import traceback
from pathlib import Path

import numpy as np
import pytest

import fabkit
import fabkit.kinematics.tracer as tracer
from fabkit.pipeline import export_one
from fabkit.templates import Design, load_template

from conftest import TEMPLATES

ROOT = Path(fabkit.__file__).parent


def _count_traces(monkeypatch, design_path):
    """Export a design (every format, checked) and return the targets of every trace of the
    design's own motion (``Design.trace``), the tracer calls on the design's own network made
    outside the as-built checks (which re-simulate the network read back) and outside the laser
    guide's functional test, and the functional test's (drive, target) pushes."""
    reference = load_template(design_path).network
    designs, own, function = [], [], []
    real_design_trace, real_problem = Design.trace, tracer.make_problem

    def design_trace(self, **overrides):
        designs.append(float(overrides.get("to", self.motion.to)))
        return real_design_trace(self, **overrides)

    def make_problem(net, drive, to, **kwargs):
        # every call of fabkit.trace, however its caller imported it, builds its problem here
        if sys._getframe(1).f_code is tracer.trace.__code__:
            same = (net.nodes.shape == reference.nodes.shape
                    and np.array_equal(net.edges, reference.edges)
                    and np.array_equal(net.edge_lengths, reference.edge_lengths))
            stack = [f.filename for f in traceback.extract_stack()]
            in_check = any("/fabkit/check/" in f for f in stack)
            if same and any(f.endswith("/fabkit/fab/guide/function.py") for f in stack):
                function.append((drive, float(to)))
            elif same and not in_check:
                own.append(float(np.nan if to is None else to))
        return real_problem(net, drive, to, **kwargs)

    monkeypatch.setattr(Design, "trace", design_trace)
    monkeypatch.setattr(tracer, "make_problem", make_problem)
    # the functional test is made once per design and kept for the process: an earlier export of
    # the same design in this worker (another test file) would leave none of its pushes to count
    monkeypatch.setattr("fabkit.fab.guide.function._MADE", {})
    return designs, own, function


@pytest.mark.parametrize("name, windows", [
    # no window: the design's motion, traced once for the laser kit, the print, the checks,
    # the previews and the tolerance analysis
    ("super_stable_chain", [1.009950493837208]),
    # the laser kit and the print both stop at motion_to = 2.9: that window is traced once
    ("fixed_point_chain8", [2.9, 2.944486372867092]),
])
def test_an_export_traces_each_motion_window_once(monkeypatch, tmp_path, name, windows):
    path = TEMPLATES / f"{name}.toml"
    designs, own, _ = _count_traces(monkeypatch, path)
    res = export_one(path, None, tmp_path, {}, check=True, tolerance_samples=10,
                     previews=False)
    assert res.ok, res.message
    assert {"dxf", "stl"} <= set(res.exported_formats)
    assert sorted(designs) == windows
    # every call of the tracer on the design's own network outside the checks is one of those
    assert len(own) == len(windows)


#: The modules that are handed the traced motion and must never trace the design themselves.
NO_TRACE = sorted([*(ROOT / "writers").glob("*.py"), *(ROOT / "check").glob("*.py"),
                   ROOT / "report" / "text.py", *(ROOT / "report" / "html").glob("*.py"),
                   ROOT / "pipeline" / "formats.py",
                   ROOT / "pipeline" / "design.py", ROOT / "pipeline" / "stages.py"])
#: Names that trace a design's motion or place a kit by tracing it.
TRACERS = {"trace_motion", "kit_design", "printed_design", "motion_window", "traced_motion"}


@pytest.mark.parametrize("path", NO_TRACE, ids=lambda p: str(p.relative_to(ROOT.parent)))
def test_no_exporter_check_or_report_traces_the_design_itself(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    checks = "check" in path.parts
    pipeline = path.name in ("design.py", "formats.py") and "pipeline" in path.parts
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and node.func.attr == "trace":
            found.append(f"line {node.lineno}: .trace(...)")
        if isinstance(node, ast.ImportFrom):
            names = {a.name for a in node.names}
            if not checks and node.module and node.module.endswith("kinematics") \
                    and "trace" in names:
                # an exporter or a report has no network of its own to trace
                found.append(f"line {node.lineno}: imports kinematics.trace")
            bad = names & TRACERS
            if pipeline:  # the pipeline's Motion stage is the one place the design is traced
                bad -= {"trace_motion"}
            if bad:
                found.append(f"line {node.lineno}: imports {', '.join(sorted(bad))}")
    assert not found, f"{path.relative_to(ROOT.parent)}: " + "; ".join(found)


def test_every_origami_format_is_written_from_one_fold(monkeypatch, tmp_path):
    # the crease SVG, FOLD and .cp writers share the origami plan: the sheet is folded once
    import fabkit.fab.creases.plan as origami

    folds = []
    real = origami.fold_model

    def fold_model(model, drive, to, samples=None, **kw):
        folds.append(model.name)
        return real(model, drive, to, samples, **kw)

    monkeypatch.setattr(origami, "fold_model", fold_model)
    res = export_one(TEMPLATES / "origami_sheet.toml", ["svg", "fold", "cp"], tmp_path, {},
                     check=False, tolerance_samples=0, previews=False)
    assert res.ok, res.message
    assert set(res.exported_formats) == {"svg", "fold", "cp"}
    assert folds == ["origami_sheet"]


def _count_outer_traces(monkeypatch, design_path) -> list:
    """The targets of every trace of the design's own network that is not part of another
    trace (a branch switch traces again after its step off the flat state: one trace) and not
    the as-built checks' (they re-fold the network read back)."""
    reference = load_template(design_path).network
    outer = []
    real_problem = tracer.make_problem

    def make_problem(net, drive, to, **kwargs):
        if sys._getframe(1).f_code is tracer.trace.__code__:
            stack = traceback.extract_stack()
            nested = sum(f.name == "trace" and f.filename == tracer.__file__ for f in stack)
            same = (net.nodes.shape == reference.nodes.shape
                    and np.array_equal(net.edges, reference.edges))
            if same and nested == 1 and not any("/fabkit/check/" in f.filename for f in stack):
                outer.append(float(to))
        return real_problem(net, drive, to, **kwargs)

    monkeypatch.setattr(tracer, "make_problem", make_problem)
    return outer


@pytest.mark.parametrize("name, formats", [("origami_sheet", ["svg", "fold", "cp"]),
                                           ("origami_chain12", ["svg", "fold"])])
def test_an_origami_export_traces_its_motion_once(monkeypatch, tmp_path, name, formats):
    # the Motion stage traces the motion as the fold does (fab.creases.plan.trace_needs: the
    # sheet's branch chosen by its assignment; the chain placed geometrically, then from its
    # far end) and the fold is made of that trace: one trace, not the stage's and the fold's
    path = TEMPLATES / f"{name}.toml"
    outer = _count_outer_traces(monkeypatch, path)
    res = export_one(path, formats, tmp_path, {}, check=True, tolerance_samples=10,
                     previews=False)
    assert res.ok, res.message
    assert sorted(res.exported_formats) == sorted(formats)
    assert outer == [load_template(path).motion.to]


@pytest.mark.parametrize("name", ["origami_sheet", "origami_chain12"])
def test_the_fold_is_made_of_the_motion_stage_trace(name):
    from fabkit.writers import EXPORTERS
    from fabkit.fab.plans import make_plan
    from fabkit.pipeline.formats import choose_formats, traced_for

    design = load_template(TEMPLATES / f"{name}.toml")
    motion = traced_for(design, choose_formats(design, None, EXPORTERS)[0], {})
    plan = make_plan("origami", design, {}, motion)
    assert plan.fold.positions is motion.trajectory.positions
    # without the stage's trace (the Python API) the fold traces the same motion itself
    alone = make_plan("origami", design, {}, None)
    assert alone.fold.positions is not motion.trajectory.positions
    assert np.array_equal(alone.fold.positions, plan.fold.positions)
    assert alone.fold.method == plan.fold.method and alone.fold.branch == plan.fold.branch


def test_a_flat_sheet_its_motion_does_not_leave_is_folded_by_its_plan(tmp_path):
    # motion.method = "auto" stops at the flat start (a singular start): the fold chooses the
    # branch by the crease assignment and traces it; its FOLD file is the one made of the
    # Motion stage's trace when the motion leaves the flat state on that branch
    text = (TEMPLATES / "origami_sheet.toml").read_text()
    (tmp_path / "src").mkdir()
    auto = tmp_path / "src" / "origami_sheet.toml"
    auto.write_text(text.replace('method = "branch"', 'method = "auto"'))
    assert auto.read_text() != text
    a = export_one(auto, ["fold"], tmp_path / "auto", {}, check=True, tolerance_samples=0,
                   previews=False)
    b = export_one(TEMPLATES / "origami_sheet.toml", ["fold"], tmp_path / "branch", {},
                   check=True, tolerance_samples=0, previews=False)
    assert a.ok and b.ok, (a.error, b.error)
    fold_a = (tmp_path / "auto" / "origami_sheet" / "origami_sheet.fold").read_bytes()
    fold_b = (tmp_path / "branch" / "origami_sheet" / "origami_sheet.fold").read_bytes()
    assert fold_a == fold_b and b'"branch": 2' in fold_a


def test_a_writer_takes_a_plan_and_plans_nothing():
    # writers of a process's plan: no planner, tracer or settings reader is imported in them
    from fabkit.writers import EXPORTERS
    from fabkit.fab.plans import PLANNERS

    import importlib

    planners = {"laser_plan", "print_plan", "origami_plan", "origami_model", "fold_model",
                "pinned_print", "laser_settings", "design_print_settings", "make_plan"}
    for fmt, name in EXPORTERS.items():
        module = importlib.import_module(name)
        assert module.PROCESS in PLANNERS and callable(module.write), fmt
        path = Path(module.__file__)
        tree = ast.parse(path.read_text(encoding="utf-8"))
        shortcut = [n for n in tree.body if isinstance(n, ast.FunctionDef)
                    and n.name == "export_design"]
        assert len(shortcut) == 1, fmt  # the one-call shortcut: plans, then writes
        allowed = {id(n) for n in ast.walk(shortcut[0])}
        imported = [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                    and id(n) not in allowed]
        assert imported, fmt  # the walk sees the writer's imports
        for node in imported:
            bad = {a.name for a in node.names} & planners
            assert not bad, f"{path.name}:{node.lineno} imports {sorted(bad)}"


#: What builds a model, a fold or a plan: a report draws what the export's plans made.
MODEL_BUILDERS = {"origami_model", "fold_model", "origami_plan", "crease_layout",
                  "rigid_triangles", "print_geometry", "print_plan", "laser_plan", "make_plan",
                  "network_from_pattern"}
#: The modules that build them (a report imports none of them).
MODEL_MODULES = ("fab.creases", "fab.hinges", "fab.plans", "fab.print_plan", "fab.laser_plan",
                 "model.triangles")


def _imports(tree) -> list[tuple[int, str, set]]:
    """Every import of a module (inside functions too): (line, module, names)."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            out.append((node.lineno, "." * node.level + (node.module or ""),
                        {a.name for a in node.names}))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name, set()) for a in node.names]
    return out


@pytest.mark.parametrize("path", sorted((ROOT / "report").rglob("*.py")),
                         ids=lambda p: str(p.relative_to(ROOT.parent)))
def test_a_report_draws_from_the_plans_and_builds_no_model(path):
    # the motion drawing's panels come from the origami plan and the print plan the export
    # made (Artefacts.plans), not from an origami model or rigid triangles rebuilt for it
    found = []
    for line, module, names in _imports(ast.parse(path.read_text(encoding="utf-8"))):
        bare = module.lstrip(".").removeprefix("fabkit.")
        pulled = [f"{bare}.{n}" if bare else n for n in names] or [bare]
        if any(p == m or p.startswith(m + ".") for p in [bare, *pulled] for m in MODEL_MODULES):
            found.append(f"line {line}: imports {module} {sorted(names)}")
        if names & MODEL_BUILDERS:
            found.append(f"line {line}: imports {', '.join(sorted(names & MODEL_BUILDERS))}")
    assert not found, f"{path.relative_to(ROOT.parent)}: " + "; ".join(found)


def test_the_ast_walk_of_reports_sees_a_model_import():
    # the test above can fail: an import of the origami model, inside a function, is found
    tree = ast.parse("def f():\n    from ...fab.creases import origami_model\n")
    line, module, names = _imports(tree)[0]
    assert (line, module, names) == (2, "...fab.creases", {"origami_model"})
    assert names & MODEL_BUILDERS


def test_the_report_fills_the_panels_the_plans_made():
    # the motion drawing of report.html fills the panels of the export's own plans
    from fabkit.report.html import motion_frames

    design = load_template(TEMPLATES / "origami_sheet.toml")
    traj = fabkit.motion.trace_motion(design).trajectory

    class Plan:
        panels = [[0, 1, 4], [1, 2, 4]]

    frames = motion_frames(design, traj, {}, {"origami": Plan()})
    assert frames["faces"] == [[0, 1, 4], [1, 2, 4]] and frames["fill"] == "#fff3c4"
    bare = motion_frames(design, traj, {})
    assert bare["faces"] == [] and bare["fill"] == ""  # no plan: no model rebuilt for it


@pytest.mark.slow
def test_the_and_gate_laser_kit_is_planned_along_the_one_trace(monkeypatch, tmp_path):
    # a projected motion is traced once, with the node step the stacking needs
    # (fabkit.fab.laser_plan.trace_needs): the laser plan does not trace it again
    path = TEMPLATES / "and_gate.toml"
    designs, own, function = _count_traces(monkeypatch, path)
    res = export_one(path, ["dxf"], tmp_path, {}, check=False, tolerance_samples=0,
                     previews=False)
    assert res.ok, res.message
    assert len(designs) == 1 and len(own) == 1
    # the guide's functional test pushes A, B, then A and B, once, though the guide's plan is
    # made twice (for the kit's pictures, then with the verdict)
    assert [p for p, _ in function] == ["d1", "d1_b", "d1", "d1_b"]
