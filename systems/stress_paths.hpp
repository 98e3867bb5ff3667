#pragma once
// The servo's built-in stress paths, one row each (docs/physics.md section 6): the one name a path
// has everywhere (the servo, the triaxial app's tests.path and results files, the analysis, Python),
// the setting that scales its errors, whether it has a b, and its targets. A new built-in path is
// an enum value in engine/model.hpp plus a row in stress_paths.cpp; the servo, its validation, the
// path watchdog and the Python names read the row.
#include "engine/model.hpp"

#include <span>
#include <string>
#include <string_view>

namespace sandcell {

/// The setting a path's stress targets are relative to, which must be > 0 on a stress-controlled path.
enum class PathScale {
  target,  // the per-axis targets (`fixed`)
  p,       // servo.p
  sigma3,  // servo.sigma3
  normal,  // servo.normal_stress (simple shear)
  none,    // the custom path's function decides
};

struct StressPathSpec {
  StressPath id;
  std::string_view name;         // e.g. "constant_p"
  std::string_view description;  // the formulas, one line
  PathScale scale;
  bool has_b;             // targets follow b = (s2 - s3)/(s1 - s3), the watchdog checks b
  bool axis1_by_strain;   // axis 1 must be strain controlled (its target is the measured s1)
  /// Target principal stresses (s1*, s2*, s3*), Pa, compression positive, from the measured s1;
  /// null for `custom`.
  Vec3 (*targets)(const ServoSettings& servo, double s1);
  /// The paths that decide all six components (simple shear, rotation): their answer at a servo
  /// update, handled as a custom path's (custom_strain_rates); null for the others.
  PathTargets (*answer)(const ServoSettings& servo, const PathInput& input);
  bool shear_settings;  // the shear components follow servo.shear_control (all but rotation and custom)
};

/// The stress tensor (Pa, compression positive) with principal values from p, b and q and the
/// major principal direction at angle alpha (rad) from x toward z, the intermediate along y:
/// s3 = p - d (1 + b)/3, s1 = s3 + d, s2 = s3 + b d, d = q / sqrt(1 - b + b^2).
Mat3 rotated_stress(double p, double b, double q, double alpha);

/// A strain-controlled rate `set` (1/s) at a servo update: at a set inertial number times
/// I sqrt(p/rho) / d50, p the measured mean stress floored at 1e-3 of the path's scale; during the
/// ramp (clock time below ramp_time) times time / ramp_time.
double driven_rate(const ServoSettings& servo, double set, double mean_stress, double time);

/// The rotation path's target at clock time t (s): q rising linearly to servo.q over servo.ramp_time
/// at alpha = rotation_start, then alpha = rotation_start + rotation_rate (t - ramp_time).
Mat3 rotation_target(const ServoSettings& servo, double time);

/// Every built-in path, in enum order.
std::span<const StressPathSpec> stress_paths();
/// The row of a path.
const StressPathSpec& stress_path(StressPath path);
/// The row of a path name, or nullptr.
const StressPathSpec* find_stress_path(std::string_view name);
/// The names, comma separated (for messages).
std::string stress_path_names();
/// The value of the setting that scales the path's errors (|p|, |sigma3|, or the largest |target|).
double path_scale(const ServoSettings& servo);

}  // namespace sandcell
