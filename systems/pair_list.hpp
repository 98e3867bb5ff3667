#pragma once
// Scratch the broadphase builds with each pair list and the systems after it read (engine/scratch.hpp:
// shared scratch types, reached through Scratch::read<T>() / write<T>() under their component).
#include "components/fields.hpp"
#include "components/types.hpp"

#include <cstdint>
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
  static constexpr Component component = Component::gather_index;
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
  static constexpr Component component = Component::pair_constants;
  std::vector<double> r_i, r_j;          // (m) m, radii of the two spheres; broadphase
  std::vector<double> r_star;            // (m) m, R* = R_i R_j / (R_i + R_j); broadphase
  std::vector<double> m_star;            // (m) kg, m* = m_i m_j / (m_i + m_j); broadphase
  std::vector<std::uint8_t> image_code;  // (m) -, the image (each of -1, 0, 1) as 9 (I_z+1) + 3 (I_y+1) + I_x+1
  std::uint64_t generation = 0;          // -, counts rebuilds: per-pair hints kept elsewhere know the list changed
};

}  // namespace sandcell
