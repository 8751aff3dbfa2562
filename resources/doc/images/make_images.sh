#!/bin/bash
# The README's pictures, screenshots of the FreeCAD workbench under Xvfb:
#   strip.png     the GUI smoke test's strip (a sketch B-spline; the bent and the flat strip)
#   analysis.png  its "Analyze part" on the L-bracket: deformed, coloured by von Mises stress
#   rod.png       a Kirchhoff rod on samples/rods/helix.json (images_macro.py)
#   optimize.png  the main job's wrench optimization (samples/optimizations/wrench.json): the
#                 original beside the optimized solid the workbench adds, faces coloured by how
#                 far they moved (images_macro.py)
#
# Usage: resources/doc/images/make_images.sh [BUILD_DIR]      (default: <repo>/build)
#
# Runs tests/gui/gui_smoke.sh (it must pass), `parafab optimize` on the wrench, and
# images_macro.py the way the smoke test runs its macro (the workbench installed into a
# throw-away HOME, freecad under xvfb-run). Then crops the white border, scales each screenshot
# to at most 800 px wide and quantizes it (Debian's python3-pil), so each PNG stays under 150 kB
# (tests/docs/test_docs.py checks that). About a minute.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../../.." && pwd)
build_dir=$(cd "${1:-$repo/build}" && pwd)
timeout_s=${PARAFAB_GUI_TIMEOUT:-180}
work=$(mktemp -d "${TMPDIR:-/tmp}/parafab_images.XXXXXX")
trap 'rm -rf "$work"' EXIT

echo "== GUI smoke test (strip, analysis)"
PARAFAB_ARTIFACT_DIR=$work/gui bash "$repo/tests/gui/gui_smoke.sh" "$build_dir" >"$work/gui_smoke.out" 2>&1 || {
    cat "$work/gui_smoke.out" >&2; exit 1; }
tail -n 1 "$work/gui_smoke.out"

echo "== parafab optimize on the wrench (the main job's optimization)"
"$build_dir/workbench/entry/parafab" optimize "$repo/samples/parts/wrench.step" \
    "$repo/samples/optimizations/wrench.json" -o "$work/wrench" >/dev/null

echo "== rod and optimized wrench (images_macro.py)"
mkdir -p "$work/macro" "$work/home"
FREECAD_MOD_DIR=$work/home/.local/share/FreeCAD/Mod bash "$repo/tests/freecad/install_wb.sh" "$build_dir"
status=0
HOME=$work/home QTWEBENGINE_DISABLE_SANDBOX=1 PYTHONDONTWRITEBYTECODE=1 \
PARAFAB_ARTIFACT_DIR=$work/macro PARAFAB_SAMPLES_DIR=$repo/samples PARAFAB_WRENCH_OUT=$work/wrench \
    timeout --kill-after=10 "$timeout_s" \
    xvfb-run -a -s "-screen 0 1280x1024x24" \
    freecad "$here/images_macro.py" >"$work/macro/freecad.log" 2>&1 || status=$?
if [ "$status" -ne 0 ] || ! grep -q '"status": "pass"' "$work/macro/images_status.json" 2>/dev/null; then
    echo "make_images.sh: images_macro.py failed (FreeCAD exit status $status)" >&2
    cat "$work/macro/images_status.json" >&2 2>/dev/null || tail -n 20 "$work/macro/freecad.log" >&2
    exit 1
fi

echo "== crop, scale, write into $here"
/usr/bin/python3 - "$here" "$work/gui/strip.png" "$work/gui/analysis.png" "$work/macro/rod.png" \
    "$work/macro/optimize.png" <<'PY'
import os
import sys

from PIL import Image, ImageChops

out_dir, paths = sys.argv[1], sys.argv[2:]
WIDTH, LIMIT, MARGIN = 800, 150 * 1024, 16
for path in paths:
    image = Image.open(path).convert("RGB")
    # Crop to what differs from the white background, with a margin.
    mask = ImageChops.difference(image, Image.new("RGB", image.size, (255, 255, 255))).convert("L")
    box = mask.point(lambda v: 255 if v > 12 else 0).getbbox() or (0, 0) + image.size
    box = (max(box[0] - MARGIN, 0), max(box[1] - MARGIN, 0),
           min(box[2] + MARGIN, image.width), min(box[3] + MARGIN, image.height))
    image = image.crop(box)
    if image.width > WIDTH:
        image = image.resize((WIDTH, round(image.height * WIDTH / image.width)), Image.LANCZOS)
    target = os.path.join(out_dir, os.path.basename(path))
    for colors in (256, 128, 64):
        image.quantize(colors=colors, method=Image.MEDIANCUT, dither=Image.NONE).save(target, optimize=True)
        if os.path.getsize(target) < LIMIT:
            break
    size = os.path.getsize(target)
    print("%s: %dx%d, %d colours, %.0f kB" % (target, image.width, image.height, colors, size / 1024))
    if size >= LIMIT:
        sys.exit("%s is %d bytes, not under %d" % (target, size, LIMIT))
PY
