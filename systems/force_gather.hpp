#pragma once
// force_gather: per-particle sums of the pair slots in a fixed order: first the pairs where the
// particle is i (a contiguous run, since the list is sorted by i), then those where it is j (from
// the gather index, ascending). F_k = sum(F on i, k is i) - sum(F on i, k is j); torques from the
// torque_i / torque_j slots. No atomics; the order of every sum is fixed by the pair list, so the
// result is bitwise the same for any thread count. Reads contact_forces and gather_index; writes
// particle forces and torques (all of them: a particle without contacts gets zero).
// Particles are visited in GatherIndex::visit order (sorted by their pair counts within blocks of
// 128), which changes no sum but lets the branch predictor learn the loops' trip counts:
// docs/performance.md gives the measured effect.
#include "engine/system.hpp"

namespace sandcell {

struct ForceGather {
  static constexpr std::string_view name = "force_gather";
  static constexpr ComponentMask reads =
      mask_of({Component::contact_forces, Component::gather_index, Component::halo});
  static constexpr ComponentMask writes = mask_of({Component::particle_force, Component::particle_torque});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
  /// The sums of the initial configuration's forces (the same pass).
  static void setup(const Model& model, State& state, Scratch& scratch, Executor& exec) {
    run(model, state, scratch, exec);
  }
};

}  // namespace sandcell
