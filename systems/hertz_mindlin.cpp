#include "systems/hertz_mindlin.hpp"

#include "systems/rolling.hpp"

#include "engine/assert.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <type_traits>

namespace sandcell {

namespace {

constexpr double k_two_sqrt_5_6 = 1.8257418583505538;  // 2 sqrt(5/6)

struct PairKinematics {
  Vec3 n;           // unit normal, from j to i
  double overlap;   // m
  double r_star;    // m
  double c_i, c_j;  // m, lever arms from the centres to the contact point
  Vec3 v_rel;       // m/s, at the centres (fluctuating difference + affine D r)
  Vec3 w_i, w_j;    // rad/s
};

struct NormalTangential {
  Vec3 f_t;         // N, tangential force on i
  double f_n;       // N, normal force (signed)
  double k_n, k_t;  // N/m
  unsigned capped;  // 1 at the Coulomb cap, else 0
};

// Hertz-Mindlin with the LIGGGHTS-form displacement history (u_t, m) or the incremental force
// history (F_s, N).
template <TangentialModel Tangential, bool Update>
struct HertzMindlinEvaluator {
  const PairMaterial& mat;
  double dt;

  /// k_n = 4/3 E* sqrt(R* delta), k_t = 8 G* sqrt(R* delta), gamma_n = -2 sqrt(5/6) beta sqrt(S_n m*).
  [[gnu::always_inline]] inline NormalTangential evaluate(const PairKinematics& c, double k_n, double k_t,
                                                          double gamma_n, Vec3& history) const {
    const double gamma_t = gamma_n * mat.damping_ratio_t;  // -2 sqrt(5/6) beta sqrt(S_t m*)

    const double v_n = c.v_rel.dot(c.n);
    const double f_n = k_n * c.overlap - gamma_n * v_n;
    const Vec3 v_t = c.v_rel - v_n * c.n + c.n.cross(c.c_i * c.w_i + c.c_j * c.w_j);
    const double f_cap = mat.friction * std::abs(f_n);

    Vec3 f_t;
    unsigned capped = 0;
    Vec3 h = history;
    if constexpr (Tangential == TangentialModel::history) {
      // u_t += v_t dt, projected on the tangent plane; F_t = -k_t u_t; at the Coulomb cap the
      // force is scaled to mu |F_n| (no damping) and u_t set to -F_t / k_t.
      if constexpr (Update) h += v_t * dt;
      h -= h.dot(c.n) * c.n;
      f_t = -k_t * h;
      const double f2 = f_t.squaredNorm();
      if (f2 > f_cap * f_cap) {
        capped = 1;
        f_t *= f_cap / std::sqrt(f2);
        h = f_t / -k_t;
      } else {
        f_t -= gamma_t * v_t;
      }
    } else {
      // Stored elastic tangential force, rotated into the new tangent plane (projected, magnitude
      // kept), plus -k_t times the displacement increment; Coulomb cap on it.
      const double old2 = h.squaredNorm();
      h -= h.dot(c.n) * c.n;
      const double new2 = h.squaredNorm();
      if (new2 > 0.0) h *= std::sqrt(old2 / new2);
      if constexpr (Update) h -= (k_t * dt) * v_t;
      const double f2 = h.squaredNorm();
      if (f2 > f_cap * f_cap) {
        capped = 1;
        h *= f_cap / std::sqrt(f2);
        f_t = h;
      } else {
        f_t = h - gamma_t * v_t;
      }
    }
    history = h;
    return NormalTangential{f_t, f_n, k_n, k_t, capped};
  }
};

// The pair loop runs in blocks of k_block pairs, in three phases: gather the branch vectors (and
// the material constants with more than one material; scalar loads), the square roots and
// divisions of the Hertz stiffness for the whole block (branch-free, so the compiler vectorizes
// it and the long sqrt/div latencies of different pairs overlap), then the history-dependent
// tangential and rolling laws per pair.
// IEEE sqrt and division are correctly rounded in vector and scalar form alike, so the result
// of a pair does not depend on the blocking (nor on the thread count).
// The radii, R* and m* of each pair are read from PairConstants, computed when the list is built:
// the same values, bitwise, as computed here from the spheres, with two divisions per pair and
// the loads of both spheres' radii and masses taken out of every step (hertz_mindlin 2.19 ->
// 1.96 s per 1000 steps on dense-20k, 1 thread).
constexpr std::size_t k_block = 64;
static_assert(k_contact_grain % k_block == 0, "blocks must not straddle parallel chunks");
static_assert(k_block < 256, "phase 3 keeps the visiting order as byte offsets");

struct alignas(64) Block {
  double rx[k_block], ry[k_block], rz[k_block];  // m, branch vector
  double e_star[k_block], g_star[k_block];       // Pa
  double damp[k_block];                          // -, -2 sqrt(5/6) beta
  const PairMaterial* mat[k_block];
  // Computed in phase 2:
  double inv_dist[k_block];                      // 1/m
  double overlap[k_block];                       // m, <= 0 when apart
  double k_n[k_block], k_t[k_block];             // N/m
  double gamma_n[k_block];                       // kg/s
};

template <TangentialModel Tangential, RollingModel Roll, bool Affine, bool Update>
void contact_loop(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  const ContactPairs& pairs = state.read<Component::contact_pairs>();
  const Vec3* __restrict x = state.read<Component::particle_position>().data();
  const Vec3* __restrict v = state.read<Component::particle_velocity>().data();
  const Vec3* __restrict w = state.read<Component::particle_angular_velocity>().data();
  const double* __restrict mass = state.read<Component::particle_mass>().data();
  const std::uint32_t* __restrict material = state.read<Component::particle_material>().data();
  const PairConstants& constants = scratch.read<Component::pair_constants>();
  SANDCELL_CHECK(constants.r_star.size() == pairs.size(),
                 "hertz_mindlin: " + std::to_string(constants.r_star.size()) + " pair constants for " +
                     std::to_string(pairs.size()) + " pairs: the pair list must come from the broadphase "
                     "(or World's rebuild of its scratch), which computes them");
  const Cell& cell = state.read<Component::cell>();
  ContactForces& out = state.write<Component::contact_forces>();
  auto& tangential = state.write<Component::contact_tangential>();
  auto& rolling = state.write<Component::contact_rolling>();

  const std::size_t m = pairs.size();
  out.force.resize(m);
  out.torque_i.resize(m);
  out.torque_j.resize(m);
  // cdt has no history: like none, it allocates none.
  constexpr bool rolling_history = Roll == RollingModel::epsd2 || Roll == RollingModel::epsd;
  if constexpr (rolling_history) rolling.resize(m);
  // Last step's regimes (ContactScratch) describe the slots of the list they were made for: a new
  // list starts from none (its slots hold other pairs, and no slot's outputs are known to be zero).
  ContactScratch& hint = scratch.contact;
  if (hint.generation != constants.generation) {
    hint.regime.assign(m, 0);
    hint.order.assign(m, 0);
    hint.stale.assign((m + k_block - 1) / k_block, 1);
    hint.sorted.assign((m + k_block - 1) / k_block, 0);
    hint.generation = constants.generation;
  }
  SANDCELL_ASSERT(hint.regime.size() == m, "contact regimes of another pair list");

  const Vec3 rate = cell.rate;
  const std::size_t n_mat = model.materials.size();
  const std::uint32_t* __restrict pi = pairs.i.data();
  const std::uint32_t* __restrict pj = pairs.j.data();
  const double* __restrict pair_r_star = constants.r_star.data();
  const double* __restrict pair_m_star = constants.m_star.data();
  const double* __restrict pair_r_i = constants.r_i.data();
  const double* __restrict pair_r_j = constants.r_j.data();
  const std::uint8_t* __restrict image_code = constants.image_code.data();
  // H n of the 27 images, by image code (PairConstants): the product img * L exactly as per pair.
  std::array<Vec3, 27> shift_table;
  for (int c = 0; c < 27; ++c) {
    const Image img{static_cast<std::int8_t>(c % 3 - 1), static_cast<std::int8_t>(c / 3 % 3 - 1),
                    static_cast<std::int8_t>(c / 9 - 1)};
    shift_table[c] = Vec3(img[0] * cell.length[0], img[1] * cell.length[1], img[2] * cell.length[2]);
  }
  const Vec3* __restrict shift = shift_table.data();
  Vec3* __restrict force = out.force.data();
  Vec3* __restrict torque_i = out.torque_i.data();
  Vec3* __restrict torque_j = out.torque_j.data();
  Vec3* __restrict hist_t = tangential.data();
  Vec3* __restrict hist_r = rolling.data();
  std::uint8_t* __restrict regime = hint.regime.data();
  std::uint8_t* __restrict order_all = hint.order.data();
  std::uint8_t* __restrict stale = hint.stale.data();
  std::uint8_t* __restrict sorted = hint.sorted.data();
  const RollingEvaluator<Roll, Update> roll{model.dt, model.contact.rolling_damping};

  const PairMaterial* const pair_mat = model.pairs.data();
  const double dt = model.dt;
  // One material: the constant of every pair (no pairs without materials: then nothing reads it).
  const double damp_0 = n_mat == 0 ? 0.0 : -k_two_sqrt_5_6 * model.pairs[0].beta;
  exec.parallel_for(m, k_contact_grain, [=](std::size_t b, std::size_t e) {
    // The pointers are copied by value into the closure: the pass needs more of them than there
    // are registers, and a spilled copy reloads with one load instead of two through a reference.
    Block blk;
    for (std::size_t k0 = b; k0 < e; k0 += k_block) {
      const std::size_t nb = std::min(k_block, e - k0);
      // Phase 1: gather. With one material the pair constants are the same for every pair and
      // neither loaded nor stored per pair (the common case, compiled as its own loop).
      auto gather = [&](auto one_material) {
        for (std::size_t t = 0; t < nb; ++t) {
          const std::size_t k = k0 + t;
          const std::uint32_t i = pi[k], j = pj[k];
          const Vec3& s = shift[image_code[k]];
          blk.rx[t] = x[i][0] - x[j][0] - s[0];
          blk.ry[t] = x[i][1] - x[j][1] - s[1];
          blk.rz[t] = x[i][2] - x[j][2] - s[2];
          if constexpr (!decltype(one_material)::value) {
            const PairMaterial& mat = pair_mat[material[i] * n_mat + material[j]];
            blk.mat[t] = &mat;
            blk.e_star[t] = mat.e_star;
            blk.g_star[t] = mat.g_star;
            blk.damp[t] = -k_two_sqrt_5_6 * mat.beta;
          }
          // Phase 3 reads these per pair inside a long chain of arithmetic; fetching them here
          // overlaps their cache misses across the block. Only the j side: i changes every ~4
          // pairs and walks the arrays in order, which the hardware prefetcher follows (the
          // prefetches of v_i, w_i cost 2 % of the step).
          __builtin_prefetch(&v[j]);
          __builtin_prefetch(&w[j]);
        }
      };
      // Phase 2: stiffness and damping, branch-free (apart pairs get overlap <= 0, zeros after).
      auto stiffness = [&](auto one_material) {
        constexpr bool one = decltype(one_material)::value;
        for (std::size_t t = 0; t < nb; ++t) {
          const double e_star = one ? pair_mat[0].e_star : blk.e_star[t];
          const double g_star = one ? pair_mat[0].g_star : blk.g_star[t];
          const double damp = one ? damp_0 : blk.damp[t];
          const double r2 = blk.rx[t] * blk.rx[t] + blk.ry[t] * blk.ry[t] + blk.rz[t] * blk.rz[t];
          const double dist = std::sqrt(r2);
          const double overlap = (pair_r_i[k0 + t] + pair_r_j[k0 + t]) - dist;
          const double od = overlap > 0.0 ? overlap : 0.0;
          blk.inv_dist[t] = 1.0 / dist;
          blk.overlap[t] = overlap;
          const double m_star = pair_m_star[k0 + t];
          const double sqrt_rd = std::sqrt(pair_r_star[k0 + t] * od);
          const double s_n = 2.0 * e_star * sqrt_rd;
          blk.k_n[t] = (2.0 / 3.0) * s_n;     // 4/3 E* sqrt(R* delta)
          blk.k_t[t] = 8.0 * g_star * sqrt_rd;  // = S_t
          blk.gamma_n[t] = damp * std::sqrt(s_n * m_star);
        }
      };
      if (n_mat == 1) {
        gather(std::true_type{});
        stiffness(std::true_type{});
      } else {
        gather(std::false_type{});
        stiffness(std::false_type{});
      }
      // Phase 3 visits the block's pairs grouped by their regime in the last step: touching below
      // the caps, at the Coulomb cap, at the rolling cap, at both, open. The overlap and cap tests
      // then run in stretches of the same outcome, which the branch predictor follows. In array
      // order they come at random, and each miss costs ~50 cycles: on dense-20k shortened by 1 %
      // (scene B), a quarter of the touching pairs slide and 59 % are at the rolling cap (means
      // over its 20,000 steps), and a pair changes regime about 5 times in 10,000 steps; on
      // dense-20k a quarter of the candidate pairs are open. The order is a stable counting sort of
      // the block by regime, made again only when a regime in the block changed in the last step;
      // a block of pairs all touching below the caps keeps array order. Scene B over 20,000 steps:
      // grouping by the caps took hertz_mindlin from 29.5-31.7 to 23.6-24.1 s on 2 threads.
      // An open pair already marked open is not written: its outputs are zero since it opened.
      const std::size_t block = k0 / k_block;
      std::uint8_t* __restrict order = order_all + k0;
      if (stale[block]) {
        unsigned start[6] = {0, 0, 0, 0, 0, 0};
        for (std::size_t t = 0; t < nb; ++t) ++start[regime[k0 + t] + 1];
        sorted[block] = start[1] != nb;
        if (sorted[block]) {
          for (unsigned g = 1; g < 5; ++g) start[g] += start[g - 1];
          for (std::size_t t = 0; t < nb; ++t) order[start[regime[k0 + t]]++] = static_cast<std::uint8_t>(t);
        }
        stale[block] = 0;
      }
      unsigned changed = 0;
      // Phase 3: tangential and rolling laws, outputs.
      auto visit = [&](std::size_t t) __attribute__((always_inline)) {
        const std::size_t k = k0 + t;
        if (!(blk.overlap[t] > 0.0)) {
          if (regime[k] != ContactScratch::k_apart) [[unlikely]] {  // else all zero since the step it opened
            force[k].setZero();
            torque_i[k].setZero();
            torque_j[k].setZero();
            hist_t[k].setZero();  // history resets when the contact opens
            if constexpr (rolling_history) hist_r[k].setZero();
            regime[k] = ContactScratch::k_apart;
            changed = 1;
          }
          return;
        }
        const std::uint32_t i = pi[k], j = pj[k];
        const Vec3 r(blk.rx[t], blk.ry[t], blk.rz[t]);
        PairKinematics c;
        c.n = r * blk.inv_dist[t];
        c.overlap = blk.overlap[t];
        c.r_star = pair_r_star[k];
        c.c_i = pair_r_i[k] - 0.5 * c.overlap;
        c.c_j = pair_r_j[k] - 0.5 * c.overlap;
        c.v_rel = v[i] - v[j];
        if constexpr (Affine) c.v_rel += rate.cwiseProduct(r);
        c.w_i = w[i];
        c.w_j = w[j];
        const PairMaterial& mat = n_mat == 1 ? pair_mat[0] : *blk.mat[t];
        const HertzMindlinEvaluator<Tangential, Update> law{mat, dt};
        const NormalTangential nt = law.evaluate(c, blk.k_n[t], blk.k_t[t], blk.gamma_n[t], hist_t[k]);
        const Vec3 arm_torque = c.n.cross(nt.f_t);  // torque on i is -c_i n x F_t, on j -c_j n x F_t
        Vec3 t_i = -c.c_i * arm_torque;
        Vec3 t_j = -c.c_j * arm_torque;
        unsigned rolling_capped = 0;
        if constexpr (Roll != RollingModel::none) {
          Vec3 no_history = Vec3::Zero();  // cdt: not read, not kept
          double i_r = 0.0;
          if constexpr (Roll == RollingModel::epsd) {
            const double a = mass[i] * pair_r_i[k] * pair_r_i[k];
            const double d = mass[j] * pair_r_j[k] * pair_r_j[k];
            i_r = 1.4 * a * d / (a + d);
          }
          const Vec3 moment = roll.evaluate(RollingInput{c.n, c.w_i - c.w_j, c.overlap, nt.f_n, nt.k_n, nt.k_t,
                                                         c.r_star, i_r, mat.rolling_friction},
                                            rolling_history ? hist_r[k] : no_history, rolling_capped);
          t_i -= moment;
          t_j += moment;
        }
        force[k] = nt.f_n * c.n + nt.f_t;
        torque_i[k] = t_i;
        torque_j[k] = t_j;
        const std::uint8_t now = static_cast<std::uint8_t>(nt.capped | rolling_capped);
        if (now != regime[k]) [[unlikely]] {  // a few times per pair in 10,000 steps
          regime[k] = now;
          changed = 1;
        }
      };
      if (sorted[block]) {
        for (std::size_t u = 0; u < nb; ++u) visit(order[u]);
      } else {
        for (std::size_t t = 0; t < nb; ++t) visit(t);  // no pair at a cap: array order
      }
      stale[block] = changed != 0;
    }
  });
}

template <TangentialModel T, RollingModel R, bool Affine>
void dispatch_update(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  // The setup pass (forces without advancing the history) is rare: the stepping pass is compiled
  // without the test.
  if (scratch.setup) contact_loop<T, R, Affine, false>(model, state, scratch, exec);
  else contact_loop<T, R, Affine, true>(model, state, scratch, exec);
}

template <TangentialModel T, RollingModel R>
void dispatch_affine(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  if (model.contact.liggghts_compat) dispatch_update<T, R, false>(model, state, scratch, exec);
  else dispatch_update<T, R, true>(model, state, scratch, exec);
}

template <TangentialModel T>
void dispatch_rolling(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  switch (model.contact.rolling) {
    case RollingModel::none: dispatch_affine<T, RollingModel::none>(model, state, scratch, exec); break;
    case RollingModel::epsd2: dispatch_affine<T, RollingModel::epsd2>(model, state, scratch, exec); break;
    case RollingModel::epsd: dispatch_affine<T, RollingModel::epsd>(model, state, scratch, exec); break;
    case RollingModel::cdt: dispatch_affine<T, RollingModel::cdt>(model, state, scratch, exec); break;
  }
}

}  // namespace

void HertzMindlin::run(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  if (model.contact.tangential == TangentialModel::history)
    dispatch_rolling<TangentialModel::history>(model, state, scratch, exec);
  else
    dispatch_rolling<TangentialModel::incremental>(model, state, scratch, exec);
}

}  // namespace sandcell
