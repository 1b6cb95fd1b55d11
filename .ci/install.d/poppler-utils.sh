#!/usr/bin/env bash
# Optional: poppler (Debian package poppler-utils, ~1 MB) reads the assembly guide as a
# second PDF engine for tests/test_laser_guide.py: `pdftotext` finds every line on its page,
# `pdffonts` lists the embedded fonts. Without it (no root, no apt) the tests skip and say why.
set -euo pipefail
if command -v pdftotext >/dev/null; then exit 0; fi
command -v apt-get >/dev/null || { echo "apt-get not found: skipping poppler-utils"; exit 1; }
SUDO=""
if [ "$(id -u)" != 0 ]; then
  command -v sudo >/dev/null || { echo "not root and no sudo: skipping poppler-utils"; exit 1; }
  SUDO="sudo -n"
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get install -y --no-install-recommends poppler-utils >/dev/null \
  || { $SUDO apt-get update -qq && $SUDO apt-get install -y --no-install-recommends poppler-utils >/dev/null; }
command -v pdftotext >/dev/null
