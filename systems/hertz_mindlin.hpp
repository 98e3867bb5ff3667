#pragma once
// hertz_mindlin: Hertz normal force with viscous damping and Mindlin no-slip tangential force with
// Coulomb cap (DESIGN 3.2), as LIGGGHTS `model hertz tangential history`, or with an incremental
// force history (ContactSettings::tangential).
//
// Reads the pair list, positions, fluctuating and angular velocities, radii, masses, materials and
// the cell. Writes, per pair slot: the force on i and the torques on i and j (contact_forces), the
// tangential history (contact_tangential), and the geometry the rolling system needs
// (contact_geometry). One parallel_for over pairs; each pair writes only its own slots.
// Relative velocity at the contact includes the affine part D r unless liggghts_compat.
// Separated pairs get zero force and zero history.
#include "engine/system.hpp"

namespace sandcell {

struct HertzMindlin {
  static constexpr std::string_view name = "hertz_mindlin";
  static constexpr ComponentMask reads =
      mask_of({Component::contact_pairs, Component::particle_position, Component::particle_velocity,
               Component::particle_angular_velocity, Component::particle_radius, Component::particle_mass,
               Component::particle_material, Component::cell});
  static constexpr ComponentMask writes =
      mask_of({Component::contact_forces, Component::contact_tangential, Component::contact_geometry});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

/// Pairs per parallel_for chunk for per-contact loops.
inline constexpr std::size_t k_contact_grain = 4096;

}  // namespace sandcell
