// The shearing periodic cell (components/cell.hpp, docs/physics.md section 1): a full upper
// triangular H, its affine field L x, wrapping and bins in reduced coordinates, flips.
#include "engine/world.hpp"
#include "systems/broadphase.hpp"
#include "systems/catalogue.hpp"
#include "systems/stress.hpp"
#include "support/scenes.hpp"

#include <doctest/doctest.h>

#include <cmath>

using namespace sandcell;

namespace {

Model quartz() { return test::quartz_model(2e-8, 0.05e-3); }

// A dense jittered lattice (every lattice neighbour touching), at rest.
State dense(const Model& model, std::size_t side = 6) {
  return test::jittered_lattice(model, side, 2e-3, 1.01e-3, 1.03e-3, 0.02e-3, 0.0, 0.0, 3);
}

}  // namespace

TEST_CASE("simple shear of a dense packing to gamma = 2.5: flips, the deformation continuous, a finite stress") {
  const Model model = quartz();
  State s = dense(model);
  const double gamma_dot = 2000.0;  // 1/s: gamma = 2.5 in 62,500 steps
  s.cell.shear_rate = Vec3(0.0, gamma_dot, 0.0);
  World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  const std::uint64_t steps = 62500;
  world.step(steps);
  const Cell& c = world.state().cell;
  MESSAGE("flips " << c.flip.transpose() << " tilt " << c.tilt.transpose() << " F " << c.deformation());
  CHECK(c.flip[1] != 0.0);
  CHECK(c.deformation()(0, 2) == doctest::Approx(double(steps) * gamma_dot * model.dt).epsilon(1e-9));
  const Mat3 sigma = contact_stress(world.state(), world.executor());
  MESSAGE("stress " << sigma);
  CHECK(sigma.allFinite());
}
