#!/usr/bin/env bash
# Optional: Chromium (Debian package), driven by Playwright's Python client (a test extra in
# pyproject.toml, installed with the venv) against the system browser. tests/test_report_html.py opens report.html / index.html in headless Chromium, checks
# the console, drags the motion slider and saves a screenshot. Without them the test skips and
# says why.
set -euo pipefail
if ! command -v chromium >/dev/null; then
  command -v apt-get >/dev/null || { echo "apt-get not found: skipping Chromium"; exit 1; }
  SUDO=""
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null || { echo "not root and no sudo: skipping Chromium"; exit 1; }
    SUDO="sudo -n"
  fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get install -y --no-install-recommends chromium >/dev/null \
    || { $SUDO apt-get update -qq && $SUDO apt-get install -y --no-install-recommends chromium >/dev/null; }
fi
command -v chromium >/dev/null
