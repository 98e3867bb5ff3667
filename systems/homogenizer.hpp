#pragma once
// Stress homogenizer (docs/physics.md section 5): the cell's stress from the contact forces, and the state measures
// a geomechanics user reads off a test.
//
// The system (`Homogenizer`) measures only what the servo needs, only on servo steps
// (clock.step % servo.interval == 0): the symmetrized Love-Weber stress
//   S = (1/V) sum_c f_c (x) r_c  [+ (1/V) sum_p m v~ (x) v~ when servo.kinetic_stress],
// compression positive, into the MeasuredStress scratch. It is scheduled only when the servo is.
// The contact part comes from the contact pass of the same step, which sums f (x) r per block of
// 64 pairs with the branch vectors and forces in hand (StressBlocks, systems/contact_pass.hpp); the
// homogenizer adds the blocks in order (a deterministic reduction with fixed grain). Reads those
// sums and the cell (and velocities and masses for the kinetic part); writes the `stress` scratch
// component. measure() sums the pairs itself (contact_stress_sum): the same stress to round-off.
//
// measure() computes every derived quantity, outside the step, on the steps an output needs them;
// its tensor measures (strain tensor, principal directions, alpha, non-coaxiality) are the pure
// functions of systems/kinematics.hpp. An orthorhombic cell's measures keep the arithmetic they had
// before the cell could shear (bitwise); a sheared cell's eps_q and inertial number come from the
// tensors.
#include "engine/system.hpp"
#include "systems/kinematics.hpp"

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
  static constexpr ComponentMask reads = mask_of(
      {Component::particle_velocity, Component::particle_mass, Component::stress_blocks, Component::cell});
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

/// What measure() reports. Strains are logarithmic from the cell's reference (length0, tilt0),
/// compression positive. `strain` is that of the cell's edge lengths L_k (the diagonal of H); for a
/// sheared cell the strain is the tensor `strain_tensor`, whose diagonal differs from it.
struct Measures {
  Mat3 stress = Mat3::Zero();          // Pa, symmetrized contact (+ kinetic, if asked) stress
  Mat3 contact_stress = Mat3::Zero();  // Pa, contact part only
  StressInvariants inv;
  Vec3 strain = Vec3::Zero();              // -, eps_k = -ln(L_k / L0_k)
  Vec3 strain_engineering = Vec3::Zero();  // -, 1 - L_k / L0_k
  Vec3 strain_rate = Vec3::Zero();         // 1/s, -D_kk (= -L_kk: the diagonal of strain_rate_tensor)
  double eps_v = 0.0;  // -, eps1 + eps2 + eps3 (= -ln det F = trace of strain_tensor, tilted or not)
  double eps_q = 0.0;  // -, sqrt(2)/3 sqrt((e1-e2)^2 + (e2-e3)^2 + (e3-e1)^2): e_k = strain, or
                       // the principal_strain when the deformation is not diagonal (sheared)
  // Tensor measures (systems/kinematics.hpp). For a cell that never sheared (diagonal F) the strain
  // tensor is diag(strain) bitwise.
  Mat3 deformation = Mat3::Identity();        // -, F = H N H0^-1 since the reference (Cell::deformation);
                                              // diag(L_k / L0_k) exactly when diagonal
  Mat3 strain_tensor = Mat3::Zero();          // -, -ln V, V = sqrt(F F^T) (log_strain)
  Mat3 strain_rate_tensor = Mat3::Zero();     // 1/s, -(L + L^T)/2 of the cell's velocity gradient L
  Vec3 gamma = Vec3::Zero();                  // -, engineering shear strains (xy, xz, yz) = -(F_xy, F_xz, F_yz):
                                              // in simple shear (fixed lengths) the time integral of the servo's
                                              // shear_strain_rate; F continues through flips
  Mat3 stress_directions = Mat3::Identity();  // -, columns: the unit directions of inv.principal (principal())
  Vec3 principal_strain = Vec3::Zero();       // -, principal values of strain_tensor, descending
  Mat3 strain_directions = Mat3::Identity();  // -, columns: their unit directions
  double alpha = 0.0;              // deg, in (-90, 90]: sigma1's direction in the xz plane from x toward z (alpha_deg)
  double noncoaxiality = 0.0;      // deg, in [0, 90]: between the major principal directions of stress and
                                   // strain_rate_tensor (0 while the cell does not deform)
  double void_ratio = 0.0;         // -, V / V_s - 1
  double solid_fraction = 0.0;     // -, V_s / V
  std::size_t contacts = 0;        // touching pairs (overlap > 0)
  std::size_t rattlers = 0;        // particles with fewer than 2 contacts
  double z = 0.0;                  // -, 2 N_c / N_p
  double z_mech = 0.0;             // -, 2 N_c' / N_p' without rattlers (and their contacts)
  Mat3 fabric = Mat3::Zero();      // -, <n (x) n> over touching contacts
  double unbalanced = 0.0;         // -, mean |F_net| / mean |f_contact|
  double kinetic_energy = 0.0;     // J, fluctuating translational + rotational
  double elastic_energy = 0.0;     // J, stored in the contacts: normal Hertz 8/15 E* sqrt(R*) delta^(5/2),
                                   // tangential |F_t^el|^2 / (2 k_t), rolling |M|^2 / (2 k_r)
  double max_overlap_ratio = 0.0;  // -, largest delta / min(R_i, R_j) over touching contacts
  double inertial_number = 0.0;    // -, (eps_dot_1 - eps_dot_3) d50 sqrt(rho / p), principal rates (of
                                   // strain_rate_tensor when the cell shears)
  double inertial_number_axial = 0.0;  // -, |eps_dot_1| d50 sqrt(rho / p): axis 1 alone, the form a set
                                       // inertial number (ServoSettings::inertial_number) controls
  double dt = 0.0;                     // s, the time step in effect (Model::dt; adaptive: Model::time_step)
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
