"""The table of docs/maps.md: the map of every module of ``tests/data/paper_modules.json``.

A row per module, on the branch through its start (``fabkit.module_map``), and a row for a
further branch where it holds the fixed point the paper speaks of. Its last two columns hold
what the paper's labels say about the module (as docs/paper_notes.md quotes them) and whether
the computed map agrees: a label the computation does not bear out says **differs**, with the
computed number.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PAPER_MODULES = ROOT / "tests" / "data" / "paper_modules.json"

SQRT3 = math.sqrt(3.0)

#: Further branches shown, by module: where the paper's second fixed point lies off the start's
#: branch (the start is a flat state, or a turning point separates the two).
EXTRA_BRANCHES = {"physical_fourbar": 1, "printed_planar": 1}

#: |f(d) - d| below this from D1* to D2*: the label d1 = d2 holds (the curvature modules'
#: variable nodes were found numerically, to about 1e-8).
IDENTITY_TOL = 1e-6


#: Below this a slope or a residual is round-off, whose digits differ from one CPU or BLAS
#: kernel to another: the table says "0" rather than a number that could not be checked
#: elsewhere.
ROUND_OFF = 1e-12


def number(x: float, digits: int = 4) -> str:
    """A number for the table: ``digits`` significant digits, a true minus sign, ∞, and 0 for
    round-off."""
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    if abs(x) < ROUND_OFF:
        return "0"
    text = f"{x:.{digits}g}"
    if "e" in text:
        mantissa, exp = text.split("e")
        text = f"{mantissa}e{int(exp)}"
    return text.replace("-", "−")


def _value(x: float) -> str:
    return number(x, 10)


def _fixed_text(p) -> str:
    end = ", at the end of the branch" if p.at_end else ""
    return f"{_value(p.value)}: s = {number(p.slope)} ({p.kind}{end})"


def _cycle_text(c) -> str:
    values = ", ".join(_value(v) for v in c.values)
    return f"({values}) μ = {number(c.multiplier)} ({c.kind})"


def _deviation(g, lo: float, hi: float, samples: int = 2001) -> float:
    """Largest |f(d) - d| over [lo, hi] (sampled)."""
    d = np.linspace(lo, hi, samples)
    return float(np.max(np.abs(np.asarray(g(d)) - d)))


def _near(points, value: float, rtol: float = 1e-6):
    return next((p for p in points if abs(p.value - value) <= rtol * max(1.0, value)), None)


@dataclass
class Computed:
    """What the table shows of one module: its start branch ``start`` (a Map1D) and the
    further branch ``extra`` (or None), with their fixed points and 2-cycles."""

    start: object
    start_fixed: list
    start_cycles: list
    extra: object = None
    extra_fixed: list | None = None


# --- what the paper's labels say, and whether the computed map agrees ---------------------------

def _stable_then_unstable(c: Computed, d1: float, d2: float) -> tuple[bool, str]:
    a, b = _near(c.start_fixed, d1), _near(c.start_fixed, d2)
    ok = (a is not None and b is not None and a.kind in ("stable", "super-stable")
          and b.kind == "unstable")
    found = "; ".join(_fixed_text(p) for p in (a, b) if p is not None)
    return ok, found


def _fixed_point(c):
    ok, found = _stable_then_unstable(c, SQRT3, 1.7 * SQRT3)
    d1 = _near(c.start_fixed, SQRT3)
    extra = " (D1* is in fact super-stable)" if ok and d1.kind == "super-stable" else ""
    return ok, found + extra


def _period_two(c):
    fp = _near(c.start_fixed, SQRT3)
    ok = fp is not None and fp.kind == "unstable" and len(c.start_cycles) == 1 \
        and c.start_cycles[0].kind == "stable"
    return ok, (_fixed_text(fp) if fp else "no fixed point at √3") + "; " + (
        ", ".join(f"2-cycle {_cycle_text(c2)}" for c2 in c.start_cycles) or "no 2-cycle")


def _chaotic(c):
    fp = _near(c.start_fixed, 1.5)
    lyap = c.start.lyapunov()  # the paper's protocol: 1000 orbits, 5000 discarded, 20 000 averaged
    label = 0.312
    ok = (fp is not None and fp.kind == "unstable" and len(c.start_cycles) == 1
          and c.start_cycles[0].kind == "unstable" and abs(lyap.mean - label) <= 2 * lyap.std)
    return ok, ((_fixed_text(fp) if fp else "no fixed point at 1.5") + "; "
                + (f"2-cycle {_cycle_text(c.start_cycles[0])}" if c.start_cycles
                   else "no 2-cycle") + "; λ = "
                f"{lyap.mean:.3f} ± {lyap.std:.3f} ({lyap.values.size} orbits, {lyap.discard} "
                f"discarded, {lyap.average} averaged; three digits: the fourth is at the "
                "orbits' standard error)")


def _identity(c):
    lo, hi = c.start.domain
    dev = _deviation(c.start, lo, hi)
    to = "round-off" if dev < ROUND_OFF else number(dev, 2)
    return dev <= IDENTITY_TOL, f"f = id on the whole branch (f(d) = d to {to})"


def _slope_at_sqrt3(label: float):
    def check(c):
        fp = _near(c.start_fixed, SQRT3)
        if fp is None:
            return False, "no fixed point at √3"
        return abs(fp.slope - label) <= 0.01 * abs(label), f"s = {number(fp.slope)} at √3"
    return check


def _super_stable(c):
    ok, found = _stable_then_unstable(c, SQRT3, _second(c.start_fixed, SQRT3))
    d1 = _near(c.start_fixed, SQRT3)
    return ok and d1.kind == "super-stable", found


def _second(points, first: float) -> float:
    """The value of the fixed point that is not ``first`` (NaN when there is none)."""
    others = [p.value for p in points if abs(p.value - first) > 1e-6 * first]
    return others[0] if others else math.nan


def _curvature(c):
    dev = _deviation(c.start, SQRT3, 1.5 * SQRT3)
    return dev <= IDENTITY_TOL, f"f(d) = d to {number(dev, 2)} on [√3, 1.5√3]"


def _flat_then_stable(c):
    d1 = next((p for p in c.start_fixed if p.at_end), None)
    d2 = next((p for p in c.extra_fixed or () if not p.at_end), None)
    ok = (d1 is not None and d1.kind == "super-unstable" and d2 is not None
          and d2.kind == "stable")
    return ok, "; ".join(_fixed_text(p) for p in (d1, d2) if p is not None)


def _super_stable_then_super_unstable(c):
    d1 = _near(c.start_fixed, 4.0)
    d2 = next(iter(c.extra_fixed or ()), None)
    ok = (d1 is not None and d1.kind == "super-stable" and d2 is not None
          and d2.kind == "super-unstable")
    found = "; ".join(_fixed_text(p) for p in (d1, d2) if p is not None)
    if d2 is not None and d2.kind != "super-unstable":
        lo = min(c.extra.domain)
        found += f" ({number(d2.value - lo, 2)} above the turning point d1 = {_value(lo)})"
    return ok, found


@dataclass(frozen=True)
class Label:
    """What the paper says of a module, and the check of it against the computed map."""

    says: str
    check: Callable[[Computed], tuple[bool, str]]


#: The paper's labels, as docs/paper_notes.md quotes them (modules without one: none).
LABELS = {
    "fixed_point": Label("stable D1*, unstable D2*", _fixed_point),
    "period_two": Label("unstable fixed point, stable 2-cycle", _period_two),
    "chaotic": Label("unstable fixed point and limit cycle; λ ≈ 0.312", _chaotic),
    "slope_one": Label("s = 1", _identity),
    "slope_one_and_a_half": Label("s = 1.5 at D* = √3", _slope_at_sqrt3(1.5)),
    "super_stable": Label("s = 0 at D1*, unstable D2*", _super_stable),
    "curvature_contract": Label("d1 = d2 from D1* to D2*", _curvature),
    "curvature_maintain": Label("d1 = d2 from D1* to D2*", _curvature),
    "curvature_expand": Label("d1 = d2 from D1* to D2*", _curvature),
    "physical_fourbar": Label("D1* super-unstable (s = ∞), D2* stable", _flat_then_stable),
    "printed_planar": Label("D1* super-stable, D2* super-unstable",
                            _super_stable_then_super_unstable),
}


# --- the table ------------------------------------------------------------------------------------

def _maps(module: dict):
    import fabkit

    ports = {"d1": tuple(module["d1"]), "d2": tuple(module["d2"])}
    net = fabkit.Network(module["nodes"], module["edges"], ports=ports)
    return fabkit.module_map(net)


def _fixed_column(g, fixed) -> str:
    if g.is_identity():
        return "f = id on the whole branch: every point neutral (s = 1)"
    return "; ".join(_fixed_text(p) for p in fixed) or "none"


def _cycles_column(g, cycles) -> str:
    if g.is_identity():
        return "—"
    if g.is_identity(power=2):
        return "f∘f = id: every point (a continuum)"
    return "; ".join(_cycle_text(c) for c in cycles) or "none"


def _domain(g) -> str:
    lo, hi = g.domain
    return f"[{lo:.6g}, {hi:.6g}]"


@functools.lru_cache(maxsize=1)
def _computed() -> list[tuple[str, dict, Computed, tuple[bool, str] | None]]:
    """Every paper module: its name, its entry of the JSON, its maps and, where the paper
    labels it, (agrees, what was found)."""
    out = []
    for name, module in json.loads(PAPER_MODULES.read_text())["modules"].items():
        f = _maps(module)
        computed = Computed(f, f.fixed_points(), f.cycles(2))
        extra = EXTRA_BRANCHES.get(name)
        if extra is not None:
            computed.extra = f.on_branch(extra)
            computed.extra_fixed = computed.extra.fixed_points()
        label = LABELS.get(name)
        out.append((name, module, computed, None if label is None else label.check(computed)))
    return out


def paper_modules_table() -> str:
    """Markdown rows: the map of every paper module, and the paper's labels checked."""
    rows = ["| module | branch | d1 domain | fixed points: value, slope (kind) | 2-cycles | "
            "the paper says | computed |",
            "|---|---|---|---|---|---|---|"]
    for name, module, computed, checked in _computed():
        f = computed.start
        start = f.branch.index
        extra = EXTRA_BRANCHES.get(name)
        if checked is None:
            says = verdict = "—"
        else:
            ok, found = checked
            says = LABELS[name].says
            verdict = ("agrees: " if ok else "**differs**: ") + found
        shown = f"{name} (3D)" if module.get("dim") == 3 else name
        rows.append(f"| {shown} | **{start}** | {_domain(f)} | "
                    f"{_fixed_column(f, computed.start_fixed)} | "
                    f"{_cycles_column(f, computed.start_cycles)} | {says} | {verdict} |")
        if extra is not None:
            g = computed.extra
            rows.append(f"| {shown} | {extra} | {_domain(g)} | "
                        f"{_fixed_column(g, computed.extra_fixed)} | "
                        f"{_cycles_column(g, g.cycles(2))} | | |")
    return "\n".join(rows)


def paper_notes_table() -> str:
    """Markdown rows of docs/paper_notes.md: each label of the paper, what fabkit computes
    and whether they agree."""
    rows = ["| module (figure) | paper says | fabkit computes | verdict |", "|---|---|---|---|"]
    for name, module, _, checked in _computed():
        if checked is None:
            continue
        ok, found = checked
        figure = module.get("figure", "").split(":")[0]
        shown = f"{name} ({figure})" if figure else name
        rows.append(f"| {shown} | {LABELS[name].says} | {found} | "
                    f"{'agrees' if ok else '**differs**'} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(paper_modules_table())
