#include "systems/wrap.hpp"

#include "systems/integrate.hpp"

#include <cmath>

namespace sandcell {

void wrap_positions(Vec3* x, const Vec3& length, std::size_t b, std::size_t e, std::array<int, 3>* shift) {
  for (std::size_t k = b; k < e; ++k)
    for (int a = 0; a < 3; ++a) {
      int s = 0;
      if (x[k][a] >= length[a]) {
        x[k][a] -= length[a];
        s = 1;
      } else if (x[k][a] < 0.0) {
        x[k][a] += length[a];
        s = -1;
      }
      if (s != 0 && !(x[k][a] >= 0.0 && x[k][a] < length[a])) {  // more than one length out (a free fast flight)
        const double f = std::floor(x[k][a] / length[a]);
        x[k][a] -= length[a] * f;
        s += static_cast<int>(f);
        if (x[k][a] >= length[a]) {  // -tiny + L rounded up to L
          x[k][a] = 0.0;
          s += 1;
        }
      }
      if (shift) shift[k - b][a] = s;
    }
}

void wrap_positions(Vec3* x, const Cell& cell, std::size_t b, std::size_t e, std::array<int, 3>* shift) {
  if (cell.tilt.isZero(0.0)) return wrap_positions(x, cell.length, b, e, shift);
  const Vec3& l = cell.length;
  const Vec3& t = cell.tilt;
  for (std::size_t k = b; k < e; ++k) {
    const Vec3 s = reduced(x[k], l, t);
    std::array<int, 3> n{};
    for (int a = 0; a < 3; ++a) n[a] = static_cast<int>(std::floor(s[a]));
    if (n[0] != 0 || n[1] != 0 || n[2] != 0) {
      const Vec3 f(n[0], n[1], n[2]);
      x[k] -= unreduced(f, l, t);
    }
    if (shift) shift[k - b] = n;
  }
}

void Wrap::run(const Model&, State& state, Scratch&, Executor& exec) {
  const Cell cell = state.read<Component::cell>();
  auto& position = state.write<Component::particle_position>();
  Vec3* x = position.data();
  exec.parallel_for(position.size(), k_particle_grain,
                    [&](std::size_t b, std::size_t e) { wrap_positions(x, cell, b, e); });
}

}  // namespace sandcell
