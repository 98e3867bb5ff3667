// Compiled for the baseline instruction set whatever SANDCELL_ARCH is (CMakeLists.txt), so that it
// runs on any CPU and can say why the rest of the library will not.
#include "engine/build_arch.hpp"

#include <array>
#include <cstdio>
#include <cstdlib>

#ifndef SANDCELL_BUILD_ARCH
#error "SANDCELL_BUILD_ARCH must be defined by the build"
#endif

namespace sandcell {

namespace {

// The features of the x86-64 levels v2-v4 that GCC and Clang predefine a macro for, in the bit
// order of detail::required_isa() (engine/build_arch.cpp).
constexpr std::array<const char*, 18> isa_feature_names = {
    "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx",      "avx2",     "bmi",      "bmi2",
    "f16c", "fma",   "lzcnt",  "movbe", "avx512f", "avx512vl", "avx512bw", "avx512dq", "avx512cd"};

// A startup check, before any static constructor of the rest of the library (priority 101 runs
// before the default): their code may already use the missing instructions.
[[gnu::constructor(101)]] void stop_on_unsupported_cpu() {
  const std::vector<std::string> missing = missing_cpu_features();
  if (missing.empty()) return;
  std::string list;
  for (const std::string& f : missing) {
    if (!list.empty()) list += ", ";
    list += f;
  }
  std::fprintf(stderr,
               "sandcell: this build's kernels were compiled for %s (SANDCELL_ARCH), and this CPU lacks %s: "
               "rebuild on this machine, or with cmake -DSANDCELL_ARCH=portable\n",
               SANDCELL_BUILD_ARCH, list.c_str());
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
  // __builtin_cpu_supports takes a string literal only: one call per feature.
  const bool has[isa_feature_names.size()] = {
      __builtin_cpu_supports("sse3") != 0,     __builtin_cpu_supports("ssse3") != 0,
      __builtin_cpu_supports("sse4.1") != 0,   __builtin_cpu_supports("sse4.2") != 0,
      __builtin_cpu_supports("popcnt") != 0,   __builtin_cpu_supports("avx") != 0,
      __builtin_cpu_supports("avx2") != 0,     __builtin_cpu_supports("bmi") != 0,
      __builtin_cpu_supports("bmi2") != 0,     __builtin_cpu_supports("f16c") != 0,
      __builtin_cpu_supports("fma") != 0,      __builtin_cpu_supports("lzcnt") != 0,
      __builtin_cpu_supports("movbe") != 0,    __builtin_cpu_supports("avx512f") != 0,
      __builtin_cpu_supports("avx512vl") != 0, __builtin_cpu_supports("avx512bw") != 0,
      __builtin_cpu_supports("avx512dq") != 0, __builtin_cpu_supports("avx512cd") != 0};
  unsigned bits = 0;
  for (std::size_t k = 0; k < isa_feature_names.size(); ++k)
    if (has[k]) bits |= 1u << k;
  return bits;
#else
  return 0;  // no x86 features are required either (required_isa() is 0 off x86)
#endif
}

std::vector<std::string> missing_isa(unsigned required, unsigned present) {
  std::vector<std::string> out;
  for (std::size_t k = 0; k < isa_feature_names.size(); ++k)
    if ((required >> k & 1u) && !(present >> k & 1u)) out.emplace_back(isa_feature_names[k]);
  return out;
}

}  // namespace detail
}  // namespace sandcell
