#pragma once
// broadphase: the neighbour (candidate pair) list over the periodic cell (orthorhombic or tilted,
// components/cell.hpp), with a Verlet skin, rebuilt only when needed, and the history carried from
// the old list to the new.
//
// Reads radii, ids and the cell. Writes the cell's tilts and flips (a flip at a build), positions (wrapped into the cell at each build, the only
// place they are wrapped in a scene with contacts), the pair list (contact_pairs), the history
// arrays (every per-contact history of the field registry) when it rebuilds, the per-particle reference
// positions of the last build and the CSR gather index.
//
// Rebuild test (every step, O(n)): with reduced coordinates s = H^-1 x, a pair's branch vector
// changes since the last build by the particles' non-affine displacements |H (s - s_ref)| (at most
// d_max each) plus the affine stretch of the branch itself, at most max_k |L_k/L_ref_k - 1| (a tilted
// cell: the Frobenius norm of H H_ref^-1 - I) times the cutoff. Pairs left out at the build were farther than r_i + r_j + skin, so the list stays
// complete while 2 d_max + stretch * (2 r_max + skin) <= skin. This also covers a deforming cell.
//
// Build: first a flip when a tilt is past half a length (another basis of the same lattice; each old
// image re-expressed in it, so histories carry over); bins of width >= 2 r_max + skin, measured
// between faces, in reduced coordinates; each particle looks at the 27
// neighbouring bins with their integer image shifts (distinct even with 1 or 2 bins per axis, so a
// pair touching through several images gets one entry per image). Pairs are kept once, from the
// particle with the smaller id, and sorted by (i, id_j, image) per particle i: a canonical order
// that does not depend on the thread count. History of a pair (id_i, id_j, image) present in the
// old list is copied; new pairs start with zero history.
// Instability: a displacement since the build beyond skin/2 + r_min means some particle moved
// farther than the smallest radius in the last step (the step before passed the test), so contacts
// may have been passed through; a non-finite position is worse. Either sets
// Scratch::error naming the particle (World stops with it): never a NaN silently stepped.
// The cell must be wider than 2 r_max + skin on every axis: otherwise a particle could meet its
// own image; the system then sets Scratch::error and World stops with that message.
#include "systems/pair_list.hpp"

#include "engine/system.hpp"

#include <array>
#include <string>
#include <vector>

namespace sandcell {

/// The broadphase's private buffers and statistics (Scratch::own).
struct BroadphaseScratch {
  std::vector<std::uint32_t> bin_start;         // (n_bins+1) -, CSR of particles per bin
  std::vector<std::uint32_t> bin_particle;      // (n) -, particle indices sorted by bin
  std::vector<std::uint32_t> particle_bin;      // (n) -, bin of each particle
  std::vector<std::uint32_t> count;             // (n) -, new pairs per particle i
  std::vector<std::uint32_t> start;             // (n+1) -, prefix sum of count
  std::vector<std::uint32_t> old_start;         // (n+1) -, ranges of old_order per particle i
  std::vector<std::uint32_t> old_order;         // (m_old) -, previous list's pair indices grouped by i
  std::vector<std::array<int, 3>> shift;        // (n) -, cell lengths the last wrap subtracted from each position
  ContactPairs next_pairs;                      // the list being built, swapped with the State's
  std::vector<std::vector<double>> next_scalar_history;  // (scalar histories)(m) the same for scalar histories
  std::vector<std::vector<Vec3>> next_history;  // (histories)(m,3) the per-contact histories for the list
                                                //   being built (components/fields.hpp: for_each_contact_history)
  double cutoff = 0.0;                          // m, 2 r_max + skin of the last build
  double r_min = 0.0;                           // m, smallest radius (0: not yet known)
  std::uint64_t builds = 0;                     // neighbour-list builds so far
  std::vector<Vec3> reference_reduced;          // (n) -, H_ref^-1 x_ref: the build's positions in reduced
                                                //   coordinates, only while the cell is tilted
  std::uint64_t reduced_for_build = 0;          // the build reference_reduced belongs to
};

/// The components of every per-contact history (components/fields.hpp).
constexpr ComponentMask contact_history_mask() {
  ComponentMask m = 0;
  for (Component c : k_contact_history_components) m |= mask_of(c);
  return m;
}

struct Broadphase {
  static constexpr std::string_view name = "broadphase";
  static constexpr ComponentMask reads =
      mask_of({Component::particle_id, Component::particle_radius, Component::particle_mass});
  static constexpr ComponentMask writes =
      mask_of({Component::particle_position, Component::contact_pairs, Component::particle_reference,
               Component::gather_index, Component::pair_constants, Component::cell}) |
      contact_history_mask();
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
  /// The first list (build_neighbor_list).
  static void setup(const Model& model, State& state, Scratch& scratch, Executor& exec);
  /// The gather index and pair constants of the list a state holds (rebuild_gather_index,
  /// rebuild_pair_constants).
  static void restore(const Model& model, State& state, Scratch& scratch);
};

/// Neighbour-list builds so far in a scene (0 before its first).
inline std::uint64_t list_builds(const Scratch& scratch) {
  return scratch.has<BroadphaseScratch>() ? scratch.own<BroadphaseScratch>().builds : 0;
}

/// Rebuilds the CSR gather index from the pair list alone (which is sorted by i): for a World made
/// from a state that already holds its list and forces (a checkpoint, the next stage of a test).
void rebuild_gather_index(const ContactPairs& pairs, std::size_t n_particles, GatherIndex& gather);

/// Recomputes the per-pair constants (radii, R*, m*, image code) of the list; same use.
void rebuild_pair_constants(const ContactPairs& pairs, const std::vector<double>& radius,
                            const std::vector<double>& mass, PairConstants& out);

/// Builds the list unconditionally (used at scene start and by tests).
void build_neighbor_list(const Model& model, State& state, Scratch& scratch, Executor& exec);

}  // namespace sandcell
