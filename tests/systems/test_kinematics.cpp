// Tensor kinematic measures (systems/kinematics.hpp) against closed forms: the logarithmic strain of
// simple shear and of a pure stretch, its two frame rules, principal values and directions of a
// rotated diagonal tensor, alpha of the rotation path, non-coaxiality, the strain rate tensor.
#include "systems/kinematics.hpp"
#include "systems/path_watch.hpp"
#include "systems/stress_paths.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <numbers>

using namespace sandcell;

namespace {

constexpr double k_deg = 180.0 / std::numbers::pi;

double max_abs(const Mat3& m) { return m.cwiseAbs().maxCoeff(); }

// A rotation by `deg` about y, taking x toward z (the rotation path's plane).
Mat3 turn_xz(double deg) {
  const double a = deg / k_deg;
  Mat3 r = Mat3::Identity();
  r(0, 0) = r(2, 2) = std::cos(a);
  r(2, 0) = std::sin(a);
  r(0, 2) = -std::sin(a);
  return r;
}

// A generic rotation (no axis, no symmetry), for the frame rules.
Mat3 generic_rotation() {
  return (Eigen::AngleAxisd(0.5, Vec3::UnitZ()) * Eigen::AngleAxisd(0.8, Vec3::UnitX()) *
          Eigen::AngleAxisd(-1.1, Vec3::UnitY()))
      .toRotationMatrix();
}

// The direction v with its largest-magnitude component made positive (principal()'s sign rule).
Vec3 signed_as_principal(Vec3 v) {
  int k = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(v[a]) > std::abs(v[k])) k = a;
  return v[k] < 0.0 ? Vec3(-v) : v;
}

}  // namespace

TEST_CASE("log_strain: simple shear against the closed form, large and small gamma") {
  // F = I + g e_x e_z^T. B = F F^T has, in the xz plane, trace 2 + g^2 and determinant 1, so its
  // eigenvalues are mu = 1 + g^2/2 +- g sqrt(1 + g^2/4) = lambda^2 with the principal stretches
  //   lambda_1,2 = sqrt(1 + g^2/4) +- g/2,   lambda_1 lambda_2 = 1,  lambda_1 - lambda_2 = g
  // (the amount of shear g = lambda - 1/lambda: Ogden, Non-Linear Elastic Deformations, 1984,
  // section 2.2, simple shear), and ln lambda_1 = asinh(g/2) (sqrt(1 + x^2) + x = e^asinh(x)).
  // The stretched direction n = (cos t, 0, sin t) of B: tan 2t = 2 B_xz / (B_xx - B_zz) = 2/g, i.e.
  // cos 2t = (g/2) / sqrt(1 + g^2/4), sin 2t = 1 / sqrt(1 + g^2/4). So
  //   ln V = asinh(g/2) (n n^T - m m^T) = asinh(g/2) [[cos 2t, sin 2t], [sin 2t, -cos 2t]] (xz block),
  // and eps = -ln V, with eps_yy = 0 and the volume kept (trace 0).
  for (double g : {1e-9, 1e-4, 0.3, 1.0, 2.5}) {
    CAPTURE(g);
    Mat3 f = Mat3::Identity();
    f(0, 2) = g;
    const Mat3 e = log_strain(f);
    const double a = std::asinh(0.5 * g), r = std::sqrt(1.0 + 0.25 * g * g);
    const double c2 = 0.5 * g / r, s2 = 1.0 / r;
    Mat3 expected = Mat3::Zero();
    expected(0, 0) = -a * c2;
    expected(2, 2) = a * c2;
    expected(0, 2) = expected(2, 0) = -a * s2;
    // The eigen-solver on F F^T - I keeps relative precision: 1e-13 of the largest component
    // (a ~ g/2) covers its ~1e-15 and the closed form's own rounding; measured below 3e-16.
    const double err = max_abs(e - expected);
    MESSAGE("simple shear g = " << g << ": |eps - closed form| = " << err << " (scale " << a << ")");
    CHECK(err <= 1e-13 * a);
    CHECK(std::abs(e.trace()) <= 1e-13 * a);  // det F = 1: no volume change
    // The principal strains: +-asinh(g/2) and 0, the compressed (major) direction at t + 90 deg.
    const Principal p = principal(e);
    CHECK(std::abs(p.values[0] - a) <= 1e-13 * a);
    CHECK(std::abs(p.values[1]) <= 1e-13 * a);
    CHECK(std::abs(p.values[2] + a) <= 1e-13 * a);
    const double t = 0.5 * std::atan2(s2, c2);
    const Vec3 major = signed_as_principal(Vec3(-std::sin(t), 0.0, std::cos(t)));
    CHECK((p.directions.col(0) - major).norm() <= 1e-12);
  }
}

TEST_CASE("log_strain: a pure stretch is -ln of the stretches exactly, and the two frame rules") {
  const Vec3 stretch(0.9, 1.05, 1.2);
  const Mat3 f = stretch.asDiagonal();
  const Mat3 e = log_strain(f);
  for (int k = 0; k < 3; ++k) CHECK(e(k, k) == -std::log(stretch[k]));  // the diagonal path: bitwise
  CHECK(max_abs(e - Mat3(e.diagonal().asDiagonal())) == 0.0);
  // A symmetric stretch R S R^T is its own V: eps = R diag(-ln s) R^T.
  const Mat3 r = generic_rotation();
  const Mat3 rotated = log_strain(r * f * r.transpose());
  CHECK(max_abs(rotated - r * e * r.transpose()) <= 1e-14);
  // V = sqrt(F F^T): F R (the reference turned) leaves F F^T, hence V and eps, unchanged;
  // R F (the current configuration turned) gives R V R^T. Checked on a general (sheared and
  // stretched) F; ~10 rounding steps of O(1) numbers: 1e-14.
  Mat3 g;
  g << 1.1, 0.3, -0.2, 0.0, 0.95, 0.4, 0.0, 0.0, 1.02;
  const Mat3 eg = log_strain(g);
  CHECK(max_abs(log_strain(g * r) - eg) <= 1e-14);
  CHECK(max_abs(log_strain(r * g) - r * eg * r.transpose()) <= 1e-14);
  CHECK(max_abs(eg - eg.transpose()) == 0.0);
  // trace(eps) = -ln det F (volumetric): the eps_v of the cell's lengths.
  CHECK(std::abs(eg.trace() + std::log(g.determinant())) <= 1e-14);
}

TEST_CASE("principal: values descending and directions of a rotated diagonal tensor") {
  const Mat3 r = generic_rotation();
  const Vec3 values(3e6, 2e6, 1e6);
  const Principal p = principal(r * values.asDiagonal() * r.transpose());
  // Self-adjoint solver: ~1e-16 of the largest value; 1e-12 relative leaves room.
  for (int k = 0; k < 3; ++k) {
    CHECK(std::abs(p.values[k] - values[k]) <= 1e-12 * values[0]);
    CHECK((p.directions.col(k) - signed_as_principal(r.col(k))).norm() <= 1e-12);
  }
  CHECK(max_abs(p.directions.transpose() * p.directions - Mat3::Identity()) <= 1e-14);
  // A diagonal tensor exactly: sorted, ties in axis order, the unit axes.
  const Principal d = principal(Vec3(1.0, 3.0, 1.0).asDiagonal());
  CHECK(d.values == Vec3(3.0, 1.0, 1.0));
  Mat3 axes;
  axes << 0, 1, 0, 1, 0, 0, 0, 0, 1;
  CHECK(d.directions == axes);
}

TEST_CASE("alpha and axes_rotation_deg on the rotation path's stress, and agreement with the watchdog's angle") {
  // rotated_stress puts sigma1 at alpha from x toward z and sigma2 on y: alpha comes back exactly
  // up to rounding (atan2 of computed sines and cosines: 1e-9 degrees covers it), in (-90, 90].
  for (double deg : {-80.0, -45.0, 0.0, 10.0, 30.0, 60.0, 89.5, 90.0, 100.0, 170.0}) {
    CAPTURE(deg);
    const Mat3 s = rotated_stress(1e5, 0.5, 6e4, deg / k_deg);
    const double expected = deg > 90.0 ? deg - 180.0 : deg;  // a direction: alpha and alpha - 180 agree
    CHECK(std::abs(alpha_deg(s) - expected) <= 1e-9);
  }
  CHECK(alpha_deg(Mat3::Identity() * 1e5) == 0.0);
  CHECK(alpha_deg(Vec3(1e5, 2e5, 3e5).asDiagonal()) == 90.0);  // sigma_zz the larger: along z
  // A turn a <= 45 degrees in the sigma1-sigma3 plane: the angle from the nearest axis is a, the
  // watchdog's principal_rotation_deg (from the shear stresses) gives the same.
  for (double deg : {0.0, 1.0, 12.0, 30.0, 45.0}) {
    CAPTURE(deg);
    const Mat3 s = turn_xz(deg) * Vec3(3e6, 2e6, 1e6).asDiagonal() * turn_xz(deg).transpose();
    CHECK(std::abs(axes_rotation_deg(s) - deg) <= 1e-9);
    CHECK(std::abs(axes_rotation_deg(s) - principal_rotation_deg(s)) <= 1e-9);
  }
  // Past 45 degrees the nearest axis is z: 60 degrees from x is 30 from z.
  const Mat3 s60 = turn_xz(60.0) * Vec3(3e6, 2e6, 1e6).asDiagonal() * turn_xz(60.0).transpose();
  CHECK(std::abs(axes_rotation_deg(s60) - 30.0) <= 1e-9);
}

TEST_CASE("noncoaxiality_deg: 0 for coaxial tensors, the angle between major directions otherwise") {
  const Vec3 stress(3e6, 2e6, 1e6), strain(2e-3, -0.5e-3, -1e-3);
  // Coaxial and axis-aligned: exactly 0 (the diagonal path).
  CHECK(noncoaxiality_deg(stress.asDiagonal(), strain.asDiagonal()) == 0.0);
  // Coaxial, both turned by the same generic rotation: 0 up to the solver's rounding.
  const Mat3 r = generic_rotation();
  CHECK(noncoaxiality_deg(r * stress.asDiagonal() * r.transpose(), r * strain.asDiagonal() * r.transpose()) <= 1e-9);
  // Majors 30 degrees apart in xz (stress at 10, strain increment at 40), then in a turned frame.
  const Mat3 s = turn_xz(10.0) * stress.asDiagonal() * turn_xz(10.0).transpose();
  const Mat3 e = turn_xz(40.0) * strain.asDiagonal() * turn_xz(40.0).transpose();
  CHECK(std::abs(noncoaxiality_deg(s, e) - 30.0) <= 1e-9);
  CHECK(std::abs(noncoaxiality_deg(r * s * r.transpose(), r * e * r.transpose()) - 30.0) <= 1e-9);
  CHECK(std::abs(noncoaxiality_deg(e, s) - 30.0) <= 1e-9);  // symmetric in its arguments
  // Majors 120 degrees apart are 60 degrees apart as directions (a direction has no sign).
  const Mat3 e130 = turn_xz(130.0) * strain.asDiagonal() * turn_xz(130.0).transpose();
  CHECK(std::abs(noncoaxiality_deg(s, e130) - 60.0) <= 1e-9);
  // An isotropic (here zero) increment has no direction: 0.
  CHECK(noncoaxiality_deg(s, Mat3::Zero()) == 0.0);
}

TEST_CASE("strain_rate_tensor: -sym(L), the diagonal exactly -L_kk") {
  Mat3 l = Mat3::Zero();
  l.diagonal() = Vec3(-5.0, 2.5, 1.25);
  l(0, 2) = -4.0;  // simple shear at gamma_dot_xz = -L_xz = 4 1/s
  const Mat3 d = strain_rate_tensor(l);
  for (int k = 0; k < 3; ++k) CHECK(d(k, k) == -l(k, k));
  CHECK(d(0, 2) == 2.0);
  CHECK(d(2, 0) == 2.0);
  CHECK(d(0, 1) == 0.0);
}

TEST_CASE("cell_strain: the lengths' strain bitwise for an orthorhombic cell, log_strain(F) once tilted") {
  Cell c;
  c.length0 = Vec3(10e-3, 11e-3, 12e-3);
  c.length = Vec3(9.9e-3, 11.05e-3, 12.02e-3);
  const Mat3 e = cell_strain(c);
  for (int k = 0; k < 3; ++k) CHECK(e(k, k) == -std::log(c.length[k] / c.length0[k]));
  c.tilt = Vec3(0.0, 3e-3, 0.0);
  c.flip = Vec3(0.0, 1.0, 0.0);  // one flip: F_xz = (xz + L1) / L3_0
  const Mat3 f = c.deformation();
  CHECK(f(0, 2) == doctest::Approx((3e-3 + 9.9e-3) / 12e-3).epsilon(1e-15));
  CHECK(max_abs(cell_strain(c) - log_strain(f)) == 0.0);
}
