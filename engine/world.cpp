#include "engine/world.hpp"

#include "systems/broadphase.hpp"
#include "systems/force_gather.hpp"
#include "systems/hertz_mindlin.hpp"
#include "systems/homogenizer.hpp"
#include "systems/integrate.hpp"
#include "systems/servo.hpp"
#include "systems/spatial_sort.hpp"
#include "systems/wrap.hpp"

#include <cmath>
#include <cstdlib>
#include <string>

namespace sandcell {

std::vector<SystemSpec> build_systems(const Model& model) {
  std::vector<SystemSpec> systems;
  systems.push_back(make_system<IntegrateInitial>());
  if (!model.contact.enabled) systems.push_back(make_system<Wrap>());
  if (model.contact.enabled) {
    if (model.contact.sort_interval > 0) systems.push_back(make_system<SpatialSort>());
    systems.push_back(make_system<Broadphase>());
    systems.push_back(make_system<HertzMindlin>());
    systems.push_back(make_system<ForceGather>());
  }
  if (model.servo.enabled) {
    systems.push_back(make_system<Homogenizer>());
    systems.push_back(make_system<Servo>());
  }
  systems.push_back(make_system<IntegrateFinal>());
  return systems;
}

void validate(const ServoSettings& servo) {
  const auto fail = [](const std::string& key, double value, const std::string& allowed) {
    throw std::invalid_argument("servo." + key + " = " + std::to_string(value) + ": " + allowed);
  };
  if (!(servo.gain > 0.0) || !std::isfinite(servo.gain)) fail("gain", servo.gain, "must be a finite value > 0 1/s");
  if (!(servo.max_rate > 0.0) || !std::isfinite(servo.max_rate))
    fail("max_rate", servo.max_rate, "must be a finite value > 0 1/s");
  if (servo.interval < 1) fail("interval", servo.interval, "must be >= 1 step");
  if (!(servo.integral_time >= 0.0) || !std::isfinite(servo.integral_time))
    fail("integral_time", servo.integral_time, "must be a finite value >= 0 s (0: no integral term)");
  if (!(servo.b >= 0.0 && servo.b <= 1.0)) fail("b", servo.b, "must be in [0, 1]");
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(servo.strain_rate[k]))
      fail("strain_rate[" + std::to_string(k) + "]", servo.strain_rate[k], "must be finite");
  if (!(servo.inertial_number >= 0.0) || !std::isfinite(servo.inertial_number))
    fail("inertial_number", servo.inertial_number, "must be a finite value >= 0 (0: strain_rate as given)");
  if (servo.inertial_number > 0.0) {
    if (!(servo.d50 > 0.0) || !std::isfinite(servo.d50)) fail("d50", servo.d50, "must be > 0 m with inertial_number > 0");
    if (!(servo.density > 0.0) || !std::isfinite(servo.density))
      fail("density", servo.density, "must be > 0 kg/m^3 with inertial_number > 0");
  }
  const bool any_stress = servo.control[0] == AxisControl::stress || servo.control[1] == AxisControl::stress ||
                          servo.control[2] == AxisControl::stress;
  if (!any_stress) return;
  switch (servo.path) {
    case StressPath::isotropic:
    case StressPath::constant_p_b:
      if (!(servo.p > 0.0)) fail("p", servo.p, "must be > 0 Pa (compression positive)");
      break;
    case StressPath::constant_sigma3_b:
      if (!(servo.sigma3 > 0.0)) fail("sigma3", servo.sigma3, "must be > 0 Pa (compression positive)");
      break;
    case StressPath::fixed:
      for (int k = 0; k < 3; ++k)
        if (servo.control[k] == AxisControl::stress && !(servo.target[k] > 0.0))
          fail("target[" + std::to_string(k) + "]", servo.target[k], "must be > 0 Pa on a stress-controlled axis");
      break;
  }
  if (servo.path != StressPath::fixed && servo.path != StressPath::isotropic &&
      servo.control[0] != AxisControl::strain)
    throw std::invalid_argument("servo.control[0] = stress: the constant-b paths drive axis 1 by strain");
}

void validate(const Model& model, const State& state) {
  if (!(model.dt > 0.0) || !std::isfinite(model.dt))
    throw std::invalid_argument("dt = " + std::to_string(model.dt) + ": must be a finite value > 0 s");
  if (model.materials.empty()) throw std::invalid_argument("materials: at least one material is required");
  for (std::size_t m = 0; m < model.materials.size(); ++m) {
    const Material& mat = model.materials[m];
    const std::string key = "materials[" + std::to_string(m) + "].";
    if (!(mat.density > 0.0)) throw std::invalid_argument(key + "density = " + std::to_string(mat.density) + ": must be > 0 kg/m^3");
    if (!(mat.young > 0.0)) throw std::invalid_argument(key + "young = " + std::to_string(mat.young) + ": must be > 0 Pa");
    if (!(mat.poisson > -1.0 && mat.poisson < 0.5))
      throw std::invalid_argument(key + "poisson = " + std::to_string(mat.poisson) + ": must be in (-1, 0.5)");
    if (!(mat.restitution > 0.0 && mat.restitution <= 1.0))
      throw std::invalid_argument(key + "restitution = " + std::to_string(mat.restitution) + ": must be in (0, 1]");
    if (!(mat.friction >= 0.0)) throw std::invalid_argument(key + "friction = " + std::to_string(mat.friction) + ": must be >= 0");
    if (!(mat.rolling_friction >= 0.0))
      throw std::invalid_argument(key + "rolling_friction = " + std::to_string(mat.rolling_friction) + ": must be >= 0");
  }
  if (model.contact.enabled && !(model.contact.skin > 0.0))
    throw std::invalid_argument("contact.skin = " + std::to_string(model.contact.skin) + ": must be > 0 m");
  if (model.contact.sort_interval < 0)
    throw std::invalid_argument("contact.sort_interval = " + std::to_string(model.contact.sort_interval) +
                                ": must be >= 0 steps (0: never)");
  if (!(model.contact.rolling_damping >= 0.0))
    throw std::invalid_argument("contact.rolling_damping = " + std::to_string(model.contact.rolling_damping) +
                                ": must be >= 0");
  if (model.servo.enabled) validate(model.servo);
  for (std::size_t k = 0; k < state.particles.size(); ++k) {
    const Particles& p = state.particles;
    const auto fail = [&](const char* what, const std::string& value, const std::string& allowed) {
      throw std::invalid_argument("particle " + std::to_string(p.id[k]) + ": " + what + " = " + value + ": " + allowed);
    };
    const auto vec = [](const Vec3& v) {
      return "(" + std::to_string(v[0]) + ", " + std::to_string(v[1]) + ", " + std::to_string(v[2]) + ")";
    };
    if (!(p.radius[k] > 0.0) || !std::isfinite(p.radius[k]))
      fail("radius", std::to_string(p.radius[k]), "must be a finite value > 0 m");
    if (!p.position[k].allFinite()) fail("position", vec(p.position[k]), "must be finite");
    if (!p.velocity[k].allFinite()) fail("velocity", vec(p.velocity[k]), "must be finite");
    if (!p.angular_velocity[k].allFinite()) fail("angular velocity", vec(p.angular_velocity[k]), "must be finite");
    if (p.material[k] >= model.materials.size())
      fail("material index", std::to_string(p.material[k]),
           "not in [0, " + std::to_string(model.materials.size()) + ")");
  }
  for (int a = 0; a < 3; ++a)
    if (!(state.cell.length[a] > 0.0) || !std::isfinite(state.cell.length[a]))
      throw std::invalid_argument("cell length " + std::to_string(a) + " = " + std::to_string(state.cell.length[a]) +
                                  ": must be > 0 m");
  // The broadphase builds images of -1, 0 or 1 per axis (the cell is wider than the cutoff); the
  // contact pass takes the shift from a table of those 27 (PairConstants).
  const ContactPairs& pairs = state.contacts.pairs;
  for (std::size_t k = 0; k < pairs.image.size(); ++k) {
    const Image& img = pairs.image[k];
    if (std::abs(img[0]) > 1 || std::abs(img[1]) > 1 || std::abs(img[2]) > 1)
      throw std::invalid_argument("contact " + std::to_string(k) + " (ids " + std::to_string(pairs.id_i[k]) + ", " +
                                  std::to_string(pairs.id_j[k]) + "): image = (" + std::to_string(img[0]) + ", " +
                                  std::to_string(img[1]) + ", " + std::to_string(img[2]) +
                                  "): each component must be -1, 0 or 1");
  }
}

namespace {
Model finalized(Model m) {
  m.finalize();
  return m;
}
State prepared(State s, const Model& m) {
  validate(m, s);
  // Only the laws with a stored moment keep one (cdt has none).
  s.contacts.has_rolling = m.contact.enabled &&
                           (m.contact.rolling == RollingModel::epsd2 || m.contact.rolling == RollingModel::epsd);
  if (!s.contacts.has_rolling) s.contacts.rolling.clear();
  if (s.particles.reference_position.size() != s.particles.size()) s.particles.reference_position.resize(s.particles.size());
  return s;
}
}  // namespace

World::World(Model model, State state, ExecutorConfig exec, bool initial_forces)
    : World(model, std::move(state), build_systems(model), exec, initial_forces) {}

World::World(Model model, State state, std::vector<SystemSpec> systems, ExecutorConfig exec, bool initial_forces)
    : model_(finalized(std::move(model))),
      state_(prepared(std::move(state), model_)),
      exec_(exec),
      graph_(std::move(systems), exec_),
      defer_kick_(can_defer_kick(graph_)) {
  if (graph_.find(Broadphase::name) == graph_.size()) return;
  if (!initial_forces) {
    // The state holds its list and the forces of its last step (a checkpoint, or the previous
    // stage of a test): only the gather index, which is scratch, is rebuilt from the pair list.
    // Nothing else is recomputed, so continuing from here is bitwise the same as never stopping.
    rebuild_gather_index(state_.contacts.pairs, state_.particles.size(), scratch_.gather);
    rebuild_pair_constants(state_.contacts.pairs, state_.particles.radius, state_.particles.mass, scratch_.pair);
    return;
  }
  // Forces of the initial configuration (LAMMPS `setup`): list build, contact law, gather, with
  // contact history frozen. Only the systems present in the graph are run.
  scratch_.setup = true;
  build_neighbor_list(model_, state_, scratch_, exec_);
  check_health();
  for (std::string_view name : {HertzMindlin::name, ForceGather::name}) {
    const std::size_t k = graph_.find(name);
    if (k < graph_.size()) run_system(graph_.system(k), model_, state_, scratch_, exec_);
  }
  scratch_.setup = false;
}

void World::check_health() const {
  if (!scratch_.broadphase.error.empty())
    throw SimulationError("step " + std::to_string(state_.clock.step) + ": " + scratch_.broadphase.error);
}

void World::step(std::uint64_t n) {
  step_until(n, [](Cell&, const Clock&) { return false; });
}

std::uint64_t World::step_until(std::uint64_t n, FunctionRef<bool(Cell&, const Clock&)> stop) {
  std::uint64_t done = 0;
  try {
    scratch_.defer_final_kick = defer_kick_;
    while (done < n) {
      graph_.run(model_, state_, scratch_);
      ++state_.clock.step;
      state_.clock.time += model_.dt;
      ++done;
      check_health();
      if (stop(state_.cell, state_.clock)) break;
    }
  } catch (...) {
    finish_kick();  // the state handed back is the end of a step, as without the deferral
    throw;
  }
  finish_kick();
  return done;
}

void World::finish_kick() {
  scratch_.defer_final_kick = false;
  if (!scratch_.kick_pending) return;
  scratch_.kick_pending = false;
  graph_.run_one(graph_.find(IntegrateFinal::name), model_, state_, scratch_);
}

bool World::can_defer_kick(const StepGraph& graph) {
  // Deferring integrate_final's kick to the next integrate_initial is exact only if nothing runs
  // between them: integrate_final must come after every other system of the step, and
  // integrate_initial before every other (a system unordered with them does not conflict with
  // them, so it neither reads the velocities nor writes what the kicks read).
  const std::size_t n = graph.size();
  const std::size_t first = graph.find(IntegrateInitial::name), last = graph.find(IntegrateFinal::name);
  if (first == n || last == n) return false;
  for (std::size_t k = 0; k < n; ++k) {
    if (k != first && graph.ordered(k, first)) return false;
    if (k != last && graph.ordered(last, k)) return false;
  }
  return true;
}

}  // namespace sandcell
