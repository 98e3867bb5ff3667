#pragma once
// Scratch: rebuilt every step or every neighbour rebuild; never checkpointed. Buffers keep their
// capacity between steps so nothing is allocated inside a step once warmed up.
// Systems reach the shared parts through read<C>() / write<C>() (checked like State access);
// a system's private buffers (e.g. the broadphase bins) are its own business.
#include "components/contacts.hpp"
#include "components/types.hpp"
#include "components/fields.hpp"
#include "engine/access.hpp"

#include <cstdint>
#include <string>
#include <array>
#include <vector>

namespace sandcell {

/// Index from particles to their pair slots, for the fixed-order per-particle force gather.
/// The pair list is sorted by i, so the pairs where particle k is i are the contiguous range
/// [i_start[k], i_start[k+1]); the pairs where it is j are listed in j_entry (CSR by j_start),
/// in ascending pair order.
/// The gather visits the particles of each block of k_gather_block consecutive ones sorted by their
/// two counts: the loops over a particle's pairs then run the same number of times for several
/// particles in a row, and their exits are predicted (in array order the counts vary at random
/// and nearly every exit is mispredicted), while the block keeps the memory locality of the array
/// order. Each particle's sum is the same whatever the visiting order.
inline constexpr std::size_t k_gather_block = 128;

struct GatherIndex {
  std::vector<std::uint32_t> i_start;  // (n+1) -, pair range of particle k as i; broadphase
  std::vector<std::uint32_t> j_start;  // (n+1) -, j_entry range of particle k as j; broadphase
  std::vector<std::uint32_t> j_entry;  // (m) -, pair indices, ascending within a particle; broadphase
  std::vector<std::uint32_t> fill;     // (n) -, cursor buffer of the counting sort (kept: no allocation per build)
  std::vector<std::uint32_t> visit;    // (n) -, particle indices in the order the gather visits them; broadphase
};

/// Per-pair constants of the contact law that depend only on the two spheres (radii and masses
/// never change) and the pair's image: computed when the list is built, so the contact pass
/// reads them in pair order instead of loading both spheres' radii and masses and dividing for
/// R* and m* every step, and takes the image shift H n from a table of the 27 images instead of
/// converting and multiplying three integers. R* is kept although R_i and R_j are: it saves a
/// division per pair and step.
struct PairConstants {
  std::vector<double> r_i, r_j;  // (m) m, radii of the two spheres; broadphase
  std::vector<double> r_star;    // (m) m, R* = R_i R_j / (R_i + R_j); broadphase
  std::vector<double> m_star;    // (m) kg, m* = m_i m_j / (m_i + m_j); broadphase
  std::vector<std::uint8_t> image_code;  // (m) -, the image (each of -1, 0, 1) as 9 (I_z+1) + 3 (I_y+1) + I_x+1
  std::uint64_t generation = 0;          // -, counts rebuilds: per-pair hints kept elsewhere know the list changed
};

/// Broadphase private buffers and statistics.
struct BroadphaseScratch {
  std::vector<std::uint32_t> bin_start;     // (n_bins+1) -, CSR of particles per bin
  std::vector<std::uint32_t> bin_particle;  // (n) -, particle indices sorted by bin
  std::vector<std::uint32_t> particle_bin;  // (n) -, bin of each particle
  std::vector<std::uint32_t> count;         // (n) -, new pairs per particle i
  std::vector<std::uint32_t> start;         // (n+1) -, prefix sum of count
  std::vector<std::uint32_t> old_start;     // (n+1) -, ranges of old_order per particle i
  std::vector<std::uint32_t> old_order;     // (m_old) -, previous list's pair indices grouped by i
  std::vector<std::array<int, 3>> shift;    // (n) -, cell lengths the last wrap subtracted from each position
  ContactPairs next_pairs;                  // the list being built, swapped with the State's
  std::vector<Vec3> next_tangential;        // (m,3) history for the list being built
  std::vector<Vec3> next_rolling;           // (m,3) rolling history for the list being built
  double cutoff = 0.0;                      // m, 2 r_max + skin of the last build
  double r_min = 0.0;                       // m, smallest radius (0: not yet known)
  std::uint64_t builds = 0;                 // neighbour-list builds so far
  std::string error;                        // set when the scene cannot be continued; checked by World
};

/// Contact pass private buffers: last step's regime of each pair and the order in which the pass
/// visits the pairs of each block of 64 (hertz_mindlin.cpp says why). Every pair is visited once
/// whatever the order and writes only its own slots. One regime is more than a hint: an open pair
/// marked apart is not written again, its outputs being zero since it opened; so the regimes hold
/// for one list only (a new list, PairConstants::generation, starts them again) and a World made
/// from a state starts without them. Not checkpointed.
struct ContactScratch {
  static constexpr std::uint8_t k_apart = 4;  // regime of an open pair: its outputs and histories zero since it opened
  std::vector<std::uint8_t> regime;  // (m) -, pair k in the last step: bit 0 Coulomb cap, bit 1 rolling cap;
                                     //   or k_apart
  std::vector<std::uint8_t> order;   // (m) -, per block, a permutation of its pair offsets 0..63
  std::vector<std::uint8_t> stale;   // (blocks) -, 1: a regime in the block changed, sort it again
  std::vector<std::uint8_t> sorted;  // (blocks) -, 1: visit in `order`; 0: all touching, none capped: array order
  std::uint64_t generation = ~std::uint64_t{0};  // -, PairConstants::generation the regimes describe
};

template <Component C>
struct ScratchField;

/// The stress measured by the homogenizer on servo steps, for the servo of the same step.
struct MeasuredStress {
  Mat3 stress = Mat3::Zero();  // (3,3) Pa, symmetrized, compression positive (docs/physics.md section 5)
  std::uint64_t step = ~std::uint64_t{0};  // clock step at which it was measured (none: max)
};

class Scratch {
 public:
  GatherIndex gather;
  PairConstants pair;
  MeasuredStress measured;
  BroadphaseScratch broadphase;
  ContactScratch contact;
  // True while forces are evaluated at scene setup: contact laws then leave their history untouched
  // (as LAMMPS/LIGGGHTS do in `run 0` setup), so setting up a scene does not advance it.
  bool setup = false;
  // The final half kick of a step and the first half kick of the next use the same forces, and
  // nothing in between reads velocities. Within one World::step_until call, integrate_final sets
  // `kick_pending` instead of kicking, and the next integrate_initial applies both kicks in one
  // pass over the particles (the same two additions in the same order: bitwise the same as two
  // passes); World applies the last step's kick before returning. World sets `defer_final_kick`
  // for the length of the call, where the graph allows it (World::defers_final_kick).
  bool defer_final_kick = false;
  bool kick_pending = false;

  template <Component C>
  const auto& read() const {
    check_access(C, false);
    return ScratchField<C>::get(*this);
  }
  template <Component C>
  auto& write() {
    check_access(C, true);
    return ScratchField<C>::get(*this);
  }
};

template <>
struct ScratchField<Component::gather_index> {
  template <class S>
  static auto& get(S& s) { return s.gather; }
};

template <>
struct ScratchField<Component::pair_constants> {
  template <class S>
  static auto& get(S& s) { return s.pair; }
};

template <>
struct ScratchField<Component::stress> {
  template <class S>
  static auto& get(S& s) { return s.measured; }
};

}  // namespace sandcell
