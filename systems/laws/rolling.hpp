#pragma once
// Rolling laws (docs/physics.md section 3, Ai et al. 2011), evaluated inside the contact pass.
//
// epsd2 (LIGGGHTS `rolling_friction epsd2`): k_r = k_t R*^2; M += k_r w_r dt, capped at mu_r R* |F_n|.
// epsd (Ai type C): k_r = 2.25 k_n mu_r^2 R*^2, same cap, plus a dashpot C_r w_r below the cap,
//   C_r = eta_r 2 sqrt(I_r k_r), I_r = 1.4 (m_i R_i^2)(m_j R_j^2) / (m_i R_i^2 + m_j R_j^2).
// cdt (Ai type A): M = mu_r k_n delta R* w_r / |w_r| (no history).
// w_r = w_i - w_j with its twisting (normal) part removed. The torque on i is -M, on j +M.
//
// Why an evaluator and not a pass of its own: a separate rolling pass over the pair list re-read
// the normal, the normal force and the stiffness the contact law had just computed (written to and
// read back from memory per pair) and cost a sixth of a step on the dense-20k benchmark (docs/performance.md); evaluated in
// the contact pass it reuses them from registers. With RollingModel::none the contact pass is
// instantiated without it and the rolling history is never allocated; cdt keeps no history either,
// so it allocates none.
#include "systems/laws/lanes.hpp"
#include "systems/laws/law.hpp"

#include <cmath>
#include <string_view>

namespace sandcell {

/// The registry of rolling laws: ContactSettings::rolling's names and what each keeps per contact.
struct RollingLawInfo {
  RollingModel id;
  std::string_view name;
  std::string_view history;  // the per-contact history it keeps ("" none), Contacts::rolling
};
inline constexpr RollingLawInfo k_rolling_laws[] = {
    {RollingModel::none, "none", ""},
    {RollingModel::epsd2, "epsd2", "rolling moment, N m"},
    {RollingModel::epsd, "epsd", "rolling moment, N m"},
    {RollingModel::cdt, "cdt", ""},
};

struct RollingInput {
  const Vec3& n;    // unit normal, j to i
  Vec3 w_rel;       // rad/s, w_i - w_j
  double overlap;   // m
  double f_n;       // N, normal force
  double k_n, k_t;  // N/m
  double r_star;    // m
  double i_r;       // kg m^2, rolling inertia (epsd only)
  double mu_r;      // -, rolling friction
};

/// k_r of the laws with a stored moment (epsd2, epsd), N m/rad.
template <RollingModel Kind>
[[gnu::always_inline]] inline double rolling_stiffness(double k_n, double k_t, double mu_r, double r_star) {
  return Kind == RollingModel::epsd2 ? k_t * r_star * r_star : 2.25 * k_n * mu_r * mu_r * r_star * r_star;
}

// Update: whether the stored moment advances (false in the setup pass).
template <RollingModel Kind, bool Update>
struct RollingEvaluator {
  double dt;
  double eta_r;

  /// Returns the rolling moment M (torque -M on i, +M on j); updates the stored moment. Sets bit 1
  /// of `regime` when the moment is at its cap (never for cdt).
  [[gnu::always_inline]] inline Vec3 evaluate(const RollingInput& in, Vec3& history, unsigned& regime) const {
    Vec3 w_r = in.w_rel;
    w_r -= w_r.dot(in.n) * in.n;  // twisting part removed
    if constexpr (Kind == RollingModel::cdt) {
      const double wn = w_r.norm();
      if (!(wn > 0.0)) return Vec3::Zero();
      return (in.mu_r * in.k_n * in.overlap * in.r_star / wn) * w_r;
    } else {
      const double k_r = rolling_stiffness<Kind>(in.k_n, in.k_t, in.mu_r, in.r_star);
      const double cap = in.mu_r * in.r_star * std::abs(in.f_n);
      Vec3 h = history;
      if constexpr (Update) h += (k_r * dt) * w_r;
      const double h2 = h.squaredNorm();
      if (h2 > cap * cap) {
        regime |= 2;
        h *= cap / std::sqrt(h2);
        history = h;
        return h;
      }
      history = h;
      if constexpr (Kind == RollingModel::epsd) return h + (eta_r * 2.0 * std::sqrt(in.i_r * k_r)) * w_r;
      return h;
    }
  }
#if defined(SANDCELL_LANES)
  // epsd2's four-lane form of evaluate (systems/laws/lanes.hpp), stepping pass only: the stored moment
  // g as x, y, z lanes, loaded by load(gx, gy, gz) where the scalar form reads it, updated in place;
  // returns the lanes at the cap.
  static constexpr bool lanes = Kind == RollingModel::epsd2 && Update;
  template <class Load>
  [[gnu::always_inline]] inline lanes::L evaluate4(lanes::V nx, lanes::V ny, lanes::V nz, lanes::V wx, lanes::V wy,
                                                  lanes::V wz, lanes::V f_n, lanes::V k_t, lanes::V r_star,
                                                  lanes::V mu_r, double step, Load&& load, lanes::V& gx,
                                                  lanes::V& gy, lanes::V& gz) const {
    using lanes::V;
    const V wn = lanes::sum3(wx * nx, wy * ny, wz * nz);
    wx -= wn * nx;
    wy -= wn * ny;
    wz -= wn * nz;
    const V k_r = k_t * r_star * r_star;
    const V cap = mu_r * r_star * lanes::vabs(f_n);
    load(gx, gy, gz);
    const V kdt = k_r * step;  // step: the pass's dt (= this->dt), as the caller holds it
    gx += kdt * wx;
    gy += kdt * wy;
    gz += kdt * wz;
    const V g2 = lanes::sum3(gx * gx, gy * gy, gz * gz);
    const lanes::L r_cap = g2 > cap * cap;
    if (lanes::any(r_cap)) [[unlikely]] {
      const V rs = cap / lanes::vsqrt(g2);
      gx = lanes::sel(r_cap, gx * rs, gx);
      gy = lanes::sel(r_cap, gy * rs, gy);
      gz = lanes::sel(r_cap, gz * rs, gz);
    }
    return r_cap;
  }
#endif
};

}  // namespace sandcell
