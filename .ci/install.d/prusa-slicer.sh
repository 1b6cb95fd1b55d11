#!/usr/bin/env bash
# Optional: PrusaSlicer (Debian package prusa-slicer, ~100 MB with its libraries) gives a real
# slicer's command line for tests/test_print_slicer.py: `prusa-slicer --info` reads fabkit's STL
# files and `--export-gcode` slices them. Without it (no root, no apt) the test skips and says why.
set -euo pipefail
if command -v prusa-slicer >/dev/null; then exit 0; fi
command -v apt-get >/dev/null || { echo "apt-get not found: skipping PrusaSlicer"; exit 1; }
SUDO=""
if [ "$(id -u)" != 0 ]; then
  command -v sudo >/dev/null || { echo "not root and no sudo: skipping PrusaSlicer"; exit 1; }
  SUDO="sudo -n"
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get install -y --no-install-recommends prusa-slicer >/dev/null \
  || { $SUDO apt-get update -qq && $SUDO apt-get install -y --no-install-recommends prusa-slicer >/dev/null; }
command -v prusa-slicer >/dev/null
