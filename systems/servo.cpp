#include "systems/servo.hpp"

#include "systems/homogenizer.hpp"
#include "systems/stress_paths.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace sandcell {

void validate(const ServoSettings& servo) {
  const auto fail = [](const std::string& key, double value, const std::string& allowed) {
    throw std::invalid_argument("servo." + key + " = " + std::to_string(value) + ": " + allowed);
  };
  // The gain and the rate cap drive the stress-controlled axes only: a path that controls none
  // (every axis by strain) needs neither; a custom path may answer `stress` at any update.
  const StressPathSpec& spec = stress_path(servo.path);
  bool any_shear_stress = false;
  if (spec.shear_settings)
    for (int k = 0; k < 3; ++k) {
      const std::string names_k = k_shear_names[k];
      if (servo.shear_control[k] == AxisControl::volume)
        throw std::invalid_argument("servo.shear_control[" + names_k +
                                    "] = volume: a shear component is strain or stress controlled");
      if (!std::isfinite(servo.shear_strain_rate[k]))
        fail("shear_strain_rate[" + names_k + "]", servo.shear_strain_rate[k], "must be finite (1/s)");
      if (!std::isfinite(servo.shear_target[k]))
        fail("shear_target[" + names_k + "]", servo.shear_target[k], "must be finite (Pa)");
      any_shear_stress = any_shear_stress || servo.shear_control[k] == AxisControl::stress;
    }
  const bool diagonal_stress =
      spec.answer == nullptr && (servo.control[0] == AxisControl::stress || servo.control[1] == AxisControl::stress ||
                                 servo.control[2] == AxisControl::stress);
  const bool any_stress = diagonal_stress || any_shear_stress || servo.path == StressPath::simple_shear ||
                          servo.path == StressPath::rotation;
  if (any_stress || servo.path == StressPath::custom) {
    if (!(servo.gain > 0.0) || !std::isfinite(servo.gain)) fail("gain", servo.gain, "must be a finite value > 0 1/s");
    if (!(servo.max_rate > 0.0) || !std::isfinite(servo.max_rate))
      fail("max_rate", servo.max_rate, "must be a finite value > 0 1/s");
  }
  if (!(servo.max_rate_ratio >= 0.0) || !std::isfinite(servo.max_rate_ratio))
    fail("max_rate_ratio", servo.max_rate_ratio, "must be a finite value >= 0 (0: max_rate alone)");
  if (!(servo.integral_strain >= 0.0) || !std::isfinite(servo.integral_strain))
    fail("integral_strain", servo.integral_strain, "must be a finite value >= 0 (0: integral_time alone)");
  if (servo.interval < 1) fail("interval", servo.interval, "must be >= 1 step");
  if (!(servo.gain_time >= 0.0) || !std::isfinite(servo.gain_time))
    fail("gain_time", servo.gain_time, "must be a finite value >= 0 s (0: the gain at any step)");
  if (!(servo.integral_time >= 0.0) || !std::isfinite(servo.integral_time))
    fail("integral_time", servo.integral_time, "must be a finite value >= 0 s (0: no integral term)");
  if (!(servo.b >= 0.0 && servo.b <= 1.0)) fail("b", servo.b, "must be in [0, 1]");
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(servo.strain_rate[k]))
      fail("strain_rate[" + std::to_string(k) + "]", servo.strain_rate[k], "must be finite");
  if (!(servo.inertial_number >= 0.0) || !std::isfinite(servo.inertial_number))
    fail("inertial_number", servo.inertial_number, "must be a finite value >= 0 (0: strain_rate as given)");
  if (servo.inertial_number > 0.0) {
    if (!(servo.d50 > 0.0) || !std::isfinite(servo.d50))
      fail("d50", servo.d50, "must be > 0 m with inertial_number > 0");
    if (!(servo.density > 0.0) || !std::isfinite(servo.density))
      fail("density", servo.density, "must be > 0 kg/m^3 with inertial_number > 0");
  }
  if (servo.path == StressPath::simple_shear && !(servo.normal_stress > 0.0 && std::isfinite(servo.normal_stress)))
    fail("normal_stress", servo.normal_stress, "must be a finite value > 0 Pa (compression positive) on simple_shear");
  if (servo.path == StressPath::rotation) {
    if (!(servo.p > 0.0) || !std::isfinite(servo.p)) fail("p", servo.p, "must be a finite value > 0 Pa");
    if (!std::isfinite(servo.rotation_rate)) fail("rotation_rate", servo.rotation_rate, "must be finite (rad/s)");
    if (!std::isfinite(servo.rotation_start)) fail("rotation_start", servo.rotation_start, "must be finite (rad)");
    const double s3 = rotated_stress(servo.p, servo.b, servo.q, 0.0)(2, 2);
    if (!(servo.q >= 0.0) || !(s3 > 0.0))
      fail("q", servo.q,
           "must be >= 0 Pa and leave sigma3 = p - q (1 + b) / (3 sqrt(1 - b + b^2)) > 0 (no tension), here " +
               std::to_string(s3) + " Pa");
  }
  if (spec.answer != nullptr) return;  // the path's answer decides the axes' controls
  if (servo.path == StressPath::custom) {
    if (!servo.custom)
      throw std::invalid_argument(
          "servo.custom: empty; the custom path needs a function (PathInput -> PathTargets), "
          "e.g. undrained_path(rate) or a CyclicPath");
    return;  // the function decides each axis's control and target at every servo update
  }
  for (int k = 0; k < 3; ++k)
    if (servo.control[k] == AxisControl::volume)
      throw std::invalid_argument(
          "servo.control[" + std::to_string(k) +
          "] = volume: only a custom path's answer may hold the volume; allowed here: strain, stress");
  if (!diagonal_stress) return;
  switch (spec.scale) {
    case PathScale::p:
      if (!(servo.p > 0.0)) fail("p", servo.p, "must be > 0 Pa (compression positive)");
      break;
    case PathScale::sigma3:
      if (!(servo.sigma3 > 0.0)) fail("sigma3", servo.sigma3, "must be > 0 Pa (compression positive)");
      break;
    case PathScale::target:
      for (int k = 0; k < 3; ++k)
        if (servo.control[k] == AxisControl::stress && !(servo.target[k] > 0.0))
          fail("target[" + std::to_string(k) + "]", servo.target[k], "must be > 0 Pa on a stress-controlled axis");
      break;
    case PathScale::normal:
    case PathScale::none: break;
  }
  if (spec.axis1_by_strain && servo.control[0] != AxisControl::strain)
    throw std::invalid_argument("servo.control[0] = stress: the " + std::string(spec.name) +
                                " path drives axis 1 by strain");
}

void Servo::check(const Model& model) {
  if (model.servo.enabled) validate(model.servo);
}

Vec3 path_targets(const ServoSettings& servo, double s1) {
  const StressPathSpec& spec = stress_path(servo.path);
  return spec.targets ? spec.targets(servo, s1) : servo.target;  // custom: its function decides (custom_strain_rates)
}

namespace {
// The gain at this update: servo.gain, or at a step above gain_time (an adaptive time step)
// gain x gain_time / dt, so the loop gain per step g dt stays at most g gain_time. `interval` is
// dt x servo.interval. With gain_time = 0, or dt <= gain_time, exactly servo.gain.
double step_gain(const ServoSettings& servo, double interval) {
  const double limit = servo.gain_time * servo.interval;  // s, gain_time per update
  return servo.gain_time > 0.0 && interval > limit ? servo.gain * (limit / interval) : servo.gain;
}

// The PI law of one stress-controlled axis on its normalized error, capped at +-cap, with integral
// time t_i; `integral` null or t_i = 0: a P law.
double pi_rate(const ServoSettings& servo, double error, double* integral, double interval, double cap, double t_i) {
  const double gain = step_gain(servo, interval);
  if (integral == nullptr || !(t_i > 0.0)) return std::clamp(gain * error, -cap, cap);
  // PI: the integral removes the lag a P law keeps while the target moves (error ~ rate / g).
  // Anti-windup: the integral advances only while the output is inside the cap, or when the
  // error would bring it back inside.
  double& i = *integral;
  const double trial_i = i + error * interval;
  const double trial = gain * (error + trial_i / t_i);
  if (std::abs(trial) <= cap || trial * error < 0.0) i = trial_i;
  return std::clamp(gain * (error + i / t_i), -cap, cap);
}

// The cap and the integral time of the stress-controlled axes at one update, from the rates of the
// strain-controlled axes. The cap: max_rate, or (max_rate_ratio > 0) at least that multiple of the
// fastest strain-controlled axis. At b = 1 on constant sigma3 the axis of sigma3 extends at twice
// the axial rate plus the dilation (measured up to 6x at the peak of a dense sample); at a set
// inertial number the axial rate grows with sqrt(p), so a cap fixed at p0 let the axis of sigma3
// fall behind, sigma3 and p rise, the axial rate rise with them: a runaway to 2,000 p0.
// The integral time: integral_time, or (integral_strain > 0) at most the time the fastest axis
// takes to strain by integral_strain. A target that moves with the axial strain leaves a P law an
// error ~ rate / g; the integral removes it only if it is short against the strain over which the
// lateral rates change (the peak: a few 0.1 % of axial strain).
struct Limits {
  double cap;
  double integral_time;
};
Limits limits(const ServoSettings& servo, const Vec3& rate, const std::array<AxisControl, 3>& control,
              const Vec3& shear_rate = Vec3::Zero(), const std::array<AxisControl, 3>* shear_control = nullptr) {
  double fastest = 0.0;
  for (int k = 0; k < 3; ++k)
    if (control[k] == AxisControl::strain) fastest = std::max(fastest, std::abs(rate[k]));
  if (shear_control != nullptr)  // a strain-controlled shear component (simple shear): its engineering rate
    for (int k = 0; k < 3; ++k)
      if ((*shear_control)[k] == AxisControl::strain) fastest = std::max(fastest, std::abs(shear_rate[k]));
  Limits l{servo.max_rate, servo.integral_time};
  if (servo.max_rate_ratio > 0.0) l.cap = std::max(l.cap, servo.max_rate_ratio * fastest);
  if (servo.integral_strain > 0.0 && servo.integral_time > 0.0 && fastest > 0.0)
    l.integral_time = std::min(l.integral_time, servo.integral_strain / fastest);
  return l;
}
// The PI law of the shear components held by stress: gamma_dot_ab from (S*_ab - S_ab) / scale into
// `shear`, the integral in `integral` (null: a P law); the strain-controlled ones are left as they are.
void shear_stress_rates(const ServoSettings& servo, const std::array<AxisControl, 3>& control, const Vec3& target,
                        const Mat3& stress, double scale, Vec3* integral, double interval, const Limits& l,
                        Vec3& shear) {
  for (int k = 0; k < 3; ++k) {
    if (control[k] != AxisControl::stress) continue;
    const double error = (target[k] - stress(k_shear_row[k], k_shear_col[k])) / scale;
    shear[k] = pi_rate(servo, error, integral != nullptr ? &(*integral)[k] : nullptr, interval, l.cap, l.integral_time);
  }
}
}  // namespace

Vec3 servo_strain_rates(const ServoSettings& servo, const Vec3& sigma, Vec3* integral, double interval, double time) {
  Mat3 stress = Mat3::Zero();
  stress.diagonal() = sigma;
  return servo_rates(servo, stress, integral, interval, time).axial;
}

CellRates servo_rates(const ServoSettings& servo, const Mat3& stress, Vec3* integral, double interval, double time,
                      Vec3* shear_integral) {
  const Vec3 sigma = stress.diagonal();
  const Vec3 target = path_targets(servo, sigma[0]);
  // Errors are normalized by |sigma*_k| (docs/physics.md section 6), floored at a thousandth of the
  // path's own stress scale, so a target passing through zero (constant p at eta near 3) cannot
  // divide by zero.
  const double floor = 1e-3 * path_scale(servo);
  // At a set inertial number the strain-controlled rates follow the measured mean stress (driven_rate).
  const auto ramped = [&](double set) { return driven_rate(servo, set, sigma.mean(), time); };
  Vec3 rate = Vec3::Zero();
  for (int k = 0; k < 3; ++k) {
    if (servo.control[k] != AxisControl::strain) continue;
    rate[k] = ramped(servo.strain_rate[k]);
  }
  Vec3 shear = Vec3::Zero();
  for (int k = 0; k < 3; ++k)
    if (servo.shear_control[k] == AxisControl::strain && servo.shear_strain_rate[k] != 0.0)
      shear[k] = ramped(servo.shear_strain_rate[k]);
  const Limits l = limits(servo, rate, servo.control, shear, &servo.shear_control);
  for (int k = 0; k < 3; ++k) {
    if (servo.control[k] == AxisControl::strain) continue;
    const double error = (target[k] - sigma[k]) / std::max(std::abs(target[k]), floor);
    rate[k] = pi_rate(servo, error, integral != nullptr ? &(*integral)[k] : nullptr, interval, l.cap, l.integral_time);
  }
  // Shear stresses: errors relative to the path's stress scale (a shear target is often zero).
  shear_stress_rates(servo, servo.shear_control, servo.shear_target, stress,
                     std::max({path_scale(servo), std::abs(sigma.mean()), 1e-300}), shear_integral, interval, l, shear);
  return {rate, shear};
}

Vec3 custom_strain_rates(const ServoSettings& servo, const PathTargets& targets, const PathInput& input, Vec3* integral,
                         Vec3* shear_out, Vec3* shear_integral) {
  const Vec3 sigma = input.stress.diagonal();
  double scale = std::abs(sigma.mean());
  int volume_axes = 0;
  for (int k = 0; k < 3; ++k) {
    const char* kind = targets.control[k] == AxisControl::strain   ? "strain"
                       : targets.control[k] == AxisControl::stress ? "stress"
                                                                   : nullptr;
    if (kind == nullptr) {
      ++volume_axes;
      continue;
    }
    if (!std::isfinite(targets.value[k]))
      throw std::invalid_argument("servo.custom returned value[" + std::to_string(k) +
                                  "] = " + std::to_string(targets.value[k]) + " on a " + kind +
                                  "-controlled axis: must be finite");
    if (targets.control[k] == AxisControl::stress) scale = std::max(scale, std::abs(targets.value[k]));
  }
  const double floor = 1e-3 * scale;
  const double interval = input.dt * input.interval;
  Vec3 rate = Vec3::Zero();
  for (int k = 0; k < 3; ++k)
    if (targets.control[k] == AxisControl::strain) rate[k] = targets.value[k];
  Vec3 shear = Vec3::Zero();
  for (int k = 0; k < 3; ++k) {
    if (targets.shear_control[k] == AxisControl::volume)
      throw std::invalid_argument(std::string("servo.custom returned shear_control[") + k_shear_names[k] +
                                  "] = volume: a shear component is strain or stress controlled");
    if (!std::isfinite(targets.shear_value[k]))
      throw std::invalid_argument(std::string("servo.custom returned shear_value[") + k_shear_names[k] +
                                  "] = " + std::to_string(targets.shear_value[k]) + ": must be finite");
    if (targets.shear_control[k] == AxisControl::strain) shear[k] = targets.shear_value[k];
  }
  const Limits l = limits(servo, rate, targets.control, shear, &targets.shear_control);
  for (int k = 0; k < 3; ++k) {
    if (targets.control[k] != AxisControl::stress) continue;
    const double error = (targets.value[k] - sigma[k]) / std::max(std::abs(targets.value[k]), floor);
    rate[k] = pi_rate(servo, error, integral != nullptr ? &(*integral)[k] : nullptr, interval, l.cap, l.integral_time);
  }
  // Shear stresses: errors relative to the stress scale of the answer (a shear target is often zero).
  shear_stress_rates(servo, targets.shear_control, targets.shear_value, input.stress, std::max(scale, 1e-300),
                     shear_integral, interval, l, shear);
  if (shear_out != nullptr) *shear_out = shear;
  if (volume_axes == 0) return rate;
  // L <- L (1 + D dt) each step (integrate_initial), D = -rate: after n steps the volume is
  // V prod_k (1 + D_k dt)^n. The volume axes share the D that makes it V0 = prod L0:
  // (1 + D dt)^(m n) = V0 / (V prod_others (1 + D_k dt)^n).
  const double n = input.interval;
  double others = 1.0;  // prod over the other axes of (1 + D_k dt)
  for (int k = 0; k < 3; ++k)
    if (targets.control[k] != AxisControl::volume) others *= 1.0 - rate[k] * input.dt;
  const double ratio = input.length0.prod() / input.length.prod();
  if (!(others > 0.0) || !(ratio > 0.0) || !std::isfinite(ratio))
    throw std::invalid_argument(
        "servo.custom: the volume axes cannot hold the volume: the other axes' rates over one step "
        "give a length factor " +
        std::to_string(others) + " (must be > 0)");
  const double factor = std::pow(ratio, 1.0 / (volume_axes * n)) / std::pow(others, 1.0 / volume_axes);
  const double volume_rate = -(factor - 1.0) / input.dt;
  for (int k = 0; k < 3; ++k)
    if (targets.control[k] == AxisControl::volume) rate[k] = volume_rate;
  return rate;
}

PathInput path_input(const Model& model, const Mat3& stress, const Cell& cell, const Clock& clock) {
  PathInput in;
  in.step = clock.step;
  in.time = clock.time;
  in.dt = model.dt;
  in.interval = model.servo.interval;
  in.stress = stress;
  in.length = cell.length;
  in.length0 = cell.length0;
  for (int k = 0; k < 3; ++k) in.strain[k] = -std::log(cell.length[k] / cell.length0[k]);
  in.strain_rate = -cell.rate;
  in.deformation = cell.deformation();
  in.shear_strain_rate = Vec3::Zero() - cell.shear_rate;
  return in;
}

PathFunction undrained_path(double axial_rate) {
  if (!std::isfinite(axial_rate))
    throw std::invalid_argument("undrained.axial_rate = " + std::to_string(axial_rate) + ": must be finite (1/s)");
  return [axial_rate](const PathInput&) {
    PathTargets t;
    t.control = {AxisControl::strain, AxisControl::volume, AxisControl::volume};
    t.value = Vec3(axial_rate, 0.0, 0.0);
    return t;
  };
}

void validate(const CyclicSettings& c) {
  const auto fail = [](const std::string& key, double value, const std::string& allowed) {
    throw std::invalid_argument("cyclic." + key + " = " + std::to_string(value) + ": " + allowed);
  };
  if (c.axial == AxisControl::volume) throw std::invalid_argument("cyclic.axial = volume: must be strain or stress");
  if (!std::isfinite(c.lower)) fail("lower", c.lower, "must be finite");
  if (!(c.upper > c.lower) || !std::isfinite(c.upper)) fail("upper", c.upper, "must be finite and > lower");
  if (c.axial == AxisControl::strain && (!(c.rate > 0.0) || !std::isfinite(c.rate)))
    fail("rate", c.rate, "must be a finite value > 0 1/s in strain mode");
  if (!(c.tolerance >= 0.0 && c.tolerance < 0.5)) fail("tolerance", c.tolerance, "must be in [0, 0.5)");
  if (!c.undrained && (!(c.sigma3 > 0.0) || !std::isfinite(c.sigma3)))
    fail("sigma3", c.sigma3, "must be a finite value > 0 Pa when drained");
  if (c.cycles < 0) fail("cycles", c.cycles, "must be >= 0 (0: no limit)");
  if (!(c.max_strain >= 0.0) || !std::isfinite(c.max_strain))
    fail("max_strain", c.max_strain, "must be finite and >= 0 (0: no limit)");
}

CyclicPath::CyclicPath(const CyclicSettings& settings) : settings_(settings), memory_(std::make_shared<Memory>()) {
  validate(settings_);
}

std::vector<double> CyclicPath::save() const {
  const Memory& m = *memory_;
  std::vector<double> out{m.up ? 1.0 : 0.0, double(m.reversals), m.finished ? 1.0 : 0.0};
  for (std::size_t k = 0; k < m.reversal_strain.size(); ++k) {
    out.push_back(m.reversal_strain[k]);
    out.push_back(double(m.reversal_step[k]));  // exact below 2^53 steps
  }
  return out;
}

void CyclicPath::restore(const std::vector<double>& saved) const {
  if (saved.size() < 3 || (saved.size() - 3) % 2 != 0 || saved[1] != double((saved.size() - 3) / 2))
    throw std::invalid_argument("CyclicPath::restore: " + std::to_string(saved.size()) +
                                " values: not a saved cyclic path (3 + 2 per reversal)");
  Memory& m = *memory_;
  m.up = saved[0] != 0.0;
  m.reversals = static_cast<int>(saved[1]);
  m.finished = saved[2] != 0.0;
  m.reversal_strain.clear();
  m.reversal_step.clear();
  for (std::size_t k = 3; k < saved.size(); k += 2) {
    m.reversal_strain.push_back(saved[k]);
    m.reversal_step.push_back(static_cast<std::uint64_t>(saved[k + 1]));
  }
}

PathTargets CyclicPath::operator()(const PathInput& in) const {
  const CyclicSettings& c = settings_;
  Memory& m = *memory_;
  const double eps1 = in.strain[0];
  const double lateral = 0.5 * (in.stress(1, 1) + in.stress(2, 2));
  const double q = in.stress(0, 0) - lateral;
  // Reversal: the measure reached the bound it was heading for (stress mode: within the tolerance).
  const double measure = c.axial == AxisControl::strain ? eps1 : q;
  const double slack = c.axial == AxisControl::strain ? 0.0 : c.tolerance * (c.upper - c.lower);
  if (!m.finished && (m.up ? measure >= c.upper - slack : measure <= c.lower + slack)) {
    m.up = !m.up;
    ++m.reversals;
    m.reversal_strain.push_back(eps1);
    m.reversal_step.push_back(in.step);
  }
  if ((c.cycles > 0 && m.reversals >= 2 * c.cycles) || (c.max_strain > 0.0 && std::abs(eps1) >= c.max_strain))
    m.finished = true;
  PathTargets t;
  t.control[0] = c.axial;
  t.value[0] = c.axial == AxisControl::strain ? (m.up ? c.rate : -c.rate) : lateral + (m.up ? c.upper : c.lower);
  for (int k = 1; k < 3; ++k) {
    t.control[k] = c.undrained ? AxisControl::volume : AxisControl::stress;
    t.value[k] = c.undrained ? 0.0 : c.sigma3;
  }
  return t;
}

void Servo::run(const Model& model, State& state, Scratch& scratch, Executor&) {
  if (!servo_due(model.servo, state.clock.step)) return;
  const MeasuredStress& measured = scratch.read<MeasuredStress>();
  Cell& cell = state.write<Component::cell>();
  const StressPathSpec& spec = stress_path(model.servo.path);
  if (model.servo.path == StressPath::custom || spec.answer != nullptr) {
    const PathInput input = path_input(model, measured.stress, cell, state.clock);
    PathTargets targets = spec.answer ? spec.answer(model.servo, input) : model.servo.custom(input);
    // A shear component the settings hold by stress (cell.shear = "free") stays so under a custom path.
    if (!spec.answer)
      for (int k = 0; k < 3; ++k)
        if (model.servo.shear_control[k] == AxisControl::stress) {
          targets.shear_control[k] = AxisControl::stress;
          targets.shear_value[k] = model.servo.shear_target[k];
        }
    Vec3 shear = Vec3::Zero();
    cell.rate = -custom_strain_rates(model.servo, targets, input, &cell.servo_integral, &shear, &cell.shear_integral);
    cell.shear_rate = Vec3::Zero() - shear;  // L_ab = -gamma_dot_ab (0 - 0 = +0: a fixed cell stays orthorhombic)
    return;
  }
  const CellRates rates = servo_rates(model.servo, measured.stress, &cell.servo_integral,
                                      model.dt * model.servo.interval, state.clock.time, &cell.shear_integral);
  cell.rate = -rates.axial;  // D_kk is tension positive
  cell.shear_rate = Vec3::Zero() - rates.shear;
}

}  // namespace sandcell
