#include "systems/stress.hpp"

namespace sandcell {

Mat3 contact_stress_sum(const ContactPairs& pairs, const std::vector<Vec3>& force, const std::vector<Vec3>& x,
                        const Cell& cell, Executor& exec) {
  const std::size_t m = std::min(pairs.size(), force.size());
  return exec.deterministic_reduce(
      m, 4096, Mat3(Mat3::Zero()),
      [&](std::size_t b, std::size_t e) {
        // s += f r^T pair by pair, written out in scalars that stay in registers: the same
        // operations in the same order as the Eigen expressions they replace (each product rounded,
        // then added), so the same bits, in a fifth of their time: their accumulator went through
        // memory every pair (experiments/2026-11-29-homogenizer).
        const std::uint32_t* pi = pairs.i.data();
        const std::uint32_t* pj = pairs.j.data();
        const Image* image = pairs.image.data();
        const Vec3* xs = x.data();
        const Vec3* fs = force.data();
        double s00 = 0.0, s10 = 0.0, s20 = 0.0, s01 = 0.0, s11 = 0.0, s21 = 0.0, s02 = 0.0, s12 = 0.0, s22 = 0.0;
        const double l0 = cell.length[0], l1 = cell.length[1], l2 = cell.length[2];
        const double t0 = cell.tilt[0], t1 = cell.tilt[1], t2 = cell.tilt[2];
        for (std::size_t k = b; k < e; ++k) {
          // r = (x_i - x_j) - H n component by component, H n as image_offset(n, cell) computes it
          // (components/cell.hpp), in scalars: in a Vec3 two of its components went through memory.
          const Vec3& a = xs[pi[k]];
          const Vec3& c = xs[pj[k]];
          const double n0 = image[k][0], n1 = image[k][1], n2 = image[k][2];
          const double r0 = (a[0] - c[0]) - (n0 * l0 + n1 * t0 + n2 * t1);
          const double r1 = (a[1] - c[1]) - (n1 * l1 + n2 * t2);
          const double r2 = (a[2] - c[2]) - n2 * l2;
          const Vec3 r(r0, r1, r2);
          const Vec3& f = fs[k];
          s00 += f[0] * r[0];
          s10 += f[1] * r[0];
          s20 += f[2] * r[0];
          s01 += f[0] * r[1];
          s11 += f[1] * r[1];
          s21 += f[2] * r[1];
          s02 += f[0] * r[2];
          s12 += f[1] * r[2];
          s22 += f[2] * r[2];
        }
        Mat3 s;
        s << s00, s01, s02, s10, s11, s12, s20, s21, s22;
        return s;
      },
      [](const Mat3& a, const Mat3& b) { return Mat3(a + b); });
}

Mat3 contact_stress(const State& state, Executor& exec) {
  const Mat3 sum =
      contact_stress_sum(state.contacts.pairs, state.contacts.forces.force, state.particles.position, state.cell, exec);
  const Mat3 stress = sum / state.cell.volume();
  return 0.5 * (stress + stress.transpose());
}

std::size_t count_touching(const State& state) {
  const ContactPairs& pairs = state.contacts.pairs;
  const auto& x = state.particles.position;
  const auto& radius = state.particles.radius;
  const Cell& cell = state.cell;
  std::size_t count = 0;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const Image& img = pairs.image[k];
    const Vec3 r = x[pairs.i[k]] - x[pairs.j[k]] - image_offset(img, cell);
    const double s = radius[pairs.i[k]] + radius[pairs.j[k]];
    if (r.squaredNorm() < s * s) ++count;
  }
  return count;
}

}  // namespace sandcell
