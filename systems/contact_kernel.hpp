#pragma once
// The contact pass's kernel (ContactKernel) and its loop, for the translation units that compile
// them, one per rolling law (contact_parts.hpp): included only by contact_pass_none.cpp,
// contact_pass_epsd2.cpp, contact_pass_epsd.cpp and contact_pass_cdt.cpp. Everything here has
// internal linkage, so each of them holds its own copy of what it instantiates.
#include "systems/contact_parts.hpp"

#include "systems/laws/mindlin.hpp"
#include "systems/laws/normal_laws.hpp"
#include "systems/laws/rolling.hpp"
#include "systems/laws/select.hpp"
#include "systems/halo.hpp"
#include "systems/homogenizer.hpp"
#include "systems/integrate.hpp"
#include "systems/pair_list.hpp"

#include "engine/assert.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#if defined(__AVX2__)
#include <immintrin.h>
#endif

namespace sandcell {

namespace {

struct PairKinematics {
  Vec3 n;           // unit normal, from j to i
  double overlap;   // m
  double r_star;    // m
  double c_i, c_j;  // m, lever arms from the centres to the contact point
  Vec3 v_rel;       // m/s, at the centres (fluctuating difference + affine D r)
  Vec3 w_i, w_j;    // rad/s
};

// The characteristic velocity of the laws that have one (0: none given; such a law's validate()
// refuses that).
double characteristic_velocity(const ContactSettings& contact) {
  const auto it = contact.parameters.find("characteristic_velocity");
  return it == contact.parameters.end() ? 0.0 : it->second;
}

// The pair loop runs in blocks of k_block pairs, in three phases: gather the branch vectors (and
// the material constants with more than one material; scalar loads), the normal law's stiffness
// and damping for the whole block (branch-free, so the compiler vectorizes Hertz's square roots
// and divisions and their long latencies overlap across pairs), then the history-dependent
// tangential and rolling laws per pair.
// IEEE sqrt and division are correctly rounded in vector and scalar form alike, so the result
// of a pair does not depend on the blocking (nor on the thread count).
// The radii, R* and m* of each pair are read from PairConstants, computed when the list is built:
// the same values, bitwise, as computed here from the spheres, with two divisions per pair and
// the loads of both spheres' radii and masses taken out of every step.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool k_sanitized = true;
#else
constexpr bool k_sanitized = false;
#endif

constexpr std::size_t k_block = 64;
static_assert(StressBlocks::k_stress_block == k_block, "the stress is summed per block of the pass");
static_assert(k_contact_grain % k_block == 0, "blocks must not straddle parallel chunks");
static_assert(k_block < 256, "phase 3 keeps the visiting order as byte offsets");

struct alignas(64) Block {
  double rx[k_block], ry[k_block], rz[k_block];  // m, branch vector
  double e_star[k_block], g_star[k_block];       // Pa
  double beta[k_block];                          // -
  const PairMaterial* mat[k_block];
  // Computed in phase 2:
  double inv_dist[k_block];           // 1/m
  double overlap[k_block];            // m, <= 0 when apart
  double k_n[k_block], k_t[k_block];  // N/m
  double gamma_n[k_block];            // kg/s
};

// Everything the pass reads and writes, bound once per pass and copied by value into each chunk:
// the pass needs more of these than there are registers, and a spilled copy reloads with one load
// instead of two through a reference.
struct PassData {
  const std::uint32_t* __restrict pi;
  const std::uint32_t* __restrict pj;
  const std::uint32_t* __restrict pjh;  // j, or n + ghost slot (Halo); pj without a halo
  const Vec3* __restrict x;
  const Vec3* __restrict v;
  const Vec3* __restrict w;
  const Vec3* gx;  // ghost copies of x, v, w (Halo); x, v, w without a halo
  const Vec3* gv;
  const Vec3* gw;
  std::uint32_t n_own;              // pjh below this indexes x, v, w; above, the ghosts (no halo: the maximum)
  const std::uint8_t* ghost_block;  // per block of k_block pairs, 1: some pair's j is a ghost (Halo)
  const double* __restrict mass;
  const std::uint32_t* __restrict material;
  const double* __restrict r_star;
  const double* __restrict m_star;
  const double* __restrict r_i;
  const double* __restrict r_j;
  const std::uint8_t* __restrict image_code;
  const PairMaterial* pair_mat;
  std::size_t n_mat;
  Vec3* __restrict force;
  Vec3* __restrict torque_i;
  Vec3* __restrict torque_j;
  Vec3* __restrict hist_t;
  Vec3* __restrict hist_r;
  std::uint8_t* __restrict regime;
  std::uint8_t* __restrict order;
  std::uint8_t* __restrict stale;
  std::uint8_t* __restrict sorted;
  std::array<Vec3, 27> shift;  // H n of the 27 images, by image code (PairConstants)
  Vec3 rate;                   // 1/s, the cell's strain rate (affine velocity D r)
  Vec3 shear;                  // 1/s, (L_xy, L_xz, L_yz): a shearing cell's affine velocity adds them
  double dt;                   // s
  double v_char;               // m/s, for the laws that have one
  double* __restrict hist_a = nullptr;  // m, the contact radius at the last step (laws with radius_history)
  double* __restrict stress_blocks = nullptr;  // N m, StressBlocks::sum on servo steps; else none
};

// The affine term of the relative velocity, a template argument so that each cell pays only its own:
// none (contact.liggghts_compat), D r (an orthorhombic cell), L r (a shearing cell).
constexpr int k_affine_none = 0, k_affine_diagonal = 1, k_affine_full = 2;

// Last step's regimes (ContactScratch) describe the slots of the list they were made for: a new
// list starts from none (its slots hold other pairs, and no slot's outputs are known to be zero).
void restart_regimes(ContactScratch& hint, std::size_t m, std::uint64_t generation) {
  if (hint.generation == generation) return;
  hint.regime.assign(m, 0);
  hint.order.assign(m, 0);
  hint.stale.assign((m + k_block - 1) / k_block, 1);
  hint.sorted.assign((m + k_block - 1) / k_block, 0);
  hint.generation = generation;
}

// Binds the pass's arrays (sizing the outputs) and restarts the regimes of a new list.
template <bool RollingHistory>
PassData bind_pass(const Model& model, State& state, Scratch& scratch) {
  const ContactPairs& pairs = state.read<Component::contact_pairs>();
  const PairConstants& constants = scratch.read<PairConstants>();
  SANDCELL_CHECK(constants.r_star.size() == pairs.size(),
                 "contact: " + std::to_string(constants.r_star.size()) + " pair constants for " +
                     std::to_string(pairs.size()) +
                     " pairs: the pair list must come from the broadphase "
                     "(or World's rebuild of its scratch), which computes them");
  const Cell& cell = state.read<Component::cell>();
  ContactForces& out = state.write<Component::contact_forces>();
  auto& tangential = state.write<Component::contact_tangential>();
  auto& rolling = state.write<Component::contact_rolling>();
  const std::size_t m = pairs.size();
  out.force.resize(m);
  out.torque_i.resize(m);
  out.torque_j.resize(m);
  if constexpr (RollingHistory) rolling.resize(m);  // cdt has no history: like none, it allocates none
  ContactScratch& hint = scratch.own<ContactScratch>();
  restart_regimes(hint, m, constants.generation);
  SANDCELL_ASSERT(hint.regime.size() == m, "contact regimes of another pair list");

  PassData d{pairs.i.data(),
             pairs.j.data(),
             pairs.j.data(),
             state.read<Component::particle_position>().data(),
             state.read<Component::particle_velocity>().data(),
             state.read<Component::particle_angular_velocity>().data(),
             nullptr,
             nullptr,
             nullptr,
             std::numeric_limits<std::uint32_t>::max(),
             nullptr,
             state.read<Component::particle_mass>().data(),
             state.read<Component::particle_material>().data(),
             constants.r_star.data(),
             constants.m_star.data(),
             constants.r_i.data(),
             constants.r_j.data(),
             constants.image_code.data(),
             model.pairs.data(),
             model.materials.size(),
             out.force.data(),
             out.torque_i.data(),
             out.torque_j.data(),
             tangential.data(),
             rolling.data(),
             hint.regime.data(),
             hint.order.data(),
             hint.stale.data(),
             hint.sorted.data(),
             {},
             cell.rate,
             cell.shear_rate,
             model.dt,
             characteristic_velocity(model.contact)};
  d.gx = d.x;
  d.gv = d.v;
  d.gw = d.w;
  if (servo_due(model.servo, state.clock.step)) {  // the homogenizer measures after this pass
    StressBlocks& blocks = scratch.write<StressBlocks>();
    blocks.sum.resize(9 * ((m + k_block - 1) / k_block));
    blocks.step = state.clock.step;
    blocks.pairs = m;
    d.stress_blocks = blocks.sum.data();
  }
  if (state.contacts.has_tangential_radius) {  // contact_tangential's access was taken above
    state.contacts.tangential_radius.resize(m);
    d.hist_a = state.contacts.tangential_radius.data();
  }
  // H n exactly as per pair (cell.hpp: bitwise img * L for an orthorhombic cell).
  for (int c = 0; c < 27; ++c) {
    const Image img{static_cast<std::int8_t>(c % 3 - 1), static_cast<std::int8_t>(c / 3 % 3 - 1),
                    static_cast<std::int8_t>(c / 9 - 1)};
    d.shift[c] = image_offset(img, cell);
  }
  return d;
}

// The block's sum of f (x) r for the homogenizer (StressBlocks says in what order). The forces were
// just written (L1); r is the branch vector of phase 1, as the homogenizer computed it
// (x_i - x_j - H n). An open pair adds zeros.
// With the lanes, four pairs at a time in the lanes of AVX2 registers (the forces as x, y, z lanes):
// lane l is partial sum l, so the operations are the scalar loop's. Outside the kernel, whose every
// instantiation would otherwise compile its own copy (the stepping pass inlines it: `flatten`).
template <bool Lanes>
void stress_of_block(const PassData& d, const Block& blk, std::size_t k0, std::size_t nb) {
  double acc[9][4] = {};
  std::size_t t = 0;
#if defined(SANDCELL_LANES)
  if constexpr (Lanes) {
    using V = lanes::V;
    V s[9] = {};
    for (; t + 4 <= nb; t += 4) {
      V f[3], r[3];
      lanes::load_xyz(d.force[k0 + t].data(), f[0], f[1], f[2]);
      std::memcpy(&r[0], blk.rx + t, sizeof(V));
      std::memcpy(&r[1], blk.ry + t, sizeof(V));
      std::memcpy(&r[2], blk.rz + t, sizeof(V));
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) s[3 * a + b] += f[a] * r[b];
    }
    for (int c = 0; c < 9; ++c)
      for (int l = 0; l < 4; ++l) acc[c][l] = s[c][l];
  }
#endif
  const auto add = [&](std::size_t u, std::size_t l) {
    const Vec3& f = d.force[k0 + u];
    const double r[3] = {blk.rx[u], blk.ry[u], blk.rz[u]};
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) acc[3 * a + b][l] += f[a] * r[b];
  };
  for (; t + 4 <= nb; t += 4)
    for (std::size_t l = 0; l < 4; ++l) add(t + l, l);
  for (; t < nb; ++t) add(t, t & 3);
  double* __restrict out = d.stress_blocks + 9 * (k0 / k_block);
  for (int c = 0; c < 9; ++c) out[c] = (acc[c][0] + acc[c][1]) + (acc[c][2] + acc[c][3]);
}

// The pass over one chunk of pairs, block by block, with the laws composed at compile time.
template <class Normal, class Tangential, RollingModel Roll, int Affine, bool Update, bool Ghosts>
struct ContactKernel {
  static constexpr bool rolling_history = Roll == RollingModel::epsd2 || Roll == RollingModel::epsd;
  static constexpr bool update = Update;
  PassData d;
  RollingEvaluator<Roll, Update> roll;

  // Particle j's entry of a per-particle array, or in a block with crossing pairs (G) of its ghost
  // copy: a select, not a branch, compiled only into the blocks that need it (Halo::ghost_block).
  template <bool G>
  const Vec3& of_j(const Vec3* own, const Vec3* ghost, std::uint32_t jh) const {
    if constexpr (G)
      return *(jh < d.n_own ? own + jh : ghost + (jh - d.n_own));
    else
      return own[jh];
  }

  // Phase 1: gather. With one material the pair constants are the same for every pair and
  // neither loaded nor stored per pair (the common case, compiled as its own loop).
  template <bool OneMaterial, bool G>
  void gather(Block& blk, std::size_t k0, std::size_t nb) const {
    for (std::size_t t = 0; t < nb; ++t) {
      const std::size_t k = k0 + t;
      const std::uint32_t i = d.pi[k], jh = d.pjh[k];
      const Vec3& s = d.shift[d.image_code[k]];
      const Vec3& xj = of_j<G>(d.x, d.gx, jh);
      blk.rx[t] = d.x[i][0] - xj[0] - s[0];
      blk.ry[t] = d.x[i][1] - xj[1] - s[1];
      blk.rz[t] = d.x[i][2] - xj[2] - s[2];
      if constexpr (!OneMaterial) {
        const PairMaterial& mat = d.pair_mat[d.material[i] * d.n_mat + d.material[d.pj[k]]];
        blk.mat[t] = &mat;
        blk.e_star[t] = mat.e_star;
        blk.g_star[t] = mat.g_star;
        blk.beta[t] = mat.beta;
      }
      // Phase 3 reads these per pair inside a long chain of arithmetic; fetching them here
      // overlaps their cache misses across the block. Only the j side: i changes every ~4
      // pairs and walks the arrays in order, which the hardware prefetcher follows.
      __builtin_prefetch(&of_j<G>(d.v, d.gv, jh));
      __builtin_prefetch(&of_j<G>(d.w, d.gw, jh));
    }
  }

  // Phase 2: the normal law's stiffness and damping, branch-free (apart pairs get overlap <= 0,
  // zeros after).
  template <bool OneMaterial>
  void stiffness(Block& blk, std::size_t k0, std::size_t nb) const {
    for (std::size_t t = 0; t < nb; ++t) {
      const PairMaterial& m0 = d.pair_mat[0];
      const LawPair law_pair = OneMaterial ? LawPair{m0.e_star, m0.g_star, m0.beta, d.v_char}
                                           : LawPair{blk.e_star[t], blk.g_star[t], blk.beta[t], d.v_char};
      const double r2 = blk.rx[t] * blk.rx[t] + blk.ry[t] * blk.ry[t] + blk.rz[t] * blk.rz[t];
      const double dist = std::sqrt(r2);
      const double overlap = (d.r_i[k0 + t] + d.r_j[k0 + t]) - dist;
      const double od = overlap > 0.0 ? overlap : 0.0;
      blk.inv_dist[t] = 1.0 / dist;
      blk.overlap[t] = overlap;
      const Stiffness s = Normal::stiffness(law_pair, d.r_star[k0 + t], d.m_star[k0 + t], od);
      blk.k_n[t] = s.k_n;
      blk.k_t[t] = s.k_t;
      blk.gamma_n[t] = s.gamma_n;
    }
  }

  // Phase 3 visits the block's pairs grouped by their regime in the last step: touching below the
  // caps, at the Coulomb cap, at the rolling cap, at both, open. The overlap and cap tests then run
  // in stretches of the same outcome, which the branch predictor follows; in array order they come
  // at random (in a dense sheared packing a good part of the touching pairs slide or roll at their
  // caps, and a pair changes regime only a few times in 10,000 steps). The order is a stable
  // counting sort of the block by regime, made again only when a regime in the block changed in
  // the last step; a block of pairs all touching below the caps keeps array order.
  // docs/performance.md gives the measured effect.
  void sort_block(std::size_t k0, std::size_t nb) const {
    const std::size_t block = k0 / k_block;
    if (!d.stale[block]) return;
    std::uint8_t* __restrict order = d.order + k0;
    unsigned start[6] = {0, 0, 0, 0, 0, 0};
    for (std::size_t t = 0; t < nb; ++t) ++start[d.regime[k0 + t] + 1];
    d.sorted[block] = start[1] != nb;
    if (d.sorted[block]) {
      for (unsigned g = 1; g < 5; ++g) start[g] += start[g - 1];
      for (std::size_t t = 0; t < nb; ++t) order[start[d.regime[k0 + t]]++] = static_cast<std::uint8_t>(t);
    }
    d.stale[block] = 0;
  }

  // Phase 3, one pair: normal force, tangential and rolling laws, outputs. An open pair already
  // marked open is not written: its outputs are zero since it opened. Sets `changed` when the
  // pair's regime changed.
  template <bool G>
  void visit(const Block& blk, std::size_t k0, std::size_t t, unsigned& changed) const {
    const std::size_t k = k0 + t;
    if (!(blk.overlap[t] > 0.0)) {
      if (d.regime[k] != ContactScratch::k_apart) [[unlikely]] {  // else all zero since the step it opened
        d.force[k].setZero();
        d.torque_i[k].setZero();
        d.torque_j[k].setZero();
        d.hist_t[k].setZero();  // history resets when the contact opens
        if constexpr (rolling_history) d.hist_r[k].setZero();
        if constexpr (Tangential::radius_history) d.hist_a[k] = 0.0;
        d.regime[k] = ContactScratch::k_apart;
        changed = 1;
      }
      return;
    }
    const std::uint32_t i = d.pi[k], j = d.pj[k], jh = d.pjh[k];
    const Vec3 r(blk.rx[t], blk.ry[t], blk.rz[t]);
    PairKinematics c;
    c.n = r * blk.inv_dist[t];
    c.overlap = blk.overlap[t];
    c.r_star = d.r_star[k];
    c.c_i = d.r_i[k] - 0.5 * c.overlap;
    c.c_j = d.r_j[k] - 0.5 * c.overlap;
    c.v_rel = d.v[i] - of_j<G>(d.v, d.gv, jh);
    if constexpr (Affine != k_affine_none) c.v_rel += d.rate.cwiseProduct(r);
    if constexpr (Affine == k_affine_full) {  // the off-diagonal part of L r, as the lanes add it
      c.v_rel[0] += d.shear[0] * r[1] + d.shear[1] * r[2];
      c.v_rel[1] += d.shear[2] * r[2];
    }
    c.w_i = d.w[i];
    c.w_j = of_j<G>(d.w, d.gw, jh);
    const PairMaterial& mat = d.n_mat == 1 ? d.pair_mat[0] : *blk.mat[t];
    const double k_n = blk.k_n[t], k_t = blk.k_t[t], gamma_n = blk.gamma_n[t];
    const double v_n = c.v_rel.dot(c.n);
    const double f_n = Normal::force(k_n, gamma_n, c.overlap, v_n);
    const Vec3 v_t = c.v_rel - v_n * c.n + c.n.cross(c.c_i * c.w_i + c.c_j * c.w_j);
    const double f_cap = mat.friction * std::abs(f_n);
    double no_radius = 0.0;  // the laws without a radius history neither read nor keep it
    const double a = Tangential::radius_history ? std::sqrt(c.r_star * c.overlap) : 0.0;  // contact radius, m
    const TangentialResult tr = Tangential::template force<Update>(
        c.n, v_t, k_t, Normal::gamma_t(mat, gamma_n), f_cap, d.dt, d.hist_t[k], a,
        Tangential::radius_history ? d.hist_a[k] : no_radius);
    const Vec3 arm_torque = c.n.cross(tr.f_t);  // torque on i is -c_i n x F_t, on j -c_j n x F_t
    Vec3 t_i = -c.c_i * arm_torque;
    Vec3 t_j = -c.c_j * arm_torque;
    unsigned rolling_capped = 0;
    if constexpr (Roll != RollingModel::none) {
      Vec3 no_history = Vec3::Zero();  // cdt: not read, not kept
      double i_r = 0.0;
      if constexpr (Roll == RollingModel::epsd) {
        const double a = d.mass[i] * d.r_i[k] * d.r_i[k];
        const double b = d.mass[j] * d.r_j[k] * d.r_j[k];
        i_r = 1.4 * a * b / (a + b);
      }
      const Vec3 moment =
          roll.evaluate(RollingInput{c.n, c.w_i - c.w_j, c.overlap, f_n, k_n, k_t, c.r_star, i_r, mat.rolling_friction},
                        rolling_history ? d.hist_r[k] : no_history, rolling_capped);
      t_i -= moment;
      t_j += moment;
    }
    d.force[k] = f_n * c.n + tr.f_t;
    d.torque_i[k] = t_i;
    d.torque_j[k] = t_j;
    const std::uint8_t now = static_cast<std::uint8_t>(tr.capped | rolling_capped);
    if (now != d.regime[k]) [[unlikely]] {  // a few times per pair in 10,000 steps
      d.regime[k] = now;
      changed = 1;
    }
  }

#if defined(SANDCELL_LANES)
  // Phase 3 for four touching pairs at once, in the lanes of AVX2 registers, when every law of the
  // pass has a four-lane form (systems/laws/lanes.hpp; today Hertz, Mindlin with history, epsd2 or
  // no rolling): this is the plumbing (loads, the slip velocity, torques, stores, regimes), the
  // physics is the laws' force4 / gamma_t4 / evaluate4. Each lane does the scalar visit's
  // operations in the scalar visit's order, so a pair's result is bitwise the one of visit()
  // (dem-bench's digest, the portable build without this path, and
  // tests/systems/test_contact_lanes.cpp, check it). Where a lane is at a cap, both outcomes are
  // computed and each lane's is selected; the square roots and divisions of the caps are skipped
  // when no lane is (in a block sorted by regime, most groups).
  // Not for the setup pass (Update false), which runs once per scene: fewer instantiations.
  static constexpr bool k_lanes = Update && has_lanes<Normal> && has_lanes<Tangential> &&
                                  (Roll == RollingModel::none || has_lanes<RollingEvaluator<Roll, Update>>);
  using V = lanes::V;
  using L = lanes::L;
  static V sum3(V a, V b, V c) { return lanes::sum3(a, b, c); }
  // The four lanes f(0), ..., f(3).
  template <class F>
  static V lanes_of(F f) {
    return V{f(0), f(1), f(2), f(3)};
  }
  // Contig: the four are consecutive pairs (tt[0] + l), whose per-pair arrays load as vectors;
  // OneMaterial: one material pair, whose constants are broadcast.
  template <bool G, bool Contig, bool OneMaterial>
  void visit4(const Block& blk, std::size_t k0, const std::uint8_t* tt, unsigned& changed) const {
    std::size_t k[4];
    const Vec3* vi[4];
    const Vec3* vj[4];
    const Vec3* wi[4];
    const Vec3* wj[4];
    [[maybe_unused]] const PairMaterial* mt[4];
    for (int l = 0; l < 4; ++l) {
      k[l] = k0 + tt[l];
      const std::uint32_t i = d.pi[k[l]], jh = d.pjh[k[l]];
      vi[l] = &d.v[i];
      vj[l] = &of_j<G>(d.v, d.gv, jh);
      wi[l] = &d.w[i];
      wj[l] = &of_j<G>(d.w, d.gw, jh);
      if constexpr (!OneMaterial) mt[l] = blk.mat[tt[l]];
    }
    // A block array's lanes, and a per-pair array's.
    const auto of_block = [&](const double* a) {
      if constexpr (Contig) {
        V x;
        std::memcpy(&x, a + tt[0], sizeof x);
        return x;
      } else {
        return lanes_of([&](int l) { return a[tt[l]]; });
      }
    };
    const auto of_pair = [&](const double* a) {
      if constexpr (Contig) {
        V x;
        std::memcpy(&x, a + k[0], sizeof x);
        return x;
      } else {
        return lanes_of([&](int l) { return a[k[l]]; });
      }
    };
    const auto of_mat = [&](double PairMaterial::*f) {
      if constexpr (OneMaterial) {
        const double x = d.pair_mat[0].*f;
        return V{x, x, x, x};
      } else {
        return lanes_of([&](int l) { return mt[l]->*f; });
      }
    };
    // A per-pair array of 3-vectors as x, y, z lanes, and back.
    const auto of_pair3 = [&](const Vec3* a, V& x, V& y, V& z) {
      if constexpr (Contig) {
        lanes::load_xyz(a[k[0]].data(), x, y, z);
      } else {
        x = lanes_of([&](int l) { return a[k[l]][0]; });
        y = lanes_of([&](int l) { return a[k[l]][1]; });
        z = lanes_of([&](int l) { return a[k[l]][2]; });
      }
    };
    const auto to_pair3 = [&](Vec3* a, V x, V y, V z) {
      if constexpr (Contig) {
        lanes::store_xyz(a[k[0]].data(), x, y, z);
      } else {
        for (int l = 0; l < 4; ++l) a[k[l]] = Vec3(x[l], y[l], z[l]);
      }
    };
    const V rx = of_block(blk.rx), ry = of_block(blk.ry), rz = of_block(blk.rz);
    const V inv = of_block(blk.inv_dist);
    const V ov = of_block(blk.overlap);
    const V k_n = of_block(blk.k_n), k_t = of_block(blk.k_t);
    const V gamma_n = of_block(blk.gamma_n);
    const V nx = rx * inv, ny = ry * inv, nz = rz * inv;
    const V c_i = of_pair(d.r_i) - 0.5 * ov;
    const V c_j = of_pair(d.r_j) - 0.5 * ov;
    // Component c of four particles' 3-vectors.
    const auto comp = [](const Vec3* const* p, int c) { return lanes_of([&](int l) { return (*p[l])[c]; }); };
    V vx = comp(vi, 0) - comp(vj, 0);
    V vy = comp(vi, 1) - comp(vj, 1);
    V vz = comp(vi, 2) - comp(vj, 2);
    if constexpr (Affine != k_affine_none) {
      vx += d.rate[0] * rx;
      vy += d.rate[1] * ry;
      vz += d.rate[2] * rz;
    }
    if constexpr (Affine == k_affine_full) {  // the off-diagonal part of L r (a shearing cell)
      vx += d.shear[0] * ry + d.shear[1] * rz;
      vy += d.shear[2] * rz;
    }
    const V wix = comp(wi, 0), wiy = comp(wi, 1), wiz = comp(wi, 2);
    const V wjx = comp(wj, 0), wjy = comp(wj, 1), wjz = comp(wj, 2);
    const V friction = of_mat(&PairMaterial::friction);
    const V damping_t = of_mat(&PairMaterial::damping_ratio_t);
    const V v_n = sum3(vx * nx, vy * ny, vz * nz);
    const V f_n = Normal::force4(k_n, gamma_n, ov, v_n);
    // v_t = v_rel - v_n n + n x (c_i w_i + c_j w_j)
    const V ux = c_i * wix + c_j * wjx, uy = c_i * wiy + c_j * wjy, uz = c_i * wiz + c_j * wjz;
    const V vtx = (vx - v_n * nx) + (ny * uz - nz * uy);
    const V vty = (vy - v_n * ny) + (nz * ux - nx * uz);
    const V vtz = (vz - v_n * nz) + (nx * uy - ny * ux);
    const V f_cap = friction * lanes::vabs(f_n);
    const V gamma_t = Normal::gamma_t4(gamma_n, damping_t);
    // The tangential law (the lanes run only in the stepping pass, k_lanes: the history advances).
    V hx, hy, hz, ftx, fty, ftz;
    of_pair3(d.hist_t, hx, hy, hz);
    const L t_cap = Tangential::force4(nx, ny, nz, vtx, vty, vtz, k_t, gamma_t, f_cap, d.dt, hx, hy, hz, ftx, fty, ftz);
    // torques of the tangential force: -c n x F_t
    const V ax = ny * ftz - nz * fty, ay = nz * ftx - nx * ftz, az = nx * fty - ny * ftx;
    const V mc_i = -c_i, mc_j = -c_j;
    V tix = mc_i * ax, tiy = mc_i * ay, tiz = mc_i * az;
    V tjx = mc_j * ax, tjy = mc_j * ay, tjz = mc_j * az;
    L r_cap = L{0, 0, 0, 0};
    V gx, gy, gz;
    if constexpr (Roll != RollingModel::none) {  // the rolling law's four-lane form (k_lanes)
      const V mu_r = of_mat(&PairMaterial::rolling_friction);
      const V r_star = of_pair(d.r_star);
      r_cap = roll.evaluate4(
          nx, ny, nz, wix - wjx, wiy - wjy, wiz - wjz, f_n, k_t, r_star, mu_r, d.dt,
          [&](V& x, V& y, V& z) { of_pair3(d.hist_r, x, y, z); }, gx, gy, gz);
      tix -= gx;
      tiy -= gy;
      tiz -= gz;
      tjx += gx;
      tjy += gy;
      tjz += gz;
    }
    const V fx = f_n * nx + ftx, fy = f_n * ny + fty, fz = f_n * nz + ftz;
    to_pair3(d.force, fx, fy, fz);
    to_pair3(d.torque_i, tix, tiy, tiz);
    to_pair3(d.torque_j, tjx, tjy, tjz);
    to_pair3(d.hist_t, hx, hy, hz);
    if constexpr (Roll != RollingModel::none) to_pair3(d.hist_r, gx, gy, gz);
    // The four regimes as bytes (lane l: bit 0 at the Coulomb cap, bit 1 at the rolling cap) from the
    // caps' sign masks, compared with last step's four at once where the pairs are consecutive.
    static constexpr std::uint32_t k_spread[16] = {
        0x00000000, 0x00000001, 0x00000100, 0x00000101, 0x00010000, 0x00010001, 0x00010100, 0x00010101,
        0x01000000, 0x01000001, 0x01000100, 0x01000101, 0x01010000, 0x01010001, 0x01010100, 0x01010101};
    const std::uint32_t now4 = k_spread[_mm256_movemask_pd((__m256d)t_cap)] |
                               (k_spread[_mm256_movemask_pd((__m256d)r_cap)] << 1);
    if constexpr (Contig) {
      std::uint32_t old4;
      std::memcpy(&old4, d.regime + k[0], sizeof old4);
      if (old4 != now4) [[unlikely]] {
        std::memcpy(d.regime + k[0], &now4, sizeof now4);
        changed = 1;
      }
    } else {
      for (int l = 0; l < 4; ++l) {
        const std::uint8_t now = static_cast<std::uint8_t>(now4 >> (8 * l));
        if (now != d.regime[k[l]]) [[unlikely]] {
          d.regime[k[l]] = now;
          changed = 1;
        }
      }
    }
  }
#else
  static constexpr bool k_lanes = false;
#endif

  // Phase 3 over the block in the order `at(u)`, u < nb: with the lanes, touching pairs in fours.
  template <bool G, class At>
  void phase3(const Block& blk, std::size_t k0, std::size_t nb, At at, unsigned& changed) const {
#if defined(SANDCELL_LANES)
    if constexpr (k_lanes) {
      // The touching pairs in visiting order, gathered without branches (an apart pair's slot is
      // overwritten by the next); the apart pairs go to the scalar visit, which writes only those
      // that opened this step. Each pair's result depends on that pair alone, so visiting the apart
      // ones first changes no result.
      std::uint8_t touching[k_block];
      unsigned n_touch = 0;
      for (std::size_t u = 0; u < nb; ++u) {
        const std::uint8_t t = at(u);
        touching[n_touch] = t;
        const bool touch = blk.overlap[t] > 0.0;
        n_touch += touch;
        if (!touch) [[unlikely]]
          visit<G>(blk, k0, t, changed);
      }
      unsigned u = 0;
      for (; u + 4 <= n_touch; u += 4) {
        const std::uint8_t* four = touching + u;
        const bool contig = four[1] == four[0] + 1 && four[2] == four[0] + 2 && four[3] == four[0] + 3;
        if (d.n_mat == 1) {
          if (contig)
            visit4<G, true, true>(blk, k0, four, changed);
          else
            visit4<G, false, true>(blk, k0, four, changed);
        } else {
          if (contig)
            visit4<G, true, false>(blk, k0, four, changed);
          else
            visit4<G, false, false>(blk, k0, four, changed);
        }
      }
      for (; u < n_touch; ++u) visit<G>(blk, k0, touching[u], changed);
      return;
    }
#endif
    for (std::size_t u = 0; u < nb; ++u) visit<G>(blk, k0, at(u), changed);
  }

  // One block of pairs, all three phases; G: the block has pairs whose j is a ghost.
  template <bool G>
  void block(Block& blk, std::size_t k0, std::size_t nb) const {
    if (d.n_mat == 1) {
      gather<true, G>(blk, k0, nb);
      stiffness<true>(blk, k0, nb);
    } else {
      gather<false, G>(blk, k0, nb);
      stiffness<false>(blk, k0, nb);
    }
    sort_block(k0, nb);
    const std::size_t index = k0 / k_block;
    unsigned changed = 0;
    if (d.sorted[index]) {
      const std::uint8_t* __restrict order = d.order + k0;
      const auto by_regime = [order](std::size_t u) { return order[u]; };
      phase3<G>(blk, k0, nb, by_regime, changed);
    } else {  // no pair at a cap: array order
      const auto in_array_order = [](std::size_t u) { return static_cast<std::uint8_t>(u); };
      phase3<G>(blk, k0, nb, in_array_order, changed);
    }
    d.stale[index] = changed != 0;
    if (d.stress_blocks) stress_of_block<k_lanes>(d, blk, k0, nb);
  }

  void chunk(std::size_t b, std::size_t e) const {
    Block blk;
    for (std::size_t k0 = b; k0 < e; k0 += k_block) {
      const std::size_t nb = std::min(k_block, e - k0);
      if constexpr (Ghosts) {
        if (d.ghost_block[k0 / k_block]) {
          block<true>(blk, k0, nb);
          continue;
        }
      }
      block<false>(blk, k0, nb);
    }
  }
};

// Under the owner partition with more than one share the pairs are cut where the particle passes
// cut the particles, and what crosses a cut goes through the halo (systems/halo.hpp): the ghosts
// are copied first, each share by the thread that owns its particles, then each pass chunk copies
// its crossing pairs' force and torque on j into the slots the gather reads. Each pair's result
// does not depend on its chunk nor on where it reads j from, so the results are the same for any
// shares; without a halo, one share: the plain pass.
Halo& prepare_halo(const State& state, Scratch& scratch, const Executor& exec) {
  Halo& halo = scratch.write<Halo>();
  const std::size_t n = state.particles.size(), m = state.contacts.pairs.size();
  const Executor::Shares particles = exec.shares(n, k_particle_grain);
  if (particles.count == 1) {
    halo.active = false;
    halo.n = n;
    halo.m = m;
    halo.particles = particles;  // so that a later pass in shares (Partition::adaptive) rebuilds it
    return halo;
  }
  const PairConstants& constants = scratch.read<PairConstants>();
  if (halo.generation != constants.generation || halo.n != n || halo.m != m ||
      halo.particles.count != particles.count ||
      !std::equal(particles.bounds.begin(), particles.bounds.begin() + particles.count + 1,
                  halo.particles.bounds.begin()))
    rebuild_halo(state.contacts.pairs, scratch.read<GatherIndex>(), particles, k_block, constants.generation, halo);
  return halo;
}

// The pass over the shares, each chunk followed by the copy of its crossing pairs' outputs to the
// halo's slots (when there is a halo).
template <class Kernel>
void run_kernel(const Kernel& kernel, const Executor::Shares& shares, Halo* h, Executor& exec) {
  const auto copy_slots = [h](const PassData& d, std::size_t b, std::size_t e) {
    if (!h) return;
    auto q = std::lower_bound(h->slot_pair.begin(), h->slot_pair.end(), static_cast<std::uint32_t>(b));
    for (; q != h->slot_pair.end() && *q < e; ++q) {
      const std::size_t slot = h->slot_of[static_cast<std::size_t>(q - h->slot_pair.begin())];
      h->sf[slot] = d.force[*q];
      h->st[slot] = d.torque_j[*q];
    }
  };
  // `flatten` inlines the kernel and the laws' small Eigen operations into the loop: left to GCC's
  // heuristics, composing the laws as types kept one of them out of line, +7.7 % instructions
  // (callgrind). Only the stepping pass, and not under a sanitizer: there it multiplies the
  // instrumented code, and compiling this file under ASan took 11 min and 7.5 GB.
  if constexpr (Kernel::update && !k_sanitized) {
    exec.parallel_for_shares(
        shares, k_contact_grain, [&kernel, copy_slots ](std::size_t b, std::size_t e) __attribute__((flatten)) {
          kernel.chunk(b, e);
          copy_slots(kernel.d, b, e);
        });
  } else {
    exec.parallel_for_shares(shares, k_contact_grain, [&kernel, copy_slots](std::size_t b, std::size_t e) {
      kernel.chunk(b, e);
      copy_slots(kernel.d, b, e);
    });
  }
}

template <class Normal, class Tangential, RollingModel Roll, int Affine, bool Update>
void contact_loop(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  constexpr bool rolling_history = Roll == RollingModel::epsd2 || Roll == RollingModel::epsd;
  PassData d = bind_pass<rolling_history>(model, state, scratch);
  const RollingEvaluator<Roll, Update> roll{model.dt, model.contact.rolling_damping};
  Halo& halo = prepare_halo(state, scratch, exec);
  if (!halo.active) {
    Executor::Shares all;
    all.count = 1;
    all.bounds[1] = state.contacts.pairs.size();
    run_kernel(ContactKernel<Normal, Tangential, Roll, Affine, Update, false>{d, roll}, all, nullptr, exec);
    return;
  }
  if constexpr (!Update) {
    // The setup pass reads j in place (the same values): no kernels with ghosts compiled for it.
    run_kernel(ContactKernel<Normal, Tangential, Roll, Affine, Update, false>{d, roll}, halo.pairs, &halo, exec);
  } else {
    exec.parallel_for_shares(halo.exports, std::numeric_limits<std::size_t>::max() / 2,
                             [&halo, &d](std::size_t b, std::size_t e) {
                               for (std::size_t q = b; q < e; ++q) {
                                 const std::uint32_t g = halo.export_ghost[q], p = halo.ghost_of[g];
                                 halo.gx[g] = d.x[p];
                                 halo.gv[g] = d.v[p];
                                 halo.gw[g] = d.w[p];
                               }
                             });
    d.pjh = halo.pj.data();
    d.gx = halo.gx.data();
    d.gv = halo.gv.data();
    d.gw = halo.gw.data();
    d.n_own = static_cast<std::uint32_t>(halo.n);
    d.ghost_block = halo.ghost_block.data();
    run_kernel(ContactKernel<Normal, Tangential, Roll, Affine, Update, true>{d, roll}, halo.pairs, &halo, exec);
  }
}

// The pass for the rolling law R, with the model's normal and tangential laws and the cell's
// affine term: `update` true for a step, false for the setup pass.
template <RollingModel R>
void run_rolling(const Model& model, State& state, Scratch& scratch, Executor& exec, bool update) {
  with_laws(model.contact, [&](auto normal, auto tangential, auto roll) {
    if constexpr (decltype(roll)::value == R) {
      using N = typename decltype(normal)::type;
      using T = typename decltype(tangential)::type;
      const auto loop = [&]<bool Update>(std::bool_constant<Update>) {
        if (model.contact.liggghts_compat)
          contact_loop<N, T, R, k_affine_none, Update>(model, state, scratch, exec);
        else if (state.cell.shear_rate.isZero(0.0))
          contact_loop<N, T, R, k_affine_diagonal, Update>(model, state, scratch, exec);
        else
          contact_loop<N, T, R, k_affine_full, Update>(model, state, scratch, exec);
      };
      if (update)
        loop(std::true_type{});
      else
        loop(std::false_type{});
    }
  });
}

}  // namespace

}  // namespace sandcell
