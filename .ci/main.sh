#!/usr/bin/env bash
# Command 1 of the README: set up if needed (packages, Release build, workbench install),
# then run the main job on the bundled samples:
#   bash .ci/main.sh [OUT_DIR]        (default OUT_DIR: ./out)
# Writes OUT_DIR/strips/<sample>.result.json (the CLI's output), <sample>.png (charts) and
# OUT_DIR/strips.FCStd (a FreeCAD document with one strip feature per sample).
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
build=${PARAFAB_BUILD_DIR:-$repo/build}
out=$(mkdir -p "${1:-$repo/out}" && cd "${1:-$repo/out}" && pwd)
bash "$repo/.ci/setup.sh"

mkdir -p "$out/strips"
rm -f "$out"/strips/*.json "$out"/strips/*.png
echo "== strips: parafab strip on samples/strips/*.json"
for f in "$repo"/samples/strips/*.json; do
  name=$(basename "$f" .json)
  cp "$f" "$out/strips/$name.request.json"
  "$build/workbench/entry/parafab" strip "$f" -o "$out/strips/$name.result.json"
done
/usr/bin/python3 "$repo/workbench/scripts/plot_strips.py" "$out/strips" >/dev/null
echo "== FreeCAD document"
PARAFAB_RESULTS="$out/strips" PARAFAB_DOCUMENT="$out/strips.FCStd" \
  freecadcmd -c "exec(open('$repo/workbench/scripts/strip_document.py').read())" \
  >"$out/freecad.log" 2>&1 || { cat "$out/freecad.log"; exit 1; }
grep -E '^strip |^wrote' "$out/freecad.log" || true
test -s "$out/strips.FCStd"
echo "== results in $out: strips/*.result.json, strips/*.png, strips.FCStd"
