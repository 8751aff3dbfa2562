// Where an installed ParaFab finds its data at run time (the chart scripts), wherever the
// package was installed: relative to the binary that holds this code (the parafab CLI or the
// Python module), with an environment override and the source tree as the build tree's fallback.
#pragma once

#include <string>

namespace parafab::entry {

// Version of this build (the CMake project version).
const char* version();

// Folder of the helper scripts (plot_optimization.py, ...), tried in this order:
//   $PARAFAB_SCRIPTS_DIR if set and not empty (taken as it is);
//   <folder of the CLI>/../share/parafab/scripts (installed CLI: <prefix>/bin/parafab);
//   <folder of the module>/../../../share/parafab/scripts (installed module:
//     <prefix>/lib/python3/dist-packages/parafab*.so);
//   the source tree's workbench/scripts (a build tree).
// An installed folder counts only if it holds plot_optimization.py. The relative paths come
// from the install layout configured in CMake (PARAFAB_SCRIPTS_FROM_BIN/_FROM_PYTHON).
std::string scripts_dir();

}  // namespace parafab::entry
