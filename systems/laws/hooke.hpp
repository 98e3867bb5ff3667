#pragma once
// Linear spring-dashpot normal law (Cundall & Strack 1979), as LIGGGHTS `model hooke` with its
// default options (tangential_damping on, ktToKnUser off, limitForce off):
//   k_n = 16/15 sqrt(R*) E* (15 m* V^2 / (16 sqrt(R*) E*))^(1/5), V the characteristic velocity
//         (ContactSettings::parameters["characteristic_velocity"], m/s): the stiffness at which the
//         maximum overlap of a collision at V equals Hertz's;
//   k_t = k_n;  gamma_n = gamma_t = -2 beta sqrt(m* k_n) = sqrt(4 m* k_n / (1 + (pi / ln e)^2));
//   F_n = k_n delta - gamma_n v_n; stored energy k_n delta^2 / 2.
// A head-on collision then lasts t_c = pi / sqrt(k_n/m* - (gamma_n / (2 m*))^2) and rebounds with
// the restitution coefficient e exactly, whatever the impact velocity (docs/physics.md section 2).
// The tangential and rolling laws compose with it as with Hertz.
#include "systems/laws/law.hpp"

#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace sandcell {

struct Hooke {
  static constexpr std::string_view name = "hooke";
  static constexpr std::array<LawParameter, 1> parameters{
      {{"characteristic_velocity", "m/s", 1e-9, 1e6, "LIGGGHTS characteristicVelocity"}}};

  static void validate(const ContactSettings& contact) {
    const auto it = contact.parameters.find("characteristic_velocity");
    const double v = it == contact.parameters.end() ? 0.0 : it->second;
    if (!(v > 0.0) || !std::isfinite(v))
      throw std::invalid_argument("contact.parameters.characteristic_velocity = " +
                                  (it == contact.parameters.end() ? std::string("(none)") : std::to_string(v)) +
                                  ": the hooke law needs a finite value > 0 m/s (LIGGGHTS characteristicVelocity)");
  }
  static double normal_stiffness(double e_star, double v_char, double r_star, double m_star) {
    const double sqrt_r = std::sqrt(r_star);
    return 16.0 / 15.0 * sqrt_r * e_star * std::pow(15.0 * m_star * v_char * v_char / (16.0 * sqrt_r * e_star), 0.2);
  }
  static Stiffness stiffness(const LawPair& p, double r_star, double m_star, double) {
    const double k_n = normal_stiffness(p.e_star, p.v_char, r_star, m_star);
    return Stiffness{k_n, k_n, -2.0 * p.beta * std::sqrt(m_star * k_n)};
  }
  static double gamma_t(const PairMaterial&, double gamma_n) { return gamma_n; }
  static double force(double k_n, double gamma_n, double overlap, double v_n) { return k_n * overlap - gamma_n * v_n; }
  static AtRest at_rest(const PairMaterial& mat, const ContactSettings& contact, double r_star, double m_star,
                        double overlap) {
    const double k_n = normal_stiffness(mat.e_star, contact.parameters.at("characteristic_velocity"), r_star, m_star);
    return AtRest{k_n, k_n, 0.5 * k_n * overlap * overlap, k_n};
  }
};

}  // namespace sandcell
