#include "occt_version.h"

#include <Standard_Version.hxx>

namespace parafab::occ {

std::string occt_version() { return OCC_VERSION_COMPLETE; }

}  // namespace parafab::occ
