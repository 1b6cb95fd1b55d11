#!/usr/bin/env bash
# Optional: the `fold` npm library (the FOLD format's reference reader), used by
# tests/test_origami_export.py to load fabkit's FOLD files from node. Installed into
# out/.node-fold (git-ignored); without node the test skips and says why.
set -euo pipefail
cd "$(dirname "$0")/../.."
command -v node >/dev/null || { echo "node not found: skipping the fold library"; exit 1; }
command -v npm >/dev/null || { echo "npm not found: skipping the fold library"; exit 1; }
mkdir -p out/.node-fold
npm install --prefix out/.node-fold --no-audit --no-fund --silent fold@0.12.0
test -f out/.node-fold/node_modules/fold/package.json
