#include "systems/kinematics.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace sandcell {

namespace {

constexpr double k_deg = 180.0 / std::numbers::pi;

bool off_diagonal_zero(const Mat3& m) {
  return m(0, 1) == 0.0 && m(0, 2) == 0.0 && m(1, 0) == 0.0 && m(1, 2) == 0.0 && m(2, 0) == 0.0 && m(2, 1) == 0.0;
}

// The index of v's largest |component|, the first on a tie (so the choice is deterministic).
int largest_component(const Vec3& v) {
  int k = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(v[a]) > std::abs(v[k])) k = a;
  return k;
}

}  // namespace

Principal principal(const Mat3& sym) {
  const Mat3 s = 0.5 * (sym + sym.transpose());
  Principal out;
  if (off_diagonal_zero(s)) {
    // Exact: no iteration round-off for a tensor aligned with the axes (an orthorhombic cell's).
    std::array<int, 3> order{0, 1, 2};
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return s(a, a) > s(b, b); });
    out.directions = Mat3::Zero();
    for (int k = 0; k < 3; ++k) {
      out.values[k] = s(order[k], order[k]);
      out.directions(order[k], k) = 1.0;
    }
    return out;
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> solver(s);  // ascending
  for (int k = 0; k < 3; ++k) {
    out.values[k] = solver.eigenvalues()[2 - k];
    Vec3 v = solver.eigenvectors().col(2 - k);
    if (v[largest_component(v)] < 0.0) v = -v;
    out.directions.col(k) = v;
  }
  return out;
}

Mat3 log_strain(const Mat3& f) {
  if (off_diagonal_zero(f)) {
    Mat3 e = Mat3::Zero();
    for (int k = 0; k < 3; ++k) e(k, k) = -std::log(f(k, k));
    return e;
  }
  // F F^T - I = G + G^T + G G^T with G = F - I: small strains keep their relative precision.
  const Mat3 g = f - Mat3::Identity();
  Mat3 c = g + g.transpose() + g * g.transpose();
  c = 0.5 * (c + c.transpose());
  const Eigen::SelfAdjointEigenSolver<Mat3> solver(c);
  Vec3 half_ln;  // ln(lambda_k) = ln(mu_k) / 2, mu_k = 1 + c_k the eigenvalues of F F^T
  for (int k = 0; k < 3; ++k) half_ln[k] = 0.5 * std::log1p(solver.eigenvalues()[k]);
  const Mat3& q = solver.eigenvectors();
  const Mat3 ln_v = q * half_ln.asDiagonal() * q.transpose();
  return -0.5 * (ln_v + ln_v.transpose());
}

Mat3 cell_strain(const Cell& cell) {
  if (!diagonal_deformation(cell)) return log_strain(cell.deformation());
  // The same arithmetic as Measures::strain (the bits an orthorhombic cell's strain always had).
  Mat3 e = Mat3::Zero();
  for (int k = 0; k < 3; ++k) e(k, k) = -std::log(cell.length[k] / cell.length0[k]);
  return e;
}

Mat3 strain_rate_tensor(const Mat3& l) { return -0.5 * (l + l.transpose()); }

double axes_rotation_deg(const Mat3& sym) {
  const Vec3 v = principal(sym).directions.col(0);
  const int k = largest_component(v);
  const double off = std::hypot(v[(k + 1) % 3], v[(k + 2) % 3]);
  return std::atan2(off, std::abs(v[k])) * k_deg;
}

double alpha_deg(const Mat3& sym) {
  const double xz = 0.5 * (sym(0, 2) + sym(2, 0));
  const double a = 0.5 * std::atan2(2.0 * xz, sym(0, 0) - sym(2, 2)) * k_deg;  // in [-90, 90]
  return a <= -90.0 ? a + 180.0 : a;                                           // the same direction: (-90, 90]
}

double noncoaxiality_deg(const Mat3& stress, const Mat3& strain_increment) {
  const Principal s = principal(stress), e = principal(strain_increment);
  // An isotropic tensor (zero, say) has no major direction: no angle to report.
  if (s.values[0] == s.values[2] || e.values[0] == e.values[2]) return 0.0;
  const Vec3 a = s.directions.col(0), b = e.directions.col(0);
  return std::atan2(a.cross(b).norm(), std::abs(a.dot(b))) * k_deg;
}

double deviatoric_strain(const Cell& cell) {
  Vec3 e;
  if (diagonal_deformation(cell)) {
    for (int a = 0; a < 3; ++a) e[a] = -std::log(cell.length[a] / cell.length0[a]);
  } else {
    e = principal(cell_strain(cell)).values;
  }
  return std::sqrt(2.0) / 3.0 *
         std::sqrt((e[0] - e[1]) * (e[0] - e[1]) + (e[1] - e[2]) * (e[1] - e[2]) + (e[2] - e[0]) * (e[2] - e[0]));
}

}  // namespace sandcell
