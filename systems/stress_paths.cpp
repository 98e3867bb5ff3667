#include "systems/stress_paths.hpp"

#include "engine/name_table.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>

namespace sandcell {

namespace {

Vec3 fixed_targets(const ServoSettings& s, double) { return s.target; }
Vec3 isotropic_targets(const ServoSettings& s, double) { return Vec3::Constant(s.p); }
// From p = (s1 + s2 + s3)/3 and b = (s2 - s3)/(s1 - s3), solved for s2 and s3.
Vec3 constant_p_targets(const ServoSettings& s, double s1) {
  const double p = s.p, b = s.b;
  return Vec3(s1, (3.0 * p * (1.0 - b) + (2.0 * b - 1.0) * s1) / (2.0 - b), (3.0 * p - (1.0 + b) * s1) / (2.0 - b));
}
Vec3 constant_sigma3_targets(const ServoSettings& s, double s1) {
  return Vec3(s1, s.b * s1 + (1.0 - s.b) * s.sigma3, s.sigma3);
}

// Simple shear: xx and yy fixed, zz held at normal_stress (drained) or fixed (constant volume); the
// shear components from the shear settings (xz at shear_strain_rate[1]).
PathTargets simple_shear_answer(const ServoSettings& s, const PathInput& in) {
  PathTargets t;
  const bool drained = s.path == StressPath::simple_shear;
  t.control = {AxisControl::strain, AxisControl::strain, drained ? AxisControl::stress : AxisControl::strain};
  t.value = Vec3(0.0, 0.0, drained ? s.normal_stress : 0.0);  // xx and yy fixed (and zz at constant volume)
  t.shear_control = s.shear_control;
  for (int k = 0; k < 3; ++k)
    t.shear_value[k] =
        s.shear_control[k] == AxisControl::strain
            ? driven_rate(s, s.shear_strain_rate[k], in.stress.diagonal().mean(), in.time)
            : s.shear_target[k];
  return t;
}

// Rotation of the principal axes: every component stress controlled toward rotated_stress, q raised
// linearly to servo.q over ramp_time at rotation_start, then alpha = rotation_start + rotation_rate (t - ramp_time).
PathTargets rotation_answer(const ServoSettings& s, const PathInput& in) {
  const Mat3 target = rotation_target(s, in.time);
  PathTargets t;
  t.control = {AxisControl::stress, AxisControl::stress, AxisControl::stress};
  t.shear_control = t.control;
  t.value = target.diagonal();
  t.shear_value = Vec3(target(0, 1), target(0, 2), target(1, 2));
  return t;
}

constexpr StressPathSpec k_paths[] = {
    {StressPath::fixed, "fixed", "per-axis targets as given (servo.target)", PathScale::target, false, false,
     &fixed_targets, nullptr, true},
    {StressPath::isotropic, "isotropic", "all three axes to p", PathScale::p, false, false, &isotropic_targets, nullptr,
     true},
    {StressPath::constant_p, "constant_p",
     "mean stress p and b held: s3* = (3p - (1+b) s1)/(2-b), s2* = (3p(1-b) + (2b-1) s1)/(2-b)", PathScale::p, true,
     true, &constant_p_targets, nullptr, true},
    {StressPath::constant_sigma3, "constant_sigma3", "sigma3 and b held: s3* = sigma3, s2* = b s1 + (1-b) sigma3",
     PathScale::sigma3, true, true, &constant_sigma3_targets, nullptr, true},
    {StressPath::simple_shear, "simple_shear",
     "xz sheared at shear_strain_rate, xx and yy fixed, S_zz held at normal_stress (drained)", PathScale::normal, false,
     false, nullptr, &simple_shear_answer, true},
    {StressPath::simple_shear_cv, "simple_shear_cv",
     "xz sheared at shear_strain_rate, xx, yy and zz fixed (constant "
     "volume)",
     PathScale::none, false, false, nullptr, &simple_shear_answer, true},
    {StressPath::rotation, "rotation",
     "principal axes rotating in xz at rotation_rate, p, b and q held: all six components stress controlled",
     PathScale::p, true, false, nullptr, &rotation_answer, false},
    {StressPath::custom, "custom", "servo.custom decides each axis's control and target at every update",
     PathScale::none, false, false, nullptr, nullptr, false},
};

static_assert(in_id_order(k_paths), "k_paths: one row per StressPath, in enum order");

}  // namespace

std::span<const StressPathSpec> stress_paths() { return k_paths; }

const StressPathSpec& stress_path(StressPath path) { return k_paths[static_cast<std::size_t>(path)]; }

const StressPathSpec* find_stress_path(std::string_view name) { return find_named(stress_paths(), name); }

std::string stress_path_names() { return joined_names(stress_paths()); }

double driven_rate(const ServoSettings& servo, double set, double mean_stress, double time) {
  // |eps_dot| d50 sqrt(rho / p) = I, p floored like the errors' normalization (servo.cpp).
  const double floor = 1e-3 * path_scale(servo);
  const double scale = servo.inertial_number > 0.0
                           ? servo.inertial_number * std::sqrt(std::max(mean_stress, floor) / servo.density) / servo.d50
                           : 1.0;
  const double full = set * scale;
  return servo.ramp_time > 0.0 && time < servo.ramp_time ? full * (time / servo.ramp_time) : full;
}

Mat3 rotation_target(const ServoSettings& s, double time) {
  const double ramp = s.ramp_time > 0.0 ? std::min(1.0, time / s.ramp_time) : 1.0;
  const double turning = std::max(0.0, time - s.ramp_time);
  return rotated_stress(s.p, s.b, s.q * ramp, s.rotation_start + s.rotation_rate * turning);
}

Mat3 rotated_stress(double p, double b, double q, double alpha) {
  const double d = q / std::sqrt(1.0 - b + b * b);
  const double s3 = p - d * (1.0 + b) / 3.0, s1 = s3 + d, s2 = s3 + b * d;
  const double c = std::cos(alpha), s = std::sin(alpha);
  Mat3 t;  // R diag(s1, s2, s3) R^T, R's columns: (c, 0, s), (0, 1, 0), (-s, 0, c)
  t << s1 * c * c + s3 * s * s, 0.0, (s1 - s3) * c * s, 0.0, s2, 0.0, (s1 - s3) * c * s, 0.0, s1 * s * s + s3 * c * c;
  return t;
}

double path_scale(const ServoSettings& servo) {
  switch (stress_path(servo.path).scale) {
    case PathScale::p: return std::abs(servo.p);
    case PathScale::sigma3: return std::abs(servo.sigma3);
    case PathScale::normal: return std::abs(servo.normal_stress);
    case PathScale::target:
    case PathScale::none: break;
  }
  return servo.target.cwiseAbs().maxCoeff();
}

}  // namespace sandcell
