#!/bin/bash
# Run the headless FreeCAD tests of the ParaFab workbench (strip, rod, analysis features, optimize shape).
#
# Usage: tests/freecad/run_tests.sh [BUILD_DIR]      (default: <repo>/build)
#
# Uses the workbench sources from the repository and the solver module
# parafab*.so from BUILD_DIR/workbench/entry (override with
# PARAFAB_MODULE_DIR / PARAFAB_WB_DIR).  FreeCAD runs with a throw-away HOME
# so that an installed copy of the workbench or user settings cannot
# interfere.  Exits non-zero when a test fails or FreeCAD crashes/times out.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
build_dir=${1:-$repo/build}
timeout_s=${PARAFAB_TEST_TIMEOUT:-600}

export PARAFAB_MODULE_DIR=${PARAFAB_MODULE_DIR:-$build_dir/workbench/entry}
export PARAFAB_WB_DIR=${PARAFAB_WB_DIR:-$repo/workbench/freecad/ParaFab}
export PYTHONDONTWRITEBYTECODE=1  # keep the source tree free of __pycache__
if ! compgen -G "$PARAFAB_MODULE_DIR/parafab*" >/dev/null; then
    echo "run_tests.sh: no parafab module in $PARAFAB_MODULE_DIR (build first)" >&2
    exit 2
fi

tmp_home=$(mktemp -d "${TMPDIR:-/tmp}/parafab_home.XXXXXX")
trap 'rm -rf "$tmp_home"' EXIT

echo "run_tests.sh: solver from $PARAFAB_MODULE_DIR, workbench from $PARAFAB_WB_DIR"
status=0
for module in test_strip_feature test_rod_feature test_analysis_feature test_strip_improve test_strip_stabilize test_optimize_feature; do
    HOME=$tmp_home PYTHONPATH="$here${PYTHONPATH:+:$PYTHONPATH}" \
        timeout "$timeout_s" freecadcmd -t "$module" || { status=$?; break; }
done
if [ "$status" -eq 124 ]; then
    echo "run_tests.sh: FAILED (timeout after ${timeout_s}s)" >&2
elif [ "$status" -ne 0 ]; then
    echo "run_tests.sh: FAILED (freecadcmd exit status $status)" >&2
else
    echo "run_tests.sh: all tests passed"
fi
exit "$status"
