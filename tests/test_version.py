"""``fabkit --version`` prints the package's version and exits 0."""

import subprocess
import sys

import fabkit


def test_version_prints_the_package_version():
    proc = subprocess.run([sys.executable, "-m", "fabkit.cli", "--version"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"fabkit {fabkit.__version__}"


def test_python_dash_m_fabkit_is_the_command_line(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "fabkit", "--version"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"fabkit {fabkit.__version__}"
    # and its errors are the command line's: one line, exit code 1, no traceback
    proc = subprocess.run([sys.executable, "-m", "fabkit", "info", str(tmp_path / "none.toml")],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines() == [f"fabkit: error: {tmp_path / 'none.toml'}: no such file"]
