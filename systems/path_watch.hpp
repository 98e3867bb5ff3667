#pragma once
// The stress-path watchdog (docs/physics.md section 6.2): judges, row by row, whether a test still
// follows the path its servo settings describe, and names the first quantity that left it.
//
// The cell's axes are the intended principal axes (sigma1 on x, sigma2 on y, sigma3 on z). Each
// quantity is taken from the mean stress tensor over a trailing window of axial strain (the sum of
// |d eps_1|, counted from `start`, the end of the ramp), since single rows of a small sample
// fluctuate by several per cent:
//   p          constant p:       |p - p*| / p*
//   sigma3     constant sigma3:  |S_zz - sigma3*| / sigma3*
//   axis k     isotropic, fixed: |S_kk - sigma*_k| / the path's stress scale, stress-controlled axes
//   b          both b paths:     |(S_yy - S_zz) / (S_xx - S_zz) - b*|, where S_xx - S_zz >= 0.1 p
//   rotation   the principal axes' turn off the cell axes, 1/2 asin(2 |tau| / (s1 - s3)) in degrees,
//              |tau| = sqrt(S_xy^2 + S_xz^2 + S_yz^2), where s1 - s3 >= 0.1 p
//   shear      the largest |shear stress| / p
//   unbalanced the window mean of the unbalanced force ratio
// and, row by row without a window, the largest overlap / radius. A window of fewer than `rows` rows
// (5) is no mean: such a test fails as "rows" (its path cannot be judged). A custom path (its targets are
// the function's) gets the rotation, shear, unbalanced and overlap checks only.
// The paths of a shearing cell (their travel is the app's: the shear strain gamma, or the angle
// turned in radians) are judged on what they hold:
//   simple_shear      sigma_n: |S_zz - normal_stress| / normal_stress
//   rotation          p: |p - p*| / p*; q: |q - q*| / p*; b where s1 - s3 >= 0.1 p; alpha: the angle
//                     between the measured and the target major principal directions (degrees,
//                     against `rotation`), the targets the window mean of rotation_target
//   both simple shears with free xy and yz: shear = max(|S_xy|, |S_yz|) / p
// (the turn of the principal axes is their purpose: no rotation check there).
// apps/analysis/sandcell_analysis/path_check.py applies the same rules to a results file.
#include "engine/model.hpp"

#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace sandcell {

/// The tolerances of the watchdog (defaults argued in docs/physics.md section 6.2).
struct PathTolerance {
  double stress = 0.02;      // -, relative error of p, sigma3 or a stress-controlled axis
  double b = 0.03;           // -, absolute error of b
  double rotation = 5.0;     // degrees
  double shear = 0.15;       // -, largest |shear stress| / p
  double window = 0.01;      // -, axial strain over which the window means are taken
  double start = 0.0;        // -, axial strain (travel) before which nothing is averaged (the ramp)
  double overlap = 0.2;      // -, largest overlap / radius, row by row
  double unbalanced = 1.0;   // -, unbalanced force ratio, window mean
  int rows = 5;              // rows a window must hold to be a mean (fewer: the path cannot be judged)
};

/// Throws std::invalid_argument naming the tolerance (watch.<key>), its value and what is allowed.
void validate(const PathTolerance& tolerance);

/// One row's input.
struct PathRow {
  std::uint64_t step = 0;
  double eps1 = 0.0;              // -, axial strain (logarithmic, compression positive), or the path's travel
  Mat3 stress = Mat3::Zero();     // Pa, compression positive
  double max_overlap_ratio = 0.0; // -, 0 when not measured
  double unbalanced = 0.0;        // -, 0 when not measured
  double time = 0.0;              // s, clock time (the rotation path's target)
};

/// The first quantity beyond its tolerance.
struct PathFailure {
  std::string quantity;  // "p", "sigma3", "b", "axis 1".."axis 3", "rotation", "shear", "unbalanced", "overlap",
                         // "rows" (too few rows in a window: the path cannot be judged)
  double value = 0.0;      // the error (relative, absolute or degrees, as the quantity)
  double tolerance = 0.0;
  std::uint64_t step = 0;
  double eps1 = 0.0;
  std::string message;  // one line: quantity, value, tolerance, step, strain, and what it means
};

/// A path's travel as the logs write it: "eps1 = 1.23 %" (the axial paths), "gamma = 1.23 %" (the
/// simple shears), "turned 12.3 deg" (the rotation, travel in radians).
std::string travel_text(StressPath path, double travel);

/// The principal axes' turn off the cell axes of one stress tensor, degrees (0 where s1 - s3 < 0.1 |p|).
double principal_rotation_deg(const Mat3& stress);
/// The largest |shear stress| / |p| of one stress tensor (0 where p = 0).
double shear_ratio(const Mat3& stress);

class PathWatch {
 public:
  /// The path is read from `servo` (path, p, sigma3, b, target, control); throws like validate().
  PathWatch(const ServoSettings& servo, PathTolerance tolerance);

  /// Adds one row; returns the failure when this row is the first beyond a tolerance (later rows
  /// return nothing, but still count in the worst values).
  std::optional<PathFailure> add(const PathRow& row);

  const std::optional<PathFailure>& failure() const { return failure_; }
  /// The largest error of each quantity over the rows checked so far (names as PathFailure::quantity;
  /// "path" is the largest of p, sigma3 and the axes).
  double worst(const std::string& quantity) const;
  double worst_path() const { return worst_[k_path]; }
  double worst_b() const { return worst_[k_b]; }
  double worst_rotation() const { return worst_[k_rotation]; }
  std::size_t rows_checked() const { return checked_; }
  const PathTolerance& tolerance() const { return tol_; }

  /// The watch's memory (window, sums, worst values, failure) as numbers, for a checkpoint; restore()
  /// takes them back so a resumed test is judged as if it had not stopped.
  std::vector<double> save() const;
  void restore(const std::vector<double>& memory);

 private:
  enum Slot { k_path = 0, k_b, k_rotation, k_shear, k_unbalanced, k_overlap, k_slots };
  void judge(const PathRow& row);
  void fail(const char* quantity, double value, double tolerance, const PathRow& row);

  ServoSettings servo_;
  PathTolerance tol_;
  struct Entry {
    double travel;
    Mat3 stress;
    double unbalanced;
    double time = 0.0;
  };
  void judge_shearing(const Mat3& mean, const PathRow& row);
  std::pair<std::string, std::string> travel_text(const PathRow& row) const;
  std::deque<Entry> window_;
  double travel_ = 0.0, last_eps1_ = 0.0, begin_ = -1.0;
  bool first_row_ = true;
  double worst_[k_slots] = {};
  std::size_t checked_ = 0;
  std::optional<PathFailure> failure_;
};

}  // namespace sandcell
