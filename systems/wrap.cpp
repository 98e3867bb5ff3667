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

void Wrap::run(const Model&, State& state, Scratch&, Executor& exec) {
  const Vec3 length = state.read<Component::cell>().length;
  auto& position = state.write<Component::particle_position>();
  Vec3* x = position.data();
  exec.parallel_for(position.size(), k_particle_grain,
                    [&](std::size_t b, std::size_t e) { wrap_positions(x, length, b, e); });
}

}  // namespace sandcell
