#include "engine/version.hpp"

// Defined by the build from PROJECT_VERSION (CMakeLists.txt), so there is one place to bump it.
#ifndef SANDCELL_VERSION
#error "SANDCELL_VERSION must be defined by the build"
#endif

namespace sandcell {

std::string_view version() { return SANDCELL_VERSION; }

}  // namespace sandcell
