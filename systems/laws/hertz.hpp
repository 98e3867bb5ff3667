#pragma once
// Hertz normal law with viscous damping (docs/physics.md section 2), as LIGGGHTS `model hertz`:
//   k_n = 4/3 E* sqrt(R* delta), k_t = S_t = 8 G* sqrt(R* delta),
//   gamma_n = -2 sqrt(5/6) beta sqrt(S_n m*), S_n = 2 E* sqrt(R* delta),
//   gamma_t = -2 sqrt(5/6) beta sqrt(S_t m*) = gamma_n sqrt(S_t / S_n),
//   F_n = k_n delta - gamma_n v_n, stored energy 8/15 E* sqrt(R*) delta^(5/2).
#include "systems/laws/lanes.hpp"
#include "systems/laws/law.hpp"

#include <array>
#include <cmath>

namespace sandcell {

struct Hertz {
  static constexpr std::string_view name = "hertz";
  static constexpr std::array<LawParameter, 0> parameters{};
  static constexpr double k_two_sqrt_5_6 = 1.8257418583505538;  // 2 sqrt(5/6)

  static void validate(const ContactSettings&) {}

  [[gnu::always_inline]] static inline Stiffness stiffness(const LawPair& p, double r_star, double m_star, double od) {
    const double sqrt_rd = std::sqrt(r_star * od);
    const double s_n = 2.0 * p.e_star * sqrt_rd;
    return Stiffness{(2.0 / 3.0) * s_n,         // 4/3 E* sqrt(R* delta)
                     8.0 * p.g_star * sqrt_rd,  // = S_t
                     -k_two_sqrt_5_6 * p.beta * std::sqrt(s_n * m_star)};
  }
  [[gnu::always_inline]] static inline double gamma_t(const PairMaterial& mat, double gamma_n) {
    return gamma_n * mat.damping_ratio_t;  // -2 sqrt(5/6) beta sqrt(S_t m*)
  }
  [[gnu::always_inline]] static inline double force(double k_n, double gamma_n, double overlap, double v_n) {
    return k_n * overlap - gamma_n * v_n;
  }
#if defined(SANDCELL_LANES)
  // The four-lane forms of force and gamma_t (systems/laws/lanes.hpp).
  static constexpr bool lanes = true;
  [[gnu::always_inline]] static inline lanes::V force4(lanes::V k_n, lanes::V gamma_n, lanes::V overlap, lanes::V v_n) {
    return k_n * overlap - gamma_n * v_n;
  }
  [[gnu::always_inline]] static inline lanes::V gamma_t4(lanes::V gamma_n, lanes::V damping_ratio_t) {
    return gamma_n * damping_ratio_t;
  }
#endif
  static AtRest at_rest(const PairMaterial& mat, const ContactSettings&, double r_star, double, double overlap) {
    const double sqrt_rd = std::sqrt(r_star * overlap);
    return AtRest{4.0 / 3.0 * mat.e_star * sqrt_rd, 8.0 * mat.g_star * sqrt_rd,
                  8.0 / 15.0 * mat.e_star * sqrt_rd * overlap * overlap, 2.0 * mat.e_star * sqrt_rd};
  }
};

}  // namespace sandcell
