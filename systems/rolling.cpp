#include "systems/rolling.hpp"

#include <cmath>

namespace sandcell {

namespace {

template <RollingModel Kind>
void rolling_loop(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  const ContactPairs& pairs = state.read<Component::contact_pairs>();
  const Vec3* __restrict w = state.read<Component::particle_angular_velocity>().data();
  const double* __restrict radius = state.read<Component::particle_radius>().data();
  const double* __restrict mass = state.read<Component::particle_mass>().data();
  const std::uint32_t* __restrict material = state.read<Component::particle_material>().data();
  const ContactGeometry& geo = scratch.read<Component::contact_geometry>();
  auto& history = state.write<Component::contact_rolling>();
  ContactForces& out = state.write<Component::contact_forces>();

  const std::size_t m = pairs.size();
  history.resize(m);
  const double dt = model.dt;
  const double eta_r = model.contact.rolling_damping;
  const std::size_t n_mat = model.materials.size();
  const bool update_history = !scratch.setup;
  const std::uint32_t* __restrict pi = pairs.i.data();
  const std::uint32_t* __restrict pj = pairs.j.data();
  Vec3* __restrict hist = history.data();
  Vec3* __restrict torque_i = out.torque_i.data();
  Vec3* __restrict torque_j = out.torque_j.data();

  exec.parallel_for(m, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) {
      if (geo.overlap[k] <= 0.0) {
        hist[k].setZero();  // history resets when the contact opens
        continue;
      }
      const std::uint32_t i = pi[k], j = pj[k];
      const Vec3& n = geo.normal[k];
      Vec3 w_r = w[i] - w[j];
      w_r -= w_r.dot(n) * n;  // twisting part removed
      const double r_star = radius[i] * radius[j] / (radius[i] + radius[j]);
      const double mu_r = model.pairs[material[i] * n_mat + material[j]].rolling_friction;
      const double cap = mu_r * r_star * std::abs(geo.normal_force[k]);
      Vec3 moment;
      if constexpr (Kind == RollingModel::cdt) {
        const double wn = w_r.norm();
        moment = wn > 0.0 ? Vec3(mu_r * geo.stiffness_n[k] * geo.overlap[k] * r_star / wn * w_r) : Vec3::Zero();
      } else {
        const double k_r = Kind == RollingModel::epsd2
                               ? geo.stiffness_t[k] * r_star * r_star
                               : 2.25 * geo.stiffness_n[k] * mu_r * mu_r * r_star * r_star;
        Vec3 h = hist[k];
        if (update_history) h += k_r * dt * w_r;
        const double h2 = h.squaredNorm();
        moment = h;
        if (h2 > cap * cap) {
          h *= cap / std::sqrt(h2);
          moment = h;
        } else if constexpr (Kind == RollingModel::epsd) {
          // Dashpot below the cap only: C_r = eta_r 2 sqrt(I_r k_r).
          const double a = mass[i] * radius[i] * radius[i];
          const double c = mass[j] * radius[j] * radius[j];
          const double i_r = 1.4 * a * c / (a + c);
          moment += eta_r * 2.0 * std::sqrt(i_r * k_r) * w_r;
        }
        hist[k] = h;
      }
      torque_i[k] -= moment;
      torque_j[k] += moment;
    }
  });
}

}  // namespace

void Rolling::run(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  switch (model.contact.rolling) {
    case RollingModel::epsd2: rolling_loop<RollingModel::epsd2>(model, state, scratch, exec); break;
    case RollingModel::epsd: rolling_loop<RollingModel::epsd>(model, state, scratch, exec); break;
    case RollingModel::cdt: rolling_loop<RollingModel::cdt>(model, state, scratch, exec); break;
    case RollingModel::none: break;
  }
}

}  // namespace sandcell
