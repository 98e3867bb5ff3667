// triaxial: the main job. Until the servo and contact systems land, it runs a free-flight demo in a
// deforming periodic cell: N spheres with random velocities in a cube shortened along axis 3 at a
// constant strain rate, and reports what a user can check by hand (momentum, kinetic energy, the
// cell's strain, the wrap of every particle into the cell).
#include "engine/world.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <string_view>

using namespace sandcell;

int main(int argc, char** argv) {
  int threads = 0;
  for (int a = 1; a < argc; ++a) {
    std::string_view arg = argv[a];
    if (arg == "--threads" && a + 1 < argc) {
      char* end = nullptr;
      const long t = std::strtol(argv[++a], &end, 10);
      if (*end != '\0' || t < 1 || t > 1024) {
        std::fprintf(stderr, "triaxial: --threads = '%s': must be an integer in [1, 1024]\n", argv[a]);
        return 2;
      }
      threads = static_cast<int>(t);
    } else {
      std::fprintf(stderr, "triaxial: unknown argument '%s' (allowed: --threads N)\n", argv[a]);
      return 2;
    }
  }

  Model model;
  model.dt = 1e-6;
  model.materials.push_back(Material{});
  model.contact.enabled = false;  // free flight
  State state;
  const double box = 0.05;  // m
  state.cell.length = state.cell.length0 = Vec3::Constant(box);
  state.cell.rate = Vec3(0.0, 0.0, -1.0);  // 1/s: axis 3 shortened, 1e-6 per step
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 0.1);  // m/s
  const int n = 2000;
  for (int k = 0; k < n; ++k) {
    const std::size_t i = add_sphere(state, model, static_cast<ParticleId>(k),
                                     Vec3(u01(rng), u01(rng), u01(rng)) * box, 1e-3, 0);
    state.particles.velocity[i] = Vec3(gauss(rng), gauss(rng), gauss(rng));
  }

  World world(model, std::move(state), ExecutorConfig{Backend::tbb, threads});
  std::printf("sandcell triaxial (free-flight demo until the contact systems land)\n");
  std::printf("step graph:\n%s", world.graph().describe().c_str());
  const auto t0 = std::chrono::steady_clock::now();
  const int steps = 20000;
  world.step(steps);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const State& s = world.state();
  Vec3 momentum = Vec3::Zero();
  double kinetic = 0.0;
  bool inside = true;
  for (std::size_t k = 0; k < s.particles.size(); ++k) {
    momentum += s.particles.mass[k] * s.particles.velocity[k];
    kinetic += 0.5 * s.particles.mass[k] * s.particles.velocity[k].squaredNorm();
    for (int a = 0; a < 3; ++a)
      inside = inside && s.particles.position[k][a] >= 0.0 && s.particles.position[k][a] < s.cell.length[a];
  }
  std::printf("particles %zu, steps %d, threads %d, wall %.3f s, %.3g particle-steps/s\n", s.particles.size(),
              steps, world.executor().threads(), wall, double(n) * steps / wall);
  std::printf("cell L = (%.6f, %.6f, %.6f) m, axial log strain eps3 = %.6f\n", s.cell.length[0], s.cell.length[1],
              s.cell.length[2], -std::log(s.cell.length[2] / s.cell.length0[2]));
  std::printf("momentum = (%.3e, %.3e, %.3e) kg m/s, kinetic energy (fluctuating) = %.6e J, all wrapped: %s\n",
              momentum[0], momentum[1], momentum[2], kinetic, inside ? "yes" : "NO");
  return inside ? 0 : 1;
}
