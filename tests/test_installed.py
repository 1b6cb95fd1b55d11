"""fabkit as users install it: the wheel, the sdist and an editable install, each in a fresh venv,
run from elsewhere.

``python -m build`` builds the wheel and the sdist from a copy of this checkout (no warning may
come from the project's metadata); each, and the copy itself as an editable install (``pip
install -e``, whose output must be free of deprecation warnings too), is installed with ``pip
--no-deps`` into a new venv under a temporary folder, and the smoke test runs the installed
``fabkit`` from a folder outside the repo: the bundled templates, an export and an as-built check
by name, letters, the quick bench's stability study (once, from the wheel: the other installs
reach the same bundled templates through the commands before it; the bench's other parts are
tests/test_bench.py's), the copy of a bundled design, and the Python API. The new venv gets the dependencies (numpy, scipy, ...) of the environment running the tests
through a folder of links to them, which leaves out fabkit's own editable install, so nothing
heavy is downloaded; building needs setuptools from the package index (build isolation). About
50 s on a quiet 2-core machine.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import zipfile
from pathlib import Path

import pytest

import fabkit

pytestmark = pytest.mark.install

ROOT = Path(__file__).resolve().parents[1]

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: What is not copied from the checkout before building (generated or local files).
NOT_COPIED = (".git", ".venv", "out", "build", "dist", "*.egg-info", "__pycache__",
              ".pytest_cache", ".hypothesis")

#: Entries of the test environment's site-packages that the new venvs must not see: fabkit's own
#: (editable) install, and the packaging tools each venv has its own copy of.
NOT_LINKED = ("fabkit", "__editable__", "_distutils_hack", "distutils-precedence", "pip",
              "setuptools", "pkg_resources", "_virtualenv", "__pycache__")


def _run(cmd, cwd, env=None, timeout=600) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)
    assert proc.returncode == 0, (f"{' '.join(map(str, cmd))} exited {proc.returncode}\n"
                                  f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


def _clean_env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "PYTHONSTARTUP",
                        "PYTHONDONTWRITEBYTECODE", "FABKIT_ALLOW_LARGE")}
    env.update(PIP_DISABLE_PIP_VERSION_CHECK="1", MPLBACKEND="Agg", **extra)
    return env


@pytest.fixture(scope="module")
def dist(tmp_path_factory):
    """The sdist and the wheel built from a copy of this checkout, and the build's output."""
    work = tmp_path_factory.mktemp("dist")
    src = work / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(*NOT_COPIED), symlinks=True)
    proc = _run([sys.executable, "-m", "build", "--outdir", work / "dist", src], cwd=work,
                env=_clean_env())
    wheels = sorted((work / "dist").glob("fabkit-*.whl"))
    sdists = sorted((work / "dist").glob("fabkit-*.tar.gz"))
    assert len(wheels) == 1 and len(sdists) == 1, sorted((work / "dist").iterdir())
    return {"wheel": wheels[0], "sdist": sdists[0], "src": src, "log": proc.stdout + proc.stderr}


@pytest.fixture(scope="module")
def deps(tmp_path_factory) -> Path:
    """A folder of links to this environment's installed packages, without fabkit itself."""
    site = Path(sysconfig.get_paths()["purelib"])
    folder = tmp_path_factory.mktemp("deps")
    for entry in site.iterdir():
        if entry.name.startswith(NOT_LINKED) or entry.suffix == ".pth":
            continue
        (folder / entry.name).symlink_to(entry)
    assert (folder / "numpy").exists() and not any(folder.glob("fabkit*"))
    return folder


def _bundled_files() -> set[str]:
    top = {p.name for p in (ROOT / "templates").glob("*.toml")}
    sweeps = {f"sweeps/{p.name}" for p in (ROOT / "templates" / "sweeps").glob("*.toml")}
    curves = {f"curves/{p.name}" for p in (ROOT / "templates" / "curves").glob("*.csv")}
    return top | sweeps | curves


def test_pyproject_lists_every_package():
    # automatic discovery is off (a package is mapped onto templates/), so a new package under
    # fabkit/ must be added to [tool.setuptools] packages by hand
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "fabkit").rglob("__init__.py")}
    assert set(config["packages"]) == found | {"fabkit.bundled_templates",
                                               "fabkit.bundled_templates.curves",
                                               "fabkit.bundled_templates.sweeps"}
    assert config["package-dir"] == {"fabkit.bundled_templates": "templates"}


def test_the_build_is_clean_and_ships_everything(dist):
    log = dist["log"]
    noisy = [ln for ln in log.splitlines() if "warn" in ln.lower() or "deprecat" in ln.lower()]
    assert noisy == [], "\n".join(noisy)
    with zipfile.ZipFile(dist["wheel"]) as zf:
        names = set(zf.namelist())
        metadata = zf.read(f"fabkit-{fabkit.__version__}.dist-info/METADATA").decode()
    code = {p.relative_to(ROOT).as_posix() for p in (ROOT / "fabkit").rglob("*.py")}
    data = {f"fabkit/bundled_templates/{n}" for n in _bundled_files()}
    shipped = {n for n in names if ".dist-info/" not in n}
    assert shipped == code | data | {"fabkit/py.typed", "fabkit/bundled_templates/__init__.py"}
    assert len(data) == 36  # 30 templates, 2 sweeps, 4 curves
    headers = dict(line.split(": ", 1) for line in metadata.split("\n\n")[0].splitlines()
                   if ": " in line)
    assert headers["Version"] == fabkit.__version__  # the version lives in fabkit/__init__.py
    assert headers["License-Expression"] == "MIT" and "License" not in headers
    with tarfile.open(dist["sdist"]) as tf:
        members = {m.name.split("/", 1)[1] for m in tf.getmembers() if m.isfile()}
    assert {f"templates/{n}" for n in _bundled_files()} <= members
    assert {"pyproject.toml", "README.md", "fabkit/py.typed"} | code <= members


@pytest.mark.parametrize("kind", ["wheel", "sdist", "editable"])
def test_the_installed_package_runs_from_another_folder(dist, deps, tmp_path, kind):
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", venv], cwd=tmp_path, env=_clean_env())
    python = venv / "bin" / "python"
    site = Path(_run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                     cwd=tmp_path, env=_clean_env()).stdout.strip())
    (site / "fabkit_test_deps.pth").write_text(f"{deps}\n")
    # a wheel installs offline; an sdist or a folder is built first, with setuptools from the index
    what = {"wheel": ["--no-index", dist["wheel"]], "sdist": [dist["sdist"]],
            "editable": ["--verbose", "-e", dist["src"]]}[kind]
    pip = _run([python, "-m", "pip", "install", "--no-deps", *what], cwd=tmp_path,
               env=_clean_env())
    assert "deprecat" not in (pip.stdout + pip.stderr).lower()
    here = tmp_path / "elsewhere"
    here.mkdir()
    env = _clean_env(PATH=f"{venv / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}")
    code = dist["src"] / "fabkit" if kind == "editable" else site / "fabkit"
    bundled = dist["src"] / "templates" if kind == "editable" else code / "bundled_templates"

    def fabkit_cli(*args, timeout=600):
        return _run([venv / "bin" / "fabkit", *args], cwd=here, env=env, timeout=timeout)

    # the Python API, from the installed files
    api = _run([python, "-c", (
        "import importlib.metadata as md, importlib.resources as r, fabkit\n"
        "from fabkit.templates import bundled_folder\n"
        "d = fabkit.load_template('fourbar')\n"
        "print(fabkit.__file__, bundled_folder(), d.path, d.network.n_nodes, sep='\\n')\n"
        "print(md.version('fabkit'), fabkit.__version__, r.files('fabkit').joinpath('py.typed')"
        ".is_file())")], cwd=here, env=env).stdout.splitlines()
    assert api == [str(code / "__init__.py"), str(bundled),
                   str(bundled / "fourbar.toml"), "4",
                   f"{fabkit.__version__} {fabkit.__version__} True"]

    listing = fabkit_cli("templates").stdout.splitlines()
    assert listing[0] == f"30 bundled templates in {bundled}:"
    assert len(listing) == 32 and not [ln for ln in listing if "(invalid" in ln]

    fabkit_cli("export", "super_stable", "--to", "dxf", "-o", "out", "--quiet")
    sheet = here / "out" / "super_stable" / "laser_sheet1.dxf"
    report = json.loads(fabkit_cli("check", sheet, "--design", "super_stable", "--json").stdout)
    assert [v["ok"] for v in report.values()] == [True]

    fabkit_cli("letters", "NO")
    fit = json.loads((here / "out" / "letters" / "no_fit.json").read_text())
    assert [row["letter"] for row in fit["letters"]] == ["N", "O"]
    assert max(row["max_edge_error"] for row in fit["letters"]) < 1e-9
    assert max(row["rms_error"] for row in fit["letters"]) < 0.05

    if kind == "wheel":  # the bench once, its stability study (the other parts: test_bench.py)
        fabkit_cli("bench", "--quick", "--parts", "stability", timeout=900)
        bench = json.loads((here / "out" / "bench" / "bench.json").read_text())
        flat = next(r for r in bench["stability"]["rows"]
                    if r["case"] == "fourbar_flat" and r["method"] == "constructive")
        assert flat["status"] == "turning_point"
        assert flat["stop_drive"] == pytest.approx(2 * 2 ** 0.5 - 2, abs=1e-9)

    fabkit_cli("templates", "--copy", "super_stable_chain", "mine")
    assert sorted(p.name for p in (here / "mine").iterdir()) == ["super_stable.toml",
                                                                 "super_stable_chain.toml"]
    assert "nodes, edges  74, 144" in fabkit_cli("info", "mine/super_stable_chain.toml").stdout
