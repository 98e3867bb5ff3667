#pragma once
// rolling: rolling resistance torque (DESIGN 3.3, Ai et al. 2011): epsd2 (LIGGGHTS default form),
// epsd (spring + dashpot below the cap) or cdt (constant directional torque). Not scheduled when
// the model says none, and then no rolling history exists.
//
// Reads the pair list, angular velocities, radii, masses, materials and the contact geometry of
// this step (normal, overlap, F_n, k_n, k_t from hertz_mindlin). Writes the rolling history
// (contact_rolling) and adds -M to the torque on i and +M to the torque on j in the pair's own
// slots (contact_forces). One parallel_for over pairs.
#include "engine/system.hpp"

namespace sandcell {

struct Rolling {
  static constexpr std::string_view name = "rolling";
  static constexpr ComponentMask reads =
      mask_of({Component::contact_pairs, Component::particle_angular_velocity, Component::particle_radius,
               Component::particle_mass, Component::particle_material, Component::contact_geometry});
  static constexpr ComponentMask writes = mask_of({Component::contact_rolling, Component::contact_forces});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

}  // namespace sandcell
