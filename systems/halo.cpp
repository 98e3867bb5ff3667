#include "systems/halo.hpp"

#include "components/contacts.hpp"
#include "systems/pair_list.hpp"

#include <algorithm>
#include <limits>

namespace sandcell {

namespace {
constexpr std::uint32_t k_none = std::numeric_limits<std::uint32_t>::max();

// Ghost slots in the order each share's pairs first read them; exports grouped by owner.
void build_ghosts(const ContactPairs& pairs, std::size_t block, Halo& halo) {
  const std::size_t n = halo.n, shares = halo.particles.count;
  halo.pj.resize(halo.m);
  halo.stamp.assign(n, 0);
  halo.ghost_at.resize(n);
  halo.ghost_of.clear();
  for (std::size_t s = 0; s < shares; ++s) {
    for (std::size_t k = halo.pairs.bounds[s]; k < halo.pairs.bounds[s + 1]; ++k) {
      const std::uint32_t j = pairs.j[k];
      if (share_of(halo.particles, j) == s) {
        halo.pj[k] = j;
        continue;
      }
      if (halo.stamp[j] != s + 1) {
        halo.stamp[j] = static_cast<std::uint32_t>(s + 1);
        halo.ghost_at[j] = static_cast<std::uint32_t>(halo.ghost_of.size());
        halo.ghost_of.push_back(j);
      }
      halo.pj[k] = static_cast<std::uint32_t>(n + halo.ghost_at[j]);
    }
  }
  halo.ghost_block.assign((halo.m + block - 1) / block, 0);
  for (std::size_t k = 0; k < halo.m; ++k)
    if (halo.pj[k] >= n) halo.ghost_block[k / block] = 1;
  const std::size_t ghosts = halo.ghost_of.size();
  halo.exports = Executor::Shares{};
  halo.exports.count = shares;
  for (std::size_t g = 0; g < ghosts; ++g) ++halo.exports.bounds[share_of(halo.particles, halo.ghost_of[g]) + 1];
  for (std::size_t s = 0; s < shares; ++s) halo.exports.bounds[s + 1] += halo.exports.bounds[s];
  halo.export_ghost.resize(ghosts);
  Executor::Shares fill = halo.exports;
  for (std::size_t g = 0; g < ghosts; ++g)
    halo.export_ghost[fill.bounds[share_of(halo.particles, halo.ghost_of[g])]++] = static_cast<std::uint32_t>(g);
  halo.gx.resize(ghosts);
  halo.gv.resize(ghosts);
  halo.gw.resize(ghosts);
}

// Slots in the order each share's gather visits them; the copy list sorted by pair.
void build_slots(const GatherIndex& index, Halo& halo) {
  const std::size_t m = halo.m, shares = halo.particles.count;
  halo.j_entry = index.j_entry;
  halo.slot_at.assign(m, k_none);
  std::uint32_t slots = 0;
  for (std::size_t r = 0; r < shares; ++r) {
    for (std::size_t o = halo.particles.bounds[r]; o < halo.particles.bounds[r + 1]; ++o) {
      const std::uint32_t p = index.visit[o];
      for (std::uint32_t q = index.j_start[p]; q < index.j_start[p + 1]; ++q) {
        const std::uint32_t k = index.j_entry[q];
        if (share_of(halo.pairs, k) == r) continue;
        halo.slot_at[k] = slots;
        halo.j_entry[q] = static_cast<std::uint32_t>(m + slots);
        ++slots;
      }
    }
  }
  halo.slot_pair.clear();
  halo.slot_of.clear();
  for (std::size_t k = 0; k < m; ++k) {
    if (halo.slot_at[k] == k_none) continue;
    halo.slot_pair.push_back(static_cast<std::uint32_t>(k));
    halo.slot_of.push_back(halo.slot_at[k]);
  }
  halo.sf.resize(slots);
  halo.st.resize(slots);
}
}  // namespace

void rebuild_halo(const ContactPairs& pairs, const GatherIndex& index, const Executor::Shares& particles,
                  std::size_t pair_align, std::uint64_t generation, Halo& halo) {
  const std::size_t n = index.i_start.empty() ? 0 : index.i_start.size() - 1;
  const std::size_t m = pairs.size();
  halo.generation = generation;
  halo.n = n;
  halo.m = m;
  halo.particles = particles;
  // Indices n + ghost and m + slot must fit the 32-bit pair and entry arrays.
  halo.active = particles.count > 1 && index.i_start.size() == n + 1 && index.i_start[n] == m &&
                2 * static_cast<std::uint64_t>(std::max(n, m)) < k_none;
  if (!halo.active) return;
  halo.pairs = Executor::Shares{};
  halo.pairs.count = particles.count;
  for (std::size_t s = 1; s < particles.count; ++s)
    halo.pairs.bounds[s] =
        std::max(halo.pairs.bounds[s - 1], index.i_start[particles.bounds[s]] / pair_align * pair_align);
  halo.pairs.bounds[particles.count] = m;
  build_ghosts(pairs, pair_align, halo);
  build_slots(index, halo);
}

}  // namespace sandcell
