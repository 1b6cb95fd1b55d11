#!/usr/bin/env bash
# Optional: LibreCAD (Debian package, ~24 packages with Qt) gives `librecad dxf2pdf`, a headless
# third-party DXF reader used by tests/test_laser_thirdparty.py to open fabkit's laser-cut DXF
# files. Without it (no root, no apt) the test skips and says why.
set -euo pipefail
if command -v librecad >/dev/null; then exit 0; fi
command -v apt-get >/dev/null || { echo "apt-get not found: skipping LibreCAD"; exit 1; }
SUDO=""
if [ "$(id -u)" != 0 ]; then
  command -v sudo >/dev/null || { echo "not root and no sudo: skipping LibreCAD"; exit 1; }
  SUDO="sudo -n"
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get install -y --no-install-recommends librecad >/dev/null \
  || { $SUDO apt-get update -qq && $SUDO apt-get install -y --no-install-recommends librecad >/dev/null; }
command -v librecad >/dev/null
