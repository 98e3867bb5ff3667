// The instruction-set check (engine/build_arch.hpp): which features a build needs that a CPU
// lacks, and what the running build says of itself.
#include "engine/build_arch.hpp"
#include "engine/prefetch.hpp"

#include <doctest/doctest.h>

#include <fstream>
#include <string>
#include <vector>

using namespace sandcell;

TEST_CASE("missing_isa lists the required features the CPU lacks, in table order") {
  // Bits as in engine/build_arch.cpp: 5 avx, 6 avx2, 8 bmi2, 13 avx512f.
  const unsigned avx = 1u << 5, avx2 = 1u << 6, bmi2 = 1u << 8, avx512f = 1u << 13;
  CHECK(detail::missing_isa(0, 0).empty());                           // portable: needs nothing
  CHECK(detail::missing_isa(avx | avx2, avx | avx2 | bmi2).empty());  // more than needed is fine
  CHECK(detail::missing_isa(avx | avx2 | bmi2, avx) == std::vector<std::string>{"avx2", "bmi2"});
  CHECK(detail::missing_isa(avx512f | avx, 0) == std::vector<std::string>{"avx", "avx512f"});
}

TEST_CASE("the startup check's message names the build, every missing feature and the portable option") {
  const std::string m = detail::unsupported_cpu_message("x86-64-v3", {"avx2", "bmi2"});
  CHECK(m.find("x86-64-v3") != std::string::npos);
  CHECK(m.find("avx2, bmi2") != std::string::npos);
  CHECK(m.find("-DSANDCELL_ARCH=portable") != std::string::npos);
  CHECK(m.back() == '\n');
  CHECK(m.find('\n') == m.size() - 1);  // one line
}

TEST_CASE("the running build says which it is, and what it needs matches that") {
  // (That this CPU has what the build needs is not checked here: the startup check would have
  // stopped the test program first.)
  const unsigned required = detail::required_isa();
  const std::string arch(build_arch());
  CHECK(!arch.empty());
  // A portable build needs nothing beyond the baseline; the default on a recent x86-64 machine,
  // x86-64-v3, needs AVX2 (bit 6) and must not use FMA (bit 10: -mno-fma, for bitwise equality).
  if (arch == "portable") CHECK(required == 0u);
  if (arch == "x86-64-v3") {
    CHECK((required >> 6 & 1u) == 1u);
    CHECK((required >> 10 & 1u) == 0u);
  }
  // x86-64-v4 (auto on an AVX-512 CPU) needs AVX2 and avx512f, vl, bw, dq, cd (bits 13-17), still no
  // FMA. avx512f must be required although the build hides __AVX512F__ from Eigen (CMakeLists.txt):
  // without it a CPU lacking AVX-512 would get past the startup check.
  if (arch == "x86-64-v4") {
    CHECK((required >> 6 & 1u) == 1u);
    CHECK((required >> 10 & 1u) == 0u);
    for (unsigned bit = 13; bit <= 17; ++bit) CHECK((required >> bit & 1u) == 1u);
  }
}

TEST_CASE("cpu_has_prefetchw agrees with the kernel's view of the CPU") {
  // Linux lists the CPUID bit of PREFETCHW (0x80000001 ECX bit 8) as the flag "3dnowprefetch" in
  // /proc/cpuinfo: an independent reading of the same bit. Off Linux or off x86-64 there is no
  // such line, and the query must say false off x86-64.
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  bool listed = false, have_flags = false;
  while (std::getline(in, line))
    if (line.rfind("flags", 0) == 0) {
      have_flags = true;
      listed = (line + " ").find(" 3dnowprefetch ") != std::string::npos;
      break;
    }
#if defined(__x86_64__)
  if (have_flags) CHECK(cpu_has_prefetchw() == listed);
#else
  static_cast<void>(listed);
  static_cast<void>(have_flags);
  CHECK_FALSE(cpu_has_prefetchw());
#endif
}
