"""`fabkit info` on large networks: counts without a dense matrix, a dense path that cannot fit
is refused."""

from pathlib import Path

import pytest
import scipy.sparse

from fabkit.model import matrix, rigidity
from fabkit.cli import main
from fabkit.errors import ResourceError

ROOT = Path(__file__).resolve().parents[1]


def chain_template(tmp_path, copies, mirror=False):
    path = tmp_path / f"chain{copies}{'m' if mirror else ''}.toml"
    path.write_text(
        f'name = "chain{copies}"\ndescription = "super-stable chain"\n'
        f'[chain]\nmodule = "{(ROOT / "templates" / "super_stable.toml").as_posix()}"\n'
        f'copies = {copies}\n' + ('mirror = "alternate"\n' if mirror else '')
        + '[motion]\ndrive = "d1"\nto = 1.2\n'
    )
    return path


def test_info_counts_a_ten_thousand_module_chain(tmp_path, capsys, dense_copies):
    path = chain_template(tmp_path, 10_000)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "nodes, edges  30002, 60000" in out
    assert "4 zero modes = 3 rigid + 1 conformational; 0 state(s) of self-stress" in out
    assert "sparse" in out and "ambiguous" not in out
    # counted without a dense copy of the 60000 × 60004 matrix (what would take minutes)
    assert not [s for s in dense_copies if max(s) > 1000], dense_copies


def test_info_refuses_a_dense_path_that_cannot_fit(tmp_path, capsys, monkeypatch):
    path = chain_template(tmp_path, 10_000)
    calls = []
    monkeypatch.setattr(scipy.sparse.csr_matrix, "toarray",
                        lambda self, *a, **k: calls.append(self.shape))
    assert main(["info", "--rank-method", "dense", str(path)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith("fabkit: error: a dense SVD of the 60000 × 60004 rigidity matrix needs")
    assert calls == []  # refused before the dense matrix was made


def test_dense_memory_check_uses_the_available_memory(monkeypatch):
    monkeypatch.setattr(matrix, "available_memory", lambda: 10**6)
    assert matrix.require_dense_memory(100, 100) < 10**6
    with pytest.raises(ResourceError):
        matrix.require_dense_memory(1000, 1000)
    net = rigidity.Network([[0, 0], [1, 0], [0, 1]] * 1, [[0, 1], [1, 2], [0, 2]])
    assert rigidity.count_modes(net).total == 3
    with pytest.raises(ValueError):
        rigidity.count_modes(net, method="qr")


def test_info_proves_the_counts_of_a_hundred_thousand_module_chain(tmp_path, capsys):
    path = chain_template(tmp_path, 100_000, mirror=True)
    assert main(["--allow-large", "info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "nodes, edges  300002, 600000" in out
    assert "modes         4 zero modes = 3 rigid + 1 conformational; 0 state(s) of self-stress" in out
    assert ("certificate   structure: every node placed by transversal intersections from d1; "
            "no extra bars; margin (smallest intersection sine) 0.866") in out
    assert "rank gap      not measured (numeric cross-check not run: 600004 coordinates" in out
    assert "ambiguous" not in out and "constructive  yes" in out


def test_info_says_where_the_numeric_rank_alone_cannot_decide(tmp_path, capsys):
    path = chain_template(tmp_path, 10_000, mirror=True)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "certificate   structure: " in out and "ambiguous" not in out
    assert "cross-check   numeric rank undecided: the bounds " in out
    assert main(["info", "--rank-method", "sparse", str(path)]) == 0
    assert "ambiguous rank (the bounds " in capsys.readouterr().out
