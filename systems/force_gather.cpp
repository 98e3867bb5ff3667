#include "systems/force_gather.hpp"

#include "systems/halo.hpp"
#include "systems/integrate.hpp"
#include "systems/pair_list.hpp"

#include <algorithm>
#include <chrono>


namespace sandcell {

namespace {
// Particles ahead at which the array order asks for the pair slots of a particle's j entries:
// 8 ran the 160,000-sphere scene's gather in 0.82x the time of no prefetch on 1 thread (2-core
// host, 2026-11-29; experiments/2026-11-29-gather-order). In the sorted order the prefetch gained
// nothing (1.00x), so that order goes without it.
constexpr std::size_t k_ahead = 8;

// The sums of particles [b, e) of the visiting order (Sorted: GatherIndex::visit; else the array
// order). With a halo (Halo::active), entries of j_entry at or above m name a slot of the halo's
// copies instead of a pair.
template <bool UseHalo, bool Sorted>
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
    if constexpr (!Sorted) {
      if (o + k_ahead < e) {
        const std::size_t a = o + k_ahead;
        for (std::uint32_t q = j_start[a]; q < j_start[a + 1]; ++q) {
          const std::uint32_t k = j_entry[q];
          if (!UseHalo || k < m) {
            __builtin_prefetch(f + k);
            __builtin_prefetch(t_j + k);
          } else {
            __builtin_prefetch(sf + (k - m));
            __builtin_prefetch(st + (k - m));
          }
        }
      }
    }
    const std::uint32_t p = Sorted ? visit[o] : static_cast<std::uint32_t>(o);  // visit: a permutation within blocks
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

template <bool Sorted>
void gather_all(const ContactForces& in, const GatherIndex& index, const Halo& halo, Vec3* out_f, Vec3* out_t,
                std::size_t n, Executor& exec) {
  // Under the owner partition a crossing pair's force and torque on j come from the halo's slots
  // (systems/halo.hpp), which the contact pass of this step filled.
  if (halo.active && halo.m == in.force.size() && halo.n == n) {
    exec.parallel_for(n, k_particle_grain, [&](std::size_t b, std::size_t e) {
      gather<true, Sorted>(b, e, index, halo.j_entry.data(), in, halo, out_f, out_t);
    });
  } else {
    exec.parallel_for(n, k_particle_grain, [&](std::size_t b, std::size_t e) {
      gather<false, Sorted>(b, e, index, index.j_entry.data(), in, halo, out_f, out_t);
    });
  }
}

double median_of(std::array<double, GatherTrials::k_trial> t) {
  std::nth_element(t.begin(), t.begin() + t.size() / 2, t.end());
  return t[t.size() / 2];
}
}  // namespace

void ForceGather::run(const Model&, State& state, Scratch& scratch, Executor& exec) {
  const ContactForces& in = state.read<Component::contact_forces>();
  const GatherIndex& index = scratch.read<GatherIndex>();
  const Halo& halo = scratch.read<Halo>();
  auto& force = state.write<Component::particle_force>();
  auto& torque = state.write<Component::particle_torque>();
  GatherTrials& trials = scratch.own<GatherTrials>();
  const VisitOrder asked = exec.visit_order();
  const bool adaptive = asked == VisitOrder::adaptive;
  const bool array = adaptive ? trials.next_array() : asked == VisitOrder::array;
  const auto start = adaptive ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
  if (array)
    gather_all<false>(in, index, halo, force.data(), torque.data(), force.size(), exec);
  else
    gather_all<true>(in, index, halo, force.data(), torque.data(), force.size(), exec);
  trials.count(array);
  if (adaptive) trials.record(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

void GatherTrials::record(double seconds) {
  if (!in_trial) {
    if (++call == k_hold) in_trial = true, call = 0;
    return;
  }
  (call % 2 == 1 ? array_seconds : sorted_seconds)[call / 2] = seconds;
  if (++call < 2 * k_trial) return;
  array = median_of(array_seconds) < median_of(sorted_seconds);
  in_trial = false;
  call = 0;
  ++trials;
}

}  // namespace sandcell
