// The stress-path watchdog (systems/path_watch.hpp) on series made up row by row: a test on its
// path is never failed (the false-positive check, with fluctuations as large as a 1,000-sphere
// sample's), each quantity off its path is named at the first full window, a transient shorter
// than the window is tolerated, the rotation is the exact angle of a turn in one principal plane,
// and a watch saved and restored judges like one that never stopped.
#include "systems/path_watch.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

using namespace sandcell;

namespace {

ServoSettings constant_p(double p, double b) {
  ServoSettings s;
  s.path = StressPath::constant_p;
  s.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
  s.p = p;
  s.b = b;
  return s;
}

ServoSettings constant_sigma3(double sigma3, double b) {
  ServoSettings s = constant_p(0.0, b);
  s.path = StressPath::constant_sigma3;
  s.sigma3 = sigma3;
  return s;
}

// The principal stresses of a path at stress ratio eta = q/p (triaxial q = sqrt(3 J2)) and b, with p given.
Vec3 on_path(double p, double eta, double b) {
  // s1 - s3 = d, s2 = s3 + b d; q = d sqrt(1 - b + b^2); p = s3 + d (1 + b)/3.
  const double d = eta * p / std::sqrt(1.0 - b + b * b);
  const double s3 = p - d * (1.0 + b) / 3.0;
  return Vec3(s3 + d, s3 + b * d, s3);
}

Mat3 diag(const Vec3& s) { return s.asDiagonal(); }

// A row every 2.5e-4 of axial strain (a 1 % window holds 40 rows, as the fast protocol's series).
constexpr double k_row = 2.5e-4;

}  // namespace

TEST_CASE("path watch: principal_rotation_deg is the exact angle of a turn in one principal plane") {
  const Vec3 s = on_path(1e6, 1.0, 0.0);
  for (double deg : {0.0, 1.0, 5.0, 12.0, 30.0}) {
    const double a = deg * std::numbers::pi / 180.0;
    Mat3 r = Mat3::Identity();  // about y: x-z plane, the sigma1-sigma3 plane
    r(0, 0) = r(2, 2) = std::cos(a);
    r(0, 2) = -std::sin(a);
    r(2, 0) = std::sin(a);
    const Mat3 t = r * diag(s) * r.transpose();
    // asin of a computed sine: exact to rounding, 1e-9 degrees covers it
    CHECK(std::abs(principal_rotation_deg(t) - deg) < 1e-9);
  }
  CHECK(principal_rotation_deg(Mat3::Identity() * 1e6) == 0.0);  // isotropic: no axes to turn
  Mat3 t = diag(Vec3(3e6, 1e6, 1e6));
  t(0, 1) = t(1, 0) = 0.2e6;
  CHECK(shear_ratio(t) == doctest::Approx(0.2e6 / (5e6 / 3.0)));
}

TEST_CASE("path watch: a test on its path, with rows scattered like a small sample's, is never failed") {
  // Every stress component scatters about the path by 2 % of p0, row to row, independently: 2-7x
  // the row-to-row scatter of 1,000-sphere rows about their 1 % window mean (0.3-1.0 % of p,
  // measured on constant p and constant sigma3 at 0.5 and 16 MPa). Window means of 41 rows then
  // scatter by 0.3 % of p0, a seventh of the stress tolerance; the shear stresses give a turn of
  // about 0.5 deg, a tenth of the rotation's.
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  for (double b : {0.0, 0.5, 1.0}) {
    for (bool sigma3 : {false, true}) {
      const double p0 = 1e6;
      PathWatch w(sigma3 ? constant_sigma3(p0, b) : constant_p(p0, b), PathTolerance{.start = 0.002});
      const double p = sigma3 ? 2.0 * p0 : p0;  // on constant sigma3 p rises with q
      for (int k = 0; k <= 800; ++k) {
        Vec3 s = on_path(p, k == 0 ? 0.0 : 0.9, b);
        if (sigma3) s += Vec3::Constant(p0 - s[2]);  // hold sigma3 at its target
        Mat3 t = diag(s);
        for (int i = 0; i < 3; ++i) t(i, i) += 0.02 * p0 * n(rng);
        t(0, 1) = t(1, 0) = 0.02 * p0 * n(rng);
        t(0, 2) = t(2, 0) = 0.02 * p0 * n(rng);
        t(1, 2) = t(2, 1) = 0.02 * p0 * n(rng);
        CHECK_FALSE(w.add({std::uint64_t(k), k * k_row, t, 0.01, 0.02}).has_value());
      }
      CHECK(w.rows_checked() > 700);
      CHECK(w.worst_path() < 0.02);
      CHECK(w.worst_b() < 0.03);
      CHECK(w.worst_rotation() < 5.0);
    }
  }
}

TEST_CASE("path watch: each quantity off its path is named at the first full window, not before") {
  struct Case {
    const char* quantity;
    ServoSettings servo;
    Mat3 stress;  // every row's stress after the first
    double overlap = 0.01, unbalanced = 0.02;
  };
  const double p0 = 1e6;
  const Vec3 s = on_path(p0, 1.0, 0.5);
  Mat3 turned = diag(s);
  turned(0, 2) = turned(2, 0) = 0.5 * (s[0] - s[2]) * std::sin(2.0 * 6.0 * std::numbers::pi / 180.0);  // 6 deg
  Mat3 b_off = diag(s);
  b_off(1, 1) += 0.05 * (s[0] - s[2]);  // b = 0.575, p unchanged
  b_off(0, 0) -= 0.025 * (s[0] - s[2]);
  b_off(2, 2) -= 0.025 * (s[0] - s[2]);
  const Case cases[] = {
      {"p", constant_p(p0, 0.5), diag(s * 1.03)},                                     // p 3 % high
      {"sigma3", constant_sigma3(0.5 * s[2], 0.5), diag(s)},                           // sigma3 twice its target
      {"b", constant_p(p0, 0.5), b_off},                                               // b 0.075 high
      {"rotation", constant_p(p0, 0.5), turned},                                       // axes turned by 6 deg
      {"unbalanced", constant_p(p0, 0.5), diag(s), 0.01, 1.5},                        // forces unbalanced
      {"overlap", constant_p(p0, 0.5), diag(s), 0.3, 0.02},                           // overlap 0.3 R
  };
  for (const Case& c : cases) {
    CAPTURE(c.quantity);
    PathWatch w(c.servo, PathTolerance{.start = 0.002});
    REQUIRE_FALSE(w.add({0, 0.0, diag(Vec3::Constant(p0)), 0.0, 0.0}).has_value());  // the sample
    std::optional<PathFailure> f;
    int row = 1;
    for (; row < 200 && !f; ++row) f = w.add({std::uint64_t(row), row * k_row, c.stress, c.overlap, c.unbalanced});
    REQUIRE(f.has_value());
    CHECK(f->quantity == c.quantity);
    CHECK(f->message.find(c.quantity) != std::string::npos);
    CHECK(f->message.find("step " + std::to_string(f->step)) != std::string::npos);
    if (std::string(c.quantity) == "overlap") {
      CHECK(f->step == 1);  // a bound of the contact model: no window
    } else {
      // the window [start, start + 1 %] fills at eps1 = 1.2 % (row 48): the first check fails
      CHECK(f->eps1 == doctest::Approx(0.012).epsilon(0.03));
    }
    CHECK_FALSE(w.add({999, 0.5, c.stress, c.overlap, c.unbalanced}).has_value());  // once only
    CHECK(w.failure()->quantity == c.quantity);
  }
}

TEST_CASE("path watch: a transient shorter than the window passes, a lasting one fails") {
  const double p0 = 1e6;
  const Vec3 s = on_path(p0, 1.0, 0.0);
  for (int spike_rows : {4, 30}) {  // 0.1 % and 0.75 % of strain at 20 % off: means 2 % and 15 %
    PathWatch w(constant_p(p0, 0.0), PathTolerance{.stress = 0.05, .start = 0.0});
    std::optional<PathFailure> f;
    for (int k = 0; k <= 400 && !f; ++k) {
      const bool spike = k >= 100 && k < 100 + spike_rows;
      f = w.add({std::uint64_t(k), k * k_row, diag(s * (spike ? 1.2 : 1.0)), 0.01, 0.02});
    }
    CAPTURE(spike_rows);
    // 4 rows at +20 % in a 41-row window: mean +1.95 %, inside 5 %; 30 rows: +14.6 %, beyond
    CHECK(f.has_value() == (spike_rows == 30));
  }
}

TEST_CASE("path watch: saved and restored, it judges like a watch that never stopped") {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  const double p0 = 2e6;
  std::vector<PathRow> rows;
  for (int k = 0; k <= 600; ++k) {
    Mat3 t = diag(on_path(p0, k == 0 ? 0.0 : 0.8, 0.25) * (1.0 + 0.0001 * k));  // p drifts: +2 % at row 200
    t(0, 1) = t(1, 0) = 0.02 * p0 * n(rng);
    rows.push_back({std::uint64_t(k), k * k_row, t, 0.01, 0.05});
  }
  PathWatch whole(constant_p(p0, 0.25), PathTolerance{.start = 0.002});
  PathWatch first(constant_p(p0, 0.25), PathTolerance{.start = 0.002});
  for (std::size_t k = 0; k < rows.size(); ++k) whole.add(rows[k]);
  for (std::size_t k = 0; k < 150; ++k) first.add(rows[k]);
  PathWatch second(constant_p(p0, 0.25), PathTolerance{.start = 0.002});
  second.restore(first.save());
  for (std::size_t k = 150; k < rows.size(); ++k) second.add(rows[k]);
  REQUIRE(whole.failure().has_value());
  REQUIRE(second.failure().has_value());
  CHECK(second.failure()->step == whole.failure()->step);  // bitwise the same sums in the same order
  CHECK(second.worst_path() == whole.worst_path());
  CHECK(second.worst_rotation() == whole.worst_rotation());
  CHECK_THROWS_AS(second.restore({1.0, 2.0}), std::invalid_argument);
}

TEST_CASE("path watch: a bad tolerance is refused naming it") {
  PathTolerance t;
  t.rotation = 90.0;
  CHECK_THROWS_WITH_AS(validate(t), doctest::Contains("watch.rotation = 90"), std::invalid_argument);
  t = {};
  t.window = 0.0;
  CHECK_THROWS_WITH_AS(PathWatch(constant_p(1e6, 0.0), t), doctest::Contains("watch.window = 0"),
                       std::invalid_argument);
}

TEST_CASE("path watch: a series too coarse to judge fails as rows; a test shorter than a window is not judged") {
  const double p0 = 1e6;
  const Mat3 s = diag(on_path(p0, 1.0, 0.5));  // exactly on its path
  // Rows 0.6 % of strain apart: a 1 % window holds 2 rows, fewer than the 5 a mean needs (a set
  // inertial number of 0.1 strained 300 spheres by 2 % between rows of 50 steps).
  PathWatch coarse(constant_p(p0, 0.5), PathTolerance{.start = 0.002});
  std::optional<PathFailure> f;
  for (int k = 0; k <= 20 && !f; ++k) f = coarse.add({std::uint64_t(50 * k), 0.006 * k, s, 0.01, 0.02});
  REQUIRE(f.has_value());
  CHECK(f->quantity == "rows");
  CHECK(f->message.find("cannot be judged") != std::string::npos);
  // The same rows 0.025 % apart (41 to a window) pass; to 0.5 % of strain nothing is judged.
  PathWatch fine(constant_p(p0, 0.5), PathTolerance{.start = 0.002});
  for (int k = 0; k <= 200; ++k) CHECK_FALSE(fine.add({std::uint64_t(k), k * k_row, s, 0.01, 0.02}).has_value());
  CHECK(fine.rows_checked() > 100);
  PathWatch short_test(constant_p(p0, 0.5), PathTolerance{.start = 0.002});
  for (int k = 0; k <= 20; ++k) CHECK_FALSE(short_test.add({std::uint64_t(k), k * k_row, s, 0.01, 0.02}).has_value());
  CHECK(short_test.rows_checked() == 0);
}
