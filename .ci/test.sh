#!/usr/bin/env bash
# Command 2 of the README: set up if needed, then run every test through ctest
# (GoogleTest suites, Python checks against scipy, FreeCADCmd tests, GUI smoke test).
#   bash .ci/test.sh
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
build=${PARAFAB_BUILD_DIR:-$repo/build}
bash "$repo/.ci/setup.sh"
cd "$build"
ctest --output-on-failure --timeout 900 -j2
