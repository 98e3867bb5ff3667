#include "protocol/protocol.hpp"

#include "protocol/text.hpp"

#include "engine/generate.hpp"
#include "engine/world.hpp"
#include "systems/homogenizer.hpp"
#include "systems/servo.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>

namespace sandcell::triaxial {

std::string p0_tag(double p0) { return "p0_" + num(p0 / 1e3, "%g") + "kPa"; }

double Protocol::chained_from(double p0) const {
  if (!config.prepare.chain) return 0.0;
  double from = 0.0;
  for (double q : this->p0)
    if (q < p0) from = std::max(from, q);
  return from;
}

namespace {

// Servo gain derived from the physics when the config leaves it 0. A strain increment changes the
// stress through the packing's stiffness K ~ p (E*/p)^(2/3) (Hertzian contacts), so a servo acting
// for a time t changes the normalized error by about c g t (E*/p)^(2/3), c of order 10 for the
// affine response. g = alpha (p/E*)^(2/3) / t_s keeps that loop gain at c alpha whatever the
// material and pressure. The time unit t_s is physical, 0.2 Rayleigh times (the default dt), so
// the servo's response in time does not change with time.dt_fraction: a gain per step (t_s = dt,
// as before) made a 4x smaller dt a 4x stiffer servo against the same inertia of the sample, and
// the preparation of 400 spheres at dt_fraction 0.05 hovered at 2.8 % stress error for 5e6 steps.
// Above 0.2 t_R, t_s = dt bounds the loop gain per step, which must stay below the period-2
// limit: measured (every step sampled, 300 soft spheres sheared at 10/s, constant p, b = 0,
// dt = 0.2 t_R) alpha = 0.25 and 0.2 oscillate with period 2 steps (p alternating +-10 %), 0.1 does
// not. A P law lags a moving target by err ~ rate / g (2 % there); the integral term removes it:
// with T_i = 1000 t_s the rms |p - p0|/p0 after 1 % strain fell from 2.0 % to 0.4 % (T_i = 200 t_s:
// 0.1 %, closer to the slow modes of large samples). Preparation (a fixed target from rest through
// jamming) keeps the P law with alpha = 0.05. Every dt_fraction = 0.2 config runs bitwise as before.
constexpr double k_shear_alpha = 0.1;
constexpr double k_integral_units = 1000.0;
constexpr double k_integral_strain = 3e-4;  // at a set inertial number: T_i <= 3e-4 / axial rate
// The default cap on the stress-controlled axes' rates, as a multiple of the axial rate. At b = 1 on
// constant p a dense sample's sigma3 axis extends at up to 10.6x the axial rate through the peak
// (19,436 spheres, 0.5 MPa, experiments/2026-11-28-servo-cap): the 10x of old bound it there and p
// stood 4-8 % high for 0.02 of eps_q. 20x leaves room; the cap is a guard against a runaway, not a
// limit a test should meet.
constexpr double k_max_rate_ratio = 20.0;
constexpr double k_servo_time_fraction = 0.2;  // t_s / t_Rayleigh, floor of the servo time unit

// The first pair of spheres of a packing that overlap by more than a tenth of the smaller radius
// ("" when none): such a start blows up in the first steps ("went unstable ... lower dt"), which
// blames the time step for what is the file's fault. Periodic box; a grid of cells >= 2 r_max.
std::string deep_overlap(const Packing& pk) {
  const std::size_t n = pk.position.size();
  const double r_max = *std::max_element(pk.radius.begin(), pk.radius.end());
  Vec3 cells_f = (pk.box / (2.0 * r_max)).array().floor().max(1.0).min(256.0);
  const int nx = int(cells_f[0]), ny = int(cells_f[1]), nz = int(cells_f[2]);
  std::vector<std::vector<std::uint32_t>> grid(static_cast<std::size_t>(nx) * ny * nz);
  const auto cell_of = [&](const Vec3& x, int c[3]) {
    const int dims[3] = {nx, ny, nz};
    for (int a = 0; a < 3; ++a) {
      const double f = x[a] / pk.box[a] - std::floor(x[a] / pk.box[a]);
      c[a] = std::min(dims[a] - 1, static_cast<int>(f * dims[a]));
    }
  };
  for (std::size_t k = 0; k < n; ++k) {
    int c[3];
    cell_of(pk.position[k], c);
    grid[(static_cast<std::size_t>(c[2]) * ny + c[1]) * nx + c[0]].push_back(static_cast<std::uint32_t>(k));
  }
  for (std::size_t k = 0; k < n; ++k) {
    int c[3];
    cell_of(pk.position[k], c);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const std::size_t cell = (static_cast<std::size_t>((c[2] + dz + nz) % nz) * ny + (c[1] + dy + ny) % ny) * nx +
                                   (c[0] + dx + nx) % nx;
          for (std::uint32_t q : grid[cell]) {
            if (q <= k) continue;
            Vec3 d = pk.position[k] - pk.position[q];
            for (int a = 0; a < 3; ++a) d[a] -= pk.box[a] * std::nearbyint(d[a] / pk.box[a]);
            const double overlap = pk.radius[k] + pk.radius[q] - d.norm();
            if (overlap > 0.1 * std::min(pk.radius[k], pk.radius[q]))
              return "spheres " + std::to_string(k + 1) + " and " + std::to_string(q + 1) +
                     " (in file order) overlap by " + num(overlap / std::min(pk.radius[k], pk.radius[q]), "%.3g") +
                     " of the smaller radius (allowed: up to 0.1; coincident spheres?)";
          }
        }
  }
  return "";
}

// The sample's diameters: the packing file's (read into plan.packing, checked for coincident
// spheres), else those [sample] generates. Throws ConfigError.
std::vector<double> sample_sizes(Protocol& plan) {
  const std::string& src = plan.config.source;
  const SampleConfig& sc = plan.config.sample;
  std::vector<double> diameters;
  if (!sc.packing_file.empty()) {
    try {
      plan.packing = read_packing(sc.packing_file);
    } catch (const std::exception& e) {
      throw ConfigError(src + ": sample.file = \"" + sc.packing_file + "\": " + e.what());
    }
    if (plan.packing.position.size() < 2)
      throw ConfigError(src + ": sample.file = \"" + sc.packing_file + "\": needs at least 2 spheres");
    plan.from_file = true;
    for (double r : plan.packing.radius) diameters.push_back(2.0 * r);
    if (const std::string pair = deep_overlap(plan.packing); !pair.empty())
      throw ConfigError(src + ": sample.file = \"" + sc.packing_file + "\": " + pair);
  } else {
    diameters = sample_diameters(sc.generation.sizes, sc.generation.count, sc.generation.seed);
  }
  return diameters;
}

// The shear stage's model (material, contact settings, skin, dt) and the time units of the
// preparation and the servos, from the smallest radius.
void derive_model(Protocol& plan) {
  const Config& config = plan.config;
  Model& m = plan.base;
  m.materials = {config.material};
  m.contact = config.contact;
  if (m.contact.skin == 0.0) m.contact.skin = 0.2 * plan.r_min;  // 0.1 x the smallest diameter
  const double t_r = rayleigh_time(plan.r_min, config.material);
  // time.step = "stiffness": the shear stage's dt starts (and stays at most) at max_dt_fraction t_R;
  // the World sets it from the contacts before the first step (shear_model). The servo's time unit
  // is the floor, so its gain per step follows the step (ServoSettings::gain_time).
  const bool stiffness = config.dt_rule == TimeStepRule::stiffness;
  m.dt = (stiffness ? config.max_dt_fraction : config.dt_fraction) * t_r;
  plan.servo_time = servo_time_unit(stiffness ? 0.0 : m.dt, plan.r_min, config.material);
  // The preparation may take its own step: frictionless, it has no tangential or rolling springs,
  // whose stiff rotational modes bound the shearing step at high pressure (docs/reproducing-the-study.md).
  plan.prepare_dt = (config.prepare.dt_fraction > 0.0 ? config.prepare.dt_fraction : config.dt_fraction) * t_r;
  plan.prepare_servo_time = servo_time_unit(plan.prepare_dt, plan.r_min, config.material);
}

}  // namespace

Protocol make_protocol(Config config_in) {
  Protocol pr;
  pr.config = std::move(config_in);
  const Config& config = pr.config;
  pr.diameters = sample_sizes(pr);
  pr.r_min = 0.5 * *std::min_element(pr.diameters.begin(), pr.diameters.end());
  pr.r_max = 0.5 * *std::max_element(pr.diameters.begin(), pr.diameters.end());
  {
    std::vector<double> radii(pr.diameters.size());
    for (std::size_t k = 0; k < pr.diameters.size(); ++k) radii[k] = 0.5 * pr.diameters[k];
    pr.d50 = median_diameter(radii);
  }
  derive_model(pr);
  for (const TestSpec& t : config.tests)
    if (std::find(pr.p0.begin(), pr.p0.end(), t.p0) == pr.p0.end()) pr.p0.push_back(t.p0);
  if (config.prepare.chain) std::sort(pr.p0.begin(), pr.p0.end());
  return pr;
}

void validate_servos(const Protocol& protocol) {
  try {
    validate(prepare_model(protocol, protocol.p0.front()).servo);
    for (const TestSpec& t : protocol.config.tests) {
      const Model sm = shear_model(protocol, t);
      if (sm.servo.enabled) validate(sm.servo);
    }
  } catch (const std::invalid_argument& e) {
    throw ConfigError(protocol.config.source + ": " + e.what());
  }
}

double derived_gain(double alpha, double p, const Material& mat, double servo_time) {
  const double e_star = mat.young / (2.0 * (1.0 - mat.poisson * mat.poisson));
  return alpha * std::pow(p / e_star, 2.0 / 3.0) / servo_time;
}

DerivedServo derived_servo(Stage stage, double p, const Material& material, double servo_time) {
  if (stage == Stage::prepare) return {derived_gain(0.05, p, material, servo_time), 0.0};
  return {derived_gain(k_shear_alpha, p, material, servo_time), k_integral_units * servo_time};
}

double servo_time_unit(double dt, double r_min, const Material& material) {
  return std::max(dt, k_servo_time_fraction * rayleigh_time(r_min, material));
}

Model prepare_model(const Protocol& plan, double p0) {
  Model m = plan.base;
  m.dt = plan.prepare_dt;
  m.materials[0].friction = plan.config.prepare.friction;
  m.materials[0].rolling_friction = plan.config.prepare.rolling_friction;
  ServoSettings& s = m.servo;
  s.enabled = true;
  s.path = StressPath::isotropic;
  s.control = {AxisControl::stress, AxisControl::stress, AxisControl::stress};
  s.p = p0;
  s.max_rate = plan.config.prepare.max_rate;
  s.gain =
      plan.config.prepare.gain > 0.0 ? plan.config.prepare.gain
                                     : derived_servo(Stage::prepare, p0, m.materials[0], plan.prepare_servo_time).gain;
  s.interval = 1;
  return m;
}

// The axial rate of a test at p = p0, 1/s: shear.strain_rate, or what shear.inertial_number sets.
double axial_rate(const Protocol& plan, double p0) {
  const ShearConfig& h = plan.config.shear;
  if (h.inertial_number > 0.0) return h.inertial_number * std::sqrt(p0 / plan.config.material.density) / plan.d50;
  return h.strain_rate;
}

Model shear_model(const Protocol& plan, const TestSpec& test) {
  Model m = plan.base;
  const ShearConfig& h = plan.config.shear;
  ServoSettings& s = m.servo;
  if (plan.config.dt_rule == TimeStepRule::stiffness) {
    m.time_step = TimeStepSettings{TimeStepRule::stiffness, plan.config.dt_safety, plan.config.dt_interval, m.dt};
    s.gain_time = plan.servo_time;
  }
  if (test.path == ShearPath::strain) return m;  // rates set once on the cell; no servo scheduled
  s.enabled = true;
  // cell.shear = "free": the three shear stresses held at zero (every servo path but the rotation,
  // which controls all six). A custom path's answer keeps its own shear components unless these say
  // stress (systems/servo.hpp).
  if (plan.config.cell.free) {
    s.shear_control = {AxisControl::stress, AxisControl::stress, AxisControl::stress};
    s.shear_target = Vec3::Zero();
  }
  switch (test.path) {
    case ShearPath::constant_p: s.path = StressPath::constant_p; break;
    case ShearPath::constant_sigma3: s.path = StressPath::constant_sigma3; break;
    case ShearPath::undrained:  // axis 1 at the axial rate, axes 2 and 3 at eps_v = 0 (config: strain_rate only)
      s.path = StressPath::custom;
      s.custom = undrained_path(h.strain_rate);
      break;
    case ShearPath::cyclic: {  // axis 1 between the [cyclic] bounds, laterally undrained or at sigma3 = p0
      const CyclicConfig& c = plan.config.cyclic;
      CyclicSettings cs;
      cs.axial = c.axial == "strain" ? AxisControl::strain : AxisControl::stress;
      const double unit = c.axial == "strain" ? 1.0 : test.p0;  // stress mode: the bounds are q/p0
      cs.lower = c.lower * unit;
      cs.upper = c.upper * unit;
      cs.rate = h.strain_rate;
      cs.tolerance = c.tolerance;
      cs.undrained = c.undrained;
      cs.sigma3 = test.p0;
      cs.cycles = c.cycles;
      cs.max_strain = c.max_strain;
      s.path = StressPath::custom;
      s.custom = CyclicPath(cs);
      break;
    }
    case ShearPath::simple_shear:
    case ShearPath::simple_shear_cv: {
      s.path = test.path == ShearPath::simple_shear ? StressPath::simple_shear : StressPath::simple_shear_cv;
      s.normal_stress = test.p0;
      s.shear_control[1] = AxisControl::strain;  // xz driven; xy and yz fixed or free (cell.shear)
      s.strain_rate = Vec3::Zero();
      break;
    }
    case ShearPath::rotation: {
      const RotationConfig& r = plan.config.rotation;
      s.path = StressPath::rotation;
      s.p = test.p0;
      s.b = test.b;
      s.q = r.eta * test.p0;
      s.rotation_start = r.alpha0 * std::numbers::pi / 180.0;
      s.rotation_rate = r.rate * std::numbers::pi / 180.0;
      s.ramp_time = r.ramp_time;
      s.shear_control = {AxisControl::stress, AxisControl::stress, AxisControl::stress};
      s.control = s.shear_control;
      s.max_rate = h.max_rate > 0.0 ? h.max_rate : 1.0;
      const DerivedServo derived = derived_servo(Stage::shear, test.p0, m.materials[0], plan.servo_time);
      s.gain = h.gain > 0.0 ? h.gain : derived.gain;
      s.integral_time = h.integral_time > 0.0 ? h.integral_time : derived.integral_time;
      s.interval = h.servo_interval;
      return m;
    }
    case ShearPath::strain: break;
  }
  s.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};  // (a simple shear's answer decides)
  const double rate0 = axial_rate(plan, test.p0);
  // The driven component: axis 1, or the simple shears' xz at gamma_dot = -L_xz = +rate (gamma = -F_xz
  // grows: soil convention, docs/physics.md section 1); the rest of the servo is the same.
  const bool simple = test.path == ShearPath::simple_shear || test.path == ShearPath::simple_shear_cv;
  Vec3& driven = simple ? s.shear_strain_rate : s.strain_rate;
  const Vec3 direction = simple ? Vec3(0.0, 1.0, 0.0) : Vec3(1.0, 0.0, 0.0);
  if (h.inertial_number > 0.0) {
    // The servo (a simple shear's answer) scales the direction by I sqrt(p/rho) / d50 at each update.
    driven = direction;
    s.inertial_number = h.inertial_number;
    s.d50 = plan.d50;
    s.density = plan.config.material.density;
  } else {
    driven = direction * h.strain_rate;
  }
  // A linear ramp over ramp_strain of (logarithmic) axial strain takes 2 ramp_strain / rate (at a
  // set inertial number, the rate at p = p0).
  s.ramp_time = 2.0 * h.ramp_strain / rate0;
  s.p = test.p0;
  s.sigma3 = test.p0;
  s.b = test.b;
  // The default cap follows the axial rate (k_max_rate_ratio x, the rate at p0 a floor): at a set
  // inertial number the axial rate grows with sqrt(p), and a cap fixed at p0 ran the b = 1
  // constant-sigma3 test away (docs/physics.md section 6). An explicit shear.max_rate is a fixed cap,
  // as set, unless shear.max_rate_ratio is given too.
  const double ratio = h.max_rate_ratio >= 0.0 ? h.max_rate_ratio : (h.max_rate > 0.0 ? 0.0 : k_max_rate_ratio);
  s.max_rate = h.max_rate > 0.0 ? h.max_rate : ratio * rate0;  // ratio > 0 here (config_tests.cpp refuses 0 alone)
  s.max_rate_ratio = ratio;
  const DerivedServo derived = derived_servo(Stage::shear, test.p0, m.materials[0], plan.servo_time);
  s.gain = h.gain > 0.0 ? h.gain : derived.gain;
  s.integral_time = h.integral_time > 0.0 ? h.integral_time : derived.integral_time;
  // At a set inertial number the axial rate is 6-80 /s (0.5-16 MPa, I = 3e-3) and T_i = 1000 t_s spans
  // up to 1 % of axial strain: on constant sigma3 the lateral axes lagged through the peak (sigma3 up to
  // 31 % high over 1 % of strain at b = 1, 1,000 spheres). T_i at most the time of 3e-4 axial strain
  // held every b at 0.5 and 16 MPa within 1.0 % (docs/physics.md section 6). At a set strain rate of
  // 1 /s every path held within 0.2 % with T_i = 1000 t_s, which stays (the default test is unchanged).
  s.integral_strain = h.integral_time > 0.0          ? 0.0
                      : h.integral_strain > 0.0      ? h.integral_strain
                      : h.inertial_number > 0.0      ? k_integral_strain
                                                     : 0.0;
  s.interval = h.servo_interval;
  return m;
}

// The stress-path watchdog of a test ([watch]; systems/path_watch.hpp): its checks begin at the end
// of the ramp. The strain path has no stress targets and its shear stresses are the material's
// answer, not a departure: there only the overlap and the unbalanced force are judged.
PathWatch make_path_watch(const Protocol& plan, const TestSpec& test) {
  PathTolerance t = plan.config.watch.tolerance;
  t.start = plan.config.shear.ramp_strain;
  if (test.path == ShearPath::strain) {
    t.rotation = 45.0;  // the largest turn 1/2 asin(2 |tau| / (s1 - s3)) can give: never beyond
    t.shear = 10.0;
  }
  return PathWatch(shear_model(plan, test).servo, t);
}

void start_test(const Protocol& protocol, const TestSpec& test, State& state) {
  const ShearConfig& h = protocol.config.shear;
  state.clock = {};
  state.cell.length0 = state.cell.length;
  state.cell.tilt0 = state.cell.tilt;  // the strains count from here: F = I
  state.cell.flip.setZero();
  state.cell.servo_integral.setZero();  // servo state resets between stages
  state.cell.shear_integral.setZero();
  state.cell.shear_rate.setZero();
  if (test.path == ShearPath::strain) {
    state.cell.rate = -h.strain_rates;
    state.cell.shear_rate = Vec3::Zero() - h.shear_rates;  // 0 - 0 = +0: no shear, an orthorhombic cell
  }
  else if (test.path == ShearPath::cyclic || test.path == ShearPath::rotation ||
           test.path == ShearPath::simple_shear || test.path == ShearPath::simple_shear_cv)
    state.cell.rate.setZero();  // the path's first update sets every axis
  else
    state.cell.rate = Vec3(h.ramp_strain > 0.0 ? 0.0 : -axial_rate(protocol, test.p0), 0.0, 0.0);
}

void finish_preparation(State& state) { state.cell.length0 = state.cell.length; }

const CyclicPath* cyclic_path(const Model& model) {
  return model.servo.path == StressPath::custom ? model.servo.custom.target<CyclicPath>() : nullptr;
}

// Every value the run derives from its config, one `key = value` line each (the run record).
std::string resolved_settings(const Protocol& plan, const TestSpec& test) {
  const Model m = shear_model(plan, test);
  const ServoSettings& s = m.servo;
  const TimeStepSettings& t = m.time_step;
  std::string out;
  const auto line = [&](const std::string& key, const std::string& value) { out += key + " = " + value + "\n"; };
  line("dt", num(m.dt, "%.17g"));
  line("time_step", t.rule == TimeStepRule::stiffness ? "stiffness" : "fixed");
  if (t.rule == TimeStepRule::stiffness) {
    line("time_step.safety", num(t.safety, "%.17g"));
    line("time_step.interval", std::to_string(t.interval));
    line("time_step.max_dt", num(t.max_dt, "%.17g"));
  }
  line("contact.skin", num(m.contact.skin, "%.17g"));
  line("servo.gain", num(s.gain, "%.17g"));
  line("servo.integral_time", num(s.integral_time, "%.17g"));
  line("servo.integral_strain", num(s.integral_strain, "%.17g"));
  line("servo.gain_time", num(s.gain_time, "%.17g"));
  line("servo.max_rate", num(s.max_rate, "%.17g"));
  line("servo.max_rate_ratio", num(s.max_rate_ratio, "%.17g"));
  line("servo.interval", std::to_string(s.interval));
  line("servo.inertial_number", num(s.inertial_number, "%.17g"));
  line("servo.d50", num(s.d50, "%.17g"));
  line("servo_time", num(plan.servo_time, "%.17g"));
  line("sample.seed", std::to_string(plan.config.sample.generation.seed));
  return out;
}

}  // namespace sandcell::triaxial
