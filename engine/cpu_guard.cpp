// Compiled for the baseline instruction set whatever SANDCELL_ARCH is (CMakeLists.txt), so that it
// runs on any CPU and can say why the rest of the library will not.
#include "engine/build_arch.hpp"

#include <array>
#include <cstdio>
#include <cstdlib>
#include <iterator>

#ifndef SANDCELL_BUILD_ARCH
#error "SANDCELL_BUILD_ARCH must be defined by the build"
#endif

namespace sandcell {

namespace {

// The features of the x86-64 levels v2-v4 that GCC and Clang predefine a macro for, in the bit
// order of detail::required_isa() (engine/build_arch.cpp). One list gives both the names and the
// CPU queries: __builtin_cpu_supports takes a string literal only.
#define SANDCELL_ISA_FEATURES(X)                                                                                     \
  X("sse3")                                                                                                          \
  X("ssse3") X("sse4.1") X("sse4.2") X("popcnt") X("avx") X("avx2") X("bmi") X("bmi2") X("f16c") X("fma") X("lzcnt") \
      X("movbe") X("avx512f") X("avx512vl") X("avx512bw") X("avx512dq") X("avx512cd")

#define SANDCELL_ISA_NAME(name) name,
constexpr std::array isa_feature_names = {SANDCELL_ISA_FEATURES(SANDCELL_ISA_NAME)};
#undef SANDCELL_ISA_NAME

// A startup check, before any static constructor of the rest of the library (priority 101 runs
// before the default): their code may already use the missing instructions.
[[gnu::constructor(101)]] void stop_on_unsupported_cpu() {
  const std::vector<std::string> missing = missing_cpu_features();
  if (missing.empty()) return;
  std::fputs(detail::unsupported_cpu_message(build_arch(), missing).c_str(), stderr);
  std::_Exit(2);
}

}  // namespace

std::string_view build_arch() { return SANDCELL_BUILD_ARCH; }

std::vector<std::string> missing_cpu_features() {
  return detail::missing_isa(detail::required_isa(), detail::present_isa());
}

namespace detail {

unsigned present_isa() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  __builtin_cpu_init();  // constructors may run before the compiler's own initialization of this
#define SANDCELL_ISA_PRESENT(name) __builtin_cpu_supports(name) != 0,
  const bool has[] = {SANDCELL_ISA_FEATURES(SANDCELL_ISA_PRESENT)};
#undef SANDCELL_ISA_PRESENT
  static_assert(std::size(has) == isa_feature_names.size());
  unsigned bits = 0;
  for (std::size_t k = 0; k < isa_feature_names.size(); ++k)
    if (has[k]) bits |= 1u << k;
  return bits;
#else
  return 0;  // no x86 features are required either (required_isa() is 0 off x86)
#endif
}

std::string unsupported_cpu_message(std::string_view arch, const std::vector<std::string>& missing) {
  std::string list;
  for (const std::string& f : missing) {
    if (!list.empty()) list += ", ";
    list += f;
  }
  return "sandcell: this build's code was compiled for " + std::string(arch) + " (SANDCELL_ARCH), and this CPU lacks " +
         list + ": rebuild on this machine, or with cmake -DSANDCELL_ARCH=portable\n";
}

std::vector<std::string> missing_isa(unsigned required, unsigned present) {
  std::vector<std::string> out;
  for (std::size_t k = 0; k < isa_feature_names.size(); ++k)
    if ((required >> k & 1u) && !(present >> k & 1u)) out.emplace_back(isa_feature_names[k]);
  return out;
}

}  // namespace detail
}  // namespace sandcell
