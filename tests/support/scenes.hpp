#pragma once
// Scene builders shared by tests. Every scene is made here from a seed; no test reads a file outside the repository.
#include "engine/state.hpp"

#include <cstdint>
#include <stdexcept>
#include <string>

namespace sandcell::test {

/// N spheres (radius in [r_min, r_max]) at random positions in a cube of side `box`, with random
/// fluctuating and angular velocities of the given scales. Overlaps are allowed (free flight).
State random_gas(const Model& model, std::size_t n, double box, double r_min, double r_max, double v_scale,
                 double w_scale, std::uint64_t seed);

/// One material of the benchmark (quartz-like: E = 70 GPa, nu = 0.3, e = 0.5, mu = 0.5, mu_r = 0.1,
/// epsd2 rolling, history tangential law) with the given time step and Verlet skin.
Model quartz_model(double dt, double skin);

/// An assert handler that throws, so a failing SANDCELL_CHECK can be caught by a test.
struct AssertionError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
void throwing_assert_handler(const char* file, int line, const char* expr, const std::string& message);

}  // namespace sandcell::test

namespace sandcell::test {

/// n_side^3 spheres on a simple cubic lattice of the given spacing, in a periodic cube of side
/// n_side * spacing; each sphere is displaced by a uniform random jitter in [-jitter, jitter]^3 and
/// has a radius uniform in [r_min, r_max], so with 2 r_min > spacing + 2 sqrt(3) jitter every lattice
/// neighbour pair overlaps (a dense, jammed periodic packing), with 2 r_max < spacing - 2 sqrt(3)
/// jitter none does (a dilute gas on a lattice, free of initial overlaps). Random fluctuating and
/// angular velocities of the given scales. Ids 0..n-1 in lattice order, material 0.
State jittered_lattice(const Model& model, std::size_t n_side, double spacing, double r_min, double r_max,
                       double jitter, double v_scale, double w_scale, std::uint64_t seed);

}  // namespace sandcell::test
