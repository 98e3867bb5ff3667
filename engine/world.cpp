#include "engine/world.hpp"

#include "systems/integrate.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace sandcell {

std::vector<SystemSpec> build_systems(const Model&) {
  std::vector<SystemSpec> systems;
  systems.push_back(make_system<IntegrateInitial>());
  systems.push_back(make_system<IntegrateFinal>());
  return systems;
}

void validate(const Model& model, const State& state) {
  if (!(model.dt > 0.0) || !std::isfinite(model.dt))
    throw std::invalid_argument("dt = " + std::to_string(model.dt) + ": must be a finite value > 0 s");
  if (model.materials.empty()) throw std::invalid_argument("materials: at least one material is required");
  for (std::size_t k = 0; k < state.particles.size(); ++k)
    if (state.particles.material[k] >= model.materials.size())
      throw std::invalid_argument("particle " + std::to_string(state.particles.id[k]) + ": material index " +
                                  std::to_string(state.particles.material[k]) + " not in [0, " +
                                  std::to_string(model.materials.size()) + ")");
  for (int a = 0; a < 3; ++a)
    if (!(state.cell.length[a] > 0.0))
      throw std::invalid_argument("cell length " + std::to_string(a) + " = " + std::to_string(state.cell.length[a]) +
                                  ": must be > 0 m");
}

World::World(Model model, State state, ExecutorConfig exec)
    : World(model, std::move(state), build_systems(model), exec) {}

World::World(Model model, State state, std::vector<SystemSpec> systems, ExecutorConfig exec)
    : model_(std::move(model)), state_(std::move(state)), exec_(exec), graph_((validate(model_, state_), std::move(systems)), exec_) {}

void World::step(std::uint64_t n) {
  for (std::uint64_t s = 0; s < n; ++s) {
    graph_.run(model_, state_, scratch_);
    ++state_.clock.step;
    state_.clock.time += model_.dt;
  }
}

}  // namespace sandcell
