// Compiled with the library's -march flags: the macros below say what the compiler may emit.
// required_isa() only returns a constant, so calling it is safe on any CPU.
#include "engine/build_arch.hpp"

namespace sandcell::detail {

unsigned required_isa() {
  unsigned bits = 0;
  // Bit order: isa_feature_names in engine/cpu_guard.cpp.
#if defined(__SSE3__)
  bits |= 1u << 0;
#endif
#if defined(__SSSE3__)
  bits |= 1u << 1;
#endif
#if defined(__SSE4_1__)
  bits |= 1u << 2;
#endif
#if defined(__SSE4_2__)
  bits |= 1u << 3;
#endif
#if defined(__POPCNT__)
  bits |= 1u << 4;
#endif
#if defined(__AVX__)
  bits |= 1u << 5;
#endif
#if defined(__AVX2__)
  bits |= 1u << 6;
#endif
#if defined(__BMI__)
  bits |= 1u << 7;
#endif
#if defined(__BMI2__)
  bits |= 1u << 8;
#endif
#if defined(__F16C__)
  bits |= 1u << 9;
#endif
#if defined(__FMA__)
  bits |= 1u << 10;
#endif
#if defined(__LZCNT__)
  bits |= 1u << 11;
#endif
#if defined(__MOVBE__)
  bits |= 1u << 12;
#endif
#if defined(__AVX512F__) || defined(__AVX512VL__)  // AVX-512 builds undefine __AVX512F__ for Eigen (CMakeLists.txt)
  bits |= 1u << 13;
#endif
#if defined(__AVX512VL__)
  bits |= 1u << 14;
#endif
#if defined(__AVX512BW__)
  bits |= 1u << 15;
#endif
#if defined(__AVX512DQ__)
  bits |= 1u << 16;
#endif
#if defined(__AVX512CD__)
  bits |= 1u << 17;
#endif
  return bits;
}

}  // namespace sandcell::detail
