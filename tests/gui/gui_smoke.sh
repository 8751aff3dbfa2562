#!/bin/bash
# GUI smoke test of the ParaFab workbench under Xvfb.
#
# Usage: tests/gui/gui_smoke.sh [BUILD_DIR]            (default: <repo>/build)
#
# Installs the workbench (tests/freecad/install_wb.sh) into a throw-away HOME,
# runs FreeCAD on gui_smoke_macro.py under xvfb-run and checks the status
# file written by the macro (also runs "Plot strip profile").  Artifacts (status.json, strip.png, analysis.png, analysis_panel.png,
# optimize_panel_open.png, optimize_panel.png, optimize.png, optimize_out/, gui_smoke.FCStd, gui_smoke_analysis.FCStd, gui_smoke_analysis_legacy.FCStd, analysis_out/, freecad.log) go to
# $PARAFAB_ARTIFACT_DIR
# (default: BUILD_DIR/gui-artifacts).  Timeout: $PARAFAB_GUI_TIMEOUT
# seconds (default 180).  Exits non-zero on failure or timeout.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
build_dir=$(cd "${1:-$repo/build}" && pwd)
timeout_s=${PARAFAB_GUI_TIMEOUT:-180}
artifacts=${PARAFAB_ARTIFACT_DIR:-$build_dir/gui-artifacts}
mkdir -p "$artifacts"
artifacts=$(cd "$artifacts" && pwd)
rm -rf "$artifacts/status.json" "$artifacts/strip.png" "$artifacts/gui_smoke.FCStd" \
       "$artifacts/analysis.png" "$artifacts/analysis_panel.png" "$artifacts/gui_smoke_analysis.FCStd" "$artifacts/gui_smoke_analysis_legacy.FCStd" "$artifacts/analysis_out" \
       "$artifacts/optimize_panel.png" "$artifacts/optimize_panel_open.png" "$artifacts/optimize.png" "$artifacts/optimize_out"

tmp_home=$(mktemp -d "${TMPDIR:-/tmp}/parafab_gui_home.XXXXXX")
trap 'rm -rf "$tmp_home"' EXIT

FREECAD_MOD_DIR=$tmp_home/.local/share/FreeCAD/Mod \
    "$repo/tests/freecad/install_wb.sh" "$build_dir"

# QTWEBENGINE_DISABLE_SANDBOX: the Start page's web view refuses to run as
# root otherwise, and FreeCAD then aborts.
status=0
HOME=$tmp_home \
QTWEBENGINE_DISABLE_SANDBOX=1 \
PYTHONDONTWRITEBYTECODE=1 \
PARAFAB_ARTIFACT_DIR=$artifacts \
PARAFAB_SAMPLES_DIR=$repo/samples \
    timeout --kill-after=10 "$timeout_s" \
    xvfb-run -a -s "-screen 0 1280x1024x24" \
    freecad "$here/gui_smoke_macro.py" >"$artifacts/freecad.log" 2>&1 || status=$?

if [ "$status" -eq 124 ] || [ "$status" -eq 137 ]; then
    echo "gui_smoke.sh: FAILED (timeout after ${timeout_s}s), log: $artifacts/freecad.log" >&2
    exit 1
fi
if [ ! -f "$artifacts/status.json" ]; then
    echo "gui_smoke.sh: FAILED (no status file, FreeCAD exit status $status)," \
         "log: $artifacts/freecad.log" >&2
    tail -n 20 "$artifacts/freecad.log" >&2
    exit 1
fi
cat "$artifacts/status.json"
echo
if [ "$status" -ne 0 ] || ! grep -q '"status": "pass"' "$artifacts/status.json"; then
    echo "gui_smoke.sh: FAILED (FreeCAD exit status $status), artifacts in $artifacts" >&2
    exit 1
fi
echo "gui_smoke.sh: passed, screenshots: $artifacts/strip.png $artifacts/analysis.png"
