#pragma once
// Periodic servo (docs/physics.md section 6, Huang et al. 2014 style): per-axis strain rates of the cell from the
// stress the homogenizer measured in the same step, by a PI law.
//   stress-controlled axis k: eps_dot_k = clamp(g (err_k + I_k / T_i), -max, +max),
//     err_k = (sigma*_k - sigma_k)/|sigma*_k|, I_k its time integral (Cell::servo_integral, checkpointed,
//     advanced only while the output is inside the cap); T_i = 0 gives the P law g err_k
//   strain-controlled axis k: eps_dot_k = the set rate (ramped from 0 over ramp_time, or following the
//     measured p at a set inertial number)
// (soil convention, compression positive; the cell's D_kk = -eps_dot_k). The targets sigma*_k are
// recomputed every servo step from the measured sigma1 = S_xx by the path's formulas. The servo's
// only memory is the integral, which a checkpoint carries with the cell.
// Reads the `stress` scratch component; writes the cell (rates only). Acts on servo steps only.
#include "engine/system.hpp"

namespace sandcell {

struct Servo {
  static constexpr std::string_view name = "servo";
  static constexpr ComponentMask reads = mask_of({Component::stress});
  static constexpr ComponentMask writes = mask_of({Component::cell});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

/// Target principal stresses (sigma1*, sigma2*, sigma3*), Pa, compression positive, of the path
/// given the measured sigma1. sigma1* is meaningful only for the isotropic and fixed paths (axis 1
/// is strain controlled on the others; there it is returned as s1 itself).
Vec3 path_targets(const ServoSettings& servo, double sigma1);

/// Cell strain rates (compression positive, 1/s) the servo sets for a measured stress diagonal:
/// eps_dot_k = clamp(g (err_k + I_k / T_i), +-max_rate), err_k = (sigma*_k - sigma_k)/|sigma*_k|.
/// With `integral` (the cell's servo_integral) and servo.integral_time > 0, I_k advances by
/// err_k * interval (s) first, unless the output sits at the cap (anti-windup); otherwise a P law.
/// Strain-controlled axes get servo.strain_rate (times I sqrt(p/rho) / d50 with p the mean of
/// `sigma` when servo.inertial_number = I > 0), times time / servo.ramp_time while time (s, the
/// clock's) is below a nonzero ramp_time.
Vec3 servo_strain_rates(const ServoSettings& servo, const Vec3& sigma, Vec3* integral = nullptr, double interval = 0.0,
                        double time = 0.0);

}  // namespace sandcell
