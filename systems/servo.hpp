#pragma once
// Periodic servo (docs/physics.md section 6, Huang et al. 2014 style): per-axis strain rates of the cell from the
// stress the homogenizer measured in the same step, by a PI law.
//   stress-controlled axis k: eps_dot_k = clamp(g (err_k + I_k / T_i), -cap, +cap),
//     cap = max_rate, or max(max_rate, max_rate_ratio x |fastest strain-controlled rate|)
//     err_k = (sigma*_k - sigma_k)/|sigma*_k|, I_k its time integral (Cell::servo_integral, checkpointed,
//     advanced only while the output is inside the cap); T_i = 0 gives the P law g err_k
//   strain-controlled axis k: eps_dot_k = the set rate (ramped from 0 over ramp_time, or following the
//     measured p at a set inertial number)
// (soil convention, compression positive; the cell's D_kk = -eps_dot_k). The targets sigma*_k are
// recomputed every servo step from the measured sigma1 = S_xx by the path's formulas. The servo's
// only memory is the integral, which a checkpoint carries with the cell.
// A custom path (StressPath::custom: ServoSettings::custom, e.g. undrained_path, CyclicPath or a
// Python callable) is called on servo steps only, and decides each axis's control and target.
// Reads the `stress` scratch component; writes the cell (rates only). Acts on servo steps only.
#include "engine/system.hpp"

#include <cstdint>
#include <memory>
#include <vector>

namespace sandcell {

struct Servo {
  static constexpr std::string_view name = "servo";
  static constexpr ComponentMask reads = mask_of({Component::stress});
  static constexpr ComponentMask writes = mask_of({Component::cell});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
  /// The servo's settings, checked when a World is built (validate below).
  static void check(const Model& model);
};

/// Checks the servo settings (docs/physics.md section 6; the path's own checks from its row in
/// systems/stress_paths.cpp); throws std::invalid_argument naming the key, the value and what is allowed.
void validate(const ServoSettings& servo);

/// Target principal stresses (sigma1*, sigma2*, sigma3*), Pa, compression positive, of the path
/// given the measured sigma1. sigma1* is meaningful only for the isotropic and fixed paths (axis 1
/// is strain controlled on the others; there it is returned as s1 itself).
Vec3 path_targets(const ServoSettings& servo, double sigma1);

/// Cell strain rates (compression positive, 1/s) the servo sets for a measured stress diagonal:
/// eps_dot_k = clamp(g (err_k + I_k / T_i), +-cap), err_k = (sigma*_k - sigma_k)/|sigma*_k|, cap = max_rate,
/// or with max_rate_ratio > 0 max(max_rate, max_rate_ratio x the fastest strain-controlled axis's rate).
/// With `integral` (the cell's servo_integral) and servo.integral_time > 0, I_k advances by
/// err_k * interval (s) first, unless the output sits at the cap (anti-windup); otherwise a P law.
/// Strain-controlled axes get servo.strain_rate (times I sqrt(p/rho) / d50 with p the mean of
/// `sigma` when servo.inertial_number = I > 0), times time / servo.ramp_time while time (s, the
/// clock's) is below a nonzero ramp_time.
Vec3 servo_strain_rates(const ServoSettings& servo, const Vec3& sigma, Vec3* integral = nullptr, double interval = 0.0,
                        double time = 0.0);

/// The servo's rates of the six components, soil convention: axial eps_dot_k = -L_kk and the
/// engineering shear rates gamma_dot = -(L_xy, L_xz, L_yz) (docs/physics.md section 6.2).
struct CellRates {
  Vec3 axial = Vec3::Zero();
  Vec3 shear = Vec3::Zero();
};

/// servo_strain_rates for the whole measured stress tensor: the axes as there; the shear components
/// by servo.shear_control: strain at shear_strain_rate (scaled and ramped as the axes), stress by
/// the same PI law toward shear_target with the error (S*_ab - S_ab) / max(path scale, |p|) and its
/// integral in `shear_integral`. The cap and the integral time count strain-controlled shear rates
/// among the strain-controlled axes.
CellRates servo_rates(const ServoSettings& servo, const Mat3& stress, Vec3* integral = nullptr, double interval = 0.0,
                      double time = 0.0, Vec3* shear_integral = nullptr);

/// Cell strain rates (compression positive, 1/s) of a custom path's answer (StressPath::custom,
/// docs/physics.md section 6.1): strain axes at their value; stress axes by the same PI law as the
/// built-in paths, the error normalized by max(|sigma*_k|, 1e-3 max(|p|, |sigma*|)); the `volume`
/// axes at the common rate that makes the volume the product of input.length0 after
/// input.interval steps of L <- L (1 + D dt). Throws std::invalid_argument when the answer has a
/// non-finite value on a strain or stress axis, or cannot hold the volume (the other axes' rates
/// over one update would shrink a length to zero).
/// The shear components of the answer (PathTargets::shear_control) go to `shear_out` (engineering
/// rates, -L_ab): strain at their value, stress by the PI law (integral in `shear_integral`) with
/// the error normalized by the answer's stress scale, max(|p|, |stress targets|).
Vec3 custom_strain_rates(const ServoSettings& servo, const PathTargets& targets, const PathInput& input,
                         Vec3* integral = nullptr, Vec3* shear_out = nullptr, Vec3* shear_integral = nullptr);

/// The input a custom path gets from a measured stress and the cell (what Servo::run passes).
PathInput path_input(const Model& model, const Mat3& stress, const Cell& cell, const Clock& clock);

// ---- ready-made custom paths (docs/physics.md section 6.1) -------------------------------------

/// Undrained (constant-volume) triaxial compression: axis 1 strain controlled at axial_rate
/// (1/s, compression positive), axes 2 and 3 at the common rate that keeps eps_v = 0. The excess
/// pore pressure of the equivalent saturated sample is u = p0 - p' (p' the measured mean stress).
/// Throws std::invalid_argument unless axial_rate is finite.
PathFunction undrained_path(double axial_rate);

/// A cyclic test (docs/physics.md section 6.1).
struct CyclicSettings {
  AxisControl axial = AxisControl::strain;  // strain: eps1 between the bounds at +-rate;
                                            // stress: q = s1 - (s2 + s3)/2 between the bounds (Pa),
                                            // axis 1 stress controlled toward s1* = (s2 + s3)/2 + bound
  double lower = 0.0;                       // lower bound: eps1 (-) or q (Pa); lower < upper
  double upper = 0.0;                       // upper bound; the first half cycle goes from the start toward it
  double rate = 0.0;                        // 1/s, |eps_dot_1| (strain mode), > 0
  double tolerance = 0.02;  // stress mode: reverse when q is within tolerance (upper - lower) of the bound
  bool undrained = false;   // lateral axes: constant volume (true) or stress controlled at sigma3
  double sigma3 = 0.0;      // Pa, lateral stress of the drained form, > 0
  int cycles = 0;           // finished after this many full cycles (two reversals each); 0: no limit
  double max_strain = 0.0;  // finished when |eps1| reaches it; 0: no limit
};

/// Throws std::invalid_argument naming the key (cyclic.<key>), its value and what is allowed.
void validate(const CyclicSettings& settings);

/// The cyclic path: a callable with memory (the direction, the reversals), shared by its copies.
/// Its memory is not in the State: save() and restore() carry it (the triaxial app puts it in its
/// checkpoints' extras, so a resumed cyclic test goes on where it stopped).
class CyclicPath {
 public:
  explicit CyclicPath(const CyclicSettings& settings);
  PathTargets operator()(const PathInput& input) const;
  const CyclicSettings& settings() const { return settings_; }
  int reversals() const { return memory_->reversals; }
  int cycles() const { return memory_->reversals / 2; }  // completed full cycles
  bool loading() const { return memory_->up; }           // toward the upper bound
  bool finished() const { return memory_->finished; }    // cycle count or max_strain reached
  /// The strain (eps1) and step of each reversal.
  const std::vector<double>& reversal_strains() const { return memory_->reversal_strain; }
  const std::vector<std::uint64_t>& reversal_steps() const { return memory_->reversal_step; }
  /// The memory as numbers (up, reversals, finished, then each reversal's strain and step), and back.
  std::vector<double> save() const;
  void restore(const std::vector<double>& saved) const;  // the memory is shared: const as operator()

 private:
  struct Memory {
    bool up = true;
    int reversals = 0;
    bool finished = false;
    std::vector<double> reversal_strain;
    std::vector<std::uint64_t> reversal_step;
  };
  CyclicSettings settings_;
  std::shared_ptr<Memory> memory_;
};

}  // namespace sandcell
