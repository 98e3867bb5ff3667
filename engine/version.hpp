#pragma once
// The software version, written into every results file and checkpoint so that a file says which
// build produced it.
#include <string_view>

namespace sandcell {

/// The project version (CMake PROJECT_VERSION), e.g. "0.1.0".
std::string_view version();

}  // namespace sandcell
