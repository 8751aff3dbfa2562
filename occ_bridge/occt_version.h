// OpenCASCADE bridge: the version of the OCCT ParaFab is linked against (the same system
// OCCT as FreeCAD's, so one OCCT lives in the process). Readers and grid cutting follow.
#pragma once

#include <string>

namespace parafab::occ {

/// OCCT version string, e.g. "7.6.3".
std::string occt_version();

}  // namespace parafab::occ
