#pragma once
// broadphase: the neighbour (candidate pair) list over the orthorhombic periodic cell, with a
// Verlet skin, rebuilt only when needed, and the history carried from the old list to the new.
//
// Reads radii, ids and the cell. Writes positions (wrapped into the cell at each build, the only
// place they are wrapped in a scene with contacts), the pair list (contact_pairs), the history
// arrays (contact_tangential, contact_rolling) when it rebuilds, the per-particle reference
// positions of the last build and the CSR gather index.
//
// Rebuild test (every step, O(n)): with reduced coordinates s = x / L, a pair's branch vector
// changes since the last build by the particles' non-affine displacements |L (s - s_ref)| (at most
// d_max each) plus the affine stretch of the branch itself, at most max_k |L_k/L_ref_k - 1| times
// the cutoff. Pairs left out at the build were farther than r_i + r_j + skin, so the list stays
// complete while 2 d_max + stretch * (2 r_max + skin) <= skin. This also covers a deforming cell.
//
// Build: bins of width >= 2 r_max + skin in reduced coordinates; each particle looks at the 27
// neighbouring bins with their integer image shifts (distinct even with 1 or 2 bins per axis, so a
// pair touching through several images gets one entry per image). Pairs are kept once, from the
// particle with the smaller id, and sorted by (i, id_j, image) per particle i: a canonical order
// that does not depend on the thread count. History of a pair (id_i, id_j, image) present in the
// old list is copied; new pairs start with zero history.
// Instability: a displacement since the build beyond skin/2 + r_min means some particle moved
// farther than the smallest radius in the last step (the step before passed the test), so contacts
// may have been passed through; a non-finite position is worse. Either sets
// scratch.broadphase.error naming the particle (World stops with it): never a NaN silently stepped.
// The cell must be wider than 2 r_max + skin on every axis: otherwise a particle could meet its
// own image; the system then sets scratch.broadphase.error and World stops with that message.
#include "engine/system.hpp"

namespace sandcell {

struct Broadphase {
  static constexpr std::string_view name = "broadphase";
  static constexpr ComponentMask reads =
      mask_of({Component::particle_id, Component::particle_radius, Component::particle_mass, Component::cell});
  static constexpr ComponentMask writes =
      mask_of({Component::particle_position, Component::contact_pairs, Component::contact_tangential, Component::contact_rolling,
               Component::particle_reference, Component::gather_index, Component::pair_constants});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

/// Rebuilds the CSR gather index from the pair list alone (which is sorted by i): for a World made
/// from a state that already holds its list and forces (a checkpoint, the next stage of a test).
void rebuild_gather_index(const ContactPairs& pairs, std::size_t n_particles, GatherIndex& gather);

/// Recomputes the per-pair constants (radii, R*, m*, image code) of the list; same use.
void rebuild_pair_constants(const ContactPairs& pairs, const std::vector<double>& radius,
                            const std::vector<double>& mass, PairConstants& out);

/// Builds the list unconditionally (used at scene start and by tests).
void build_neighbor_list(const Model& model, State& state, Scratch& scratch, Executor& exec);

}  // namespace sandcell
