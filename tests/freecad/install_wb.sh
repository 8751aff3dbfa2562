#!/bin/bash
# Install the ParaFab FreeCAD workbench for the current user.
#
# Usage: tests/freecad/install_wb.sh BUILD_DIR
#    or: source tests/freecad/install_wb.sh; install_parafab_wb BUILD_DIR
#
# Installs into ${FREECAD_MOD_DIR:-$HOME/.local/share/FreeCAD/Mod}/ParaFab:
#   workbench/freecad/ParaFab/*           -> ParaFab/
#   resources/icons/*                     -> ParaFab/Resources/icons/
#   BUILD_DIR/workbench/entry/parafab*.so -> ParaFab/
#   BUILD_DIR/workbench/entry/parafab     -> ParaFab/   (the CLI run by the task panel)
# Any previous copy is removed first, so running it twice is harmless.

_parafab_repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)

install_parafab_wb() {
    local build_dir=${1:?usage: install_wb.sh BUILD_DIR}
    local mod_dir=${FREECAD_MOD_DIR:-$HOME/.local/share/FreeCAD/Mod}
    local dest=$mod_dir/ParaFab
    local so
    so=$(compgen -G "$build_dir/workbench/entry/parafab*.so" | head -n 1)
    if [ -z "$so" ]; then
        echo "install_wb.sh: no parafab*.so in $build_dir/workbench/entry" >&2
        return 1
    fi
    if ! { rm -rf "$dest" &&
           mkdir -p "$dest/Resources/icons" &&
           cp -R "$_parafab_repo/workbench/freecad/ParaFab/." "$dest/" &&
           cp -R "$_parafab_repo/resources/icons/." "$dest/Resources/icons/" &&
           cp "$so" "$dest/" &&
           { [ ! -x "$build_dir/workbench/entry/parafab" ] ||
             cp "$build_dir/workbench/entry/parafab" "$dest/parafab"; } &&
           find "$dest" -name __pycache__ -type d -prune -exec rm -rf {} +; }; then
        echo "install_wb.sh: installation into $dest failed" >&2
        return 1
    fi
    echo "install_wb.sh: installed ParaFab workbench into $dest"
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
    set -euo pipefail
    install_parafab_wb "$@"
fi
