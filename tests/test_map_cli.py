"""``fabkit map``: files written, JSON summaries of the paper's modules, one-line errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from fabkit.cli import main

TEMPLATES = Path(__file__).resolve().parents[1] / "templates"
PNG = b"\x89PNG\r\n\x1a\n"


def _run(tmp_path, *args):
    return main(["map", *map(str, args), "-o", str(tmp_path)])


def test_period_two_summary_states_the_papers_claims(tmp_path, capsys):
    assert _run(tmp_path, TEMPLATES / "period_two.toml") == 0
    folder = tmp_path / "period_two"
    for name in ("map.png", "cobweb.png"):
        assert (folder / name).read_bytes().startswith(PNG)
    s = json.loads((folder / "map.json").read_text())
    assert s["source"] == "constructive"
    (fp,) = s["fixed_points"]
    assert fp["value"] == pytest.approx(math.sqrt(3), abs=1e-12) and fp["kind"] == "unstable"
    (cyc,) = s["cycles"]
    assert cyc["period"] == 2 and cyc["kind"] == "stable" and abs(cyc["multiplier"]) < 1
    assert len(s["cobweb"]) >= 2 and all(len(c["orbit"]) == 17 for c in s["cobweb"])
    out = capsys.readouterr().out
    assert "2-cycle" in out and "(stable)" in out


def test_chaotic_summary_has_positive_lyapunov_exponent(tmp_path):
    rc = _run(tmp_path, TEMPLATES / "chaotic.toml", "--lyapunov", "--orbits", "50",
              "--discard", "500", "--average", "2000", "--d1", "0.76,0.761")
    assert rc == 0
    s = json.loads((tmp_path / "chaotic" / "map.json").read_text())
    assert 0.28 < s["lyapunov"]["mean"] < 0.34
    assert s["lyapunov"]["orbits"] == 50 and s["lyapunov"]["escaped"] == 0
    assert [p["kind"] for p in s["fixed_points"]] == ["unstable"]
    assert s["cycles"][0]["kind"] == "unstable"
    assert any("chaotic" in c for c in s["claims"])
    assert (tmp_path / "chaotic" / "lyapunov.png").read_bytes().startswith(PNG)
    assert [c["d1"] for c in s["cobweb"]] == [0.76, 0.761]


def test_designed_template_writes_its_solution_spaces(tmp_path):
    assert _run(tmp_path, TEMPLATES / "fixed_point.toml", "--steps", "8") == 0
    folder = tmp_path / "fixed_point"
    assert (folder / "design.png").read_bytes().startswith(PNG)
    s = json.loads((folder / "map.json").read_text())
    assert s["design"]["meets"] == {"velocity": True, "displacement": True}
    values = [p["value"] for p in s["fixed_points"]]
    assert values == pytest.approx([math.sqrt(3), 1.7 * math.sqrt(3)], abs=1e-9)


def test_identical_input_gives_identical_json(tmp_path):
    assert _run(tmp_path / "a", TEMPLATES / "fourbar.toml") == 0
    assert _run(tmp_path / "b", TEMPLATES / "fourbar.toml") == 0
    a = (tmp_path / "a" / "fourbar" / "map.json").read_text()
    claims = json.loads(a)["claims"]
    assert claims[0] == "f^2(d) = d on the whole branch: every d1 lies on a 2-cycle"
    b = (tmp_path / "b" / "fourbar" / "map.json").read_text().replace(str(tmp_path / "b"),
                                                                         str(tmp_path / "a"))
    assert a == b


@pytest.mark.parametrize("args,match,code", [
    (["--d1", "abc"], "--d1: 'abc' is not a number", 2),
    (["--d1", "9.5"], "--d1 9.5 is outside the map's domain", 1),
    (["--steps", "0"], "--steps: must be at least 1", 2),
    (["--period", "1"], "--period: must be at least 2", 2),
    (["--d-out", "d7"], "no port 'd7'", 1),
])
def test_bad_arguments_fail_with_one_line_and_write_nothing(tmp_path, capsys, args, match, code):
    rc = _run(tmp_path, TEMPLATES / "period_two.toml", *args)
    assert rc == code
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and match in err and "Traceback" not in err
    assert not (tmp_path / "period_two").exists()


def test_missing_template(tmp_path, capsys):
    assert _run(tmp_path, tmp_path / "nope.toml") == 1
    assert "no such file" in capsys.readouterr().err
