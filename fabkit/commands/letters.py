"""``fabkit letters WORD``: chains of curvature modules whose final states spell a word."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..design.assemble import chain
from ..design.letters import (chain_centerline, curvature_modules, design_word, GLYPHS,
                              letter_template, polyline_distance)
from ..errors import FabkitError, UsageError
from ..io.outputs import write_files
from ..templates import with_settings
from ..kinematics import trace
from ..plots.viz import draw_network, figure_kit, figure_png
from . import (out_folder, add_out_dir, add_progress_options, add_settings, check_count, check_number, Example,
               progress_for)
from .settings import read_settings

NAME = "letters"
HELP = "design one curvature chain per letter of WORD; writes templates, a PNG and the fit errors"

EXAMPLES = [
    Example("fabkit letters NO", "two chains whose final states spell NO; out/letters/"),
    Example("fabkit letters NETWORK -o out/network",
            "the paper's word: seven chains, their templates, network.png and the fit errors"),
    Example("fabkit letters FAB --height 60 --beam 200",
            "taller letters (more modules each), a wider search"),
]

#: The curvature modules used, by name → template file (Fig 4a-c).
MODULE_FILES = {
    "contract": "curvature_contract.toml",
    "maintain": "curvature_maintain.toml",
    "expand": "curvature_expand.toml",
}


def add_arguments(p):
    p.add_argument("word", metavar="WORD", help="capital letters A-Z, e.g. NETWORK")
    add_out_dir(p, "out/letters", "output folder (default: out/letters)")
    p.add_argument("--height", type=float, default=40.0,
                   help="letter height in design units (default 40: about 16 strip widths)")
    p.add_argument("--modules", default=None,
                   help="folder holding curvature_contract/maintain/expand.toml "
                        "(default: the bundled templates)")
    p.add_argument("--beam", type=int, default=96, help="beam width of the search (default 96)")
    add_settings(p, "override the final state D2* the chains are designed for and traced to "
                    "(the expand module's motion target), e.g. --set motion.to=2.6 (letters "
                    "reads motion.to only)")
    add_progress_options(p)


def _module_folder(arg) -> Path:
    if arg is not None:
        folder = Path(arg)
    else:
        from ..templates import bundled_folder

        folder = bundled_folder()
    missing = [f for f in MODULE_FILES.values() if not (folder / f).is_file()]
    if missing:
        raise FabkitError(f"{folder}: no curvature module template {missing[0]}; "
                          "give the folder that holds them with --modules")
    return folder


def _align(points, reference):
    """Proper rigid motion (no reflection) of ``points`` onto ``reference`` (least squares)."""
    cp, cr = points.mean(axis=0), reference.mean(axis=0)
    u, _, vt = np.linalg.svd((points - cp).T @ (reference - cr))
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    rot = vt.T @ np.diag([1.0, d]) @ u.T
    return lambda x: (x - cp) @ rot.T + cr


def simulate_letter(fit, modules_by_name, final):
    """Build the letter's chain, trace it from D1* to D2* and measure the fit of the final state.

    Returns
    -------
    dict with the network, trajectory, the final positions in the target's frame and the errors.
    """
    net = chain([modules_by_name[n] for n in fit.names], mirror="alternate")
    traj = trace(net, "d1", to=final, method="constructive", samples=5)
    if not traj.success:
        raise FabkitError(f"the chain does not reach D2*: {traj.message}")
    k = len(fit.names)
    move = _align(chain_centerline(net, traj.positions[-1], k), fit.centerline)
    final_xy = move(traj.positions[-1])
    center = chain_centerline(net, final_xy, k)
    dist = polyline_distance(center, fit.target)
    height = float(np.ptp(fit.target[:, 1])) or 1.0
    return {
        "network": net, "trajectory": traj, "final": final_xy,
        "rms": float(np.sqrt(np.mean(dist ** 2))) / height,
        "max": float(dist.max()) / height,
        "end": float(np.linalg.norm(center[-1] - fit.target[-1])) / height,
        "edge_error": traj.max_edge_error,
    }


def word_figure(word, fits, sims):
    """Initial (straight) and final states of every letter's chain, side by side."""
    fig, (top, ax) = figure_kit.subplots(2, 1, figsize=(2.4 * len(word) + 1, 8.5),
                                  gridspec_kw={"height_ratios": [1.3, 3]})
    x0 = 0.0
    for letter, fit, sim in zip(word, fits, sims):
        net, traj = sim["network"], sim["trajectory"]
        width = float(np.ptp(fit.target[:, 0]))
        shift = np.array([x0 - fit.target[:, 0].min(), 0.0])
        ax.plot(*(fit.target + shift).T, "-", color="0.85", lw=6, zorder=1)
        draw_network(ax, net, sim["final"] + shift, color="C0", lw=0.6, nodes=False)
        ax.text(x0 + width / 2, fit.target[:, 1].min() - 6, f"{letter}: {len(fit.names)} modules\n"
                f"rms {sim['rms']:.3f}, max {sim['max']:.3f}", ha="center", va="top", fontsize=8)
        start = traj.positions[0] - traj.positions[0].min(axis=0)
        row = -6.0 * (len(top.texts))
        draw_network(top, net, start + [0.0, row], color="C0", lw=0.4, nodes=False)
        top.text(-3.0, row + 1.2, letter, ha="right", va="center", fontsize=8)
        x0 += max(width, 10.0) + 12.0
    ax.set_title(f"{word}: final states (D2*); grey: target strokes; errors relative to letter height")
    ax.set_axis_off()
    top.set_title("initial states (D1*): straight chains")
    top.set_axis_off()
    fig.tight_layout()
    return fig


#: Bounds (``fabkit --allow-large`` lifts them): the search costs about beam x letters x modules.
MAX_LETTERS = 40
MAX_BEAM = 5_000


def run(args) -> int:
    from ..templates import load_template

    word = args.word
    if not word:
        raise UsageError("WORD", "is empty; give capital letters, e.g. NETWORK")
    if any(c not in GLYPHS for c in word):
        from ..io.suggest import did_you_mean

        known = "".join(sorted(GLYPHS))
        bad = next((c for c in word if c.upper() not in GLYPHS), None)
        why = (f"{bad!r} is none of them" if bad is not None else
               did_you_mean(word, [word.upper()], quote=False))
        raise UsageError("WORD", f"must be capital letters, those with strokes: {known}; got "
                                 f"{word!r}: {why}")
    check_count("WORD", len(word), 1, MAX_LETTERS, "letters")
    if not args.height > 0:
        raise UsageError("--height", f"--height must be positive, got {args.height}")
    check_number("--height", args.height)
    check_count("--beam", args.beam, 1, MAX_BEAM, "for the beam width")
    settings = read_settings(args, {"motion": {"to"}}, "letters reads motion.to only (D2*, the "
                                                       "final state of the chains)")
    progress = progress_for(args, NAME)
    steps = 1 + 2 * len(word)  # the modules, then a search and a trace per letter
    progress.stage(f"{word}: the curvature modules", total=steps, unit="steps")
    folder = _module_folder(args.modules)
    designs = {name: with_settings(load_template(folder / f), settings)
               for name, f in MODULE_FILES.items()}
    nets = {name: d.network for name, d in designs.items()}
    final = designs["expand"].motion.to
    if final is None:
        raise FabkitError(f"{folder / MODULE_FILES['expand']}: [motion] has no `to` (D2*)")
    try:
        modules = curvature_modules(nets, float(final))
    except FabkitError as exc:
        if "to" in settings.get("motion", {}):  # the value given is not the modules' D2*
            raise UsageError("--set", f"motion.to: {exc}") from None
        raise
    progress.update(1, text=f"{word}: searching the chains")
    fits = design_word(word, modules, height=args.height, beam=args.beam,
                       progress=lambda done, total, letter: progress.update(
                           1 + done, text=f"{letter}: searching the modules"))
    sims = []
    for i, (letter, fit) in enumerate(zip(word, fits)):
        progress.update(1 + len(word) + i, text=f"{letter}: tracing {len(fit.names)} modules")
        sims.append(simulate_letter(fit, nets, float(final)))
    progress.update(steps, text=f"{word}: drawing and writing")
    # Everything is computed before the first file is written.
    files: dict[str, bytes] = {}
    for name, f in MODULE_FILES.items():
        files[f] = (folder / f).read_bytes()
    report = {"word": word, "height": args.height, "D2": float(final), "letters": []}
    for i, (letter, fit, sim) in enumerate(zip(word, fits, sims), start=1):
        fname = f"{word.lower()}_{i}_{letter}.toml"
        files[fname] = letter_template(fit, letter, word, float(final), MODULE_FILES).encode()
        report["letters"].append({
            "letter": letter, "template": fname, "modules": len(fit.names),
            "rms_error": sim["rms"], "max_error": sim["max"], "end_error": sim["end"],
            "max_edge_error": sim["edge_error"],
            "counts": {n: fit.names.count(n) for n in MODULE_FILES},
        })
    files[f"{word.lower()}.png"] = figure_png(word_figure(word, fits, sims), dpi=100)
    files[f"{word.lower()}_fit.json"] = (json.dumps(report, indent=1) + "\n").encode()
    out = out_folder(args)
    write_files(out, files)
    progress.close()
    print(f"{word}: {len(word)} chains -> {out}")
    print("letter  modules  rms/height  max/height  end/height")
    for row in report["letters"]:
        print(f"{row['letter']:>6}  {row['modules']:7d}  {row['rms_error']:10.4f}  "
              f"{row['max_error']:10.4f}  {row['end_error']:10.4f}")
    worst = max(r["rms_error"] for r in report["letters"])
    print(f"worst rms fit error {worst:.4f} of the letter height; PNG: {out.path / (word.lower() + '.png')}")
    return 0
