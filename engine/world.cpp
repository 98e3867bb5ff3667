#include "engine/world.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>

namespace sandcell {

void validate(const Model& model, const State& state) {
  if (!(model.dt > 0.0) || !std::isfinite(model.dt))
    throw std::invalid_argument("dt = " + std::to_string(model.dt) + ": must be a finite value > 0 s");
  if (model.materials.empty()) throw std::invalid_argument("materials: at least one material is required");
  if (model.time_step.rule == TimeStepRule::stiffness) {
    const TimeStepSettings& t = model.time_step;
    if (!(t.safety > 0.0 && t.safety <= std::sqrt(2.0)))
      throw std::invalid_argument("time_step.safety = " + std::to_string(t.safety) +
                                  ": must be in (0, sqrt 2] (sqrt 2: the stability limit of an undamped linear network)");
    if (t.interval < 1)
      throw std::invalid_argument("time_step.interval = " + std::to_string(t.interval) + ": must be >= 1 step");
    if (!(t.max_dt > 0.0) || !std::isfinite(t.max_dt))
      throw std::invalid_argument("time_step.max_dt = " + std::to_string(t.max_dt) + ": must be a finite value > 0 s");
    if (!(state.clock.dt >= 0.0) || !std::isfinite(state.clock.dt))
      throw std::invalid_argument("clock.dt = " + std::to_string(state.clock.dt) + ": must be a finite value >= 0 s");
  }
  for (std::size_t m = 0; m < model.materials.size(); ++m) {
    const Material& mat = model.materials[m];
    const std::string key = "materials[" + std::to_string(m) + "].";
    if (!(mat.density > 0.0))
      throw std::invalid_argument(key + "density = " + std::to_string(mat.density) + ": must be > 0 kg/m^3");
    if (!(mat.young > 0.0))
      throw std::invalid_argument(key + "young = " + std::to_string(mat.young) + ": must be > 0 Pa");
    if (!(mat.poisson > -1.0 && mat.poisson < 0.5))
      throw std::invalid_argument(key + "poisson = " + std::to_string(mat.poisson) + ": must be in (-1, 0.5)");
    if (!(mat.restitution > 0.0 && mat.restitution <= 1.0))
      throw std::invalid_argument(key + "restitution = " + std::to_string(mat.restitution) + ": must be in (0, 1]");
    if (!(mat.friction >= 0.0))
      throw std::invalid_argument(key + "friction = " + std::to_string(mat.friction) + ": must be >= 0");
    if (!(mat.rolling_friction >= 0.0))
      throw std::invalid_argument(key + "rolling_friction = " + std::to_string(mat.rolling_friction) +
                                  ": must be >= 0");
  }
  if (model.contact.enabled && !(model.contact.skin > 0.0))
    throw std::invalid_argument("contact.skin = " + std::to_string(model.contact.skin) + ": must be > 0 m");
  if (model.contact.sort_interval < 0)
    throw std::invalid_argument("contact.sort_interval = " + std::to_string(model.contact.sort_interval) +
                                ": must be >= 0 steps (0: never)");
  if (!(model.contact.rolling_damping >= 0.0))
    throw std::invalid_argument("contact.rolling_damping = " + std::to_string(model.contact.rolling_damping) +
                                ": must be >= 0");
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
  // A cell that shears: finite tilts and shear rates, whole flips (a cell too thin between its faces
  // for the spheres is the broadphase's to name, with the widths, at the first list build).
  for (int a = 0; a < 3; ++a) {
    const auto check = [&](const char* key, double v, bool ok, const char* allowed) {
      if (!ok)
        throw std::invalid_argument(std::string("cell.") + key + "[" + k_shear_names[a] + "] = " + std::to_string(v) +
                                    ": " + allowed);
    };
    check("tilt", state.cell.tilt[a], std::isfinite(state.cell.tilt[a]), "must be finite (m)");
    check("tilt0", state.cell.tilt0[a], std::isfinite(state.cell.tilt0[a]), "must be finite (m)");
    check("shear_rate", state.cell.shear_rate[a], std::isfinite(state.cell.shear_rate[a]), "must be finite (1/s)");
    const double n = state.cell.flip[a];
    check("flip", n, std::isfinite(n) && n == std::round(n), "must be a whole number");
  }
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
State validated(State s, const Model& m) {
  validate(m, s);
  if (s.particles.reference_position.size() != s.particles.size())
    s.particles.reference_position.resize(s.particles.size());
  return s;
}
}  // namespace

World::World(Model model, State state, std::vector<SystemSpec> systems, ExecutorConfig exec, bool initial_forces)
    : model_(finalized(std::move(model))),
      state_(validated(std::move(state), model_)),
      exec_(exec),
      graph_(std::move(systems), exec_),
      batching_(can_batch(graph_)) {
  for (std::size_t k = 0; k < graph_.size(); ++k)  // each system's own settings (e.g. the servo's)
    if (graph_.system(k).check) graph_.system(k).check(model_);
  if (model_.time_step.rule == TimeStepRule::stiffness) {
    bool bounded = false;
    for (std::size_t k = 0; k < graph_.size(); ++k) bounded = bounded || bool(graph_.system(k).stable_step);
    if (!bounded)
      throw std::invalid_argument(
          "time_step.rule = stiffness: no scheduled system bounds the step (contacts disabled?): use a fixed step");
    // A state that carries the step in effect (a checkpoint taken between updates) continues with it;
    // one without (a fresh run, a sample prepared at a fixed step) gets the rule's at the end of
    // construction (first_time_step).
    if (state_.clock.dt > 0.0) model_.dt = state_.clock.dt;
  }
  for (std::size_t k = 0; k < graph_.size(); ++k)
    if (graph_.system(k).prepare) graph_.system(k).prepare(model_, state_);
  if (!initial_forces) {
    restore();
    first_time_step();
    return;
  }
  // Forces of the initial configuration (LAMMPS `setup`): the systems' setup hooks in reference
  // order (list build, contact law with history frozen, gather).
  for (std::size_t k = 0; k < graph_.size(); ++k) {
    const SystemSpec& s = graph_.system(k);
    if (!s.setup) continue;
    run_hook(s, s.setup, model_, state_, *scratch_, exec_);
    check_health();
  }
  first_time_step();
}

void World::first_time_step() {
  // An adaptive step starting afresh (no step in effect yet): the rule's value for the state as it
  // is, which the first step's update would give too, so that what is read before stepping (an
  // output row) is the step the run takes.
  if (model_.time_step.rule == TimeStepRule::stiffness && state_.clock.dt == 0.0) update_time_step();
}

void World::restore() {
  // The state holds its list and the forces of its last step (a checkpoint, or the previous
  // stage of a test): the systems rebuild only their scratch from it (e.g. the gather index from
  // the pair list). Nothing else is recomputed, so continuing from here is bitwise the same as
  // never stopping.
  for (std::size_t k = 0; k < graph_.size(); ++k) {
    const SystemSpec& s = graph_.system(k);
    if (!s.restore) continue;
    const AccessSets sets{s.name, s.reads, s.writes};
    AccessScope scope(sets);
    s.restore(model_, state_, *scratch_);
  }
}

void World::reset(const State& state) {
  // Copy assignment reuses a vector's buffer when its capacity suffices (the particle arrays: the
  // same sizes), so views into them stay valid; the Python module relies on it and tests it.
  state_ = state;
  if (model_.time_step.rule == TimeStepRule::stiffness && state_.clock.dt > 0.0) model_.dt = state_.clock.dt;
  scratch_ = std::make_unique<Scratch>();
  restore();
  first_time_step();
}

void World::check_health() const {
  if (!scratch_->error.empty())
    throw SimulationError("step " + std::to_string(state_.clock.step) + ": " + scratch_->error);
}

void World::step(std::uint64_t n) {
  step_until(n, [](Cell&, const Clock&) { return false; });
}

std::uint64_t World::step_until(std::uint64_t n, FunctionRef<bool(Cell&, const Clock&)> stop) {
  std::uint64_t done = 0;
  try {
    scratch_->batching = batching_;
    while (done < n) {
      if (model_.time_step.rule == TimeStepRule::stiffness &&
          state_.clock.step % static_cast<std::uint64_t>(model_.time_step.interval) == 0)
        update_time_step();
      exec_.begin_step();
      graph_.run(model_, state_, *scratch_);
      exec_.end_step();
      ++state_.clock.step;
      state_.clock.time += model_.dt;
      ++done;
      check_health();
      if (stop(state_.cell, state_.clock)) break;
    }
  } catch (...) {
    flush();  // the state handed back is the end of a step, as without the deferral
    throw;
  }
  flush();
  return done;
}

void World::update_time_step() {
  // The state as after one step per call (the deferred half kick applied with the step it closes),
  // so the rule sees the same state whatever the chunking of the calls.
  flush();
  scratch_->batching = batching_;
  double bound = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < graph_.size(); ++k) {
    const SystemSpec& s = graph_.system(k);
    if (!s.stable_step) continue;
    const AccessSets sets{s.name, s.stable_step_reads, 0};
    AccessScope scope(sets);
    bound = std::min(bound, s.stable_step(model_, state_));
  }
  const double dt = std::min(model_.time_step.max_dt, model_.time_step.safety * bound);
  if (!(dt > 0.0) || !std::isfinite(dt))
    throw SimulationError("step " + std::to_string(state_.clock.step) + ": the stiffness time step is " +
                          std::to_string(dt) + " s (a contact stiffness not finite?)");
  model_.dt = dt;
  state_.clock.dt = dt;
}

void World::flush() {
  scratch_->batching = false;
  for (std::size_t k = 0; k < graph_.size(); ++k)
    if (graph_.system(k).flush) graph_.run_hook(k, graph_.system(k).flush, model_, state_, *scratch_);
}

bool World::can_batch(const StepGraph& graph) {
  // Leaving a system's work to the next run of the system it names is exact only if nothing runs
  // between them: the deferring system must come after every other system of the step, and the
  // absorbing one before every other (a system unordered with them does not conflict with them,
  // so it neither reads nor writes what they touch).
  const std::size_t n = graph.size();
  bool any = false;
  for (std::size_t last = 0; last < n; ++last) {
    const SystemSpec& s = graph.system(last);
    if (!s.flush || s.deferred_to.empty()) continue;
    const std::size_t first = graph.find(s.deferred_to);
    if (first == n) return false;
    for (std::size_t k = 0; k < n; ++k) {
      if (k != first && graph.ordered(k, first)) return false;
      if (k != last && graph.ordered(last, k)) return false;
    }
    any = true;
  }
  return any;
}

}  // namespace sandcell
