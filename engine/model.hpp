#pragma once
// The Model: everything constant during a run. Validated once, when the scene is built.
#include "components/material.hpp"
#include "components/types.hpp"

#include <array>
#include <functional>
#include <map>
#include <string>

#include <cstdint>
#include <vector>

namespace sandcell {

/// Tangential force history (docs/physics.md section 2).
enum class TangentialModel {
  history,      // LIGGGHTS `tangential history`: spring displacement u_t, F_t = -k_t u_t (default)
  incremental,  // stored force, rotated with the contact frame, plus k_t times the increment
  mindlin_rescale,  // history, the displacement scaled down with the contact radius on unloading (LAMMPS)
};

/// Rolling resistance (docs/physics.md section 3).
enum class RollingModel {
  none,   // no rolling system scheduled, no rolling history allocated
  epsd2,  // LIGGGHTS `rolling_friction epsd2` (default)
  epsd,   // Ai et al. type C: spring + dashpot below the cap
  cdt,    // Ai et al. type A: constant directional torque
};

struct ContactSettings {
  bool enabled = true;           // false: free flight (no broadphase, no forces)
  std::string normal = "hertz";  // the normal law, by its registered name (docs/physics.md section 2):
                                 // hertz, hooke
  // Named parameters of the chosen laws, SI units (e.g. hooke: characteristic_velocity, m/s).
  std::map<std::string, double> parameters;
  TangentialModel tangential = TangentialModel::history;
  RollingModel rolling = RollingModel::epsd2;
  double rolling_damping = 0.0;  // -, eta_r of the epsd dashpot (docs/physics.md section 3), >= 0
  double skin = 0.3e-3;          // m, Verlet skin of the neighbour list, > 0
  bool liggghts_compat = false;  // drop the affine term D r from relative velocities (docs/physics.md section 1)
  // Steps between spatial sorts of the particle arrays (Morton order of position; 0: never).
  // Sorting keeps neighbours close in memory; it changes array indices, never ids.
  int sort_interval = 0;
};

/// Effective contact constants of a pair of materials (mixing rule: docs/physics.md section 2 for E*, G*;
/// arithmetic mean of restitution, friction and rolling friction when the two materials differ).
struct PairMaterial {
  double e_star = 0.0;            // Pa, 1/E* = (1-nu_i^2)/E_i + (1-nu_j^2)/E_j
  double g_star = 0.0;            // Pa, 1/G* = (2-nu_i)/G_i + (2-nu_j)/G_j
  double beta = 0.0;              // -, ln(e)/sqrt(ln(e)^2 + pi^2), <= 0
  double friction = 0.0;          // -, mu
  double rolling_friction = 0.0;  // -, mu_r
  double damping_ratio_t = 0.0;   // -, gamma_t / gamma_n = sqrt(S_t / S_n) = sqrt(4 G* / E*)
};

/// How a cell axis is driven (docs/physics.md section 6).
enum class AxisControl {
  strain,  // at the set strain rate
  stress,  // by the servo, toward the path's target stress
  volume,  // custom paths only (PathTargets): the common rate of such axes that keeps the volume constant
};

/// The stress path whose targets the servo recomputes from the measured sigma1 (docs/physics.md
/// section 6). Each path's name, formulas and checks are its row in systems/stress_paths.cpp.
enum class StressPath {
  fixed,            // per-axis targets as given (`target`)
  isotropic,        // all three axes to p
  constant_p,       // p and b held
  constant_sigma3,  // sigma3 and b held
  simple_shear,     // xz strain at shear_strain_rate[1], xx and yy fixed, zz at normal_stress (drained)
  simple_shear_cv,  // the same at constant volume: zz fixed too
  rotation,         // principal stress axes rotating in the xz plane at rotation_rate, p, b and q held
  custom,           // ServoSettings::custom decides each axis's control and target at every servo update
};

/// What a custom path sees at each servo update (docs/physics.md section 6.1): the stress the
/// homogenizer measured in this step and the cell after this step's drift. Compression positive.
struct PathInput {
  std::uint64_t step = 0;           // clock step at which the stress was measured
  double time = 0.0;                // s, clock time at that step
  double dt = 0.0;                  // s, time step
  int interval = 1;                 // steps until the next servo update (the returned rates hold that long)
  Mat3 stress = Mat3::Zero();       // Pa, measured (symmetrized, compression positive)
  Vec3 length = Vec3::Ones();       // m, cell lengths now
  Vec3 length0 = Vec3::Ones();      // m, reference lengths (strains and eps_v count from them)
  Vec3 strain = Vec3::Zero();       // -, logarithmic, -ln(L/L0)
  Vec3 strain_rate = Vec3::Zero();  // 1/s, the rates applied until now (-D_kk)
  Mat3 deformation = Mat3::Identity();    // -, F = H N H0^-1 since the reference (components/cell.hpp)
  Vec3 shear_strain_rate = Vec3::Zero();  // 1/s, (xy, xz, yz): -L_ab, the shear rates applied until now
};

/// What a custom path returns, per axis: `strain`, at `value` 1/s (compression positive); `stress`,
/// toward `value` Pa by the PI servo (gain, integral_time, max_rate, as the other paths); `volume`
/// (value unused), one common rate of the `volume` axes that brings the cell's volume to the
/// product of length0 by the next servo update, given the other axes' rates: constant volume,
/// eps_v = 0, exactly up to rounding (docs/physics.md section 6.1).
/// The shear components xy, xz, yz (shear_control, shear_value): `strain` at shear_value 1/s, the
/// engineering rate gamma_dot_ab = -L_ab of the upper triangular velocity gradient (soil convention);
/// `stress` toward shear_value Pa (S_ab, compression positive), the error normalized by the path's
/// stress scale. The default, strain at 0, keeps the cell orthorhombic. `volume` is not allowed.
struct PathTargets {
  std::array<AxisControl, 3> control{AxisControl::strain, AxisControl::strain, AxisControl::strain};
  Vec3 value = Vec3::Zero();
  std::array<AxisControl, 3> shear_control{AxisControl::strain, AxisControl::strain, AxisControl::strain};
  Vec3 shear_value = Vec3::Zero();
};

/// A user-defined path (StressPath::custom). Called by the servo on servo updates only, from the
/// thread that runs the servo system; it may keep its own state (a cyclic path's direction), which
/// checkpoints do not hold. An exception it throws stops World::step with that exception.
using PathFunction = std::function<PathTargets(const PathInput&)>;

/// The periodic servo (docs/physics.md section 6). Soil convention: stresses and strain rates compression positive.
/// Axis k of the cell is principal direction k: sigma1 = S_xx, sigma2 = S_yy, sigma3 = S_zz.
struct ServoSettings {
  bool enabled = false;  // false: no homogenizer or servo scheduled; the cell keeps its rate
  StressPath path = StressPath::fixed;
  std::array<AxisControl, 3> control{AxisControl::strain, AxisControl::strain, AxisControl::strain};
  Vec3 strain_rate = Vec3::Zero();  // 1/s, compression positive, for strain-controlled axes
  double ramp_time = 0.0;           // s, strain-controlled rates rise linearly from 0 at clock time 0
                                    // to strain_rate at ramp_time (0: the full rate from the start)
  double inertial_number = 0.0;     // -, > 0: strain-controlled rates are strain_rate[k] I sqrt(p/rho) / d50
                                    // at each servo update, p the measured mean stress (strain_rate then
                                    // gives only sign and proportions); 0: strain_rate as given
  double d50 = 0.0;                 // m, median diameter, for inertial_number
  double density = 0.0;             // kg/m^3, solid density, for inertial_number
  Vec3 target = Vec3::Zero();       // Pa, per-axis targets of the `fixed` path
  double p = 0.0;                   // Pa, mean stress of the isotropic and constant-p paths
  double b = 0.0;                   // -, intermediate principal stress ratio, in [0, 1]
  double sigma3 = 0.0;              // Pa, minor stress of the constant-sigma3 path
  double gain = 0.0;                // 1/s, g in eps_dot = g (err + I / T_i), err = (sigma* - sigma)/|sigma*|
  double integral_time = 0.0;       // s, T_i of the integral term (I = time integral of err); 0: none (P law)
  double integral_strain = 0.0;     // -, > 0: T_i is at most integral_strain / (the fastest strain-controlled
                                    // axis's rate at this update), so the integral keeps pace with a fast test;
                                    // 0: integral_time alone
  double max_rate = 0.0;            // 1/s, cap on |eps_dot| of a stress-controlled axis
  double max_rate_ratio = 0.0;      // -, > 0: the cap is max(max_rate, ratio x the largest |eps_dot| of the
                                    // strain-controlled axes at this update), so it follows an axial rate
                                    // that grows with p at a set inertial number; 0: max_rate alone
  int interval = 1;                 // steps between stress measurements and servo updates
  bool kinetic_stress = false;      // include the kinetic part sum m v~ (x) v~ / V in the measured stress
  PathFunction custom;              // the path of StressPath::custom (control, strain_rate, target unused)
  // The shear components xy, xz, yz of the cell (docs/physics.md section 6.2): strain controlled at
  // shear_strain_rate (engineering, -L_ab, 1/s; scaled like the axes at a set inertial number) or
  // stress controlled toward shear_target (Pa, S_ab compression positive; `free` = stress toward 0).
  // The default (strain at 0) is the orthorhombic cell. Used by every built-in path but `rotation`.
  std::array<AxisControl, 3> shear_control{AxisControl::strain, AxisControl::strain, AxisControl::strain};
  Vec3 shear_strain_rate = Vec3::Zero();
  Vec3 shear_target = Vec3::Zero();
  double normal_stress = 0.0;   // Pa, S_zz of the simple_shear path, > 0
  double q = 0.0;               // Pa, deviator q of the rotation path, >= 0
  double rotation_rate = 0.0;   // rad/s, d alpha/dt of the rotation path (alpha: sigma1's angle from x toward z)
  double rotation_start = 0.0;  // rad, alpha at clock time 0
  // s, > 0: the gain holds for steps up to gain_time; at a longer step (an adaptive time step,
  // Model::time_step) it is gain x gain_time / dt, so the loop gain per step, g dt, never exceeds
  // g gain_time (docs/physics.md section 6); 0: the gain as given at any step.
  double gain_time = 0.0;
};

/// How the time step is chosen (docs/physics.md section 4.1).
enum class TimeStepRule {
  fixed,      // Model::dt throughout
  stiffness,  // every `interval` steps, from the contacts' tangent stiffnesses (the systems' stable_step hooks)
};

/// The adaptive step (TimeStepRule::stiffness): before every step whose clock step is a multiple of
/// `interval`, dt = min(max_dt, safety x min over the systems' stable_step), each system's bound being
/// min over particles of sqrt(m / K) and sqrt(I / K_rot) from the summed tangent stiffnesses of the
/// particle's contacts (docs/physics.md section 4.1). The rule reads only the state, so results stay
/// bitwise for any thread count and chunking of World::step calls. The step in effect is Model::dt
/// (World updates it) and Clock::dt (so a checkpoint holds it).
struct TimeStepSettings {
  TimeStepRule rule = TimeStepRule::fixed;
  double safety = 0.0;  // -, stiffness: in (0, sqrt 2] (sqrt 2: the stability limit of an undamped linear network)
  int interval = 0;     // steps between updates, >= 1
  double max_dt = 0.0;  // s, upper bound of the step (and the step while no contact touches), > 0
};

struct Model {
  double dt = 0.0;                  // s, time step (with an adaptive rule: the step in effect, World updates it)
  TimeStepSettings time_step;       // fixed, or the adaptive rule
  std::vector<Material> materials;  // indexed by particles.material
  ContactSettings contact;
  ServoSettings servo;

  /// (n_materials^2) pair constants, row-major [mi * n + mj]; filled by finalize().
  std::vector<PairMaterial> pairs;

  const PairMaterial& pair(std::uint32_t mi, std::uint32_t mj) const { return pairs[mi * materials.size() + mj]; }
  /// Computes the derived tables (pairs). Called by World; idempotent.
  void finalize();
};

/// Rayleigh time of the smallest sphere: pi R_min sqrt(rho/G) / (0.1631 nu + 0.8766), s
/// (minimum over materials present is the caller's business: pass that material's constants).
double rayleigh_time(double r_min, const Material& material);

}  // namespace sandcell
