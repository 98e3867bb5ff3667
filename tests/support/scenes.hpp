#pragma once
// Scene builders shared by tests. Every scene is made here from a seed; no test reads ../shared.
#include "engine/state.hpp"

#include <cstdint>
#include <stdexcept>
#include <string>

namespace sandcell::test {

/// N spheres (radius in [r_min, r_max]) at random positions in a cube of side `box`, with random
/// fluctuating and angular velocities of the given scales. Overlaps are allowed (free flight).
State random_gas(const Model& model, std::size_t n, double box, double r_min, double r_max, double v_scale,
                 double w_scale, std::uint64_t seed);

/// An assert handler that throws, so a failing SANDCELL_CHECK can be caught by a test.
struct AssertionError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
void throwing_assert_handler(const char* file, int line, const char* expr, const std::string& message);

}  // namespace sandcell::test
