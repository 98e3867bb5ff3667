#include "engine/version.hpp"

// Defined by the build from PROJECT_VERSION (CMakeLists.txt), so there is one place to bump it.
#ifndef SANDCELL_VERSION
#error "SANDCELL_VERSION must be defined by the build"
#endif

namespace sandcell {

std::string_view version() { return SANDCELL_VERSION; }

std::string_view compiler() {
#if defined(__clang__)
  return "clang " __clang_version__;
#elif defined(__GNUC__)
  return "gcc " __VERSION__;
#else
  return "unknown";
#endif
}

}  // namespace sandcell
