#!/usr/bin/env bash
# Command 1 of the README: set up if needed (packages, Release build, workbench install),
# then run the main job on the bundled samples:
#   bash .ci/main.sh [OUT_DIR]        (default OUT_DIR: ./out)
# Writes OUT_DIR/strips/<sample>.result.json (the CLI's output), <sample>.png (charts),
# <sample>.dxf/.svg (cut sheets of the feasible designs) and
# OUT_DIR/strips.FCStd (a FreeCAD document with one strip feature per sample);
# OUT_DIR/rods/<sample>.result.json, <sample>.png (twist plots), <sample>.step (deformed and
# straight rod) and OUT_DIR/rods.FCStd (one Rod feature per sample) for samples/rods;
# OUT_DIR/optimizations/<job>/{optimized.step,history.json,history.png}: the shape optimization
# of samples/parts/<job>.step by samples/optimizations/<job>.json (the original stays unchanged).
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
build=${PARAFAB_BUILD_DIR:-$repo/build}
out=$(mkdir -p "${1:-$repo/out}" && cd "${1:-$repo/out}" && pwd)
# PARAFAB_SKIP_SETUP=1: the build exists already (the ctest `main_job` runs this script so that
# a sample that breaks the main job fails CI).
[ "${PARAFAB_SKIP_SETUP:-0}" = 1 ] || bash "$repo/.ci/setup.sh"

mkdir -p "$out/strips"
rm -f "$out"/strips/*.json "$out"/strips/*.png "$out"/strips/*.dxf "$out"/strips/*.svg
echo "== strips: parafab strip on samples/strips/*.json"
for f in "$repo"/samples/strips/*.json; do
  name=$(basename "$f" .json)
  cp "$f" "$out/strips/$name.request.json"
  "$build/workbench/entry/parafab" strip "$f" -o "$out/strips/$name.result.json"
done
/usr/bin/python3 "$repo/workbench/scripts/plot_strips.py" "$out/strips" >/dev/null
echo "== strips: cut sheets (DXF, SVG) of the feasible designs"
/usr/bin/python3 "$repo/workbench/scripts/export_cut_sheets.py" "$out/strips" "$build/workbench/entry"
echo "== FreeCAD document"
PARAFAB_RESULTS="$out/strips" PARAFAB_DOCUMENT="$out/strips.FCStd" \
  freecadcmd -c "exec(open('$repo/workbench/scripts/strip_document.py').read())" \
  >"$out/freecad.log" 2>&1 || { cat "$out/freecad.log"; exit 1; }
grep -E '^strip |^wrote' "$out/freecad.log" || true
test -s "$out/strips.FCStd"
echo "== rods: parafab rod on samples/rods/*.json (Kirchhoff rods, forward-simulated when validate)"
mkdir -p "$out/rods"
rm -f "$out"/rods/*.json "$out"/rods/*.png "$out"/rods/*.step
for f in "$repo"/samples/rods/*.json; do
  name=$(basename "$f" .json)
  cp "$f" "$out/rods/$name.request.json"
  "$build/workbench/entry/parafab" rod "$f" -o "$out/rods/$name.result.json"
  /usr/bin/python3 -c "import json,sys; d=json.load(open(sys.argv[1])); m=d.get('simulation') or {}
g=lambda x: '-' if x is None else '%.2e' % x
print('rod %-20s %-10s L %.3f m  R %s  max|twist| %.3g rad/m  load iterations %d  deviation/L %s  %.3f s' % (sys.argv[2], d['status'], d['length'], g(d['R']), max(map(abs, d.get('twist') or [0])), d['load_iterations']['iterations'], g(m.get('deviation')), d['diagnostics']['total_seconds']))" "$out/rods/$name.result.json" "$name"
done
for f in "$repo"/samples/rods/invalid/*.json; do  # kappa = 0: exit 2 and a JSON error naming s
  code=0; "$build/workbench/entry/parafab" rod "$f" >"$out/rods/invalid_$(basename "$f")" || code=$?
  [ "$code" -eq 2 ] || { echo "rod $(basename "$f"): expected exit 2, got $code"; exit 1; }
  echo "rod invalid/$(basename "$f" .json): exit 2, $(/usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['error']['message'][:90])" "$out/rods/invalid_$(basename "$f")")"
done
/usr/bin/python3 "$repo/workbench/scripts/plot_rods.py" "$out/rods" >/dev/null
PARAFAB_RESULTS="$out/rods" PARAFAB_DOCUMENT="$out/rods.FCStd" \
  freecadcmd -c "exec(open('$repo/workbench/scripts/rod_document.py').read())" \
  >"$out/freecad_rods.log" 2>&1 || { cat "$out/freecad_rods.log"; exit 1; }
grep -E '^rod |^wrote' "$out/freecad_rods.log" || true
test -s "$out/rods.FCStd"
echo "== parts: parafab inspect + integrate on samples/parts/*.step (cut-cell quadrature vs OCCT)"
mkdir -p "$out/parts"
rm -f "$out"/parts/*.json
for f in "$repo"/samples/parts/*.step; do
  name=$(basename "$f" .step)
  [ "$name" = two_blocks ] && continue  # holds two solids on purpose (tests of --solid)
  "$build/workbench/entry/parafab" inspect "$f" -o "$out/parts/$name.inspect.json"
  "$build/workbench/entry/parafab" integrate "$f" --cells 8 -o "$out/parts/$name.integrate.json"
  /usr/bin/python3 -c "import json,sys; d=json.load(open(sys.argv[1])); e=d['relative_errors']; g=d['grid']; s=d['seconds']
print('part %-11s %3d cut cells %4d subvolumes  errors V %.1e c %.1e I %.1e  cut %.2f s rules %.2f s' % (sys.argv[2], g['cut_cells'], g['subvolumes'], e['volume'], e['center'], e['inertia'], s['cut'], s['rules']))" "$out/parts/$name.integrate.json" "$name"
done
echo "== simulations: parafab simulate on samples/simulations/*.json (linear XFEM)"
for f in "$repo"/samples/simulations/*.json; do
  name=$(basename "$f" .json)
  "$build/workbench/entry/parafab" simulate "$repo/samples/parts/$name.step" "$f" -o "$out/simulations/$name" >/dev/null
  /usr/bin/python3 -c "import json,sys; d=json.load(open(sys.argv[1])); s=d['seconds']
print('simulation %-10s %6d dofs, max displacement %.4g, max von Mises %.4g, cut %.2f s rules %.2f s assemble %.2f s solve %.2f s' % (sys.argv[2], d['dofs'], d['max_displacement'], d['max_von_mises'], s['cut'], s['rules'], s['assemble'], s['solve']))" "$out/simulations/$name/result.json" "$name"
done
echo "== strips from sections: parafab sections on samples/sections/*.json"
mkdir -p "$out/sections"
for f in "$repo"/samples/sections/*.json; do
  name=$(basename "$f" .json)
  part=$(/usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['part'])" "$f")
  src="$repo/samples/parts/$part"; [ -f "$src" ] || src="$repo/samples/surfaces/$part"
  "$build/workbench/entry/parafab" sections "$src" "$f" -o "$out/sections/$name.result.json"
  /usr/bin/python3 -c "import json,sys; d=json.load(open(sys.argv[1]))
print('sections %-10s %d curves: %d designed, %d infeasible, %d failed; R %s' % (sys.argv[2], len(d['curves']), d['designed'], d['infeasible'], d['failed'], ['%.4f' % c['strip']['R'] for c in d['curves'] if c['strip'].get('feasible')]))" "$out/sections/$name.result.json" "$name"
done
echo "== surfaces of revolution: parafab revolution on samples/revolution/*.json"
mkdir -p "$out/revolution"
for f in "$repo"/samples/revolution/*.json; do
  name=$(basename "$f" .json)
  "$build/workbench/entry/parafab" revolution "$f" -o "$out/revolution/$name.result.json"
  /usr/bin/python3 -c "import json,sys; d=json.load(open(sys.argv[1])); m=d['meridian']; s=d['strips']
print('revolution %-8s meridian complete=%s residual %.1e, %d strips, R %.4f' % (sys.argv[2], m['complete'], m['residual'], s['count'], s['R']))" "$out/revolution/$name.result.json" "$name"
done
echo "== shape optimization: parafab optimize on samples/optimizations/*.json (part: samples/parts/<name>.step)"
mkdir -p "$out/optimizations"
for f in "$repo"/samples/optimizations/*.json; do
  name=$(basename "$f" .json)
  part="$repo/samples/parts/$name.step"
  before=$(sha256sum "$part" | cut -d' ' -f1)
  rm -rf "$out/optimizations/$name"
  "$build/workbench/entry/parafab" optimize "$part" "$f" -o "$out/optimizations/$name" >"$out/optimizations/$name.stdout.json" \
    || { echo "optimize $name failed:"; cat "$out/optimizations/$name.stdout.json"; exit 1; }
  [ "$(sha256sum "$part" | cut -d' ' -f1)" = "$before" ] || { echo "optimize $name: the original part changed"; exit 1; }
  for file in optimized.step history.json history.png; do
    [ -s "$out/optimizations/$name/$file" ] || { echo "optimize $name: $out/optimizations/$name/$file is missing or empty"; exit 1; }
  done
  /usr/bin/python3 -c "import json,sys; h=json.load(open(sys.argv[1])); n=len(h['iterations']) - 1  # iterate 0 is the start
print('optimize %-8s %s: J %.4g -> %.4g (%+.1f %%), max von Mises %.1f -> %.1f MPa, V/V0 %.4f, %d iterations, %.2f s/iteration, tangency residual %.1e' % (sys.argv[2], h['status'], h['initial_objective'], h['final_objective'], 100 * (h['final_objective'] / h['initial_objective'] - 1), h['initial_max_von_mises'], h['final_max_von_mises'], h['final_volume'] / h['initial_volume'], n, h['seconds'] / max(n, 1), h['tangency_residual_max']))
for p in h['parameters']: print('    %-28s %8.4f -> %8.4f' % (p['name'], p['initial'], p['final']))
bad = [w for w, ok in [('status %r is not a normal stop' % h['status'], h['status'] in ('converged', 'max_iterations')),
                       ('the objective did not fall', h['final_objective'] < h['initial_objective']),
                       ('V/V0 above 1', h['final_volume'] <= h['initial_volume'] * (1 + 1e-3)),
                       ('no history chart', bool(h.get('chart')))] if not ok]
sys.exit('optimize %s: %s' % (sys.argv[2], '; '.join(bad)) if bad else 0)" "$out/optimizations/$name/history.json" "$name"
done
echo "== results in $out: strips/*.result.json, strips/*.png, strips/*.{dxf,svg}, strips.FCStd, rods/*.result.json, rods/*.png, rods/*.step, rods.FCStd, parts/*.inspect.json, parts/*.integrate.json, simulations/*/result.{json,vtu}, sections/*.result.json, revolution/*.result.json, optimizations/*/{optimized.step,history.json,history.png}"
