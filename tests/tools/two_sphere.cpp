// two-sphere: a two-sphere collision (tests/support/two_sphere.hpp), one CSV row per step, for the
// side-by-side comparison with LIGGGHTS (experiments/2026-11-25-hooke-vs-liggghts: its script's docstring is
// the contract):
//   two-sphere --radius R --density RHO --young E --poisson NU --restitution E --friction MU
//              --vn VN --vt VT --vchar VC --dt DT --steps N --gap GAP [--normal hertz|hooke]
//              [--tangential history|incremental|mindlin_rescale] [--rotation 0]
#include "engine/world.hpp"
#include "support/two_sphere.hpp"
#include "systems/catalogue.hpp"
#include "systems/contact_pass.hpp"

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
    if (const auto it = args.find("--tangential"); it != args.end()) {  // a registered name (contact_pass.hpp)
      const auto law = tangential_law(it->second);
      if (!law) throw std::invalid_argument("--tangential " + it->second + ": not a registered tangential law");
      s.tangential = *law;
      args.erase(it);
    }
    // --rotation 0: the spheres never turn (inverse inertia 0), as LAMMPS `fix nve` (no nve/sphere): the
    // tangential law compared alone, without the codes' levers (LAMMPS: R in the slip velocity).
    double rotation = 1.0;
    number("--rotation", rotation);
    if (!args.empty()) {
      std::fprintf(stderr, "two-sphere: unknown option %s\n", args.begin()->first.c_str());
      return 2;
    }
    const Model model = test::two_sphere_model(s);
    State initial = test::two_sphere_state(model, s);
    if (rotation == 0.0)
      for (double& inv : initial.particles.inv_inertia) inv = 0.0;
    World world(model, std::move(initial), systems_for(model), ExecutorConfig{Backend::serial, 1});
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
