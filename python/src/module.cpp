// The Python front end (docs/python.md): module sandcell._sandcell, wrapped by the package sandcell.
// Settings are plain classes with attribute access; the World owns its state, and its arrays are
// seen from Python as read-only NumPy views without copies, valid until the next call that may
// resize or reorder them (World.step, World.step_until). Bad input raises ValueError naming the
// argument (the engine's std::invalid_argument is translated to ValueError by pybind11).
#include <sandcell/sandcell.hpp>

#include "protocol/series.hpp"
#include "systems/contact_pass.hpp"
#include "systems/homogenizer.hpp"
#include "systems/path_watch.hpp"
#include "systems/servo.hpp"
#include "systems/stress_paths.hpp"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace py = pybind11;
using namespace sandcell;

namespace {

// ---- names <-> enums ----------------------------------------------------------------------------

template <class E>
struct Names {
  std::vector<std::pair<std::string, E>> items;
  E parse(const std::string& key, const std::string& value) const {
    for (const auto& [n, e] : items)
      if (value == n) return e;
    std::string allowed;
    for (const auto& [n, e] : items) allowed += (allowed.empty() ? "" : ", ") + std::string(n);
    throw std::invalid_argument(key + " = '" + value + "': unknown; allowed: " + allowed);
  }
  std::string name(E e) const {
    for (const auto& [n, v] : items)
      if (v == e) return n;
    return "?";
  }
};

// The built-in paths' names: their rows in systems/stress_paths.cpp.
const Names<StressPath> k_paths = [] {
  Names<StressPath> n;
  for (const StressPathSpec& s : stress_paths()) n.items.emplace_back(s.name.data(), s.id);
  return n;
}();
const Names<AxisControl> k_controls{
    {{"strain", AxisControl::strain}, {"stress", AxisControl::stress}, {"volume", AxisControl::volume}}};
// The laws' names: their registries (systems/laws/mindlin.hpp TangentialLaws, rolling.hpp k_rolling_laws).
const Names<TangentialModel> k_tangential = [] {
  Names<TangentialModel> n;
  for (const std::string& name : tangential_law_names()) n.items.emplace_back(name, *tangential_law(name));
  return n;
}();
const Names<RollingModel> k_rolling = [] {
  Names<RollingModel> n;
  for (const std::string& name : rolling_law_names()) n.items.emplace_back(name, *rolling_law(name));
  return n;
}();

std::array<AxisControl, 3> parse_controls(const std::string& key, const std::vector<std::string>& names) {
  if (names.size() != 3)
    throw std::invalid_argument(key + ": " + std::to_string(names.size()) + " entries: must be 3 (one per axis)");
  std::array<AxisControl, 3> c{};
  for (int k = 0; k < 3; ++k) c[k] = k_controls.parse(key + "[" + std::to_string(k) + "]", names[k]);
  return c;
}
std::vector<std::string> control_names(const std::array<AxisControl, 3>& c) {
  return {k_controls.name(c[0]), k_controls.name(c[1]), k_controls.name(c[2])};
}

// A 3-vector from any sequence of 3 numbers, or ValueError naming the argument.
Vec3 vec3(const std::string& key, const py::handle& value) {
  py::array_t<double, py::array::forcecast> a;
  try {
    a = py::array_t<double, py::array::forcecast>::ensure(value);
  } catch (const py::error_already_set&) {
  }
  if (!a || a.ndim() != 1 || a.shape(0) != 3)
    throw std::invalid_argument(key + ": must be a sequence of 3 numbers (shape (3,))" +
                                (a ? ", got shape with " + std::to_string(a.ndim()) + " dimensions" : std::string()));
  return Vec3(a.at(0), a.at(1), a.at(2));
}

double positive(const std::string& key, double v, const char* unit) {
  if (!(v > 0.0) || !std::isfinite(v))
    throw std::invalid_argument(key + " = " + std::to_string(v) + ": must be a finite value > 0 " + unit);
  return v;
}

// ---- Python stress paths --------------------------------------------------------------------------

// A Python error raised inside a path called from the step loop, kept until the step returns to
// Python (the step may run the servo on another thread; the error crosses TBB as PathError).
struct ErrorSlot {
  std::optional<py::error_already_set> error;
};
struct PathError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

PathTargets targets_from_python(const py::handle& result) {
  if (py::isinstance<PathTargets>(result)) return result.cast<PathTargets>();
  if (py::isinstance<py::tuple>(result) && py::len(result) == 2) {
    const py::tuple t = result.cast<py::tuple>();
    PathTargets out;
    if (py::isinstance<py::str>(t[0]) || !py::isinstance<py::sequence>(t[0]))
      throw std::invalid_argument("path result control: must be a sequence of 3 of strain, stress, volume");
    std::vector<std::string> names;
    for (const py::handle h : t[0].cast<py::sequence>()) {
      if (!py::isinstance<py::str>(h))
        throw std::invalid_argument("path result control: must be a sequence of 3 of strain, stress, volume");
      names.push_back(h.cast<std::string>());
    }
    out.control = parse_controls("path result control", names);
    out.value = vec3("path result value", t[1]);
    return out;
  }
  throw std::invalid_argument("path result: " + std::string(py::str(py::type::of(result))) +
                              ": must be a sandcell.PathTargets or a tuple (control[3], value[3])");
}

// The C++ side of a Python callable path. Holds the GIL while it runs.
struct PythonPath {
  py::object fn;
  std::shared_ptr<ErrorSlot> slot;
  PathTargets operator()(const PathInput& in) const {
    py::gil_scoped_acquire gil;
    try {
      return targets_from_python(fn(in));
    } catch (py::error_already_set& e) {
      std::string what = e.what();
      slot->error = std::move(e);
      throw PathError("stress path raised: " + what);
    } catch (const std::invalid_argument& e) {
      slot->error = std::nullopt;
      throw;
    }
  }
};

PathFunction path_function(const py::object& value) {
  if (value.is_none()) return {};
  if (py::isinstance<CyclicPath>(value)) return value.cast<CyclicPath>();
  if (py::isinstance<PathFunction>(value)) return value.cast<PathFunction>();
  if (!PyCallable_Check(value.ptr()))
    throw std::invalid_argument("servo.custom: " + std::string(py::str(py::type::of(value))) +
                                ": must be callable (PathInput -> PathTargets), a CyclicPath or undrained_path(rate)");
  return PythonPath{value, std::make_shared<ErrorSlot>()};
}

// ---- the World and its views --------------------------------------------------------------------

struct PyWorld {
  std::unique_ptr<World> world;
  std::shared_ptr<ErrorSlot> slot;  // the Python path's, when the servo runs one
  py::object path;                  // the Python object given as servo.custom (kept alive)

  // Runs fn with the GIL released, then turns a Python path's error back into that Python error.
  template <class Fn>
  auto guarded(Fn&& fn) {
    try {
      py::gil_scoped_release release;
      return fn();
    } catch (const PathError&) {
      if (slot && slot->error) {
        py::error_already_set e = std::move(*slot->error);
        slot->error.reset();
        throw e;
      }
      throw;
    }
  }
};

template <class T>
py::array view(const py::object& owner, const std::vector<T>& v, bool /*vec3*/) {
  py::array a;
  if constexpr (std::is_same_v<T, Vec3>) {
    const auto* data = reinterpret_cast<const double*>(v.data());
    a = py::array(py::dtype::of<double>(), {static_cast<py::ssize_t>(v.size()), py::ssize_t{3}},
                  {static_cast<py::ssize_t>(sizeof(T)), static_cast<py::ssize_t>(sizeof(double))}, data, owner);
  } else {
    a = py::array(py::dtype::of<T>(), {static_cast<py::ssize_t>(v.size())}, {static_cast<py::ssize_t>(sizeof(T))},
                  v.data(), owner);
  }
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

py::array image_view(const py::object& owner, const std::vector<Image>& v) {
  py::array a(py::dtype::of<std::int8_t>(), {static_cast<py::ssize_t>(v.size()), py::ssize_t{3}},
              {static_cast<py::ssize_t>(sizeof(Image)), py::ssize_t{1}}, reinterpret_cast<const std::int8_t*>(v.data()),
              owner);
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

py::array vec_view(const py::object& owner, const Vec3& v) {
  py::array a(py::dtype::of<double>(), {py::ssize_t{3}}, {py::ssize_t{sizeof(double)}}, v.data(), owner);
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

// The particle arrays of a State, by name (components/particles.hpp).
py::dict particle_views(const py::object& owner, const State& s) {
  const Particles& p = s.particles;
  py::dict d;
  d["id"] = view(owner, p.id, false);
  d["position"] = view(owner, p.position, true);
  d["velocity"] = view(owner, p.velocity, true);
  d["angular_velocity"] = view(owner, p.angular_velocity, true);
  d["force"] = view(owner, p.force, true);
  d["torque"] = view(owner, p.torque, true);
  d["radius"] = view(owner, p.radius, false);
  d["mass"] = view(owner, p.mass, false);
  d["inv_inertia"] = view(owner, p.inv_inertia, false);
  d["material"] = view(owner, p.material, false);
  d["reference_position"] = view(owner, p.reference_position, true);
  return d;
}

py::dict contact_views(const py::object& owner, const State& s) {
  const Contacts& c = s.contacts;
  py::dict d;
  d["id_i"] = view(owner, c.pairs.id_i, false);
  d["id_j"] = view(owner, c.pairs.id_j, false);
  d["i"] = view(owner, c.pairs.i, false);
  d["j"] = view(owner, c.pairs.j, false);
  d["image"] = image_view(owner, c.pairs.image);
  d["force"] = view(owner, c.forces.force, true);
  d["torque_i"] = view(owner, c.forces.torque_i, true);
  d["torque_j"] = view(owner, c.forces.torque_j, true);
  d["tangential"] = view(owner, c.tangential, true);
  if (c.has_tangential_radius) d["tangential_radius"] = view(owner, c.tangential_radius, false);
  if (c.has_rolling) d["rolling"] = view(owner, c.rolling, true);
  return d;
}

py::dict cell_views(const py::object& owner, const State& s) {
  py::dict d;
  d["length"] = vec_view(owner, s.cell.length);
  d["length0"] = vec_view(owner, s.cell.length0);
  d["rate"] = vec_view(owner, s.cell.rate);
  d["servo_integral"] = vec_view(owner, s.cell.servo_integral);
  return d;
}

py::dict extra_to_dict(const CheckpointExtra& x) {
  py::dict d;
  d["doubles"] = x.doubles;
  d["integers"] = x.integers;
  d["strings"] = x.strings;
  return d;
}

CheckpointExtra extra_from_dict(const py::object& o) {
  CheckpointExtra x;
  if (o.is_none()) return x;
  if (!py::isinstance<py::dict>(o))
    throw std::invalid_argument("extra: must be a dict with keys doubles, integers, strings");
  const py::dict d = o.cast<py::dict>();
  for (const auto& [key, value] : d) {
    const std::string k = key.cast<std::string>();
    if (k == "doubles")
      x.doubles = value.cast<std::map<std::string, std::vector<double>>>();
    else if (k == "integers")
      x.integers = value.cast<std::map<std::string, std::vector<std::int64_t>>>();
    else if (k == "strings")
      x.strings = value.cast<std::map<std::string, std::string>>();
    else
      throw std::invalid_argument("extra['" + k + "']: unknown key; allowed: doubles, integers, strings");
  }
  return x;
}

State state_from_arrays(const Model& model, const py::object& box, const py::object& position, const py::object& radius,
                        std::uint32_t material) {
  Packing pk;
  pk.box = vec3("box", box);
  for (int k = 0; k < 3; ++k) positive("box[" + std::to_string(k) + "]", pk.box[k], "m");
  const auto x = py::array_t<double, py::array::forcecast | py::array::c_style>::ensure(position);
  const auto r = py::array_t<double, py::array::forcecast | py::array::c_style>::ensure(radius);
  if (!x || x.ndim() != 2 || x.shape(1) != 3)
    throw std::invalid_argument("position: " +
                                (x ? "shape with " + std::to_string(x.ndim()) + " dimensions" +
                                         (x.ndim() == 2 ? " (n, " + std::to_string(x.shape(1)) + ")" : "")
                                   : std::string("not an array of numbers")) +
                                ": must be an array of shape (n, 3), m");
  if (!r || r.ndim() != 1 || r.shape(0) != x.shape(0))
    throw std::invalid_argument("radius: " +
                                (r ? "shape with " + std::to_string(r.ndim()) + " dimensions, " +
                                         std::to_string(r.ndim() ? r.shape(0) : 0) + " entries"
                                   : std::string("not an array of numbers")) +
                                ": must be an array of shape (n,) with n = " + std::to_string(x.shape(0)) +
                                " (position's rows)");
  if (material >= model.materials.size())
    throw std::invalid_argument("material = " + std::to_string(material) + ": must be below the model's " +
                                std::to_string(model.materials.size()) + " materials");
  for (py::ssize_t k = 0; k < x.shape(0); ++k) {
    const Vec3 p(x.at(k, 0), x.at(k, 1), x.at(k, 2));
    if (!p.allFinite()) throw std::invalid_argument("position[" + std::to_string(k) + "]: must be finite");
    positive("radius[" + std::to_string(k) + "]", r.at(k), "m");
    pk.position.push_back(p);
    pk.radius.push_back(r.at(k));
  }
  return make_state(model, pk, material);
}

Measures measure_world(World& w, bool kinetic_stress, double d50, double density) {
  MeasureOptions o;
  o.kinetic_stress = kinetic_stress;
  o.d50 = d50;
  o.density = density;
  return measure(w.model(), w.state(), w.executor(), o);
}

}  // namespace

void bind_protocol(py::module_& m);  // protocol.cpp: sandcell.Protocol and the triaxial series

PYBIND11_MODULE(_sandcell, m) {
  m.doc() = "sandcell: DEM engine for stress-controlled periodic element tests (docs/python.md)";
  m.attr("__version__") = std::string(version());
  py::register_exception<SimulationError>(m, "SimulationError", PyExc_RuntimeError);

  py::class_<Material>(m, "Material", "A sphere material (SI units)")
      .def(py::init([](double density, double young, double poisson, double restitution, double friction,
                       double rolling_friction) {
             Material mat{density, young, poisson, restitution, friction, rolling_friction};
             positive("density", density, "kg/m^3");
             positive("young", young, "Pa");
             if (!(poisson > -1.0 && poisson < 0.5))
               throw std::invalid_argument("poisson = " + std::to_string(poisson) + ": must be in (-1, 0.5)");
             if (!(restitution > 0.0 && restitution <= 1.0))
               throw std::invalid_argument("restitution = " + std::to_string(restitution) + ": must be in (0, 1]");
             if (!(friction >= 0.0))
               throw std::invalid_argument("friction = " + std::to_string(friction) + ": must be >= 0");
             if (!(rolling_friction >= 0.0))
               throw std::invalid_argument("rolling_friction = " + std::to_string(rolling_friction) + ": must be >= 0");
             return mat;
           }),
           py::arg("density") = 2650.0, py::arg("young") = 70e9, py::arg("poisson") = 0.3, py::arg("restitution") = 0.5,
           py::arg("friction") = 0.5, py::arg("rolling_friction") = 0.1)
      .def_readwrite("density", &Material::density)
      .def_readwrite("young", &Material::young)
      .def_readwrite("poisson", &Material::poisson)
      .def_readwrite("restitution", &Material::restitution)
      .def_readwrite("friction", &Material::friction)
      .def_readwrite("rolling_friction", &Material::rolling_friction)
      .def("__repr__", [](const Material& a) {
        std::ostringstream s;
        s << "Material(density=" << a.density << ", young=" << a.young << ", poisson=" << a.poisson
          << ", restitution=" << a.restitution << ", friction=" << a.friction
          << ", rolling_friction=" << a.rolling_friction << ")";
        return s.str();
      });

  py::class_<ContactSettings>(m, "ContactSettings", "Contact laws and the neighbour list (engine/model.hpp)")
      .def(py::init<>())
      .def_readwrite("enabled", &ContactSettings::enabled)
      .def_readwrite("normal", &ContactSettings::normal)
      .def_readwrite("parameters", &ContactSettings::parameters)
      .def_property(
          "tangential", [](const ContactSettings& c) { return k_tangential.name(c.tangential); },
          [](ContactSettings& c, const std::string& v) { c.tangential = k_tangential.parse("contact.tangential", v); })
      .def_property(
          "rolling", [](const ContactSettings& c) { return k_rolling.name(c.rolling); },
          [](ContactSettings& c, const std::string& v) { c.rolling = k_rolling.parse("contact.rolling", v); })
      .def_readwrite("rolling_damping", &ContactSettings::rolling_damping)
      .def_readwrite("skin", &ContactSettings::skin)
      .def_readwrite("liggghts_compat", &ContactSettings::liggghts_compat)
      .def_readwrite("sort_interval", &ContactSettings::sort_interval);

  py::class_<PathInput>(m, "PathInput", "What a custom stress path sees at each servo update (compression positive)")
      .def_readonly("step", &PathInput::step)
      .def_readonly("time", &PathInput::time)
      .def_readonly("dt", &PathInput::dt)
      .def_readonly("interval", &PathInput::interval)
      .def_readonly("stress", &PathInput::stress)
      .def_readonly("length", &PathInput::length)
      .def_readonly("length0", &PathInput::length0)
      .def_readonly("strain", &PathInput::strain)
      .def_readonly("strain_rate", &PathInput::strain_rate)
      .def_property_readonly("p", [](const PathInput& i) { return i.stress.trace() / 3.0; })
      .def_property_readonly("eps_v", [](const PathInput& i) { return i.strain.sum(); });

  py::class_<PathTargets>(m, "PathTargets",
                          "A custom path's answer: per axis 'strain' (value 1/s), 'stress' (value Pa) or 'volume'")
      .def(py::init([](const std::vector<std::string>& control, const py::object& value) {
             PathTargets t;
             t.control = parse_controls("control", control);
             t.value = vec3("value", value);
             return t;
           }),
           py::arg("control"), py::arg("value") = py::make_tuple(0.0, 0.0, 0.0))
      .def_property(
          "control", [](const PathTargets& t) { return control_names(t.control); },
          [](PathTargets& t, const std::vector<std::string>& c) { t.control = parse_controls("control", c); })
      .def_property(
          "value", [](const PathTargets& t) { return t.value; },
          [](PathTargets& t, const py::object& v) { t.value = vec3("value", v); });

  // An opaque C++ path (undrained_path); give it to ServoSettings.custom.
  py::class_<PathFunction>(m, "PathFunction", "A stress path implemented in C++")
      .def("__call__", [](const PathFunction& f, const PathInput& in) { return f(in); });

  py::class_<CyclicSettings>(m, "CyclicSettings", "A cyclic test (systems/servo.hpp)")
      .def(py::init<>())
      .def_property(
          "axial", [](const CyclicSettings& c) { return k_controls.name(c.axial); },
          [](CyclicSettings& c, const std::string& v) { c.axial = k_controls.parse("cyclic.axial", v); })
      .def_readwrite("lower", &CyclicSettings::lower)
      .def_readwrite("upper", &CyclicSettings::upper)
      .def_readwrite("rate", &CyclicSettings::rate)
      .def_readwrite("tolerance", &CyclicSettings::tolerance)
      .def_readwrite("undrained", &CyclicSettings::undrained)
      .def_readwrite("sigma3", &CyclicSettings::sigma3)
      .def_readwrite("cycles", &CyclicSettings::cycles)
      .def_readwrite("max_strain", &CyclicSettings::max_strain);

  py::class_<CyclicPath>(m, "CyclicPath",
                         "The cyclic path (C++): give it to ServoSettings.custom; its memory is shared")
      .def(py::init<const CyclicSettings&>(), py::arg("settings"))
      .def("__call__", [](const CyclicPath& p, const PathInput& in) { return p(in); })
      .def_property_readonly("settings", &CyclicPath::settings)
      .def_property_readonly("reversals", &CyclicPath::reversals)
      .def_property_readonly("cycles", &CyclicPath::cycles)
      .def_property_readonly("loading", &CyclicPath::loading)
      .def_property_readonly("finished", &CyclicPath::finished)
      .def_property_readonly("reversal_strains", &CyclicPath::reversal_strains)
      .def_property_readonly("reversal_steps", &CyclicPath::reversal_steps);

  m.def("undrained_path", &undrained_path, py::arg("axial_rate"),
        "Constant volume: axis 1 at axial_rate (1/s, compression positive), axes 2 and 3 keep eps_v = 0");

  py::class_<ServoSettings>(m, "ServoSettings", "The periodic servo and its stress path (docs/physics.md section 6)")
      .def(py::init<>())
      .def_readwrite("enabled", &ServoSettings::enabled)
      .def_property(
          "path", [](const ServoSettings& s) { return k_paths.name(s.path); },
          [](ServoSettings& s, const std::string& v) { s.path = k_paths.parse("servo.path", v); })
      .def_property(
          "control", [](const ServoSettings& s) { return control_names(s.control); },
          [](ServoSettings& s, const std::vector<std::string>& c) { s.control = parse_controls("servo.control", c); })
      .def_property(
          "strain_rate", [](const ServoSettings& s) { return s.strain_rate; },
          [](ServoSettings& s, const py::object& v) { s.strain_rate = vec3("servo.strain_rate", v); })
      .def_readwrite("ramp_time", &ServoSettings::ramp_time)
      .def_readwrite("inertial_number", &ServoSettings::inertial_number)
      .def_readwrite("d50", &ServoSettings::d50)
      .def_readwrite("density", &ServoSettings::density)
      .def_property(
          "target", [](const ServoSettings& s) { return s.target; },
          [](ServoSettings& s, const py::object& v) { s.target = vec3("servo.target", v); })
      .def_readwrite("p", &ServoSettings::p)
      .def_readwrite("b", &ServoSettings::b)
      .def_readwrite("sigma3", &ServoSettings::sigma3)
      .def_readwrite("gain", &ServoSettings::gain)
      .def_readwrite("integral_time", &ServoSettings::integral_time)
      .def_readwrite("max_rate", &ServoSettings::max_rate)
      .def_readwrite("max_rate_ratio", &ServoSettings::max_rate_ratio)
      .def_readwrite("integral_strain", &ServoSettings::integral_strain)
      .def_property(
          "interval", [](const ServoSettings& s) { return s.interval; },
          [](ServoSettings& s, int v) {
            if (v < 1) throw std::invalid_argument("servo.interval = " + std::to_string(v) + ": must be >= 1 step");
            s.interval = v;
          })
      .def_readwrite("kinetic_stress", &ServoSettings::kinetic_stress)
      .def_property(
          "custom",
          [](const ServoSettings& s) -> py::object {
            if (!s.custom) return py::none();
            return py::cast(s.custom);
          },
          [](ServoSettings& s, const py::object& v) {
            s.custom = path_function(v);
            if (s.custom) s.path = StressPath::custom;
          })
      .def("validate", [](const ServoSettings& s) { validate(s); });

  py::class_<PathTolerance>(m, "PathTolerance",
                            "Tolerances of the stress-path watchdog (systems/path_watch.hpp, docs/physics.md 6.2)")
      .def(py::init<>())
      .def_readwrite("stress", &PathTolerance::stress)
      .def_readwrite("b", &PathTolerance::b)
      .def_readwrite("rotation", &PathTolerance::rotation)
      .def_readwrite("shear", &PathTolerance::shear)
      .def_readwrite("window", &PathTolerance::window)
      .def_readwrite("start", &PathTolerance::start)
      .def_readwrite("overlap", &PathTolerance::overlap)
      .def_readwrite("unbalanced", &PathTolerance::unbalanced)
      .def_readwrite("rows", &PathTolerance::rows)
      .def("validate", [](const PathTolerance& t) { validate(t); });

  py::class_<PathWatch>(m, "PathWatch",
                        "The stress-path watchdog: add() one row at a time (after each World.step of a series "
                        "interval); returns the first failure as a dict, else None (systems/path_watch.hpp)")
      .def(py::init<const ServoSettings&, PathTolerance>(), py::arg("servo"), py::arg("tolerance") = PathTolerance{})
      .def(
          "add",
          [](PathWatch& w, double eps1, const Mat3& stress, std::uint64_t step, double max_overlap_ratio,
             double unbalanced) -> py::object {
            const auto f = w.add({step, eps1, stress, max_overlap_ratio, unbalanced});
            if (!f) return py::none();
            py::dict d;
            d["quantity"] = f->quantity;
            d["value"] = f->value;
            d["tolerance"] = f->tolerance;
            d["step"] = f->step;
            d["eps1"] = f->eps1;
            d["message"] = f->message;
            return d;
          },
          py::arg("eps1"), py::arg("stress"), py::arg("step") = 0, py::arg("max_overlap_ratio") = 0.0,
          py::arg("unbalanced") = 0.0,
          "eps1: axial strain; stress: 3x3, Pa, compression positive (Measures.stress); returns the failure "
          "(quantity, value, tolerance, step, eps1, message) on the first row beyond a tolerance, else None")
      .def_property_readonly("failed", [](const PathWatch& w) { return w.failure().has_value(); })
      .def_property_readonly("message",
                             [](const PathWatch& w) { return w.failure() ? w.failure()->message : std::string(); })
      .def("worst", &PathWatch::worst, py::arg("quantity"),
           "largest error so far of p, sigma3, path (the largest of the stress targets), b, rotation, shear, "
           "unbalanced or overlap")
      .def_property_readonly("rows_checked", &PathWatch::rows_checked);
  m.def("principal_rotation_deg", &principal_rotation_deg, py::arg("stress"),
        "The principal axes' turn off the cell axes, 1/2 asin(2 |tau| / (s1 - s3)), degrees");
  m.def("shear_ratio", &shear_ratio, py::arg("stress"), "Largest |shear stress| / p of a 3x3 stress");

  py::class_<Model>(m, "Model", "Everything constant during a run (engine/model.hpp)")
      .def(py::init([](double dt, std::vector<Material> materials, std::optional<ContactSettings> contact,
                       std::optional<ServoSettings> servo) {
             Model model;
             model.dt = positive("dt", dt, "s");
             if (materials.empty()) throw std::invalid_argument("materials: empty; at least one Material is required");
             model.materials = std::move(materials);
             if (contact) model.contact = *contact;
             if (servo) model.servo = *servo;
             return model;
           }),
           py::arg("dt"), py::arg("materials"), py::arg("contact") = py::none(), py::arg("servo") = py::none())
      .def_property(
          "dt", [](const Model& m) { return m.dt; }, [](Model& m, double v) { m.dt = positive("dt", v, "s"); })
      .def_readwrite("materials", &Model::materials)
      .def_readwrite("contact", &Model::contact)
      .def_readwrite("servo", &Model::servo);

  m.def("rayleigh_time", &rayleigh_time, py::arg("r_min"), py::arg("material"),
        "Rayleigh time of a sphere of radius r_min, s");
  m.def(
      "median_diameter", [](const std::vector<double>& radius) { return median_diameter(radius); }, py::arg("radius"),
      "Mass-weighted median diameter of spheres of these radii, m");
  m.def(
      "sample_diameters",
      [](double d_min, double d_max, std::size_t count, std::uint64_t seed) {
        SizeDistribution sizes;
        sizes.d_min = d_min;
        sizes.d_max = d_max;
        return sample_diameters(sizes, count, seed);
      },
      py::arg("d_min"), py::arg("d_max"), py::arg("count"), py::arg("seed") = 1,
      "Diameters drawn uniformly by number (the generator's, for the same seed), m");

  py::class_<State>(m, "State",
                    "Particle and contact arrays, the cell, the clock (engine/state.hpp). A value: World copies it")
      .def_static(
          "from_packing",
          [](const Model& model, const std::string& path, std::uint32_t material) {
            return make_state(model, read_packing(path), material);
          },
          py::arg("model"), py::arg("path"), py::arg("material") = 0, "The spheres of a packing file, at rest")
      .def_static(
          "generate",
          [](const Model& model, std::size_t count, double d_min, double d_max, double solid_fraction,
             std::uint64_t seed, std::vector<std::pair<double, double>> gradation) {
            GenerationSettings g;
            g.count = count;
            if (gradation.empty()) {
              g.sizes.d_min = d_min;
              g.sizes.d_max = d_max;
            } else {
              g.sizes.kind = SizeDistribution::Kind::gradation;
              g.sizes.table = std::move(gradation);
            }
            g.solid_fraction = solid_fraction;
            g.seed = seed;
            validate(g);
            return make_state(model, generate_packing(g));
          },
          py::arg("model"), py::arg("count"), py::arg("d_min") = 0.0, py::arg("d_max") = 0.0,
          py::arg("solid_fraction") = 0.3, py::arg("seed") = 1,
          py::arg("gradation") = std::vector<std::pair<double, double>>{},
          "A random cloud (engine/generate.hpp): uniform in [d_min, d_max] by number, or a gradation table")
      .def_static("from_arrays", &state_from_arrays, py::arg("model"), py::arg("box"), py::arg("position"),
                  py::arg("radius"), py::arg("material") = 0, "Spheres at rest in the periodic box [0, box)")
      .def_static(
          "from_checkpoint", [](const std::string& path) { return read_checkpoint(path); }, py::arg("path"))
      .def("__len__", [](const State& s) { return s.particles.size(); })
      .def_property_readonly(
          "particles", [](py::object self) { return particle_views(self, self.cast<const State&>()); },
          "Read-only views of the particle arrays (valid while the State lives and is not changed)")
      .def_property_readonly("contacts", [](py::object self) { return contact_views(self, self.cast<const State&>()); })
      .def_property_readonly("step", [](const State& s) { return s.clock.step; })
      .def_property(
          "time", [](const State& s) { return s.clock.time; }, [](State& s, double t) { s.clock.time = t; })
      .def(
          "reset_clock", [](State& s) { s.clock = {}; }, "Step 0 at time 0 (a new stage)")
      .def_property_readonly("cell_length", [](const State& s) { return s.cell.length; })
      .def_property(
          "cell_length0", [](const State& s) { return s.cell.length0; },
          [](State& s, const py::object& v) {
            s.cell.length0 = vec3("cell_length0", v);
            for (int k = 0; k < 3; ++k) positive("cell_length0[" + std::to_string(k) + "]", s.cell.length0[k], "m");
          })
      .def_property(
          "cell_rate", [](const State& s) { return s.cell.rate; },
          [](State& s, const py::object& v) {
            s.cell.rate = vec3("cell_rate", v);
            if (!s.cell.rate.allFinite())
              throw std::invalid_argument("cell_rate: must be finite (1/s, D_kk, tension positive)");
          })
      .def_property(
          "servo_integral", [](const State& s) { return s.cell.servo_integral; },
          [](State& s, const py::object& v) { s.cell.servo_integral = vec3("servo_integral", v); });

  py::class_<StressInvariants>(m, "StressInvariants")
      .def_readonly("principal", &StressInvariants::principal)
      .def_readonly("p", &StressInvariants::p)
      .def_readonly("q", &StressInvariants::q)
      .def_readonly("eta", &StressInvariants::eta)
      .def_readonly("b", &StressInvariants::b)
      .def_readonly("theta", &StressInvariants::theta);

  py::class_<Measures>(m, "Measures", "What measure() reports (systems/homogenizer.hpp); a copy")
      .def_readonly("stress", &Measures::stress)
      .def_readonly("contact_stress", &Measures::contact_stress)
      .def_readonly("inv", &Measures::inv)
      .def_property_readonly("p", [](const Measures& x) { return x.inv.p; })
      .def_property_readonly("q", [](const Measures& x) { return x.inv.q; })
      .def_property_readonly("eta", [](const Measures& x) { return x.inv.eta; })
      .def_property_readonly("b", [](const Measures& x) { return x.inv.b; })
      .def_property_readonly("theta", [](const Measures& x) { return x.inv.theta; })
      .def_readonly("strain", &Measures::strain)
      .def_readonly("strain_engineering", &Measures::strain_engineering)
      .def_readonly("strain_rate", &Measures::strain_rate)
      .def_readonly("eps_v", &Measures::eps_v)
      .def_readonly("eps_q", &Measures::eps_q)
      .def_readonly("void_ratio", &Measures::void_ratio)
      .def_property_readonly("e", [](const Measures& x) { return x.void_ratio; })
      .def_readonly("solid_fraction", &Measures::solid_fraction)
      .def_readonly("contacts", &Measures::contacts)
      .def_readonly("rattlers", &Measures::rattlers)
      .def_readonly("z", &Measures::z)
      .def_readonly("z_mech", &Measures::z_mech)
      .def_readonly("fabric", &Measures::fabric)
      .def_readonly("unbalanced", &Measures::unbalanced)
      .def_readonly("kinetic_energy", &Measures::kinetic_energy)
      .def_readonly("elastic_energy", &Measures::elastic_energy)
      .def_readonly("max_overlap_ratio", &Measures::max_overlap_ratio)
      .def_readonly("inertial_number", &Measures::inertial_number)
      .def_readonly("inertial_number_axial", &Measures::inertial_number_axial);

  py::class_<PyWorld>(m, "World",
                      "One scene: World(model, state, threads=1, initial_forces=True, partition='adaptive'). Arrays "
                      "are read-only NumPy views into the engine, "
                      "valid until the next step (docs/python.md)")
      .def(py::init([](const Model& model, const State& state, int threads, bool initial_forces,
                       const std::string& partition) {
             if (threads < 1) throw std::invalid_argument("threads = " + std::to_string(threads) + ": must be >= 1");
             // How the threads share each pass; every one gives bitwise the same results.
             const std::optional<Partition> named = partition_from_name(partition);
             if (!named)
               throw std::invalid_argument("partition = '" + partition +
                                           "': allowed 'adaptive', 'owner', 'dynamic' or 'fixed'");
             PyWorld w;
             if (const PythonPath* p = model.servo.custom.target<PythonPath>()) {
               w.slot = p->slot;
               w.path = p->fn;
             }
             w.world = std::make_unique<World>(model, state, systems_for(model),
                                               ExecutorConfig{Backend::tbb, threads, *named}, initial_forces);
             return w;
           }),
           py::arg("model"), py::arg("state"), py::arg("threads") = 1, py::arg("initial_forces") = true,
           py::arg("partition") = "adaptive")
      .def(
          "step", [](PyWorld& w, std::uint64_t n) { w.guarded([&] { w.world->step(n); }); }, py::arg("n") = 1,
          "Advances n steps (the GIL is released; a Python path takes it on servo updates)")
      .def(
          "step_until",
          [](PyWorld& w, std::uint64_t n, std::uint64_t every, std::optional<double> max_strain, int axis,
             const py::object& path, const py::object& stop) {
            if (axis < 0 || axis > 2)
              throw std::invalid_argument("axis = " + std::to_string(axis) + ": must be 0, 1 or 2");
            std::optional<CyclicPath> cyclic;
            if (!path.is_none()) {
              if (!py::isinstance<CyclicPath>(path))
                throw std::invalid_argument("path: must be a CyclicPath (stops when finished)");
              cyclic = path.cast<CyclicPath>();
            }
            const bool py_stop = !stop.is_none();
            if (py_stop && !PyCallable_Check(stop.ptr()))
              throw std::invalid_argument("stop: must be callable (step, cell_length) -> bool");
            std::optional<py::error_already_set> stop_error;
            std::uint64_t done = 0;
            done = w.guarded([&] {
              return w.world->step_until(n, [&](Cell& cell, const Clock& clock) {
                if (every > 0 && clock.step % every == 0) return true;
                if (max_strain && -std::log(cell.length[axis] / cell.length0[axis]) >= *max_strain) return true;
                if (cyclic && cyclic->finished()) return true;
                if (!py_stop) return false;
                py::gil_scoped_acquire gil;
                try {
                  return stop(clock.step, cell.length).cast<bool>();
                } catch (py::error_already_set& e) {
                  stop_error = std::move(e);
                  return true;
                }
              });
            });
            if (stop_error) throw *stop_error;
            return done;
          },
          py::arg("n"), py::kw_only(), py::arg("every") = 0, py::arg("max_strain") = py::none(), py::arg("axis") = 0,
          py::arg("path") = py::none(), py::arg("stop") = py::none(),
          "Advances at most n steps, stopping after the first step at a multiple of `every`, at a logarithmic strain of "
          "`axis` >= max_strain, when the CyclicPath `path` is finished, or when stop(step, cell_length) is true (a "
          "Python stop is called every step: slow). Returns the steps done.")
      .def(
          "measure",
          [](PyWorld& w, bool kinetic_stress, double d50, double density) {
            return w.guarded([&] { return measure_world(*w.world, kinetic_stress, d50, density); });
          },
          py::kw_only(), py::arg("kinetic_stress") = false, py::arg("d50") = 0.0, py::arg("density") = 0.0,
          "Every measure of docs/physics.md section 5 on the current state")
      .def_property_readonly(
          "model", [](const PyWorld& w) { return w.world->model(); }, "A copy of the model")
      .def(
          "state", [](const PyWorld& w) { return w.world->state(); }, "A copy of the state")
      .def_property_readonly("step_count", [](const PyWorld& w) { return w.world->state().clock.step; })
      .def_property_readonly("time", [](const PyWorld& w) { return w.world->state().clock.time; })
      .def_property_readonly(
          "particles", [](py::object self) { return particle_views(self, self.cast<PyWorld&>().world->state()); },
          "Read-only views of the particle arrays, valid until the next step")
      .def_property_readonly(
          "contacts", [](py::object self) { return contact_views(self, self.cast<PyWorld&>().world->state()); },
          "Read-only views of the contact arrays, valid until the next step")
      .def_property_readonly(
          "cell", [](py::object self) { return cell_views(self, self.cast<PyWorld&>().world->state()); },
          "Read-only views of the cell's 3-vectors (length, length0, rate, servo_integral)")
      .def(
          "set_cell_rate",
          [](PyWorld& w, const py::object& v) {
            const Vec3 r = vec3("rate", v);
            if (!r.allFinite()) throw std::invalid_argument("rate: must be finite (1/s, D_kk, tension positive)");
            w.world->state().cell.rate = r;
          },
          py::arg("rate"), "Sets the cell's D_kk (1/s, tension positive) for the next step")
      .def(
          "write_checkpoint",
          [](PyWorld& w, const std::string& path, const py::object& extra) {
            write_checkpoint(path, w.world->state(), extra_from_dict(extra));
          },
          py::arg("path"), py::arg("extra") = py::none())
      .def(
          "_address",
          [](const PyWorld& w, const std::string& name) {
            const Particles& p = w.world->state().particles;
            if (name == "position") return reinterpret_cast<std::uintptr_t>(p.position.data());
            if (name == "velocity") return reinterpret_cast<std::uintptr_t>(p.velocity.data());
            if (name == "force") return reinterpret_cast<std::uintptr_t>(p.force.data());
            if (name == "radius") return reinterpret_cast<std::uintptr_t>(p.radius.data());
            if (name == "contact_force")
              return reinterpret_cast<std::uintptr_t>(w.world->state().contacts.forces.force.data());
            throw std::invalid_argument("name = '" + name +
                                        "': allowed: position, velocity, force, radius, contact_force");
          },
          py::arg("name"), "The C++ array's data address (for the tests of the views)")
      .def("defers_work", [](const PyWorld& w) { return w.world->defers_work(); });

  m.def(
      "write_checkpoint",
      [](const std::string& path, const State& state, const py::object& extra) {
        write_checkpoint(path, state, extra_from_dict(extra));
      },
      py::arg("path"), py::arg("state"), py::arg("extra") = py::none());
  m.def(
      "read_checkpoint",
      [](const std::string& path) {
        CheckpointExtra extra;
        State s = read_checkpoint(path, &extra);
        return py::make_tuple(std::move(s), extra_to_dict(extra));
      },
      py::arg("path"), "(State, extra dict with doubles, integers, strings)");

  py::class_<ResultsFile>(m, "ResultsFile", "A results file (engine/results.hpp)")
      .def_static(
          "create",
          [](const std::string& path, const std::string& config_text,
             const std::map<std::string, std::string>& attributes) {
            return ResultsFile::create(path, config_text, attributes);
          },
          py::arg("path"), py::arg("config_text") = "", py::arg("attributes") = std::map<std::string, std::string>{})
      .def_static(
          "reopen",
          [](const std::string& path, std::uint64_t last_step) { return ResultsFile::reopen(path, last_step); },
          py::arg("path"), py::arg("last_step"))
      .def_property_readonly("path", [](const ResultsFile& r) { return r.path().string(); })
      .def(
          "append",
          [](ResultsFile& r, const std::string& name, const py::object& values, const std::string& units) {
            const auto a = py::array_t<double, py::array::forcecast | py::array::c_style>::ensure(values);
            if (!a || a.ndim() > 1)
              throw std::invalid_argument("values of series '" + name + "': must be a number or a 1-d sequence");
            r.append(name, std::span<const double>(a.data(), static_cast<std::size_t>(a.size())), units);
          },
          py::arg("name"), py::arg("values"), py::arg("units"))
      .def(
          "write_snapshot", [](ResultsFile& r, const PyWorld& w) { r.write_snapshot(w.world->state()); },
          py::arg("world"))
      .def(
          "write_snapshot", [](ResultsFile& r, const State& s) { r.write_snapshot(s); }, py::arg("state"))
      .def("set_attribute",
           py::overload_cast<std::string_view, std::string_view, std::string_view>(&ResultsFile::set_attribute),
           py::arg("group"), py::arg("name"), py::arg("value"))
      .def("set_attribute", py::overload_cast<std::string_view, std::string_view, double>(&ResultsFile::set_attribute),
           py::arg("group"), py::arg("name"), py::arg("value"))
      .def("flush", &ResultsFile::flush)
      .def("close", &ResultsFile::close)
      .def_property_readonly("is_open", &ResultsFile::is_open)
      .def(
          "__enter__", [](ResultsFile& r) -> ResultsFile& { return r; }, py::return_value_policy::reference)
      .def("__exit__", [](ResultsFile& r, const py::args&) { r.close(); });
  // The app's series row (apps/triaxial/protocol/series.hpp: the same columns, units and order).
  m.def(
      "append_row",
      [](ResultsFile& r, const PyWorld& w, const Measures& mm, double wall) {
        triaxial::append_row(r, w.world->state(), mm, wall);
      },
      py::arg("results"), py::arg("world"), py::arg("measures"), py::arg("wall") = 0.0,
      "Appends one row of the triaxial app's series from measure()'s result (docs/physics.md section 8)");
  m.def(
      "append_row",
      [](ResultsFile& r, const State& st, const Measures& mm, double wall) { triaxial::append_row(r, st, mm, wall); },
      py::arg("results"), py::arg("state"), py::arg("measures"), py::arg("wall") = 0.0);
  bind_protocol(m);
  m.def(
      "contact_laws",
      [] {
        py::dict d;
        py::list normal;
        for (const NormalLawInfo& law : normal_laws()) {
          py::list params;
          for (const LawParameter& q : law.parameters)
            params.append(py::dict(py::arg("name") = std::string(q.name), py::arg("units") = std::string(q.units),
                                   py::arg("range") = py::make_tuple(q.lo, q.hi), py::arg("what") = std::string(q.what)));
          normal.append(py::dict(py::arg("name") = law.name, py::arg("parameters") = params));
        }
        d["normal"] = normal;
        d["tangential"] = tangential_law_names();
        d["rolling"] = rolling_law_names();
        return d;
      },
      "The registered contact laws of the three slots (systems/laws/): names, and the normal laws' parameters");
}
