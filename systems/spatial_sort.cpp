#include "systems/spatial_sort.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace sandcell {

namespace {
// Spreads the low 21 bits of v so that there are two zero bits between each.
std::uint64_t spread3(std::uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}
}  // namespace

void spatial_sort(State& state) {
  Particles& p = state.particles;
  const std::size_t n = p.size();
  const Vec3 inv_length = state.cell.length.cwiseInverse();
  std::vector<std::pair<std::uint64_t, ParticleId>> key(n);
  for (std::size_t k = 0; k < n; ++k) {
    std::uint64_t code = 0;
    for (int a = 0; a < 3; ++a) {
      const double s = std::clamp(p.position[k][a] * inv_length[a], 0.0, 1.0);
      code |= spread3(static_cast<std::uint64_t>(s * 1048575.0)) << a;
    }
    key[k] = {code, p.id[k]};
  }
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
  std::vector<std::uint32_t> new_index(n);
  for (std::uint32_t k = 0; k < n; ++k) new_index[order[k]] = k;
  if (p.reference_position.size() != n) p.reference_position.resize(n);
  reorder(p, order);
  ContactPairs& pairs = state.contacts.pairs;
  for (std::size_t c = 0; c < pairs.size(); ++c) {
    pairs.i[c] = new_index[pairs.i[c]];
    pairs.j[c] = new_index[pairs.j[c]];
  }
  pairs.reference_length.setZero();  // indices changed: the broadphase rebuilds this step
}

void SpatialSort::run(const Model& model, State& state, Scratch&, Executor&) {
  // The clock is advanced by World between steps only; reading it here is race-free.
  if (model.contact.sort_interval <= 0 || state.clock.step % model.contact.sort_interval != 0) return;
  // spatial_sort permutes every particle array through the field registry (all declared as
  // written) and remaps the pair indices (contact_pairs, declared).
  spatial_sort(state);
}

}  // namespace sandcell
