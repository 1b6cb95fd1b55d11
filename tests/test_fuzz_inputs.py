"""Mutation fuzz of every file format fabkit reads: drawn curves (SVG, CSV), 3MF, STL, DXF and
FOLD files read back by the as-built check, templates (TOML) and a sweep's own files (JSON).

Each mutant is a real file changed the way damaged and hostile files are: numbers replaced by
extremes (1e300, nan, 10^23, text), attributes removed, elements repeated up to thousands of
times, files cut short, bytes flipped, transforms and DTDs added. Every mutant is read as the
command line reads it, in a child process held to its work estimate
(:mod:`fabkit.stoppable`: CPU seconds and memory from the estimate), and must end in a
result or a fabkit error: no internal error (what the command line reports with exit status 70),
and no run stopped at its limits. The mutants come from fixed seeds: a failure names the seed that makes it again.
"""

from __future__ import annotations

import io
import random
import re
import zipfile

import numpy as np
import pytest

import fabkit.check.pinned  # noqa: F401 - imported once here, not in every mutant's process
import fabkit.check.stl  # noqa: F401
import fabkit.check.threemf  # noqa: F401
from fabkit.check import check_file
from fabkit.cli import main
from fabkit.design import read_curve
from fabkit.design.curve_files import svg_work
from fabkit.errors import FabkitError
from fabkit.stoppable import StepLimitError, keep_to, run_stoppable
from fabkit.io.workload import require

#: Mutants of each format that is read in about 0.05 s (an SVG curve, a 3MF print): 320 seeds
#: give each kind of mutation dozens of tries and keep the two files to 15 s each.
MUTANTS = 320
#: Mutants of each format whose every mutant runs a full as-built check (about 0.2 s each).
CHECK_MUTANTS = 24
#: Mutants of each format that is cheap to read (a template, a CSV curve, a sweep's files).
CHEAP_MUTANTS = 60
#: Template mutants (each read builds its network: about 0.4 s).
TEMPLATE_MUTANTS = 30

#: Values a damaged or hostile file puts where a number belongs.
EXTREMES = ["1e300", "-1e300", "1e308", "1e400", "nan", "NaN", "inf", "-inf", "-0", "", "abc",
            "1e-320", "100000000000000000000000", "-1", "0", "0.5", "0x10", "1,5", " 7 ",
            "1e+", "--3", "9" * 400]

NUMBER = re.compile(r"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")


def _replace_number(text: str, rng: random.Random) -> str:
    spans = [m.span() for m in NUMBER.finditer(text)]
    if not spans:
        return text
    a, b = rng.choice(spans)
    return text[:a] + rng.choice(EXTREMES) + text[b:]


def _delete_attribute(text: str, rng: random.Random) -> str:
    spans = [m.span() for m in re.finditer(r'\s[\w:-]+="[^"]*"', text)]
    if not spans:
        return text
    a, b = rng.choice(spans)
    return text[:a] + text[b:]


def _repeat_element(text: str, rng: random.Random) -> str:
    spans = [m.span() for m in re.finditer(r"<\w+[^<>]*/>", text)]
    if not spans:
        return text
    a, b = rng.choice(spans)
    return text[:a] + text[a:b] * rng.choice([2, 10, 100, 1000, 5000]) + text[b:]


def _cut_short(text: str, rng: random.Random) -> str:
    return text[:rng.randrange(len(text))]


def _flip(text: str, rng: random.Random) -> str:
    k = rng.randrange(len(text))
    return text[:k] + rng.choice(['"', "<", ">", "&", "\x00", "\u00e9", " ", "/", "=", "9",
                                  "\x7f", "]]>"]) + text[k + 1:]


def _swap(text: str, rng: random.Random) -> str:
    a, b = sorted(rng.randrange(len(text)) for _ in range(2))
    c = rng.randrange(len(text))
    return text[:c] + text[a:b] + text[c:]


TEXT_MUTATIONS = [_replace_number, _replace_number, _replace_number, _delete_attribute,
                  _repeat_element, _cut_short, _flip, _swap]


def mutate_text(text: str, seed: int, extra=()) -> tuple[str, list[str]]:
    """``text`` changed by one to three mutations; returns it and their names."""
    rng = random.Random(seed)
    done = []
    for _ in range(rng.choice([1, 1, 2, 3])):
        how = rng.choice([*TEXT_MUTATIONS, *extra])
        text = how(text, rng) if text else text
        done.append(how.__name__)
    return text, done


def _outcome(func, *args):
    """``"ok"``, ``"refused"`` (a fabkit error), ``"limit"`` or ``"internal: <line>"``."""
    try:
        run_stoppable(func, *args, what="mutant")
    except StepLimitError as exc:
        return f"limit: {exc}"
    except FabkitError:
        return "refused"
    except Exception as exc:  # what the command line reports as an internal error
        return f"internal: {getattr(exc, 'internal_line', exc)}"
    return "ok"


def _assert_clean(outcomes: dict) -> None:
    bad = {seed: (how, result) for seed, (how, result) in outcomes.items()
           if not result.startswith(("ok", "refused"))}
    assert not bad, f"{len(bad)} of {len(outcomes)} mutants: " + "; ".join(
        f"seed {s} {how}: {result}" for s, (how, result) in list(bad.items())[:5])


# --- SVG curves -----------------------------------------------------------------------------

SVG_BASES = [
    '<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="300mm" viewBox="0 0 300 300">'
    '<path d="M 275 275 A 250 250 0 0 0 25 25" fill="none" stroke="black"/></svg>',
    '<svg xmlns="http://www.w3.org/2000/svg" width="800mm" height="400mm" viewBox="0 0 800 400">'
    '<path d="M 0 200 C 250 -100 550 500 800 200 S 1000 100 1100 300 Q 1200 0 1300 200 T 1500 '
    '100" fill="none" stroke="black"/></svg>',
    '<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" viewBox="0 0 200 200">'
    '<g transform="translate(10,20) rotate(15) scale(0.8)"><polyline points="0,0 40,30 80,20 '
    '120,60 160,50" fill="none" stroke="black"/><circle cx="100" cy="100" r="40"/></g>'
    '<rect x="5" y="5" width="50" height="20" rx="4"/><ellipse cx="60" cy="150" rx="30" '
    'ry="10"/><line x1="0" y1="190" x2="190" y2="190" stroke="black"/></svg>',
    '<svg xmlns="http://www.w3.org/2000/svg" width="10in" height="5in" viewBox="0 0 1000 500">'
    '<path d="m 10 10 h 100 v 50 l 30 30 z M 300 300 q 50 -100 100 0 t 100 0" stroke="black"/>'
    '<polygon points="500,10 600,60 550,120"/></svg>',
]


def _svg_transform(text: str, rng: random.Random) -> str:
    t = rng.choice(["scale(1e300)", "scale(0)", "matrix(1 0 0 1 1e308 0)", "rotate(nan)",
                    "skewX(90)", "matrix(0 0 0 0 0 0)", "scale(-1e-300)"])
    return text.replace("<path", f'<path transform="{t}"', 1).replace(
        "<g ", f'<g transform="{t}" ', 1)


def _svg_command(text: str, rng: random.Random) -> str:
    spans = [m.span() for m in re.finditer(r"[MLHVCSQTAZmlhvcsqtaz]", text)]
    if not spans:
        return text
    a, b = rng.choice(spans)
    return text[:a] + rng.choice(list("MLHVCSQTAZmlhvcsqtazXE ")) + text[b:]


def _svg_units(text: str, rng: random.Random) -> str:
    return re.sub(r'(width|height)="[^"]*"', lambda m: f'{m.group(1)}="'
                  + rng.choice(["0mm", "1e300mm", "-5in", "nanpx", "100%", "", "1e-300pt"])
                  + '"', text, count=1)


def _svg_viewbox(text: str, rng: random.Random) -> str:
    return re.sub(r'viewBox="[^"]*"', 'viewBox="' + rng.choice(
        ["0 0 0 0", "0 0 1e-300 1e-300", "0 0 -10 10", "nan nan 1 1", "0 0 1e308 1e308",
         "0 0 1"]) + '"', text, count=1)


def _svg_entity(text: str, rng: random.Random) -> str:
    return ('<?xml version="1.0"?><!DOCTYPE svg [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;'
            '&a;&a;&a;&a;&a;&a;&a;">]>' + text.replace("fill=\"none\"", "fill=\"&b;\"", 1))


def _svg_repeat_path(text: str, rng: random.Random) -> str:
    m = re.search(r'd="([^"]*)"', text)
    if not m:
        return text
    body = m.group(1)
    return text.replace(body, body + (" " + body.replace("M", "L").replace("m", "l"))
                        * rng.choice([10, 100, 400]), 1)


SVG_MUTATIONS = [_svg_transform, _svg_command, _svg_units, _svg_viewbox, _svg_entity,
                 _svg_repeat_path]


def _read_svg_as_design_does(data: bytes):
    """What ``fabkit design --curve`` does with the file's bytes: the estimate, then the read;
    the curve it returns must be finite."""
    keep_to(require("mutant.svg", *svg_work(data), option=True))
    curve = read_curve(data, "mutant.svg")
    assert np.isfinite(curve.points).all() and np.isfinite(curve.length)
    return len(curve.points)


def test_svg_curve_mutants_end_in_a_curve_or_one_error():
    outcomes = {}
    for seed in range(MUTANTS):
        text, how = mutate_text(SVG_BASES[seed % len(SVG_BASES)], seed, SVG_MUTATIONS * 2)
        outcomes[seed] = (how, _outcome(_read_svg_as_design_does,
                                        text.encode("utf-8", "surrogatepass")))
    _assert_clean(outcomes)
    results = [r for _, r in outcomes.values()]
    # the mutants reach past the parser: many still give a curve, many are refused
    assert results.count("ok") > 50 and results.count("refused") > 50


# --- 3MF print files ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def prints(tmp_path_factory):
    out = tmp_path_factory.mktemp("prints")
    rc = main(["export", "fourbar", "printed_planar", "--to", "stl", "-o", str(out),
               "--tolerance-samples", "0", "--no-previews", "-q"])
    assert rc == 0
    from fabkit.templates import load_template

    return {name: ((out / name / f"{name}.3mf").read_bytes(), load_template(name))
            for name in ("fourbar", "printed_planar")}


def _3mf_transform(text: str, rng: random.Random) -> str:
    t = rng.choice(["1e300 0 0 0 1 0 0 0 1 0 0 0", "0 0 0 0 0 0 0 0 0 0 0 0",
                    "a b c d e f g h i j k l", "1 0 0 0 1 0 0 0 1 1e6 0 0", "1 0 0",
                    "nan 0 0 0 1 0 0 0 1 0 0 0", "1 0 0 0 1 0 0 0 -1 0 0 0"])
    return re.sub(r"<item ", f'<item transform="{t}" ', text, count=1) if "transform=" not in \
        text else re.sub(r'transform="[^"]*"', f'transform="{t}"', text, count=1)


def _3mf_dtd(text: str, rng: random.Random) -> str:
    return text.replace("<model", '<!DOCTYPE model [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
                                  "<model", 1)


def _3mf_unit(text: str, rng: random.Random) -> str:
    return re.sub(r'unit="[^"]*"', 'unit="' + rng.choice(["micron", "meter", "parsec", "",
                                                          "inch"]) + '"', text, count=1)


MODEL_MUTATIONS = [_3mf_transform, _3mf_dtd, _3mf_unit]


def _mutant_3mf(base: bytes, seed: int) -> tuple[bytes, list[str]]:
    """A mutant package: its model XML mutated (most), or its raw bytes (some)."""
    rng = random.Random(seed)
    if rng.random() < 0.15:  # the ZIP itself damaged: flipped, cut, or a member renamed
        data = bytearray(base)
        kind = rng.choice(["flip", "cut", "rename"])
        if kind == "flip":
            for _ in range(rng.choice([1, 5, 50])):
                data[rng.randrange(len(data))] = rng.randrange(256)
            return bytes(data), ["zip bytes flipped"]
        if kind == "cut":
            return bytes(data[:rng.randrange(len(data))]), ["zip cut short"]
        src = zipfile.ZipFile(io.BytesIO(base))
        out = io.BytesIO()
        with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
            for info in src.infolist():
                name = info.filename.replace("3dmodel", "model3d") if rng.random() < 0.5 \
                    else info.filename
                z.writestr(name, src.read(info.filename))
        return out.getvalue(), ["member renamed"]
    src = zipfile.ZipFile(io.BytesIO(base))
    out = io.BytesIO()
    how: list[str] = []
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for info in src.infolist():
            data = src.read(info.filename)
            if info.filename.lower().endswith(".model") or (
                    info.filename.lower().endswith(".config") and rng.random() < 0.2):
                text, how = mutate_text(data.decode("utf-8"), seed, MODEL_MUTATIONS * 2)
                data = text.encode("utf-8", "surrogatepass")
            z.writestr(info.filename, data)
    return out.getvalue(), how


def _check_as_the_command_does(path, design):
    report = check_file(path, design=design)
    assert isinstance(report["ok"], bool) and report["checks"]
    return report["ok"]


def test_3mf_mutants_end_in_a_report_or_one_error(prints, tmp_path):
    outcomes = {}
    names = sorted(prints)
    for seed in range(MUTANTS):
        name = names[seed % len(names)]
        base, design = prints[name]
        data, how = _mutant_3mf(base, seed)
        path = tmp_path / f"{name}.3mf"
        path.write_bytes(data)
        # half the mutants against their design (the full as-built check), half alone
        outcomes[seed] = (how, _outcome(_check_as_the_command_does, path,
                                        design if seed % 4 < 2 else None))
    _assert_clean(outcomes)
    results = [r for _, r in outcomes.values()]
    assert results.count("ok") > 25 and results.count("refused") > 100


# --- every other format: FOLD, DXF, STL, TOML templates, CSV curves, a sweep's JSON -----------

def _json_repeat(text: str, rng: random.Random) -> str:
    """An array's first element repeated up to 20 000 times (edges, faces, frames)."""
    spans = [m.span() for m in re.finditer(r"\[\[[^\[\]]*\]", text)]
    if not spans:
        return text
    a, b = rng.choice(spans)
    first = text[a + 1:b]
    return text[:a + 1] + (first + ",") * rng.choice([2, 100, 20_000]) + text[a + 1:]


def _json_deep(text: str, rng: random.Random) -> str:
    k = rng.randrange(len(text))
    depth = rng.choice([50, 1000, 100_000])
    return text[:k] + "[" * depth + "1" + "]" * depth + text[k:]


def _json_digits(text: str, rng: random.Random) -> str:
    """A number replaced by one of thousands of digits (Python refuses more than 4300)."""
    spans = [m.span() for m in NUMBER.finditer(text)]
    if not spans:
        return text
    a, b = rng.choice(spans)
    return text[:a] + "1" * rng.choice([20, 4301, 5001]) + text[b:]


JSON_MUTATIONS = [_json_repeat, _json_deep, _json_digits]


def _bytes_mutant(data: bytes, seed: int) -> tuple[bytes, list[str]]:
    """A binary file changed: bytes flipped, cut short, a span repeated, NaNs written."""
    rng = random.Random(seed)
    data = bytearray(data)
    kind = rng.choice(["flip", "cut", "repeat", "nan", "count"])
    if kind == "flip":
        for _ in range(rng.choice([1, 10, 100])):
            data[rng.randrange(len(data))] = rng.randrange(256)
    elif kind == "cut":
        data = data[:rng.randrange(len(data))]
    elif kind == "repeat":
        a = rng.randrange(84, len(data))
        data = data[:a] + data[a:a + 50] * rng.choice([2, 100, 1000]) + data[a:]
    elif kind == "nan":
        for _ in range(rng.choice([1, 10])):
            k = rng.randrange(84, len(data) - 4)
            data[k:k + 4] = np.float32(rng.choice([np.nan, np.inf, 1e38])).tobytes()
    else:  # the header's triangle count
        data[80:84] = int(rng.choice([0, 1, 2**31, 2**32 - 1, len(data)])).to_bytes(4, "little")
    return bytes(data), [kind]


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    """A laser kit (DXF), a folded sheet (FOLD) and a print (STL), each checked once here so
    that what a check computes once per process is ready before the mutants fork."""
    out = tmp_path_factory.mktemp("exports")
    for name, fmt in (("fourbar", "dxf"), ("origami_sheet", "fold"), ("printed_planar", "stl")):
        assert main(["export", name, "--to", fmt, "-o", str(out), "--tolerance-samples", "0",
                     "--no-previews", "-q"]) == 0
    from fabkit.templates import load_template

    files = {"dxf": (out / "fourbar" / "laser_sheet1.dxf", "fourbar"),
             "fold": (out / "origami_sheet" / "origami_sheet.fold", "origami_sheet"),
             "stl": (out / "printed_planar" / "printed_planar.stl", "printed_planar")}
    for path, name in files.values():
        assert check_file(path, design=load_template(name))["ok"]
    return {fmt: (path.read_bytes(), load_template(name)) for fmt, (path, name) in files.items()}


@pytest.mark.parametrize("fmt", ["fold", "dxf", "stl"])
def test_files_read_back_by_the_check_end_in_a_report_or_one_error(exports, fmt, tmp_path):
    base, design = exports[fmt]
    outcomes = {}
    for seed in range(CHECK_MUTANTS):
        if fmt == "stl":
            data, how = _bytes_mutant(base, seed)
        else:
            text, how = mutate_text(base.decode("utf-8"), seed,
                                    JSON_MUTATIONS * 2 if fmt == "fold" else ())
            data = text.encode("utf-8", "surrogatepass")
        path = tmp_path / f"mutant{seed}.{fmt}"
        path.write_bytes(data)
        outcomes[seed] = (how, _outcome(_check_as_the_command_does, path,
                                        design if seed % 2 else None))
    _assert_clean(outcomes)
    results = [r for _, r in outcomes.values()]
    assert results.count("refused") + results.count("ok") == CHECK_MUTANTS


def _toml_deep(text: str, rng: random.Random) -> str:
    depth = rng.choice([100, 10_000])
    return text + "\nextra = " + "[" * depth + "1" + "]" * depth + "\n"


def _load_template_file(path):
    from fabkit.templates import load_template

    return load_template(path).name


def test_template_mutants_end_in_a_design_or_one_error(tmp_path):
    from fabkit.templates import resolve_template

    base = resolve_template("fourbar").read_text(encoding="utf-8")
    outcomes = {}
    for seed in range(TEMPLATE_MUTANTS):
        text, how = mutate_text(base, seed, [_toml_deep, _json_digits] * 2)
        path = tmp_path / f"mutant{seed}.toml"
        path.write_bytes(text.encode("utf-8", "surrogatepass"))
        outcomes[seed] = (how, _outcome(_load_template_file, path))
    _assert_clean(outcomes)


def _read_csv_curve(data: bytes):
    curve = read_curve(data, "mutant.csv")
    assert np.isfinite(curve.points).all()
    return len(curve.points)


def test_csv_curve_mutants_end_in_a_curve_or_one_error():
    rows = "x,y\n" + "".join(f"{100 * np.cos(t):.4f},{100 * np.sin(t):.4f}\n"
                              for t in np.linspace(0, 3, 40))
    outcomes = {}
    for seed in range(CHEAP_MUTANTS):
        text, how = mutate_text(rows, seed)
        outcomes[seed] = (how, _outcome(_read_csv_curve, text.encode("utf-8", "surrogatepass")))
    _assert_clean(outcomes)
    results = [r for _, r in outcomes.values()]
    assert results.count("ok") > 10 and results.count("refused") > 10


@pytest.fixture(scope="module")
def finished_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "s"
    assert main(SWEEP + ["-o", str(out)]) == 0
    return out


SWEEP = ["sweep", "chaotic", "--vary", "nodes[4].x=-0.3:-0.2:2", "--measure", "fixed_points",
         "-j", "1", "--no-plots", "-q"]


def _resume(folder):
    rc = main(SWEEP + ["-o", str(folder)])
    if rc not in (0, 1, 2):  # 70: what the command line reports as an internal error
        raise RuntimeError(f"exit status {rc}")
    return rc


def test_a_sweeps_own_files_mutated_end_in_a_result_or_one_error(finished_sweep, tmp_path):
    import shutil

    outcomes = {}
    for seed in range(CHECK_MUTANTS):
        folder = tmp_path / f"s{seed}"
        shutil.copytree(finished_sweep, folder)
        target = sorted((folder / "chunks").glob("*.json"))[seed % 3]  # a chunk or spec.json
        text, how = mutate_text(target.read_text(encoding="utf-8"), seed, JSON_MUTATIONS * 2)
        target.write_bytes(text.encode("utf-8", "surrogatepass"))
        outcomes[seed] = (how, _outcome(_resume, folder))
    _assert_clean(outcomes)
