#include "systems/force_gather.hpp"

#include "systems/integrate.hpp"
#include "systems/pair_list.hpp"

namespace sandcell {

void ForceGather::run(const Model&, State& state, Scratch& scratch, Executor& exec) {
  const ContactForces& in = state.read<Component::contact_forces>();
  const GatherIndex& index = scratch.read<GatherIndex>();
  auto& force = state.write<Component::particle_force>();
  auto& torque = state.write<Component::particle_torque>();
  const Vec3* __restrict f = in.force.data();
  const Vec3* __restrict t_i = in.torque_i.data();
  const Vec3* __restrict t_j = in.torque_j.data();
  const std::uint32_t* __restrict i_start = index.i_start.data();
  const std::uint32_t* __restrict j_start = index.j_start.data();
  const std::uint32_t* __restrict j_entry = index.j_entry.data();
  const std::uint32_t* __restrict visit = index.visit.data();
  Vec3* __restrict out_f = force.data();
  Vec3* __restrict out_t = torque.data();
  exec.parallel_for(force.size(), k_particle_grain, [&](std::size_t b, std::size_t e) {
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
        fs -= f[k];
        ts += t_j[k];
      }
      out_f[p] = fs;
      out_t[p] = ts;
    }
  });
}

}  // namespace sandcell
