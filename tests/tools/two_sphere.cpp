// two-sphere: a two-sphere collision (tests/support/two_sphere.hpp), one CSV row per step, for the
// side-by-side comparison with LIGGGHTS (experiments/2026-11-25-hooke-vs-liggghts: its script's docstring is
// the contract):
//   two-sphere --radius R --density RHO --young E --poisson NU --restitution E --friction MU
//              --vn VN --vt VT --vchar VC --dt DT --steps N --gap GAP [--normal hertz|hooke]
#include "engine/world.hpp"
#include "support/two_sphere.hpp"
#include "systems/catalogue.hpp"

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <map>
#include <string>

using namespace sandcell;

int main(int argc, char** argv) {
  std::map<std::string, std::string> args;
  for (int k = 1; k + 1 < argc; k += 2) args[argv[k]] = argv[k + 1];
  if (argc % 2 == 0) {
    std::fprintf(stderr, "two-sphere: options come in pairs (--key value)\n");
    return 2;
  }
  test::TwoSphere s;
  long steps = 0;
  try {
    const auto number = [&](const char* key, double& out) {
      if (const auto it = args.find(key); it != args.end()) {
        out = std::stod(it->second);
        args.erase(it);
      }
    };
    number("--radius", s.radius);
    number("--density", s.density);
    number("--young", s.young);
    number("--poisson", s.poisson);
    number("--restitution", s.restitution);
    number("--friction", s.friction);
    number("--vn", s.v_n);
    number("--vt", s.v_t);
    number("--vchar", s.v_char);
    number("--dt", s.dt);
    number("--gap", s.gap);
    double n = 0.0;
    number("--steps", n);
    steps = static_cast<long>(n);
    if (const auto it = args.find("--normal"); it != args.end()) {
      s.normal = it->second;
      args.erase(it);
    }
    if (!args.empty()) {
      std::fprintf(stderr, "two-sphere: unknown option %s\n", args.begin()->first.c_str());
      return 2;
    }
    const Model model = test::two_sphere_model(s);
    World world(model, test::two_sphere_state(model, s), systems_for(model), ExecutorConfig{Backend::serial, 1});
    const double c = test::two_sphere_centre(s);
    std::printf("t,x1,x2,z1,z2,v1x,v2x,v1z,v2z,w1y,w2y,f1x,f1z\n");
    for (long k = 1; k <= steps; ++k) {
      world.step(1);
      const Particles& p = world.state().particles;
      std::printf("%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n",
                  static_cast<double>(k) * s.dt, p.position[0].x() - c, p.position[1].x() - c, p.position[0].z() - c,
                  p.position[1].z() - c, p.velocity[0].x(), p.velocity[1].x(), p.velocity[0].z(), p.velocity[1].z(),
                  p.angular_velocity[0].y(), p.angular_velocity[1].y(), p.force[0].x(), p.force[0].z());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "two-sphere: %s\n", e.what());
    return 2;
  }
  return 0;
}
