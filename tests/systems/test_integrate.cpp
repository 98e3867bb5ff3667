// Velocity-Verlet integrator in a deforming periodic cell (docs/physics.md section 1, 3.4).
#include "engine/world.hpp"
#include "support/scenes.hpp"
#include "systems/integrate.hpp"
#include "systems/wrap.hpp"

#include <doctest/doctest.h>

#include <cmath>

using namespace sandcell;

namespace {
Model one_material(double dt) {
  Model m;
  m.dt = dt;
  m.materials.push_back(Material{});
  return m;
}
std::vector<SystemSpec> integrator_only() { return {make_system<IntegrateInitial>(), make_system<IntegrateFinal>()}; }
}  // namespace

TEST_CASE("a free particle moves exactly x + (v~ + D x) dt per step and wraps across every face") {
  const Model model = one_material(1e-3);
  State s;
  s.cell.length = s.cell.length0 = Vec3(1.0, 2.0, 3.0);
  s.cell.rate = Vec3(0.01, -0.02, 0.03);
  // One particle heading out through each of the six faces.
  const Vec3 starts[6] = {{0.999, 1, 1.5},   {0.001, 1, 1.5}, {0.5, 1.999, 1.5},
                          {0.5, 0.001, 1.5}, {0.5, 1, 2.999}, {0.5, 1, 0.001}};
  const Vec3 vels[6] = {{3, 0, 0}, {-3, 0, 0}, {0, 3, 0}, {0, -3, 0}, {0, 0, 3}, {0, 0, -3}};
  for (int k = 0; k < 6; ++k) {
    add_sphere(s, model, k, starts[k], 0.01, 0);
    s.particles.velocity[k] = vels[k];
  }
  // The free-flight step: drift, then wrap into the cell.
  World world(model, s, {make_system<IntegrateInitial>(), make_system<Wrap>(), make_system<IntegrateFinal>()},
              {Backend::tbb, 2});
  std::vector<Vec3> x(starts, starts + 6);
  Vec3 length = s.cell.length;
  int wraps[6] = {0, 0, 0, 0, 0, 0};
  for (int step = 0; step < 10; ++step) {
    world.step();
    // Expected with the same operations, so the comparison is exact (built with -ffp-contract=off).
    length = length + length.cwiseProduct(s.cell.rate) * model.dt;
    for (int k = 0; k < 6; ++k) {
      Vec3 e = x[k] + (vels[k] + s.cell.rate.cwiseProduct(x[k])) * model.dt;
      for (int a = 0; a < 3; ++a) {
        if (e[a] >= length[a]) {
          e[a] -= length[a];
          ++wraps[k];
        } else if (e[a] < 0.0) {
          e[a] += length[a];
          ++wraps[k];
        }
      }
      x[k] = e;
      REQUIRE(world.state().particles.position[k] == x[k]);
      REQUIRE(world.state().particles.velocity[k] == vels[k]);
    }
    REQUIRE(world.state().cell.length == length);
  }
  for (int k = 0; k < 6; ++k) CHECK(wraps[k] == 1);  // each crossed its face once
}

TEST_CASE("with a deforming cell and v~ = 0, reduced coordinates are kept over 1e5 steps (affine motion)") {
  const Model model = one_material(1e-6);
  State s = test::random_gas(model, 500, 1.0, 0.01, 0.02, 0.0, 0.0, 11);
  // Per-step factors 1 + D dt = 1 - 1e-6, 1 + 5e-7, 1 + 2e-6: total stretches e^-0.1, e^0.05, e^0.2.
  s.cell.rate = Vec3(-1.0, 0.5, 2.0);
  std::vector<Vec3> s0(s.particles.size());
  for (std::size_t k = 0; k < s0.size(); ++k) s0[k] = s.particles.position[k].cwiseQuotient(s.cell.length);
  World world(model, s, integrator_only(), {Backend::tbb, 2});
  world.step(100000);
  const State& f = world.state();
  // Exact cell stretch: (1 + rate dt)^n, against exp(n log1p(rate dt)).
  for (int a = 0; a < 3; ++a)
    CHECK(f.cell.length[a] == doctest::Approx(std::exp(1e5 * std::log1p(s.cell.rate[a] * 1e-6))).epsilon(1e-10));
  // Tolerance: each step rounds x and L (a few operations each, <= 4 roundings of 2^-53 relative)
  // so the reduced coordinate drifts at most 1e5 * 4 * 1.1e-16 = 4.4e-11 even if every rounding had
  // the same sign. A scheme with a different cell update (e.g. exp(D dt) for L) drifts by
  // n (D dt)^2 / 2 ~ 1e-7 and fails.
  double worst = 0.0;
  for (std::size_t k = 0; k < s0.size(); ++k) {
    const Vec3 sk = f.particles.position[k].cwiseQuotient(f.cell.length);
    for (int a = 0; a < 3; ++a) {
      double d = std::abs(sk[a] - s0[k][a]);
      d = std::min(d, std::abs(1.0 - d));  // a particle at s ~ 0 may have wrapped to s ~ 1 by round-off
      worst = std::max(worst, d);
    }
  }
  MESSAGE("largest drift of a reduced coordinate over 1e5 steps: " << worst);
  CHECK(worst < 4.4e-11);
  CHECK(f.particles.velocity == s.particles.velocity);
}

TEST_CASE("constant force and torque: velocity Verlet is exact for uniform acceleration") {
  const double dt = 1e-4;
  const Model model = one_material(dt);
  State s;
  s.cell.length = s.cell.length0 = Vec3::Constant(100.0);
  add_sphere(s, model, 0, Vec3(50, 50, 50), 0.05, 0);
  const Vec3 F(1e-3, -2e-3, 0.5e-3), T(2e-6, 1e-6, -3e-6), v0(0.1, 0.2, -0.3);
  s.particles.force[0] = F;
  s.particles.torque[0] = T;
  s.particles.velocity[0] = v0;
  const double m = s.particles.mass[0];
  const double inv_i = s.particles.inv_inertia[0];
  CHECK(inv_i == doctest::Approx(1.0 / (0.4 * m * 0.05 * 0.05)).epsilon(1e-15));
  World world(model, s, integrator_only(), {Backend::serial, 1});
  const int n = 1000;
  world.step(n);
  const double t = n * dt;
  const Particles& p = world.state().particles;
  // Tolerances: n = 1000 steps, each adding a rounded increment (<= 2 ulp relative): 1e-12 relative
  // bounds the accumulated rounding with a wide margin, while any O(dt) scheme error (e.g. a missed
  // half kick, off by F dt / 2m ~ 5e-5 relative) is far above it.
  for (int a = 0; a < 3; ++a) {
    CHECK(p.velocity[0][a] == doctest::Approx(v0[a] + F[a] / m * t).epsilon(1e-12));
    CHECK(p.angular_velocity[0][a] == doctest::Approx(T[a] * inv_i * t).epsilon(1e-12));
    CHECK(p.position[0][a] == doctest::Approx(50 + v0[a] * t + 0.5 * F[a] / m * t * t).epsilon(1e-12));
  }
}
