#pragma once
// Tangential laws: Mindlin's no-slip spring with a Coulomb cap (docs/physics.md section 2), in the
// two history forms of ContactSettings::tangential. The stiffness k_t and the damping gamma_t come
// from the normal law; the history is the contact component's `tangential` field.
//
// MindlinHistory (LIGGGHTS `tangential history`): spring displacement u_t (m),
//   u_t += v_t dt, projected on the tangent plane; F_t = -k_t u_t - gamma_t v_t; at the cap
//   (|k_t u_t| > mu |F_n|) F_t = mu |F_n| in the direction of -u_t, undamped, and u_t = -F_t / k_t.
// MindlinIncremental: stored elastic force F_s (N), rotated into the new tangent plane (projected,
//   magnitude kept), F_s -= k_t v_t dt; at the cap F_s is scaled to mu |F_n| and F_t = F_s, else
//   F_t = F_s - gamma_t v_t.
// MindlinRescale (LAMMPS GRANULAR `tangential mindlin_rescale`): MindlinHistory, and when the
//   contact unloads (its radius a = sqrt(R* delta) below the last step's a_prev) the displacement
//   is first scaled by a / a_prev, so a contact that shrinks does not keep a tangential force its
//   smaller area (k_t = 8 G* a) can no longer carry elastically; a_prev is a per-contact history
//   (Contacts::tangential_radius, m, allocated only for this law).
// Each law: `name` (ContactSettings::tangential's value; the registry is TangentialLaws below),
// `id`, `radius_history` (whether it keeps a_prev), force<Update>(..., a, a_prev) and energy.
// Update: whether the history advances (false in the setup pass, which freezes it).
#include "systems/laws/lanes.hpp"
#include "systems/laws/law.hpp"

#include <cmath>
#include <string_view>

namespace sandcell {

struct TangentialResult {
  Vec3 f_t;         // N, tangential force on i
  unsigned capped;  // 1 at the Coulomb cap, else 0
};

struct MindlinHistory {
  static constexpr std::string_view name = "history";
  static constexpr TangentialModel id = TangentialModel::history;
  static constexpr bool radius_history = false;

  template <bool Update>
  [[gnu::always_inline]] static inline TangentialResult force(const Vec3& n, const Vec3& v_t, double k_t,
                                                              double gamma_t, double f_cap, double dt, Vec3& history,
                                                              double /*a*/, double& /*a_prev*/) {
    Vec3 h = history;
    if constexpr (Update) h += v_t * dt;
    h -= h.dot(n) * n;
    Vec3 f_t = -k_t * h;
    unsigned capped = 0;
    const double f2 = f_t.squaredNorm();
    if (f2 > f_cap * f_cap) {
      capped = 1;
      f_t *= f_cap / std::sqrt(f2);
      h = f_t / -k_t;
    } else {
      f_t -= gamma_t * v_t;
    }
    history = h;
    return TangentialResult{f_t, capped};
  }
  /// Stored energy 1/2 k_t |u_t|^2, J.
  static double energy(double k_t, double h2) { return 0.5 * k_t * h2; }
#if defined(SANDCELL_LANES)
  // The four-lane form of force<true> (systems/laws/lanes.hpp): the history h (in, out) and the force
  // f_t (out) as x, y, z lanes; returns the lanes at the Coulomb cap. The cap's square root and
  // division only where a lane is capped (in a group sorted by regime, seldom).
  static constexpr bool lanes = true;
  [[gnu::always_inline]] static inline lanes::L force4(lanes::V nx, lanes::V ny, lanes::V nz, lanes::V vtx,
                                                      lanes::V vty, lanes::V vtz, lanes::V k_t, lanes::V gamma_t,
                                                      lanes::V f_cap, double dt, lanes::V& hx, lanes::V& hy,
                                                      lanes::V& hz, lanes::V& ftx, lanes::V& fty, lanes::V& ftz) {
    using lanes::V;
    hx += vtx * dt;
    hy += vty * dt;
    hz += vtz * dt;
    const V hn = lanes::sum3(hx * nx, hy * ny, hz * nz);
    hx -= hn * nx;
    hy -= hn * ny;
    hz -= hn * nz;
    const V mk_t = -k_t;
    ftx = mk_t * hx;
    fty = mk_t * hy;
    ftz = mk_t * hz;
    const V f2 = lanes::sum3(ftx * ftx, fty * fty, ftz * ftz);
    const lanes::L t_cap = f2 > f_cap * f_cap;
    if (lanes::any(t_cap)) [[unlikely]] {
      const V scale = f_cap / lanes::vsqrt(f2);
      const V ctx = ftx * scale, cty = fty * scale, ctz = ftz * scale;
      hx = lanes::sel(t_cap, ctx / mk_t, hx);
      hy = lanes::sel(t_cap, cty / mk_t, hy);
      hz = lanes::sel(t_cap, ctz / mk_t, hz);
      ftx = lanes::sel(t_cap, ctx, ftx - gamma_t * vtx);
      fty = lanes::sel(t_cap, cty, fty - gamma_t * vty);
      ftz = lanes::sel(t_cap, ctz, ftz - gamma_t * vtz);
    } else {
      ftx -= gamma_t * vtx;
      fty -= gamma_t * vty;
      ftz -= gamma_t * vtz;
    }
    return t_cap;
  }
#endif
};

struct MindlinIncremental {
  static constexpr std::string_view name = "incremental";
  static constexpr TangentialModel id = TangentialModel::incremental;
  static constexpr bool radius_history = false;

  template <bool Update>
  [[gnu::always_inline]] static inline TangentialResult force(const Vec3& n, const Vec3& v_t, double k_t,
                                                              double gamma_t, double f_cap, double dt, Vec3& history,
                                                              double /*a*/, double& /*a_prev*/) {
    Vec3 h = history;
    const double old2 = h.squaredNorm();
    h -= h.dot(n) * n;
    const double new2 = h.squaredNorm();
    if (new2 > 0.0) h *= std::sqrt(old2 / new2);
    if constexpr (Update) h -= (k_t * dt) * v_t;
    Vec3 f_t;
    unsigned capped = 0;
    const double f2 = h.squaredNorm();
    if (f2 > f_cap * f_cap) {
      capped = 1;
      h *= f_cap / std::sqrt(f2);
      f_t = h;
    } else {
      f_t = h - gamma_t * v_t;
    }
    history = h;
    return TangentialResult{f_t, capped};
  }
  /// Stored energy |F_s|^2 / (2 k_t), J.
  static double energy(double k_t, double h2) { return 0.5 * h2 / k_t; }
};

struct MindlinRescale {
  static constexpr std::string_view name = "mindlin_rescale";
  static constexpr TangentialModel id = TangentialModel::mindlin_rescale;
  static constexpr bool radius_history = true;

  template <bool Update>
  [[gnu::always_inline]] static inline TangentialResult force(const Vec3& n, const Vec3& v_t, double k_t,
                                                              double gamma_t, double f_cap, double dt, Vec3& history,
                                                              double a, double& a_prev) {
    if constexpr (Update) {
      if (a < a_prev) history *= a / a_prev;  // unloading: the displacement shrinks with the contact
      a_prev = a;
    }
    return MindlinHistory::force<Update>(n, v_t, k_t, gamma_t, f_cap, dt, history, a, a_prev);
  }
  static double energy(double k_t, double h2) { return MindlinHistory::energy(k_t, h2); }
};

// The registry of tangential laws: ContactSettings::tangential names one of them by `name`.
using TangentialLaws = LawList<MindlinHistory, MindlinIncremental, MindlinRescale>;

}  // namespace sandcell
