#include "systems/stress.hpp"

namespace sandcell {

Mat3 contact_stress_sum(const ContactPairs& pairs, const std::vector<Vec3>& force, const std::vector<Vec3>& x,
                        const Cell& cell, Executor& exec) {
  const std::size_t m = std::min(pairs.size(), force.size());
  return exec.deterministic_reduce(
      m, 4096, Mat3(Mat3::Zero()),
      [&](std::size_t b, std::size_t e) {
        Mat3 s = Mat3::Zero();
        for (std::size_t k = b; k < e; ++k) {
          const Image& img = pairs.image[k];
          const Vec3 r = x[pairs.i[k]] - x[pairs.j[k]] - image_offset(img, cell);
          s += force[k] * r.transpose();
        }
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
