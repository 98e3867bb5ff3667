#include "support/scenes.hpp"

#include <random>

namespace sandcell::test {

State random_gas(const Model& model, std::size_t n, double box, double r_min, double r_max, double v_scale,
                 double w_scale, std::uint64_t seed) {
  State state;
  state.cell.length = state.cell.length0 = Vec3::Constant(box);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::uniform_real_distribution<double> u11(-1.0, 1.0);
  for (std::size_t k = 0; k < n; ++k) {
    const double r = r_min + (r_max - r_min) * u01(rng);
    const std::size_t i =
        add_sphere(state, model, static_cast<ParticleId>(k), Vec3(u01(rng), u01(rng), u01(rng)) * box, r, 0);
    state.particles.velocity[i] = Vec3(u11(rng), u11(rng), u11(rng)) * v_scale;
    state.particles.angular_velocity[i] = Vec3(u11(rng), u11(rng), u11(rng)) * w_scale;
  }
  return state;
}

Model quartz_model(double dt, double skin) {
  Model m;
  Material mat;
  mat.young = 70e9;
  mat.poisson = 0.3;
  mat.restitution = 0.5;
  mat.friction = 0.5;
  mat.rolling_friction = 0.1;
  m.materials = {mat};
  m.dt = dt;
  m.contact.skin = skin;
  return m;
}

void throwing_assert_handler(const char*, int, const char*, const std::string& message) {
  throw AssertionError(message);
}

}  // namespace sandcell::test

namespace sandcell::test {

State jittered_lattice(const Model& model, std::size_t n_side, double spacing, double r_min, double r_max,
                       double jitter, double v_scale, double w_scale, std::uint64_t seed) {
  State state;
  const double box = static_cast<double>(n_side) * spacing;
  state.cell.length = state.cell.length0 = Vec3::Constant(box);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::uniform_real_distribution<double> u11(-1.0, 1.0);
  ParticleId id = 0;
  for (std::size_t a = 0; a < n_side; ++a)
    for (std::size_t b = 0; b < n_side; ++b)
      for (std::size_t c = 0; c < n_side; ++c) {
        const double r = r_min + (r_max - r_min) * u01(rng);
        Vec3 x = (Vec3(double(a), double(b), double(c)) + Vec3::Constant(0.5)) * spacing +
                 Vec3(u11(rng), u11(rng), u11(rng)) * jitter;
        for (int k = 0; k < 3; ++k) {  // wrap into [0, box)
          if (x[k] < 0.0) x[k] += box;
          if (x[k] >= box) x[k] -= box;
        }
        const std::size_t i = add_sphere(state, model, id++, x, r, 0);
        state.particles.velocity[i] = Vec3(u11(rng), u11(rng), u11(rng)) * v_scale;
        state.particles.angular_velocity[i] = Vec3(u11(rng), u11(rng), u11(rng)) * w_scale;
      }
  return state;
}

}  // namespace sandcell::test
