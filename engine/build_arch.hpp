#pragma once
// The instruction set the library was compiled for (CMake option SANDCELL_ARCH), and the check
// that this CPU runs it. A build for x86-64-v3 started on a CPU without AVX2 would otherwise die of
// an illegal instruction somewhere in the first step; it stops at program start instead, naming
// the missing features and the option that builds a portable library (engine/cpu_guard.cpp).
// Every value of SANDCELL_ARCH gives bitwise the same results: fused multiply-add is off in all.
#include <string>
#include <string_view>
#include <vector>

namespace sandcell {

/// "portable" (the compiler's baseline, SSE2 on x86-64) or the -march value, e.g. "x86-64-v3".
std::string_view build_arch();

/// The CPU features the library's code uses that this CPU lacks; empty when it runs here.
std::vector<std::string> missing_cpu_features();

namespace detail {

/// Bit k set: the library was compiled to use feature k of `isa_feature_names` (from the
/// compiler's predefined macros in a file compiled with the library's flags).
unsigned required_isa();
/// Bit k set: this CPU has feature k (0 on other architectures than x86-64).
unsigned present_isa();
/// The names of the features in `required` and not in `present`, in table order.
std::vector<std::string> missing_isa(unsigned required, unsigned present);
/// What the startup check prints before it stops the program (one line).
std::string unsupported_cpu_message(std::string_view arch, const std::vector<std::string>& missing);

}  // namespace detail
}  // namespace sandcell
