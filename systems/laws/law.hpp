#pragma once
// What a contact law is, to the contact pass (systems/contact_pass.cpp). A contact is evaluated by
// three small laws, composed at compile time, so the hot loop has no run-time switches:
//
// Normal law (systems/laws/hertz.hpp, hooke.hpp; registered in normal_laws.hpp), a type with
//   static constexpr std::string_view name;                    its key in ContactSettings::normal
//   static constexpr std::array<LawParameter, N> parameters;    the keys it reads from
//                                                               ContactSettings::parameters, with
//                                                               units and ranges (the apps read them)
//   static void validate(const ContactSettings&);               their values (throws invalid_argument)
//   static Stiffness stiffness(const LawPair&, double r_star, double m_star, double od);
//       k_n, k_t and gamma_n of a pair at overlap od >= 0 (branch-free: the pass calls it for a
//       block of pairs at once, apart ones with od = 0, and the compiler vectorizes the block)
//   static double gamma_t(const PairMaterial&, double gamma_n);  tangential damping coefficient
//   static double force(double k_n, double gamma_n, double overlap, double v_n);   F_n (signed)
//   static AtRest at_rest(const PairMaterial&, const ContactSettings&, double r_star, double m_star,
//                         double overlap);   k_n, k_t, the stored normal energy and the tangent
//                                            normal stiffness dF_n/d delta (measures, time step)
// Tangential law (systems/laws/mindlin.hpp; selected by ContactSettings::tangential): updates its
//   per-contact history (ContactS::tangential) and returns the tangential force, capped by Coulomb;
//   energy(k_t, history) is its stored energy.
// Rolling law (systems/laws/rolling.hpp; ContactSettings::rolling): the moment from the relative
//   rotation, its history (Contacts::rolling) when the law keeps one, stiffness and energy.
//
// Each law's per-contact history is a field of the contact component registry (components/fields.hpp:
// for_each_contact_history), which the broadphase carries from list to list without naming it.
#include "engine/model.hpp"
#include "components/types.hpp"

#include <string_view>

namespace sandcell {

/// The constants of a material pair the normal laws read in the vectorized stiffness phase (the
/// contact pass gathers them per pair only when the scene has more than one material).
struct LawPair {
  double e_star;  // Pa
  double g_star;  // Pa
  double beta;    // -, ln(e)/sqrt(ln(e)^2 + pi^2), <= 0
  double v_char;  // m/s, the characteristic velocity of laws that have one (hooke), else 0
};

struct Stiffness {
  double k_n;      // N/m, normal stiffness: F_n = k_n delta - gamma_n v_n
  double k_t;      // N/m, tangential stiffness
  double gamma_n;  // kg/s, normal damping coefficient
};

struct AtRest {
  double k_n;        // N/m, F_n / delta (the force's secant stiffness)
  double k_t;        // N/m
  double energy;     // J, stored elastic energy of the normal spring
  double k_tangent;  // N/m, dF_n / d delta (the stiffness a small oscillation sees: the time step's)
};

/// A named parameter of a law (ContactSettings::parameters[name]): its units, range and meaning,
/// which the apps' configs, dem-bench and Python read from the registry.
struct LawParameter {
  std::string_view name;
  std::string_view units;
  double lo, hi;  // the allowed range, inclusive
  std::string_view what;
};

/// The registered laws of one kind, in the order of their registration.
template <class... Laws>
struct LawList {};

}  // namespace sandcell
