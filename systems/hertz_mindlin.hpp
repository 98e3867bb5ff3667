#pragma once
// hertz_mindlin: the contact pass. Hertz normal force with viscous damping and Mindlin no-slip
// tangential force with a Coulomb cap (docs/physics.md section 2), as LIGGGHTS `model hertz tangential history`,
// or with an incremental force history (ContactSettings::tangential); plus the rolling resistance
// evaluator of systems/rolling.hpp when the model has one (docs/physics.md section 3).
//
// Reads the pair list, positions, fluctuating and angular velocities, masses (epsd rolling),
// materials, the cell and the per-pair constants (radii, R*, m*, image code) of the list. Writes,
// per pair slot, the force on i and the torques on i and j (contact_forces), the tangential history
// (contact_tangential) and the rolling history (contact_rolling). One parallel_for over pairs; each
// pair writes only its own slots, so no atomics are needed and the per-particle sums are left to
// force_gather in a fixed order. Keeps, as its own scratch (Scratch::contact), each pair's regime
// of the last step (caps, or open) and the order in which it visits the pairs of a block: the
// order is a branch hint that changes no result; an open pair marked open is not written again,
// so the regimes are started again with every new pair list (hertz_mindlin.cpp).
// The relative velocity at the contact includes the affine part D r unless liggghts_compat.
// Pairs in the list that do not touch get zero force and zero history (history resets when a
// contact opens). The law is instantiated per (tangential model, rolling model, affine term), so
// the hot loop has no run-time switches.
#include "engine/system.hpp"

namespace sandcell {

struct HertzMindlin {
  static constexpr std::string_view name = "hertz_mindlin";
  static constexpr ComponentMask reads =
      mask_of({Component::contact_pairs, Component::particle_position, Component::particle_velocity,
               Component::particle_angular_velocity, Component::particle_mass,
               Component::particle_material, Component::cell, Component::pair_constants});
  static constexpr ComponentMask writes =
      mask_of({Component::contact_forces, Component::contact_tangential, Component::contact_rolling});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

/// Pairs per parallel_for chunk for per-contact loops (1024: ~76 chunks on the 20k benchmark, so
/// the last chunk leaves a thread idle for less of the pass than with 4096).
inline constexpr std::size_t k_contact_grain = 1024;

}  // namespace sandcell
