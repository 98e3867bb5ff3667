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

#include <cstring>

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

// Four consecutive 3-vectors (12 doubles from p, as an array of Eigen 3-vectors lies) as three
// vectors of x, y and z, and back.
[[gnu::always_inline]] inline void load_xyz(const double* p, V& x, V& y, V& z) {
  V a0, a1, a2;  // x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3
  std::memcpy(&a0, p, sizeof a0);
  std::memcpy(&a1, p + 4, sizeof a1);
  std::memcpy(&a2, p + 8, sizeof a2);
  x = __builtin_shuffle(__builtin_shuffle(a0, a1, L{0, 3, 6, 7}), a2, L{0, 1, 2, 5});
  y = __builtin_shuffle(__builtin_shuffle(a0, a1, L{1, 4, 7, 7}), a2, L{0, 1, 2, 6});
  z = __builtin_shuffle(__builtin_shuffle(a0, a1, L{2, 5, 5, 5}), a2, L{0, 1, 4, 7});
}
[[gnu::always_inline]] inline void store_xyz(double* p, V x, V y, V z) {
  const V a0 = __builtin_shuffle(__builtin_shuffle(x, y, L{0, 4, 1, 1}), z, L{0, 1, 4, 2});
  const V a1 = __builtin_shuffle(__builtin_shuffle(x, y, L{2, 5, 2, 6}), z, L{1, 5, 0, 3});
  const V a2 = __builtin_shuffle(__builtin_shuffle(x, y, L{3, 3, 3, 7}), z, L{6, 0, 3, 7});
  std::memcpy(p, &a0, sizeof a0);
  std::memcpy(p + 4, &a1, sizeof a1);
  std::memcpy(p + 8, &a2, sizeof a2);
}

}  // namespace sandcell::lanes
#endif

namespace sandcell {

/// Whether a law (or rolling evaluator) has a four-lane form: `static constexpr bool lanes = true`.
template <class Law>
inline constexpr bool has_lanes = requires { requires Law::lanes; };

}  // namespace sandcell
