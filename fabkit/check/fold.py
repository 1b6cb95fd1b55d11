"""As-built check of a FOLD file: read it back, rebuild the network, re-fold, compare the map.

Checks, each reported as ``{"name", "ok", "value", "limit", "detail"}``:

- ``structure``: the FOLD fields fabkit relies on are present and consistent (array lengths,
  assignments in B/M/V/F/U/C/J, fold angles in [-180, 180], faces made of edges, vertex
  indices in range);
- ``frames_keep_lengths``: every frame keeps the edge lengths of the root frame (relative);
- ``modes``: the network rebuilt from the file has one conformational motion, counted at the
  file's root frame, or for a crease pattern at its first frame off the flat state (from the
  file alone: reported whether or not the re-fold below succeeds);
- ``refold_map``: the rebuilt network, folded again by the simulator from the file alone
  (branch chosen by its mountain/valley assignment), reproduces every port distance stored in
  ``fabkit:map`` at the file's drive values (absolute, design units, limit 1e-8);
- ``design_map`` (with a design): the same against the design's own simulation;
- ``maekawa`` and ``kawasaki``: for a crease pattern, at every interior vertex with folds,
  ``|#M - #V| = 2`` and the alternate sector angles sum to pi
  (:mod:`fabkit.check.flat_fold`; the failing vertices are named).

The network is rebuilt from the file's own vertices, edges, assignment and faces
(:mod:`fabkit.check.fold_network`) and folded by the shared simulator; nothing is taken from the
code that wrote the file.
"""

from __future__ import annotations

import numpy as np

from ..errors import FabkitError, FabricationError
from ..io.formats import damaged, load_json
from ..io.readback import ReadBack
from ..kinematics import place, plan_construction
from ..model.network import Network
from ..numerics import apply_fit, FLAT_RTOL, rigid_fit
from . import require_files
from .flat_fold import KAWASAKI_TOL, vertex_folds
from .fold_network import rebuild, refold
from .items import Check, check, finish, not_run

FORMAT = "fold"
#: The sections of ``--set`` this check reads (any other has no effect on it).
READS = ("origami",)
SUFFIXES = (".fold",)

#: Most values (numbers, strings, arrays) a FOLD file may hold, counted on its bytes before it is
#: parsed: origami_chain12 with its frames holds about 30 000; the rest is room for long traces.
MAX_FOLD_VALUES = 2_000_000
#: Largest difference of a port distance between the file and the re-folded network.
MAP_TOL = 1e-8


#: Edge lengths stored in a FOLD file's frames must match the creases to this relative error:
#: the frames are written with 12 significant digits (see export/fold.py), so 1e-8 leaves margin
#: for rounding and refuses a frame that is visibly off.
FRAME_RTOL = 1e-8
#: Largest distance (mm) of a file vertex from the design's node: the file stores 12
#: significant digits, so anything above round-off is a vertex the writer put elsewhere.
GEOMETRY_TOL_MM = 1e-6
#: The checks of every FOLD file, in the order they run; with a design, :data:`DESIGN_CHECKS`
#: follow. A check an earlier failure leaves without what it needs is reported as not run.
CHECKS = ("structure", "frames_keep_lengths", "modes", "refold_map")
#: The checks against the design's template.
DESIGN_CHECKS = ("design_geometry", "design_map")


def read_fold(path, folder=None) -> dict:
    """Parse a FOLD file through the bounded readers (:mod:`fabkit.io.formats`), read by path
    or through ``folder`` (as for :func:`fabkit.check.check_file`).

    Raises
    ------
    InputFileError
        Missing or not a regular file; not FOLD JSON (``kind="damaged"``); nested deeper, with
        longer numbers or more values than any FOLD file fabkit reads (``kind="bounds"``).
    """
    from ..io.workload import MAX_BYTES

    doc = load_json(ReadBack.of(folder).read(path, MAX_BYTES), path, max_items=MAX_FOLD_VALUES,
                    what="FOLD JSON")
    if not isinstance(doc, dict):
        raise damaged(path, "not FOLD JSON (the top level is not an object)")
    return doc


def structure_problems(doc: dict) -> list[str]:
    """Problems of the FOLD fields fabkit uses (empty when none): see
    :func:`fabkit.check.fold_schema.fold_problems`."""
    from .fold_schema import fold_problems

    return fold_problems(doc)


def _map_at(model, fold, drive: str, values: np.ndarray) -> dict:
    """Port distances of the re-folded network at given drive values (exact placement)."""
    net = model.network
    ref = fold.positions[1] if model.flat_start else net.nodes
    plan = plan_construction(net, net.port(drive), ref)
    vals = np.asarray(values, dtype=np.float64)
    start = 1 if model.flat_start else 0  # the flat frame itself is the bifurcation
    pos, margin, _ = place(plan, vals[start:])
    out = {}
    for k in net.ports:
        d = net.port_distance(k, pos)
        if start:
            d = np.concatenate([[net.port_distance(k)], d])
        out[k] = d
    return out


def _sheet_maps(model, sheets, stored) -> tuple[float, str]:
    """Every sheet's map d_out = f(d_in), re-folded from the file, against the stored frames.

    A chain's configuration as a function of its end distance is ill-conditioned (errors grow by
    the map's slope at every sheet), so a chain is checked where it is well-conditioned: sheet
    by sheet, each rebuilt from the file alone and folded at the stored input distances.
    """
    net = model.network
    worst, n = 0.0, 0
    for k, sh in enumerate(sheets):
        if len(sh.get("map", [])) != 2:
            continue
        verts = [int(v) for v in sh["vertices"]]
        local = {g: i for i, g in enumerate(verts)}
        sub_edges = [(local[a], local[b]) for a, b in net.edges.tolist()
                     if a in local and b in local]
        din, dout = sh["map"]
        ports = {"in": tuple(local[v] for v in net.ports[din]),
                 "out": tuple(local[v] for v in net.ports[dout])}
        sub = Network(net.nodes[verts], np.array(sub_edges), ports)
        plan = plan_construction(sub, sub.port("in"))
        pos, margin, _ = place(plan, stored[din])
        if (margin < -FLAT_RTOL).any():
            raise FabricationError(f"sheet {k + 1} cannot reach the stored {din} values")
        worst = max(worst, float(np.max(np.abs(sub.port_distance("out", pos) - stored[dout]))))
        n += 1
    return worst, (f"{n} sheets re-folded from the file, each map d_out = f(d_in) at "
                   f"{len(next(iter(stored.values())))} frames")


def _design_checks(checks, doc, model, design, drive, values, stored, sheets):
    """The file against the design's template: its vertices are the design's nodes (a rigid
    fit, the worst vertex named), its edges and ports the design's; and the design's own
    geometry, folded by the simulator as the file says (its assignment, branch and frames),
    gives the map the file stores. Returns the largest map difference, None when the file is
    another design's."""
    net = design.network
    scale = float(doc["fabkit:scale"])
    root = np.asarray(doc["vertices_coords"], dtype=np.float64) / scale
    nv = root.shape[0]
    file_edges = {tuple(sorted(e)) for e, a in zip(model.edges.tolist(), doc["edges_assignment"])
                  if a != "C"}
    design_edges = {tuple(sorted(e)) for e in net.edges.tolist() if max(e) < nv}
    same = (net.n_nodes >= nv and net.dim == 3 and file_edges == design_edges
            and {k: tuple(v) for k, v in doc["fabkit:ports"].items()}
            == {k: tuple(v) for k, v in net.ports.items()})
    if not same:  # another design (other sheets, other ports): a failed check, not an error
        checks.append(check("design_map", False, None, MAP_TOL,
                            f"the design {design.name} does not match this file ({net.n_nodes} "
                            f"nodes, ports {', '.join(sorted(net.ports))} against {nv} "
                            f"vertices, ports {', '.join(sorted(doc['fabkit:ports']))})"))
        return None
    flat = np.zeros((nv, 3))
    flat[:, :root.shape[1]] = root
    fit = rigid_fit(flat, net.nodes[:nv])
    off = np.linalg.norm(apply_fit(fit, flat) - net.nodes[:nv], axis=1) * scale
    k = int(np.argmax(off))
    checks.append(check("design_geometry", off[k] <= GEOMETRY_TOL_MM, float(off[k]),
                        GEOMETRY_TOL_MM,
                        f"vertex {k} lies {off[k]:.3f} mm from the design's node {k} (best "
                        "rigid fit of the file's vertices onto the design's nodes)"
                        if off[k] > GEOMETRY_TOL_MM else
                        "largest distance (mm) of a file vertex from the design's node after a "
                        "rigid fit; edges and ports are the design's"))
    # the design's nodes carried into the file's frame, folded as the file says
    inverse = (net.nodes[:nv] - fit.shift) @ fit.rotation
    again = dict(doc, vertices_coords=(inverse[:, :root.shape[1]] * scale).tolist())
    m = design.motion
    try:
        dm = rebuild(again)
        dfold = refold(dm, m.drive, m.to)
        if len(sheets) > 1:
            ddiff, _ = _sheet_maps(dm, sheets, stored)
        else:
            dmap = _map_at(dm, dfold, drive, values)
            ddiff = max(float(np.max(np.abs(dmap[k] - stored[k]))) for k in stored)
    except FabkitError as exc:
        checks.append(check("design_map", False, None, MAP_TOL,
                            f"the design's geometry does not fold as the file says: {exc}"))
        return None
    checks.append(check("design_map", ddiff <= MAP_TOL, ddiff, MAP_TOL,
                        f"the file's map against the design {design.name}'s geometry, folded by "
                        f"the simulator to {m.drive} = {float(m.to):g}"))
    return ddiff


def _frames_check(doc, model) -> Check:
    """Every frame keeps the edge lengths of the root frame (relative)."""
    net = model.network
    scale = float(doc["fabkit:scale"])
    frames = np.asarray([f["vertices_coords"] for f in doc.get("file_frames", [])],
                        dtype=np.float64) / scale
    root = np.zeros((model.n_vertices, 3))
    root[:, : net.nodes.shape[1]] = net.nodes[:model.n_vertices]
    rest = np.linalg.norm(root[model.edges[:, 0]] - root[model.edges[:, 1]], axis=1)
    if frames.size:
        lens = np.linalg.norm(frames[:, model.edges[:, 0]] - frames[:, model.edges[:, 1]], axis=-1)
        worst = float(np.max(np.abs(lens / rest - 1.0)))
    else:
        worst = 0.0
    return check("frames_keep_lengths", worst <= FRAME_RTOL, worst, FRAME_RTOL,
                 f"{len(frames)} frames; largest relative edge-length change {worst:.1e}")


def _flat_fold_checks(doc, model) -> list[Check]:
    """Maekawa and Kawasaki at the interior vertices of the file's crease pattern, from the
    file's vertices, edges and assignment (see :mod:`fabkit.check.flat_fold`)."""
    folds = vertex_folds(np.asarray(doc["vertices_coords"], dtype=np.float64), model.edges,
                         model.assignment)
    if not folds:
        return [check("maekawa", True, [], 2, "no interior vertex with folds"),
                check("kawasaki", True, 0.0, KAWASAKI_TOL, "no interior vertex with folds")]
    bad = [f for f in folds if not f["maekawa"]]
    maekawa = check("maekawa", not bad, [f["vertex"] for f in bad], 2, "; ".join(
        f"vertex {f['vertex']}: {f['mountains']} mountains, {f['valleys']} valleys, "
        f"|#M - #V| = {abs(f['mountains'] - f['valleys'])}" for f in bad or folds))
    odd = [f["vertex"] for f in folds if f["kawasaki"] is None]
    off = {f["vertex"]: abs(f["kawasaki"]) for f in folds if f["kawasaki"] is not None}
    worst = max(off, key=off.get) if off else None
    value = None if odd else off[worst]
    detail = (f"vertex {', '.join(map(str, odd))}: an odd number of folds" if odd else
              f"vertex {worst}: the alternate sector angles sum to pi within {off[worst]:.1e} "
              f"rad (worst of {len(folds)} interior vertices with folds)")
    kawasaki = check("kawasaki", not odd and value <= KAWASAKI_TOL, value, KAWASAKI_TOL, detail)
    return [maekawa, kawasaki]


def _frame_positions(doc, model, k: int):
    """The rebuilt network's nodes in the file's frame ``k`` (design units): the file's vertices
    as the frame has them, and each node added to a panel (off its plane) carried along by the
    panel's rigid motion from the flat sheet; None when the file has no such frame (or
    one of another shape)."""
    frames = doc.get("file_frames") or []
    if len(frames) <= k:
        return None
    net = model.network
    nv = model.n_vertices
    frame = np.asarray(frames[k]["vertices_coords"], dtype=np.float64)
    if frame.shape != (nv, net.dim):
        return None
    x = np.array(net.nodes, dtype=np.float64)
    x[:nv] = frame / float(doc["fabkit:scale"])
    for node in range(nv, net.n_nodes):
        panel = np.unique(net.edges[(net.edges == node).any(axis=1)])
        panel = panel[panel != node]
        fit = rigid_fit(net.nodes[panel], x[panel])
        x[node] = apply_fit(fit, net.nodes[node][None])[0]
    return x


def _modes_check(doc, model) -> Check:
    """The rebuilt network has one conformational motion, counted where the file says it is
    folded (:func:`fabkit.model.rigidity.count_modes`): at its root frame, or for a flat crease
    pattern (a bifurcation, where every sheet counts several) at the file's first frame off the
    flat state. Counted from the file alone, whether or not the re-fold succeeds: a FOLD file
    holds one motion (the writer folds along one), so a network of more moves as it should not.
    """
    from ..model.rigidity import count_modes

    if model.flat_start:
        x = _frame_positions(doc, model, 1)
        if x is None:
            return not_run("modes", "the file holds no frame of its vertices off its flat "
                                    "state, where its motions are counted")
        where = "at the file's first frame off the flat state"
    else:
        x, where = model.network.nodes, "at the file's root frame"
    m = count_modes(model.network, x)
    return check("modes", m.conformational == 1, m.conformational, 1,
                 f"conformational motions of the network rebuilt from the file, {where}: {m}")


def _refold_check(model, fold, motion, stored, sheets) -> Check:
    """The rebuilt network, folded again, against the map the file stores (``refold_map``)."""
    values = stored[motion["drive"]]
    if len(sheets) > 1:
        diff, detail = _sheet_maps(model, sheets, stored)
    else:
        again = _map_at(model, fold, motion["drive"], values)
        diff = max(float(np.max(np.abs(again[k] - stored[k]))) for k in stored)
        detail = (f"{len(values)} drive values, ports {', '.join(sorted(stored))}; branch "
                  f"{fold.branch} (file: {motion.get('branch')})")
    return check("refold_map", diff <= MAP_TOL, diff, MAP_TOL, detail)


def check_file(path, design=None, settings=None, *, folder=None) -> dict:
    """Read a FOLD file back and re-fold it (see the module docstring); ``folder`` as for
    :func:`fabkit.check.check_file`.

    Returns
    -------
    dict
        ``ok``, ``checks``, ``max_map_difference``, the branch taken and the branches found;
        for a crease pattern ``flat_foldable`` (Maekawa and Kawasaki hold).
    """
    require_files([path], folder)  # the check is held to the work its size allows
    doc = read_fold(path, folder)
    checks = []
    problems = structure_problems(doc)
    checks.append(check("structure", not problems, len(problems), 0,
                        "; ".join(problems) or "fields present and consistent"))
    report = {"format": FORMAT, "file": str(path)}
    expected = CHECKS + (DESIGN_CHECKS if design is not None else ())
    if problems:
        return finish(report, checks, expected)
    try:
        model = rebuild(doc)
    except FabkitError as exc:
        checks.append(check("refold_map", False, None, MAP_TOL, f"rebuilding failed: {exc}"))
        return finish(report, checks, expected, f"the network cannot be rebuilt: {exc}")
    checks.append(_frames_check(doc, model))
    if model.flat_start:
        flat = _flat_fold_checks(doc, model)
        checks += flat
        report["flat_foldable"] = all(c.passed for c in flat)
    checks.append(_modes_check(doc, model))
    motion = doc["fabkit:motion"]
    stored = {k: np.asarray(v, dtype=np.float64) for k, v in doc["fabkit:map"].items()}
    sheets = doc.get("fabkit:sheets") or []
    try:
        fold = refold(model, motion["drive"], float(motion["to"]))
        refolded = _refold_check(model, fold, motion, stored, sheets)
    except FabkitError as exc:
        checks.append(check("refold_map", False, None, MAP_TOL, f"re-folding failed: {exc}"))
    else:
        checks.append(refolded)
        report.update(max_map_difference=refolded.value, branches=fold.branches,
                      branch=fold.branch)
    if design is not None:  # the file's vertices and stored map against the design's own
        report["max_design_difference"] = _design_checks(
            checks, doc, model, design, motion["drive"], stored[motion["drive"]], stored, sheets)
    else:
        report["not_checked"] = (f"no design given: {', '.join(DESIGN_CHECKS)} need the "
                                 "design's template")
    return finish(report, checks, expected)
