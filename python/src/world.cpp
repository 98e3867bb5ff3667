// sandcell.World (docs/python.md): a World seen from Python, and its lifetime rules.
//  - Reentrancy. While a World steps or measures (the GIL released), every call on it but `model`
//    raises RuntimeError; one made by the step's own Python callback (its stress path or a stop
//    function) also fails that step, even if the callback catches the error.
//  - Exceptions. A World with a custom path keeps a snapshot of its state, taken between calls and
//    renewed every k_replay_steps steps, and the path's answers since (the tape). An exception that
//    interrupts a step (the path raised, or returned garbage) puts the World back at the start of
//    that step: the snapshot, then the steps since replayed with the recorded answers (the path is
//    not called again), bitwise the state a clean run had there. A SimulationError (a run gone
//    unstable) is raised after its step, whose end the World keeps, as in C++.
//  - Views. The particle arrays never move in a World's life (the spatial sort permutes them in
//    place, a rollback assigns them in place), nor does the cell: World.particles and World.cell are
//    live views, valid as long as they exist (they keep the World alive). The contact arrays move
//    at every neighbour-list build: World.contacts gives copies.
#include "common.hpp"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <stdexcept>
#include <string>
#include <utility>

namespace sandcell::python {

namespace {

// ---- views --------------------------------------------------------------------------------------

// A read-only NumPy array of v: a view into owner's memory (which it keeps alive), or a copy when
// owner is a null handle (pybind11 copies the data of an array given no base).
template <class T>
py::array view(py::handle owner, const std::vector<T>& v) {
  py::array a;
  if constexpr (std::is_same_v<T, Vec3>) {
    const auto* data = reinterpret_cast<const double*>(v.data());
    a = py::array(py::dtype::of<double>(), {static_cast<py::ssize_t>(v.size()), py::ssize_t{3}},
                  {static_cast<py::ssize_t>(sizeof(T)), static_cast<py::ssize_t>(sizeof(double))}, data, owner);
  } else if constexpr (std::is_same_v<T, Image>) {
    a = py::array(py::dtype::of<std::int8_t>(), {static_cast<py::ssize_t>(v.size()), py::ssize_t{3}},
                  {static_cast<py::ssize_t>(sizeof(Image)), py::ssize_t{1}},
                  reinterpret_cast<const std::int8_t*>(v.data()), owner);
  } else {
    a = py::array(py::dtype::of<T>(), {static_cast<py::ssize_t>(v.size())}, {static_cast<py::ssize_t>(sizeof(T))},
                  v.data(), owner);
  }
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

py::array vec_view(py::handle owner, const Vec3& v) {
  py::array a(py::dtype::of<double>(), {py::ssize_t{3}}, {py::ssize_t{sizeof(double)}}, v.data(), owner);
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

}  // namespace

py::dict particle_views(py::handle owner, const State& s) {
  const Particles& p = s.particles;
  py::dict d;
  d["id"] = view(owner, p.id);
  d["position"] = view(owner, p.position);
  d["velocity"] = view(owner, p.velocity);
  d["angular_velocity"] = view(owner, p.angular_velocity);
  d["force"] = view(owner, p.force);
  d["torque"] = view(owner, p.torque);
  d["radius"] = view(owner, p.radius);
  d["mass"] = view(owner, p.mass);
  d["inv_inertia"] = view(owner, p.inv_inertia);
  d["material"] = view(owner, p.material);
  d["reference_position"] = view(owner, p.reference_position);
  return d;
}

py::dict contact_views(py::handle owner, const State& s) {
  const Contacts& c = s.contacts;
  py::dict d;
  d["id_i"] = view(owner, c.pairs.id_i);
  d["id_j"] = view(owner, c.pairs.id_j);
  d["i"] = view(owner, c.pairs.i);
  d["j"] = view(owner, c.pairs.j);
  d["image"] = view(owner, c.pairs.image);
  d["force"] = view(owner, c.forces.force);
  d["torque_i"] = view(owner, c.forces.torque_i);
  d["torque_j"] = view(owner, c.forces.torque_j);
  d["tangential"] = view(owner, c.tangential);
  if (c.has_tangential_radius) d["tangential_radius"] = view(owner, c.tangential_radius);
  if (c.has_rolling) d["rolling"] = view(owner, c.rolling);
  return d;
}

// Every 3-vector of the cell (components/cell.hpp): lengths, tilts (xy, xz, yz) of H and H0, flip
// counts of N (integers, as doubles), rates and shear rates, the servo's integrals.
py::dict cell_views(py::handle owner, const State& s) {
  static constexpr std::pair<const char*, Vec3 Cell::*> k_vectors[] = {{"length", &Cell::length},
                                                                       {"length0", &Cell::length0},
                                                                       {"rate", &Cell::rate},
                                                                       {"servo_integral", &Cell::servo_integral},
                                                                       {"tilt", &Cell::tilt},
                                                                       {"tilt0", &Cell::tilt0},
                                                                       {"flip", &Cell::flip},
                                                                       {"shear_rate", &Cell::shear_rate},
                                                                       {"shear_integral", &Cell::shear_integral}};
  py::dict d;
  for (const auto& [name, member] : k_vectors) d[name] = vec_view(owner, s.cell.*member);
  return d;
}

namespace {

// ---- the step's Python callbacks ------------------------------------------------------------------

// A Python error raised inside a path called from the step loop: the error itself waits in the Hub
// until the step returns to Python (the servo may run on another thread; this crosses TBB).
struct PathError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Marks the current thread as running one of this World's Python callbacks (with the GIL held).
struct CallbackScope {
  Hub& hub;
  CallbackScope(Hub& h, const char* kind) : hub(h) {
    h.callback = std::this_thread::get_id();
    h.callback_kind = kind;
  }
  ~CallbackScope() { hub.callback = std::thread::id(); }
  CallbackScope(const CallbackScope&) = delete;
  CallbackScope& operator=(const CallbackScope&) = delete;
};

// Raises (as a Python error, inside the callback) the reentrant call the callback made, if any:
// a callback that caught the RuntimeError still fails the step.
void raise_reentry(const Hub& h) {
  if (h.reentry.empty()) return;
  PyErr_SetString(PyExc_RuntimeError, h.reentry.c_str());
  throw py::error_already_set();
}

// The World's custom path as its servo calls it: the path given (a Python callable or a C++
// function), its answers recorded on the tape, or, in a rollback's replay, the tape's answers.
struct WorldPath {
  PathFunction inner;  // a C++ path, or
  py::object fn;       // a Python callable
  std::shared_ptr<Hub> hub;

  PathTargets operator()(const PathInput& in) const {
    Hub& h = *hub;
    if (h.replaying) {
      if (h.next >= h.tape.size())
        throw std::logic_error("replay: past the " + std::to_string(h.tape.size()) + " recorded answers of the path");
      return h.tape[h.next++];
    }
    PathTargets t = fn ? call(in) : inner(in);
    if (h.recording) h.tape.push_back(t);
    return t;
  }

  PathTargets call(const PathInput& in) const {
    py::gil_scoped_acquire gil;
    Hub& h = *hub;
    CallbackScope scope(h, "stress path (servo.custom)");
    try {
      const py::object result = fn(in);
      raise_reentry(h);
      return targets_from_python(result);
    } catch (py::error_already_set& e) {
      std::string what = e.what();
      h.error = std::move(e);
      throw PathError("stress path raised: " + what);
    }
  }
};

// ---- stepping -------------------------------------------------------------------------------------

// The most steps replayed by a rollback: the snapshot is renewed at least this often (a state copy
// per 1000 steps, beside the steps themselves: nothing).
constexpr std::uint64_t k_replay_steps = 1000;

// Marks the World busy for the length of a call that steps or measures it.
struct Busy {
  PyWorld& w;
  Busy(PyWorld& world, const char* what) : w(world) {
    w.check(what);
    w.busy = what;
    w.hub->reentry.clear();
  }
  ~Busy() { w.busy.clear(); }
  Busy(const Busy&) = delete;
  Busy& operator=(const Busy&) = delete;
};

void take_snapshot(PyWorld& w) {
  {
    py::gil_scoped_release release;  // the World is busy: nothing else touches it
    if (w.snapshot)
      *w.snapshot = w.world->state();  // reuses the snapshot's buffers
    else
      w.snapshot.emplace(w.world->state());
  }
  w.hub->tape.clear();
  w.snapshot_stale = false;
}

// After an exception that interrupted a step: back to the start of that step, or the World marked
// broken when that cannot be done.
void roll_back(PyWorld& w) {
  Hub& h = *w.hub;
  const std::uint64_t step = w.world->state().clock.step;  // the interrupted step's clock did not advance
  const std::string undone = "an exception interrupted step " + std::to_string(step) + ", ";
  if (!w.transactional || !w.snapshot || w.snapshot_stale) {
    w.broken = undone +
               "which this World cannot undo (it has no custom path, whose answers it records); it holds "
               "that step half done: make a new World, e.g. from a checkpoint";
    return;
  }
  try {
    py::gil_scoped_release release;
    w.world->reset(*w.snapshot);
    h.replaying = true;
    h.next = 0;
    if (step > w.snapshot->clock.step) w.world->step(step - w.snapshot->clock.step);
    h.replaying = false;
  } catch (const std::exception& e) {
    h.replaying = false;
    w.broken = undone + "and replaying the steps before it from the snapshot failed (" + e.what() +
               "): make a new World, e.g. from a checkpoint";
    return;
  }
  if (w.world->state().clock.step != step) {
    w.broken = undone + "and the replay stopped at step " + std::to_string(w.world->state().clock.step) +
               ": make a new World, e.g. from a checkpoint";
    return;
  }
  h.tape.resize(h.next);  // the interrupted step's answer, if it gave one, is asked again
}

// Raises the exception that interrupted a step: a path's own Python error, else as it came.
[[noreturn]] void rethrow_step_error(Hub& hub, const std::exception_ptr& e) {
  try {
    std::rethrow_exception(e);
  } catch (const PathError&) {
    if (!hub.error) throw;
    py::error_already_set error = std::move(*hub.error);
    hub.error.reset();
    throw error;
  }
}

// Advances at most n steps, stopping after the first for which stop(cell, clock) is true; the
// GIL is released while the World steps. With a custom path the call is cut at the snapshot's
// renewals (where a call stops changes no bit: World::step_until).
template <class Stop>
std::uint64_t advance(PyWorld& w, const char* what, std::uint64_t n, Stop& stop) {
  Busy busy(w, what);
  std::uint64_t done = 0;
  bool stopped = false;
  const auto hook = [&](Cell& cell, const Clock& clock) { return stopped = stop(cell, clock); };
  while (done < n && !stopped) {
    std::uint64_t chunk = n - done;
    if (w.transactional) {
      const std::uint64_t clock = w.world->state().clock.step;
      if (w.snapshot_stale || clock - w.snapshot->clock.step >= k_replay_steps) take_snapshot(w);
      chunk = std::min(chunk, k_replay_steps - (clock - w.snapshot->clock.step));
    }
    try {
      py::gil_scoped_release release;
      done += w.world->step_until(chunk, hook);
    } catch (const SimulationError&) {
      w.snapshot_stale = true;  // the World holds the end of the failed step (C++'s rule)
      throw;
    } catch (...) {
      const std::exception_ptr e = std::current_exception();
      roll_back(w);
      rethrow_step_error(*w.hub, e);
    }
  }
  return done;
}

const char* const k_reentry_hint =
    ": a World cannot be used while it steps (its arrays are half updated). A stress path gets what it may "
    "read as its argument (PathInput: step, time, stress, strain, length, ...) and returns targets; a stop "
    "function gets (step, cell_length). The step fails with this error and leaves the World at the start of "
    "the interrupted step (a stop function: at the end of its step)";

}  // namespace

void PyWorld::check(const std::string& what) const {
  if (!broken.empty()) throw std::runtime_error(what + ": this World cannot be used: " + broken);
  if (busy.empty()) return;
  if (hub->callback == std::this_thread::get_id()) {
    hub->reentry =
        what + ": called from this World's own " + hub->callback_kind + " while " + busy + " runs it" + k_reentry_hint;
    throw std::runtime_error(hub->reentry);
  }
  throw std::runtime_error(what + ": this World is busy in " + busy +
                           " (called from another thread): a World serves one call at a time; wait for it");
}

void bind_world(py::module_& m) {
  py::class_<PyWorld>(
      m, "World",
      "One scene: World(model, state, threads=1, initial_forces=True, partition='adaptive'). particles and cell are "
      "live read-only views into the engine, contacts are copies; no call while it steps; an exception in a step "
      "leaves it at the start of that step (docs/python.md)")
      .def(py::init([](const Model& model, const State& state, int threads, bool initial_forces,
                       const std::string& partition) {
             if (threads < 1) throw std::invalid_argument("threads = " + std::to_string(threads) + ": must be >= 1");
             // How the threads share each pass; every one gives bitwise the same results.
             const std::optional<Partition> named = partition_from_name(partition);
             if (!named)
               throw std::invalid_argument("partition = '" + partition +
                                           "': allowed 'adaptive', 'owner', 'dynamic' or 'fixed'");
             // A path function that the servo would never call is an error, not a silent no-op.
             const ServoSettings& servo = model.servo;
             if (servo.custom && !servo.enabled)
               throw std::invalid_argument(
                   "servo.custom: set, but servo.enabled = False: the path would never be called; set "
                   "servo.enabled = True (setting servo.custom does) or servo.custom = None");
             if (servo.custom && servo.path != StressPath::custom)
               throw std::invalid_argument(
                   "servo.custom: set, but servo.path is not 'custom': the path would never be called; set "
                   "servo.path = 'custom' (setting servo.custom does) or servo.custom = None");
             PyWorld w;
             Model own = model;
             if (servo.enabled && servo.path == StressPath::custom && servo.custom) {
               WorldPath path;
               path.hub = w.hub;
               if (const PythonPath* p = servo.custom.target<PythonPath>())
                 path.fn = p->fn;
               else
                 path.inner = servo.custom;
               w.path = servo.custom;
               own.servo.custom = std::move(path);
               w.transactional = true;
               w.hub->recording = true;
             }
             std::vector<SystemSpec> systems = systems_for(own);
             w.world = std::make_unique<World>(std::move(own), state, std::move(systems),
                                               ExecutorConfig{Backend::tbb, threads, *named}, initial_forces);
             return w;
           }),
           py::arg("model"), py::arg("state"), py::arg("threads") = 1, py::arg("initial_forces") = true,
           py::arg("partition") = "adaptive")
      .def(
          "step",
          [](PyWorld& w, std::uint64_t n) {
            const auto never = [](Cell&, const Clock&) { return false; };
            advance(w, "World.step", n, never);
          },
          py::arg("n") = 1,
          "Advances n steps (the GIL is released; a Python path takes it on servo updates). An exception in a step "
          "leaves the World at the start of that step")
      .def(
          "step_until",
          [](PyWorld& w, std::uint64_t n, std::uint64_t every, std::optional<double> max_strain,
             std::optional<int> axis_given, const py::object& path, const py::object& stop) {
            w.check("World.step_until");
            if (max_strain) finite("max_strain", *max_strain, "(a logarithmic strain of `axis`, compression positive)");
            if (axis_given && !max_strain)
              throw std::invalid_argument("axis = " + std::to_string(*axis_given) +
                                          ": has no effect without max_strain (the axis whose strain it bounds)");
            const int axis = axis_given.value_or(0);
            if (axis < 0 || axis > 2)
              throw std::invalid_argument("axis = " + std::to_string(axis) + ": must be 0, 1 or 2");
            std::optional<CyclicPath> cyclic;
            if (!path.is_none()) {
              if (!py::isinstance<CyclicPath>(path))
                throw std::invalid_argument("path: " + std::string(py::str(py::type::of(path))) +
                                            ": must be a CyclicPath (stops when finished)");
              cyclic = path.cast<CyclicPath>();
              // Another path's `finished` never changes here: the stop would have no effect.
              const CyclicPath* own = w.path.target<CyclicPath>();
              if (!own || &own->reversal_strains() != &cyclic->reversal_strains())
                throw std::invalid_argument(
                    "path: not this World's servo path (servo.custom when the World was built): it would never "
                    "finish here; give the CyclicPath the World runs");
            }
            const bool py_stop = !stop.is_none();
            if (py_stop && !PyCallable_Check(stop.ptr()))
              throw std::invalid_argument("stop: " + std::string(py::str(py::type::of(stop))) +
                                          ": must be callable (step, cell_length) -> bool");
            std::optional<py::error_already_set> stop_error;
            auto until = [&](Cell& cell, const Clock& clock) -> bool {
              if (every > 0 && clock.step % every == 0) return true;
              if (max_strain && -std::log(cell.length[axis] / cell.length0[axis]) >= *max_strain) return true;
              if (cyclic && cyclic->finished()) return true;
              if (!py_stop) return false;
              py::gil_scoped_acquire gil;
              Hub& h = *w.hub;
              CallbackScope scope(h, "stop function");
              try {
                const py::object r = stop(clock.step, cell.length);
                raise_reentry(h);
                const int truth = PyObject_IsTrue(r.ptr());
                if (truth < 0) throw py::error_already_set();
                return truth != 0;
              } catch (py::error_already_set& e) {
                stop_error = std::move(e);
                return true;
              }
            };
            const std::uint64_t done = advance(w, "World.step_until", n, until);
            if (stop_error) throw std::move(*stop_error);
            return done;
          },
          py::arg("n"), py::kw_only(), py::arg("every") = 0, py::arg("max_strain") = py::none(),
          py::arg("axis") = py::none(), py::arg("path") = py::none(), py::arg("stop") = py::none(),
          "Advances at most n steps, stopping after the first step at a multiple of `every`, at a logarithmic strain of "
          "`axis` (default 0) >= max_strain, when the World's CyclicPath `path` is finished, or when "
          "stop(step, cell_length) is true (a Python stop is called every step: slow). Returns the steps done.")
      .def(
          "measure",
          [](PyWorld& w, bool kinetic_stress, double d50, double density) {
            non_negative("d50", d50, "m (0: no inertial number)");
            non_negative("density", density, "kg/m^3 (0: no inertial number)");
            if ((d50 > 0.0) != (density > 0.0))
              throw std::invalid_argument(d50 > 0.0 ? "d50 = " + number(d50) +
                                                          ": has no effect without density > 0 (kg/m^3): the two "
                                                          "give the inertial number"
                                                    : "density = " + number(density) +
                                                          ": has no effect without d50 > 0 (m): the two give the "
                                                          "inertial number");
            MeasureOptions o;
            o.kinetic_stress = kinetic_stress;
            o.d50 = d50;
            o.density = density;
            Busy busy(w, "World.measure");
            py::gil_scoped_release release;
            return measure(w.world->model(), w.world->state(), w.world->executor(), o);
          },
          py::kw_only(), py::arg("kinetic_stress") = false, py::arg("d50") = 0.0, py::arg("density") = 0.0,
          "Every measure of docs/physics.md section 5 on the current state (d50 and density, together: the inertial "
          "number)")
      .def_property_readonly(
          "model",
          [](const PyWorld& w) {
            Model model = w.world->model();
            if (w.transactional) model.servo.custom = w.path;  // the path as given, not the World's recorder
            return model;
          },
          "A copy of the model")
      .def(
          "state", [](const PyWorld& w) { return w.state("World.state"); }, "A copy of the state")
      .def_property_readonly("step_count", [](const PyWorld& w) { return w.state("World.step_count").clock.step; })
      .def_property_readonly("time", [](const PyWorld& w) { return w.state("World.time").clock.time; })
      .def_property_readonly(
          "particles",
          [](py::object self) { return particle_views(self, self.cast<const PyWorld&>().state("World.particles")); },
          "Read-only views of the particle arrays: live (they show each step's values) and valid while they exist "
          "(the arrays never move; the spatial sort reorders them in place: match rows by 'id')")
      .def_property_readonly(
          "contacts", [](const PyWorld& w) { return contact_views(py::handle(), w.state("World.contacts")); },
          "Read-only copies of the contact arrays (they move at each neighbour-list build)")
      .def_property_readonly(
          "cell", [](py::object self) { return cell_views(self, self.cast<const PyWorld&>().state("World.cell")); },
          "Read-only live views of the cell's 3-vectors (length, length0, rate, servo_integral, tilt, tilt0, flip, "
          "shear_rate, shear_integral)")
      .def(
          "set_cell_rate",
          [](PyWorld& w, const py::object& v) {
            w.check("World.set_cell_rate");
            const Vec3 r = vec3("rate", v);
            for (int k = 0; k < 3; ++k)
              finite("rate[" + std::to_string(k) + "]", r[k], "(1/s, D_kk, tension positive)");
            w.world->state().cell.rate = r;
            w.snapshot_stale = true;  // a change that replaying steps would not make
          },
          py::arg("rate"), "Sets the cell's D_kk (1/s, tension positive) for the next step")
      .def(
          "set_cell_shear_rate",
          [](PyWorld& w, const py::object& v) {
            w.check("World.set_cell_shear_rate");
            w.world->state().cell.shear_rate = finite_shear("shear_rate", v, "(1/s, L_ab, tension positive)");
            w.snapshot_stale = true;  // a change that replaying steps would not make
          },
          py::arg("shear_rate"),
          "Sets the cell's shear rates (L_xy, L_xz, L_yz) (1/s, tension positive: the engineering rate is -L_ab) for "
          "the next step; a servo on the shear components sets them again at its next update")
      .def(
          "write_checkpoint",
          [](const PyWorld& w, const std::string& path, const py::object& extra) {
            write_checkpoint(path, w.state("World.write_checkpoint"), extra_from_dict(extra));
          },
          py::arg("path"), py::arg("extra") = py::none())
      .def(
          "_address",
          [](const PyWorld& w, const std::string& name) {
            const State& s = w.state("World._address");
            const Particles& p = s.particles;
            if (name == "position") return reinterpret_cast<std::uintptr_t>(p.position.data());
            if (name == "velocity") return reinterpret_cast<std::uintptr_t>(p.velocity.data());
            if (name == "force") return reinterpret_cast<std::uintptr_t>(p.force.data());
            if (name == "radius") return reinterpret_cast<std::uintptr_t>(p.radius.data());
            if (name == "contact_force") return reinterpret_cast<std::uintptr_t>(s.contacts.forces.force.data());
            throw std::invalid_argument("name = '" + name +
                                        "': allowed: position, velocity, force, radius, contact_force");
          },
          py::arg("name"), "The C++ array's data address (for the tests of the views)")
      .def("defers_work", [](const PyWorld& w) {
        w.check("World.defers_work");
        return w.world->defers_work();
      });
}

}  // namespace sandcell::python
