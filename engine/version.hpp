#pragma once
// The software version, written into every results file and checkpoint so that a file says which
// build produced it.
#include <string_view>

namespace sandcell {

/// The project version (CMake PROJECT_VERSION), e.g. "0.1.0".
std::string_view version();
/// The compiler that built the engine, e.g. "gcc 12.2.0" (results files record it: a run is
/// bitwise reproducible within one build; engine/build_arch.hpp says which builds agree).
std::string_view compiler();

}  // namespace sandcell
