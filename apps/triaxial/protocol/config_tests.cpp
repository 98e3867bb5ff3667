// The config's test-side tables: [shear], [tests] (the campaign), [output], [watch], [cyclic], and
// the checks across tables (the paths' rate keys, the preparation's step).
#include "protocol/config_section.hpp"

#include "protocol/critical.hpp"
#include "protocol/paths.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace sandcell::triaxial::config_detail {
// [shear]: the axial rate (or inertial number), the lateral servo, the stop tests and the strain path.
void parse_shear(const toml::table& root, const std::string& source, ShearConfig& h) {
  Section s = section(root, "shear", source);
  s.positive("strain_rate", h.strain_rate, "1/s");
  // Above I ~ 0.1 dense granular flow is inertial (GDR MiDi 2004): no element test.
  s.number("inertial_number", h.inertial_number, std::nextafter(0.0, 1.0), 0.1,
           "must be in (0, 0.1] (eps_dot_1 d50 sqrt(rho/p); quasi-static tests: <= 3e-3)");
  s.number("ramp_strain", h.ramp_strain, 0.0, 1.0, "must be in [0, 1] (axial strain of the rate ramp; 0: none)");
  s.number("gain", h.gain, 0.0, 1e9, "must be >= 0 1/s (0: derived)");
  s.number("integral_time", h.integral_time, 0.0, 1e9, "must be >= 0 s (0: derived)");
  s.number("integral_strain", h.integral_strain, 0.0, 1.0, "must be in [0, 1] (0: the derived integral time alone)");
  s.number("max_rate", h.max_rate, 0.0, 1e9, "must be >= 0 1/s (0: max_rate_ratio x the axial rate at p0)");
  s.number("max_rate_ratio", h.max_rate_ratio, 0.0, 1e6,
           "must be >= 0 (the cap on the stress-controlled axes' rates as a multiple of the axial rate; 0: the fixed "
           "max_rate alone)");
  s.integer("servo_interval", h.servo_interval, 1, 1'000'000, "must be an integer in [1, 1e6] steps");
  s.number("max_axial_strain", h.max_axial_strain, 1e-9, 2.0, "must be in (0, 2] (logarithmic strain)");
  s.number("max_deviatoric_strain", h.max_deviatoric_strain, 0.0, 2.0,
           "must be in [0, 2] (eps_q of the logarithmic strains; 0: none, the test ends at max_axial_strain)");
  s.boolean("stop_at_critical", h.stop_at_critical);
  s.number("critical_window", h.critical_window, 1e-6, 1.0, "must be in (0, 1]");
  s.number("critical_tolerance", h.critical_tolerance, 1e-9, 1.0, "must be in (0, 1]");
  s.number("critical_tolerance_e", h.critical_tolerance_e, 1e-9, 1.0, "must be in (0, 1]");
  s.number("critical_tolerance_fabric", h.critical_tolerance_fabric, 1e-9, 1.0, "must be in (0, 1]");
  const std::vector<double> rates = s.numbers("strain_rates", "three finite rates in 1/s");
  if (!rates.empty()) {
    if (rates.size() != 3) s.fail("strain_rates", std::to_string(rates.size()) + " values", "expected 3 rates (1/s)");
    // At 1e6 1/s a cell changes by its own size in a microsecond: no element test is that fast (1e308
    // collapsed the cell in the first step, blamed on shear.steps). The strain a step is bounded
    // once dt is known (run.cpp, check_strain_per_step).
    for (std::size_t k = 0; k < 3; ++k)
      if (!(std::abs(rates[k]) <= 1e6))
        s.fail("strain_rates[" + std::to_string(k) + "]", num(rates[k]),
               "must be in [-1e6, 1e6] 1/s (compression positive)");
    h.strain_rates = Vec3(rates[0], rates[1], rates[2]);
  }
  // The strain path's shear components (a general six-component strain path): -L_xy, -L_xz, -L_yz.
  const std::vector<double> shears = s.numbers("shear_rates", "three finite engineering shear rates in 1/s");
  if (!shears.empty()) {
    if (shears.size() != 3) s.fail("shear_rates", std::to_string(shears.size()) + " values", "expected 3 rates (1/s)");
    for (std::size_t k = 0; k < 3; ++k)
      if (!(std::abs(shears[k]) <= 1e6))
        s.fail("shear_rates[" + std::to_string(k) + "]", num(shears[k]), "must be in [-1e6, 1e6] 1/s (xy, xz, yz)");
    h.shear_rates = Vec3(shears[0], shears[1], shears[2]);
  }
  s.integer("steps", h.steps, 0, UINT64_MAX, "must be an integer >= 0");
  s.number("max_shear_strain", h.max_shear_strain, 1e-9, 1e3,
           "must be in (0, 1000] (engineering shear strain gamma = -F_xz of the simple shear paths)");
  s.check_unknown();
}

// Hertz is a small-overlap law. In a dense sample at mean stress p, a contact carries
// f = 4 pi R^2 p / (phi Z) (p = phi Z f / (4 pi R^2) for equal spheres), so its overlap is
// delta/R = (3 sqrt(2) pi p / (phi Z E*))^(2/3), E* = E / (2 (1 - nu^2)); phi = 0.6, Z = 6.
// Beyond 0.1 of the radius (a loaded contact's overlap is a few times the mean) the law and
// the measures built on it are meaningless: refuse, naming both keys.
void check_contact_overlap(Section& s, const Material& mat, const std::vector<double>& p0) {
  const double e_star = mat.young / (2.0 * (1.0 - mat.poisson * mat.poisson));
  for (std::size_t k = 0; k < p0.size(); ++k) {
    const double ratio = std::pow(3.0 * std::sqrt(2.0) * std::numbers::pi * p0[k] / (0.6 * 6.0 * e_star), 2.0 / 3.0);
    if (ratio > 0.1)
      s.fail("p0[" + std::to_string(k) + "]", num(p0[k]),
             "with material.young = " + num(mat.young) + " Pa the mean contact overlap would be ~" +
                 num(std::round(ratio * 100.0) / 100.0) +
                 " of the radius (Hertz, dense sample), beyond the small-overlap contact law (allowed: < 0.1): "
                 "raise material.young or lower p0");
  }
}

// tests.path: the names, as paths.
std::vector<ShearPath> parse_paths(Section& s, const std::vector<std::string>& names) {
  std::vector<ShearPath> parsed;
  for (std::size_t k = 0; k < names.size(); ++k) {
    if (const TestPath* p = find_test_path(names[k]))
      parsed.push_back(p->id);
    else
      s.fail("path[" + std::to_string(k) + "]", "\"" + names[k] + "\"", "allowed: " + test_path_names());
  }
  return parsed;
}

// The campaign: p0 x path x b (one b for the strain path), in that order, each name once.
std::vector<TestSpec> campaign(const std::vector<double>& p0, const std::vector<ShearPath>& paths,
                               const std::vector<double>& b) {
  std::vector<TestSpec> tests;
  for (double p : p0)
    for (ShearPath path : paths)
      for (double bv : (test_path(path).has_b ? b : std::vector<double>{0.0})) {
        TestSpec t;
        t.path = path;
        t.p0 = p;
        t.b = bv;
        const std::string prefix(test_path(path).prefix);
        char name[96];
        if (test_path(path).has_b)
          std::snprintf(name, sizeof name, "%s-b%.2f-p0_%gkPa", prefix.c_str(), bv, p / 1e3);
        else
          std::snprintf(name, sizeof name, "%s-p0_%gkPa", prefix.c_str(), p / 1e3);
        t.name = name;
        bool duplicate = false;
        for (const TestSpec& other : tests) duplicate = duplicate || other.name == t.name;
        if (!duplicate) tests.push_back(t);
      }
  return tests;
}

// [tests]: p0, b, path and how many run at once; the material bounds p0 (check_contact_overlap).
void parse_tests(const toml::table& root, const std::string& source, Config& c) {
  Section s = section(root, "tests", source);
  std::vector<double> p0 = s.numbers("p0", "each > 0 Pa");
  std::vector<double> b = s.numbers("b", "each in [0, 1]");
  std::vector<std::string> path_names = {"constant_p"};
  const std::vector<std::string> paths = s.strings("path");
  if (!paths.empty()) path_names = paths;
  s.integer("parallel", c.parallel, 1, 1024, "must be an integer in [1, 1024]");
  s.check_unknown();
  if (p0.empty()) p0 = {0.5e6};
  const bool b_given = !b.empty();
  if (b.empty()) b = {0.0};
  for (std::size_t k = 0; k < p0.size(); ++k)
    if (!(p0[k] > 0.0) || !std::isfinite(p0[k])) s.fail("p0[" + std::to_string(k) + "]", num(p0[k]), "must be > 0 Pa");
  for (std::size_t k = 0; k < b.size(); ++k)
    if (!(b[k] >= 0.0 && b[k] <= 1.0)) s.fail("b[" + std::to_string(k) + "]", num(b[k]), "must be in [0, 1]");
  check_contact_overlap(s, c.material, p0);
  const std::vector<ShearPath> parsed = parse_paths(s, path_names);
  // A b no test follows would have no effect: refused.
  bool any_b = false;
  for (ShearPath path : parsed) any_b = any_b || test_path(path).has_b;
  if (b_given && !any_b)
    s.fail("b", num(b.front()), "no path of tests.path holds b; allowed: leave it out, or a path with b");
  c.tests = campaign(p0, parsed, b);
}

// [output]: the series, snapshot, checkpoint and flush intervals, and the plot.
void parse_output(const toml::table& root, const std::string& source, OutputConfig& o) {
  Section s = section(root, "output", source);
  s.integer("series_interval", o.series_interval, 1, 1'000'000'000, "must be an integer >= 1 step");
  s.integer("snapshot_interval", o.snapshot_interval, 0, UINT64_MAX,
            "must be an integer >= 0 steps (0: stage ends only)");
  s.integer("checkpoint_interval", o.checkpoint_interval, 0, UINT64_MAX,
            "must be an integer >= 0 steps (0: by time only)");
  s.number("checkpoint_minutes", o.checkpoint_minutes, 0.0, 1e6, "must be >= 0 minutes (0: by steps only)");
  s.integer("flush_interval", o.flush_interval, 1, 1'000'000, "must be an integer >= 1 row");
  s.boolean("plot", o.plot);
  s.number("max_size_gib", o.max_size_gib, 1e-6, 1e6,
           "must be in (0, 1e6] GiB (the largest estimated size of the run's results files)");
  s.check_unknown();
}

// The [shear] keys that depend on the campaign's paths: exactly one axial rate for the stress
// paths, steps and no ramp for the strain path, a ramp shorter than the test.
void check_shear_for_tests(const Config& c, const std::string& source) {
  bool stress_path = false;
  // The paths driven at an axial (or shear) rate: all but the strain path and the rotation (stress only).
  for (const TestSpec& t : c.tests)
    stress_path = stress_path || (t.path != ShearPath::strain && t.path != ShearPath::rotation);
  if (c.shear.strain_rate > 0.0 && c.shear.inertial_number > 0.0)
    throw ConfigError(source + ": shear.strain_rate = " + num(c.shear.strain_rate) +
                      " and shear.inertial_number = " + num(c.shear.inertial_number) +
                      ": give exactly one of the two (the axial rate, or the inertial number it follows)");
  if (c.shear.max_rate_ratio == 0.0 && !(c.shear.max_rate > 0.0))
    throw ConfigError(source + ": shear.max_rate_ratio = 0 (the fixed shear.max_rate alone) without a "
                      "shear.max_rate: give the fixed cap in 1/s, or a ratio > 0 (default 20)");
  if (c.shear.integral_strain > 0.0 && c.shear.integral_time > 0.0)
    throw ConfigError(source + ": shear.integral_strain = " + num(c.shear.integral_strain) +
                      " with shear.integral_time = " + num(c.shear.integral_time) +
                      ": a set integral time is used as set; give one of the two");
  if (stress_path && !(c.shear.strain_rate > 0.0) && !(c.shear.inertial_number > 0.0))
    throw ConfigError(source +
                      ": shear.strain_rate and shear.inertial_number: neither is given; the stress paths need "
                      "exactly one (e.g. strain_rate = 1.0 in 1/s, or inertial_number = 2e-3)");
  for (const TestSpec& t : c.tests) {
    const TestPath& path = test_path(t.path);
    if (!path.by_steps && !path.inertial_number && c.shear.inertial_number > 0.0)
      throw ConfigError(source + ": shear.inertial_number = " + num(c.shear.inertial_number) + ": path \"" +
                        std::string(path.name) + "\" compresses at a fixed axial rate; allowed: shear.strain_rate");
    if (!path.by_steps && !path.ramp && c.shear.ramp_strain > 0.0)
      throw ConfigError(source + ": shear.ramp_strain = " + num(c.shear.ramp_strain) + ": path \"" +
                        std::string(path.name) + "\" has no ramp; allowed: 0");
    if (t.path != ShearPath::strain && !c.shear.shear_rates.isZero(0.0))
      throw ConfigError(source + ": shear.shear_rates: only path \"strain\" sets the cell's shear rates (the others "
                        "leave them to the servo: cell.shear); allowed: leave it out");
    if (t.path == ShearPath::strain && c.shear.steps == 0)
      throw ConfigError(source + ": shear.steps = 0: path \"strain\" needs a number of steps >= 1");
    if (t.path == ShearPath::strain && c.shear.ramp_strain > 0.0)
      throw ConfigError(source + ": shear.ramp_strain = " + num(c.shear.ramp_strain) +
                        ": the ramp applies to the stress paths' axial rate; path \"strain\" allows 0 only");
  }
  // Critical state is tested once a test has sheared critical_window + pre_strain (critical.hpp):
  // with no room for that before max_axial_strain, stop_at_critical could never stop a test.
  for (const TestSpec& t : c.tests)
    if (c.shear.stop_at_critical && (t.path == ShearPath::simple_shear || t.path == ShearPath::simple_shear_cv ||
                                     t.path == ShearPath::rotation))
      throw ConfigError(source + ": shear.stop_at_critical = true: path \"" + std::string(test_path(t.path).name) +
                        "\" has no axial strain to test critical state over; allowed: false");
  // The window is in eps_q; the end is max_deviatoric_strain when given, else max_axial_strain (at
  // b = 0, eps_q ~ eps_1; at larger b more: the bound is conservative).
  const double pre = CriticalTest{}.pre_strain;
  const double end = c.shear.max_deviatoric_strain > 0.0 ? c.shear.max_deviatoric_strain : c.shear.max_axial_strain;
  const std::string end_key = c.shear.max_deviatoric_strain > 0.0 ? "max_deviatoric_strain" : "max_axial_strain";
  if (stress_path && c.shear.stop_at_critical && c.shear.critical_window + pre >= end)
    throw ConfigError(source + ": shear.critical_window = " + num(c.shear.critical_window) + " with shear." + end_key +
                      " = " + num(end) + ": shear.stop_at_critical tests critical state only after critical_window + " +
                      num(pre) + " of deviatoric strain; allowed: critical_window < " + end_key + " - " + num(pre) +
                      ", or stop_at_critical = false");
  if (c.shear.ramp_strain >= c.shear.max_axial_strain)
    throw ConfigError(source + ": shear.ramp_strain = " + num(c.shear.ramp_strain) +
                      ": must be below shear.max_axial_strain = " + num(c.shear.max_axial_strain));
}

// A preparation with friction (or rolling friction) must step at most 0.2 Rayleigh times. The
// Rayleigh time does not see the contacts stiffen under pressure, and a frictional contact's
// tangential spring acts on the spheres' rotation too, a stiffer mode than the normal one. Measured
// at 1,000 spheres with prepare.friction = 0.25 (docs/physics.md section 4): at 0.5 t_R the
// chained preparation to 16 MPa never came to rest (unbalanced force ratio 0.4 after 8e5 steps, the
// sample compacting to a frictionless density); at 0.3 t_R neither did the one to 4 MPa
// (restitution 0.29); at 0.2 t_R all of 0.5, 4 and 16 MPa converged in 1e5 steps or fewer.
constexpr double k_frictional_prepare_dt = 0.2;

void check_prepare_step(const Config& c, const std::string& source) {
  const PrepareConfig& p = c.prepare;
  if (!(p.friction > 0.0) && !(p.rolling_friction > 0.0)) return;
  const bool own = p.dt_fraction > 0.0;
  const double f = own ? p.dt_fraction : c.dt_fraction;
  if (f <= k_frictional_prepare_dt) return;
  const std::string key = own ? "prepare.dt_fraction" : "time.dt_fraction";
  const std::string why = p.friction > 0.0 ? "prepare.friction = " + num(p.friction)
                                           : "prepare.rolling_friction = " + num(p.rolling_friction);
  throw ConfigError(source + ": " + key + " = " + num(f) + " with " + why +
                    ": a frictional preparation needs prepare.dt_fraction <= 0.2 (above, it never comes to rest)");
}

// prepare.target_e0: a search over the preparation's friction (prepare_run.cpp). It sets
// prepare.friction itself, cannot keep a chained sample's e0 (the chain sets it), and its frictional
// trials need the frictional preparation's step (above).
void check_target_e0(const Config& c, const std::string& source) {
  const PrepareConfig& p = c.prepare;
  if (p.target_e0.empty()) return;
  std::vector<double> p0s;
  for (const TestSpec& t : c.tests)
    if (std::find(p0s.begin(), p0s.end(), t.p0) == p0s.end()) p0s.push_back(t.p0);
  if (p.target_e0.size() != 1 && p.target_e0.size() != p0s.size())
    throw ConfigError(source + ": prepare.target_e0: " + std::to_string(p.target_e0.size()) + " values for " +
                      std::to_string(p0s.size()) + " distinct tests.p0; allowed: one value, or one per p0 in order");
  if (p.friction > 0.0)
    throw ConfigError(source + ": prepare.friction = " + num(p.friction) +
                      " with prepare.target_e0: the search chooses the friction; allowed: leave it out");
  if (p.chain)
    throw ConfigError(source + ": prepare.chain = true with prepare.target_e0: a chained sample's e0 is set by the "
                      "chain; allowed: chain = false (each p0 from the cloud)");
  const double f = p.dt_fraction > 0.0 ? p.dt_fraction : c.dt_fraction;
  if (f > k_frictional_prepare_dt)
    throw ConfigError(source + ": " + (p.dt_fraction > 0.0 ? "prepare.dt_fraction" : "time.dt_fraction") + " = " +
                      num(f) + " with prepare.target_e0: its trials are frictional preparations, which need "
                      "prepare.dt_fraction <= 0.2 (above, they never come to rest)");
}

// [cyclic]: the cyclic path's bounds, count and drainage (CyclicConfig); checked against the tests'
// paths in check_cyclic.
void parse_cyclic(const toml::table& root, const std::string& source, CyclicConfig& c) {
  c.given = root.contains("cyclic");
  Section s = section(root, "cyclic", source);
  s.choice("axial", c.axial, {{"stress", std::string("stress")}, {"strain", std::string("strain")}});
  s.number("lower", c.lower, -10.0, 10.0, "must be in [-10, 10] (q/p0 in stress mode, axial strain in strain mode)");
  s.number("upper", c.upper, -10.0, 10.0, "must be in [-10, 10] (q/p0 in stress mode, axial strain in strain mode)");
  double tolerance = std::nan("");
  s.number("tolerance", tolerance, 0.0, 0.49, "must be in [0, 0.49] (stress mode: reversal within this share of "
           "upper - lower)");
  s.boolean("undrained", c.undrained);
  s.integer("cycles", c.cycles, 0, 1000000, "must be an integer in [0, 1e6] (0: no limit)");
  s.number("max_strain", c.max_strain, 0.0, 2.0, "must be in [0, 2] (|eps1| that ends the test; 0: no limit)");
  s.check_unknown();
  if (!std::isnan(tolerance)) {  // the reversal tolerance acts on q: in strain mode it would do nothing
    if (c.axial == "strain") s.fail("tolerance", num(tolerance), "only with axial = \"stress\"");
    c.tolerance = tolerance;
  }
}

void check_cyclic(const Config& c, const std::string& source) {
  bool cyclic = false;
  for (const TestSpec& t : c.tests) cyclic = cyclic || t.path == ShearPath::cyclic;
  if (c.cyclic.given && !cyclic)
    throw ConfigError(source + ": [cyclic]: no test of tests.path is \"cyclic\"; allowed: leave the table out");
  if (!cyclic) return;
  if (!(c.cyclic.upper > c.cyclic.lower))
    throw ConfigError(source + ": cyclic.upper = " + num(c.cyclic.upper) + ": must be > cyclic.lower = " +
                      num(c.cyclic.lower) + " (both required with tests.path = \"cyclic\")");
  if (c.cyclic.cycles == 0 && c.cyclic.max_strain == 0.0)
    throw ConfigError(source + ": cyclic.cycles = 0 and cyclic.max_strain = 0: a cyclic test needs an end; "
                      "allowed: cycles >= 1, or max_strain > 0");
}

// [cell]: shear = "fixed" (orthorhombic, the default) or "free" (the shear stresses held at zero).
void parse_cell(const toml::table& root, const std::string& source, CellConfig& c) {
  Section s = section(root, "cell", source);
  c.given = root.contains("cell") && root["cell"].as_table()->contains("shear");
  s.choice("shear", c.free, {{"fixed", false}, {"free", true}});
  s.check_unknown();
}

// [rotation]: the principal-stress rotation path's load and rotation.
void parse_rotation(const toml::table& root, const std::string& source, RotationConfig& r) {
  r.given = root.contains("rotation");
  Section s = section(root, "rotation", source);
  s.number("eta", r.eta, 1e-6, 3.0, "must be in (0, 3) (q / p0; sigma3 must stay > 0: eta < 3 / (1 + b) sqrt(1 - b + b^2))");
  s.number("alpha0", r.alpha0, -360.0, 360.0, "must be in [-360, 360] degrees");
  s.number("angle", r.angle, 1e-6, 36000.0, "must be in (0, 36000] degrees");
  s.number("rate", r.rate, 1e-9, 1e9, "must be > 0 degrees/s");
  s.number("ramp_time", r.ramp_time, 1e-12, 1e9, "must be > 0 s (the time over which q rises to eta p0)");
  s.check_unknown();
}

// The keys of the shearing cell against the campaign's paths: each must act on some test.
void check_shearing_cell(const Config& c, const std::string& source) {
  bool rotation = false, simple = false, servo_paths = false, axial = false;
  for (const TestSpec& t : c.tests) {
    rotation = rotation || t.path == ShearPath::rotation;
    simple = simple || t.path == ShearPath::simple_shear || t.path == ShearPath::simple_shear_cv;
    servo_paths = servo_paths || (t.path != ShearPath::strain && t.path != ShearPath::rotation);
    axial = axial || (t.path != ShearPath::strain && t.path != ShearPath::rotation && t.path != ShearPath::simple_shear &&
                      t.path != ShearPath::simple_shear_cv);
  }
  if (c.cell.given && !servo_paths)
    throw ConfigError(source + ": cell.shear: no test of tests.path lets the cell's shear components be fixed or free "
                      "(path \"strain\" has no servo, \"rotation\" controls all six stresses); allowed: leave it out");
  if (c.rotation.given && !rotation)
    throw ConfigError(source + ": [rotation]: no test of tests.path is \"rotation\"; allowed: leave the table out");
  if (rotation && (!(c.rotation.eta > 0.0) || !(c.rotation.rate > 0.0) || !(c.rotation.ramp_time > 0.0)))
    throw ConfigError(source + ": rotation.eta = " + num(c.rotation.eta) + ", rotation.rate = " + num(c.rotation.rate) +
                      ", rotation.ramp_time = " + num(c.rotation.ramp_time) +
                      ": tests.path = \"rotation\" needs all three > 0 (q / p0, degrees/s, s)");
  if (c.shear.max_shear_strain > 0.0 && !simple)
    throw ConfigError(source + ": shear.max_shear_strain = " + num(c.shear.max_shear_strain) +
                      ": only the simple shear paths stop at a shear strain; allowed: leave it out");
  if (c.shear.max_deviatoric_strain > 0.0 && !axial)
    throw ConfigError(source + ": shear.max_deviatoric_strain = " + num(c.shear.max_deviatoric_strain) +
                      ": only the axial stress paths (constant_p, constant_sigma3, undrained, ...) stop at a deviatoric "
                      "strain; allowed: leave it out");
  if (simple && !(c.shear.max_shear_strain > 0.0))
    throw ConfigError(source + ": shear.max_shear_strain: not given; the simple shear paths need it (e.g. 2.0)");
}

// [watch]: the stress-path watchdog's tolerances (ranges as sandcell::validate(PathTolerance)).
void parse_watch(const toml::table& root, const std::string& source, WatchConfig& w) {
  Section s = section(root, "watch", source);
  PathTolerance& t = w.tolerance;
  s.number("stress", t.stress, 1e-6, 10.0, "must be in [1e-6, 10] (relative error of p or sigma3)");
  s.number("b", t.b, 1e-6, 1.0, "must be in [1e-6, 1] (absolute error of b)");
  s.number("rotation", t.rotation, 1e-3, 45.0, "must be in [1e-3, 45] degrees");
  s.number("shear", t.shear, 1e-6, 10.0, "must be in [1e-6, 10] (largest |shear stress| / p)");
  s.number("window", t.window, 1e-6, 1.0, "must be in [1e-6, 1] (axial strain)");
  s.number("overlap", t.overlap, 1e-6, 1.0, "must be in [1e-6, 1] (overlap / radius)");
  s.number("unbalanced", t.unbalanced, 1e-6, 1e6, "must be in [1e-6, 1e6]");
  s.integer("rows", t.rows, 1, 100000, "must be an integer in [1, 1e5] (series rows a window must hold)");
  s.boolean("stop", w.stop);
  s.check_unknown();
}

}  // namespace sandcell::triaxial::config_detail
