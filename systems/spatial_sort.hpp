#pragma once
// spatial_sort: every `contact.sort_interval` steps, reorders the particle arrays along a Morton
// (Z-order) curve of their positions, so that particles close in space are close in memory and
// the contact pass reads its particle data from cache. On dense-20k (packing in insertion order)
// this raised throughput by a fifth when it was introduced (docs/performance.md).
//
// Reads and writes every particle component (a permutation of all of them) and the pair list
// (indices i, j remapped; the list is marked for a rebuild, which the broadphase does in the same
// step, carrying history by ids). Ids never change. The order is a pure function of the positions
// and ids (ties broken by id), so it is the same for any thread count. Not scheduled when
// sort_interval is 0.
#include "engine/system.hpp"

namespace sandcell {

struct SpatialSort {
  static constexpr std::string_view name = "spatial_sort";
  static constexpr ComponentMask reads = mask_of({Component::cell});
  static constexpr ComponentMask writes =
      mask_of({Component::particle_id, Component::particle_position, Component::particle_velocity,
               Component::particle_angular_velocity, Component::particle_force, Component::particle_torque,
               Component::particle_radius, Component::particle_mass, Component::particle_inv_inertia,
               Component::particle_material, Component::particle_reference, Component::contact_pairs});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

/// Sorts now, whatever the interval (scene setup, tests).
void spatial_sort(State& state);

}  // namespace sandcell
