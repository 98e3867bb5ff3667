#include "systems/path_watch.hpp"

#include "systems/servo.hpp"
#include "systems/stress_paths.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

namespace sandcell {

namespace {
constexpr double k_min_deviator = 0.1;  // b and the rotation are judged where s1 - s3 >= 0.1 |p|
// PathTolerance::rows, a window's fewest rows (5): the fast protocol's series hold ~40 over 1 % of
// axial strain, the default test's ~19; a test strained by a window in 1-4 rows (a set inertial
// number of 0.1: 5 % of strain in 46 steps) cannot be judged, and is not passed.

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}
}  // namespace

void validate(const PathTolerance& t) {
  const auto check = [](const char* key, double v, double lo, double hi, const char* allowed) {
    if (!(v >= lo && v <= hi) || !std::isfinite(v))
      throw std::invalid_argument(std::string("watch.") + key + " = " + fmt("%g", v) + ": " + allowed);
  };
  check("stress", t.stress, 1e-6, 10.0, "must be in [1e-6, 10] (relative error of p, sigma3 or an axis)");
  check("b", t.b, 1e-6, 1.0, "must be in [1e-6, 1]");
  check("rotation", t.rotation, 1e-3, 45.0, "must be in [1e-3, 45] degrees");
  check("shear", t.shear, 1e-6, 10.0, "must be in [1e-6, 10] (|shear stress| / p)");
  check("window", t.window, 1e-6, 1.0, "must be in [1e-6, 1] (axial strain)");
  check("start", t.start, 0.0, 2.0, "must be in [0, 2] (axial strain)");
  check("overlap", t.overlap, 1e-6, 1.0, "must be in [1e-6, 1] (overlap / radius)");
  check("unbalanced", t.unbalanced, 1e-6, 1e6, "must be in [1e-6, 1e6]");
  check("rows", t.rows, 1, 100000, "must be an integer in [1, 1e5] (rows a window must hold)");
}

double principal_rotation_deg(const Mat3& s) {
  const Vec3 lam = Eigen::SelfAdjointEigenSolver<Mat3>(s, Eigen::EigenvaluesOnly).eigenvalues();  // ascending
  const double p = s.trace() / 3.0;
  const double span = lam[2] - lam[0];
  if (!(span >= k_min_deviator * std::abs(p)) || !(span > 0.0)) return 0.0;
  const double tau = std::sqrt(s(0, 1) * s(0, 1) + s(0, 2) * s(0, 2) + s(1, 2) * s(1, 2));
  return 0.5 * std::asin(std::min(1.0, 2.0 * tau / span)) * 180.0 / std::numbers::pi;
}

double shear_ratio(const Mat3& s) {
  const double p = std::abs(s.trace() / 3.0);
  if (!(p > 0.0)) return 0.0;
  return std::max({std::abs(s(0, 1)), std::abs(s(0, 2)), std::abs(s(1, 2))}) / p;
}

PathWatch::PathWatch(const ServoSettings& servo, PathTolerance tolerance) : servo_(servo), tol_(tolerance) {
  validate(tol_);
  servo_.custom = nullptr;  // the watch never calls a custom path (its targets are the function's)
}

double PathWatch::worst(const std::string& q) const {
  if (q == "p" || q == "sigma3" || q == "q" || q == "sigma_n" || q == "path" || q.rfind("axis", 0) == 0)
    return worst_[k_path];
  if (q == "b") return worst_[k_b];
  if (q == "rotation" || q == "alpha") return worst_[k_rotation];
  if (q == "shear") return worst_[k_shear];
  if (q == "unbalanced") return worst_[k_unbalanced];
  if (q == "overlap") return worst_[k_overlap];
  throw std::invalid_argument("PathWatch::worst: no quantity '" + q + "'");
}

std::string travel_text(StressPath path, double travel) {
  if (path == StressPath::rotation) return "turned " + fmt("%.1f deg", travel * 180.0 / std::numbers::pi);
  if (path == StressPath::simple_shear || path == StressPath::simple_shear_cv)
    return "gamma = " + fmt("%.2f %%", 100.0 * travel);
  return "eps1 = " + fmt("%.2f %%", 100.0 * travel);
}

// The travel the windows count, as text: the window and where the row is.
std::pair<std::string, std::string> PathWatch::travel_text(const PathRow& row) const {
  const StressPath path = servo_.path;
  const std::string window =
      path == StressPath::rotation ? fmt("%g deg", tol_.window * 180.0 / std::numbers::pi) + " of rotation"
      : path == StressPath::simple_shear || path == StressPath::simple_shear_cv
          ? fmt("%g %%", 100.0 * tol_.window) + " of shear strain"
          : fmt("%g %%", 100.0 * tol_.window) + " of axial strain";
  return {window, sandcell::travel_text(path, row.eps1)};
}

void PathWatch::fail(const char* quantity, double value, double tolerance, const PathRow& row) {
  if (failure_ || !(value > tolerance)) return;
  PathFailure f;
  f.quantity = quantity;
  f.value = value;
  f.tolerance = tolerance;
  f.step = row.step;
  f.eps1 = row.eps1;
  const std::string q = quantity;
  const bool relative = q == "p" || q == "sigma3" || q == "q" || q == "sigma_n" || q.rfind("axis", 0) == 0;
  const std::string value_text = relative                          ? fmt("%.2f %%", 100.0 * value) + " off its target"
                                 : q == "rotation" || q == "alpha" ? fmt("%.1f deg", value)
                                 : q == "b"        ? fmt("%.3f", value) + " off its target"
                                                   : fmt("%.3g", value);
  const std::string tol_text = relative ? fmt("%g %%", 100.0 * tolerance) : fmt("%g", tolerance);
  const auto [window, where] = travel_text(row);
  const std::string over = q == "overlap" ? "at this row" : "over the last " + window;
  f.message = "left its stress path: " + q + " " + value_text + " " + over + " (tolerance " + tol_text +
              ") at step " + std::to_string(row.step) + ", " + where;
  failure_ = f;
}

std::optional<PathFailure> PathWatch::add(const PathRow& row) {
  const bool had = failure_.has_value();
  judge(row);
  if (had) return std::nullopt;  // the first failure is reported once; the worst values go on
  return failure_;
}

void PathWatch::judge(const PathRow& row) {
  if (first_row_) {  // the sample before any step: the strain origin only
    first_row_ = false;
    last_eps1_ = row.eps1;
    return;
  }
  travel_ += std::abs(row.eps1 - last_eps1_);
  last_eps1_ = row.eps1;
  worst_[k_overlap] = std::max(worst_[k_overlap], row.max_overlap_ratio);
  fail("overlap", row.max_overlap_ratio, tol_.overlap, row);
  if (begin_ < 0.0) {
    if (travel_ < tol_.start) return;
    begin_ = travel_;
  }
  window_.push_back({travel_, row.stress, row.unbalanced, row.time});
  while (travel_ - window_.front().travel > tol_.window) window_.pop_front();
  if (travel_ < tol_.start + tol_.window) return;  // the first window is not full yet
  if (window_.size() < static_cast<std::size_t>(tol_.rows)) {
    if (failure_) return;
    PathFailure f;
    f.quantity = "rows";
    f.value = double(window_.size());
    f.tolerance = double(tol_.rows);
    f.step = row.step;
    f.eps1 = row.eps1;
    f.message = "the path cannot be judged: " + std::to_string(window_.size()) + " series row(s) over the last " +
                travel_text(row).first + " (at least " + std::to_string(tol_.rows) +
                ": lower output.series_interval or the strain rate) at step " + std::to_string(row.step) + ", " +
                travel_text(row).second;
    failure_ = f;
    return;
  }

  Mat3 m = Mat3::Zero();
  double unbalanced = 0.0;
  for (const Entry& e : window_) {
    m += e.stress;
    unbalanced += e.unbalanced;
  }
  m /= static_cast<double>(window_.size());
  unbalanced /= static_cast<double>(window_.size());
  ++checked_;
  const double p = m.trace() / 3.0;
  const auto path_error = [&](const char* q, double error) {
    worst_[k_path] = std::max(worst_[k_path], error);
    fail(q, error, tol_.stress, row);
  };
  // What the path holds (systems/stress_paths.hpp): p or sigma3 on the b paths, else each
  // stress-controlled axis's target; a custom path's targets are its function's, not checked here.
  const StressPathSpec& spec = stress_path(servo_.path);
  if (spec.answer != nullptr) {
    judge_shearing(m, row);
    worst_[k_unbalanced] = std::max(worst_[k_unbalanced], unbalanced);
    fail("unbalanced", unbalanced, tol_.unbalanced, row);
    return;
  }
  if (spec.has_b) {
    if (spec.scale == PathScale::p)
      path_error("p", std::abs(p - servo_.p) / std::abs(servo_.p));
    else
      path_error("sigma3", std::abs(m(2, 2) - servo_.sigma3) / std::abs(servo_.sigma3));
    const double d = m(0, 0) - m(2, 2);
    if (d >= k_min_deviator * std::abs(p)) {
      const double error = std::abs((m(1, 1) - m(2, 2)) / d - servo_.b);
      worst_[k_b] = std::max(worst_[k_b], error);
      fail("b", error, tol_.b, row);
    }
  } else if (spec.targets) {
    const Vec3 target = spec.targets(servo_, m(0, 0));
    const double scale = std::max(1e-300, path_scale(servo_));
    static constexpr const char* names[3] = {"axis 1", "axis 2", "axis 3"};
    for (int k = 0; k < 3; ++k)
      if (servo_.control[k] == AxisControl::stress) path_error(names[k], std::abs(m(k, k) - target[k]) / scale);
  }
  const double rotation = principal_rotation_deg(m);
  worst_[k_rotation] = std::max(worst_[k_rotation], rotation);
  fail("rotation", rotation, tol_.rotation, row);
  const double shear = shear_ratio(m);
  worst_[k_shear] = std::max(worst_[k_shear], shear);
  fail("shear", shear, tol_.shear, row);
  worst_[k_unbalanced] = std::max(worst_[k_unbalanced], unbalanced);
  fail("unbalanced", unbalanced, tol_.unbalanced, row);
}

// The paths of a shearing cell (path_watch.hpp): what each holds, from the window mean stress.
void PathWatch::judge_shearing(const Mat3& m, const PathRow& row) {
  const auto path_error = [&](const char* q, double error) {
    worst_[k_path] = std::max(worst_[k_path], error);
    fail(q, error, tol_.stress, row);
  };
  const double p = m.trace() / 3.0;
  if (servo_.path == StressPath::rotation) {
    Mat3 target = Mat3::Zero();
    for (const Entry& e : window_) target += rotation_target(servo_, e.time);
    target /= static_cast<double>(window_.size());
    const double p_target = target.trace() / 3.0;
    path_error("p", std::abs(p - p_target) / std::abs(p_target));
    const Eigen::SelfAdjointEigenSolver<Mat3> measured(m), wanted(target);  // ascending
    const Vec3 lm = measured.eigenvalues(), lt = wanted.eigenvalues();
    const auto q_of = [](const Vec3& l) {
      return std::sqrt(0.5 * ((l[2] - l[1]) * (l[2] - l[1]) + (l[1] - l[0]) * (l[1] - l[0]) +
                              (l[0] - l[2]) * (l[0] - l[2])));
    };
    path_error("q", std::abs(q_of(lm) - q_of(lt)) / std::abs(p_target));
    if (lm[2] - lm[0] >= k_min_deviator * std::abs(p)) {
      const double b_error = std::abs((lm[1] - lm[0]) / (lm[2] - lm[0]) - servo_.b);
      worst_[k_b] = std::max(worst_[k_b], b_error);
      fail("b", b_error, tol_.b, row);
      if (lt[2] - lt[0] >= k_min_deviator * std::abs(p_target)) {
        // The angle between the major principal directions (an axis: the sign of a vector is free).
        const double c = std::abs(measured.eigenvectors().col(2).dot(wanted.eigenvectors().col(2)));
        const double alpha = std::acos(std::min(1.0, c)) * 180.0 / std::numbers::pi;
        worst_[k_rotation] = std::max(worst_[k_rotation], alpha);
        fail("alpha", alpha, tol_.rotation, row);
      }
    }
    return;
  }
  if (servo_.path == StressPath::simple_shear)
    path_error("sigma_n", std::abs(m(2, 2) - servo_.normal_stress) / std::abs(servo_.normal_stress));
  if (servo_.shear_control[0] == AxisControl::stress || servo_.shear_control[2] == AxisControl::stress) {
    const double shear = std::abs(p) > 0.0 ? std::max(std::abs(m(0, 1)), std::abs(m(1, 2))) / std::abs(p) : 0.0;
    worst_[k_shear] = std::max(worst_[k_shear], shear);
    fail("shear", shear, tol_.shear, row);
  }
}

// Layout: version, travel, last eps1, begin, first row, rows checked, the worst values, the window
// (count, then travel, 6 stress components xx yy zz xy xz yz and the unbalanced ratio per entry).
// Version 2 (the rotation path, whose targets follow the clock) adds each entry's time.
std::vector<double> PathWatch::save() const {
  const bool timed = servo_.path == StressPath::rotation;
  std::vector<double> v = {timed ? 2.0 : 1.0, travel_, last_eps1_, begin_, first_row_ ? 1.0 : 0.0, double(checked_)};
  v.insert(v.end(), worst_, worst_ + k_slots);
  v.push_back(double(window_.size()));
  for (const Entry& e : window_) {
    const Mat3& s = e.stress;
    v.insert(v.end(), {e.travel, s(0, 0), s(1, 1), s(2, 2), s(0, 1), s(0, 2), s(1, 2), e.unbalanced});
    if (timed) v.push_back(e.time);
  }
  return v;
}

void PathWatch::restore(const std::vector<double>& v) {
  constexpr std::size_t head = 6 + k_slots + 1;
  if (v.size() < head || (v[0] != 1.0 && v[0] != 2.0))
    throw std::invalid_argument("PathWatch::restore: not a saved watch (" + std::to_string(v.size()) + " numbers)");
  const std::size_t n = static_cast<std::size_t>(v[head - 1]);
  const std::size_t per = v[0] == 2.0 ? 9 : 8;
  if (v.size() != head + per * n)
    throw std::invalid_argument("PathWatch::restore: " + std::to_string(v.size()) + " numbers for " +
                                std::to_string(n) + " window rows");
  travel_ = v[1];
  last_eps1_ = v[2];
  begin_ = v[3];
  first_row_ = v[4] != 0.0;
  checked_ = static_cast<std::size_t>(v[5]);
  std::copy(v.begin() + 6, v.begin() + 6 + k_slots, worst_);
  window_.clear();
  for (std::size_t k = 0; k < n; ++k) {
    const double* e = v.data() + head + per * k;
    Mat3 s;
    s << e[1], e[4], e[5], e[4], e[2], e[6], e[5], e[6], e[3];
    window_.push_back({e[0], s, e[7], per == 9 ? e[8] : 0.0});
  }
  failure_.reset();
}

}  // namespace sandcell
