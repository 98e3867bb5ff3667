// The instruction-set check (engine/build_arch.hpp): which features a build needs that a CPU
// lacks, and what the running build says of itself.
#include "engine/build_arch.hpp"

#include <doctest/doctest.h>

#include <string>
#include <vector>

using namespace sandcell;

TEST_CASE("missing_isa lists the required features the CPU lacks, in table order") {
  // Bits as in engine/build_arch.cpp: 5 avx, 6 avx2, 8 bmi2, 13 avx512f.
  const unsigned avx = 1u << 5, avx2 = 1u << 6, bmi2 = 1u << 8, avx512f = 1u << 13;
  CHECK(detail::missing_isa(0, 0).empty());                    // portable: needs nothing
  CHECK(detail::missing_isa(avx | avx2, avx | avx2 | bmi2).empty());  // more than needed is fine
  CHECK(detail::missing_isa(avx | avx2 | bmi2, avx) == std::vector<std::string>{"avx2", "bmi2"});
  CHECK(detail::missing_isa(avx512f | avx, 0) == std::vector<std::string>{"avx", "avx512f"});
}

TEST_CASE("the running build's features are all present, and it says which build it is") {
  // This test runs, so the startup check passed: the CPU has everything the build uses.
  CHECK(missing_cpu_features().empty());
  const unsigned required = detail::required_isa();
  CHECK((required & ~detail::present_isa()) == 0u);
  const std::string arch(build_arch());
  // A portable build needs nothing beyond the baseline; the default on a recent x86-64 machine,
  // x86-64-v3, needs AVX2 (bit 6) and must not use FMA (bit 10: -mno-fma, for bitwise equality).
  if (arch == "portable") CHECK(required == 0u);
  if (arch == "x86-64-v3") {
    CHECK((required >> 6 & 1u) == 1u);
    CHECK((required >> 10 & 1u) == 0u);
  }
  CHECK(!arch.empty());
}
