#pragma once
// Four contacts at once, one per lane of an AVX2 register: the small vector helper that the laws'
// four-lane forms are written on (Hertz::force4, MindlinHistory::force4, the epsd2 evaluator's
// evaluate4, each in its law's header). A lane does the scalar form's operations in the scalar
// form's order (a sum of three as Eigen reduces a 3-vector: the first two, then the third), and IEEE
// arithmetic is correctly rounded in vector form, so a contact's result is bitwise the scalar law's
// (tests/systems/test_contact_lanes.cpp). A law without a four-lane form runs on the contact pass's
// per-pair path. Only on AVX2 builds (SANDCELL_LANES).
#if defined(__AVX2__)
#define SANDCELL_LANES 1
#include <immintrin.h>

namespace sandcell::lanes {

using V = double __attribute__((vector_size(32)));
using L = long long __attribute__((vector_size(32)));

[[gnu::always_inline]] inline V sum3(V a, V b, V c) { return (a + b) + c; }
[[gnu::always_inline]] inline V vabs(V a) {
  return (V)((L)a & L{~(1ll << 63), ~(1ll << 63), ~(1ll << 63), ~(1ll << 63)});
}
[[gnu::always_inline]] inline V vsqrt(V a) { return (V)_mm256_sqrt_pd((__m256d)a); }
[[gnu::always_inline]] inline V sel(L m, V a, V b) { return m ? a : b; }
[[gnu::always_inline]] inline bool any(L m) { return _mm256_movemask_pd((__m256d)m) != 0; }

}  // namespace sandcell::lanes
#endif

namespace sandcell {

/// Whether a law (or rolling evaluator) has a four-lane form: `static constexpr bool lanes = true`.
template <class Law>
inline constexpr bool has_lanes = requires { requires Law::lanes; };

}  // namespace sandcell
