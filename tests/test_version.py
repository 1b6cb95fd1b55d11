"""``fabkit --version`` prints the package's version and exits 0."""

import subprocess
import sys

import fabkit


def test_version_prints_the_package_version():
    proc = subprocess.run([sys.executable, "-m", "fabkit.cli", "--version"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"fabkit {fabkit.__version__}"
