#pragma once
// The halo of the owner partition (Partition::owner with more than one share): what one thread
// reads of another's data each step, copied once per step into buffers laid out in the order the
// reader walks them, as the MPI codes exchange their ghost atoms.
//
// Under the owner partition thread s integrates and gathers the particles of its share (a range of
// the Morton order) and computes the pairs whose i it owns. A pair whose j another thread owns
// (a pair across the boundary between two shares; a few percent of the list) needs that thread's
// positions and velocities of j, and its force and torque on j are summed by that thread. Read in
// place, these are cache lines scattered through the other core's arrays, each fetched on demand
// in the middle of the contact law; where the two cores do not share a cache (docs/performance.md
// measured ~190 ns a line on the development machine) that cost a fifth of the step. With the
// halo:
// - ghosts: at the start of the contact pass, each thread copies the position, velocity and
//   angular velocity of its particles that other threads' pairs read into ghost slots, numbered in
//   the order the reading thread's pairs use them; the pass reads j through `pj` (j, or n + ghost
//   slot), so the reader streams through a packed buffer;
// - slots: the thread computing a crossing pair copies its force and torque on j into a slot
//   buffer, numbered in the order the gathering thread visits them; the gather reads the pair's
//   slot through `j_entry` (k, or m + slot).
// The copies are exact, so every sum and every result is bitwise the same as without the halo,
// for any number of threads. Built by the contact pass when the pair list, the particle count or
// the shares change (a serial O(n + m) pass, once per list).
#include "components/fields.hpp"
#include "components/types.hpp"
#include "engine/executor.hpp"

#include <cstdint>
#include <vector>

namespace sandcell {

struct ContactPairs;
struct GatherIndex;

struct Halo {
  static constexpr Component component = Component::halo;
  bool active = false;                           // built for more than one share
  std::uint64_t generation = ~std::uint64_t{0};  // -, PairConstants::generation it was built for
  std::size_t n = 0, m = 0;                      // -, particles and pairs it was built for
  Executor::Shares particles;                    // -, the particle shares (Executor::shares)
  Executor::Shares pairs;                        // -, the pair shares: pairs whose i a share owns (block-aligned)
  Executor::Shares exports;                      // -, ranges of export_ghost by exporting share
  std::vector<std::uint32_t> pj;                 // (m) -, j, or n + ghost slot for a pair whose j another share owns
  std::vector<std::uint8_t> ghost_block;         // (m / 64 blocks) -, 1: a pair of the block reads a ghost
  std::vector<std::uint32_t> ghost_of;           // (ghosts) -, the particle each ghost slot copies
  std::vector<std::uint32_t> export_ghost;       // (ghosts) -, ghost slots grouped by the share owning their particle
  std::vector<Vec3> gx, gv, gw;          // (ghosts) m, m/s, rad/s: copies of position, velocity, angular velocity
  std::vector<std::uint32_t> j_entry;    // (m) -, GatherIndex::j_entry with a crossing pair's k replaced by m + slot
  std::vector<std::uint32_t> slot_pair;  // (slots) -, the pair each slot copies, ascending
  std::vector<std::uint32_t> slot_of;    // (slots) -, its slot, in the order of slot_pair
  std::vector<Vec3> sf, st;              // (slots) N, N m: copies of the force on i and the torque on j
  std::vector<std::uint32_t> stamp;      // (n) -, build buffer: share + 1 that last gave a particle a ghost
  std::vector<std::uint32_t> ghost_at;   // (n) -, build buffer: that share's ghost slot of the particle
  std::vector<std::uint32_t> slot_at;    // (m) -, build buffer
};

/// Builds the halo of `pairs` for the particle shares `particles` (inactive for one share).
/// The pair shares' bounds are rounded down to multiples of `pair_align` (the pass's blocks), and
/// ghost_block flags the blocks of `pair_align` pairs with a ghost.
void rebuild_halo(const ContactPairs& pairs, const GatherIndex& index, const Executor::Shares& particles,
                  std::size_t pair_align, std::uint64_t generation, Halo& halo);

/// The share of `shares` that index k falls in.
inline std::size_t share_of(const Executor::Shares& shares, std::size_t k) {
  std::size_t s = 0;
  while (s + 1 < shares.count && k >= shares.bounds[s + 1]) ++s;
  return s;
}

}  // namespace sandcell
