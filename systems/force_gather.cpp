#include "systems/force_gather.hpp"

#include "systems/halo.hpp"
#include "systems/integrate.hpp"
#include "systems/pair_list.hpp"


namespace sandcell {

namespace {
// The sums of particles [b, e) of the visiting order. With a halo (Halo::active), entries of
// j_entry at or above m name a slot of the halo's copies instead of a pair.
template <bool UseHalo>
void gather(std::size_t b, std::size_t e, const GatherIndex& index, const std::uint32_t* __restrict j_entry,
            const ContactForces& in, const Halo& halo, Vec3* __restrict out_f, Vec3* __restrict out_t) {
  const Vec3* __restrict f = in.force.data();
  const Vec3* __restrict t_i = in.torque_i.data();
  const Vec3* __restrict t_j = in.torque_j.data();
  const Vec3* __restrict sf = halo.sf.data();
  const Vec3* __restrict st = halo.st.data();
  const std::uint32_t m = static_cast<std::uint32_t>(in.force.size());
  const std::uint32_t* __restrict i_start = index.i_start.data();
  const std::uint32_t* __restrict j_start = index.j_start.data();
  const std::uint32_t* __restrict visit = index.visit.data();
  for (std::size_t o = b; o < e; ++o) {
    const std::uint32_t p = visit[o];  // a permutation within blocks (GatherIndex)
    Vec3 fs = Vec3::Zero();
    Vec3 ts = Vec3::Zero();
    // As i: a contiguous run of pair slots.
    for (std::uint32_t k = i_start[p]; k < i_start[p + 1]; ++k) {
      fs += f[k];
      ts += t_i[k];
    }
    // As j: listed slots, ascending.
    for (std::uint32_t q = j_start[p]; q < j_start[p + 1]; ++q) {
      const std::uint32_t k = j_entry[q];
      if constexpr (UseHalo) {
        fs -= *(k < m ? f + k : sf + (k - m));
        ts += *(k < m ? t_j + k : st + (k - m));
      } else {
        fs -= f[k];
        ts += t_j[k];
      }
    }
    out_f[p] = fs;
    out_t[p] = ts;
  }
}
}  // namespace

void ForceGather::run(const Model&, State& state, Scratch& scratch, Executor& exec) {
  const ContactForces& in = state.read<Component::contact_forces>();
  const GatherIndex& index = scratch.read<GatherIndex>();
  const Halo& halo = scratch.read<Halo>();
  auto& force = state.write<Component::particle_force>();
  auto& torque = state.write<Component::particle_torque>();
  Vec3* out_f = force.data();
  Vec3* out_t = torque.data();
  // Under the owner partition a crossing pair's force and torque on j come from the halo's slots
  // (systems/halo.hpp), which the contact pass of this step filled.
  if (halo.active && halo.m == in.force.size() && halo.n == force.size()) {
    exec.parallel_for(force.size(), k_particle_grain, [&](std::size_t b, std::size_t e) {
      gather<true>(b, e, index, halo.j_entry.data(), in, halo, out_f, out_t);
    });
  } else {
    exec.parallel_for(force.size(), k_particle_grain, [&](std::size_t b, std::size_t e) {
      gather<false>(b, e, index, index.j_entry.data(), in, halo, out_f, out_t);
    });
  }
}

}  // namespace sandcell
