#pragma once
// The Model: everything constant during a run. Validated once, when the scene is built.
#include "components/material.hpp"

#include <vector>

namespace sandcell {

struct Model {
  double dt = 0.0;                   // s, time step
  std::vector<Material> materials;   // indexed by particles.material
};

}  // namespace sandcell
