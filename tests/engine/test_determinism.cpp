// Determinism: bitwise identical state for the serial backend and 1, 2, 3, 8 threads.
#include "engine/world.hpp"
#include "systems/catalogue.hpp"
#include "support/scenes.hpp"

#include <doctest/doctest.h>

#include <random>

using namespace sandcell;

TEST_CASE("1e4-particle free flight, 1000 steps: bitwise identical for any thread count") {
  Model model;
  model.dt = 1e-5;
  model.materials.push_back(Material{});
  model.contact.enabled = false;  // free flight: the contact systems have their own determinism test
  State s = test::random_gas(model, 10000, 0.2, 1e-3, 2e-3, 1.0, 50.0, 2024);
  s.cell.rate = Vec3(0.5, -1.0, 0.25);
  // Constant random forces and torques so that the kicks, not only the drift, enter the result.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  for (std::size_t k = 0; k < s.particles.size(); ++k) {
    s.particles.force[k] = Vec3(g(rng), g(rng), g(rng)) * 1e-3;
    s.particles.torque[k] = Vec3(g(rng), g(rng), g(rng)) * 1e-7;
  }

  auto run = [&](ExecutorConfig cfg) {
    World w(model, s, systems_for(model), cfg);
    w.step(1000);
    return w.state();
  };
  const State reference = run({Backend::serial, 1});
  CHECK(reference.particles.position != s.particles.position);
  for (int threads : {1, 2, 3, 8}) {
    const State other = run({Backend::tbb, threads});
    INFO("threads = " << threads);
    CHECK(first_difference(other.particles, reference.particles) == "");
    CHECK(first_difference(other.contacts, reference.contacts) == "");
    CHECK(other.cell.length == reference.cell.length);
  }
  // Run to run, same thread count.
  CHECK(first_difference(run({Backend::tbb, 2}).particles, reference.particles) == "");
}
