#include "systems/hertz_mindlin.hpp"

#include <cmath>

namespace sandcell {

namespace {

constexpr double k_two_sqrt_5_6 = 1.8257418583505538;  // 2 sqrt(5/6)

// Per-pair inputs gathered by the loop; the evaluator is the law itself, independent of storage.
struct PairKinematics {
  Vec3 n;          // unit normal, from j to i
  double overlap;  // m
  double r_star;   // m
  double m_star;   // kg
  double c_i, c_j; // m, lever arms to the contact point
  Vec3 v_rel;      // m/s, at the centres (fluctuating difference + affine D r)
  Vec3 w_i, w_j;   // rad/s
};

struct PairResult {
  Vec3 f_t;         // N, tangential force on i
  double f_n;       // N, normal force (signed)
  double k_n, k_t;  // N/m
};

// Hertz-Mindlin, LIGGGHTS-form tangential history (u_t, m) or incremental force history (F_s, N).
template <TangentialModel Tangential>
struct HertzMindlinEvaluator {
  const PairMaterial& mat;
  double dt;
  bool update_history;

  PairResult evaluate(const PairKinematics& c, Vec3& history) const {
    const double sqrt_rd = std::sqrt(c.r_star * c.overlap);
    const double s_n = 2.0 * mat.e_star * sqrt_rd;
    const double k_n = (4.0 / 3.0) * mat.e_star * sqrt_rd;
    const double k_t = 8.0 * mat.g_star * sqrt_rd;  // = S_t
    const double gamma_n = -k_two_sqrt_5_6 * mat.beta * std::sqrt(s_n * c.m_star);
    const double gamma_t = -k_two_sqrt_5_6 * mat.beta * std::sqrt(k_t * c.m_star);

    const double v_n = c.v_rel.dot(c.n);
    const double f_n = k_n * c.overlap - gamma_n * v_n;
    const Vec3 v_t = c.v_rel - v_n * c.n + c.n.cross(c.c_i * c.w_i + c.c_j * c.w_j);
    const double f_cap = mat.friction * std::abs(f_n);

    Vec3 f_t;
    Vec3 h = history;
    if constexpr (Tangential == TangentialModel::history) {
      // u_t += v_t dt, projected on the tangent plane; F_t = -k_t u_t; Coulomb cap without damping.
      if (update_history) h += v_t * dt;
      h -= h.dot(c.n) * c.n;
      f_t = -k_t * h;
      const double f2 = f_t.squaredNorm();
      if (f2 > f_cap * f_cap) {
        f_t *= f_cap / std::sqrt(f2);
        h = f_t / -k_t;
      } else {
        f_t -= gamma_t * v_t;
      }
    } else {
      // Stored elastic tangential force: rotated into the new tangent plane (projection, magnitude
      // kept), plus k_t times the tangential displacement increment; Coulomb cap on it.
      const double old_mag = h.norm();
      h -= h.dot(c.n) * c.n;
      const double new_mag = h.norm();
      if (new_mag > 0.0) h *= old_mag / new_mag;
      if (update_history) h -= k_t * dt * v_t;
      const double f2 = h.squaredNorm();
      if (f2 > f_cap * f_cap) {
        h *= f_cap / std::sqrt(f2);
        f_t = h;
      } else {
        f_t = h - gamma_t * v_t;
      }
    }
    history = h;
    return PairResult{f_t, f_n, k_n, k_t};
  }
};

template <TangentialModel Tangential, bool Affine>
void contact_loop(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  const ContactPairs& pairs = state.read<Component::contact_pairs>();
  const Vec3* __restrict x = state.read<Component::particle_position>().data();
  const Vec3* __restrict v = state.read<Component::particle_velocity>().data();
  const Vec3* __restrict w = state.read<Component::particle_angular_velocity>().data();
  const double* __restrict radius = state.read<Component::particle_radius>().data();
  const double* __restrict mass = state.read<Component::particle_mass>().data();
  const std::uint32_t* __restrict material = state.read<Component::particle_material>().data();
  const Cell& cell = state.read<Component::cell>();
  ContactForces& out = state.write<Component::contact_forces>();
  auto& history = state.write<Component::contact_tangential>();
  ContactGeometry& geo = scratch.write<Component::contact_geometry>();

  const std::size_t m = pairs.size();
  out.force.resize(m);
  out.torque_i.resize(m);
  out.torque_j.resize(m);
  geo.normal.resize(m);
  geo.overlap.resize(m);
  geo.normal_force.resize(m);
  geo.stiffness_n.resize(m);
  geo.stiffness_t.resize(m);

  const Vec3 length = cell.length;
  const Vec3 rate = cell.rate;
  const std::size_t n_mat = model.materials.size();
  const bool update_history = !scratch.setup;
  const std::uint32_t* __restrict pi = pairs.i.data();
  const std::uint32_t* __restrict pj = pairs.j.data();
  const Image* __restrict image = pairs.image.data();
  Vec3* __restrict force = out.force.data();
  Vec3* __restrict torque_i = out.torque_i.data();
  Vec3* __restrict torque_j = out.torque_j.data();
  Vec3* __restrict hist = history.data();

  exec.parallel_for(m, k_contact_grain, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) {
      const std::uint32_t i = pi[k], j = pj[k];
      const Image img = image[k];
      const Vec3 r = x[i] - x[j] - Vec3(img[0] * length[0], img[1] * length[1], img[2] * length[2]);
      const double r2 = r.squaredNorm();
      const double sum_r = radius[i] + radius[j];
      if (r2 >= sum_r * sum_r) {
        force[k].setZero();
        torque_i[k].setZero();
        torque_j[k].setZero();
        hist[k].setZero();  // history resets when the contact opens
        geo.normal[k].setZero();
        geo.overlap[k] = 0.0;
        geo.normal_force[k] = 0.0;
        geo.stiffness_n[k] = 0.0;
        geo.stiffness_t[k] = 0.0;
        continue;
      }
      const double dist = std::sqrt(r2);
      PairKinematics c;
      c.n = r / dist;
      c.overlap = sum_r - dist;
      c.r_star = radius[i] * radius[j] / sum_r;
      c.m_star = mass[i] * mass[j] / (mass[i] + mass[j]);
      c.c_i = radius[i] - 0.5 * c.overlap;
      c.c_j = radius[j] - 0.5 * c.overlap;
      c.v_rel = v[i] - v[j];
      if constexpr (Affine) c.v_rel += rate.cwiseProduct(r);
      c.w_i = w[i];
      c.w_j = w[j];
      const HertzMindlinEvaluator<Tangential> law{model.pairs[material[i] * n_mat + material[j]],
                                                  model.dt, update_history};
      const PairResult res = law.evaluate(c, hist[k]);
      const Vec3& f_t = res.f_t;
      force[k] = res.f_n * c.n + f_t;
      torque_i[k] = -c.c_i * c.n.cross(f_t);
      torque_j[k] = -c.c_j * c.n.cross(f_t);
      geo.normal[k] = c.n;
      geo.overlap[k] = c.overlap;
      geo.normal_force[k] = res.f_n;
      geo.stiffness_n[k] = res.k_n;
      geo.stiffness_t[k] = res.k_t;
    }
  });
}

}  // namespace

void HertzMindlin::run(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  const bool affine = !model.contact.liggghts_compat;
  if (model.contact.tangential == TangentialModel::history) {
    if (affine) contact_loop<TangentialModel::history, true>(model, state, scratch, exec);
    else contact_loop<TangentialModel::history, false>(model, state, scratch, exec);
  } else {
    if (affine) contact_loop<TangentialModel::incremental, true>(model, state, scratch, exec);
    else contact_loop<TangentialModel::incremental, false>(model, state, scratch, exec);
  }
}

}  // namespace sandcell
