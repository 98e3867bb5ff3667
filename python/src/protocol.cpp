// sandcell.Protocol: the triaxial app's protocol (apps/triaxial/protocol) from Python, so a script
// builds the app's models from the app's config by the app's own rules instead of retyping them.
#include "protocol/accuracy.hpp"
#include "protocol/config.hpp"
#include "protocol/paths.hpp"
#include "protocol/protocol.hpp"
#include "protocol/series.hpp"

#include "engine/generate.hpp"

#include <pybind11/functional.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>

namespace py = pybind11;
using namespace sandcell;
using namespace sandcell::triaxial;

namespace {

// A parsed, derived and checked protocol; a bad config is a ValueError naming the key (ConfigError).
Protocol protocol_of(const std::string& text, const std::string& source) {
  Protocol p = make_protocol(parse_config(text, source));
  validate_servos(p);
  return p;
}

const TestSpec& test_of(const Protocol& p, const py::object& test) {
  if (py::isinstance<py::int_>(test)) {
    const long k = test.cast<long>();
    if (k < 0 || k >= static_cast<long>(p.config.tests.size()))
      throw py::index_error("test " + std::to_string(k) + ": allowed: 0.." + std::to_string(p.config.tests.size() - 1));
    return p.config.tests[static_cast<std::size_t>(k)];
  }
  const std::string name = test.cast<std::string>();
  for (const TestSpec& t : p.config.tests)
    if (t.name == name) return t;
  throw py::key_error("test '" + name + "': not a test of " + p.config.source);
}

}  // namespace

void bind_protocol(py::module_& m) {
  py::register_exception<ConfigError>(m, "ConfigError", PyExc_ValueError);

  py::class_<TestSpec>(m, "TestSpec", "One test of a campaign (apps/triaxial/protocol/config.hpp)")
      .def_readonly("name", &TestSpec::name)
      .def_property_readonly("path", [](const TestSpec& t) { return std::string(path_name(t.path)); })
      .def_readonly("p0", &TestSpec::p0)
      .def_readonly("b", &TestSpec::b)
      .def("__repr__", [](const TestSpec& t) { return "TestSpec('" + t.name + "')"; });

  py::class_<Protocol>(m, "Protocol",
                       "The triaxial app's protocol of a config (apps/triaxial/protocol/protocol.hpp): the derived "
                       "time steps and servo settings, and the models of the preparation and of each test")
      .def_static(
          "load",
          [](const std::string& path) {
            Protocol p = make_protocol(load_config(path));
            validate_servos(p);
            return p;
          },
          py::arg("path"), "Reads, validates and derives a config file (as `triaxial CONFIG --check`)")
      .def_static("parse", &protocol_of, py::arg("text"), py::arg("source") = "<string>",
                  "A config given as TOML text")
      .def_static(
          "default", [] { return protocol_of(k_default_config, "<embedded default>"); },
          "The embedded default test")
      .def_property_readonly("text", [](const Protocol& p) { return p.config.text; })
      .def_property_readonly("tests", [](const Protocol& p) { return p.config.tests; })
      .def_readonly("p0", &Protocol::p0, "distinct preparation stresses, Pa, in the order prepared")
      .def_readonly("diameters", &Protocol::diameters, "the sample's diameters, m")
      .def_readonly("d50", &Protocol::d50, "mass-weighted median diameter, m")
      .def_readonly("r_min", &Protocol::r_min)
      .def_readonly("servo_time", &Protocol::servo_time, "the servo's time unit t_s, s")
      .def_readonly("prepare_dt", &Protocol::prepare_dt, "s")
      .def_readonly("prepare_servo_time", &Protocol::prepare_servo_time, "s")
      .def_property_readonly("dt", [](const Protocol& p) { return p.base.dt; }, "the shear stage's time step, s")
      .def_property_readonly(
          "prepare",
          [](const Protocol& p) {
            const PrepareConfig& c = p.config.prepare;
            py::dict d;
            d["tolerance"] = c.tolerance;
            d["unbalanced"] = c.unbalanced;
            d["check_interval"] = c.check_interval;
            d["max_steps"] = c.max_steps;
            d["chain"] = c.chain;
            return d;
          },
          "the preparation's convergence settings ([prepare])")
      .def_property_readonly(
          "shear",
          [](const Protocol& p) {
            const ShearConfig& c = p.config.shear;
            py::dict d;
            d["max_axial_strain"] = c.max_axial_strain;
            d["max_deviatoric_strain"] = c.max_deviatoric_strain;
            d["ramp_strain"] = c.ramp_strain;
            d["stop_at_critical"] = c.stop_at_critical;
            d["steps"] = c.steps;
            return d;
          },
          "the shear stage's stop settings ([shear])")
      .def_property_readonly(
          "output",
          [](const Protocol& p) {
            const OutputConfig& c = p.config.output;
            py::dict d;
            d["series_interval"] = c.series_interval;
            d["snapshot_interval"] = c.snapshot_interval;
            return d;
          },
          "the series and snapshot intervals ([output])")
      .def_property_readonly(
          "watch_stop", [](const Protocol& p) { return p.config.watch.stop; }, "[watch] stop")
      .def(
          "cloud",
          [](const Protocol& p, const Model& model) {
            return make_state(model, p.from_file ? p.packing : generate_packing(p.config.sample.generation));
          },
          py::arg("model"), "The preparation's start: the packing file's spheres, or the cloud [sample] generates")
      .def("prepare_model", &prepare_model, py::arg("p0"), "The preparation's model: isotropic stress control to p0")
      .def(
          "shear_model", [](const Protocol& p, const py::object& t) { return shear_model(p, test_of(p, t)); },
          py::arg("test"), "The model of a test (its index or name): path, targets, servo")
      .def(
          "resolved_settings", [](const Protocol& p, const py::object& t) { return resolved_settings(p, test_of(p, t)); },
          py::arg("test"), "The run record's settings text of a test (its index or name), as the app writes it")
      .def(
          "axial_rate", [](const Protocol& p, const py::object& t) { return axial_rate(p, test_of(p, t).p0); },
          py::arg("test"), "The axial rate at p = p0, 1/s")
      .def(
          "path_watch", [](const Protocol& p, const py::object& t) { return make_path_watch(p, test_of(p, t)); },
          py::arg("test"), "The test's stress-path watchdog ([watch], checks from the ramp's end)")
      .def(
          "cyclic_path",
          [](const Protocol&, const Model& model) -> py::object {
            const CyclicPath* c = cyclic_path(model);
            return c ? py::cast(*c) : py::none();  // a copy: the memory is shared with the model's (and a World's)
          },
          py::arg("model"), "The CyclicPath of a cyclic test's model (for World.step_until(path=...)), else None")
      .def(
          "start_test",
          [](const Protocol& p, const py::object& t, State state) {
            start_test(p, test_of(p, t), state);
            return state;
          },
          py::arg("test"), py::arg("sample"),
          "The prepared sample made the start of the test: clock, strains and servo state reset, first rates set "
          "(a new State)");
  m.def(
      "finish_preparation",
      [](State state) {
        finish_preparation(state);
        return state;
      },
      py::arg("state"), "The prepared sample, its strains counted from here (a new State)");
  m.def(
      "derived_servo",
      [](const std::string& stage, double p, const Material& material, double servo_time) {
        if (stage != "prepare" && stage != "shear")
          throw std::invalid_argument("stage = '" + stage + "': allowed: prepare, shear");
        const DerivedServo d = derived_servo(stage == "prepare" ? Stage::prepare : Stage::shear, p, material, servo_time);
        return py::make_tuple(d.gain, d.integral_time);
      },
      py::arg("stage"), py::arg("p"), py::arg("material"), py::arg("servo_time"),
      "(gain 1/s, integral_time s) the app derives for a stage at stress p: alpha (p/E*)^(2/3) / t_s with alpha 0.05 "
      "(prepare, P law: integral 0) or 0.1 (shear, integral 1000 t_s); docs/physics.md section 6");
  m.def("servo_time_unit", &servo_time_unit, py::arg("dt"), py::arg("r_min"), py::arg("material"),
        "The servo's time unit t_s = max(dt, 0.2 Rayleigh time of the smallest sphere), s");
  m.def("derived_gain", &derived_gain, py::arg("alpha"), py::arg("p"), py::arg("material"), py::arg("servo_time"),
        "The app's servo gain, 1/s: alpha (p/E*)^(2/3) / t_s, E* = E / (2 (1 - nu^2)) (docs/physics.md section 6)");
  m.def(
      "test_paths",
      [] {
        py::list out;
        for (const TestPath& t : test_paths()) {
          py::dict d;
          d["name"] = std::string(t.name);
          d["prefix"] = std::string(t.prefix);
          d["has_b"] = t.has_b;
          d["by_steps"] = t.by_steps;
          d["inertial_number"] = t.inertial_number;
          d["ramp"] = t.ramp;
          d["description"] = std::string(t.description);
          out.append(d);
        }
        return out;
      },
      "The paths a triaxial test can follow (tests.path; apps/triaxial/protocol/paths.cpp), one dict each");
  m.def("p0_tag", &p0_tag, py::arg("p0"), "'p0_500kPa': the tag of a p0 in the app's file names");
  m.def(
      "series_columns",
      [] {
        py::list out;
        for (const SeriesColumn& c : series_columns()) out.append(py::make_tuple(c.name, c.units, c.width));
        return out;
      },
      "The results files' series: (name, units, width) of every column, in order (protocol/series.hpp)");

  py::class_<AccuracyWatch>(m, "AccuracyWatch",
                            "The app's live accuracy indicators (inertial number, unbalanced force, kinetic/elastic "
                            "energy, overlap), each with its safe range (protocol/accuracy.hpp)")
      .def(py::init<std::string, std::function<void(const std::string&)>>(), py::arg("job"), py::arg("warn"),
           "warn(line) receives each warning, once per indicator")
      .def("check", &AccuracyWatch::check, py::arg("measures"), py::arg("step"))
      .def("worst", &AccuracyWatch::worst);
}
