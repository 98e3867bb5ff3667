#pragma once
// sandcell's public API for running a scene: the model, the state, the world that steps them and
// the catalogue of systems a model needs.
//   sandcell::World world(model, state, sandcell::systems_for(model), {sandcell::Backend::tbb, 4});
//   world.step(1000);
#include "engine/executor.hpp"
#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/world.hpp"
#include "systems/catalogue.hpp"
#include "systems/path_watch.hpp"
#include "systems/servo.hpp"
