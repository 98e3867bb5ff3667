#include "systems/stress_paths.hpp"

#include "engine/name_table.hpp"

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

constexpr StressPathSpec k_paths[] = {
    {StressPath::fixed, "fixed", "per-axis targets as given (servo.target)", PathScale::target, false, false,
     &fixed_targets},
    {StressPath::isotropic, "isotropic", "all three axes to p", PathScale::p, false, false, &isotropic_targets},
    {StressPath::constant_p, "constant_p",
     "mean stress p and b held: s3* = (3p - (1+b) s1)/(2-b), s2* = (3p(1-b) + (2b-1) s1)/(2-b)", PathScale::p, true,
     true, &constant_p_targets},
    {StressPath::constant_sigma3, "constant_sigma3", "sigma3 and b held: s3* = sigma3, s2* = b s1 + (1-b) sigma3",
     PathScale::sigma3, true, true, &constant_sigma3_targets},
    {StressPath::custom, "custom", "servo.custom decides each axis's control and target at every update",
     PathScale::none, false, false, nullptr},
};

static_assert(in_id_order(k_paths), "k_paths: one row per StressPath, in enum order");

}  // namespace

std::span<const StressPathSpec> stress_paths() { return k_paths; }

const StressPathSpec& stress_path(StressPath path) { return k_paths[static_cast<std::size_t>(path)]; }

const StressPathSpec* find_stress_path(std::string_view name) { return find_named(stress_paths(), name); }

std::string stress_path_names() { return joined_names(stress_paths()); }

double path_scale(const ServoSettings& servo) {
  switch (stress_path(servo.path).scale) {
    case PathScale::p: return std::abs(servo.p);
    case PathScale::sigma3: return std::abs(servo.sigma3);
    case PathScale::target:
    case PathScale::none: break;
  }
  return servo.target.cwiseAbs().maxCoeff();
}

}  // namespace sandcell
