#include "systems/servo.hpp"

#include "systems/homogenizer.hpp"

#include <algorithm>
#include <cmath>

namespace sandcell {

Vec3 path_targets(const ServoSettings& servo, double s1) {
  switch (servo.path) {
    case StressPath::fixed: return servo.target;
    case StressPath::isotropic: return Vec3::Constant(servo.p);
    case StressPath::constant_p_b: {
      // From p = (s1 + s2 + s3)/3 and b = (s2 - s3)/(s1 - s3), solved for s2 and s3.
      const double p = servo.p, b = servo.b;
      return Vec3(s1, (3.0 * p * (1.0 - b) + (2.0 * b - 1.0) * s1) / (2.0 - b), (3.0 * p - (1.0 + b) * s1) / (2.0 - b));
    }
    case StressPath::constant_sigma3_b: {
      const double s3 = servo.sigma3, b = servo.b;
      return Vec3(s1, b * s1 + (1.0 - b) * s3, s3);
    }
  }
  return servo.target;
}

namespace {
// The path's own stress scale: errors are normalized by |sigma*_k| (docs/physics.md section 6), floored at a
// thousandth of this scale so a target passing through zero (constant p at eta near 3) cannot
// divide by zero.
double stress_scale(const ServoSettings& servo) {
  switch (servo.path) {
    case StressPath::isotropic:
    case StressPath::constant_p_b: return std::abs(servo.p);
    case StressPath::constant_sigma3_b: return std::abs(servo.sigma3);
    case StressPath::fixed: break;
  }
  return servo.target.cwiseAbs().maxCoeff();
}
}  // namespace

Vec3 servo_strain_rates(const ServoSettings& servo, const Vec3& sigma, Vec3* integral, double interval, double time) {
  const Vec3 target = path_targets(servo, sigma[0]);
  const double floor = 1e-3 * stress_scale(servo);
  // At a set inertial number the strain-controlled rates follow the measured mean stress:
  // |eps_dot| d50 sqrt(rho / p) = I, p floored like the errors' normalization.
  const double scale =
      servo.inertial_number > 0.0
          ? servo.inertial_number * std::sqrt(std::max(sigma.mean(), floor) / servo.density) / servo.d50
          : 1.0;
  Vec3 rate;
  for (int k = 0; k < 3; ++k) {
    if (servo.control[k] == AxisControl::strain) {
      const double full = servo.strain_rate[k] * scale;
      rate[k] = servo.ramp_time > 0.0 && time < servo.ramp_time ? full * (time / servo.ramp_time) : full;
      continue;
    }
    const double error = (target[k] - sigma[k]) / std::max(std::abs(target[k]), floor);
    if (integral == nullptr || !(servo.integral_time > 0.0)) {
      rate[k] = std::clamp(servo.gain * error, -servo.max_rate, servo.max_rate);
      continue;
    }
    // PI: the integral removes the lag a P law keeps while the target moves (error ~ rate / g).
    // Anti-windup: the integral advances only while the output is inside the cap, or when the
    // error would bring it back inside.
    double& i = (*integral)[k];
    const double trial_i = i + error * interval;
    const double trial = servo.gain * (error + trial_i / servo.integral_time);
    if (std::abs(trial) <= servo.max_rate || trial * error < 0.0) i = trial_i;
    rate[k] = std::clamp(servo.gain * (error + i / servo.integral_time), -servo.max_rate, servo.max_rate);
  }
  return rate;
}

void Servo::run(const Model& model, State& state, Scratch& scratch, Executor&) {
  if (!servo_due(model.servo, state.clock.step)) return;
  const MeasuredStress& measured = scratch.read<MeasuredStress>();
  Cell& cell = state.write<Component::cell>();
  const Vec3 rate = servo_strain_rates(model.servo, measured.stress.diagonal(), &cell.servo_integral,
                                       model.dt * model.servo.interval, state.clock.time);
  cell.rate = -rate;  // D_kk is tension positive
}

}  // namespace sandcell
