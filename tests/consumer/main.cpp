// Builds a two-sphere scene through the installed headers and steps it: v = 1 m/s for 1000 steps
// of 1e-4 s moves the sphere 0.1 m.
#include <sandcell/io.hpp>
#include <sandcell/world.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>

int main(int, char** argv) {
  sandcell::Model model;
  model.dt = 1e-4;
  model.materials.push_back(sandcell::Material{});
  sandcell::State state;
  state.cell.length = state.cell.length0 = sandcell::Vec3::Constant(1.0);
  sandcell::add_sphere(state, model, 0, sandcell::Vec3(0.2, 0.5, 0.5), 0.01, 0);
  sandcell::add_sphere(state, model, 1, sandcell::Vec3(0.8, 0.5, 0.5), 0.01, 0);
  state.particles.velocity[0] = sandcell::Vec3(1.0, 0.0, 0.0);
  sandcell::World world(model, state, sandcell::systems_for(model),
                        sandcell::ExecutorConfig{sandcell::Backend::tbb, 2});
  world.step(1000);
  const double x = world.state().particles.position[0].x();
  std::printf("consumer: x = %.12f\n", x);
  // A checkpoint round trip, so that the consumer links HDF5 through the package config.
  // Beside the executable: its build tree is this run's own.
  const std::filesystem::path ckpt = std::filesystem::absolute(argv[0]).parent_path() / "consumer_ckpt.h5";
  sandcell::write_checkpoint(ckpt, world.state());
  const double x_back = sandcell::read_checkpoint(ckpt).particles.position[0].x();
  std::filesystem::remove(ckpt);
  return std::abs(x - 0.3) < 1e-12 && x_back == x ? 0 : 1;
}
