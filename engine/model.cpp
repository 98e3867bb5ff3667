#include "engine/model.hpp"

#include <cmath>
#include <numbers>

namespace sandcell {

void Model::finalize() {
  const std::size_t n = materials.size();
  pairs.assign(n * n, PairMaterial{});
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = 0; b < n; ++b) {
      const Material& i = materials[a];
      const Material& j = materials[b];
      PairMaterial& p = pairs[a * n + b];
      p.e_star = 1.0 / ((1.0 - i.poisson * i.poisson) / i.young + (1.0 - j.poisson * j.poisson) / j.young);
      p.g_star = 1.0 / ((2.0 - i.poisson) / i.shear() + (2.0 - j.poisson) / j.shear());
      const double e = a == b ? i.restitution : 0.5 * (i.restitution + j.restitution);
      const double log_e = std::log(e);
      p.beta = log_e / std::sqrt(log_e * log_e + std::numbers::pi * std::numbers::pi);
      p.friction = a == b ? i.friction : 0.5 * (i.friction + j.friction);
      p.damping_ratio_t = std::sqrt(4.0 * p.g_star / p.e_star);
      p.rolling_friction = a == b ? i.rolling_friction : 0.5 * (i.rolling_friction + j.rolling_friction);
    }
}

double rayleigh_time(double r_min, const Material& m) {
  return std::numbers::pi * r_min * std::sqrt(m.density / m.shear()) / (0.1631 * m.poisson + 0.8766);
}

}  // namespace sandcell
