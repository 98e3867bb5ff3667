#pragma once
// The catalogue: which systems a model needs, in reference order. Systems the model does not use
// are not listed (and so neither scheduled nor allocated for). Give the list to World:
//   World world(model, state, systems_for(model), ExecutorConfig{Backend::tbb, 4});
#include "engine/system.hpp"

#include <vector>

namespace sandcell {

std::vector<SystemSpec> systems_for(const Model& model);

}  // namespace sandcell
