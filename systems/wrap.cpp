#include "systems/wrap.hpp"

#include "systems/integrate.hpp"

#include <cmath>

namespace sandcell {

void wrap_positions(Vec3* x, const Vec3& length, std::size_t b, std::size_t e) {
  for (std::size_t k = b; k < e; ++k)
    for (int a = 0; a < 3; ++a) {
      if (x[k][a] >= length[a]) x[k][a] -= length[a];
      else if (x[k][a] < 0.0) x[k][a] += length[a];
      else continue;
      if (!(x[k][a] >= 0.0 && x[k][a] < length[a])) {  // more than one length out (a free fast flight)
        x[k][a] -= length[a] * std::floor(x[k][a] / length[a]);
        if (x[k][a] >= length[a]) x[k][a] = 0.0;  // -tiny + L rounded up to L
      }
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
