#pragma once
// Stress homogenizer (docs/physics.md section 5): the cell's stress from the contact forces, and the state measures
// a geomechanics user reads off a test.
//
// The system (`Homogenizer`) measures only what the servo needs, only on servo steps
// (clock.step % servo.interval == 0): the symmetrized Love-Weber stress
//   S = (1/V) sum_c f_c (x) r_c  [+ (1/V) sum_p m v~ (x) v~ when servo.kinetic_stress],
// compression positive, into the MeasuredStress scratch. It is scheduled only when the servo is.
// Reads positions, the pair list, contact forces, the cell (and velocities and masses for the
// kinetic part); writes the `stress` scratch component. Deterministic reduction with fixed grain.
//
// measure() computes every derived quantity, outside the step, on the steps an output needs them.
#include "engine/system.hpp"

#include <cstddef>
#include <span>

namespace sandcell {

/// The stress measured by the homogenizer on servo steps, for the servo of the same step (scratch
/// component `stress`).
struct MeasuredStress {
  static constexpr Component component = Component::stress;
  Mat3 stress = Mat3::Zero();              // (3,3) Pa, symmetrized, compression positive (docs/physics.md section 5)
  std::uint64_t step = ~std::uint64_t{0};  // clock step at which it was measured (none: max)
};

struct Homogenizer {
  static constexpr std::string_view name = "homogenizer";
  static constexpr ComponentMask reads =
      mask_of({Component::particle_position, Component::particle_velocity, Component::particle_mass,
               Component::contact_pairs, Component::contact_forces, Component::cell});
  static constexpr ComponentMask writes = mask_of({Component::stress});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

/// Whether the homogenizer and the servo act during the step that follows clock step `step`.
inline bool servo_due(const ServoSettings& servo, std::uint64_t step) {
  return servo.enabled && step % static_cast<std::uint64_t>(servo.interval) == 0;
}

/// Stress invariants in the soil convention (compression positive), docs/physics.md section 5.
struct StressInvariants {
  Vec3 principal = Vec3::Zero();  // Pa, s1 >= s2 >= s3
  double p = 0.0;                 // Pa, (s1 + s2 + s3)/3
  double q = 0.0;                 // Pa, sqrt(((s1-s2)^2 + (s2-s3)^2 + (s3-s1)^2)/2)
  double eta = 0.0;               // -, q/p (0 when p <= 0)
  double b = 0.0;                 // -, (s2-s3)/(s1-s3) (0 when s1 = s3)
  double theta = 0.0;             // rad, Lode angle atan(sqrt(3) b/(2-b)): 0 compression, pi/3 extension
};

/// Invariants of a symmetric stress tensor (eigen-decomposition: valid when the tensor is not
/// aligned with the cell axes).
StressInvariants invariants(const Mat3& stress);

/// What measure() reports. Strains are logarithmic from cell.length0, compression positive.
struct Measures {
  Mat3 stress = Mat3::Zero();          // Pa, symmetrized contact (+ kinetic, if asked) stress
  Mat3 contact_stress = Mat3::Zero();  // Pa, contact part only
  StressInvariants inv;
  Vec3 strain = Vec3::Zero();              // -, eps_k = -ln(L_k / L0_k)
  Vec3 strain_engineering = Vec3::Zero();  // -, 1 - L_k / L0_k
  Vec3 strain_rate = Vec3::Zero();         // 1/s, -D_kk
  double eps_v = 0.0;                      // -, eps1 + eps2 + eps3
  double eps_q = 0.0;                      // -, sqrt(2)/3 sqrt((e1-e2)^2 + (e2-e3)^2 + (e3-e1)^2)
  double void_ratio = 0.0;                 // -, V / V_s - 1
  double solid_fraction = 0.0;             // -, V_s / V
  std::size_t contacts = 0;                // touching pairs (overlap > 0)
  std::size_t rattlers = 0;                // particles with fewer than 2 contacts
  double z = 0.0;                          // -, 2 N_c / N_p
  double z_mech = 0.0;                     // -, 2 N_c' / N_p' without rattlers (and their contacts)
  Mat3 fabric = Mat3::Zero();              // -, <n (x) n> over touching contacts
  double unbalanced = 0.0;                 // -, mean |F_net| / mean |f_contact|
  double kinetic_energy = 0.0;             // J, fluctuating translational + rotational
  double elastic_energy = 0.0;             // J, stored in the contacts: normal Hertz 8/15 E* sqrt(R*) delta^(5/2),
                                           // tangential |F_t^el|^2 / (2 k_t), rolling |M|^2 / (2 k_r)
  double max_overlap_ratio = 0.0;          // -, largest delta / min(R_i, R_j) over touching contacts
  double inertial_number = 0.0;            // -, (eps_dot_1 - eps_dot_3) d50 sqrt(rho / p)
  double inertial_number_axial = 0.0;      // -, |eps_dot_1| d50 sqrt(rho / p): axis 1 alone, the form a set
                                           // inertial number (ServoSettings::inertial_number) controls
};

struct MeasureOptions {
  bool kinetic_stress = false;  // add the kinetic part to `stress`
  double d50 = 0.0;             // m, for the inertial number (0: not reported)
  double density = 0.0;         // kg/m^3, for the inertial number
};

/// Every measure of docs/physics.md section 5 on the current state (forces as of the last step). Deterministic.
Measures measure(const Model& model, const State& state, Executor& exec, const MeasureOptions& options = {});

/// Mass-weighted median diameter (50 % passing by mass), m; the same bits for any order of the spheres.
double median_diameter(const Particles& particles);
double median_diameter(std::span<const double> radius);

}  // namespace sandcell
