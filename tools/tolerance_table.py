"""The table of docs/batch.md: the tolerance verdict of every bundled design.

Runs ``fabkit tolerance templates/*.toml`` (default settings: 200 builds, seed 0, each design's
own process) in a temporary folder and makes a row per design from its ``tolerance.json``: the
process and the builds, the verdict and its margin, the criteria judged, and the rest of the
verdict's sentence (what the builds keep, or why they do not). A line under the table counts the
designs that are ok and flagged.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FABKIT = [sys.executable, "-m", "fabkit"]


def run_tolerance(folder: Path) -> dict[str, dict]:
    """``tolerance.json`` of every bundled template, by template name, analysed into
    ``folder``."""
    templates = sorted((ROOT / "templates").glob("*.toml"))
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run(FABKIT + ["tolerance", *map(str, templates), "-o", str(folder), "-q"],
                          cwd=folder, env=env, capture_output=True, text=True)
    if proc.returncode not in (0, 1):  # 1: a design is flagged, which the table shows
        raise RuntimeError(f"fabkit tolerance exited {proc.returncode}: {proc.stderr[-2000:]}")
    results = {}
    for path in templates:
        report = folder / path.stem / "tolerance.json"
        if not report.is_file():
            raise RuntimeError(f"fabkit tolerance wrote no {report.name} for {path.name}: "
                               f"{proc.stderr[-2000:]}")
        results[path.stem] = json.loads(report.read_text())
    return results


def split_verdict(verdict: str) -> tuple[str, str]:
    """``"ok, margin 4.9: 100.0% of ..."`` → ``("ok, margin 4.9", "100.0% of ...")``: the
    level and margin, and the rest of the sentence."""
    m = re.match(r"([^:;]*)[:;]\s*(.*)", verdict, re.S)
    return (m.group(1).strip(), m.group(2).strip()) if m else (verdict.strip(), "")


def _process(report: dict) -> str:
    method = "" if report["method"] == "constructive" else f" ({report['method']})"
    return (f"{report['process']}, {report['scale_mm']:.3g} mm/unit, {report['samples']} "
            f"builds{method}")


def tolerance_table() -> str:
    """Markdown rows: every bundled design's tolerance verdict, and the count of ok and
    flagged designs."""
    with tempfile.TemporaryDirectory() as folder:
        results = run_tolerance(Path(folder))
    rows = ["| template | process | verdict | criteria | what the builds keep |",
            "|---|---|---|---|---|"]
    flagged = []
    for name, report in results.items():
        head, rest = split_verdict(report["verdict"])
        if report["flagged"]:
            flagged.append(name)
        criteria = ", ".join(report["behaviour"]["criteria"])
        rows.append(f"| `{name}` | {_process(report)} | {head} | {criteria} | {rest} |")
    rows += ["", f"{len(results) - len(flagged)} of the {len(results)} designs are ok, "
                 f"{len(flagged)} flagged ({', '.join(f'`{n}`' for n in flagged) or 'none'})."]
    return "\n".join(rows)


if __name__ == "__main__":
    print(tolerance_table())
