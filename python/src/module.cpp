// The Python front end (docs/python.md): module sandcell._sandcell, wrapped by the package sandcell.
// Settings are plain classes with attribute access, checked as they are set; the World and its
// lifetime rules (views, reentrancy, rollback) are in world.cpp. Bad input raises ValueError naming
// the argument, its value and what is allowed (the engine's std::invalid_argument is translated to
// ValueError by pybind11).
#include "common.hpp"

#include "protocol/series.hpp"
#include "systems/contact_pass.hpp"
#include "systems/homogenizer.hpp"
#include "systems/kinematics.hpp"
#include "systems/path_watch.hpp"
#include "systems/servo.hpp"
#include "systems/stress_paths.hpp"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>

namespace py = pybind11;
using namespace sandcell;
using namespace sandcell::python;

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
const Names<TimeStepRule> k_time_step_rules{{{"fixed", TimeStepRule::fixed}, {"stiffness", TimeStepRule::stiffness}}};
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

// A shear component is strain or stress controlled (a volume constraint is the axes' alone).
const Names<AxisControl> k_shear_controls{{{"strain", AxisControl::strain}, {"stress", AxisControl::stress}}};

std::array<AxisControl, 3> parse_shear_controls(const std::string& key, const std::vector<std::string>& names) {
  if (names.size() != 3)
    throw std::invalid_argument(key + ": " + std::to_string(names.size()) +
                                " entries: must be 3 (one per shear component xy, xz, yz)");
  std::array<AxisControl, 3> c{};
  for (int k = 0; k < 3; ++k) {
    const std::string item = key + "[" + k_shear_names[k] + "]";
    if (names[k] == "volume")
      throw std::invalid_argument(item + " = 'volume': a shear component is strain or stress controlled; allowed: "
                                         "strain, stress");
    c[k] = k_shear_controls.parse(item, names[k]);
  }
  return c;
}

// A 3-vector of integers (the cell's flip counts), as doubles.
Vec3 integers3(const std::string& key, const py::handle& value) {
  const Vec3 v = vec3(key, value);
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(v[k]) || v[k] != std::round(v[k]) || std::abs(v[k]) > 1e9)
      throw std::invalid_argument(key + "[" + k_shear_names[k] + "] = " + number(v[k]) +
                                  ": must be an integer (flips of the cell's lattice basis, |n| <= 1e9)");
  return v;
}

// A 3x3 tensor of finite numbers, for the kinematic functions.
Mat3 finite_tensor(const std::string& key, const Mat3& m) {
  if (!m.allFinite()) throw std::invalid_argument(key + ": must be a 3x3 tensor of finite numbers");
  return m;
}

// A path function given as servo.custom: a CyclicPath, a C++ PathFunction or a Python callable.
PathFunction path_function(const py::object& value) {
  if (value.is_none()) return {};
  if (py::isinstance<CyclicPath>(value)) return value.cast<CyclicPath>();
  if (py::isinstance<PathFunction>(value)) return value.cast<PathFunction>();
  if (!PyCallable_Check(value.ptr()))
    throw std::invalid_argument("servo.custom: " + std::string(py::str(py::type::of(value))) +
                                ": must be callable (PathInput -> PathTargets), a CyclicPath or undrained_path(rate)");
  return PythonPath{value};
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

// A 3-vector of finite numbers.
Vec3 finite3(const std::string& key, const py::handle& value, const char* unit) {
  const Vec3 v = vec3(key, value);
  for (int k = 0; k < 3; ++k) finite(key + "[" + std::to_string(k) + "]", v[k], unit);
  return v;
}

// A material's properties, each checked as it is set (the constructor and the attributes alike).
void check_density(double v) { positive("density", v, "kg/m^3"); }
void check_young(double v) { positive("young", v, "Pa"); }
void check_poisson(double v) {
  if (!(v > -1.0 && v < 0.5)) throw std::invalid_argument("poisson = " + number(v) + ": must be in (-1, 0.5)");
}
void check_restitution(double v) {
  if (!(v > 0.0 && v <= 1.0)) throw std::invalid_argument("restitution = " + number(v) + ": must be in (0, 1]");
}
void check_friction(double v) { non_negative("friction", v, "(Coulomb coefficient)"); }
void check_rolling_friction(double v) { non_negative("rolling_friction", v, "(rolling resistance coefficient)"); }

// A settings attribute whose setter checks the value: def_property with getter and checked setter.
template <class C, class T, class Check>
auto checked_setter(T C::*member, Check check) {
  return [member, check](C& c, T v) {
    check(v);
    c.*member = v;
  };
}

}  // namespace

// ---- shared with world.cpp (common.hpp) ---------------------------------------------------------

namespace sandcell::python {

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

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
    throw std::invalid_argument(key + " = " + number(v) + ": must be a finite value > 0 " + unit);
  return v;
}

double non_negative(const std::string& key, double v, const char* unit) {
  if (!(v >= 0.0) || !std::isfinite(v))
    throw std::invalid_argument(key + " = " + number(v) + ": must be a finite value >= 0 " + unit);
  return v;
}

double finite(const std::string& key, double v, const char* what) {
  if (!std::isfinite(v)) throw std::invalid_argument(key + " = " + number(v) + ": must be finite " + what);
  return v;
}

Vec3 finite_shear(const std::string& key, const py::handle& value, const char* unit) {
  const Vec3 v = vec3(key, value);
  for (int k = 0; k < 3; ++k) finite(key + "[" + k_shear_names[k] + "]", v[k], unit);
  return v;
}

namespace {
// The names of a sequence of strings (a path result's controls), or ValueError naming the key.
std::vector<std::string> control_strings(const std::string& key, const py::handle& value, const char* allowed) {
  const std::string message = key + ": must be a sequence of 3 of " + allowed;
  if (py::isinstance<py::str>(value) || !py::isinstance<py::sequence>(value)) throw std::invalid_argument(message);
  std::vector<std::string> names;
  for (const py::handle h : value.cast<py::sequence>()) {
    if (!py::isinstance<py::str>(h)) throw std::invalid_argument(message);
    names.push_back(h.cast<std::string>());
  }
  return names;
}
}  // namespace

PathTargets targets_from_python(const py::handle& result) {
  if (py::isinstance<PathTargets>(result)) return result.cast<PathTargets>();
  const std::size_t n = py::isinstance<py::tuple>(result) ? py::len(result) : 0;
  if (n == 2 || n == 4) {
    const py::tuple t = result.cast<py::tuple>();
    PathTargets out;
    out.control =
        parse_controls("path result control", control_strings("path result control", t[0], "strain, stress, volume"));
    out.value = vec3("path result value", t[1]);
    if (n == 4) {
      out.shear_control = parse_shear_controls(
          "path result shear_control", control_strings("path result shear_control", t[2], "strain, stress"));
      out.shear_value = vec3("path result shear_value", t[3]);
    }
    return out;
  }
  throw std::invalid_argument("path result: " + std::string(py::str(py::type::of(result))) +
                              (py::isinstance<py::tuple>(result) ? " of " + std::to_string(n) + " items" : "") +
                              ": must be a sandcell.PathTargets, a tuple (control[3], value[3]) or (control[3], "
                              "value[3], shear_control[3], shear_value[3])");
}

PathTargets PythonPath::operator()(const PathInput& in) const {
  py::gil_scoped_acquire gil;
  return targets_from_python(fn(in));
}

py::dict extra_to_dict(const CheckpointExtra& x) {
  py::dict d;
  d["doubles"] = x.doubles;
  d["integers"] = x.integers;
  d["strings"] = x.strings;
  return d;
}

namespace {
// One entry of a checkpoint's extra: name -> value of type T, or ValueError naming it.
template <class T>
std::map<std::string, T> extra_entries(const std::string& group, const py::handle& value, const char* allowed) {
  if (!py::isinstance<py::dict>(value))
    throw std::invalid_argument("extra['" + group + "']: " + std::string(py::str(py::type::of(value))) +
                                ": must be a dict of name -> " + allowed);
  std::map<std::string, T> out;
  for (const auto& [key, item] : value.cast<py::dict>()) {
    if (!py::isinstance<py::str>(key))
      throw std::invalid_argument("extra['" + group + "']: key " + std::string(py::repr(key)) + ": must be a str");
    const std::string name = py::cast<std::string>(key);
    try {
      out[name] = py::cast<T>(item);
    } catch (const py::cast_error&) {
      std::string shown = py::repr(item);
      if (shown.size() > 60) shown = shown.substr(0, 57) + "...";
      throw std::invalid_argument("extra['" + group + "']['" + name + "'] = " + shown + ": must be " + allowed);
    }
  }
  return out;
}
}  // namespace

CheckpointExtra extra_from_dict(const py::handle& o) {
  CheckpointExtra x;
  if (o.is_none()) return x;
  if (!py::isinstance<py::dict>(o))
    throw std::invalid_argument("extra: " + std::string(py::str(py::type::of(o))) +
                                ": must be a dict with keys doubles, integers, strings");
  for (const auto& [key, value] : o.cast<py::dict>()) {
    const std::string k = py::isinstance<py::str>(key) ? key.cast<std::string>() : std::string(py::repr(key));
    if (k == "doubles")
      x.doubles = extra_entries<std::vector<double>>(k, value, "a sequence of numbers, e.g. [5e5]");
    else if (k == "integers")
      x.integers = extra_entries<std::vector<std::int64_t>>(k, value, "a sequence of integers, e.g. [3]");
    else if (k == "strings")
      x.strings = extra_entries<std::string>(k, value, "a str");
    else
      throw std::invalid_argument("extra['" + k + "']: unknown key; allowed: doubles, integers, strings");
  }
  return x;
}

}  // namespace sandcell::python

void bind_protocol(py::module_& m);  // protocol.cpp: sandcell.Protocol and the triaxial series

PYBIND11_MODULE(_sandcell, m) {
  m.doc() = "sandcell: DEM engine for stress-controlled periodic element tests (docs/python.md)";
  m.attr("__version__") = std::string(version());
  py::register_exception<SimulationError>(m, "SimulationError", PyExc_RuntimeError);

  py::class_<Material>(m, "Material", "A sphere material (SI units); each property is checked as it is set")
      .def(py::init([](double density, double young, double poisson, double restitution, double friction,
                       double rolling_friction) {
             check_density(density);
             check_young(young);
             check_poisson(poisson);
             check_restitution(restitution);
             check_friction(friction);
             check_rolling_friction(rolling_friction);
             return Material{density, young, poisson, restitution, friction, rolling_friction};
           }),
           py::arg("density") = 2650.0, py::arg("young") = 70e9, py::arg("poisson") = 0.3, py::arg("restitution") = 0.5,
           py::arg("friction") = 0.5, py::arg("rolling_friction") = 0.1)
      .def_property("density", [](const Material& a) { return a.density; },
                    checked_setter(&Material::density, check_density))
      .def_property("young", [](const Material& a) { return a.young; }, checked_setter(&Material::young, check_young))
      .def_property("poisson", [](const Material& a) { return a.poisson; },
                    checked_setter(&Material::poisson, check_poisson))
      .def_property("restitution", [](const Material& a) { return a.restitution; },
                    checked_setter(&Material::restitution, check_restitution))
      .def_property("friction", [](const Material& a) { return a.friction; },
                    checked_setter(&Material::friction, check_friction))
      .def_property("rolling_friction", [](const Material& a) { return a.rolling_friction; },
                    checked_setter(&Material::rolling_friction, check_rolling_friction))
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
      .def_property("rolling_damping", [](const ContactSettings& c) { return c.rolling_damping; },
                    checked_setter(&ContactSettings::rolling_damping,
                                   [](double v) { non_negative("contact.rolling_damping", v, "(-)"); }))
      .def_property("skin", [](const ContactSettings& c) { return c.skin; },
                    checked_setter(&ContactSettings::skin, [](double v) { positive("contact.skin", v, "m"); }))
      .def_readwrite("liggghts_compat", &ContactSettings::liggghts_compat)
      .def_property("sort_interval", [](const ContactSettings& c) { return c.sort_interval; },
                    checked_setter(&ContactSettings::sort_interval, [](int v) {
                      if (v < 0)
                        throw std::invalid_argument("contact.sort_interval = " + std::to_string(v) +
                                                    ": must be >= 0 steps (0: never)");
                    }));

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
      .def_readonly("deformation", &PathInput::deformation,
                    "F = H N H0^-1 since the reference (3x3; tension positive, the engine's convention)")
      .def_readonly("shear_strain_rate", &PathInput::shear_strain_rate,
                    "(xy, xz, yz) engineering shear rates -L_ab applied until now, 1/s (compression positive)")
      .def_property_readonly("p", [](const PathInput& i) { return i.stress.trace() / 3.0; })
      .def_property_readonly("eps_v", [](const PathInput& i) { return i.strain.sum(); });

  py::class_<PathTargets>(m, "PathTargets",
                          "A custom path's answer: per axis 'strain' (value 1/s), 'stress' (value Pa) or 'volume'; "
                          "per shear component xy, xz, yz 'strain' (shear_value: engineering rate -L_ab, 1/s) or "
                          "'stress' (shear_value: S_ab, Pa), compression positive")
      .def(py::init([](const std::vector<std::string>& control, const py::object& value,
                       const std::vector<std::string>& shear_control, const py::object& shear_value) {
             PathTargets t;
             t.control = parse_controls("control", control);
             t.value = vec3("value", value);
             t.shear_control = parse_shear_controls("shear_control", shear_control);
             t.shear_value = vec3("shear_value", shear_value);
             return t;
           }),
           py::arg("control"), py::arg("value") = py::make_tuple(0.0, 0.0, 0.0),
           py::arg("shear_control") = std::vector<std::string>{"strain", "strain", "strain"},
           py::arg("shear_value") = py::make_tuple(0.0, 0.0, 0.0))
      .def_property(
          "control", [](const PathTargets& t) { return control_names(t.control); },
          [](PathTargets& t, const std::vector<std::string>& c) { t.control = parse_controls("control", c); })
      .def_property(
          "value", [](const PathTargets& t) { return t.value; },
          [](PathTargets& t, const py::object& v) { t.value = vec3("value", v); })
      .def_property(
          "shear_control", [](const PathTargets& t) { return control_names(t.shear_control); },
          [](PathTargets& t, const std::vector<std::string>& c) {
            t.shear_control = parse_shear_controls("shear_control", c);
          })
      .def_property(
          "shear_value", [](const PathTargets& t) { return t.shear_value; },
          [](PathTargets& t, const py::object& v) { t.shear_value = vec3("shear_value", v); });

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

  py::class_<ServoSettings> servo_settings(m, "ServoSettings",
                                           "The periodic servo and its stress path (docs/physics.md section 6)");
  // The servo's numbers that must be finite and >= 0, checked as they are set (ServoSettings.validate()
  // and World check the whole set).
  for (const auto& [name, member, unit] : {
           std::tuple{"ramp_time", &ServoSettings::ramp_time, "s (0: the full rate from the start)"},
           std::tuple{"inertial_number", &ServoSettings::inertial_number, "(0: strain_rate as given)"},
           std::tuple{"d50", &ServoSettings::d50, "m"},
           std::tuple{"density", &ServoSettings::density, "kg/m^3"},
           std::tuple{"gain", &ServoSettings::gain, "1/s"},
           std::tuple{"integral_time", &ServoSettings::integral_time, "s (0: no integral term)"},
           std::tuple{"max_rate", &ServoSettings::max_rate, "1/s"},
           std::tuple{"max_rate_ratio", &ServoSettings::max_rate_ratio, "(0: max_rate alone)"},
           std::tuple{"integral_strain", &ServoSettings::integral_strain, "(0: integral_time alone)"},
           std::tuple{"normal_stress", &ServoSettings::normal_stress,
                      "Pa (S_zz of the simple_shear path, compression positive; > 0 on that path)"},
           std::tuple{"q", &ServoSettings::q, "Pa (deviator of the rotation path)"},
           std::tuple{"gain_time", &ServoSettings::gain_time,
                      "s (> 0: the gain is scaled by gain_time / dt at a longer step; 0: as given)"},
       }) {
    const std::string key = std::string("servo.") + name;
    servo_settings.def_property(name, [member](const ServoSettings& s) { return s.*member; },
                                checked_setter(member, [key, unit](double v) { non_negative(key, v, unit); }));
  }
  servo_settings
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
          [](ServoSettings& s, const py::object& v) { s.strain_rate = finite3("servo.strain_rate", v, "(1/s)"); })
      .def_property(
          "target", [](const ServoSettings& s) { return s.target; },
          [](ServoSettings& s, const py::object& v) { s.target = finite3("servo.target", v, "(Pa)"); })
      .def_property("p", [](const ServoSettings& s) { return s.p; },
                    checked_setter(&ServoSettings::p, [](double v) { finite("servo.p", v, "Pa (compression positive)"); }))
      .def_property("b", [](const ServoSettings& s) { return s.b; },
                    checked_setter(&ServoSettings::b, [](double v) {
                      if (!(v >= 0.0 && v <= 1.0)) throw std::invalid_argument("servo.b = " + number(v) + ": must be in [0, 1]");
                    }))
      .def_property("sigma3", [](const ServoSettings& s) { return s.sigma3; },
                    checked_setter(&ServoSettings::sigma3, [](double v) { finite("servo.sigma3", v, "Pa (compression positive)"); }))
      // The shear components xy, xz, yz (docs/physics.md section 6.2), named so in the messages.
      .def_property(
          "shear_control", [](const ServoSettings& s) { return control_names(s.shear_control); },
          [](ServoSettings& s, const std::vector<std::string>& c) {
            s.shear_control = parse_shear_controls("servo.shear_control", c);
          },
          "Per shear component xy, xz, yz: 'strain' (at shear_strain_rate) or 'stress' (toward shear_target)")
      .def_property(
          "shear_strain_rate", [](const ServoSettings& s) { return s.shear_strain_rate; },
          [](ServoSettings& s, const py::object& v) {
            s.shear_strain_rate = finite_shear("servo.shear_strain_rate", v,
                                               "(1/s, engineering gamma_dot = -L_ab, compression positive)");
          },
          "(xy, xz, yz) engineering shear rates gamma_dot = -L_ab, 1/s, of the strain-controlled components")
      .def_property(
          "shear_target", [](const ServoSettings& s) { return s.shear_target; },
          [](ServoSettings& s, const py::object& v) {
            s.shear_target = finite_shear("servo.shear_target", v, "(Pa, S_ab, compression positive)");
          },
          "(xy, xz, yz) shear stress targets S_ab, Pa, of the stress-controlled components")
      .def_property("rotation_rate", [](const ServoSettings& s) { return s.rotation_rate; },
                    checked_setter(&ServoSettings::rotation_rate,
                                   [](double v) { finite("servo.rotation_rate", v, "(rad/s, d alpha/dt)"); }),
                    "rad/s, d alpha/dt of the rotation path (alpha: sigma1's angle from x toward z)")
      .def_property("rotation_start", [](const ServoSettings& s) { return s.rotation_start; },
                    checked_setter(&ServoSettings::rotation_start,
                                   [](double v) { finite("servo.rotation_start", v, "(rad, alpha at time 0)"); }),
                    "rad, alpha of the rotation path at clock time 0")
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
            if (const PythonPath* p = s.custom.target<PythonPath>()) return p->fn;
            return py::cast(s.custom);
          },
          [](ServoSettings& s, const py::object& v) {
            // A path function is the servo's path: it enables the servo (a function set on a disabled
            // servo would never be called). None removes it (then World refuses path "custom").
            s.custom = path_function(v);
            if (s.custom) {
              s.path = StressPath::custom;
              s.enabled = true;
            }
          },
          "The custom path: a Python callable (PathInput -> PathTargets or (control, value)), a CyclicPath or "
          "undrained_path(rate); setting it sets path = 'custom' and enabled = True")
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

  py::class_<TimeStepSettings>(m, "TimeStepSettings",
                               "How the time step is chosen: 'fixed' (Model.dt) or 'stiffness' (docs/physics.md 4.1)")
      .def(py::init([](const std::string& rule, double safety, int interval, double max_dt) {
             TimeStepSettings t;
             t.rule = k_time_step_rules.parse("time_step.rule", rule);
             t.safety = safety;
             t.interval = interval;
             t.max_dt = max_dt;
             return t;
           }),
           py::arg("rule") = "fixed", py::arg("safety") = 0.8, py::arg("interval") = 100, py::arg("max_dt") = 0.0,
           "World checks the values (safety in (0, sqrt 2], interval >= 1, max_dt > 0 s) under 'stiffness'")
      .def_property(
          "rule", [](const TimeStepSettings& t) { return k_time_step_rules.name(t.rule); },
          [](TimeStepSettings& t, const std::string& v) { t.rule = k_time_step_rules.parse("time_step.rule", v); })
      .def_readwrite("safety", &TimeStepSettings::safety)
      .def_readwrite("interval", &TimeStepSettings::interval)
      .def_readwrite("max_dt", &TimeStepSettings::max_dt);
  m.def(
      "particle_digest", [](const State& s) { return particle_digest(s); }, py::arg("state"),
      "FNV-1a of the particle state (ids, positions, velocities, spins, cell, clock): the results files' "
      "state_digest and sample_digest");
  m.def(
      "stable_step",
      [](const Model& model, const State& state) {
        Model finalized = model;
        finalized.finalize();
        const StableStepBound b = contact_stable_step(finalized, state);
        py::dict d;
        d["step"] = b.step;
        d["id"] = b.id;
        d["rotational"] = b.rotational;
        d["stiffness"] = b.stiffness;
        return d;
      },
      py::arg("model"), py::arg("state"),
      "The step the state's touching contacts allow before the safety factor (s; inf: none touch), with the sphere "
      "(id), the mode (rotational) and its summed stiffness that bound it (docs/physics.md section 4.1)");

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
      .def_readwrite("servo", &Model::servo)
      .def_readwrite("time_step", &Model::time_step,
                     "fixed (dt throughout) or stiffness (World sets dt every interval steps; World.model.dt: the step "
                     "in effect)");

  m.def(
      "rayleigh_time",
      [](double r_min, const Material& material) { return rayleigh_time(positive("r_min", r_min, "m"), material); },
      py::arg("r_min"), py::arg("material"), "Rayleigh time of a sphere of radius r_min, s");
  m.def(
      "median_diameter",
      [](const std::vector<double>& radius) {
        if (radius.empty()) throw std::invalid_argument("radius: empty; at least one radius is required");
        for (std::size_t k = 0; k < radius.size(); ++k) positive("radius[" + std::to_string(k) + "]", radius[k], "m");
        return median_diameter(radius);
      },
      py::arg("radius"), "Mass-weighted median diameter of spheres of these radii, m");
  m.def(
      "sample_diameters",
      [](double d_min, double d_max, std::size_t count, std::uint64_t seed) {
        GenerationSettings g;
        g.count = count;
        g.sizes.d_min = positive("d_min", d_min, "m");
        g.sizes.d_max = positive("d_max", d_max, "m");
        validate(g);
        return sample_diameters(g.sizes, count, seed);
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
              g.sizes.d_min = positive("d_min", d_min, "m");
              g.sizes.d_max = positive("d_max", d_max, "m");
            } else {
              // The table gives the sizes: d_min and d_max would have no effect.
              for (const auto& [key, v] : {std::pair{"d_min", d_min}, std::pair{"d_max", d_max}})
                if (v != 0.0)
                  throw std::invalid_argument(std::string(key) + " = " + number(v) +
                                              ": has no effect with a gradation table (the table gives the sizes)");
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
          "time", [](const State& s) { return s.clock.time; },
          [](State& s, double t) { s.clock.time = non_negative("time", t, "s"); })
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
          [](State& s, const py::object& v) { s.cell.servo_integral = finite3("servo_integral", v, "(s)"); })
      // The shearing cell (components/cell.hpp): tilts (xy, xz, yz) of H and of the reference H0,
      // the flip counts of N, the shear rates (L_xy, L_xz, L_yz) and the shear servo's integral.
      .def_property(
          "cell_tilt", [](const State& s) { return s.cell.tilt; },
          [](State& s, const py::object& v) { s.cell.tilt = finite_shear("cell_tilt", v, "(m, xy, xz, yz of H)"); })
      .def_property(
          "cell_tilt0", [](const State& s) { return s.cell.tilt0; },
          [](State& s, const py::object& v) {
            s.cell.tilt0 = finite_shear("cell_tilt0", v, "(m, xy, xz, yz of the reference H0)");
          })
      .def_property(
          "cell_flip", [](const State& s) { return s.cell.flip; },
          [](State& s, const py::object& v) { s.cell.flip = integers3("cell_flip", v); },
          "Flip counts (n_xy, n_xz, n_yz) of N: F = H N H0^-1 (integers; [0, 0, 0] with tilt0 = tilt resets F to I)")
      .def_property(
          "cell_shear_rate", [](const State& s) { return s.cell.shear_rate; },
          [](State& s, const py::object& v) {
            s.cell.shear_rate = finite_shear("cell_shear_rate", v, "(1/s, L_xy, L_xz, L_yz, tension positive)");
          })
      .def_property(
          "shear_integral", [](const State& s) { return s.cell.shear_integral; },
          [](State& s, const py::object& v) { s.cell.shear_integral = finite_shear("shear_integral", v, "(s)"); })
      .def_property_readonly(
          "cell_deformation", [](const State& s) { return s.cell.deformation(); },
          "F = H N H0^-1, the deformation gradient since the reference (3x3, a copy)");

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
      .def_readonly("inertial_number_axial", &Measures::inertial_number_axial)
      // Tensor measures (systems/kinematics.hpp): also meaningful for a sheared cell.
      .def_readonly("deformation", &Measures::deformation, "F = H N H0^-1 since the reference (3x3)")
      .def_readonly("strain_tensor", &Measures::strain_tensor,
                    "-ln V, V = sqrt(F F^T): the logarithmic strain tensor, compression positive")
      .def_readonly("strain_rate_tensor", &Measures::strain_rate_tensor, "-(L + L^T)/2, 1/s, compression positive")
      .def_readonly("gamma", &Measures::gamma, "Engineering shear strains (xy, xz, yz) = -(F_xy, F_xz, F_yz)")
      .def_property_readonly(
          "principal_stress", [](const Measures& m) { return m.inv.principal; },
          "Principal stresses, Pa, descending (the invariants' s1, s2, s3)")
      .def_readonly("stress_directions", &Measures::stress_directions, "Columns: their unit directions")
      .def_readonly("principal_strain", &Measures::principal_strain, "Principal values of strain_tensor, descending")
      .def_readonly("strain_directions", &Measures::strain_directions, "Columns: their unit directions")
      .def_readonly("alpha", &Measures::alpha, "Degrees in (-90, 90]: sigma1's direction in xz from x toward z")
      .def_readonly("noncoaxiality", &Measures::noncoaxiality,
                    "Degrees in [0, 90]: between the major directions of stress and strain_rate_tensor");

  // The kinematic functions (systems/kinematics.hpp) on any tensors, e.g. two rows of a results file.
  m.def(
      "log_strain",
      [](const Mat3& f) {
        finite_tensor("F", f);
        const double det = f.determinant();
        if (!(det > 0.0))
          throw std::invalid_argument("F: det F = " + number(det) + ": must be > 0 (a deformation gradient)");
        return log_strain(f);
      },
      py::arg("F"), "-ln sqrt(F F^T): the logarithmic (Hencky) strain of F, compression positive");
  m.def(
      "principal",
      [](const Mat3& sym) {
        const Principal p = principal(finite_tensor("tensor", sym));
        return py::make_tuple(p.values, p.directions);
      },
      py::arg("tensor"),
      "(values, directions): principal values descending, unit directions as columns (largest component positive) "
      "of the symmetric part of a 3x3 tensor");
  m.def(
      "strain_rate_tensor", [](const Mat3& l) { return strain_rate_tensor(finite_tensor("L", l)); }, py::arg("L"),
      "-(L + L^T)/2 of a velocity gradient L (tension positive): the strain rate, compression positive");
  m.def(
      "axes_rotation_deg", [](const Mat3& t) { return axes_rotation_deg(finite_tensor("tensor", t)); },
      py::arg("tensor"), "Degrees between the major principal direction and the nearest of x, y, z");
  m.def(
      "alpha_deg", [](const Mat3& t) { return alpha_deg(finite_tensor("tensor", t)); }, py::arg("tensor"),
      "Degrees in (-90, 90]: the major principal direction of the xz block from x toward z (the rotation path's "
      "alpha), atan2(2 S_xz, S_xx - S_zz) / 2");
  m.def(
      "noncoaxiality_deg",
      [](const Mat3& stress, const Mat3& increment) {
        return noncoaxiality_deg(finite_tensor("stress", stress), finite_tensor("strain_increment", increment));
      },
      py::arg("stress"), py::arg("strain_increment"),
      "Degrees in [0, 90] between the major principal directions of a stress and a strain increment (both "
      "compression positive); 0 when either is isotropic");

  bind_world(m);

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
          "write_snapshot", [](ResultsFile& r, const PyWorld& w) { r.write_snapshot(w.state("ResultsFile.write_snapshot")); },
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
        triaxial::append_row(r, w.state("append_row"), mm, wall);
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
