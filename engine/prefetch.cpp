#include "engine/prefetch.hpp"

#if defined(__x86_64__)
#include <cpuid.h>
#endif

namespace sandcell {

bool cpu_has_prefetchw() {
#if defined(__x86_64__)
  static const bool has = [] {
    unsigned a = 0, b = 0, c = 0, d = 0;
    return __get_cpuid(0x80000001u, &a, &b, &c, &d) != 0 && (c & bit_PRFCHW) != 0;
  }();
  return has;
#else
  return false;
#endif
}

}  // namespace sandcell
