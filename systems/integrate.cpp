#include "systems/integrate.hpp"

#include "engine/prefetch.hpp"

namespace sandcell {

namespace {
// Particles ahead at which two_kicks_drift asks for the lines it will write (engine/prefetch.hpp):
// 8 was the fastest of none, 4, 8 and 16 on 2 threads, and the distance does not matter on 1
// (`dem-bench --scaling`, integrate_initial's timer; docs/performance.md).
constexpr std::size_t k_write_ahead = 8;

// Half kick of linear and angular velocity over [b, e).
void half_kick(double half_dt, const Vec3* __restrict f, const Vec3* __restrict t, const double* __restrict m,
               const double* __restrict inv_i, Vec3* __restrict v, Vec3* __restrict w, std::size_t b, std::size_t e) {
  for (std::size_t k = b; k < e; ++k) {
    v[k] += f[k] * (half_dt / m[k]);
    w[k] += t[k] * (half_dt * inv_i[k]);
  }
}

// The last step's deferred final half kick, then this step's first half kick and the drift, in one
// pass over [b, e). Each kick adds the same increment as half_kick, in the same order.
// Exclusive: whether the CPU has PREFETCHW (engine/prefetch.hpp). This is the pass of every step
// of World::step_until but its first; half_kick's two passes per call (the first step's kick, the
// closing kick) go without the prefetch. `affine(x)` is the cell's affine velocity L x (with_affine below).
template <bool Exclusive, class Affine>
void two_kicks_drift(double dt, const Affine& affine, const Vec3* __restrict f, const Vec3* __restrict t,
                     const double* __restrict m, const double* __restrict inv_i, Vec3* __restrict x, Vec3* __restrict v,
                     Vec3* __restrict w, std::size_t b, std::size_t e) {
  const double half_dt = 0.5 * dt;
  for (std::size_t k = b; k < e; ++k) {
    if (k + k_write_ahead < e) {
      prefetch_for_write<Exclusive>(&x[k + k_write_ahead]);
      prefetch_for_write<Exclusive>(&v[k + k_write_ahead]);
      prefetch_for_write<Exclusive>(&w[k + k_write_ahead]);
    }
    const Vec3 dv = f[k] * (half_dt / m[k]);
    const Vec3 dw = t[k] * (half_dt * inv_i[k]);
    const Vec3 vk = (v[k] + dv) + dv;
    v[k] = vk;
    w[k] = (w[k] + dw) + dw;
    x[k] += (vk + affine(x[k])) * dt;
  }
}

// Calls fn(affine) with the cell's affine velocity x -> L x: D x for an orthorhombic cell (the
// arithmetic it always had), H-style upper triangular L x (unreduced, components/cell.hpp) for a
// shearing one. Each form is compiled apart.
template <class Fn>
void with_affine(const Vec3& rate, const Vec3& shear, Fn&& fn) {
  if (shear.isZero(0.0))
    fn([rate](const Vec3& x) { return Vec3(rate.cwiseProduct(x)); });
  else
    fn([rate, shear](const Vec3& x) { return unreduced(x, rate, shear); });
}

}  // namespace

void IntegrateInitial::run(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  const double dt = model.dt;
  const auto& force = state.read<Component::particle_force>();
  const auto& torque = state.read<Component::particle_torque>();
  const auto& mass = state.read<Component::particle_mass>();
  const auto& inv_inertia = state.read<Component::particle_inv_inertia>();
  auto& position = state.write<Component::particle_position>();
  auto& velocity = state.write<Component::particle_velocity>();
  auto& omega = state.write<Component::particle_angular_velocity>();
  Cell& cell = state.write<Component::cell>();

  const Vec3 rate = cell.rate;
  // Same factor for lengths and affine positions, so reduced coordinates are kept exactly in exact
  // arithmetic, and to round-off in floating point.
  const Vec3 new_length = cell.length + cell.length.cwiseProduct(rate) * dt;
  // A shearing cell: H <- H + L H dt, positions x <- x + (v~ + L x) dt (the same map I + L dt).
  const Vec3 shear = cell.shear_rate;
  if (!shear.isZero(0.0) || !cell.tilt.isZero(0.0)) {
    const Vec3& l = cell.length;
    const Vec3& t = cell.tilt;
    const Vec3 lh_tilt(rate[0] * t[0] + shear[0] * l[1], rate[0] * t[1] + shear[0] * t[2] + shear[1] * l[2],
                       rate[1] * t[2] + shear[2] * l[2]);  // (L H)_xy, (L H)_xz, (L H)_yz
    cell.tilt = t + lh_tilt * dt;
  }

  const Vec3* f = force.data();
  const Vec3* t = torque.data();
  const double* m = mass.data();
  const double* inv_i = inv_inertia.data();
  Vec3* x = position.data();
  Vec3* v = velocity.data();
  Vec3* w = omega.data();
  KickState& kick = scratch.own<KickState>();
  if (kick.pending) {  // the last step's final kick was left to this pass (integrate.hpp)
    kick.pending = false;
    const bool exclusive = cpu_has_prefetchw();
    with_affine(rate, shear, [&](const auto& affine) {
      exec.parallel_for(position.size(), k_particle_grain, [&](std::size_t b, std::size_t e) {
        if (exclusive)
          two_kicks_drift<true>(dt, affine, f, t, m, inv_i, x, v, w, b, e);
        else
          two_kicks_drift<false>(dt, affine, f, t, m, inv_i, x, v, w, b, e);
      });
    });
  } else {
    with_affine(rate, shear, [&](const auto& affine) {
      exec.parallel_for(position.size(), k_particle_grain, [&](std::size_t b, std::size_t e) {
        half_kick(0.5 * dt, f, t, m, inv_i, v, w, b, e);
        for (std::size_t k = b; k < e; ++k) x[k] += (v[k] + affine(x[k])) * dt;
      });
    });
  }
  cell.length = new_length;
}

namespace {
void final_kick(const Model& model, State& state, Executor& exec) {
  const double dt = model.dt;
  const Vec3* f = state.read<Component::particle_force>().data();
  const Vec3* t = state.read<Component::particle_torque>().data();
  const double* m = state.read<Component::particle_mass>().data();
  const double* inv_i = state.read<Component::particle_inv_inertia>().data();
  auto& velocity = state.write<Component::particle_velocity>();
  Vec3* v = velocity.data();
  Vec3* w = state.write<Component::particle_angular_velocity>().data();
  exec.parallel_for(velocity.size(), k_particle_grain,
                    [&](std::size_t b, std::size_t e) { half_kick(0.5 * dt, f, t, m, inv_i, v, w, b, e); });
}

}  // namespace

void IntegrateFinal::run(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  if (scratch.batching) {  // the next step's integrate_initial applies it (integrate.hpp)
    scratch.own<KickState>().pending = true;
    return;
  }
  final_kick(model, state, exec);
}

void IntegrateFinal::flush(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  KickState& kick = scratch.own<KickState>();
  if (!kick.pending) return;
  kick.pending = false;
  final_kick(model, state, exec);
}

}  // namespace sandcell
