#pragma once
// What the module's files share (docs/python.md): argument checks that raise ValueError naming the
// argument, the Python stress path, the views of a State's arrays, and the World's Python side
// (PyWorld, python/src/world.cpp) with its lifetime rules: no use while it steps (reentrancy), an
// exception in a step rolls the World back to the start of that step, contact arrays are copies.
#include <sandcell/sandcell.hpp>

#include <pybind11/pybind11.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace sandcell::python {

namespace py = pybind11;

// ---- argument checks: std::invalid_argument, which pybind11 raises as ValueError ----------------

/// A 3-vector from any sequence of 3 numbers.
Vec3 vec3(const std::string& key, const py::handle& value);
/// v itself when finite and > 0: "key = v: must be a finite value > 0 <unit>".
double positive(const std::string& key, double v, const char* unit);
/// v itself when finite and >= 0: "key = v: must be a finite value >= 0 <unit>".
double non_negative(const std::string& key, double v, const char* unit);
/// v itself when finite: "key = v: must be finite <what>".
double finite(const std::string& key, double v, const char* what);
/// A shear 3-vector (xy, xz, yz) of finite numbers: "key[xz] = nan: must be finite <unit>".
Vec3 finite_shear(const std::string& key, const py::handle& value, const char* unit);
/// A number as the messages print it (%g: 1e+05, inf, nan).
std::string number(double v);

// ---- stress paths written in Python ---------------------------------------------------------------

/// A Python callable given as servo.custom. Called outside a World (e.g. by the user) it calls the
/// function under the GIL; a World calls it through its own wrapper (world.cpp), which keeps the
/// function's exception for the step's caller and records its answers.
struct PythonPath {
  py::object fn;
  PathTargets operator()(const PathInput& in) const;
};
/// A path function's result (a PathTargets or a tuple (control[3], value[3])), or ValueError.
PathTargets targets_from_python(const py::handle& result);

// ---- views ------------------------------------------------------------------------------------------

/// Read-only NumPy arrays of a State's particle / contact arrays: views into `owner`'s memory (kept
/// alive by them), or copies when `owner` is a null handle.
py::dict particle_views(py::handle owner, const State& s);
py::dict contact_views(py::handle owner, const State& s);
py::dict cell_views(py::handle owner, const State& s);

CheckpointExtra extra_from_dict(const py::handle& o);
py::dict extra_to_dict(const CheckpointExtra& x);

// ---- the World ----------------------------------------------------------------------------------------

/// What a World's Python callbacks (its stress path, a step_until stop function) share with the code
/// that steps it; one per World. Touched with the GIL held, but for the tape, which the servo's
/// thread writes while the caller waits for the step.
struct Hub {
  std::optional<py::error_already_set> error;  // the path's Python error, until the step returns
  std::thread::id callback;                   // the thread running a Python callback of a step
  const char* callback_kind = "";             // "stress path (servo.custom)" or "stop function"
  std::string reentry;                        // set when that callback called into this World
  bool recording = false;                     // the custom path's answers go to the tape
  bool replaying = false;                     // the path answers from the tape (a rollback)
  std::vector<PathTargets> tape;              // the answers since the snapshot, in order
  std::size_t next = 0;                       // the next answer to replay
};

/// A World seen from Python. Its methods raise RuntimeError while it steps or measures (from its
/// own path or stop function, or another thread): `check` at the top of each.
struct PyWorld {
  std::unique_ptr<World> world;
  std::shared_ptr<Hub> hub = std::make_shared<Hub>();
  PathFunction path;           // servo.custom as given (World.model shows it, step_until(path=) checks it)
  bool transactional = false;  // a custom path: an exception in a step rolls the World back (snapshot + tape)
  std::optional<State> snapshot;  // the state at the start of the tape (between calls)
  bool snapshot_stale = true;     // the state changed other than by stepping: take a new one
  std::string busy;               // the call that steps or measures this World now, else empty
  std::string broken;             // why this World cannot be used any more, else empty

  /// Raises RuntimeError if this World is busy or broken; `what` names the call ("World.step").
  void check(const std::string& what) const;
  /// The state, for a call that reads it (check first).
  const State& state(const char* what) const {
    check(what);
    return world->state();
  }
};

void bind_world(py::module_& m);  // world.cpp: sandcell.World

}  // namespace sandcell::python
