#!/usr/bin/env bash
# Idempotent setup on Debian bookworm (as root): install the packages in
# .ci/packages.txt that are missing, configure and build ParaFab in Release into
# build/, and install the FreeCAD workbench for the current user.
#   bash .ci/setup.sh
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
build=${PARAFAB_BUILD_DIR:-$repo/build}

mapfile -t pkgs < <(grep -v '^#' "$repo/.ci/packages.txt" | tr ' ' '\n' | sed '/^$/d')
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "setup: all Debian packages present"
fi

cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=Release -DPYTHON_EXECUTABLE=/usr/bin/python3 >/dev/null
cmake --build "$build" -j"$(nproc)"
bash "$repo/tests/freecad/install_wb.sh" "$build"
